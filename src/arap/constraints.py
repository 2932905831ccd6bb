"""Constraint files: which vertices stay at rest, which move where.

The JSON format::

    {
      "fixed":   [0, 1, 2],                     # vertices held at their rest positions
      "handles": [40, 41],                      # vertices moved to targets
      "targets": [[0.0, 5.2, 0.1], [0.1, 5.2, 0.0]],   # one [x, y, z] per handle, same order
      "roi":     [0, 1, 2, 3, ...],             # optional region of interest (only these vertices move)
      "handle_groups": [[40, 41]],              # optional, informative (how an editor grouped the handles)
      "meta": {...}                             # optional, free-form, ignored
    }

Indices are 0-based in the mesh file's vertex order. ``fixed`` or ``handles`` may be omitted or empty, but not both.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arap.errors import ConstraintError

__all__ = ["Constraints", "load_constraints", "save_constraints"]

_KEYS = ("fixed", "handles", "targets", "roi", "handle_groups", "meta")


@dataclass
class Constraints:
    """A validated constraint set.

    Attributes
    ----------
    fixed : (f,) int64 array
        Vertices held at their rest positions.
    handles : (h,) int64 array
        Vertices moved to ``targets``.
    targets : (h, 3) float64 array
        Target position of each handle, in the order of ``handles``.
    roi : (r,) int64 array or None
        Region of interest, or None for the whole mesh.
    handle_groups : list of list of int or None
        Optional grouping of the handles (kept for round trips, not used by the solver).
    """

    fixed: np.ndarray
    handles: np.ndarray
    targets: np.ndarray
    roi: np.ndarray | None = None
    handle_groups: list[list[int]] | None = None

    @property
    def constrained(self) -> np.ndarray:
        """Fixed vertices then handles, shape (f + h,): the order of :meth:`indices_and_targets`."""
        return np.concatenate([self.fixed, self.handles])

    def indices_and_targets(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Constrained vertices and their targets, fixed vertices at their rest positions.

        Parameters
        ----------
        V : (n, 3) float array
            Rest positions.

        Returns
        -------
        indices : (f + h,) int64 array
            ``fixed`` then ``handles``.
        targets : (f + h, 3) float64 array
        """
        V = np.asarray(V, dtype=np.float64)
        return self.constrained, np.concatenate([V[self.fixed], self.targets]).reshape(-1, 3)

    def remapped(self, vertex_map: np.ndarray) -> Constraints:
        """The same constraints after a vertex renumbering (e.g. :attr:`arap.mesh.RepairResult.vertex_map`).

        Raises
        ------
        ConstraintError
            A constrained vertex was dropped (maps to -1) or two constrained vertices were merged.
        """
        vertex_map = np.asarray(vertex_map, dtype=np.int64)

        def remap(name: str, idx: np.ndarray) -> np.ndarray:
            out = vertex_map[idx]
            if (out < 0).any():
                bad = idx[out < 0]
                raise ConstraintError(f"{len(bad)} {name} vertices were removed by mesh repair "
                                      f"(unused or invalid), first: {int(bad[0])}")
            return out

        fixed = remap("fixed", self.fixed)
        handles = remap("handle", self.handles)
        merged = np.concatenate([fixed, handles])
        if len(np.unique(merged)) != len(merged):
            raise ConstraintError("mesh repair welded two constrained vertices into one; "
                                  "constrain only one of each pair of duplicate vertices")
        roi = None if self.roi is None else np.unique(remap("roi", self.roi))
        groups = None if self.handle_groups is None else [
            [int(vertex_map[i]) for i in g] for g in self.handle_groups
        ]
        return Constraints(fixed, handles, self.targets.copy(), roi, groups)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary in the file format."""
        out: dict[str, Any] = {
            "fixed": [int(i) for i in self.fixed],
            "handles": [int(i) for i in self.handles],
            "targets": [[float(x) for x in row] for row in self.targets],
        }
        if self.roi is not None:
            out["roi"] = [int(i) for i in self.roi]
        if self.handle_groups is not None:
            out["handle_groups"] = [[int(i) for i in g] for g in self.handle_groups]
        return out


# ---------------------------------------------------------------------------------------------- validation
def _indices(value: Any, name: str, n: int) -> np.ndarray:
    if isinstance(value, np.ndarray):
        if value.ndim != 1 or not (value.size == 0 or value.dtype.kind in "iu"):
            raise ConstraintError(f'"{name}" must be a flat list of integer vertex indices')
        arr = value.astype(np.int64)
    else:
        if not isinstance(value, list | tuple):
            raise ConstraintError(f'"{name}" must be a list of vertex indices, got {type(value).__name__}')
        for pos, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, int | np.integer):
                raise ConstraintError(f'"{name}" must hold integer vertex indices; item {pos} is {item!r}')
        arr = np.asarray(value, dtype=np.int64).reshape(-1)
    if len(arr):
        out = (arr < 0) | (arr >= n)
        if out.any():
            first = int(np.flatnonzero(out)[0])
            raise ConstraintError(f'"{name}" has {int(out.sum())} indices out of range [0, {n}) '
                                  f"(first: item {first} = {int(arr[first])})")
        uniq, counts = np.unique(arr, return_counts=True)
        if (counts > 1).any():
            dup = uniq[counts > 1]
            raise ConstraintError(f'"{name}" repeats {len(dup)} vertices (first: {int(dup[0])})')
    return arr


def _targets(value: Any, k: int) -> np.ndarray:
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise ConstraintError(f'"targets" must hold numbers, got dtype {value.dtype}')
        arr = value.astype(np.float64)
    else:
        if not isinstance(value, list | tuple):
            raise ConstraintError(f'"targets" must be a list of [x, y, z] points, got {type(value).__name__}')
        for pos, row in enumerate(value):
            ok = isinstance(row, list | tuple) and len(row) == 3 and all(
                isinstance(x, int | float | np.number) and not isinstance(x, bool) for x in row)
            if not ok:
                raise ConstraintError(f'"targets" item {pos} must be [x, y, z] numbers, got {row!r}')
        arr = np.asarray(value, dtype=np.float64).reshape(-1, 3) if len(value) else np.zeros((0, 3))
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ConstraintError(f'"targets" must have shape (k, 3), got {arr.shape}')
    if len(arr) != k:
        raise ConstraintError(f'"targets" has {len(arr)} points but "handles" has {k} vertices; '
                              "give one target per handle")
    finite = np.all(np.isfinite(arr), axis=1)
    if not finite.all():
        raise ConstraintError(f'"targets" has {int((~finite).sum())} non-finite points '
                              f"(first: item {int(np.flatnonzero(~finite)[0])})")
    return arr


def _read_json(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConstraintError(f"cannot read constraints file {path}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise ConstraintError(f"constraints file {path} is not UTF-8 text") from exc

    def reject(name: str) -> float:
        raise ConstraintError(f"constraints file {path} contains {name}, which is not valid JSON")

    try:
        return json.loads(text, parse_constant=reject)
    except json.JSONDecodeError as exc:
        raise ConstraintError(f"constraints file {path} is not valid JSON: {exc.msg} at line {exc.lineno}, "
                              f"column {exc.colno}") from exc


def load_constraints(source: str | os.PathLike[str] | Mapping[str, Any], n_vertices: int) -> Constraints:
    """Read and validate a constraint set against a mesh of ``n_vertices`` vertices.

    Parameters
    ----------
    source : path-like or mapping
        A JSON file in the format of this module, or the already parsed object.
    n_vertices : int
        Vertex count of the mesh the indices refer to.

    Returns
    -------
    Constraints

    Raises
    ------
    ConstraintError
        Unreadable or invalid JSON, unknown keys, values of the wrong type, non-integer, out-of-range or repeated
        indices, a vertex both fixed and a handle, a target count different from the handle count, targets not
        (k, 3) or non-finite, handles outside the region of interest, or no constraint at all.
    """
    data = source if isinstance(source, Mapping) else _read_json(Path(source))
    if not isinstance(data, Mapping):
        raise ConstraintError(f"constraints must be a JSON object, got {type(data).__name__}")
    unknown = sorted(set(data) - set(_KEYS))
    if unknown:
        raise ConstraintError(f"unknown constraint keys {unknown}; expected some of {list(_KEYS)}")
    if "fixed" not in data and "handles" not in data:
        raise ConstraintError('constraints need "fixed" and/or "handles" vertex lists')
    n = int(n_vertices)
    fixed = _indices(data.get("fixed", []), "fixed", n)
    handles = _indices(data.get("handles", []), "handles", n)
    if len(handles) and "targets" not in data:
        raise ConstraintError('"handles" are given without "targets"')
    targets = _targets(data.get("targets", []), len(handles))
    if not len(fixed) and not len(handles):
        raise ConstraintError("no vertex is constrained: give at least one fixed or handle vertex")
    both = np.intersect1d(fixed, handles)
    if len(both):
        raise ConstraintError(f"{len(both)} vertices are both fixed and handles (first: {int(both[0])})")

    roi = None
    if data.get("roi") is not None:
        roi = _indices(data["roi"], "roi", n)
        if not len(roi):
            raise ConstraintError('"roi" is empty; omit it to deform the whole mesh')
        outside = np.setdiff1d(handles, roi)
        if len(outside):
            raise ConstraintError(f"{len(outside)} handles lie outside the region of interest "
                                  f"(first: {int(outside[0])})")

    groups = None
    if data.get("handle_groups") is not None:
        raw = data["handle_groups"]
        if not isinstance(raw, list | tuple):
            raise ConstraintError('"handle_groups" must be a list of lists of vertex indices')
        groups = [[int(i) for i in _indices(g, f"handle_groups[{k}]", n)] for k, g in enumerate(raw)]
    if "meta" in data and not isinstance(data["meta"], Mapping):
        raise ConstraintError('"meta" must be a JSON object')
    return Constraints(fixed=fixed, handles=handles, targets=targets, roi=roi, handle_groups=groups)


def save_constraints(path: str | os.PathLike[str], constraints: Constraints) -> None:
    """Write a constraint set as JSON (readable by :func:`load_constraints`).

    Raises
    ------
    ConstraintError
        Non-finite targets (JSON has no NaN) or the file cannot be written.
    """
    data = constraints.to_dict()
    if not all(math.isfinite(x) for row in data["targets"] for x in row):
        raise ConstraintError("cannot save non-finite targets")
    try:
        Path(path).write_text(json.dumps(data) + "\n", encoding="utf-8")
    except OSError as exc:
        raise ConstraintError(f"cannot write constraints file {path}: {exc.strerror or exc}") from exc
