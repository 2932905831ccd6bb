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
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.errors import ConstraintError
from arap.solve.iteration import rhs_constant
from arap.solve.prepared import Prepared
from arap.sparse.linsolve import Factor, factorize

__all__ = ["SMOOTHING", "SimilarSystem"]

SMOOTHING = 1e-8
"""``ε``: the weight of the pull towards the rest pose, relative to the energy's own matrix."""


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
        self.factor: Factor = factorize(sp.csr_matrix(M))
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

    def solve(self, fixed: NDArray[np.float64], P: NDArray[np.float64] | None) -> NDArray[np.float64]:
        """The free vertices' positions (nf, 3), ``z = 0``, for the non-free positions ``fixed`` (internal order)
        and the point targets ``P`` (as the solver checked them)."""
        p = self.p
        nf = p.nf
        const = rhs_constant(p, fixed, P)
        g0 = self._G_fixed @ np.concatenate([fixed[:, 0], fixed[:, 1]])
        rhs = self._G_free.T @ (self._D * g0) - np.concatenate([const[:, 0], const[:, 1]]) + self._pull
        z = np.asarray(self.factor.solve(rhs.reshape(-1, 1))).reshape(-1)
        if self._hard is not None and self._Z is not None and self._S is not None and P is not None:
            assert p.point_system is not None
            goal = p.point_system.goal(P, fixed)
            miss = self._hard @ z - np.concatenate([goal[:, 0], goal[:, 1]])
            z = z - self._Z @ sla.cho_solve(self._S, miss, check_finite=False)
        X = np.zeros((nf, 3))
        X[:, 0], X[:, 1] = z[:nf], z[nf:]
        return X
