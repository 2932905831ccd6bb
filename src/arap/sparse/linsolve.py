"""Sparse Cholesky factorisation of the reduced global-step matrix, factorised once and reused.

Backends:

* ``sksparse``: CHOLMOD through ``scikit-sparse`` (optional; needs the system's SuiteSparse, which ``./dev setup``
  installs on Debian). The matrix is ordered by nested dissection (METIS), factorised supernodally with the system's
  optimised BLAS (OpenBLAS), then converted in place to a simplicial factor, whose triangular solves with three
  right-hand sides are the fastest of CHOLMOD's. The ordering can be given (``factorize(..., permutation=...)``):
  the solver computes METIS' nested dissection from the mesh graph on a thread while it assembles the matrix
  (:func:`background_ordering`, :mod:`arap.sparse.ordering`), which takes it off the critical path of a large set-up.
  Below :data:`arap.sparse.ordering.SPLIT_VERTICES` unknowns it is CHOLMOD's own ordering (the same factor bit for bit);
  above, METIS orders the two halves of the graph at once, on two threads.
* ``cholespy``: CHOLMOD through the self-contained ``cholespy`` wheel (nested dissection, simplicial factorisation
  without BLAS: the same solve speed, several times slower to factorise large meshes).
* ``scipy``: SciPy's SuperLU in symmetric mode, always available.

The default (:func:`default_backend`) trades factorisation time against solve time, which every iteration pays.
``sksparse`` factorises a large matrix (a 1M-vertex sphere's) several times faster than cholespy, but its converted
factor keeps the zeros of CHOLMOD's relaxed supernodes and solves noticeably slower, at every size (both are measured
side by side by ``benchmarks/bench_scaling.py --backends sksparse cholespy``). So cholespy is the default below
:data:`LARGE_SYSTEM` unknowns, where it also factorises as fast, and scikit-sparse above, where factorisation
dominates; for a tetrahedral solid, whose factor fills much more, scikit-sparse from :data:`LARGE_SOLID_SYSTEM`.
The environment variable :data:`BACKEND_ENV` (``ARAP_BACKEND``) names one backend for every size instead, e.g. to run
the tests with a backend they would not otherwise use (``.ci/run`` runs the core tests once with
``ARAP_BACKEND=sksparse``); a backend named in a call still wins.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from arap._cstdout import c_stdout_to_log
from arap.errors import OptionError
from arap.sparse._csr_permute import permuted_pattern, permuted_symmetric, with_diagonal
from arap.sparse.ordering import (
    BackgroundOrdering,
    leading_subgraph,
    metis_available,
    permute_rows,
    unpermute_rows,
)

logger = logging.getLogger(__name__)

BackendName = Literal["sksparse", "cholespy", "scipy"]
BACKENDS: tuple[str, ...] = ("sksparse", "cholespy", "scipy")
Ordering = Literal["metis", "nesdis", "amd"]
ORDERINGS: tuple[str, ...] = ("metis", "nesdis", "amd")
DEFAULT_ORDERING: Ordering = "metis"
LARGE_SYSTEM = 250_000
"""Unknowns from which the default backend is ``sksparse`` (when installed)."""
LARGE_SOLID_SYSTEM = 10_000
"""Unknowns from which the default backend of a tetrahedral solid's system is ``sksparse`` (when installed): the
fill of a volume's factor grows much faster than a surface's, so METIS' nested dissection and the supernodal
factorisation pay at far fewer unknowns (``benchmarks/bench_elements.py``'s tetrahedra)."""
BACKEND_ENV = "ARAP_BACKEND"
"""Environment variable naming the default backend for every size (one of :data:`BACKENDS`; unset or empty: by size,
see :func:`default_backend`)."""
Permutation = NDArray[np.integer] | BackgroundOrdering
"""A given fill-reducing ordering: the permutation, or the thread computing it."""


class NotPositiveDefiniteError(RuntimeError):
    """The matrix could not be factorised as symmetric positive definite."""


class Factor(Protocol):
    """A Cholesky factor of a symmetric positive definite matrix ``A``.

    Attributes
    ----------
    backend : str
        Which backend computed it.
    timings : dict of str to float
        Seconds spent building it. ``sksparse``: ``analyse`` (fill-reducing ordering and symbolic analysis, or only
        the symbolic analysis of a given ordering), ``factor`` (numeric factorisation) and ``convert`` (to the
        simplicial form used for solving); with a given ordering also ``ordering`` (waiting for it and permuting the
        matrix) and, for a :class:`~arap.sparse.ordering.BackgroundOrdering`, ``ordering_thread`` (its run time on its
        thread, mostly overlapped with the caller's work). The other backends report only ``factor``.
    """

    backend: str
    timings: dict[str, float]

    def solve(self, B: np.ndarray) -> np.ndarray:
        """Solve ``A X = B`` for ``B`` of shape (n, k)."""
        ...


@dataclass(frozen=True)
class _SymbolicPlan:
    """CHOLMOD's symbolic analysis of a permuted pattern, done before the matrix's values exist.

    ``pattern_indptr``/``pattern_indices``: the unpermuted matrix's pattern (the graph with its diagonal);
    ``indptr``/``indices``/``source``: the permuted pattern and where each of its values comes from
    (:func:`arap.sparse._csr_permute.permuted_pattern`); ``factor``: the analysis of the permuted pattern.
    """

    pattern_indptr: NDArray[np.integer]
    pattern_indices: NDArray[np.integer]
    indptr: NDArray[np.integer]
    indices: NDArray[np.integer]
    source: NDArray[np.int64]
    factor: Any

    def fits(self, A: sp.csr_matrix) -> bool:
        """Whether ``A`` (CSR, sorted) has exactly the pattern analysed."""
        return (A.nnz == len(self.pattern_indices) and np.array_equal(A.indptr, self.pattern_indptr)
                and np.array_equal(A.indices, self.pattern_indices))


def _plan_symbolic(indptr: NDArray[np.integer], indices: NDArray[np.integer],
                   perm: NDArray[np.int64]) -> _SymbolicPlan:
    """Symbolic analysis of a matrix over the graph ``(indptr, indices)``, permuted by ``perm`` (a thread's work)."""
    from sksparse.cholmod import analyze

    pattern_indptr, pattern_indices = with_diagonal(indptr, indices)
    ptr, idx, source = permuted_pattern(pattern_indptr, pattern_indices, perm)
    C = sp.csc_matrix((np.ones(len(idx)), idx, ptr), shape=(len(perm), len(perm)))
    factor = analyze(C, mode="supernodal", ordering_method="natural")
    return _SymbolicPlan(pattern_indptr, pattern_indices, ptr, idx, source, factor)


class _SksparseFactor:
    backend = "sksparse"

    def __init__(self, A: sp.csr_matrix, ordering: str, permutation: Permutation | None = None) -> None:
        from sksparse.cholmod import CholmodError, CholmodNotPositiveDefiniteError, analyze

        self.timings: dict[str, float] = {}
        self._perm: NDArray[np.int64] | None = None
        t0 = time.perf_counter()
        if permutation is not None:
            perm = permutation.result() if isinstance(permutation, BackgroundOrdering) else permutation
            perm = np.asarray(perm, dtype=np.int64)
            if perm.shape != (A.shape[0],):
                raise OptionError(f"the permutation has shape {perm.shape}, the matrix {A.shape}")
            plan = permutation.prepared if isinstance(permutation, BackgroundOrdering) else None
            if isinstance(permutation, BackgroundOrdering):
                self.timings["ordering_thread"] = permutation.seconds
            self._perm = perm
            if isinstance(plan, _SymbolicPlan) and plan.fits(A):
                C = sp.csc_matrix((A.data[plan.source], plan.indices, plan.indptr), shape=A.shape)
                self.timings["ordering"] = time.perf_counter() - t0
                t0 = time.perf_counter()
                factor = plan.factor  # analysed on the ordering's thread
            else:
                C = permuted_symmetric(A, perm)
                self.timings["ordering"] = time.perf_counter() - t0
                t0 = time.perf_counter()
                # The permutation is final (postordered): CHOLMOD only analyses the permuted pattern.
                factor = analyze(C, mode="supernodal", ordering_method="natural")
        else:
            # CSC of a symmetric CSR matrix with sorted indices is the same arrays: no copy of the values.
            C = sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)
            try:
                factor = analyze(C, mode="supernodal", ordering_method=ordering)
            except CholmodError:
                # A CHOLMOD built without METIS cannot use nested dissection; AMD is always there.
                logger.debug("CHOLMOD ordering %r unavailable, using AMD", ordering)
                factor = analyze(C, mode="supernodal", ordering_method="amd")
        t1 = time.perf_counter()
        try:
            factor.cholesky_inplace(C)
        except CholmodNotPositiveDefiniteError as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc
        t2 = time.perf_counter()
        # Supernodal triangular solves call BLAS once per supernode, which for three right-hand sides costs more
        # than it saves; the simplicial form (same ordering, same fill) solves like cholespy does. CHOLMOD converts
        # a supernodal factor to simplicial only as LDLᵀ; the second, in-place step makes it LLᵀ again.
        factor._ensure_L_or_LD_inplace(False)
        factor._ensure_L_or_LD_inplace(True)
        self._factor = factor
        self.timings.update(analyse=t1 - t0, factor=t2 - t1, convert=time.perf_counter() - t2)

    def solve(self, B: np.ndarray) -> np.ndarray:
        if self._perm is None:
            return np.asarray(self._factor.solve_A(np.asfortranarray(B, dtype=np.float64)))
        B = np.asarray(B, dtype=np.float64)
        X = np.asarray(self._factor.solve_A(permute_rows(B, self._perm)))
        return unpermute_rows(X, self._perm, B.ndim)

    @property
    def permutation(self) -> NDArray[np.int64]:
        """``perm`` of the factorisation ``A[perm][:, perm] = L Lᵀ`` (CHOLMOD's own or the given one)."""
        return np.asarray(self._factor.P(), dtype=np.int64) if self._perm is None else self._perm


