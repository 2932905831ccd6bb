"""The factorised solvers of a studio session, kept for the constraint sets used last (so that undo across a
selection change does not factorise again)."""

from __future__ import annotations

import logging
from collections import OrderedDict
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError
from arap.method.points import PointConstraints
from arap.options import DEFAULT_TOLERANCE, EnergyType
from arap.server.constraints import ConstraintSet
from arap.server.records import Params
from arap.server.session_errors import ConstraintsRejected
from arap.solve.result import ArapResult
from arap.solve.solver import ArapSolver

if TYPE_CHECKING:
    from arap.puppet.blend import BlendSolver

__all__ = [
    "SOLVER_CACHE_VERTICES", "PlaneSolver", "SolverCache", "StudioSolver", "plane_solver", "points_in_tetrahedra",
]

logger = logging.getLogger(__name__)

SOLVER_CACHE_VERTICES = 200_000
"""Meshes up to this size keep two factorised solvers (undo across a selection change is instant)."""


class SolverCache:
    """Solvers by (rest pose, energy, weights, alpha, loose parts, constraint set), the least recently used dropped
    first."""

    def __init__(self) -> None:
        self._solvers: OrderedDict[tuple[Any, ...], StudioSolver] = OrderedDict()

    def clear(self) -> None:
        """Drop every solver (a new mesh)."""
        self._solvers.clear()

    def get(self, rest_id: int, V: np.ndarray, F: np.ndarray, cs: ConstraintSet, params: Params,
            solid: tuple[np.ndarray, np.ndarray] | None = None,
            planar: bool = False) -> StudioSolver | None:
        """A factorised solver for the constraint set on the rest pose ``V`` (numbered ``rest_id``), or None when
        nothing is constrained.

        ``solid``: the tetrahedra of a solid and the tetrahedron behind each of its boundary triangles ``F``; the
        solver then deforms the tetrahedra (the element energy), with the point handles on the boundary taken
        into their tetrahedra. ``planar``: a flat mesh in ``z = 0`` (a picture) that bends in its plane, with the
        element energy, its targets put back on the plane (:class:`PlaneSolver`), in the puppet warp's mode
        ``params.warp`` (:func:`plane_solver`).

        Raises
        ------
        ConstraintsRejected
            When the solver rejects the constraints.
        """
        if cs.is_empty:
            return None
        energy = "elements" if solid is not None or planar else params.energy  # the only energy tetrahedra have
        alpha = params.alpha if energy == "smooth_rotations" else None  # other energies ignore it
        warp = params.warp if planar else None
        key = (rest_id, energy, params.weights, alpha, params.loose, planar, warp, cs.solver_digest())
        solver = self._solvers.get(key)
        if solver is not None:
            self._solvers.move_to_end(key)
            return solver
        elements, points = F, cs.solver_points  # a picture's pins that hold an angle add their rings
        if solid is not None:
            elements = solid[0]
            points = None if points is None else points_in_tetrahedra(points, F, solid[0], solid[1])
        try:
            made = ArapSolver(V, elements, cs.constrained, energy=energy, weights=params.weights, roi=cs.roi,
                              alpha=params.alpha, stiffness=cs.stiffness, points=points, loose=params.loose)
            solver = plane_solver(made, params.warp) if planar else made
        except ArapError as exc:
            raise ConstraintsRejected(str(exc)) from exc
        logger.debug("factorised %d free vertices in %.1f ms", solver.n_free, 1000 * solver.factor_seconds)
        self._solvers[key] = solver
        keep = 2 if len(V) <= SOLVER_CACHE_VERTICES else 1
        while len(self._solvers) > keep:
            self._solvers.popitem(last=False)
        return solver


