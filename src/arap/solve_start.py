"""Where a :meth:`arap.ArapSolver.solve` call starts: the previous solution (warm), the rest pose, the rest pose
moved by the targets' best-fit rigid motion (:mod:`arap.start`), whichever of these two has the lower energy, or
positions given by the caller; and the rotations its first global step uses."""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError
from arap.indexing import assign_rows
from arap.options import START_NAMES
from arap.smooth import SmoothRotations
from arap.start import rigid_start

__all__ = ["SolveStart"]


class _Solver(Protocol):
    """What the start reads of a solver (see :class:`arap.ArapSolver`)."""

    _V: NDArray[np.float64]
    _R: NDArray[np.float64]
    _E: NDArray[np.float64]
    _nf: int
    _active: NDArray[np.int64]
    _term: NDArray[np.float64]
    _constrained: NDArray[np.int64]
    _areas: NDArray[np.float64]
    _smooth: SmoothRotations | None
    _last: NDArray[np.float64] | None
    _rotations_fresh: bool

    def _local(self, U: NDArray[np.float64], const_E: float, timings: dict[str, float]) -> float: ...
    def _to_internal(self, X: np.ndarray) -> np.ndarray: ...
    def _check_positions(self, U: object, name: str) -> NDArray[np.float64]: ...
    def _cold_rotations(self, U: NDArray[np.float64]) -> None: ...
    def _stored_energy(self) -> float: ...


class SolveStart:
    """The start of a solve, a base of :class:`arap.ArapSolver`."""

    def _start(
        self: _Solver, T: NDArray[np.float64], fixed: NDArray[np.float64],
        initial: NDArray[np.float64] | str | None, timings: dict[str, float]
    ) -> tuple[NDArray[np.float64], float | None, str]:
        """Starting positions (internal order, non-free vertices at their fixed positions), their active-cell
        energy (None when the rotations in ``self._R`` were not fitted to them) and the name of the start.

        Leaves in ``self._R`` the rotations the first global step uses.
        """
        if initial is None:
            if self._last is None:
                initial = "auto"
            else:
                U = self._last  # continued in place: the solver owns it, and the result is a copy
                warm_fresh = self._rotations_fresh
                if not warm_fresh:
                    self._local(U, 0.0, timings)
                at_targets = assign_rows(U[self._nf:], fixed)
                E = self._stored_energy() if at_targets else None
                return U, E, "warm"
        if isinstance(initial, str):
            if initial not in START_NAMES:
                raise OptionError(f"unknown initial {initial!r}; expected one of {START_NAMES}, an array or None")
            candidates = []
            if initial in ("auto", "rest"):
                U = self._V.copy()
                U[self._nf:] = fixed
                candidates.append(("rest", U))
            if initial in ("auto", "rigid"):
                candidates.append(("rigid", rigid_start(self._V, self._constrained, T, self._areas, fixed)))
            best: tuple[float, str, NDArray[np.float64], NDArray[np.float64]] | None = None
            for name, U in candidates:
                self._cold_rotations(U)
                E = self._local(U, 0.0, timings)
                if best is None or E < best[0]:
                    best = (E, name, U, self._R.copy() if len(candidates) > 1 else self._R)
            assert best is not None
            E, name, U, R = best
            if R is not self._R:
                self._R[:] = R
            return U, E, name
        U = self._to_internal(self._check_positions(initial, "initial"))
        U[self._nf:] = fixed
        self._cold_rotations(U)
        return U, self._local(U, 0.0, timings), "given"

    def _cold_rotations(self: _Solver, U: NDArray[np.float64]) -> None:
        """Before a cold start: the rotations the first local step goes on from. Identities (the rotation fits start
        their search there, so that a cold start does not depend on earlier solves, to the last bit), or for
        ``smooth_rotations`` the start of the coupled local steps (:meth:`arap.smooth.SmoothRotations.start`)."""
        if self._smooth is not None:
            self._smooth.start(self._V, U, self._areas, self._R)
        else:
            self._R[:] = np.eye(3)

    def _stored_energy(self: _Solver) -> float:
        """Energy of the active cells from the last local step."""
        value = float(self._E[self._active].sum())
        if self._smooth is not None:
            value += float(self._term.sum())
        return value
