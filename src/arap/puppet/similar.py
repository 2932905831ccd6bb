"""The puppet warp's "distort" mode in the studio as one linear solve: the as-similar-as-possible energy (λ = 0 of
:mod:`arap.puppet.blend`) is quadratic in the positions, so its minimum under a solver's constraints is the solution
of one sparse system, factorised once per constraint set (Igarashi, Moscovich & Hughes 2005, the first step of their
method; the conformal energy of least-squares conformal maps).

With a cell's covariance ``S`` and ``p = S₀₀ + S₁₁``, ``q = S₀₁ − S₁₀`` (linear in the positions), the cell's energy
at its best similarity is ``Σ w ‖e'‖² − (p² + q²) / Σ w ‖e‖²``. Summed over the cells, with the solver's free
coordinates ``z = (x, y)``: ``zᵀ Ā z + 2 zᵀ c − ‖G z + g₀‖²_D`` (``Ā`` the solver's matrix for each coordinate,
``c`` its right-hand side's constant, ``G`` the map to every cell's ``(p, q)``, ``g₀`` the non-free vertices' part,
``D`` the inverse rest sums), least where

    (Ā − Gᵀ D G + ε Ā) z = −c + Gᵀ D g₀ + ε Ā z_rest

and the hard point handles hold (a Schur complement on their few rows, as :mod:`arap.method.points` does). ``ε``
(:data:`SMOOTHING`) picks, among equally similar shapes (a part held by one pin may turn and scale about it freely),
the one nearest the rest pose in the energy's norm; elsewhere it moves the result by about ``ε`` of the displacement.

The minimum is affine in what a drag moves: the constrained vertices' and the point handles' targets (``x`` and
``y`` of each, ``m`` numbers in all; held vertices stay at rest). So where its ``m`` responses fit
(:data:`RESPONSE_ENTRIES`), they are solved once with the factorisation, ``z = z₀ + J u`` (Igarashi et al.'s
precomputed handle responses), and each solve is then one dense product of ``2 n_free × m`` instead of a
back-substitution of the coupled system: the studio's Distort drag on a 50k-vertex picture is timed by
``benchmarks/bench_puppet_drag.py``. Larger constraint sets solve directly.

The coupled matrix is ``[[A, −B], [B, A]]`` with ``B`` antisymmetric (the energy does not change when the plane
turns), i.e. the complex Hermitian ``A + iB`` acting on ``x + iy``. Where CHOLMOD is installed (``sksparse``) that
n-unknown complex matrix is factorised instead of the 2n-unknown real one: the same solution from a factor of a
quarter of the real one's size pattern, several times faster to compute (:class:`HermitianFactor`).
"""

from __future__ import annotations

import os
import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.errors import ConstraintError
from arap.solve.iteration import rhs_constant
from arap.solve.prepared import Prepared
from arap.sparse.linsolve import BACKEND_ENV, Factor, NotPositiveDefiniteError, available_backends, factorize

__all__ = ["RESPONSE_ENTRIES", "SMOOTHING", "HermitianFactor", "SimilarSystem", "factorize_coupled"]

SMOOTHING = 1e-8
"""``ε``: the weight of the pull towards the rest pose, relative to the energy's own matrix."""
RESPONSE_ENTRIES = 1 << 23
"""Most entries (``2 n_free × m``, 64 MiB of float64) of the responses to the moving targets kept to solve by one
product; beyond, every solve is a back-substitution."""
RESTART = 256
"""Solves that update the previous minimum by the responses of the targets that moved (a drag moves one pin's)
before one sums all the responses again, bounding the round-off carried from solve to solve."""


class HermitianFactor:
    """A Cholesky factor (CHOLMOD, complex) of the real ``2k × 2k`` matrix ``[[A, −B], [B, A]]`` (``A``
    symmetric, ``B`` antisymmetric) as the Hermitian ``A + iB`` of ``k`` unknowns.

    Parameters
    ----------
    M : (2k, 2k) scipy.sparse matrix
        Of that form, positive definite.

    Raises
    ------
    NotPositiveDefiniteError
        ``M`` is not positive definite.
    """

    backend = "sksparse"

    def __init__(self, M: sp.csr_matrix) -> None:
        from sksparse.cholmod import CholmodError, CholmodNotPositiveDefiniteError, cholesky

        t0 = time.perf_counter()
        k = M.shape[0] // 2
        B = sp.csr_matrix(M[k:, :k])
        B = 0.5 * (B - B.T)  # antisymmetric to the last bit: a Hermitian matrix's diagonal is real
        H = sp.csc_matrix(0.5 * (M[:k, :k] + M[:k, :k].T) + 1j * B)
        try:
            try:
                factor = cholesky(H, ordering_method="metis")
            except CholmodNotPositiveDefiniteError:
                raise
            except CholmodError:  # a CHOLMOD built without METIS
                factor = cholesky(H, ordering_method="amd")
        except CholmodNotPositiveDefiniteError as exc:
            raise NotPositiveDefiniteError(str(exc)) from exc
        self._factor, self._k = factor, k
        self.timings = {"factor": time.perf_counter() - t0}

    def solve(self, B: np.ndarray) -> np.ndarray:
        """Solve ``M X = B`` for ``B`` of shape (2k, c) or (2k,)."""
        B = np.asarray(B, dtype=np.float64)
        k = self._k
        Z = np.asarray(self._factor.solve_A(B[:k] + 1j * B[k:]))
        return np.concatenate([Z.real, Z.imag])


