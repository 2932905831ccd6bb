"""Local step: cell covariances ``S_c = Σ w e e'ᵀ`` from edge vectors, their best-fit rotations and cell energies.

Covariances are built from rest and deformed **edge vectors** ``e = p_a − p_b`` and ``e' = p'_a − p'_b`` (never from
absolute positions), so the fitted rotation is translation invariant and the local step cannot raise the energy.

The kernels walk the cells in blocks of :data:`arap.method.rotations.BLOCK`: the covariances of a block are gathered
cell by cell into a structure-of-arrays scratch, the rotations of the whole block are fitted in SIMD lanes
(:func:`arap.method.rotations.rotations_block`), and rotations and energies are written back. Blocks are grouped in
chunks of :data:`CHUNK` blocks, the unit of parallel work, and energies are summed per chunk and then over chunks in
order, so the thread count never changes a result. Each kernel is compiled twice, serial and parallel;
:data:`arap.kernels.parallel.policy` picks one per call from the work size (and the measured times).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp

from arap.kernels.parallel import policy
from arap.method.cells import Cells, RhsGather
from arap.method.planar import planar_local_parallel, planar_local_serial
from arap.method.rotations import BLOCK, ROW_TRACE, SCRATCH_ROWS, put_covariance, rotations_block, take_rotation
from arap.sparse._csr import row_times

CHUNK = 8
"""Blocks per unit of parallel work (``CHUNK * BLOCK`` cells)."""


@nb.njit(cache=True, nogil=True, inline="always")
def cell_covariance(c, ptr, a, b, w, we, U):  # pragma: no cover - compiled
    """Covariance ``S_c = Σ w e e'ᵀ`` of cell ``c`` (9 values, row-major) and ``Σ w ‖e'‖²`` over its terms."""
    s00 = s01 = s02 = s10 = s11 = s12 = s20 = s21 = s22 = 0.0
    cur = 0.0
    for k in range(np.uint64(ptr[c]), np.uint64(ptr[c + np.uint64(1)])):
        ia = np.uint64(a[k])  # unsigned indices spare numba's negative-index fix-ups
        ib = np.uint64(b[k])
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
    return (s00, s01, s02, s10, s11, s12, s20, s21, s22), cur


@nb.njit(cache=True, nogil=True)
def _local_block(lo, hi, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E, sc, flag):  # pragma: no cover - compiled
    """Cells ``cell_ids[lo:hi]`` (at most BLOCK): rotations into ``R``, energies into ``E``; returns their sum."""
    m = hi - lo
    for t in range(m):
        c = np.uint64(cell_ids[lo + t])
        s, cur = cell_covariance(c, ptr, a, b, w, we, U)
        put_covariance(sc, t, s, R, c)
        E[c] = cur + rest_sq[c]
    rotations_block(sc, m, flag)
    total = 0.0
    for t in range(m):
        c = np.uint64(cell_ids[lo + t])
        take_rotation(sc, t, R, c)
        e = E[c] - 2.0 * sc[ROW_TRACE * BLOCK + t]
        E[c] = e
        total += e
    return total


@nb.njit(cache=True, nogil=True)
def _local_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    k = cell_ids.shape[0]
    sc = np.empty(SCRATCH_ROWS * BLOCK)
    flag = np.empty(BLOCK, np.int64)
    total = 0.0
    for lo in range(ch * CHUNK * BLOCK, min(k, (ch + 1) * CHUNK * BLOCK), BLOCK):
        total += _local_block(lo, min(k, lo + BLOCK), cell_ids, ptr, a, b, w, we, rest_sq, U, R, E, sc, flag)
    return total


@nb.njit(cache=True, nogil=True)
def _local_serial(cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    n_chunks = (cell_ids.shape[0] + CHUNK * BLOCK - 1) // (CHUNK * BLOCK)
    total = 0.0
    for ch in range(n_chunks):
        total += _local_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E)
    return total


@nb.njit(cache=True, nogil=True, parallel=True)
def _local_parallel(cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    n_chunks = (cell_ids.shape[0] + CHUNK * BLOCK - 1) // (CHUNK * BLOCK)
    part = np.empty(n_chunks)
    for ch in nb.prange(n_chunks):
        part[ch] = _local_chunk(ch, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E)
    total = 0.0
    for ch in range(n_chunks):
        total += part[ch]
    return total


@nb.njit(cache=True, nogil=True)
def _rhs_rows(r0, r1, ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    for r in range(r0, r1):
        b0 = 0.0
        b1 = 0.0
        b2 = 0.0
        for k in range(np.uint64(ptr[r]), np.uint64(ptr[r + 1])):
            c = np.uint64(cell[k])  # unsigned indices spare numba's negative-index fix-ups
            g0 = g[k, 0]
            g1 = g[k, 1]
            g2 = g[k, 2]
            b0 += R[c, 0, 0] * g0 + R[c, 0, 1] * g1 + R[c, 0, 2] * g2
            b1 += R[c, 1, 0] * g0 + R[c, 1, 1] * g1 + R[c, 1, 2] * g2
            b2 += R[c, 2, 0] * g0 + R[c, 2, 1] * g1 + R[c, 2, 2] * g2
        out[r, 0] = b0 - const[r, 0]
        out[r, 1] = b1 - const[r, 1]
        out[r, 2] = b2 - const[r, 2]


@nb.njit(cache=True, nogil=True)
def _rhs_serial(ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    _rhs_rows(0, ptr.shape[0] - 1, ptr, cell, g, R, const, out)


@nb.njit(cache=True, nogil=True, parallel=True)
def _rhs_parallel(ptr, cell, g, R, const, out):  # pragma: no cover - compiled
    rows = ptr.shape[0] - 1
    step = CHUNK * BLOCK
    for ch in nb.prange((rows + step - 1) // step):
        _rhs_rows(ch * step, min(rows, (ch + 1) * step), ptr, cell, g, R, const, out)


@nb.njit(cache=True, nogil=True)
def _rhs_gradient_rows(r0, r1, ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad):  # pragma: no cover
    _rhs_rows(r0, r1, ptr, cell, g, R, const, out)
    for r in range(r0, r1):
        g0, g1, g2 = row_times(a_ptr[r], a_ptr[r + 1], a_idx, a_val, x, -out[r, 0], -out[r, 1], -out[r, 2])
        grad[r, 0] = g0
        grad[r, 1] = g1
        grad[r, 2] = g2


@nb.njit(cache=True, nogil=True)
def _rhs_gradient_serial(ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad):  # pragma: no cover
    _rhs_gradient_rows(0, ptr.shape[0] - 1, ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad)


@nb.njit(cache=True, nogil=True, parallel=True)
def _rhs_gradient_parallel(ptr, cell, g, R, const, a_ptr, a_idx, a_val, x, out, grad):  # pragma: no cover
    rows = ptr.shape[0] - 1
    step = CHUNK * BLOCK
    for ch in nb.prange((rows + step - 1) // step):
        _rhs_gradient_rows(ch * step, min(rows, (ch + 1) * step), ptr, cell, g, R, const, a_ptr, a_idx, a_val, x,
                           out, grad)


def _local_work(cells: Cells, cell_ids: np.ndarray) -> int:
    """Edge terms in ``cell_ids`` (estimated from the mean cell size)."""
    return len(cell_ids) * len(cells.a) // max(cells.n_cells, 1)


def local_step(cells: Cells, cell_ids: np.ndarray, U: np.ndarray, R: np.ndarray, E: np.ndarray) -> float:
    """Fit the rotation of each listed cell to the deformed positions and evaluate its energy, in place.

    Parameters
    ----------
    cells : Cells
    cell_ids : (k,) int64 array
        Cells to process.
    U : (n, 3) float64 array
        Deformed positions.
    R : (c, 3, 3) float64 array
        In: the previous rotations (any values; finite ones close to the optimum speed up the fit). Out: ``R[c]``
        maximises ``tr(R S_c)`` over rotations (about ``z`` for planar cells).
    E : (c,) float64 array
        Output: ``E[c] = Σ w ‖e' − R_c e‖²``, the cell's energy with its optimal rotation.

    Returns
    -------
    float
        ``Σ E[c]`` over ``cell_ids``, summed in an order that does not depend on the thread count.
    """
    args = (cell_ids, cells.ptr, cells.a, cells.b, cells.w, cells.we, cells.rest_sq, U, R, E)
    if cells.planar:  # rotations about z (arap.method.planar)
        return float(policy.run("local", _local_work(cells, cell_ids), lambda: planar_local_serial(*args),
                                lambda: planar_local_parallel(*args)))
    return float(policy.run("local", _local_work(cells, cell_ids), lambda: _local_serial(*args),
                            lambda: _local_parallel(*args)))


def covariances(cells: Cells, U: np.ndarray) -> np.ndarray:
    """Covariance matrices of all cells (vectorised NumPy; for inspection and tests).

    Parameters
    ----------
    cells : Cells
    U : (n, 3) float array

    Returns
    -------
    (n, 3, 3) float64 array
        ``S_c = Σ_terms w (p_a − p_b)(p'_a − p'_b)ᵀ``.
    """
    d = U[cells.a] - U[cells.b]
    outer = cells.we[:, :, None] * d[:, None, :]
    S = np.zeros((cells.n_cells, 3, 3))
    np.add.at(S, cells.cell_of_term(), outer)
    return S


def assemble_rhs(gather: RhsGather, R: np.ndarray, const: np.ndarray, out: np.ndarray) -> None:
    """Right-hand side of the global step, ``out[r] = Σ_k R[cell_k] g_k − const[r]``, in place.

    Parameters
    ----------
    gather : RhsGather
    R : (n, 3, 3) float64 array
    const : (r, 3) float64 array
        Contribution of the constrained vertices (``L_fc X_c``).
    out : (r, 3) float64 array
    """
    args = (gather.ptr, gather.cell, gather.g, R, const, out)
    policy.run("rhs", len(gather.cell), lambda: _rhs_serial(*args), lambda: _rhs_parallel(*args))


def assemble_rhs_and_gradient(gather: RhsGather, R: np.ndarray, const: np.ndarray, A: sp.csr_matrix,
                              x: np.ndarray, out: np.ndarray, grad: np.ndarray) -> None:
    """:func:`assemble_rhs` and the residual ``grad = A x − out`` of the global step at ``x``, row by row in one pass.

    With the rotations fitted to ``x``, ``2 grad`` is the energy's gradient in the free positions (see
    :mod:`arap.solve.lbfgs`).

    Parameters
    ----------
    gather, R, const, out
        As in :func:`assemble_rhs`.
    A : (r, r) CSR matrix
        The reduced system matrix (int32 or int64 indices), rows in the order of ``gather``'s.
    x : (r, 3) C-contiguous float64 array
    grad : (r, 3) float64 array
        Output.
    """
    args = (gather.ptr, gather.cell, gather.g, R, const, A.indptr, A.indices, A.data, x, out, grad)
    policy.run("rhs+gradient", len(gather.cell) + A.nnz, lambda: _rhs_gradient_serial(*args),
               lambda: _rhs_gradient_parallel(*args))
