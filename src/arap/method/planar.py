"""The local step in the plane: each cell's best rotation about ``z``, in closed form.

For a planar mesh (``z = 0`` at rest and in every target) the rotations are 2×2. With the cell covariance
``S = Σ w e e'ᵀ``, ``tr(R S)`` for ``R = [[c, −s], [s, c]]`` is ``c (S₀₀ + S₁₁) + s (S₀₁ − S₁₀)``, largest at the angle
of the vector ``(S₀₀ + S₁₁, S₀₁ − S₁₀)``, where it equals that vector's length. A reflection is never among the
candidates, so a triangle cannot flip over in the plane (in space, a reflection of the plane is a half turn about an
axis in it, and the 3×3 fit would take it).

The kernels follow :mod:`arap.method.local_step`'s layout (chunks of cells, energies summed per chunk and then in
order, so the thread count never changes a result) and write 3×3 rotations (``z`` row and column of the identity)
so that everything downstream reads them as any other rotation. They read only the first two coordinates of the
positions, so they take the solver's (n, 3) positions (``z = 0``) and the (n, 2) ones of its iterations alike: a
planar solve carries two columns through the local step, the right-hand side (:func:`planar_rhs`,
:func:`planar_rhs_and_gradient`), the back-substitution and L-BFGS's vectors, and no work is spent on ``z``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)
from arap.kernels.parallel import policy
from arap.method.cells import RhsGather
from arap.sparse._csr import row_times_2

__all__ = ["planar_covariance", "planar_local_parallel", "planar_local_serial", "planar_rhs",
           "planar_rhs_and_gradient", "planar_rotations", "put_planar_rotation"]

_CHUNK = 512
"""Cells per unit of parallel work."""


@nb.njit(cache=True, nogil=True, inline="always")
def planar_covariance(c, ptr, a, b, w, we, U):  # pragma: no cover - compiled
    """The planar part of cell ``c``'s covariance as ``(p, q) = (S₀₀ + S₁₁, S₀₁ − S₁₀)`` and ``Σ w ‖e'‖²``, from the
    first two columns of ``U`` ((n, 2), or (n, 3) with ``z = 0``); inlined into the local steps that fit rotations
    (:func:`planar_local_serial`) and similarities (:func:`arap.puppet.blend.similarity_step`)."""
    s00 = s01 = s10 = s11 = 0.0
    cur = 0.0
    for k in range(ptr[c], ptr[c + 1]):
        d0 = U[a[k], 0] - U[b[k], 0]
        d1 = U[a[k], 1] - U[b[k], 1]
        cur += w[k] * (d0 * d0 + d1 * d1)
        x0 = we[k, 0]
        x1 = we[k, 1]
        s00 += x0 * d0
        s01 += x0 * d1
        s10 += x1 * d0
        s11 += x1 * d1
    return s00 + s11, s01 - s10, cur


@nb.njit(cache=True, nogil=True, inline="always")
def put_planar_rotation(R, c, cs, sn):  # pragma: no cover - compiled
    """``R[c] = [[cs, −sn, 0], [sn, cs, 0], [0, 0, 1]]``."""
    R[c, 0, 0] = cs
    R[c, 0, 1] = -sn
    R[c, 0, 2] = 0.0
    R[c, 1, 0] = sn
    R[c, 1, 1] = cs
    R[c, 1, 2] = 0.0
    R[c, 2, 0] = 0.0
    R[c, 2, 1] = 0.0
    R[c, 2, 2] = 1.0


@nb.njit(cache=True, nogil=True)
def _planar_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    total = 0.0
    for t in range(ch * _CHUNK, min(cell_ids.shape[0], (ch + 1) * _CHUNK)):
        c = cell_ids[t]
        p, q, cur = planar_covariance(c, ptr, a, b, w, we, U)
        r = math.sqrt(p * p + q * q)
        cs = 1.0
        sn = 0.0
        if r > 0.0:
            cs = p / r
            sn = q / r
        put_planar_rotation(R, c, cs, sn)
        e = cur + rest_sq[c] - 2.0 * r
        E[c] = e
        total += e
    return total


@nb.njit(cache=True, nogil=True)
def planar_local_serial(cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    """Rotations about ``z`` and energies of the cells ``cell_ids``, in place, for positions ``U`` (n, 2) or (n, 3)
    (its ``z`` column is not read); the energies' sum."""
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


