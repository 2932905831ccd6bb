"""The parts of a solve that only some constraint sets have, as objects with one small interface.

The plain method (Sorkine & Alexa 2007) fits every cell's rotation on its own (:class:`PlainFit`). Three add-ons
change it: smooth rotations (SR-ARAP, Levi & Gotsman 2015) fit the rotations together instead; rigid regions share
one rotation per region after the fit; point handles add terms to the energy, the global step's right-hand side and
its solution. Each is an :class:`AddOn`: what it does after the rotation fit, what it adds to the right-hand side's
constant, how it corrects a global step's solution, the tolerance it needs, and whether L-BFGS's model of the
gradient (``2 (A x − b(R))`` with the factored ``A``) holds with it. The solver runs its add-ons in one fixed order
(:func:`arap.solve.prepared.prepare`) and has no other branch on them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from arap.method.cells import Cells
from arap.method.local_step import local_step
from arap.method.points import PointSystem
from arap.method.rigid import RIGID_TOLERANCE, RigidRegions
from arap.method.rotations import identity_rotations
from arap.method.smooth import STEPS, SWEEPS, SmoothRotations

__all__ = ["AddOn", "LocalState", "PlainFit", "PointHandles", "RigidAddOn", "RotationFit", "SmoothAddOn", "SmoothFit"]

Array = NDArray[np.float64]


@dataclass
class LocalState:
    """What the local steps of one solver write and keep between solves.

    Attributes
    ----------
    R : (n, 3, 3) float64 array
        Each cell's rotation.
    E : (n,) float64 array
        Each cell's energy at the last local step.
    term : (n,) float64 array
        Smooth rotations' rotation term per cell (zeros otherwise).
    fit_term : float
        The rotation term's sum after the last fit (smooth rotations).
    points : tuple of two arrays or None
        The current solve's point targets and non-free positions, while point handles have targets.
    """

    R: Array
    E: Array
    term: Array
    fit_term: float = 0.0
    points: tuple[Array, Array] | None = None

    @classmethod
    def empty(cls, n: int) -> LocalState:
        """The state of ``n`` cells before any fit."""
        return cls(R=identity_rotations(n), E=np.zeros(n), term=np.zeros(n))


class RotationFit:
    """How the local step fits the rotations: every cell on its own, or all together (smooth rotations)."""

    #: The rotations are moved on from their previous values rather than fitted afresh.
    coupled: bool = False
    #: The fit reads only the first two coordinates of the positions, so a planar solve can iterate on (n, 2) ones
    #: (:func:`arap.solve.iteration.make_iterate`).
    planar_columns: bool = False

    def fit(self, U: Array, state: LocalState) -> float:
        """Fit the rotations of the cells the iterations update at ``U``; their energy."""
        raise NotImplementedError

    def fit_all(self, U: Array, R: Array, E: Array) -> None:
        """Fit every cell's rotation into ``R`` (in: where coupled fits start), energies into ``E``."""
        raise NotImplementedError

    def cold(self, rest: Array, U: Array, areas: Array, R: Array) -> None:
        """The rotations a cold start's first fit goes on from."""
        R[:] = np.eye(3)

    def stored_energy(self, state: LocalState, active: NDArray[np.int64]) -> float:
        """The energy of the last fit, from the state."""
        return float(state.E[active].sum())

    def rotation_energy(self, R: Array) -> float:
        """The energy's part that depends on the rotations alone (0 for the plain energies)."""
        return 0.0


class PlainFit(RotationFit):
    """Each cell's best rotation on its own: the local step of Sorkine & Alexa 2007."""

    def __init__(self, cells: Cells, active: NDArray[np.int64]) -> None:
        self.cells = cells
        self.active = active
        self.planar_columns = cells.planar  # rotations about z (arap.method.planar)

    def fit(self, U: Array, state: LocalState) -> float:
        return local_step(self.cells, self.active, U, state.R, state.E)

    def fit_all(self, U: Array, R: Array, E: Array) -> None:
        local_step(self.cells, np.arange(self.cells.n_cells), U, R, E)


class SmoothFit(RotationFit):
    """The rotations of SR-ARAP (Levi & Gotsman 2015), coupled to their neighbours' (see :mod:`arap.method.smooth`)."""

    coupled = True

    def __init__(self, smooth: SmoothRotations) -> None:
        self.smooth = smooth

    def fit(self, U: Array, state: LocalState) -> float:
        e = self.smooth.relax(U, state.R, state.E, state.term, SWEEPS, steps=STEPS)
        state.fit_term = float(state.term.sum())
        return e

    def fit_all(self, U: Array, R: Array, E: Array) -> None:
        self.smooth.local_step(U, R, E, np.empty(len(U)))

    def cold(self, rest: Array, U: Array, areas: Array, R: Array) -> None:
        self.smooth.start(rest, U, areas, R)

    def stored_energy(self, state: LocalState, active: NDArray[np.int64]) -> float:
        return float(state.E[active].sum()) + float(state.term.sum())

    def rotation_energy(self, R: Array) -> float:
        return self.smooth.rotation_term(np.ascontiguousarray(R), np.empty(len(R)))


