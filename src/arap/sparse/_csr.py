"""Compiled builders of compressed sparse rows from unsorted triplets, for the large meshes' set-up.

SciPy's COO → CSR conversion and duplicate summation go through int64 index copies and a full sort; mesh matrices
have short rows (a vertex's one ring), so a counting sort by row, duplicates summed in the order they come, and an
insertion sort of each row's few distinct columns is several times faster.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp


@nb.njit(cache=True, nogil=True)
def _triplets_to_csr(rows, cols, vals, n):  # pragma: no cover - compiled
    count = np.zeros(n + 1, np.int64)
    for k in range(rows.shape[0]):
        count[rows[k] + 1] += 1
    for i in range(n):
        count[i + 1] += count[i]
    fill = count[:-1].copy()
    idx = np.empty(rows.shape[0], np.int32)
    val = np.empty(rows.shape[0], np.float64)
    for k in range(rows.shape[0]):
        r = rows[k]
        p = fill[r]
        idx[p] = cols[k]
        val[p] = vals[k]
        fill[r] = p + 1
    return _sort_rows_and_merge(count, idx, val, n)


@nb.njit(cache=True, nogil=True)
def _terms_to_csr(a, b, w, n):  # pragma: no cover - compiled
    # The triplets (a_k, b_k, -w_k) for all k, then (b_k, a_k, -w_k), then (i, i, Σ_a w + Σ_b w) for every vertex i
    # some term uses, placed row by row in that order, as csr_from_triplets would receive them.
    diag_a = np.zeros(n)
    diag_b = np.zeros(n)
    used = np.zeros(n, np.bool_)
    count = np.zeros(n + 1, np.int64)
    for k in range(a.shape[0]):
        diag_a[a[k]] += w[k]
        used[a[k]] = True
        used[b[k]] = True
        count[a[k] + 1] += 1
        count[b[k] + 1] += 1
    for k in range(b.shape[0]):
        diag_b[b[k]] += w[k]
    for i in range(n):
        if used[i]:
            count[i + 1] += 1
    for i in range(n):
        count[i + 1] += count[i]
    fill = count[:-1].copy()
    idx = np.empty(count[n], np.int32)
    val = np.empty(count[n], np.float64)
    for k in range(a.shape[0]):
        p = fill[a[k]]
        idx[p] = b[k]
        val[p] = -w[k]
        fill[a[k]] = p + 1
    for k in range(b.shape[0]):
        p = fill[b[k]]
        idx[p] = a[k]
        val[p] = -w[k]
        fill[b[k]] = p + 1
    for i in range(n):
        if used[i]:
            p = fill[i]
            idx[p] = i
            val[p] = diag_a[i] + diag_b[i]
            fill[i] = p + 1
    return _sort_rows_and_merge(count, idx, val, n)


@nb.njit(cache=True, nogil=True)
def _leading_blocks(indptr, indices, data, k):  # pragma: no cover - compiled
    # Rows [0, k) split by column into [0, k) and [k, n): both keep their sorted order.
    n_left = 0
    for p in range(indptr[k]):
        if indices[p] < k:
            n_left += 1
    left_ptr = np.zeros(k + 1, np.int64)
    right_ptr = np.zeros(k + 1, np.int64)
    left_idx = np.empty(n_left, np.int32)
    left_val = np.empty(n_left, np.float64)
    right_idx = np.empty(indptr[k] - n_left, np.int32)
    right_val = np.empty(indptr[k] - n_left, np.float64)
    nl = 0
    nr = 0
    for r in range(k):
        for p in range(indptr[r], indptr[r + 1]):
            c = indices[p]
            if c < k:
                left_idx[nl] = c
                left_val[nl] = data[p]
                nl += 1
            else:
                right_idx[nr] = c - k
                right_val[nr] = data[p]
                nr += 1
        left_ptr[r + 1] = nl
        right_ptr[r + 1] = nr
    return left_ptr, left_idx, left_val, right_ptr, right_idx, right_val


@nb.njit(cache=True, nogil=True)
def _face_edges_to_csr(F, cw, n):  # pragma: no cover - compiled
    # Edge opposite corner k of face f joins F[f, k+1] and F[f, k+2]; both directions get cw[f, k].
    count = np.zeros(n + 1, np.int64)
    for f in range(F.shape[0]):
        for k in range(3):
            count[F[f, k] + 1] += 2
    for i in range(n):
        count[i + 1] += count[i]
    fill = count[:-1].copy()
    total = count[n]
    idx = np.empty(total, np.int32)
    val = np.empty(total, np.float64)
    for f in range(F.shape[0]):
        for k in range(3):
            i = F[f, (k + 1) % 3]
            j = F[f, (k + 2) % 3]
            w = cw[f, k] if cw.shape[0] else 1.0
            p = fill[i]
            idx[p] = j
            val[p] = w
            fill[i] = p + 1
            p = fill[j]
            idx[p] = i
            val[p] = w
            fill[j] = p + 1
    return _sort_rows_and_merge(count, idx, val, n)


@nb.njit(cache=True, nogil=True)
def _sort_rows_and_merge(count, idx, val, n):  # pragma: no cover - compiled
    # Sum the entries of each row that share a column, in the order they were placed (a stamp per column marks
    # the row that saw it last and where it went), then sort the row's distinct columns (rows are short).
    stamp = np.full(n, -1, np.int64)
    slot = np.empty(n, np.int64)
    ptr = np.zeros(n + 1, np.int64)
    out = 0
    for r in range(n):
        start = out
        for p in range(count[r], count[r + 1]):
            c = idx[p]
            if stamp[c] == r:
                val[slot[c]] += val[p]
            else:
                stamp[c] = r
                slot[c] = out
                idx[out] = c
                val[out] = val[p]
                out += 1
        for p in range(start + 1, out):
            c = idx[p]
            v = val[p]
            q = p - 1
            while q >= start and idx[q] > c:
                idx[q + 1] = idx[q]
                val[q + 1] = val[q]
                q -= 1
            idx[q + 1] = c
            val[q + 1] = v
        ptr[r + 1] = out
    return ptr, idx[:out].copy(), val[:out].copy()


def _to_scipy(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, n: int, cols: int | None = None) -> sp.csr_matrix:
    if n < np.iinfo(np.int32).max and len(val) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    M = sp.csr_matrix((val, idx, ptr), shape=(n, n if cols is None else cols))
    M.has_sorted_indices = True
    return M


def csr_from_face_edges(F: np.ndarray, n: int, corner_values: np.ndarray | None = None) -> sp.csr_matrix:
    """Symmetric matrix over the edges of triangles: ``M[i, j] = Σ`` of ``corner_values[f, k]`` over the faces ``f``
    whose corner ``k`` is opposite the edge ``(i, j)``; 1 per face if ``corner_values`` is None.

    Parameters
    ----------
    F : (m, 3) int array
    n : int
        Number of vertices.
    corner_values : (m, 3) float array or None

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        float64 values, sorted int32 column indices, zero diagonal not stored.
    """
    cw = np.zeros((0, 3)) if corner_values is None else np.ascontiguousarray(corner_values, dtype=np.float64)
    ptr, idx, val = _face_edges_to_csr(np.ascontiguousarray(F), cw, int(n))
    return _to_scipy(ptr, idx, val, int(n))


def csr_from_triplets(rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, n: int) -> sp.csr_matrix:
    """``sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()`` with duplicates summed and indices sorted.

    Parameters
    ----------
    rows, cols : (k,) int arrays
        Entry positions, each in ``[0, n)``.
    vals : (k,) float array
        Entry values; duplicates are summed.
    n : int
        Matrix size.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        float64 values, int32 column indices sorted within each row, no duplicates.
    """
    ptr, idx, val = _triplets_to_csr(
        np.asarray(rows), np.asarray(cols), np.ascontiguousarray(vals, dtype=np.float64), int(n)
    )
    return _to_scipy(ptr, idx, val, int(n))


def csr_from_terms(a: np.ndarray, b: np.ndarray, w: np.ndarray, n: int) -> sp.csr_matrix:
    """``Σ_k w_k (δ_a − δ_b)(δ_a − δ_b)ᵀ`` over edge terms, the same matrix (bit for bit) as
    ``csr_from_triplets`` of the triplets ``(a, b, −w)``, ``(b, a, −w)`` and one diagonal entry per used vertex.

    Parameters
    ----------
    a, b : (t,) int arrays
        Term endpoints, each in ``[0, n)``.
    w : (t,) float array
        Term weights.
    n : int
        Matrix size.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        float64 values, int32 column indices sorted within each row; a diagonal entry only for the vertices some
        term uses.
    """
    ptr, idx, val = _terms_to_csr(np.asarray(a), np.asarray(b), np.ascontiguousarray(w, dtype=np.float64), int(n))
    return _to_scipy(ptr, idx, val, int(n))


def leading_blocks(M: sp.csr_matrix, k: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """``M[:k, :k]`` and ``M[:k, k:]`` of a square CSR matrix with sorted indices, in one pass.

    Parameters
    ----------
    M : (n, n) scipy.sparse.csr_matrix
        Sorted column indices.
    k : int
        Size of the leading block, ``0 ≤ k ≤ n``.

    Returns
    -------
    left : (k, k) scipy.sparse.csr_matrix
    right : (k, n − k) scipy.sparse.csr_matrix
        float64 values, sorted int32 column indices, explicit zeros kept.
    """
    n = M.shape[0]
    lp, li, lv, rp, ri, rv = _leading_blocks(M.indptr, M.indices, np.ascontiguousarray(M.data, dtype=np.float64),
                                             int(k))
    return _to_scipy(lp, li, lv, int(k)), _to_scipy(rp, ri, rv, int(k), n - int(k))


@nb.njit(cache=True, nogil=True, inline="always")
def row_times(lo, hi, idx, val, X, s0, s1, s2):  # pragma: no cover - compiled
    """``(s0, s1, s2) + Σ_k val[k] X[idx[k]]`` over the entries ``lo:hi`` of a compressed row and an (m, 3) array
    ``X``, summed in entry order (SciPy's); inlined into the kernels that call it."""
    for k in range(np.uint64(lo), np.uint64(hi)):  # unsigned indices spare numba's negative-index fix-ups
        j = np.uint64(idx[k])
        v = val[k]
        s0 += v * X[j, 0]
        s1 += v * X[j, 1]
        s2 += v * X[j, 2]
    return s0, s1, s2


@nb.njit(cache=True, nogil=True, inline="always")
def row_times_2(lo, hi, idx, val, X, s0, s1):  # pragma: no cover - compiled
    """:func:`row_times` for an (m, 2) array ``X`` (the planar solver's two columns)."""
    for k in range(np.uint64(lo), np.uint64(hi)):
        j = np.uint64(idx[k])
        v = val[k]
        s0 += v * X[j, 0]
        s1 += v * X[j, 1]
    return s0, s1


@nb.njit(cache=True, nogil=True)
def _rows_product(rows, ptr, idx, val, X, out):  # pragma: no cover - compiled
    for t in range(rows.shape[0]):
        r = rows[t]
        s0, s1, s2 = row_times(ptr[t], ptr[t + 1], idx, val, X, 0.0, 0.0, 0.0)
        out[r, 0] = s0
        out[r, 1] = s1
        out[r, 2] = s2


class SparseRowsProduct:
    """``M @ X`` for a CSR matrix ``M`` with few non-empty rows and (m, 3) arrays ``X``, into one buffer kept for all
    calls, whose other rows stay zero.

    The solver's coupling of the free vertices to the fixed ones is such a matrix (only the free vertices next to a
    fixed one have entries); computed with SciPy, each call would allocate and clear an (k, 3) array for a few
    hundred rows. The sums are taken in SciPy's order, so the values are the same.

    Parameters
    ----------
    M : (k, m) scipy.sparse.csr_matrix

    Example
    -------
    >>> M = sp.csr_matrix(np.array([[0.0, 0.0], [2.0, -1.0], [0.0, 0.0]]))
    >>> SparseRowsProduct(M)(np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])).tolist()
    [[0.0, 0.0, 0.0], [-2.0, -1.0, 0.0], [0.0, 0.0, 0.0]]
    """

    def __init__(self, M: sp.csr_matrix) -> None:
        M = sp.csr_matrix(M, dtype=np.float64)
        self.shape = M.shape
        self.rows = np.flatnonzero(np.diff(M.indptr)).astype(np.int64)
        sub = M[self.rows]
        self._ptr = sub.indptr.astype(np.int64)
        self._idx = sub.indices.astype(np.int64)
        self._val = np.ascontiguousarray(sub.data)
        self._out = np.zeros((M.shape[0], 3))

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """``M @ X`` for an (m, 3) float64 array; the returned buffer is overwritten by the next call."""
        if X.shape != (self.shape[1], 3):
            raise ValueError(f"expected an array of shape {(self.shape[1], 3)}, got {X.shape}")
        _rows_product(self.rows, self._ptr, self._idx, self._val, np.ascontiguousarray(X, dtype=np.float64),
                      self._out)
        return self._out
