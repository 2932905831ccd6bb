"""Symmetric permutations of compressed sparse rows, compiled: the permuted matrix or only its pattern (with the
map from its entries to the original's, so later matrices with the same pattern are permuted by one gather), a
diagonal made explicit, and the rows of a permuted pattern (for the elimination tree, :mod:`arap.sparse._etree`).

The sparse Cholesky back ends (:mod:`arap.sparse.linsolve`) factor the reduced system in a fill-reducing order computed
from the mesh graph; SciPy's fancy indexing ``A[perm][:, perm]`` sorts and copies twice.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp

__all__ = ["permuted_pattern", "permuted_rows", "permuted_symmetric", "with_diagonal"]


def permuted_symmetric(A: sp.csr_matrix, perm: np.ndarray) -> sp.csc_matrix:
    """``A[perm][:, perm]`` of a symmetric matrix, as CSC with sorted indices (the same arrays as its CSR).

    Both entries of a symmetric pair get the value ``A[min(i, j), max(i, j)]`` of the upper triangle, the one CHOLMOD
    reads when it permutes the matrix itself (sums of floating-point terms in different orders can make the two
    triangles differ in the last bits), so a factor of the result equals CHOLMOD's own bit for bit.

    Parameters
    ----------
    A : (k, k) scipy.sparse.csr_matrix
        Symmetric pattern, both triangles stored, sorted indices.
    perm : (k,) int array
        A permutation of ``range(k)``.

    Returns
    -------
    (k, k) scipy.sparse.csc_matrix
    """
    ptr, idx, val = _permute_symmetric(A.indptr, A.indices, np.ascontiguousarray(A.data, dtype=np.float64),
                                       np.asarray(perm, dtype=np.int64))
    k = A.shape[0]
    if k < np.iinfo(np.int32).max and len(val) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    C = sp.csc_matrix((val, idx, ptr), shape=(k, k))
    C.has_sorted_indices = True
    return C


@nb.njit(cache=True, nogil=True)
def permuted_rows(indptr, perm):  # pragma: no cover - compiled
    """The inverse of ``perm`` and the row pointers of a CSR pattern whose rows are taken in the order ``perm``."""
    n = perm.shape[0]
    inv = np.empty(n, np.int64)
    for i in range(n):
        inv[perm[i]] = i
    ptr = np.zeros(n + 1, np.int64)
    for i in range(n):
        ptr[i + 1] = ptr[i] + indptr[perm[i] + 1] - indptr[perm[i]]
    return inv, ptr


@nb.njit(cache=True, nogil=True)
def _permute_symmetric(indptr, indices, data, perm):  # pragma: no cover - compiled
    inv, ptr = permuted_rows(indptr, perm)
    n = perm.shape[0]
    idx = np.empty(ptr[n], np.int32)
    val = np.empty(ptr[n], data.dtype)
    for i in range(n):
        lo = ptr[i]
        q = lo
        o = perm[i]
        for p in range(indptr[o], indptr[o + 1]):
            oc = indices[p]
            c = inv[oc]
            v = data[p]
            if oc < o:  # the value of the upper triangle (row < column), as CHOLMOD reads the unpermuted matrix
                lo_q = indptr[oc]
                hi_q = indptr[oc + 1] - 1
                while lo_q < hi_q:
                    mid = (lo_q + hi_q) // 2
                    if indices[mid] < o:
                        lo_q = mid + 1
                    else:
                        hi_q = mid
                v = data[lo_q]
            r = q - 1
            while r >= lo and idx[r] > c:
                idx[r + 1] = idx[r]
                val[r + 1] = val[r]
                r -= 1
            idx[r + 1] = c
            val[r + 1] = v
            q += 1
    return ptr, idx, val


def with_diagonal(indptr: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pattern of a graph's adjacency with its diagonal added: what a matrix over the graph stores.

    Parameters
    ----------
    indptr : (k+1,) int array
    indices : (e,) int array
        Sorted rows without the diagonal.

    Returns
    -------
    indptr : (k+1,) int32 or int64 array
        int32 where it fits, as SciPy keeps it.
    indices : (e+k,) int32 array
        Sorted rows, each with its diagonal.
    """
    ptr, idx = _with_diagonal(np.asarray(indptr), np.asarray(indices))
    if len(idx) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    return ptr, idx


@nb.njit(cache=True, nogil=True)
def _with_diagonal(indptr, indices):  # pragma: no cover - compiled
    k = indptr.shape[0] - 1
    ptr = np.empty(k + 1, np.int64)
    idx = np.empty(indices.shape[0] + k, np.int32)
    q = 0
    for i in range(k):
        ptr[i] = q
        placed = False
        for p in range(indptr[i], indptr[i + 1]):
            if not placed and indices[p] > i:
                idx[q] = i
                q += 1
                placed = True
            idx[q] = indices[p]
            q += 1
        if not placed:
            idx[q] = i
            q += 1
    ptr[k] = q
    return ptr, idx


def permuted_pattern(indptr: np.ndarray, indices: np.ndarray,
                     perm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where :func:`permuted_symmetric` takes each value from, for any matrix with a given pattern.

    Parameters
    ----------
    indptr, indices : int arrays
        A symmetric pattern in compressed rows, sorted.
    perm : (k,) int array

    Returns
    -------
    indptr, indices : int arrays
        The pattern of ``A[perm][:, perm]``, sorted.
    source : (nnz,) int64 array
        ``permuted_symmetric(A, perm).data == A.data[source]`` for every ``A`` with this pattern.
    """
    ptr, idx, src = _permute_symmetric(np.asarray(indptr), np.asarray(indices), np.arange(len(indices)),
                                       np.asarray(perm, dtype=np.int64))
    if len(idx) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    return ptr, idx, src
