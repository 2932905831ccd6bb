"""Fill-reducing orderings computed outside CHOLMOD, so that they can run beside the rest of the set-up.

CHOLMOD's nested dissection (``analyze(..., ordering_method="metis")``) holds Python's global interpreter lock for
its whole run, about 4-5 s for a 1M-vertex sphere, and needs the assembled matrix. Its ordering depends only on the
matrix's pattern, which is the mesh graph restricted to the free vertices, known before any weight is computed. So
the solver asks METIS for the same ordering directly, on a worker thread, while the main thread builds the cells,
the matrices and the right-hand side's gather (:class:`BackgroundOrdering`), and factorises with the result as a
given ordering (:func:`arap.linsolve.factorize`).

METIS is the system library that CHOLMOD itself links (Debian's ``libmetis5``, installed with SuiteSparse by
``./dev setup``), loaded with :mod:`ctypes`, which releases the interpreter lock during the call. It is called with
METIS' default options, as CHOLMOD calls it, and its permutation is postordered as CHOLMOD postorders it (elimination
tree children in increasing order of their column counts), so the factor and the solutions are the same as with
CHOLMOD's own ordering. Where the library cannot be loaded, :func:`metis_available` is False and the factorisation
falls back to CHOLMOD's own analysis.

METIS draws random numbers from the C library's shared generator, so two orderings must not run at once in one
process (they would interleave their draws and depend on timing): :data:`_metis_lock` serialises them.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import threading
import time
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap._numba_cache  # noqa: F401  (a writable cache folder before the kernels below are defined)
from arap._csr import permuted_rows

__all__ = ["BackgroundOrdering", "metis_available", "nested_dissection", "permute_rows", "unpermute_rows"]

_METIS_NAMES = ("libmetis.so.5", "libmetis.so", "libmetis.5.dylib", "libmetis.dylib")
_METIS_NOPTIONS = 40
_METIS_OK = 1
_METIS_OPTION_NITER = 6
_metis_lock = threading.Lock()
logger = logging.getLogger(__name__)


@lru_cache(maxsize=1)
def _metis() -> tuple[Any, type[np.integer]] | None:
    """The METIS library and its index type (``idx_t``: 32 or 64 bits), or None where it cannot be loaded."""
    names = list(_METIS_NAMES)
    found = ctypes.util.find_library("metis")
    if found:
        names.insert(0, found)
    for name in names:
        try:
            lib = ctypes.CDLL(name)
            set_defaults = lib.METIS_SetDefaultOptions
            node_nd = lib.METIS_NodeND
        except (OSError, AttributeError):
            continue
        set_defaults.argtypes = [ctypes.c_void_p]
        set_defaults.restype = ctypes.c_int
        node_nd.argtypes = [ctypes.c_void_p] * 7
        node_nd.restype = ctypes.c_int
        # METIS_SetDefaultOptions writes METIS_NOPTIONS values of -1: 40 int32 words for a 32-bit idx_t, 80 for a
        # 64-bit one. A probe twice that long tells which.
        probe = np.zeros(2 * _METIS_NOPTIONS, dtype=np.int32)
        if set_defaults(probe.ctypes.data) != _METIS_OK:
            continue
        written = int(np.count_nonzero(probe == -1))
        if written == _METIS_NOPTIONS:
            return lib, np.int32
        if written == 2 * _METIS_NOPTIONS:
            return lib, np.int64
    return None


def metis_available() -> bool:
    """Whether :func:`nested_dissection` can run (the METIS library could be loaded)."""
    return _metis() is not None


def nested_dissection(indptr: NDArray[np.integer], indices: NDArray[np.integer],
                      refinement_passes: int | None = None) -> NDArray[np.int64]:
    """METIS' nested dissection of a graph, postordered as CHOLMOD postorders its orderings.

    Parameters
    ----------
    indptr : (k+1,) int array
    indices : (e,) int array
        Symmetric adjacency in compressed rows, without self loops (the pattern of a symmetric matrix without its
        diagonal).
    refinement_passes : int or None
        METIS' refinement passes per uncoarsening level (``METIS_OPTION_NITER``); None: METIS' default (10), which
        is what CHOLMOD uses, so that the ordering is CHOLMOD's own. Measured on a 1M-vertex sphere's reduced matrix:
        1 pass orders in ~0.45 s less (3.7 s instead of 4.3 s) for 0.3% more fill in the factor (1.6% more flops),
        which every solve pays, so the solver keeps the default.

    Returns
    -------
    (k,) int64 array
        ``perm[i]`` is the vertex eliminated ``i``-th: factorise ``A[perm][:, perm]``.

    Raises
    ------
    RuntimeError
        If METIS cannot be loaded or reports an error.
    """
    found = _metis()
    if found is None:
        raise RuntimeError("the METIS library could not be loaded")
    lib, idx = found
    k = len(indptr) - 1
    if k == 0:
        return np.zeros(0, dtype=np.int64)
    xadj = np.ascontiguousarray(indptr, dtype=idx)
    adjncy = np.ascontiguousarray(indices, dtype=idx)
    if not len(adjncy):  # METIS refuses a graph without edges; no edge means no fill in any order
        return np.arange(k, dtype=np.int64)
    nvtxs = np.array([k], dtype=idx)
    perm = np.empty(k, dtype=idx)
    iperm = np.empty(k, dtype=idx)
    options = None
    if refinement_passes is not None:
        options = np.empty(_METIS_NOPTIONS, dtype=idx)
        lib.METIS_SetDefaultOptions(options.ctypes.data)
        options[_METIS_OPTION_NITER] = int(refinement_passes)
    with _metis_lock:
        status = lib.METIS_NodeND(nvtxs.ctypes.data, xadj.ctypes.data, adjncy.ctypes.data, None,
                                  None if options is None else options.ctypes.data, perm.ctypes.data,
                                  iperm.ctypes.data)
    if status != _METIS_OK:
        raise RuntimeError(f"METIS_NodeND failed (status {status})")
    return _postorder(np.ascontiguousarray(indptr, dtype=np.int64), np.ascontiguousarray(indices, dtype=np.int64),
                      perm.astype(np.int64))


class BackgroundOrdering:
    """:func:`nested_dissection` of a graph on a worker thread, started at construction.

    Parameters
    ----------
    indptr, indices : int arrays
        As for :func:`nested_dissection`.
    prepare : callable or None
        ``prepare(indptr, indices, perm)``, run on the same thread after the ordering (e.g. the symbolic analysis
        of the permuted pattern); its result is :attr:`prepared`. If it raises, :attr:`prepared` stays None (the
        caller then does that work itself) and the error is logged at DEBUG level.

    Attributes
    ----------
    seconds : float
        How long the thread ran (set when it has finished).
    prepared : object or None
        What ``prepare`` returned.
    """

    def __init__(self, indptr: NDArray[np.integer], indices: NDArray[np.integer],
                 prepare: Callable[[NDArray[np.integer], NDArray[np.integer], NDArray[np.int64]], Any] | None = None,
                 ) -> None:
        self.size = len(indptr) - 1
        self.seconds = 0.0
        self.prepared: Any = None
        self._perm: NDArray[np.int64] | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(indptr, indices, prepare), name="arap-ordering",
                                        daemon=True)
        self._thread.start()

    def _run(self, indptr: NDArray[np.integer], indices: NDArray[np.integer],
             prepare: Callable[[NDArray[np.integer], NDArray[np.integer], NDArray[np.int64]], Any] | None) -> None:
        t0 = time.perf_counter()
        try:
            self._perm = nested_dissection(indptr, indices)
        except Exception as exc:  # noqa: BLE001 - re-raised by result() in the thread that waits for it
            self._error = exc
        if self._perm is not None and prepare is not None:
            try:
                self.prepared = prepare(indptr, indices, self._perm)
            except Exception:
                logger.debug("preparing beside the ordering failed; the caller prepares", exc_info=True)
        self.seconds = time.perf_counter() - t0

    def result(self) -> NDArray[np.int64]:
        """Wait for the ordering and return it (``perm`` of :func:`nested_dissection`); re-raises its error."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        assert self._perm is not None
        return self._perm


