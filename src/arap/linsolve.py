"""Sparse Cholesky factorisation of the reduced global-step matrix, factorised once and reused.

Backends, fastest first: CHOLMOD through ``cholespy`` (a self-contained wheel), CHOLMOD through ``scikit-sparse``
(if installed), and SciPy's SuperLU in symmetric mode as the always-available fallback.
"""

from __future__ import annotations

import logging
from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

logger = logging.getLogger(__name__)

BACKENDS: tuple[str, ...] = ("cholespy", "sksparse", "scipy")


class NotPositiveDefiniteError(RuntimeError):
    """The matrix could not be factorised as symmetric positive definite."""


class Factor(Protocol):
    backend: str

    def solve(self, B: np.ndarray) -> np.ndarray:
        """Solve ``A X = B`` for ``B`` of shape (n, k)."""
        ...


class _CholespyFactor:
    backend = "cholespy"

    def __init__(self, A: sp.csr_matrix) -> None:
        from cholespy import CholeskySolverD, MatrixType

        self.n = A.shape[0]
        try:
            self._solver = CholeskySolverD(
                self.n, A.indptr.astype(np.int32), A.indices.astype(np.int32),
                np.ascontiguousarray(A.data, dtype=np.float64), MatrixType.CSR,
            )
        except (ValueError, RuntimeError) as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = np.ascontiguousarray(B, dtype=np.float64)
        X = np.empty_like(B)
        self._solver.solve(B, X)
        return X


class _SksparseFactor:
    backend = "sksparse"

    def __init__(self, A: sp.csr_matrix) -> None:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        try:
            self._factor = cholesky(A.tocsc(), ordering_method="amd")
        except CholmodNotPositiveDefiniteError as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc

    def solve(self, B: np.ndarray) -> np.ndarray:
        return np.asarray(self._factor(B))


class _ScipyFactor:
    backend = "scipy"

    def __init__(self, A: sp.csr_matrix) -> None:
        try:
            self._lu = spla.splu(
                A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True}
            )
        except RuntimeError as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc
        U_diag = self._lu.U.diagonal()
        if np.any(U_diag <= 0) or not np.all(np.isfinite(U_diag)):
            raise NotPositiveDefiniteError("matrix is not positive definite (non-positive pivot)")

    def solve(self, B: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(B, dtype=np.float64))


def available_backends() -> list[str]:
    """Backends importable in this environment, fastest first."""
    found = []
    for name, module in (("cholespy", "cholespy"), ("sksparse", "sksparse.cholmod")):
        try:
            __import__(module)
        except ImportError:
            continue
        found.append(name)
    found.append("scipy")
    return found


def factorize(A: sp.spmatrix, backend: str | None = None) -> Factor:
    """Cholesky-factorise a symmetric positive definite sparse matrix.

    Parameters
    ----------
    A : (k, k) sparse matrix
        Symmetric positive definite.
    backend : {"cholespy", "sksparse", "scipy"} or None
        None picks the fastest available.

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
    A = sp.csr_matrix(A)
    A.sort_indices()
    name = backend or available_backends()[0]
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}; expected one of {BACKENDS}")
    if name == "cholespy":
        factor: Factor = _CholespyFactor(A)
    elif name == "sksparse":
        factor = _SksparseFactor(A)
    else:
        factor = _ScipyFactor(A)
    logger.debug("factorised %d×%d matrix with %s", A.shape[0], A.shape[0], name)
    return factor