class _CholespyFactor:
    backend = "cholespy"

    def __init__(self, A: sp.csr_matrix) -> None:
        from cholespy import CholeskySolverD, MatrixType

        self.n = A.shape[0]
        t0 = time.perf_counter()
        try:
            with c_stdout_to_log():  # its CHOLMOD prints warnings on standard output
                self._solver = CholeskySolverD(
                    self.n, A.indptr.astype(np.int32), A.indices.astype(np.int32),
                    np.ascontiguousarray(A.data, dtype=np.float64), MatrixType.CSR,
                )
        except (ValueError, RuntimeError) as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc
        self.timings = {"factor": time.perf_counter() - t0}

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = np.ascontiguousarray(B, dtype=np.float64)
        X = np.empty_like(B)
        self._solver.solve(B, X)
        return X


class _ScipyFactor:
    backend = "scipy"

    def __init__(self, A: sp.csr_matrix) -> None:
        t0 = time.perf_counter()
        try:
            self._lu = spla.splu(
                A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True}
            )
        except RuntimeError as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc
        U_diag = self._lu.U.diagonal()
        if np.any(U_diag <= 0) or not np.all(np.isfinite(U_diag)):
            raise NotPositiveDefiniteError("matrix is not positive definite (non-positive pivot)")
        self.timings = {"factor": time.perf_counter() - t0}

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(B, dtype=np.float64))