class AddOn:
    """A part of the energy or of the constraints that only some solves have; every method defaults to nothing.

    Examples
    --------
    Rigid vertices (infinite stiffness) bring an add-on to the solve:

    >>> import numpy as np, arap
    >>> from arap.solve.prepared import prepare
    >>> V, F = arap.sphere(1)
    >>> stiffness = np.where(V[:, 1] > 0.5, np.inf, 1.0)
    >>> [type(a).__name__ for a in prepare(V, F, [0, 2], stiffness=stiffness).addons]
    ['RigidAddOn']
    >>> prepare(V, F, [0, 2]).addons
    ()
    """

    #: The tolerance a solve needs at least (relative to the diagonal), or 0.
    min_tolerance: float = 0.0
    #: The add-on works on a planar solve's (n, 2) positions (its arrays given with as many columns).
    planar_columns: bool = True

    def after_fit(self, U: Array, state: LocalState, e: float) -> float:
        """After the rotation fit of the iterations: change the state, return the energy ``e`` with its share."""
        return e

    def after_fit_all(self, U: Array, R: Array, E: Array) -> None:
        """After a fit of every cell (:meth:`RotationFit.fit_all`)."""

    def rhs_constant(self, const: Array, P: Array | None, fixed: Array) -> Array:
        """The right-hand side's constant with this add-on's part (``assemble_rhs`` subtracts it)."""
        return const

    def corrector(self, P: Array | None, fixed: Array) -> Callable[[Array], Array] | None:
        """What a global step's solution goes through (its argument, a new array, may be corrected in place), or
        None."""
        return None

    def lbfgs_applies(self, P: Array | None) -> bool:
        """Whether the energy's gradient is ``2 (A x − b(R))`` to full precision with this add-on."""
        return True


@dataclass
class SmoothAddOn(AddOn):
    """Smooth rotations as an add-on: they are only moved towards their optimum, so L-BFGS's gradient is not
    exact; the fit itself is :class:`SmoothFit`."""

    fit: SmoothFit
    planar_columns: bool = field(default=False)

    def lbfgs_applies(self, P: Array | None) -> bool:
        return False


@dataclass
class RigidAddOn(AddOn):
    """Rigid regions (infinite stiffness): after the fit every cell of a region takes the region's best rotation.

    ``active`` shares over the cells the iterations update, ``every`` over all cells (single steps); with smooth
    rotations the shared rotations change the rotation term, which ``smooth`` recomputes.
    """

    active: RigidRegions
    every: RigidRegions
    smooth: SmoothFit | None = None
    min_tolerance: float = field(default=RIGID_TOLERANCE)
    planar_columns: bool = field(default=False)  # the regions' rotations are fitted in space

    def after_fit(self, U: Array, state: LocalState, e: float) -> float:
        e += self.active.share(U, state.R, state.E)
        if self.smooth is not None:
            e += self.smooth.smooth.rotation_term(state.R, state.term) - state.fit_term
        return e

    def after_fit_all(self, U: Array, R: Array, E: Array) -> None:
        self.every.share(U, R, E)

    def lbfgs_applies(self, P: Array | None) -> bool:
        return False  # the regions' huge cell weights cancel in A x − b


@dataclass
class PointHandles(AddOn):
    """Handles anywhere on the surface (:mod:`arap.method.points`): soft ones add a penalty and a right-hand-side term,
    hard ones a projection of the global step's solution."""

    system: PointSystem
    n_free: int

    def after_fit(self, U: Array, state: LocalState, e: float) -> float:
        if state.points is not None:
            P, fixed = state.points
            d = U.shape[1]  # 2 in a planar solve's iterations (the targets' z is 0)
            e += self.system.penalty(U[:self.n_free], P[:, :d], fixed[:, :d])
        return e

    def rhs_constant(self, const: Array, P: Array | None, fixed: Array) -> Array:
        return const if P is None else self.system.subtract_rhs(const, P, fixed)

    def corrector(self, P: Array | None, fixed: Array) -> Callable[[Array], Array] | None:
        if P is None or not self.system.hard.any():
            return None
        system = self.system
        goal = system.goal(P, fixed)

        def correct(g: Array) -> Array:
            return system.project(g, goal)

        return correct

    def lbfgs_applies(self, P: Array | None) -> bool:
        return P is None or not bool(self.system.hard.any())  # the projection is not A⁻¹
