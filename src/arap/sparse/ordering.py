"""Fill-reducing orderings computed outside CHOLMOD, so that they can run beside the rest of the set-up.

CHOLMOD's nested dissection (``analyze(..., ordering_method="metis")``) holds Python's global interpreter lock for
its whole run, seconds for a 1M-vertex sphere (``benchmarks/bench_scaling.py`` times it in the set-up's split), and
needs the assembled matrix. Its ordering depends only on the
matrix's pattern, which is the mesh graph restricted to the free vertices, known before any weight is computed. So
the solver asks METIS for the same ordering directly, on a worker thread, while the main thread builds the cells,
the matrices and the right-hand side's gather (:class:`BackgroundOrdering`), and factorises with the result as a
given ordering (:func:`arap.sparse.linsolve.factorize`).

METIS is the system library that CHOLMOD itself links (Debian's ``libmetis5``, installed with SuiteSparse by
``./dev setup``), loaded with :mod:`ctypes`, which releases the interpreter lock during the call. It is called with
METIS' default options, as CHOLMOD calls it, and its permutation is postordered as CHOLMOD postorders it (elimination
tree children in increasing order of their column counts), so that, for a graph ordered in one call, the factor and
the solutions are the same as with CHOLMOD's own ordering. Where the library cannot be loaded,
:func:`metis_available` is False and the factorisation falls back to CHOLMOD's own analysis.

METIS draws random numbers from the C library's shared generator, so two orderings must not run at once in one
process (they would interleave their draws and depend on timing): :data:`_metis_lock` serialises them.

**Two halves at once.** A large graph (from :data:`SPLIT_VERTICES` vertices, with two or more CPUs) is ordered in
two parts: METIS' vertex separator splits it, and the two halves are ordered by nested dissection at the same time,
each by its own copy of METIS, the separator last. The second copy is loaded into a new link namespace
(``dlmopen``, GNU C library 2.32 or later), with its own C library and so its own random generator, so that both
orderings are reproducible. On the 1M-vertex sphere's reduced graph (899k vertices) this orders markedly faster than
one call (``benchmarks/bench_scaling.py`` times the ordering), and the factor has 1% fewer non-zeros (7% fewer
flops). Where the second copy cannot be loaded, the whole
graph is ordered by one call, as CHOLMOD orders it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import platform
import threading
import time
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numba as nb
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)
from arap.sparse._etree import postorder

__all__ = [
    "BackgroundOrdering",
    "leading_subgraph",
    "metis_available",
    "nested_dissection",
    "permute_rows",
    "unpermute_rows",
]

_METIS_NAMES = ("libmetis.so.5", "libmetis.so", "libmetis.5.dylib", "libmetis.dylib")
_METIS_NOPTIONS = 40
_METIS_OK = 1
_METIS_OPTION_NITER = 6
_LM_ID_NEWLM = -1
_RTLD_NOW = 2
_SIGNALS = (6, 15)  # SIGABRT and SIGTERM, which every METIS call traps and restores
SPLIT_VERTICES = 100_000
"""Graphs of at least this many vertices are ordered in two halves at once (see the module's docstring)."""
_metis_lock = threading.Lock()
logger = logging.getLogger(__name__)
_SEVEN_POINTERS = ctypes.CFUNCTYPE(ctypes.c_int, *[ctypes.c_void_p] * 7)


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
        if hasattr(lib, "METIS_ComputeVertexSeparator"):  # for the ordering by halves
            lib.METIS_ComputeVertexSeparator.argtypes = [ctypes.c_void_p] * 7
            lib.METIS_ComputeVertexSeparator.restype = ctypes.c_int
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


def _glibc_has_private_namespaces() -> bool:
    """Whether the C library is GNU's, 2.32 or later: the first whose copies in other link namespaces allocate
    memory apart from the main one's."""
    name, version = platform.libc_ver()
    if name != "glibc":
        return False
    try:
        major, minor = (int(part) for part in version.split(".")[:2])
    except ValueError:
        return False
    return (major, minor) >= (2, 32)


@lru_cache(maxsize=1)
def _second_metis() -> Any | None:
    """``METIS_NodeND`` of a second copy of the METIS library, loaded in a new link namespace with its own C library
    (own random generator), or None where that is not possible."""
    found = _metis()
    if found is None or not _glibc_has_private_namespaces() or not hasattr(found[0], "METIS_ComputeVertexSeparator"):
        return None
    try:
        libc = _libc()
        dlmopen, dlsym = libc.dlmopen, libc.dlsym
    except (OSError, AttributeError):
        return None
    dlmopen.restype = ctypes.c_void_p
    dlmopen.argtypes = [ctypes.c_long, ctypes.c_char_p, ctypes.c_int]
    dlsym.restype = ctypes.c_void_p
    dlsym.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
    handle = dlmopen(_LM_ID_NEWLM, found[0]._name.encode(), _RTLD_NOW)
    if not handle:
        logger.debug("a second METIS could not be loaded: %s", libc.dlerror())
        return None
    address = dlsym(handle, b"METIS_NodeND")
    return _SEVEN_POINTERS(address) if address else None


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def metis_available() -> bool:
    """Whether :func:`nested_dissection` can run (the METIS library could be loaded)."""
    return _metis() is not None


def nested_dissection(indptr: NDArray[np.integer], indices: NDArray[np.integer],
                      refinement_passes: int | None = None, halves: bool | None = None) -> NDArray[np.int64]:
    """METIS' nested dissection of a graph, postordered as CHOLMOD postorders its orderings.

    Parameters
    ----------
    indptr : (k+1,) int array
    indices : (e,) int array
        Symmetric adjacency in compressed rows, without self loops (the pattern of a symmetric matrix without its
        diagonal).
    refinement_passes : int or None
        METIS' refinement passes per uncoarsening level (``METIS_OPTION_NITER``); None: METIS' default (10), which
        is what CHOLMOD uses. On a 1M-vertex sphere's reduced matrix 1 pass saves only a small part of the ordering's
        time (``benchmarks/bench_scaling.py`` times the ordering) for 0.3% more fill in the factor (1.6% more flops),
        which every solve pays, so the solver keeps the default.
    halves : bool or None
        Order the graph's two halves (either side of METIS' vertex separator) at the same time, on two threads with
        two copies of METIS (see the module's docstring). None: where the graph has at least
        :data:`SPLIT_VERTICES` vertices, two or more CPUs are available and a second copy of METIS can be loaded.
        True: wherever the second copy can be loaded. False: one call, CHOLMOD's own ordering.

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
    if not len(indices):  # METIS refuses a graph without edges; no edge means no fill in any order
        return np.arange(k, dtype=np.int64)
    options = None
    if refinement_passes is not None:
        options = np.empty(_METIS_NOPTIONS, dtype=idx)
        lib.METIS_SetDefaultOptions(options.ctypes.data)
        options[_METIS_OPTION_NITER] = int(refinement_passes)
    indptr64 = np.ascontiguousarray(indptr, dtype=np.int64)
    indices64 = np.ascontiguousarray(indices, dtype=np.int64)
    if halves is None:
        halves = k >= SPLIT_VERTICES and _cpus() >= 2
    second = _second_metis() if halves else None
    with _metis_lock:
        if second is None:
            perm = _node_nd(lib.METIS_NodeND, idx, indptr64, indices64, options)
        else:
            perm = _by_halves(lib, second, idx, indptr64, indices64, options)
    return postorder(indptr64, indices64, perm)


def _node_nd(node_nd: Any, idx: type[np.integer], indptr: NDArray[np.int64], indices: NDArray[np.int64],
             options: NDArray[np.integer] | None) -> NDArray[np.int64]:
    """One ``METIS_NodeND`` call (of the library ``node_nd`` belongs to): its ``perm``, not postordered."""
    k = len(indptr) - 1
    if k == 0 or not len(indices):
        return np.arange(k, dtype=np.int64)
    xadj = indptr.astype(idx)
    adjncy = indices.astype(idx)
    nvtxs = np.array([k], dtype=idx)
    perm = np.empty(k, dtype=idx)
    iperm = np.empty(k, dtype=idx)
    status = node_nd(nvtxs.ctypes.data, xadj.ctypes.data, adjncy.ctypes.data, None,
                     None if options is None else options.ctypes.data, perm.ctypes.data, iperm.ctypes.data)
    if status != _METIS_OK:
        raise RuntimeError(f"METIS_NodeND failed (status {status})")
    return perm.astype(np.int64)


def _by_halves(lib: Any, second: Any, idx: type[np.integer], indptr: NDArray[np.int64], indices: NDArray[np.int64],
               options: NDArray[np.integer] | None) -> NDArray[np.int64]:
    """The two sides of METIS' vertex separator ordered at once (this thread and another, each with its own METIS),
    then the separator: a nested dissection, not yet postordered."""
    k = len(indptr) - 1
    nvtxs = np.array([k], dtype=idx)
    size = np.zeros(1, dtype=idx)
    part = np.empty(k, dtype=idx)
    saved = _signal_handlers()
    try:
        xadj = indptr.astype(idx)
        adjncy = indices.astype(idx)
        status = lib.METIS_ComputeVertexSeparator(
            nvtxs.ctypes.data, xadj.ctypes.data, adjncy.ctypes.data, None, None, size.ctypes.data, part.ctypes.data)
        if status != _METIS_OK:
            raise RuntimeError(f"METIS_ComputeVertexSeparator failed (status {status})")
        side = part.astype(np.int64)
        first, first_ptr, first_idx = _induced_subgraph(indptr, indices, side, 0)
        other, other_ptr, other_idx = _induced_subgraph(indptr, indices, side, 1)
        result: dict[str, Any] = {}

        def order_other() -> None:
            try:
                result["perm"] = _node_nd(second, idx, other_ptr, other_idx, options)
            except Exception as exc:  # noqa: BLE001 - re-raised below, in the calling thread
                result["error"] = exc

        thread = threading.Thread(target=order_other, name="arap-ordering-half", daemon=True)
        thread.start()
        try:
            first_perm = _node_nd(lib.METIS_NodeND, idx, first_ptr, first_idx, options)
        finally:
            thread.join()
    finally:
        # Each METIS call installs its own SIGABRT and SIGTERM handlers and restores those it found; two at once
        # can leave one's handler behind.
        _restore_signal_handlers(saved)
    if "error" in result:
        raise result["error"]
    return np.concatenate([first[first_perm], other[result["perm"]], np.flatnonzero(side == 2)])


@lru_cache(maxsize=1)
def _libc() -> Any:
    """The C library of the main link namespace (the process's own), with the prototypes used here."""
    libc = ctypes.CDLL(None)
    libc.sigaction.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    libc.sigaction.restype = ctypes.c_int
    libc.dlerror.restype = ctypes.c_char_p
    return libc


def _signal_handlers() -> list[tuple[int, Any]]:
    """The C library's handlers of :data:`_SIGNALS`, as opaque ``struct sigaction`` buffers."""
    libc = _libc()
    saved = []
    for signum in _SIGNALS:
        buffer = ctypes.create_string_buffer(512)
        if libc.sigaction(signum, None, buffer) == 0:
            saved.append((signum, buffer))
    return saved


def _restore_signal_handlers(saved: list[tuple[int, Any]]) -> None:
    libc = _libc()
    for signum, buffer in saved:
        libc.sigaction(signum, buffer, None)


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


def leading_subgraph(adjacency: sp.csr_matrix, order: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The graph of the first ``k`` vertices of ``order``, numbered by their position in it.

    The pattern (without the diagonal) of ``M[order][:, order][:k, :k]`` for any matrix ``M`` with the adjacency's
    pattern, e.g. the solver's reduced matrix over its free vertices, which come first in its internal order.

    Parameters
    ----------
    adjacency : (n, n) scipy.sparse.csr_matrix
        Symmetric adjacency without self loops (e.g. :func:`arap.meshes.topology.vertex_adjacency`).
    order : (n,) int array
        ``order[i]`` is the vertex numbered ``i``.
    k : int
        How many leading vertices to keep.

    Returns
    -------
    indptr : (k+1,) int64 array
    indices : (e,) int32 array
        Neighbours of every kept vertex among the kept ones, in increasing order.
    """
    return _leading_subgraph(adjacency.indptr, adjacency.indices, np.asarray(order, dtype=np.int64), int(k))


@nb.njit(cache=True, nogil=True)
def _leading_subgraph(indptr, indices, order, k):  # pragma: no cover - compiled
    # Rows read in the adjacency's own order (sequentially), written to their new places, then sorted.
    n = order.shape[0]
    position = np.empty(n, np.int64)
    for i in range(n):
        position[order[i]] = i
    ptr = np.zeros(k + 1, np.int64)
    for v in range(n):
        i = position[v]
        if i < k:
            count = 0
            for p in range(indptr[v], indptr[v + 1]):
                if position[indices[p]] < k:
                    count += 1
            ptr[i + 1] = count
    for i in range(k):
        ptr[i + 1] += ptr[i]
    out = np.empty(ptr[k], np.int32)
    for v in range(n):
        i = position[v]
        if i >= k:
            continue
        lo = ptr[i]
        q = lo
        for p in range(indptr[v], indptr[v + 1]):
            j = position[indices[p]]
            if j < k:
                r = q - 1  # insertion into the sorted row
                while r >= lo and out[r] > j:
                    out[r + 1] = out[r]
                    r -= 1
                out[r + 1] = j
                q += 1
    return ptr, out


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
def _induced_subgraph(indptr, indices, side, which):  # pragma: no cover - compiled
    # The vertices with side[v] == which (in increasing order) and their induced subgraph in compressed rows.
    n = side.shape[0]
    local = np.full(n, -1, np.int64)
    k = 0
    for v in range(n):
        if side[v] == which:
            local[v] = k
            k += 1
    vertices = np.empty(k, np.int64)
    ptr = np.zeros(k + 1, np.int64)
    for v in range(n):
        i = local[v]
        if i >= 0:
            vertices[i] = v
            count = 0
            for q in range(indptr[v], indptr[v + 1]):
                if local[indices[q]] >= 0:
                    count += 1
            ptr[i + 1] = ptr[i] + count
    adj = np.empty(ptr[k], np.int64)
    for i in range(k):
        v = vertices[i]
        p = ptr[i]
        for q in range(indptr[v], indptr[v + 1]):
            j = local[indices[q]]
            if j >= 0:
                adj[p] = j
                p += 1
    return vertices, ptr, adj