def permute_rows(B: NDArray[np.float64], perm: NDArray[np.int64]) -> NDArray[np.float64]:
    """``B[perm]`` in Fortran order (what CHOLMOD reads without a copy), shape (k,) or (k, r) as ``B``."""
    B2 = B.reshape(len(B), -1)
    out = _gather_rows_t(B2, perm).T
    return out[:, 0] if B.ndim == 1 else out


def unpermute_rows(X: NDArray[np.float64], perm: NDArray[np.int64], ndim: int) -> NDArray[np.float64]:
    """``Y`` with ``Y[perm] = X``, C-ordered, with ``ndim`` dimensions (1 or 2)."""
    X2 = X.reshape(len(X), -1)
    out = _scatter_rows(X2, perm)
    return out[:, 0] if ndim == 1 else out


@nb.njit(cache=True, nogil=True)
def _gather_rows_t(B, perm):  # pragma: no cover - compiled
    out = np.empty((B.shape[1], perm.shape[0]))
    for i in range(perm.shape[0]):
        for j in range(B.shape[1]):
            out[j, i] = B[perm[i], j]
    return out


@nb.njit(cache=True, nogil=True)
def _scatter_rows(X, perm):  # pragma: no cover - compiled
    out = np.empty((perm.shape[0], X.shape[1]))
    for i in range(perm.shape[0]):
        for j in range(X.shape[1]):
            out[perm[i], j] = X[i, j]
    return out