@nb.njit(cache=True, nogil=True)
def _rhs_rows(r0, r1, ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    # arap.method.local_step's right-hand side rows, in the plane: the rotations' 2×2 blocks, two columns.
    for r in range(r0, r1):
        b0 = 0.0
        b1 = 0.0
        for k in range(np.uint64(ptr[r]), np.uint64(ptr[r + 1])):
            c = np.uint64(cell[k])  # unsigned indices spare numba's negative-index fix-ups
            g0 = g[k, 0]
            g1 = g[k, 1]
            b0 += R[c, 0, 0] * g0 + R[c, 0, 1] * g1
            b1 += R[c, 1, 0] * g0 + R[c, 1, 1] * g1
        out[r, 0] = b0 - const[r, 0]
        out[r, 1] = b1 - const[r, 1]


_RHS_ROWS = 4096
"""Rows per unit of parallel work of the right-hand side."""


@nb.njit(cache=True, nogil=True)
def _rhs_serial(ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    _rhs_rows(0, ptr.shape[0] - 1, ptr, cell, g, R, const, out)


@nb.njit(cache=True, nogil=True, parallel=True)
def _rhs_parallel(ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    rows = ptr.shape[0] - 1
    for ch in nb.prange((rows + _RHS_ROWS - 1) // _RHS_ROWS):
        _rhs_rows(ch * _RHS_ROWS, min(rows, (ch + 1) * _RHS_ROWS), ptr, cell, g, R, const, out)


@nb.njit(cache=True, nogil=True)
def _rhs_gradient_rows(r0, r1, ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad):  # pragma: no cover
    _rhs_rows(r0, r1, ptr, cell, g, R, const, out)
    for r in range(r0, r1):
        g0, g1 = row_times_2(a_ptr[r], a_ptr[r + 1], a_idx, a_val, x, -out[r, 0], -out[r, 1])
        grad[r, 0] = g0
        grad[r, 1] = g1


@nb.njit(cache=True, nogil=True)
def _rhs_gradient_serial(ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad):  # pragma: no cover
    _rhs_gradient_rows(0, ptr.shape[0] - 1, ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad)


@nb.njit(cache=True, nogil=True, parallel=True)
def _rhs_gradient_parallel(ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad):  # pragma: no cover
    rows = ptr.shape[0] - 1
    for ch in nb.prange((rows + _RHS_ROWS - 1) // _RHS_ROWS):
        _rhs_gradient_rows(ch * _RHS_ROWS, min(rows, (ch + 1) * _RHS_ROWS), ptr, cell, g, R, const, a_ptr, a_idx,
                           a_val, x, out, grad)


def planar_rhs(gather: RhsGather, R: NDArray[np.float64], const: NDArray[np.float64],
               out: NDArray[np.float64]) -> None:
    """The global step's right-hand side in the plane, ``out[r] = Σ_k R[cell_k]₂ₓ₂ g_k − const[r]``, in place
    (:func:`arap.method.local_step.assemble_rhs` on the first two coordinates: ``z`` is 0 in every term).

    Parameters
    ----------
    gather : RhsGather
    R : (c, 3, 3) float64 array
        Rotations about ``z`` (only their 2×2 blocks are read).
    const : (r, 2) float64 array
    out : (r, 2) float64 array
    """
    args = (gather.ptr, gather.cell, gather.g, R, const, out)
    policy.run("rhs", len(gather.cell), lambda: _rhs_serial(*args), lambda: _rhs_parallel(*args))


def planar_rhs_and_gradient(gather: RhsGather, R: NDArray[np.float64], const: NDArray[np.float64],
                            A_ptr: NDArray[np.integer], A_idx: NDArray[np.integer], A_val: NDArray[np.float64],
                            x: NDArray[np.float64], out: NDArray[np.float64], grad: NDArray[np.float64]) -> None:
    """:func:`planar_rhs` and the residual ``grad = A x − out`` at ``x`` (r, 2), row by row in one pass
    (:func:`arap.method.local_step.assemble_rhs_and_gradient` in the plane; ``A`` given by its CSR arrays)."""
    args = (gather.ptr, gather.cell, gather.g, R, const, A_ptr, A_idx, A_val, x, out, grad)
    policy.run("rhs+gradient", len(gather.cell) + len(A_val), lambda: _rhs_gradient_serial(*args),
               lambda: _rhs_gradient_parallel(*args))


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
