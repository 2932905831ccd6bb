"""Single steps of a solver, for analysis and tests: the local step alone, the energy of given positions (and
rotations), the global step alone and the reduced matrix.

:class:`SingleSteps` is a base of :class:`arap.ArapSolver`; its methods read the solver's set-up (cells, factor,
vertex numbering) and leave the state of :meth:`~arap.ArapSolver.solve` untouched.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.cells import Cells, RhsGather, system_matrix
from arap.covariance import assemble_rhs, covariances, local_step
from arap.linsolve import Factor
from arap.points import PointSystem
from arap.rigid import RigidRegions
from arap.rotations import identity_rotations
from arap.smooth import SmoothRotations

__all__ = ["SingleSteps"]


class _Solver(Protocol):
    """What the single steps read of a solver (see :class:`arap.ArapSolver`)."""

    @property
    def n_vertices(self) -> int: ...
    @property
    def factor(self) -> Factor | None: ...
    @property
    def _V(self) -> NDArray[np.float64]: ...
    @property
    def _inv(self) -> NDArray[np.int64]: ...
    @property
    def _nf(self) -> int: ...
    @property
    def _free(self) -> NDArray[np.int64]: ...
    @property
    def _cells(self) -> Cells: ...
    @property
    def _gather(self) -> RhsGather: ...
    @property
    def _L_fn(self) -> sp.csr_matrix: ...
    @property
    def _R(self) -> NDArray[np.float64]: ...
    @property
    def _smooth(self) -> SmoothRotations | None: ...
    @property
    def _rigid_all(self) -> RigidRegions | None: ...
    @property
    def _points(self) -> PointSystem | None: ...
    def _to_internal(self, X: np.ndarray) -> np.ndarray: ...
    def _check_positions(self, U: object, name: str) -> NDArray[np.float64]: ...
    def _check_targets(self, targets: object) -> NDArray[np.float64]: ...
    def _check_point_targets(self, point_targets: object) -> NDArray[np.float64] | None: ...
    def _fixed_positions(self, targets: np.ndarray) -> np.ndarray: ...
    def _to_caller(self, U: np.ndarray) -> np.ndarray: ...
    def fit_rotations(self, U: np.ndarray, start: np.ndarray | None = None) -> np.ndarray: ...


class SingleSteps:
    """The local step, the energy and the global step one at a time, in the caller's vertex order."""

    def fit_rotations(self: _Solver, U: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
        """Local step alone: the optimal rotation of every cell for positions ``U``, shape (n, 3, 3).

        For ``smooth_rotations`` the rotations are coupled: this is one block-coordinate sweep from ``start``
        (n, 3, 3) (None: the solver's current rotations), which never raises the energy.
        """
        U = self._to_internal(self._check_positions(U, "U"))
        R = identity_rotations(self.n_vertices)
        E = np.empty(self.n_vertices)
        if self._smooth is not None:
            R[:] = self._R if start is None else self._to_internal(np.asarray(start, dtype=np.float64))
            self._smooth.local_step(U, R, E, np.empty(self.n_vertices))
        else:
            local_step(self._cells, np.arange(self.n_vertices), U, R, E)
        if self._rigid_all is not None:
            self._rigid_all.share(U, R, E)
        return R[self._inv]

    def energy(self: _Solver, U: np.ndarray, R: np.ndarray | None = None) -> float:
        """Energy of positions ``U`` with rotations ``R`` (None: the optimal ones; for ``smooth_rotations``, those
        of :meth:`fit_rotations`), summed over all cells."""
        if R is None and self._smooth is not None:
            R = self.fit_rotations(U)
        U = self._to_internal(self._check_positions(U, "U"))
        if R is None:
            E = np.empty(self.n_vertices)
            R_opt = identity_rotations(self.n_vertices)
            local_step(self._cells, np.arange(self.n_vertices), U, R_opt, E)
            if self._rigid_all is not None:
                self._rigid_all.share(U, R_opt, E)
            return float(E.sum())
        d = U[self._cells.a] - U[self._cells.b]
        cur = float(np.dot(self._cells.w, np.einsum("ij,ij->i", d, d)))
        S = covariances(self._cells, U)
        R = self._to_internal(np.asarray(R, dtype=np.float64))
        value = cur + float(self._cells.rest_sq.sum()) - 2.0 * float(np.einsum("cij,cji->", R, S))
        if self._smooth is not None:
            value += self._smooth.rotation_term(np.ascontiguousarray(R), np.empty(self.n_vertices))
        return value

    def global_step(self: _Solver, R: np.ndarray, targets: np.ndarray | list,
                    point_targets: np.ndarray | list | None = None) -> np.ndarray:
        """Global step alone: positions minimising the energy for fixed rotations ``R`` (n, 3, 3), shape (n, 3)."""
        T = self._check_targets(targets)
        fixed = self._fixed_positions(T)
        P = self._check_point_targets(point_targets)
        U = self._V.copy()
        U[self._nf:] = fixed
        if self.factor is not None:
            rhs = np.empty((len(self._free), 3))
            const = self._L_fn @ fixed
            if self._points is not None and P is not None:
                const = const - self._points.rhs(P, fixed)  # assemble_rhs subtracts its constant
            assemble_rhs(self._gather, self._to_internal(np.asarray(R, dtype=np.float64)), const, rhs)
            g = self.factor.solve(rhs)
            if self._points is not None and P is not None:
                g = self._points.correct(g, P, fixed)
            U[self._free] = g
        return self._to_caller(U)

    def reduced_matrix(self: _Solver) -> sp.csr_matrix:
        """The reduced global-step matrix ``L_ff`` (for inspection; rows in the solver's internal vertex order)."""
        L = system_matrix(self._cells, self.n_vertices)
        return L[self._free][:, self._free].tocsr()
