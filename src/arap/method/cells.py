"""ARAP cells: which edge terms each vertex's rotation is fitted to, and the linear system they induce.

A cell ``c`` is a list of weighted edge terms ``(a, b, w)``; its energy is ``Σ w ‖(p'_a − p'_b) − R_c (p_a − p_b)‖²``.

* ``spokes`` (Sorkine & Alexa 2007): cell ``i`` holds the edges from ``i`` to its one-ring, ``w_ij = ½(cot α + cot β)``.
* ``spokes_and_rims`` (Chao et al. 2010, "A simple geometric model for elastic deformations"): cell ``i`` holds every
  edge of every triangle around ``i``, each weighted by ``½ cot`` of the angle opposite it in that triangle.

Both are built from per-face corner weights: an edge term of face ``f`` opposite corner ``x`` belongs to the cells of
its two endpoints (spokes) or of all three corners of ``f`` (spokes and rims). Terms of one cell on the same edge are
merged. The energy's normal equations are ``L p' = Σ_c R_c g_c`` with ``L = Σ_terms w (δ_a − δ_b)(δ_a − δ_b)ᵀ``; the
right-hand side of vertex ``v`` gathers ``R_c g_vc`` over the cells ``c`` of ``v`` and its neighbours.

The cells, the system matrix and the gather are built by compiled passes (counting placement, a stamp per vertex to
merge equal terms in the order they come, short sorts): a 1M-vertex sphere's spokes-and-rims cells in about a second
instead of eight for a sort of all its (cell, a, b) triples, with the same arrays bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import scipy.sparse as sp

from arap.method.weights import corner_weights, edge_weight_matrix
from arap.options import DEFAULT_ENERGY, DEFAULT_WEIGHTS, check_energy_and_weights
from arap.sparse._csr import csr_from_terms


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
    planar : bool
        The mesh lies in ``z = 0`` and every rotation turns about ``z`` (:mod:`arap.method.planar`).
    """

    ptr: np.ndarray
    a: np.ndarray
    b: np.ndarray
    w: np.ndarray
    we: np.ndarray
    rest_sq: np.ndarray
    planar: bool = False

    @property
    def n_cells(self) -> int:
        return len(self.ptr) - 1

    def cell_of_term(self) -> np.ndarray:
        """(t,) cell index of each term."""
        return np.repeat(np.arange(self.n_cells), np.diff(self.ptr))


def build_cells(V: np.ndarray, F: np.ndarray, energy: str = DEFAULT_ENERGY, weights: str = DEFAULT_WEIGHTS,
                planar: bool = False) -> Cells:
    """Build the cell structure of a mesh.

    Parameters
    ----------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    energy : {"spokes", "spokes_and_rims", "smooth_rotations"}
        ``smooth_rotations`` uses the spoke cells (its rotation term lives in :mod:`arap.method.smooth`).
    weights : {"cotangent", "clamped", "uniform"}
    planar : bool
        The mesh lies in ``z = 0``: its rotations turn about ``z``.

    Returns
    -------
    Cells
    """
    check_energy_and_weights(energy, weights)
    n = len(V)
    F = np.asarray(F, dtype=np.int64)
    if energy in ("spokes", "smooth_rotations"):  # SR-ARAP adds a rotation term to the spoke cells
        return _spoke_cells(V, F, weights, planar)
    cw = np.ascontiguousarray(corner_weights(V, F, weights), dtype=np.float64)
    ptr, a, b, w = _rim_cells_kernel(np.ascontiguousarray(F), cw, n)
    return finish_cells(V, ptr, a, b, w, planar)


def _spoke_cells(V: np.ndarray, F: np.ndarray, weights: str, planar: bool) -> Cells:
    """Spoke cells are the rows of the edge-weight matrix: cell ``i`` holds ``(i, j, W[i, j])``."""
    W = edge_weight_matrix(V, F, weights)
    W.sort_indices()
    n = len(V)
    ptr = W.indptr.astype(np.int64)
    cell = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    return finish_cells(V, ptr, cell, W.indices, W.data, planar)


