"""A preconditioned step for the coupled rotations of smooth-rotation ARAP (:mod:`arap.method.smooth`).

At fixed positions, the rotations of SR-ARAP minimise

    f(R) = Σ_i (d_i − 2 tr(R_i S_i))  +  αA Σ_i Σ_j w⁺_ij ‖R_i − R_j‖²_F

(``S_i`` the cell's covariance, ``d_i`` the constant of its data energy). On dense meshes the rotation term outweighs
the data term by far (it grows with the number of vertices, see :mod:`arap.method.smooth`), and block-coordinate sweeps,
each moving a rotation towards its neighbours' only, spread a change across the mesh like a diffusion: on the armadillo
(43k vertices) 400 sweeps lowered the rotation energy's gap to its minimum by a third.

This step moves all rotations at once, along a direction preconditioned by the dominant part of ``f``'s Hessian.
Write ``R_i ← exp([ω_i]×) R_i``. The gradient of ``f`` in ``ω_i`` is ``−2 vee(R_i M_i)``, with
``M_i = S_i + 2αA Σ_j w⁺_ij R_jᵀ`` (the matrix a sweep fits ``R_i`` to) and ``vee(P) = (P₁₂ − P₂₁, P₂₀ − P₀₂,
P₀₁ − P₁₀)``. Its Hessian is, for neighbouring rotations that nearly agree, ``8αA L⁺ ⊗ I₃`` from the rotation term
(``L⁺`` the graph Laplacian with the weights ``w⁺_ij``) plus the blocks ``2 (tr(P_i) I − sym P_i)``, ``P_i = R_i S_i``,
from the data term. The preconditioner

    K = 8αA L⁺ + diag(4/3 · Σ_j w_ij ‖e_ij‖²)

keeps the first exactly and replaces each data block by its isotropic value at the rest pose (``P_i = S_i`` there,
and ``tr S_i = Σ_j w_ij ‖e_ij‖²``; clamped to stay positive where negative cotangent weights make it small). ``K``
depends on the rest shape alone: it is factorised once, with the solver. A step solves ``K ω = −∇f`` (three
right-hand sides), rotates every cell by ``exp([ω_i]×)`` and keeps the result only if ``f`` did not rise, halving the
step otherwise. On the armadillo, from the rotations of a solve in progress, four such steps (each followed by one
sweep) brought the gap from 3.6e-2 to 1.4e-9 of the rotation energy, and eight to round-off.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.kernels.parallel import policy
from arap.method.cells import Cells
from arap.method.local_step import CHUNK
from arap.method.rotations import BLOCK
from arap.sparse.linsolve import Factor, factorize

__all__ = ["HALVINGS", "RotationStep"]

HALVINGS = 3
"""Step lengths tried after the full step (halving each time) before the step is abandoned (the local step then
sweeps instead: see :meth:`arap.method.smooth.SmoothRotations.relax`)."""

#: Floor of the data-term diagonal of the preconditioner, relative to its mean magnitude.
_FLOOR = 1e-3


ZERO9 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@nb.njit(cache=True, nogil=True, inline="always")
def add_transposed(m, f, R, j):  # pragma: no cover - compiled
    """``m + f R_jᵀ`` for a 3×3 matrix ``m`` given as 9 values, row-major (entry (i, l) gets ``f R_j[l, i]``)."""
    return (m[0] + f * R[j, 0, 0], m[1] + f * R[j, 1, 0], m[2] + f * R[j, 2, 0],
            m[3] + f * R[j, 0, 1], m[4] + f * R[j, 1, 1], m[5] + f * R[j, 2, 1],
            m[6] + f * R[j, 0, 2], m[7] + f * R[j, 1, 2], m[8] + f * R[j, 2, 2])


@nb.njit(cache=True, nogil=True, inline="always")
def plus_scaled(S, p, k, m):  # pragma: no cover - compiled
    """``S[p] + k m``, 9 values row-major: the matrix ``M = S_c + 2αA Σ_j w⁺_ij R_jᵀ`` a rotation is fitted to."""
    return (S[p, 0] + k * m[0], S[p, 1] + k * m[1], S[p, 2] + k * m[2],
            S[p, 3] + k * m[3], S[p, 4] + k * m[4], S[p, 5] + k * m[5],
            S[p, 6] + k * m[6], S[p, 7] + k * m[7], S[p, 8] + k * m[8])


@nb.njit(cache=True, nogil=True, inline="always")
def rotation_gap(R, c, j):  # pragma: no cover - compiled
    """``‖R_c − R_j‖²`` (Frobenius)."""
    dist = 0.0
    for u in range(3):
        for v in range(3):
            y = R[c, u, v] - R[j, u, v]
            dist += y * y
    return dist


@nb.njit(cache=True, nogil=True, inline="always")
def trace_with(R, c, S, p):  # pragma: no cover - compiled
    """``tr(R_c S_p)`` with ``S_p`` stored row-major in ``S[p]``."""
    trace = 0.0
    for i in range(3):
        for j in range(3):
            trace += R[c, i, j] * S[p, 3 * j + i]
    return trace


@nb.njit(cache=True, nogil=True)
def _energy_rows(lo, hi, order, nptr, nidx, nq, S, d, coef, R, E, term, G, gradient):  # pragma: no cover
    """Energy of the cells at sweep positions ``lo:hi`` (``E[c]`` the data energy, ``term[c]`` the cell's rotation
    term ``coef Σ_j q ‖R_c − R_j‖²``); with ``gradient``, ``G[c] = −2 vee(R_c M_c)``. Returns the sum of both."""
    total = 0.0
    k2 = 2.0 * coef
    for p in range(lo, hi):
        c = np.uint64(order[p])
        m = ZERO9
        pairs = 0.0
        for k in range(np.uint64(nptr[p]), np.uint64(nptr[p + 1])):
            j = np.uint64(nidx[k])
            f = nq[k]
            pairs += f * rotation_gap(R, c, j)
            if gradient:
                m = add_transposed(m, f, R, j)
        e = d[p] - 2.0 * trace_with(R, c, S, p)
        E[c] = e
        term[c] = coef * pairs
        total += e + coef * pairs
        if gradient:
            m = plus_scaled(S, p, k2, m)
            # P = R_c M: only its antisymmetric part is needed
            p12 = R[c, 1, 0] * m[2] + R[c, 1, 1] * m[5] + R[c, 1, 2] * m[8]
            p21 = R[c, 2, 0] * m[1] + R[c, 2, 1] * m[4] + R[c, 2, 2] * m[7]
            p20 = R[c, 2, 0] * m[0] + R[c, 2, 1] * m[3] + R[c, 2, 2] * m[6]
            p02 = R[c, 0, 0] * m[2] + R[c, 0, 1] * m[5] + R[c, 0, 2] * m[8]
            p01 = R[c, 0, 0] * m[1] + R[c, 0, 1] * m[4] + R[c, 0, 2] * m[7]
            p10 = R[c, 1, 0] * m[0] + R[c, 1, 1] * m[3] + R[c, 1, 2] * m[6]
            G[c, 0] = -2.0 * (p12 - p21)
            G[c, 1] = -2.0 * (p20 - p02)
            G[c, 2] = -2.0 * (p01 - p10)
    return total


@nb.njit(cache=True, nogil=True)
def _energy_serial(order, nptr, nidx, nq, S, d, coef, R, E, term, G, gradient):  # pragma: no cover - compiled
    # Summed chunk by chunk, as the parallel kernel sums: the thread count must not change the energy's last bits.
    n = order.shape[0]
    step = CHUNK * BLOCK
    total = 0.0
    for ch in range((n + step - 1) // step):
        total += _energy_rows(ch * step, min(n, (ch + 1) * step), order, nptr, nidx, nq, S, d, coef, R, E, term,
                              G, gradient)
    return total


@nb.njit(cache=True, nogil=True, parallel=True)
def _energy_parallel(order, nptr, nidx, nq, S, d, coef, R, E, term, G, gradient):  # pragma: no cover - compiled
    n = order.shape[0]
    step = CHUNK * BLOCK
    n_chunks = (n + step - 1) // step
    part = np.empty(n_chunks)
    for ch in nb.prange(n_chunks):
        part[ch] = _energy_rows(ch * step, min(n, (ch + 1) * step), order, nptr, nidx, nq, S, d, coef, R, E, term,
                                G, gradient)
    total = 0.0
    for ch in range(n_chunks):
        total += part[ch]
    return total


@nb.njit(cache=True, nogil=True)
def _rotate_rows(lo, hi, R0, W, t, R):  # pragma: no cover - compiled
    """``R[c] = exp([t W_c]×) R0[c]`` (Rodrigues' formula) for ``c`` in ``lo:hi``."""
    for c in range(lo, hi):
        w0 = t * W[c, 0]
        w1 = t * W[c, 1]
        w2 = t * W[c, 2]
        th2 = w0 * w0 + w1 * w1 + w2 * w2
        if th2 < 1e-12:  # Taylor series, exact to round-off
            a = 1.0 - th2 / 6.0
            b = 0.5 - th2 / 24.0
        else:
            th = np.sqrt(th2)
            a = np.sin(th) / th
            b = (1.0 - np.cos(th)) / th2
        # exp = I + a K + b K², K = [w]×, K² = w wᵀ − θ² I
        e00 = 1.0 + b * (w0 * w0 - th2)
        e11 = 1.0 + b * (w1 * w1 - th2)
        e22 = 1.0 + b * (w2 * w2 - th2)
        e01 = -a * w2 + b * w0 * w1
        e10 = a * w2 + b * w0 * w1
        e02 = a * w1 + b * w0 * w2
        e20 = -a * w1 + b * w0 * w2
        e12 = -a * w0 + b * w1 * w2
        e21 = a * w0 + b * w1 * w2
        for v in range(3):
            x0 = R0[c, 0, v]
            x1 = R0[c, 1, v]
            x2 = R0[c, 2, v]
            R[c, 0, v] = e00 * x0 + e01 * x1 + e02 * x2
            R[c, 1, v] = e10 * x0 + e11 * x1 + e12 * x2
            R[c, 2, v] = e20 * x0 + e21 * x1 + e22 * x2


@nb.njit(cache=True, nogil=True)
def _rotate_serial(R0, W, t, R):  # pragma: no cover - compiled
    _rotate_rows(0, R.shape[0], R0, W, t, R)


@nb.njit(cache=True, nogil=True, parallel=True)
def _rotate_parallel(R0, W, t, R):  # pragma: no cover - compiled
    n = R.shape[0]
    step = CHUNK * BLOCK
    for ch in nb.prange((n + step - 1) // step):
        _rotate_rows(ch * step, min(n, (ch + 1) * step), R0, W, t, R)


def preconditioner(cells: Cells, q: NDArray[np.float64], coef: float) -> sp.csr_matrix:
    """The matrix ``K = 8 coef L⁺ + diag(4/3 · Σ_j w_ij ‖e_ij‖²)`` (clamped positive), shape (n, n).

    Parameters
    ----------
    cells : Cells
        Spoke cells (cell ``i`` holds the terms ``(i, j, w_ij)``).
    q : (t,) float array
        Symmetric, non-negative pair weights of the rotation term, aligned with ``cells.w``.
    coef : float
        ``αA``.

    Example
    -------
    >>> import numpy as np
    >>> from arap.method.cells import build_cells
    >>> from arap.meshes.shapes import sphere
    >>> V, F = sphere(1)
    >>> cells = build_cells(V, F, "spokes")
    >>> K = preconditioner(cells, np.maximum(cells.w, 0.0), 0.1)
    >>> bool(abs(K - K.T).max() < 1e-15)
    True
    """
    n = len(cells.ptr) - 1
    rows = cells.cell_of_term()
    W = sp.coo_matrix((q, (rows, cells.b)), shape=(n, n)).tocsr()
    W = 0.5 * (W + W.T)  # q is symmetric; this only removes round-off
    lap = sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W
    data = 4.0 / 3.0 * np.asarray(cells.rest_sq, dtype=np.float64)
    floor = _FLOOR * float(np.abs(data).mean()) if n else 1.0
    data = np.maximum(data, floor if floor > 0 else 1.0)
    return (8.0 * coef * lap + sp.diags(data)).tocsr()


class RotationStep:
    """Preconditioned steps on the rotations of SR-ARAP at fixed positions (see the module's text).

    Parameters
    ----------
    cells : Cells
        Spoke cells.
    q : (t,) float array
        Pair weights of the rotation term, aligned with ``cells.w``.
    coef : float
        ``αA``, ``> 0``.
    order : (n,) int array
        Cell at each sweep position (the layout of the stored covariances ``S``, ``d``).
    nptr : (n + 1,) int array
        Coupled neighbours of each sweep position: ``nidx[nptr[p]:nptr[p + 1]]``, weights ``nq``.
    nidx : (k,) int array
    nq : (k,) float array
    """

    def __init__(self, cells: Cells, q: NDArray[np.float64], coef: float, order: NDArray[np.int64],
                 nptr: NDArray[np.int64], nidx: NDArray[np.int64], nq: NDArray[np.float64]) -> None:
        self.coef = float(coef)
        self._order, self._nptr, self._nidx, self._nq = order, nptr, nidx, nq
        self._work = len(nidx) + len(order)
        self.factor: Factor = factorize(preconditioner(cells, q, coef))
        n = len(order)
        self._G = np.empty((n, 3))
        self._R0 = np.empty((n, 3, 3))
        self.moved = False
        """Whether the last :meth:`step` changed the rotations (False: every trial raised ``f``)."""

    def energy(self, S: NDArray[np.float64], d: NDArray[np.float64], R: NDArray[np.float64],
               E: NDArray[np.float64], term: NDArray[np.float64], gradient: bool = False) -> float:
        """``f(R)``: ``E[c]`` each cell's data energy, ``term[c]`` its rotation term ``αA Σ_j w⁺_ij ‖R_c − R_j‖²``;
        with ``gradient``, the gradient in ``ω`` is stored for :meth:`step`. ``S`` (n, 9) and ``d`` (n,) are the
        covariances and constants by sweep position."""
        args = (self._order, self._nptr, self._nidx, self._nq, S, d, self.coef, R, E, term, self._G, gradient)
        return float(policy.run("rotation_energy", self._work, lambda: _energy_serial(*args),
                                lambda: _energy_parallel(*args)))

    def _rotate(self, W: NDArray[np.float64], t: float, R: NDArray[np.float64]) -> None:
        """``R[c] = exp([t W_c]×) R0[c]`` from the rotations saved at the start of the step."""
        args = (self._R0, W, t, R)
        policy.run("rotate", len(R), lambda: _rotate_serial(*args), lambda: _rotate_parallel(*args))

    def step(self, S: NDArray[np.float64], d: NDArray[np.float64], R: NDArray[np.float64],
             E: NDArray[np.float64], term: NDArray[np.float64]) -> float:
        """One preconditioned step on ``R`` (n, 3, 3), in place; never raises ``f``.

        Returns
        -------
        float
            ``f`` of the rotations kept, whose ``E`` and ``term`` are filled.
        """
        current = self.energy(S, d, R, E, term, gradient=True)
        W = self.factor.solve(self._G)
        np.negative(W, out=W)
        np.copyto(self._R0, R)
        t = 1.0
        for _ in range(HALVINGS + 1):
            self._rotate(W, t, R)
            value = self.energy(S, d, R, E, term)
            if value <= current:
                self.moved = True
                return value
            t *= 0.5
        self.moved = False
        np.copyto(R, self._R0)
        return self.energy(S, d, R, E, term)