def factorize_coupled(M: sp.csr_matrix) -> Factor:
    """A factor of the coupled matrix ``M`` (see :class:`HermitianFactor`): the complex one where CHOLMOD is
    installed and no other backend is named (:data:`arap.sparse.linsolve.BACKEND_ENV`), else the real one of the
    default backend."""
    forced = os.environ.get(BACKEND_ENV, "").strip()
    if forced in ("", "sksparse") and "sksparse" in available_backends():
        return HermitianFactor(M)
    return factorize(M)


class SimilarSystem:
    """The as-similar-as-possible minimum of a prepared planar element solver's constraint set, as one solve.

    Parameters
    ----------
    p : Prepared
        Of a planar triangle mesh with the element energy, without rigid regions.

    Raises
    ------
    ConstraintError
        Hard point handles that do not pin independent positions.
    """

    def __init__(self, p: Prepared) -> None:
        self.p = p
        nf, n, cells = p.nf, p.n, p.cells
        nc = cells.n_cells
        cell = cells.cell_of_term()
        a, b = cells.a.astype(np.int64), cells.b.astype(np.int64)
        w0, w1 = cells.we[:, 0], cells.we[:, 1]
        rows = np.concatenate([cell, cell, cell, cell, cell + nc, cell + nc, cell + nc, cell + nc])
        cols = np.concatenate([a, b, a + n, b + n, a + n, b + n, a, b])
        vals = np.concatenate([w0, -w0, w1, -w1, w0, -w0, -w1, w1])
        G = sp.csr_matrix((vals, (rows, cols)), shape=(2 * nc, 2 * n)).tocsc()
        free = np.concatenate([np.arange(nf), np.arange(nf) + n])
        fixed = np.concatenate([np.arange(nf, n), np.arange(nf, n) + n])
        self._G_free = G[:, free].tocsr()
        self._G_fixed = G[:, fixed].tocsr()
        rest_sq = np.asarray(cells.rest_sq, dtype=np.float64)
        self._D = np.tile(np.divide(1.0, rest_sq, out=np.zeros(nc), where=rest_sq > 0.0), 2)
        A = sp.block_diag([p.matrix, p.matrix], format="csr")
        M = (1.0 + SMOOTHING) * A - (self._G_free.T @ sp.diags(self._D) @ self._G_free)
        self._pull = SMOOTHING * (A @ np.concatenate([p.rest[:nf, 0], p.rest[:nf, 1]]))
        self.factor: Factor = factorize_coupled(sp.csr_matrix(M))
        self._hard: sp.csr_matrix | None = None
        self._Z: NDArray[np.float64] | None = None
        self._S: tuple[NDArray[np.float64], bool] | None = None
        system = p.point_system
        if system is not None and system.hard.any():
            Ch = system.C_free[system.hard]
            hard = sp.csr_matrix(sp.block_diag([Ch, Ch]))
            Z = np.asarray(self.factor.solve(np.ascontiguousarray(hard.T.toarray())))
            S = np.asarray(hard @ Z)
            self._hard, self._Z = hard, Z
            try:
                self._S = sla.cho_factor(0.5 * (S + S.T))
            except sla.LinAlgError as exc:
                raise ConstraintError("the hard point constraints are not independent") from exc
        self._n_points = 0 if p.points is None else len(p.points)
        self._responses: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        m = 2 * (len(p.numbering.constrained_slot) + self._n_points)
        if 0 < 2 * nf * m <= RESPONSE_ENTRIES:
            self._responses = self._solve_responses(m)
        self._last: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._updates = 0

    def _moving(self, fixed: NDArray[np.float64], P: NDArray[np.float64] | None) -> NDArray[np.float64]:
        """``u``: the x and y of the constrained vertices' targets, then of the point targets."""
        slot = self.p.numbering.constrained_slot
        parts = [fixed[slot, :2].ravel()]
        if P is not None:
            parts.append(P[:, :2].ravel())
        return np.concatenate(parts)

    def _probe(self, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The non-free positions and point targets whose moving coordinates are ``u`` (the rest elsewhere)."""
        p = self.p
        slot = p.numbering.constrained_slot
        fixed = p.rest[p.nf:].copy()
        fixed[slot, :2] = u[:2 * len(slot)].reshape(-1, 2)
        fixed[slot, 2:] = 0.0
        if not self._n_points:
            return fixed, None
        P = np.zeros((self._n_points, p.rest.shape[1]))
        P[:, :2] = u[2 * len(slot):].reshape(-1, 2)
        return fixed, P

    def _rhs(self, fixed: NDArray[np.float64], P: NDArray[np.float64] | None) -> NDArray[np.float64]:
        """The right-hand side of the coupled system for the non-free positions ``fixed`` and point targets ``P``."""
        const = rhs_constant(self.p, fixed, P)
        g0 = self._G_fixed @ np.concatenate([fixed[:, 0], fixed[:, 1]])
        return np.asarray(self._G_free.T @ (self._D * g0) - np.concatenate([const[:, 0], const[:, 1]]) + self._pull)

    def _goal(self, fixed: NDArray[np.float64], P: NDArray[np.float64] | None) -> NDArray[np.float64] | None:
        """What the free coordinates must give the hard point handles' rows (None without any)."""
        if self._hard is None or P is None:
            return None
        assert self.p.point_system is not None
        goal = self.p.point_system.goal(P, fixed)
        return np.concatenate([goal[:, 0], goal[:, 1]])

    def _held(self, z: NDArray[np.float64], goal: NDArray[np.float64] | None) -> NDArray[np.float64]:
        """Columns ``z`` of minima without the hard point handles, corrected to meet them (``goal``: a column
        each)."""
        if goal is None or self._hard is None or self._Z is None or self._S is None:
            return z
        miss = self._hard @ z - goal
        return np.asarray(z - self._Z @ sla.cho_solve(self._S, miss, check_finite=False))

    def _solve_responses(self, m: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(z₀, J)``: the minimum with every moving coordinate 0, and its change per unit of each (by linearity:
        the differences of the right-hand sides and goals, solved together)."""
        zero = self._probe(np.zeros(m))
        r0, g0 = self._rhs(*zero), self._goal(*zero)
        R = np.empty((len(r0), m + 1))
        R[:, 0] = r0
        G = None if g0 is None else np.empty((len(g0), m + 1))
        if G is not None and g0 is not None:
            G[:, 0] = g0
        unit = np.zeros(m)
        for j in range(m):
            unit[j] = 1.0
            probe = self._probe(unit)
            R[:, j + 1] = self._rhs(*probe) - r0
            if G is not None and g0 is not None:
                goal = self._goal(*probe)
                assert goal is not None
                G[:, j + 1] = goal - g0
            unit[j] = 0.0
        Z = self._held(np.asarray(self.factor.solve(R)), G)
        return np.ascontiguousarray(Z[:, 0]), np.asfortranarray(Z[:, 1:])

    def _by_responses(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        """``z₀ + J u``; the previous minimum plus the responses of the coordinates that changed, where those are
        at most half (and fewer than :data:`RESTART` solves were updated so)."""
        assert self._responses is not None
        base, J = self._responses
        last = self._last
        if last is not None and self._updates < RESTART:
            changed = np.flatnonzero(u != last[0])
            if 2 * len(changed) <= len(u):
                z = last[1] + J[:, changed] @ (u[changed] - last[0][changed]) if len(changed) else last[1].copy()
                self._last, self._updates = (u, z), self._updates + 1
                return z
        z = base + J @ u
        self._last, self._updates = (u, z), 0
        return z

    def solve(self, fixed: NDArray[np.float64], P: NDArray[np.float64] | None) -> NDArray[np.float64]:
        """The free vertices' positions (nf, 3), ``z = 0``, for the non-free positions ``fixed`` (internal order, as
        :meth:`arap.solve.prepared.Prepared.fixed_positions` gives them: held vertices at rest) and the point targets
        ``P`` (as the solver checked them)."""
        nf = self.p.nf
        if self._responses is not None and (P is not None or not self._n_points):
            z = self._by_responses(self._moving(fixed, P))
        else:
            z = np.asarray(self.factor.solve(self._rhs(fixed, P).reshape(-1, 1))).reshape(-1)
            goal = self._goal(fixed, P)
            z = self._held(z.reshape(-1, 1), None if goal is None else goal.reshape(-1, 1)).reshape(-1)
        X = np.zeros((nf, 3))
        X[:, 0], X[:, 1] = z[:nf], z[nf:]
        return X