def available_backends() -> list[str]:
    """Backends importable in this environment, in the order of :data:`BACKENDS`."""
    found = []
    for name, module in (("sksparse", "sksparse.cholmod"), ("cholespy", "cholespy")):
        try:
            __import__(module)
        except ImportError:
            continue
        found.append(name)
    found.append("scipy")
    return found


def default_backend(size: int, solid: bool = False) -> str:
    """The backend :func:`factorize` uses for a ``size`` × ``size`` matrix when none is named.

    Parameters
    ----------
    size : int
        Number of unknowns.
    solid : bool
        The matrix is a tetrahedral solid's (:data:`LARGE_SOLID_SYSTEM` instead of :data:`LARGE_SYSTEM`).

    Returns
    -------
    str
        The backend named by the environment variable :data:`BACKEND_ENV` if set; else ``sksparse`` from
        :data:`LARGE_SYSTEM` unknowns on (:data:`LARGE_SOLID_SYSTEM` for a solid) if installed, else ``cholespy``
        if installed, else the first available.

    Raises
    ------
    OptionError
        :data:`BACKEND_ENV` names no backend.
    """
    forced = os.environ.get(BACKEND_ENV, "").strip()
    if forced:
        if forced not in BACKENDS:
            raise OptionError(f"{BACKEND_ENV}={forced!r} names no backend; expected one of {BACKENDS}")
        return forced
    found = available_backends()
    if size >= (LARGE_SOLID_SYSTEM if solid else LARGE_SYSTEM) and "sksparse" in found:
        return "sksparse"
    return "cholespy" if "cholespy" in found else found[0]