@nb.njit(cache=True, nogil=True)
def _rim_cells_kernel(F, cw, n):  # pragma: no cover - compiled
    # Face f, corner k: the edge (p, q) = (F[f, k+1], F[f, k+2]) of weight cw[f, k] is a spoke of the cells of p and
    # q and a rim (min, max) of the cell of F[f, k]. A cell's slots hold its spokes (two per face around it) and
    # then its rims (one per face), face by face. Equal terms are summed in that order; the cell's terms are then
    # sorted by (a, b): rims with a < c, spokes (a = c) by b, rims with a > c.
    m = F.shape[0]
    ptr = np.zeros(n + 1, np.int64)
    for f in range(m):
        for k in range(3):
            ptr[F[f, k] + 1] += 3
    for i in range(n):
        ptr[i + 1] += ptr[i]
    spoke_fill = ptr[:-1].copy()
    rim_fill = np.empty(n, np.int64)
    for i in range(n):
        rim_fill[i] = ptr[i] + 2 * (ptr[i + 1] - ptr[i]) // 3
    first = np.empty(ptr[n], np.int32)
    second = np.empty(ptr[n], np.int32)
    val = np.empty(ptr[n], np.float64)
    for f in range(m):
        for k in range(3):
            x = F[f, k]
            p = F[f, (k + 1) % 3]
            q = F[f, (k + 2) % 3]
            w = cw[f, k]
            s = spoke_fill[p]
            second[s] = q
            val[s] = w
            spoke_fill[p] = s + 1
            s = spoke_fill[q]
            second[s] = p
            val[s] = w
            spoke_fill[q] = s + 1
            s = rim_fill[x]
            first[s] = min(p, q)
            second[s] = max(p, q)
            val[s] = w
            rim_fill[x] = s + 1
    stamp = np.full(n, -1, np.int64)
    slot = np.empty(n, np.int64)
    a = np.empty(ptr[n], np.int32)
    b = np.empty(ptr[n], np.int32)
    w_out = np.empty(ptr[n], np.float64)
    out_ptr = np.zeros(n + 1, np.int64)
    out = 0
    for c in range(n):
        lo = ptr[c]
        mid = lo + 2 * (ptr[c + 1] - lo) // 3
        hi = ptr[c + 1]
        # spokes: merge equal ends in place (stamp), then sort by end
        ns = lo
        for s in range(lo, mid):
            j = second[s]
            if stamp[j] == c:
                val[slot[j]] += val[s]
            else:
                stamp[j] = c
                slot[j] = ns
                second[ns] = j
                val[ns] = val[s]
                ns += 1
        _sort_pairs(first, second, val, lo, ns, False)
        # rims: merge equal edges (rare: repeated faces), then sort by (a, b)
        nr = mid
        for s in range(mid, hi):
            r = mid
            while r < nr and (first[r] != first[s] or second[r] != second[s]):
                r += 1
            if r < nr:
                val[r] += val[s]
            else:
                first[nr] = first[s]
                second[nr] = second[s]
                val[nr] = val[s]
                nr += 1
        _sort_pairs(first, second, val, mid, nr, True)
        r = mid
        while r < nr and first[r] < c:
            a[out] = first[r]
            b[out] = second[r]
            w_out[out] = val[r]
            out += 1
            r += 1
        for s in range(lo, ns):
            a[out] = c
            b[out] = second[s]
            w_out[out] = val[s]
            out += 1
        while r < nr:
            a[out] = first[r]
            b[out] = second[r]
            w_out[out] = val[r]
            out += 1
            r += 1
        out_ptr[c + 1] = out
    return out_ptr, a[:out].copy(), b[:out].copy(), w_out[:out].copy()


@nb.njit(cache=True, nogil=True)
def _sort_pairs(first, second, val, lo, hi, by_first):  # pragma: no cover - compiled
    # Insertion sort of [lo, hi) by (first, second) or by second alone; keys are distinct.
    for p in range(lo + 1, hi):
        x = first[p]
        y = second[p]
        v = val[p]
        q = p - 1
        while q >= lo and ((by_first and (first[q] > x or (first[q] == x and second[q] > y)))
                           or (not by_first and second[q] > y)):
            first[q + 1] = first[q]
            second[q + 1] = second[q]
            val[q + 1] = val[q]
            q -= 1
        first[q + 1] = x
        second[q + 1] = y
        val[q + 1] = v


