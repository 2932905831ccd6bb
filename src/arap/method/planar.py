"""The local step in the plane: each cell's best rotation about ``z``, in closed form.

For a planar mesh (``z = 0`` at rest and in every target) the rotations are 2×2. With the cell covariance
``S = Σ w e e'ᵀ``, ``tr(R S)`` for ``R = [[c, −s], [s, c]]`` is ``c (S₀₀ + S₁₁) + s (S₀₁ − S₁₀)``, largest at the angle
of the vector ``(S₀₀ + S₁₁, S₀₁ − S₁₀)``, where it equals that vector's length. A reflection is never among the
candidates, so a triangle cannot flip over in the plane (in space, a reflection of the plane is a half turn about an
axis in it, and the 3×3 fit would take it).

The kernels follow :mod:`arap.method.local_step`'s layout (chunks of cells, energies summed per chunk and then in
order, so the thread count never changes a result) and write 3×3 rotations (``z`` row and column of the identity)
so that everything downstream reads them as any other rotation.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)

__all__ = ["planar_local_parallel", "planar_local_serial", "planar_rotations"]

_CHUNK = 512
"""Cells per unit of parallel work."""


@nb.njit(cache=True, nogil=True)
def _planar_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    total = 0.0
    for t in range(ch * _CHUNK, min(cell_ids.shape[0], (ch + 1) * _CHUNK)):
        c = cell_ids[t]
        s00 = s01 = s10 = s11 = 0.0
        cur = 0.0
        for k in range(ptr[c], ptr[c + 1]):
            d0 = U[a[k], 0] - U[b[k], 0]
            d1 = U[a[k], 1] - U[b[k], 1]
            d2 = U[a[k], 2] - U[b[k], 2]
            cur += w[k] * (d0 * d0 + d1 * d1 + d2 * d2)
            x0 = we[k, 0]
            x1 = we[k, 1]
            s00 += x0 * d0
            s01 += x0 * d1
            s10 += x1 * d0
            s11 += x1 * d1
        p = s00 + s11
        q = s01 - s10
        r = math.sqrt(p * p + q * q)
        cs = 1.0
        sn = 0.0
        if r > 0.0:
            cs = p / r
            sn = q / r
        R[c, 0, 0] = cs
        R[c, 0, 1] = -sn
        R[c, 0, 2] = 0.0
        R[c, 1, 0] = sn
        R[c, 1, 1] = cs
        R[c, 1, 2] = 0.0
        R[c, 2, 0] = 0.0
        R[c, 2, 1] = 0.0
        R[c, 2, 2] = 1.0
        e = cur + rest_sq[c] - 2.0 * r
        E[c] = e
        total += e
    return total


@nb.njit(cache=True, nogil=True)
def planar_local_serial(cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    """Rotations about ``z`` and energies of the cells ``cell_ids``, in place; the energies' sum."""
    total = 0.0
    for ch in range((cell_ids.shape[0] + _CHUNK - 1) // _CHUNK):
        total += _planar_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E)
    return total


@nb.njit(cache=True, nogil=True, parallel=True)
def planar_local_parallel(cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    """:func:`planar_local_serial` over threads (the same sum, bit for bit)."""
    n_chunks = (cell_ids.shape[0] + _CHUNK - 1) // _CHUNK
    part = np.empty(n_chunks)
    for ch in nb.prange(n_chunks):
        part[ch] = _planar_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E)
    total = 0.0
    for ch in range(n_chunks):
        total += part[ch]
    return total


def planar_rotations(S: NDArray[np.float64]) -> NDArray[np.float64]:
    """Best rotations about ``z`` of a stack of covariances, as 3×3 matrices.

    Parameters
    ----------
    S : (k, 3, 3) float array
        Covariances ``Σ w e e'ᵀ`` of vectors in the plane ``z = 0``.

    Returns
    -------
    (k, 3, 3) float64 array
        ``R[i]`` maximises ``tr(R S[i])`` over rotations about ``z`` (the identity where ``S[i]``'s planar part
        gives no direction).

    Example
    -------
    >>> S = np.zeros((1, 3, 3)); S[0, :2, :2] = [[0.0, 1.0], [-1.0, 0.0]]   # a quarter turn
    >>> planar_rotations(S)[0].round(12).tolist()
    [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    """
    S = np.asarray(S, dtype=np.float64)
    p = S[:, 0, 0] + S[:, 1, 1]
    q = S[:, 0, 1] - S[:, 1, 0]
    r = np.hypot(p, q)
    ok = r > 0
    cs = np.where(ok, p / np.where(ok, r, 1.0), 1.0)
    sn = np.where(ok, q / np.where(ok, r, 1.0), 0.0)
    R = np.zeros((len(S), 3, 3))
    R[:, 0, 0] = cs
    R[:, 0, 1] = -sn
    R[:, 1, 0] = sn
    R[:, 1, 1] = cs
    R[:, 2, 2] = 1.0
    return R
