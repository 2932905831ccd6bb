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
    if n < np.iinfo(np.int32).max and len(val) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    M = sp.csr_matrix((val, idx, ptr), shape=(n, n))
    M.has_sorted_indices = True
    return M
