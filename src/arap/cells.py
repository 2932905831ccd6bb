"""ARAP cells: which edge terms each vertex's rotation is fitted to, and the linear system they induce.

A cell ``c`` is a list of weighted edge terms ``(a, b, w)``; its energy is ``Σ w ‖(p'_a − p'_b) − R_c (p_a − p_b)‖²``.

* ``spokes`` (Sorkine & Alexa 2007): cell ``i`` holds the edges from ``i`` to its one-ring, ``w_ij = ½(cot α + cot β)``.
* ``spokes_and_rims`` (Chao et al. 2010, "A simple geometric model for elastic deformations"): cell ``i`` holds every
  edge of every triangle around ``i``, each weighted by ``½ cot`` of the angle opposite it in that triangle.

Both are built from per-face corner weights: an edge term of face ``f`` opposite corner ``x`` belongs to the cells of
its two endpoints (spokes) or of all three corners of ``f`` (spokes and rims). Terms of one cell on the same edge are
merged. The energy's normal equations are ``L p' = Σ_c R_c g_c`` with ``L = Σ_terms w (δ_a − δ_b)(δ_a − δ_b)ᵀ``; the
right-hand side of vertex ``v`` gathers ``R_c g_vc`` over the cells ``c`` of ``v`` and its neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numba as nb
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap._csr import csr_from_triplets
from arap.errors import OptionError
from arap.weights import DEFAULT_WEIGHTS, WEIGHT_TYPES, corner_weights, edge_weight_matrix

EnergyType = Literal["spokes", "spokes_and_rims", "smooth_rotations"]
ENERGY_TYPES: tuple[str, ...] = get_args(EnergyType)
"""Energy names: the one list the library, the command line, the studio protocol and its client use."""
ENERGY_LABELS: dict[str, str] = {"spokes": "spokes (2007 paper)", "spokes_and_rims": "spokes and rims",
                                 "smooth_rotations": "smooth rotations (SR-ARAP)"}
"""How the studio names each energy."""
DEFAULT_ENERGY: EnergyType = "spokes_and_rims"
"""The default cells: unlike ``spokes`` with cotangent weights, they do not fold meshes with obtuse triangles, and
their energy is a sum of non-negative per-triangle terms (see ``benchmarks/bench_folds.py``)."""


@dataclass(frozen=True)
class Cells:
    """Edge terms of every cell in CSR layout.

    Attributes
    ----------
    ptr : (n+1,) int64
        Terms of cell ``c`` are ``ptr[c]:ptr[c+1]``.
    a, b : (t,) int32
        Edge endpoints of each term.
    w : (t,) float64
        Term weights.
    we : (t, 3) float64
        ``w · (V[a] − V[b])``, the weighted rest edge.
    rest_sq : (n,) float64
        ``Σ_terms w ‖V[a] − V[b]‖²`` per cell.
    """

    ptr: np.ndarray
    a: np.ndarray
    b: np.ndarray
    w: np.ndarray
    we: np.ndarray
    rest_sq: np.ndarray

    @property
    def n_cells(self) -> int:
        return len(self.ptr) - 1

    def cell_of_term(self) -> np.ndarray:
        """(t,) cell index of each term."""
        return np.repeat(np.arange(self.n_cells), np.diff(self.ptr))


def check_energy_and_weights(energy: str, weights: str) -> None:
    """Refuse an unknown energy or weights name (:class:`~arap.errors.OptionError`): the one check of both names."""
    if energy not in ENERGY_TYPES:
        raise OptionError(f"unknown energy {energy!r}; expected one of {ENERGY_TYPES}")
    if weights not in WEIGHT_TYPES:
        raise OptionError(f"unknown weights {weights!r}; expected one of {WEIGHT_TYPES}")


def build_cells(V: np.ndarray, F: np.ndarray, energy: str = DEFAULT_ENERGY, weights: str = DEFAULT_WEIGHTS) -> Cells:
    """Build the cell structure of a mesh.

    Parameters
    ----------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    energy : {"spokes", "spokes_and_rims", "smooth_rotations"}
        ``smooth_rotations`` uses the spoke cells (its rotation term lives in :mod:`arap.smooth`).
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    Cells
    """
    check_energy_and_weights(energy, weights)
    n = len(V)
    F = np.asarray(F, dtype=np.int64)
    if energy in ("spokes", "smooth_rotations"):  # SR-ARAP adds a rotation term to the spoke cells
        return _spoke_cells(V, F, weights)
    cw = corner_weights(V, F, weights)
    # Edge opposite corner k of each face: (F[:, k+1], F[:, k+2]) with weight cw[:, k].
    ea = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    eb = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    ew = np.concatenate([cw[:, 0], cw[:, 1], cw[:, 2]])
    ex = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    lo = np.minimum(ea, eb)
    hi = np.maximum(ea, eb)
    cell = np.concatenate([ea, eb, ex])
    # Spokes are oriented away from their cell's vertex, rims canonically (lo, hi).
    a = np.concatenate([ea, eb, lo])
    b = np.concatenate([eb, ea, hi])
    w = np.concatenate([ew, ew, ew])
    order = np.lexsort((b, a, cell))
    cell, a, b, w = cell[order], a[order], b[order], w[order]
    first = np.ones(len(cell), dtype=bool)
    first[1:] = (cell[1:] != cell[:-1]) | (a[1:] != a[:-1]) | (b[1:] != b[:-1])
    group = np.cumsum(first) - 1
    w = np.bincount(group, weights=w)
    cell, a, b = cell[first], a[first], b[first]
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell, minlength=n), out=ptr[1:])
    return _finish(V, ptr, a, b, w)


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
        Wrong shape, not numbers, zero, negative or NaN values.

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
    finite_max = float(s[~rigid].max(initial=1.0))
    s[rigid] = RIGID_STIFFNESS * max(finite_max, 1.0)
    return s, rigid


def scale_cells(cells: Cells, stiffness: NDArray[np.float64]) -> Cells:
    """Cells whose terms are multiplied by their cell's stiffness: the energy ``Σ_i w_i E_i`` (Sorkine & Alexa 2007).

    Parameters
    ----------
    cells : Cells
    stiffness : (n,) float64 array
        Validated weights (see :func:`check_stiffness`).

    Returns
    -------
    Cells
        The rotations they fit are unchanged; the system matrix and the right-hand side follow from the weights.
    """
    per_term = stiffness[cells.cell_of_term()]
    return Cells(ptr=cells.ptr, a=cells.a, b=cells.b, w=cells.w * per_term, we=cells.we * per_term[:, None],
                 rest_sq=cells.rest_sq * stiffness)


def _spoke_cells(V: np.ndarray, F: np.ndarray, weights: str) -> Cells:
    """Spoke cells are the rows of the edge-weight matrix: cell ``i`` holds ``(i, j, W[i, j])``."""
    W = edge_weight_matrix(V, F, weights)
    W.sort_indices()
    n = len(V)
    ptr = W.indptr.astype(np.int64)
    cell = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    return _finish(V, ptr, cell, W.indices, W.data)


def _finish(V: np.ndarray, ptr: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray) -> Cells:
    a = a.astype(np.int32)
    b = b.astype(np.int32)
    w = np.ascontiguousarray(w, dtype=np.float64)
    e, we = _rest_edges(np.ascontiguousarray(V, dtype=np.float64), a, b, w)
    rest_sq = np.bincount(np.repeat(np.arange(len(ptr) - 1), np.diff(ptr)), weights=w * np.einsum("ij,ij->i", e, e),
                          minlength=len(ptr) - 1)
    return Cells(ptr=ptr, a=a, b=b, w=w, we=we, rest_sq=rest_sq)


@nb.njit(cache=True, nogil=True)
def _rest_edges(V, a, b, w):  # pragma: no cover - compiled
    e = np.empty((a.shape[0], 3))
    we = np.empty((a.shape[0], 3))
    for k in range(a.shape[0]):
        for d in range(3):
            x = V[a[k], d] - V[b[k], d]
            e[k, d] = x
            we[k, d] = x * w[k]
    return e, we


def system_matrix(cells: Cells, n: int) -> sp.csr_matrix:
    """``L = Σ_terms w (δ_a − δ_b)(δ_a − δ_b)ᵀ``, the Hessian (over 2) of the energy in the positions, shape (n, n).

    For ``spokes`` this is twice the cotangent Laplacian; for ``spokes_and_rims`` three times.
    """
    a, b, w = cells.a, cells.b, cells.w
    diagonal = np.bincount(a, weights=w, minlength=n) + np.bincount(b, weights=w, minlength=n)
    has = np.flatnonzero(np.bincount(a, minlength=n) + np.bincount(b, minlength=n))
    rows = np.concatenate([a, b, has])
    cols = np.concatenate([b, a, has])
    vals = np.concatenate([-w, -w, diagonal[has]])
    return csr_from_triplets(rows, cols, vals, n)


@dataclass(frozen=True)
class RhsGather:
    """Right-hand side in gather form: ``b_v = Σ_k R[cell[k]] @ g[k]`` for ``k`` in ``ptr[r]:ptr[r+1]``.

    Rows ``r`` index the vertices listed in ``rows`` (usually the free vertices).
    """

    rows: np.ndarray
    ptr: np.ndarray
    cell: np.ndarray
    g: np.ndarray


@nb.njit(cache=True, nogil=True)
def _gather_kernel(ptr, a, b, we, row_of, n_rows):  # pragma: no cover - compiled
    # Term k of cell c adds +R_c we_k to the row of a_k and −R_c we_k to the row of b_k.
    count = np.zeros(n_rows + 1, np.int64)
    for k in range(a.shape[0]):
        ra = row_of[a[k]]
        rb = row_of[b[k]]
        if ra >= 0:
            count[ra + 1] += 1
        if rb >= 0:
            count[rb + 1] += 1
    for r in range(n_rows):
        count[r + 1] += count[r]
    fill = count[:-1].copy()
    cell = np.empty(count[n_rows], np.int32)
    g = np.empty((count[n_rows], 3))
    for c in range(ptr.shape[0] - 1):
        for k in range(ptr[c], ptr[c + 1]):
            for end in range(2):
                r = row_of[a[k]] if end == 0 else row_of[b[k]]
                if r < 0:
                    continue
                sign = 1.0 if end == 0 else -1.0
                p = fill[r]
                cell[p] = c
                g[p, 0] = sign * we[k, 0]
                g[p, 1] = sign * we[k, 1]
                g[p, 2] = sign * we[k, 2]
                fill[r] = p + 1
    # Cells arrive in increasing order within each row: merge the entries of a row that share a cell.
    out_ptr = np.zeros(n_rows + 1, np.int64)
    out = 0
    for r in range(n_rows):
        start = out
        for p in range(count[r], count[r + 1]):
            if out > start and cell[out - 1] == cell[p]:
                g[out - 1, 0] += g[p, 0]
                g[out - 1, 1] += g[p, 1]
                g[out - 1, 2] += g[p, 2]
            else:
                cell[out] = cell[p]
                g[out, 0] = g[p, 0]
                g[out, 1] = g[p, 1]
                g[out, 2] = g[p, 2]
                out += 1
        out_ptr[r + 1] = out
    return out_ptr, cell[:out].copy(), g[:out].copy()


def build_rhs_gather(cells: Cells, rows: np.ndarray, n: int) -> RhsGather:
    """Gather structure of the right-hand side for the vertices ``rows``.

    Parameters
    ----------
    cells : Cells
    rows : (r,) int array
        Vertices whose right-hand side is needed.
    n : int
        Number of vertices.
    """
    rows = np.asarray(rows, dtype=np.int64)
    row_of = np.full(n, -1, dtype=np.int64)
    row_of[rows] = np.arange(len(rows))
    ptr, cell, g = _gather_kernel(cells.ptr, cells.a, cells.b, cells.we, row_of, len(rows))
    return RhsGather(rows=rows, ptr=ptr, cell=cell, g=g)
