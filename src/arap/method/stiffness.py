"""Painted stiffness: the per-vertex cell weights ``w_i`` of the paper's energy ``Σ_i w_i E_i`` (Sorkine & Alexa
2007), checked, with infinity (a rigid part) mapped to a large finite weight; the cells scaled by them; and the error
that says why a stiffened system has no minimum.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError, ConstraintError, OptionError
from arap.method.cells import Cells

__all__ = ["MAX_STIFFNESS", "RIGID_STIFFNESS", "check_stiffness", "element_stiffness", "scale_cells",
           "singular_system_error"]

MAX_STIFFNESS = 1e6
"""Largest finite stiffness. Stiffer cells turn ever more slowly in the alternating iteration (a band of the cactus:
139 iterations at 100, 1,487 at 1e6, the iteration cap beyond 1e9): for a part that must not bend at all, ``np.inf``
(``"rigid"``) makes it one rigid body instead."""
RIGID_STIFFNESS = 1e8
"""Cell weight that stands for an infinite stiffness (``np.inf``): relative to the finite weights around it, large
enough to keep a region rigid to about 1e-8 of the mesh size, small enough for the factorisation to stay accurate."""


def check_stiffness(stiffness: object, n: int) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Validate per-vertex stiffness (the paper's cell weights ``w_i``) and map ``inf`` to :data:`RIGID_STIFFNESS`.

    Parameters
    ----------
    stiffness : (n,) array-like of float
        Positive weight of each vertex's cell: 1 is the plain energy, larger values make the cell stiffer, ``np.inf``
        (or the string ``"rigid"`` in files) keeps it rigid.
    n : int
        Number of vertices.

    Returns
    -------
    weights : (n,) float64 array
        The finite weights as given; rigid cells at :data:`RIGID_STIFFNESS` times the largest finite weight (at
        least 1).
    rigid : (n,) bool array
        The vertices given ``inf``.

    Raises
    ------
    OptionError
        Wrong shape, not numbers, zero, negative or NaN values, finite values above :data:`MAX_STIFFNESS`.

    Example
    -------
    >>> weights, rigid = check_stiffness([1.0, 2.0, np.inf], 3)
    >>> weights.tolist(), rigid.tolist()
    ([1.0, 2.0, 200000000.0], [False, False, True])
    """
    try:
        s = np.array(stiffness, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise OptionError(f"stiffness must be an array of {n} positive numbers ({exc})") from exc
    if s.shape != (n,):
        raise OptionError(f"stiffness must have shape ({n},), one value per vertex, got {s.shape}")
    if np.isnan(s).any() or (s <= 0).any():
        bad = int(np.flatnonzero(np.isnan(s) | (s <= 0))[0])
        raise OptionError(f"stiffness must be positive (vertex {bad} has {s[bad]})")
    rigid = np.isinf(s)
    if (s[~rigid] > MAX_STIFFNESS).any():
        bad = int(np.flatnonzero(~rigid & (s > MAX_STIFFNESS))[0])
        raise OptionError(f"stiffness must be at most {MAX_STIFFNESS:g} (vertex {bad} has {s[bad]:g}); for a part that "
                          "must not bend at all use infinity (\"rigid\" in a constraints file), which moves it as "
                          "one rigid body")
    finite_max = float(s[~rigid].max(initial=1.0))
    s[rigid] = RIGID_STIFFNESS * max(finite_max, 1.0)
    return s, rigid


def singular_system_error(cells: Cells, energy: str, stiffness: NDArray[np.float64] | None,
                          reason: str) -> ArapError:
    """The error to raise when the reduced system of ``cells`` could not be factorised (``reason``, the solver's
    message): painted stiffness on spoke cells with negative cotangent weights (:class:`OptionError`: the energy has
    no minimum), otherwise free vertices tied to the constraints only by zero-weight edges (:class:`ConstraintError`).
    """
    negative = int(np.count_nonzero(cells.w < 0)) if energy != "spokes_and_rims" else 0
    if stiffness is not None and negative and np.ptp(stiffness) > 0:
        return OptionError(
            f"painted stiffness needs non-negative edge weights with the {energy} energy: this mesh has obtuse "
            f"triangles ({negative} cell terms with a negative cotangent weight), and with unequal cell weights such "
            "terms leave the energy without a minimum. Use energy='spokes_and_rims' (the default), or "
            "weights='clamped'")
    return ConstraintError("the reduced ARAP system is singular: some free vertices are connected to the constraints "
                           f"only through zero-weight edges ({reason})")


def scale_cells(cells: Cells, stiffness: NDArray[np.float64]) -> Cells:
    """Cells whose terms are multiplied by their cell's stiffness: the energy ``Σ_i w_i E_i`` (Sorkine & Alexa 2007).

    Parameters
    ----------
    cells : Cells
    stiffness : (c,) float64 array
        Validated weights of the cells (see :func:`check_stiffness`, and :func:`cell_stiffness` for element cells).

    Returns
    -------
    Cells
        The rotations they fit are unchanged; the system matrix and the right-hand side follow from the weights.
    """
    per_term = stiffness[cells.cell_of_term()]
    return Cells(ptr=cells.ptr, a=cells.a, b=cells.b, w=cells.w * per_term, we=cells.we * per_term[:, None],
                 rest_sq=cells.rest_sq * stiffness, planar=cells.planar)


def element_stiffness(T: NDArray[np.int64], weights: NDArray[np.float64],
                      rigid: NDArray[np.bool_]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Per-vertex stiffness (:func:`check_stiffness`'s output) as the weights of element cells.

    An element is rigid when all its vertices are; the others weigh the mean of their vertices' finite weights (a
    rigid corner does not stiffen the elements that merely touch a rigid part).

    Parameters
    ----------
    T : (m, k) int array
        Elements (triangles or tetrahedra).
    weights : (n,) float64 array
    rigid : (n,) bool array

    Returns
    -------
    weights : (m,) float64 array
    rigid : (m,) bool array

    Example
    -------
    >>> w, r = check_stiffness([1.0, 3.0, np.inf, np.inf, np.inf], 5)
    >>> ew, er = element_stiffness(np.array([[0, 1, 2], [1, 2, 3], [2, 3, 4]]), w, r)
    >>> ew[:2].tolist(), er.tolist()
    ([2.0, 3.0], [False, False, True])
    """
    corner_rigid = rigid[T]
    element_rigid: NDArray[np.bool_] = np.asarray(corner_rigid.all(axis=1), dtype=bool)
    finite = np.where(corner_rigid, 0.0, weights[T])
    count = (~corner_rigid).sum(axis=1)
    out = np.empty(len(T))
    soft = ~element_rigid
    out[soft] = finite[soft].sum(axis=1) / count[soft]
    if element_rigid.any():
        out[element_rigid] = float(weights[rigid].max())
    return out, element_rigid