def finish_cells(V: np.ndarray, ptr: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray,
                 planar: bool = False) -> Cells:
    """Cells from their terms: the weighted rest edges and rest sums computed, the arrays in the kernels' types.

    Parameters
    ----------
    V : (n, 3) float array
        Rest positions.
    ptr : (c+1,) int64 array
        Terms of cell ``c`` are ``ptr[c]:ptr[c+1]``.
    a, b : (t,) int arrays
    w : (t,) float array
    planar : bool
        See :class:`Cells`.
    """
    a = np.ascontiguousarray(a, dtype=np.int32)
    b = np.ascontiguousarray(b, dtype=np.int32)
    w = np.ascontiguousarray(w, dtype=np.float64)
    we, rest_sq = _rest_edges(np.ascontiguousarray(V, dtype=np.float64), ptr, a, b, w)
    return Cells(ptr=ptr, a=a, b=b, w=w, we=we, rest_sq=rest_sq, planar=planar)


@nb.njit(cache=True, nogil=True)
def _rest_edges(V, ptr, a, b, w):  # pragma: no cover - compiled
    # Weighted rest edges and, per cell, the weighted sum of squared rest edge lengths (summed in term order).
    we = np.empty((a.shape[0], 3))
    rest_sq = np.zeros(ptr.shape[0] - 1)
    for c in range(ptr.shape[0] - 1):
        acc = 0.0
        for k in range(ptr[c], ptr[c + 1]):
            e0 = V[a[k], 0] - V[b[k], 0]
            e1 = V[a[k], 1] - V[b[k], 1]
            e2 = V[a[k], 2] - V[b[k], 2]
            we[k, 0] = e0 * w[k]
            we[k, 1] = e1 * w[k]
            we[k, 2] = e2 * w[k]
            acc += w[k] * ((e0 * e0 + e2 * e2) + e1 * e1)  # NumPy's einsum order: the same bits as before
        rest_sq[c] = acc
    return we, rest_sq


def system_matrix(cells: Cells, n: int) -> sp.csr_matrix:
    """``L = Σ_terms w (δ_a − δ_b)(δ_a − δ_b)ᵀ``, the Hessian (over 2) of the energy in the positions, shape (n, n).

    For ``spokes`` this is twice the cotangent Laplacian; for ``spokes_and_rims`` three times.
    """
    return csr_from_terms(cells.a, cells.b, cells.w, n)


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
    # Term k of cell c adds +R_c we_k to the row of a_k and −R_c we_k to the row of b_k. Cells are visited in
    # increasing order, so a row's entries arrive sorted by cell and those of one cell are consecutive: they are
    # summed as they arrive (in term order), and a first pass counts the (row, cell) pairs to size the output.
    last = np.full(n_rows, -1, np.int64)
    out_ptr = np.zeros(n_rows + 1, np.int64)
    for c in range(ptr.shape[0] - 1):
        for k in range(ptr[c], ptr[c + 1]):
            for end in range(2):
                r = row_of[a[k]] if end == 0 else row_of[b[k]]
                if r >= 0 and last[r] != c:
                    last[r] = c
                    out_ptr[r + 1] += 1
    for r in range(n_rows):
        out_ptr[r + 1] += out_ptr[r]
    fill = out_ptr[:-1].copy()
    last[:] = -1
    cell = np.empty(out_ptr[n_rows], np.int32)
    g = np.empty((out_ptr[n_rows], 3))
    for c in range(ptr.shape[0] - 1):
        for k in range(ptr[c], ptr[c + 1]):
            for end in range(2):
                r = row_of[a[k]] if end == 0 else row_of[b[k]]
                if r < 0:
                    continue
                sign = 1.0 if end == 0 else -1.0
                if last[r] == c:
                    p = fill[r] - 1
                    g[p, 0] += sign * we[k, 0]
                    g[p, 1] += sign * we[k, 1]
                    g[p, 2] += sign * we[k, 2]
                else:
                    last[r] = c
                    p = fill[r]
                    cell[p] = c
                    g[p, 0] = sign * we[k, 0]
                    g[p, 1] = sign * we[k, 1]
                    g[p, 2] = sign * we[k, 2]
                    fill[r] = p + 1
    return out_ptr, cell, g


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
