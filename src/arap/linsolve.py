"""Sparse Cholesky factorisation of the reduced global-step matrix, factorised once and reused.

Backends:

* ``sksparse``: CHOLMOD through ``scikit-sparse`` (optional; needs the system's SuiteSparse, which ``./dev setup``
  installs on Debian). The matrix is ordered by nested dissection (METIS), factorised supernodally with the system's
  optimised BLAS (OpenBLAS), then converted in place to a simplicial factor, whose triangular solves with three
  right-hand sides are the fastest of CHOLMOD's.
* ``cholespy``: CHOLMOD through the self-contained ``cholespy`` wheel (nested dissection, simplicial factorisation
  without BLAS: the same solve speed, several times slower to factorise large meshes).
* ``scipy``: SciPy's SuperLU in symmetric mode, always available.

The default (:func:`default_backend`) trades factorisation time against solve time, which every iteration pays.
``sksparse`` factorises a 1M-vertex sphere's matrix in ~8 s instead of cholespy's ~24 s, but its converted factor
keeps the zeros of CHOLMOD's relaxed supernodes and solves 15–40% slower (measured on spheres of 40k–1M vertices
and the shared scans). So cholespy is the default below :data:`LARGE_SYSTEM` unknowns, where it also factorises
as fast, and scikit-sparse above, where factorisation dominates.
"""

from __future__ import annotations

import logging
import time
from typing import Literal, Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from arap.errors import OptionError

logger = logging.getLogger(__name__)

BackendName = Literal["sksparse", "cholespy", "scipy"]
BACKENDS: tuple[str, ...] = ("sksparse", "cholespy", "scipy")
Ordering = Literal["metis", "nesdis", "amd"]
ORDERINGS: tuple[str, ...] = ("metis", "nesdis", "amd")
DEFAULT_ORDERING: Ordering = "metis"
LARGE_SYSTEM = 250_000
"""Unknowns from which the default backend is ``sksparse`` (when installed)."""


class NotPositiveDefiniteError(RuntimeError):
    """The matrix could not be factorised as symmetric positive definite."""


class Factor(Protocol):
    """A Cholesky factor of a symmetric positive definite matrix ``A``.

    Attributes
    ----------
    backend : str
        Which backend computed it.
    timings : dict of str to float
        Seconds spent building it. ``sksparse``: ``analyse`` (fill-reducing ordering and symbolic analysis),
        ``factor`` (numeric factorisation) and ``convert`` (to the simplicial form used for solving); the other
        backends report only ``factor``.
    """

    backend: str
    timings: dict[str, float]

    def solve(self, B: np.ndarray) -> np.ndarray:
        """Solve ``A X = B`` for ``B`` of shape (n, k)."""
        ...


class _SksparseFactor:
    backend = "sksparse"

    def __init__(self, A: sp.csr_matrix, ordering: str) -> None:
        from sksparse.cholmod import CholmodError, CholmodNotPositiveDefiniteError, analyze

        # CSC of a symmetric CSR matrix with sorted indices is the same arrays: no copy of the values.
        C = sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)
        self.timings: dict[str, float] = {}
        t0 = time.perf_counter()
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
        return np.asarray(self._factor.solve_A(np.asfortranarray(B, dtype=np.float64)))


class _CholespyFactor:
    backend = "cholespy"

    def __init__(self, A: sp.csr_matrix) -> None:
        from cholespy import CholeskySolverD, MatrixType

        self.n = A.shape[0]
        t0 = time.perf_counter()
        try:
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


def default_backend(size: int) -> str:
    """The backend :func:`factorize` uses for a ``size`` × ``size`` matrix when none is named.

    Parameters
    ----------
    size : int
        Number of unknowns.

    Returns
    -------
    str
        ``sksparse`` from :data:`LARGE_SYSTEM` unknowns on if installed, else ``cholespy`` if installed, else the
        first available.
    """
    found = available_backends()
    if size >= LARGE_SYSTEM and "sksparse" in found:
        return "sksparse"
    return "cholespy" if "cholespy" in found else found[0]


def factorize(A: sp.csr_matrix | sp.csc_matrix | sp.coo_matrix, backend: str | None = None,
              ordering: str = DEFAULT_ORDERING) -> Factor:
    """Cholesky-factorise a symmetric positive definite sparse matrix.

    Parameters
    ----------
    A : (k, k) sparse matrix
        Symmetric positive definite.
    backend : {"sksparse", "cholespy", "scipy"} or None
        None: :func:`default_backend` for the matrix's size.
    ordering : {"metis", "nesdis", "amd"}
        Fill-reducing ordering for ``sksparse``: METIS' nested dissection (the default: on a 1M-vertex sphere about
        1.6× less fill than AMD and a quarter faster to compute than ``nesdis``), CHOLMOD's own nested dissection
        (METIS bisections, constrained minimum degree inside; what cholespy uses), or approximate minimum degree
        (fastest to compute, most fill). The other backends choose their own.

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
        factor: Factor = _SksparseFactor(A, ordering)
    elif name == "cholespy":
        factor = _CholespyFactor(A)
    else:
        factor = _ScipyFactor(A)
    logger.debug("factorised %d×%d matrix with %s in %s", A.shape[0], A.shape[0], name, factor.timings)
    return factor
