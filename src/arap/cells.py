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
from typing import Literal

import numpy as np
import scipy.sparse as sp

from arap.weights import DEFAULT_WEIGHTS, corner_weights, edge_weight_matrix

EnergyType = Literal["spokes", "spokes_and_rims"]
ENERGY_TYPES: tuple[str, ...] = ("spokes", "spokes_and_rims")
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


def build_cells(V: np.ndarray, F: np.ndarray, energy: str = DEFAULT_ENERGY, weights: str = DEFAULT_WEIGHTS) -> Cells:
    """Build the cell structure of a mesh.

    Parameters
    ----------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    energy : {"spokes", "spokes_and_rims"}
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    Cells
    """
    if energy not in ENERGY_TYPES:
        raise ValueError(f"unknown energy {energy!r}; expected one of {ENERGY_TYPES}")
    n = len(V)
    F = np.asarray(F, dtype=np.int64)
    if energy == "spokes":
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
    return _finish(V, ptr, cell, a, b, w)


def _spoke_cells(V: np.ndarray, F: np.ndarray, weights: str) -> Cells:
    """Spoke cells are the rows of the edge-weight matrix: cell ``i`` holds ``(i, j, W[i, j])``."""
    W = edge_weight_matrix(V, F, weights)
    W.sort_indices()
    n = len(V)
    ptr = W.indptr.astype(np.int64)
    cell = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    return _finish(V, ptr, cell, cell, W.indices.astype(np.int64), W.data.astype(np.float64))


def _finish(V: np.ndarray, ptr: np.ndarray, cell: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray) -> Cells:
    e = V[a] - V[b]
    we = np.ascontiguousarray(e * w[:, None])
    rest_sq = np.bincount(cell, weights=w * np.einsum("ij,ij->i", e, e), minlength=len(V))
    return Cells(ptr=ptr, a=a.astype(np.int32), b=b.astype(np.int32), w=w, we=we, rest_sq=rest_sq)


def system_matrix(cells: Cells, n: int) -> sp.csr_matrix:
    """``L = Σ_terms w (δ_a − δ_b)(δ_a − δ_b)ᵀ``, the Hessian (over 2) of the energy in the positions, shape (n, n).

    For ``spokes`` this is twice the cotangent Laplacian; for ``spokes_and_rims`` three times.
    """
    a, b, w = cells.a, cells.b, cells.w
    rows = np.concatenate([a, b, a, b])
    cols = np.concatenate([a, b, b, a])
    vals = np.concatenate([w, w, -w, -w])
    L = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
    L.sum_duplicates()
    return L


@dataclass(frozen=True)
class RhsGather:
    """Right-hand side in gather form: ``b_v = Σ_k R[cell[k]] @ g[k]`` for ``k`` in ``ptr[r]:ptr[r+1]``.

    Rows ``r`` index the vertices listed in ``rows`` (usually the free vertices).
    """

    rows: np.ndarray
    ptr: np.ndarray
    cell: np.ndarray
    g: np.ndarray


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
    tcell = cells.cell_of_term()
    # Term (cell c, a, b, we) adds +R_c we to b_a and −R_c we to b_b.
    v = np.concatenate([cells.a, cells.b])
    c = np.concatenate([tcell, tcell])
    g = np.concatenate([cells.we, -cells.we])
    r = row_of[v]
    keep = r >= 0
    r, c, g = r[keep], c[keep], g[keep]
    order = np.lexsort((c, r))
    r, c, g = r[order], c[order], g[order]
    first = np.ones(len(r), dtype=bool)
    first[1:] = (r[1:] != r[:-1]) | (c[1:] != c[:-1])
    group = np.cumsum(first) - 1
    gs = np.stack([np.bincount(group, weights=g[:, k]) for k in range(3)], axis=1) if len(group) else g
    r, c = r[first], c[first]
    ptr = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=len(rows)), out=ptr[1:])
    return RhsGather(rows=rows, ptr=ptr, cell=c.astype(np.int32), g=np.ascontiguousarray(gs))
