"""Compiled builders of compressed sparse rows from unsorted triplets, for the large meshes' set-up.

SciPy's COO → CSR conversion and duplicate summation go through int64 index copies and a full sort; mesh matrices
have short rows (a vertex's one ring), so a counting sort by row and an insertion sort inside each row is several
times faster.
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
    # Sort each row by column (stable insertion sort: rows are short) and sum duplicates in place.
    ptr = np.zeros(n + 1, np.int64)
    out = 0
    for r in range(n):
        lo = count[r]
        hi = count[r + 1]
        for p in range(lo + 1, hi):
            c = idx[p]
            v = val[p]
            q = p - 1
            while q >= lo and idx[q] > c:
                idx[q + 1] = idx[q]
                val[q + 1] = val[q]
                q -= 1
            idx[q + 1] = c
            val[q + 1] = v
        start = out
        for p in range(lo, hi):
            if out > start and idx[out - 1] == idx[p]:
                val[out - 1] += val[p]
            else:
                idx[out] = idx[p]
                val[out] = val[p]
                out += 1
        ptr[r + 1] = out
    return ptr, idx[:out].copy(), val[:out].copy()


def _to_scipy(ptr: np.ndarray, idx: np.ndarray, val: np.ndarray, n: int) -> sp.csr_matrix:
    if n < np.iinfo(np.int32).max and len(val) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    M = sp.csr_matrix((val, idx, ptr), shape=(n, n))
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
