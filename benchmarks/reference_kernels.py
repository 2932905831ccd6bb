"""Cell-by-cell kernels of the local step, the rotation fit and the right-hand side: the reference for the batched
kernels of the package (the tests check that both agree; ``benchmarks/bench_armadillo.py`` times one against the
other).

These are the straightforward per-cell loops (one covariance, one scalar rotation fit
(:func:`arap.method.horn.rotation_from_covariance`), one energy per cell; one gathered row per vertex), parallel over
cells with numba's current thread count. :mod:`arap.method.local_step` computes the same quantities in blocks of cells
with SIMD rotations; tests check that both agree, and benchmarks time one against the other.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from arap.kernels.parallel import kernel_lock
from arap.method.cells import Cells, RhsGather
from arap.method.horn import best_rotation, rotation_from_covariance


@nb.njit(cache=True, parallel=True, nogil=True)
def _local_kernel(cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    for t in nb.prange(cell_ids.shape[0]):
        c = cell_ids[t]
        s00 = s01 = s02 = s10 = s11 = s12 = s20 = s21 = s22 = 0.0
        cur = 0.0
        for k in range(ptr[c], ptr[c + 1]):
            ia = a[k]
            ib = b[k]
            d0 = U[ia, 0] - U[ib, 0]
            d1 = U[ia, 1] - U[ib, 1]
            d2 = U[ia, 2] - U[ib, 2]
            cur += w[k] * (d0 * d0 + d1 * d1 + d2 * d2)
            x0 = we[k, 0]
            x1 = we[k, 1]
            x2 = we[k, 2]
            s00 += x0 * d0
            s01 += x0 * d1
            s02 += x0 * d2
            s10 += x1 * d0
            s11 += x1 * d1
            s12 += x1 * d2
            s20 += x2 * d0
            s21 += x2 * d1
            s22 += x2 * d2
        Rc = R[c]
        lower = (Rc[0, 0] * s00 + Rc[0, 1] * s10 + Rc[0, 2] * s20 + Rc[1, 0] * s01 + Rc[1, 1] * s11
                 + Rc[1, 2] * s21 + Rc[2, 0] * s02 + Rc[2, 1] * s12 + Rc[2, 2] * s22)
        if not (lower > -np.inf and lower < np.inf):
            lower = -np.inf
        tr = rotation_from_covariance(s00, s01, s02, s10, s11, s12, s20, s21, s22, lower, Rc)
        E[c] = cur + rest_sq[c] - 2.0 * tr


@nb.njit(cache=True, parallel=True, nogil=True)
def _rhs_kernel(ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    for r in nb.prange(ptr.shape[0] - 1):
        b0 = 0.0
        b1 = 0.0
        b2 = 0.0
        for k in range(ptr[r], ptr[r + 1]):
            c = cell[k]
            g0 = g[k, 0]
            g1 = g[k, 1]
            g2 = g[k, 2]
            b0 += R[c, 0, 0] * g0 + R[c, 0, 1] * g1 + R[c, 0, 2] * g2
            b1 += R[c, 1, 0] * g0 + R[c, 1, 1] * g1 + R[c, 1, 2] * g2
            b2 += R[c, 2, 0] * g0 + R[c, 2, 1] * g1 + R[c, 2, 2] * g2
        out[r, 0] = b0 - const[r, 0]
        out[r, 1] = b1 - const[r, 1]
        out[r, 2] = b2 - const[r, 2]


def local_step_reference(cells: Cells, cell_ids: np.ndarray, U: np.ndarray, R: np.ndarray, E: np.ndarray) -> None:
    """Cell-by-cell version of :func:`arap.method.local_step.local_step` (same arguments, nothing returned)."""
    with kernel_lock:
        _local_kernel(cell_ids, cells.ptr, cells.a, cells.b, cells.w, cells.we, cells.rest_sq, U, R, E)


def assemble_rhs_reference(gather: RhsGather, R: np.ndarray, const: np.ndarray, out: np.ndarray) -> None:
    """Row-by-row version of :func:`arap.method.local_step.assemble_rhs` (same arguments)."""
    with kernel_lock:
        _rhs_kernel(gather.ptr, gather.cell, gather.g, R, const, out)


@nb.njit(cache=True, nogil=True)
def fit_rotations_scalar(S: np.ndarray, R: np.ndarray) -> None:  # pragma: no cover - compiled
    """Cell-by-cell :func:`arap.method.horn.best_rotation` of a (k, 3, 3) stack into ``R`` (the reference of the
    blocks)."""
    for i in range(S.shape[0]):
        best_rotation(S[i], R[i])


def fit_rotations_svd(S: np.ndarray) -> np.ndarray:
    """Best-fit rotations by ``numpy.linalg.svd``: the reference for
    :func:`arap.method.rotations.rotations_from_covariances`.

    ``S = U Σ Vᵀ``, ``R = V Uᵀ``; where ``det R < 0`` the column of ``U`` of the smallest singular value is negated.

    Parameters
    ----------
    S : (k, 3, 3) float array

    Returns
    -------
    (k, 3, 3) float64 array
    """
    S = np.asarray(S, dtype=np.float64)
    U, _, Vt = np.linalg.svd(S)
    R = np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2)
    flip = np.linalg.det(R) < 0
    if np.any(flip):
        U = U.copy()
        U[flip, :, 2] *= -1.0
        R[flip] = np.swapaxes(Vt[flip], 1, 2) @ np.swapaxes(U[flip], 1, 2)
    return R
