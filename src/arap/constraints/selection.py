"""Validation of vertex selections and handle targets: the one place the library, the command line and the studio
check them (re-exported by :mod:`arap.constraints`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from arap.errors import ConstraintError
from arap.solve.indexing import check_index_array

__all__ = ["check_listed_targets", "check_selection"]


def check_selection(
    n: int,
    fixed: Any,
    handle_groups: Sequence[Any],
    roi: Any = None,
    *,
    group_names: Sequence[str] | None = None,
) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
    """Validate a selection of fixed vertices, handle groups and a region of interest against a mesh.

    Parameters
    ----------
    n : int
        Vertex count of the mesh.
    fixed : list of int or (f,) integer array
    handle_groups : sequence of lists of int or of integer arrays
        Handles, group by group (a constraints file's ``handles`` is one group).
    roi : list of int, (r,) integer array or None
        Region of interest; None is the whole mesh.
    group_names : sequence of str or None
        Names of the groups in messages; default ``"handle group i"``.

    Returns
    -------
    fixed : (f,) int64 array
    groups : list of (h_g,) int64 arrays
    roi : (r,) int64 array or None

    Raises
    ------
    ConstraintError
        Not lists of integers (floats such as ``1.0`` and booleans included), indices out of range, a vertex
        repeated within a list or listed in two of ``fixed`` and the groups, an empty group, or an empty region of
        interest.
    """
    fixed_arr = check_index_array(fixed, n, "fixed")
    if not isinstance(handle_groups, list | tuple):
        raise ConstraintError(f"handle groups must be a list of lists of vertex indices, got "
                              f"{type(handle_groups).__name__}")
    names = list(group_names) if group_names is not None else [f"handle group {i}" for i in range(len(handle_groups))]
    groups = [check_index_array(g, n, name, allow_empty=False) for g, name in zip(handle_groups, names, strict=True)]
    named = [("fixed", fixed_arr), *zip(names, groups, strict=True)]
    everything = np.concatenate([a for _, a in named])
    uniq, counts = np.unique(everything, return_counts=True)
    if np.any(counts > 1):
        v = int(uniq[np.argmax(counts > 1)])
        where = [name for name, a in named if np.any(a == v)]
        raise ConstraintError(f"vertex {v} is in both {where[0]} and {where[1]}; a vertex is either fixed or a "
                              "handle of one group")
    roi_arr = None if roi is None else check_index_array(roi, n, "roi", allow_empty=False)
    return fixed_arr, groups, roi_arr


def check_listed_targets(value: Any, k: int) -> np.ndarray:
    """Validate the target positions of ``k`` handles as a document lists them (the solver's arrays are checked by
    :func:`arap.solve.partition.check_targets`, with the solver's wording).

    Parameters
    ----------
    value : list of [x, y, z] or (k, 3) array
    k : int
        Number of handles.

    Returns
    -------
    (k, 3) float64 array

    Raises
    ------
    ConstraintError
        Not ``k`` points of three numbers, or numbers that are not finite doubles (NaN, infinity, or an integer
        too large for double precision).
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise ConstraintError(f"targets must hold numbers, got dtype {value.dtype}")
        arr = value.astype(np.float64)
    else:
        if not isinstance(value, list | tuple):
            raise ConstraintError(f"targets must be a list of [x, y, z] points, got {type(value).__name__}")
        rows = []
        for pos, row in enumerate(value):
            ok = isinstance(row, list | tuple) and len(row) == 3 and all(
                isinstance(x, int | float | np.number) and not isinstance(x, bool | np.bool_) for x in row)
            if not ok:
                text = repr(row)
                raise ConstraintError(f"targets item {pos} must be [x, y, z] numbers, got "
                                      f"{text if len(text) <= 40 else text[:37] + '...'}")
            try:
                rows.append([float(x) for x in row])
            except OverflowError:
                raise ConstraintError(f"targets item {pos} holds an integer too large for a coordinate "
                                      "(beyond ±1.8e308)") from None
        arr = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ConstraintError(f"targets must have shape (k, 3), got {arr.shape}")
    if len(arr) != k:
        raise ConstraintError(f'targets has {len(arr)} points but "handles" has {k} vertices; '
                              "give one target per handle")
    finite = np.all(np.isfinite(arr), axis=1)
    if not finite.all():
        raise ConstraintError(f"targets has {int((~finite).sum())} non-finite points "
                              f"(first: item {int(np.flatnonzero(~finite)[0])})")
    return arr