@nb.njit(cache=True, nogil=True)
def _postorder(indptr, indices, perm):  # pragma: no cover - compiled
    # Elimination tree of the permuted pattern (Liu's algorithm with path compression), its column counts (Gilbert,
    # Ng and Peyton's skeleton-matrix method) and a depth-first postorder that visits the children of every node in
    # increasing order of their counts (ties by index), so that the heaviest child ends next to its parent.
    inv, ptr = permuted_rows(indptr, perm)
    n = perm.shape[0]
    adj = np.empty(ptr[n], np.int64)
    for i in range(n):
        p = ptr[i]
        for q in range(indptr[perm[i]], indptr[perm[i] + 1]):
            adj[p] = inv[indices[q]]
            p += 1
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    for k in range(n):
        for p in range(ptr[k], ptr[k + 1]):
            i = adj[p]
            while i != -1 and i < k:
                nxt = ancestor[i]
                ancestor[i] = k
                if nxt == -1:
                    parent[i] = k
                i = nxt
    post = _depth_first(parent, np.zeros(n, np.int64))
    count = _column_counts(ptr, adj, parent, post)
    post = _depth_first(parent, count)
    out = np.empty(n, np.int64)
    for i in range(n):
        out[i] = perm[post[i]]
    return out


@nb.njit(cache=True, nogil=True)
def _depth_first(parent, weight):  # pragma: no cover - compiled
    # Children lists in increasing (weight, index), by a bucket pass over the weights, then an iterative DFS.
    n = parent.shape[0]
    bucket_head = np.full(n, -1, np.int64)
    bucket_next = np.full(n, -1, np.int64)
    for j in range(n):
        if parent[j] != -1:
            w = min(max(weight[j], 0), n - 1)
            bucket_next[j] = bucket_head[w]
            bucket_head[w] = j
    head = np.full(n, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    for w in range(n - 1, -1, -1):
        j = bucket_head[w]
        while j != -1:
            after = bucket_next[j]
            p = parent[j]
            nxt[j] = head[p]
            head[p] = j
            j = after
    post = np.empty(n, np.int64)
    stack = np.empty(n, np.int64)
    k = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            p = stack[top]
            c = head[p]
            if c == -1:
                top -= 1
                post[k] = p
                k += 1
            else:
                head[p] = nxt[c]
                top += 1
                stack[top] = c
    return post


@nb.njit(cache=True, nogil=True)
def _column_counts(ptr, adj, parent, post):  # pragma: no cover - compiled
    # Nonzeros of every column of the Cholesky factor, diagonal included, without forming it: each row subtree's
    # leaves add one, the least common ancestor of consecutive leaves (found with a path-compressed forest) takes
    # one off, and the differences are summed up the tree.
    n = parent.shape[0]
    first = np.full(n, -1, np.int64)
    delta = np.zeros(n, np.int64)
    for k in range(n):
        j = post[k]
        if first[j] == -1:
            delta[j] = 1  # a leaf of the tree
        while j != -1 and first[j] == -1:
            first[j] = k
            j = parent[j]
    ancestor = np.arange(n)
    max_first = np.full(n, -1, np.int64)
    prev_leaf = np.full(n, -1, np.int64)
    for k in range(n):
        j = post[k]
        if parent[j] != -1:
            delta[parent[j]] -= 1
        for p in range(ptr[j], ptr[j + 1]):
            i = adj[p]
            if i <= j or first[j] <= max_first[i]:
                continue  # not a leaf of row i's subtree
            max_first[i] = first[j]
            previous = prev_leaf[i]
            prev_leaf[i] = j
            delta[j] += 1
            if previous != -1:
                q = previous
                while q != ancestor[q]:
                    q = ancestor[q]
                s = previous
                while s != q:
                    up = ancestor[s]
                    ancestor[s] = q
                    s = up
                delta[q] -= 1
        if parent[j] != -1:
            ancestor[j] = parent[j]
    for j in range(n):
        if parent[j] != -1:
            delta[parent[j]] += delta[j]
    return delta