def background_ordering(adjacency: sp.csr_matrix, order: np.ndarray, size: int,
                        backend: str | None = None) -> BackgroundOrdering | None:
    """Start the fill-reducing ordering of a system over the first ``size`` vertices of ``order`` on a thread.

    For the ``sksparse`` backend (named or the default for ``size`` unknowns) with METIS loadable: the ordering
    :func:`factorize` would compute (CHOLMOD's METIS nested dissection), from the mesh graph alone, so that the
    matrix can be assembled meanwhile. Pass the result to :func:`factorize` as ``permutation``.

    Parameters
    ----------
    adjacency : (n, n) scipy.sparse.csr_matrix
        The mesh's vertex adjacency (:func:`arap.meshes.topology.vertex_adjacency`).
    order : (n,) int array
        The system's vertex numbering: ``order[i]`` is the vertex of unknown ``i``; the unknowns are the first
        ``size``.
    size : int
        Number of unknowns.
    backend : str or None
        As for :func:`factorize`.

    Returns
    -------
    BackgroundOrdering or None
        None where :func:`factorize` orders by itself (another backend, no METIS library, no unknowns).
    """
    if size == 0 or (backend or default_backend(size)) != "sksparse" or not metis_available():
        return None
    indptr, indices = leading_subgraph(adjacency, order, size)
    return BackgroundOrdering(indptr, indices, _plan_symbolic)


def factorize(A: sp.csr_matrix | sp.csc_matrix | sp.coo_matrix, backend: str | None = None,
              ordering: str = DEFAULT_ORDERING, permutation: Permutation | None = None) -> Factor:
    """Cholesky-factorise a symmetric positive definite sparse matrix.

    Parameters
    ----------
    A : (k, k) sparse matrix
        Symmetric positive definite.
    backend : {"sksparse", "cholespy", "scipy"} or None
        None: :func:`default_backend` for the matrix's size.
    ordering : {"metis", "nesdis", "amd"}
        Fill-reducing ordering for ``sksparse``: METIS' nested dissection (the default: on a 1M-vertex sphere about
        1.6× less fill than AMD, and quicker to compute than ``nesdis``), CHOLMOD's own nested dissection
        (METIS bisections, constrained minimum degree inside; what cholespy uses), or approximate minimum degree
        (fastest to compute, most fill). The other backends choose their own.
    permutation : (k,) int array, BackgroundOrdering or None
        A fill-reducing ordering for ``sksparse`` instead of ``ordering``: ``A[perm][:, perm]`` is factorised as it
        is (CHOLMOD does not postorder it), so pass a postordered one such as
        :func:`arap.sparse.ordering.nested_dissection` returns, or the :class:`~arap.sparse.ordering.BackgroundOrdering`
        computing it (waited for here). The other backends ignore it.

    Returns
    -------
    Factor
        Object with ``solve(B)`` for ``B`` of shape (k, r).

    Raises
    ------
    NotPositiveDefiniteError
        If the matrix is singular or indefinite.
    ImportError
        If the requested backend is not installed.
    """
    A = sp.csr_matrix(A, dtype=np.float64)
    A.sort_indices()
    name = backend or default_backend(A.shape[0])
    if name not in BACKENDS:
        raise OptionError(f"unknown backend {name!r}; expected one of {BACKENDS}")
    if ordering not in ORDERINGS:
        raise OptionError(f"unknown ordering {ordering!r}; expected one of {ORDERINGS}")
    if name == "sksparse":
        factor: Factor = _SksparseFactor(A, ordering, permutation)
    elif name == "cholespy":
        factor = _CholespyFactor(A)
    else:
        factor = _ScipyFactor(A)
    logger.debug("factorised %d×%d matrix with %s in %s", A.shape[0], A.shape[0], name, factor.timings)
    return factor