def points_in_tetrahedra(points: PointConstraints, F: np.ndarray, T: np.ndarray,
                         owner: np.ndarray) -> PointConstraints:
    """Point handles on boundary triangles ``F`` of a solid as points in the tetrahedra ``T`` behind them
    (``owner``): the same positions, with a zero coordinate at each tetrahedron's fourth corner.

    Example
    -------
    >>> p = PointConstraints(np.array([0]), np.array([[0.2, 0.3, 0.5]]), np.array([np.inf]))
    >>> points_in_tetrahedra(p, np.array([[1, 2, 3]]), np.array([[0, 1, 2, 3]]), np.array([0])).barycentric.tolist()
    [[0.0, 0.2, 0.3, 0.5]]
    """
    corners = F[points.faces]
    tets = T[owner[points.faces]]
    match = tets[:, :, None] == corners[:, None, :]
    barycentric = (match * points.barycentric[:, None, :]).sum(axis=2)
    return PointConstraints(owner[points.faces], barycentric, points.weights)


def _on_plane(points: Any) -> Any:
    """``points`` (k, 3) with z = 0 (other shapes as given)."""
    if points is None:
        return None
    flat = np.array(points, dtype=np.float64)
    if flat.ndim == 2 and flat.shape[1:] == (3,):
        flat[:, 2] = 0.0
    return flat


class PlaneSolver:
    """A solver of a flat mesh in ``z = 0`` (a picture) whose targets are put back on the plane (the studio's handles
    can be dragged in any direction), in one of the puppet warp's modes (:data:`arap.puppet.warp.MODES`):
    ``rigid`` is the element ARAP energy itself, ``normal`` and ``distort`` the hybrid energy of
    :mod:`arap.puppet.blend` (λ = 1 and λ = 0) in ARAP's solve on its factorisation (``distort``: one linear solve,
    :mod:`arap.puppet.similar`).

    Parameters
    ----------
    solver : ArapSolver
        Of the flat mesh with the element energy, factorised for the constraints.
    mode : str
        The warp's mode.
    """

    def __init__(self, solver: ArapSolver, mode: str = "rigid") -> None:
        from arap.puppet.blend import NORMAL_LAMBDA, BlendSolver

        self.mode = mode
        self.inner = solver
        self._blend: BlendSolver | None = None if mode == "rigid" else \
            BlendSolver(solver, NORMAL_LAMBDA if mode == "normal" else 0.0)
        self.n_free = solver.n_free
        self.factor_seconds = solver.factor_seconds if self._blend is None else self._blend.factor_seconds

    @property
    def V(self) -> NDArray[np.float64]:
        """The rest positions (:attr:`arap.ArapSolver.V`)."""
        return self.inner.V

    @property
    def F(self) -> NDArray[np.int64]:
        """The triangles (:attr:`arap.ArapSolver.F`)."""
        return self.inner.F

    @property
    def energy_type(self) -> EnergyType:
        """The energy, ``"elements"`` (:attr:`arap.ArapSolver.energy_type`)."""
        return self.inner.energy_type

    def solve(self, targets: Any, initial: Any = None, max_iterations: int | None = None,
              tolerance: float = DEFAULT_TOLERANCE, callback: Any = None, acceleration: Any = "lbfgs",
              window: int | None = None, point_targets: Any = None) -> ArapResult:
        """:meth:`arap.ArapSolver.solve` with the targets on the plane, in the solver's mode."""
        kind: ArapSolver | BlendSolver = self.inner if self._blend is None else self._blend
        return kind.solve(_on_plane(targets), initial=initial, max_iterations=max_iterations, tolerance=tolerance,
                          callback=callback, acceleration=acceleration, window=window,
                          point_targets=_on_plane(point_targets))

    def current_vertices(self) -> np.ndarray:
        """The current iterate during :meth:`solve`, else the last solution."""
        return (self.inner if self._blend is None else self._blend).current_vertices()


StudioSolver: TypeAlias = ArapSolver | PlaneSolver
"""A studio session's factorised solver: a mesh's (:class:`arap.ArapSolver`) or a picture's (:class:`PlaneSolver`)."""


def plane_solver(solver: ArapSolver, mode: str) -> PlaneSolver:
    """The studio's solver of a picture (see :class:`PlaneSolver`).

    Raises
    ------
    ArapError
        An unknown mode.
    """
    from arap.puppet.warp import MODES

    if mode not in MODES:
        raise ArapError(f"unknown warp mode {mode!r}; expected one of {', '.join(MODES)}")
    return PlaneSolver(solver, mode)
