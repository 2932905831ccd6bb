"""One studio editing session: what it holds (the mesh, rest pose, shape, constraint set, solver and parameters, the
undo history, the keyframes' kept shapes) and its requests: load a mesh, set constraints, drag, settle, change
parameters, undo, redo, reset, apply, export and describe the constraints.

A :class:`Session` is synchronous and not thread-safe: the server calls it from one worker at a time (on a
thread, since solves and factorisations take a while). Every request either succeeds or raises a
:class:`~arap.server.session_errors.SessionError` and leaves the session unchanged; the session knows nothing of
the wire protocol (the transports' layer turns its refusals into ``error`` messages). Its state is its own: other
modules read its attributes and change them only through its methods.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable
from dataclasses import asdict
from typing import Any

import numpy as np

from arap.errors import ArapError
from arap.meshes.domain import check_domain
from arap.meshes.mesh import bounding_box
from arap.method.weights import WeightType
from arap.options import EnergyType, LoosePartsMode
from arap.render.show import show
from arap.server.appearance import Look, export_asset
from arap.server.constraints import ConstraintSet, identity_transforms, matrices_from_json, turn_of
from arap.server.history import History, Snapshot
from arap.server.mesh_model import MeshData
from arap.server.numbering import document_in_file_numbering, message_in_file_numbering
from arap.server.records import DragOutcome, Params, SettleOutcome
from arap.server.session_errors import BadValues, ConstraintsRejected, NoMesh, SolveFailed, UnusableMesh
from arap.server.settling import FrameCallback
from arap.server.solve_calls import check_target_range, checked_settle, solve_for_targets
from arap.server.solvers import SolverCache, StudioSolver

__all__ = ["MAX_KEPT_SHAPES", "Session"]

logger = logging.getLogger(__name__)

MAX_KEPT_SHAPES = 64
"""Most keyframe shapes a session keeps (:meth:`Session.keep_shape`); the oldest goes first."""
_KEPT_AT_TARGETS = 1e-9
"""How far (per bounding-box diagonal) a kept shape's constrained vertices may be from the targets it is given for."""
_GIVEN_AT_TARGETS = 2.0**-18
"""How far (per largest rest coordinate) the constrained vertices of a shape the client gave back may be from the
targets: it knows shapes as float32 frames, and a restored timeline poses them with transforms rebased on them."""


class Session:
    """One client's editing session.

    Parameters
    ----------
    max_history_steps : int
        Undo steps kept.
    max_history_bytes : int
        Memory budget of the undo history.
    """

    def __init__(self, max_history_steps: int = 100, max_history_bytes: int = 512 * 2**20) -> None:
        self.mesh: MeshData | None = None
        """The loaded mesh (None before the first :meth:`load`)."""
        self.look: Look | None = None
        """The mesh file's colours, texture and render mesh (None for a plain mesh)."""
        self.params: Params = Params()
        """The solver's parameters (kept across meshes)."""
        self.history: History = History(max_history_steps, max_history_bytes)
        """The undo history: one snapshot of the state per step."""
        self.rest_id: int = 0
        """Number of the rest pose ``V``: a new one with each mesh and each :meth:`apply`."""
        self._rest_counter: int = 0
        """The last rest pose number handed out."""
        self.V: np.ndarray = np.zeros((0, 3))
        """The rest pose, (n, 3), never modified in place."""
        self.U: np.ndarray = self.V
        """The deformed shape shown, (n, 3), never modified in place (a new shape is a new array)."""
        self.constraints: ConstraintSet = ConstraintSet.empty(self.V)
        """The constraint set: region, fixed vertices, handle groups and point handles, on the pose it was made on."""
        self.transforms: np.ndarray = identity_transforms(0)
        """One 4×4 transform per handle group, then per point handle, relative to the constraint set's pose."""
        self._solvers: SolverCache = SolverCache()
        """The factorised solvers of the constraint sets used last."""
        self.solver: StudioSolver | None = None
        """The factorised solver of the current constraints (None when nothing is constrained or they cannot be
        solved)."""
        self._unsolvable: str | None = None
        """Why the solver rejected the constraints an undo or redo restored (``solver`` is then None)."""
        self._warm: bool = False
        """Whether the solver's last solution is the shape ``U`` (the next solve starts from it)."""
        self._dirty: bool = False
        """Whether the shape moved since the last history step (a drag under way)."""
        self.solves: int = 0
        """Solves run for drags, loaded targets and pins' angles (settling runs not counted)."""
        self.settled: bool = True
        """Whether the shape is converged for the constraints (or settling gave up on it): nothing to settle."""
        self.energy: float | None = 0.0
        """Energy of the shape ``U`` when known (0 at a rest pose)."""
        self._diagonal: tuple[int, float] = (-1, 0.0)
        """The rest pose's number and its bounding-box diagonal, computed once per rest pose."""
        self.pin_depth: list[int] = []
        """A picture's depth per point handle (pin): larger ones' parts are drawn over smaller ones' (none: 0)."""
        self.kept_shapes: dict[int, np.ndarray] = {}
        """The shapes kept as keyframes' (:meth:`keep_shape`), by the keyframe's number, oldest first."""
        self._given_shapes: set[int] = set()
        """The keys of :attr:`kept_shapes` whose shape the client gave (float32 frames), not the session's own."""

    # ------------------------------------------------------------------ what the state tells
    @property
    def n_vertices(self) -> int:
        """Vertices of the current mesh (0 without one)."""
        return 0 if self.mesh is None else self.mesh.n_vertices

    @property
    def scale(self) -> float:
        """Largest absolute rest coordinate (1 without a mesh): the size float32 frames resolve against."""
        return max(float(np.abs(self.V).max(initial=0.0)), 1e-300) if self.mesh is not None else 1.0

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal of the rest pose (0 without a mesh)."""
        if self.mesh is None or not len(self.V):
            return 0.0
        if self._diagonal[0] != self.rest_id:
            lo, hi = bounding_box(self.V)
            self._diagonal = (self.rest_id, float(np.linalg.norm(hi - lo)))
        return self._diagonal[1]

    @property
    def n_groups(self) -> int:
        """Handle groups of the current constraint set."""
        return self.constraints.n_groups

    @property
    def needs_settle(self) -> bool:
        """True when the shape may not be converged and no drag is under way (see :meth:`settle`)."""
        return not self.settled and not self._dirty and self.solver is not None and self.mesh is not None

    @property
    def can_undo(self) -> bool:
        """Whether undo has a step to go back to (an unfinished drag counts as one)."""
        return self.history.can_undo or self._dirty

    @property
    def can_redo(self) -> bool:
        """Whether redo has a step to go forward to (not during a drag)."""
        return self.history.can_redo and not self._dirty

    def require_mesh(self) -> MeshData:
        """The loaded mesh.

        Raises
        ------
        NoMesh
            No mesh is loaded.
        """
        if self.mesh is None:
            raise NoMesh("no mesh is loaded")
        return self.mesh

    def solver_moved_on(self) -> None:
        """The solver was used for other shapes (an animation export): the next solve starts from the shape shown,
        not from the solver's last solution."""
        self._warm = False

    # ------------------------------------------------------------------ the bookkeeping the requests share
    def _new_rest_id(self) -> int:
        self._rest_counter += 1
        return self._rest_counter

    def _solver_for(self, rest_id: int, V: np.ndarray, cs: ConstraintSet, params: Params) -> StudioSolver | None:
        """A factorised solver for the constraint set (cached), or None when nothing is constrained.

        Raises ConstraintsRejected when the solver rejects the constraints.
        """
        try:
            mesh = self.require_mesh()
            solid = None if mesh.elements is None or mesh.face_owner is None else (mesh.elements, mesh.face_owner)
            return self._solvers.get(rest_id, V, mesh.F, cs, params, solid, planar=mesh.picture is not None)
        except ConstraintsRejected as exc:
            raise self._in_file_numbering(exc) from exc.__cause__

    def _in_file_numbering(self, exc: ConstraintsRejected) -> ConstraintsRejected:
        """``exc`` with the vertices its message names numbered as in the mesh file (the user's numbering)."""
        message = message_in_file_numbering(exc.message, self.mesh)
        if message == exc.message:
            return exc
        return type(exc)(message)

    def _build(self, rest: np.ndarray, pose: np.ndarray, roi: Any, fixed: Any, groups: Any,
               **kwargs: Any) -> ConstraintSet:
        """:meth:`ConstraintSet.build` for the current mesh, its errors naming vertices in the file's numbering."""
        try:
            return ConstraintSet.build(rest, pose, roi, fixed, groups, faces=self.require_mesh().F, **kwargs)
        except ConstraintsRejected as exc:
            raise self._in_file_numbering(exc) from exc.__cause__

    def _snapshot(self) -> Snapshot:
        return Snapshot(self.rest_id, self.V, self.U, self.constraints, self.transforms, self.settled,
                        self.energy)

    def _restore(self, snap: Snapshot) -> None:
        self._unsolvable = None
        try:
            solver = self._solver_for(snap.rest_id, snap.V, snap.constraints, self.params)
        except ConstraintsRejected as exc:
            logger.warning("restored constraints cannot be solved with the current parameters: %s", exc.message)
            solver = None
            self._unsolvable = (f"the constraints of this step cannot be solved with the {self.params.energy} "
                                f"energy and {self.params.weights} weights: {exc.message}")
        self.rest_id, self.V, self.U = snap.rest_id, snap.V, snap.U
        self.constraints, self.transforms = snap.constraints, snap.transforms
        self.solver = solver
        self._warm = False
        self._dirty = False
        self.settled = snap.settled
        self.energy = snap.energy

    def _commit(self) -> None:
        """Record the current state as a new history step."""
        self.history.push(self._snapshot())
        self._dirty = False

    def _commit_pending_drag(self) -> None:
        if self._dirty:
            self._commit()

    # ------------------------------------------------------------------ the requests
    def load(self, mesh: MeshData, look: Look | None = None) -> None:
        """Replace the mesh (and its file's colours and texture); constraints, transforms and history start afresh
        (parameters are kept)."""
        self.mesh = mesh
        self.look = look
        self._solvers.clear()
        self.solver = None
        self.rest_id = self._new_rest_id()
        self.V = mesh.V
        self.U = mesh.V
        self.constraints = ConstraintSet.empty(self.U)
        self.transforms = identity_transforms(0)
        self._warm = False
        self._dirty = False
        self.settled = True
        self.energy = 0.0
        self.kept_shapes.clear()
        self._given_shapes.clear()
        self.pin_depth = []
        self.history.clear(self._snapshot())

    def set_constraints(self, roi: list[int] | None, fixed: list[int], groups: list[list[int]],
                        targets: list[list[float]] | None = None,
                        stiffness: list[dict[str, Any]] | None = None,
                        points: list[dict[str, Any]] | None = None) -> DragOutcome | None:
        """New constraint set referring to the current deformed pose; transforms reset to identity.

        Parameters
        ----------
        roi : list of int or None
        fixed : list of int
        groups : list of lists of int
            Handle groups.
        targets : list of [x, y, z] or None
            Positions of the handle vertices (groups concatenated) that replace their pose positions as the
            base of the transforms; the shape is then solved at once.
        stiffness : list of {"vertices": [...], "value": v} or None
            Painted stiffness (v > 0 or ``"rigid"``, 1 elsewhere), as in constraints files; None: all 1.
        points : list of {"face", "barycentric", "weight"?, "target"?} or None
            Point handles (no weight: hard), each a handle group of its own whose transform follows the groups'.
            A ``target`` replaces the point's pose position as the base of its transform (the shape is then
            solved at once, as with ``targets``).

        Returns
        -------
        DragOutcome or None
            The solve that moved the handles to ``targets``, or None when nothing was solved.

        Raises
        ------
        ConstraintsRejected
            Invalid indices or constraints the solver rejects.
        BadValues
            Targets of the wrong shape or absurdly far away.
        """
        self.require_mesh()
        positions = None
        n_handles = sum(len(g) for g in groups)
        if targets is not None:
            given = np.asarray(targets, dtype=np.float64)
            if given.shape != (n_handles, 3) and not (n_handles == 0 and given.size == 0):
                raise BadValues(f"targets must be {n_handles} points [x, y, z], one per handle vertex")
            self._check_range(given)
            positions = given if n_handles else None
        cs = self._build(self.V, self.U, roi, fixed, groups, handle_positions=positions, stiffness=stiffness,
                         points=points)
        cs = self._with_angles(cs, self._carried_angles(cs))
        moved = positions is not None or any("target" in p for p in points or [])
        if moved:
            self._check_range(cs.point_pose)
        unchanged = (not moved and cs.same_selection(self.constraints) and self.constraints.pose is self.U
                     and np.array_equal(self.transforms, identity_transforms(cs.n_groups)))
        if unchanged:
            return None
        solver = self._solver_for(self.rest_id, self.V, cs, self.params)
        T = identity_transforms(cs.n_groups)
        outcome = None
        U = self.U
        if moved:
            assert solver is not None
            # Loaded targets can be far from the current shape: iterate until the energy settles, not one drag's worth.
            U, outcome = self._solve(solver, cs.targets(T), self.U, settle=True,
                                     point_targets=cs.solver_point_targets(T))
        self.constraints = cs
        self.transforms = T
        self.solver = solver
        self.U = U
        self._warm = moved
        self.settled = False
        self.energy = outcome.energies[-1] if outcome is not None and outcome.energies else None
        self._commit()
        return outcome

    def _carried_angles(self, cs: ConstraintSet) -> list[float | None]:
        """Per point handle of ``cs`` (a new set on the current shape), the angle the same pin (same triangle and
        coordinates) holds now, or None."""
        old = self.constraints
        if old.rings is None or old.points is None or cs.points is None:
            return [None] * cs.n_points
        now = {(int(f), tuple(b.tolist())): a for f, b, a in zip(old.points.faces, old.points.barycentric,
                                                                 old.pin_angles(self.transforms), strict=True)}
        return [now.get((int(f), tuple(b.tolist()))) for f, b in zip(cs.points.faces, cs.points.barycentric,
                                                                       strict=True)]

    def _with_angles(self, cs: ConstraintSet, angles: list[float | None], rest: np.ndarray | None = None
                     ) -> ConstraintSet:
        """``cs`` whose pins hold ``angles`` (radians under identity transforms; None: turn freely), with their
        hidden rings on the rest pose ``rest`` (None: the session's; :func:`arap.server.pictures.pin_rings`).

        Raises
        ------
        BadValues
            A pin too near the picture's edge to hold an angle.
        """
        if cs.points is None or all(a is None for a in angles):
            return cs if cs.rings is None else dataclasses.replace(cs, rings=None)
        from arap.server.pictures import pin_rings

        return dataclasses.replace(cs, rings=pin_rings(self.V if rest is None else rest, self.require_mesh().F,
                                                       cs.points, angles))

    def _check_range(self, points: np.ndarray) -> None:
        check_target_range(points, self.V)

    def _solve(self, solver: StudioSolver, targets: np.ndarray, initial: np.ndarray | None,
               settle: bool = False, point_targets: np.ndarray | None = None) -> tuple[np.ndarray, DragOutcome]:
        """:func:`~arap.server.solve_calls.solve_for_targets` with the session's parameters; the positions and the
        outcome, the session unchanged but for the count of solves (and no warm start after a failed one)."""
        try:
            U, outcome = solve_for_targets(solver, self.params, targets, initial, settle, point_targets)
        except SolveFailed:
            self._warm = False
            raise
        self.solves += 1
        return U, outcome

    def keep_shape(self, key: int, shape: list[list[float]] | None = None) -> None:
        """Keep the shape shown as keyframe ``key``'s: a drag or an animation export at that keyframe gives it back
        (:meth:`kept_shape`) instead of solving the pose again, which could end in another shape. At most
        :data:`MAX_KEPT_SHAPES` are kept.

        ``shape``: one ``[x, y, z]`` per vertex, kept instead of the shape shown: a keyframe's shape the client keeps
        and gives back to a new session (after the connection was lost, or a saved session restored).

        Raises
        ------
        BadValues
            ``shape`` does not have one finite point per vertex, or lies absurdly far away.
        """
        self.require_mesh()
        if shape is None:
            kept = np.array(self.U, dtype=np.float64)
        else:
            kept = np.array(shape, dtype=np.float64)
            if kept.shape != (len(self.V), 3):
                raise BadValues(f"a kept shape must be {len(self.V)} points [x, y, z], one per vertex")
            self._check_range(kept)
            kept = np.ascontiguousarray(kept[:, :self.V.shape[1]])
        kept.setflags(write=False)
        shapes = self.kept_shapes
        shapes.pop(key, None)
        shapes[key] = kept
        given = self._given_shapes
        given.discard(key)
        if shape is not None:
            given.add(key)
        while len(shapes) > MAX_KEPT_SHAPES:
            oldest = next(iter(shapes))
            shapes.pop(oldest)
            given.discard(oldest)

    def kept_shape(self, key: int | None, targets: np.ndarray) -> np.ndarray | None:
        """Keyframe ``key``'s kept shape when its constrained vertices are at ``targets`` (in the order of the
        constraint set's ``constrained``), else None (none kept, another mesh, or the pose is not that keyframe's)."""
        shape = None if key is None else self.kept_shapes.get(int(key))
        if shape is None or shape.shape != self.V.shape:
            return None
        constrained = self.constraints.constrained
        off = float(np.abs(shape[constrained] - targets).max(initial=0.0))
        slack = _KEPT_AT_TARGETS * self.diagonal + 1e-12 * self.scale
        if key is not None and int(key) in self._given_shapes:
            slack = max(slack, _GIVEN_AT_TARGETS * self.scale)
        return shape if off <= slack else None

    def drag(self, transforms: list[list[float]], key: int | None = None) -> DragOutcome:
        """Move the handle groups by ``transforms`` (column-major 4×4 each) and solve; or, when ``key`` names a
        keyframe whose kept shape (:meth:`keep_shape`) has its handles where ``transforms`` put them, show that shape
        (the next solve starts from it).

        Raises
        ------
        ConstraintsRejected
            Nothing is constrained.
        BadValues
            The targets are not finite, or absurdly far away.
        """
        self.require_mesh()
        if len(transforms) != self.n_groups:
            raise BadValues(f"drag has {len(transforms)} transforms but the constraints have {self.n_groups} handle "
                            "groups")
        if self.solver is None:
            if self._unsolvable is not None and not self.constraints.is_empty:
                raise ConstraintsRejected(self._unsolvable)
            raise ConstraintsRejected("nothing to solve: select fixed vertices or handles first")
        T = matrices_from_json(transforms)
        targets = self.constraints.targets(T)
        point_targets = self.constraints.solver_point_targets(T)
        self._check_range(targets)
        if point_targets is not None:
            self._check_range(point_targets)
        kept = self.kept_shape(key, targets)
        if kept is not None:
            self.U, self.energy, self.transforms = kept, None, T
            self._warm = False  # the next solve starts from the kept shape
            self._dirty = True
            self.settled = True  # what was kept is not solved again
            return DragOutcome(0, [], 0.0)
        U, outcome = self._solve(self.solver, targets, None if self._warm else self.U, point_targets=point_targets)
        self.U = U
        self.energy = outcome.energies[-1] if outcome.energies else None
        self.transforms = T
        self._warm = True
        self._dirty = True
        self.settled = False
        return outcome

    def settle(self, interrupted: Callable[[], bool],
               on_frame: FrameCallback | None = None) -> SettleOutcome | None:
        """Iterate the current constraints until converged, unless :attr:`settled` already.

        Parameters
        ----------
        interrupted : callable
            Polled after every iteration; True stops at once (a new request is waiting). The shape reached so far
            is kept: it is what the client was shown, and settling resumes from it later.
        on_frame : callable or None
            ``on_frame(vertices, iteration, energy)``, at most every
            :data:`~arap.server.settling.SETTLE_FRAME_SECONDS`; ``vertices`` is None when no vertex moved more than
            :data:`~arap.server.settling.SETTLE_FRAME_MOTION` of the diagonal since the last vertices given.

        Returns
        -------
        SettleOutcome or None
            None when there was nothing to settle (or a drag has not ended). A converged shape also replaces the
            current undo step, so undo and redo come back to settled shapes.
        """
        solver = self.solver
        if self._dirty:
            return None  # a drag is under way: it settles when it ends
        if self.settled or solver is None or self.mesh is None:
            self.settled = True
            return None
        t0 = time.perf_counter()
        try:
            result, stopped = checked_settle(solver, self.constraints.targets(self.transforms),
                                             self.constraints.solver_point_targets(self.transforms),
                                             None if self._warm else self.U, self.U, self.diagonal, interrupted,
                                             on_frame)
        except SolveFailed:
            self._warm = False
            self.settled = True
            raise
        except BadValues:
            self.settled = True
            raise
        moved = float(np.abs(result.vertices - self.U).max(initial=0.0))
        if moved > 1e-12 * self.scale:
            self.U = result.vertices
        else:
            moved = 0.0  # the shape is kept as it was, free of rounding noise
        self._warm = True
        # Settling resumes after an interruption; a run that used up its iterations is not repeated.
        self.settled = not stopped
        if result.energies:
            self.energy = float(result.energies[-1])
        if result.converged:
            self.history.replace_current(self._snapshot())
        return SettleOutcome(result.iterations, self.energy, result.converged, time.perf_counter() - t0, moved,
                             interrupted=stopped)

    def end_drag(self) -> bool:
        """Make the deformation since the last step an undo step; True if there was one."""
        dirty = self._dirty
        self._commit_pending_drag()
        return dirty

    def set_params(self, iterations: int | None = None, energy: EnergyType | None = None,
                   weights: WeightType | None = None, alpha: float | None = None,
                   loose: LoosePartsMode | None = None, warp: str | None = None) -> None:
        """Change solver parameters; a new energy, weighting or loose-parts mode refactorises, and so does a new
        warp mode for a picture.

        Raises
        ------
        ConstraintsRejected
            The current constraints cannot be solved with the new parameters.
        """
        new = Params(**asdict(self.params))
        if iterations is not None:
            new.iterations = iterations
        if energy is not None:
            new.energy = energy
        if weights is not None:
            new.weights = weights
        if alpha is not None:
            new.alpha = float(alpha)
        if loose is not None:
            new.loose = loose
        if warp is not None:
            new.warp = warp
        changed = (new.energy, new.weights, new.loose) != (self.params.energy, self.params.weights,
                                                           self.params.loose) or (
            new.energy == "smooth_rotations" and new.alpha != self.params.alpha) or (
            new.warp != self.params.warp and self.mesh is not None and self.mesh.picture is not None)
        if changed and self.mesh is not None:
            self.solver = self._solver_for(self.rest_id, self.V, self.constraints, new)
            self._warm = False
            self.settled = False
            self.energy = None  # another energy: known once settled
        self.params = new

    def undo(self) -> bool:
        """Step back in the history (an unfinished drag becomes a step first); True if something changed."""
        self.require_mesh()
        self._commit_pending_drag()
        snap = self.history.undo()
        if snap is None:
            return False
        self._restore(snap)
        return True

    def redo(self) -> bool:
        """Step forward in the history; True if something changed."""
        self.require_mesh()
        if self._dirty:
            return False
        snap = self.history.redo()
        if snap is None:
            return False
        self._restore(snap)
        return True

    def reset(self) -> None:
        """Back to the rest pose, keeping the selection (an undo step)."""
        self.require_mesh()
        self._commit_pending_drag()
        old = self.constraints
        at_rest = (self.U is self.V and old.pose is self.V
                   and np.array_equal(self.transforms, identity_transforms(old.n_groups)))
        if at_rest:
            return
        groups = [g.tolist() for g in old.groups]
        roi = None if old.roi is None else old.roi.tolist()
        cs = self._build(self.V, self.V, roi, old.fixed.tolist(), groups, stiffness=old.stiffness_json(),
                         points=old.points_json())
        cs = self._with_angles(cs, [None if a is None else 0.0 for a in old.pin_angles(self.transforms)])
        self.solver = self._solver_for(self.rest_id, self.V, cs, self.params)
        self.U = self.V
        self.constraints = cs
        self.transforms = identity_transforms(cs.n_groups)
        self._warm = False
        self.settled = False
        self.energy = None
        self._commit()

    def apply(self) -> None:
        """Make the deformed shape the new rest pose, keeping the selection (an undo step)."""
        mesh = self.require_mesh()
        self._commit_pending_drag()
        V = np.array(self.U, dtype=np.float64)
        V.setflags(write=False)
        try:
            check_domain(V, mesh.solve_elements)
        except ArapError as exc:
            raise UnusableMesh(f"the deformed shape cannot become the rest pose: {exc}") from exc
        old = self.constraints
        cs = self._build(V, V, None if old.roi is None else old.roi.tolist(), old.fixed.tolist(),
                         [g.tolist() for g in old.groups], stiffness=old.stiffness_json(), points=old.points_json())
        cs = self._with_angles(cs, [None if a is None else 0.0 for a in old.pin_angles(self.transforms)], rest=V)
        rest_id = self._new_rest_id()
        self.solver = self._solver_for(rest_id, V, cs, self.params)
        self.rest_id, self.V, self.U = rest_id, V, V
        self.constraints = cs
        self.transforms = identity_transforms(cs.n_groups)
        self._warm = False
        self.settled = True  # the rest pose itself: no energy, nothing to settle
        self.energy = 0.0
        self._commit()

    def export(self, fmt: str) -> tuple[str, str, bytes]:
        """The deformed mesh as a file: ``(filename, mime, bytes)``; GLB, and the source's own format, keep the file's
        UVs, textures and colours (:func:`arap.server.appearance.export_asset`)."""
        mesh = self.require_mesh()
        try:
            if fmt == "png":
                return f"{mesh.name}-deformed.png", "image/png", self._picture()
            return export_asset(mesh.name, self.U, mesh.F, self.look, fmt)
        except ArapError as exc:
            raise UnusableMesh(f"cannot export: {exc}") from exc

    def _picture(self) -> bytes:
        """PNG: a picture's warp at its resolution, else a picture of the deformed shape (:func:`arap.show`)."""
        mesh = self.require_mesh()
        if mesh.picture is not None:
            from arap.server.pictures import warped_picture_png

            return warped_picture_png(mesh, self.U, self.constraints.points, self.pin_depth)
        return bytes(show(self.U, mesh.F, width=1024, height=768).png())

    def set_pin_depth(self, depth: list[int]) -> None:
        """A picture's depth per pin (point handle, in their order): where parts overlap, the part of the pin of
        larger depth is drawn over the other (Export PNG); pins beyond the list have depth 0."""
        self.require_mesh()
        self.pin_depth = [int(d) for d in depth]

    def pin_angles(self) -> list[float | None]:
        """Per pin (point handle, in their order), the angle in degrees (counter-clockwise as seen, from the picture
        as opened) by which it holds its surroundings turned about it, or None for a pin whose surroundings turn
        freely with the bend."""
        return [None if a is None else math.degrees(a) for a in self.constraints.pin_angles(self.transforms)]

    def set_pin_angle(self, pin: int, angle: float | None = None) -> DragOutcome:
        """Make a picture's pin hold its surroundings turned by ``angle`` degrees about it (counter-clockwise as seen,
        from the picture as opened; None: the angle they show now), as Photoshop's fixed pin rotation: a hidden
        ring of points about the pin moves with it, turned by that angle (:func:`arap.puppet.rings.pin_rings`);
        a turn of the pin's transform about z (a drag that turns it about itself) adds to the angle. The shape is
        solved at once; like a drag, the change becomes an undo step with the next :meth:`end_drag`.

        Raises
        ------
        UnusableMesh
            The mesh is not a picture's.
        BadValues
            No such pin, or a pin too near the picture's edge to hold an angle.
        ConstraintsRejected
            The constraints cannot be solved.
        """
        from arap.server.pictures import pin_turn

        mesh = self.require_mesh()
        if mesh.picture is None:
            raise UnusableMesh("only a picture's pins hold angles")
        cs = self.constraints
        if cs.points is None or not 0 <= pin < cs.n_points:
            raise BadValues(f"there is no pin {pin}: the picture has {cs.n_points} pins")
        if angle is not None and not math.isfinite(angle):
            raise BadValues("the angle must be a finite number of degrees")
        held = cs.pin_angles(self.transforms)
        if angle is not None:
            now = math.radians(angle)
        else:
            found = held[pin]
            now = pin_turn(self.V, self.U, mesh.F, cs.points, pin) if found is None else found
        turn = float(turn_of(self.transforms[len(cs.groups) + pin])[0])
        bases: list[float | None] = list(cs.rings.angles) if cs.rings is not None else [None] * cs.n_points
        bases[pin] = now - turn
        new = self._with_angles(cs, bases)
        solver = self._solver_for(self.rest_id, self.V, new, self.params)
        assert solver is not None  # the pins are constraints
        U, outcome = self._solve(solver, new.targets(self.transforms), self.U,
                                 point_targets=new.solver_point_targets(self.transforms))
        self.constraints, self.solver, self.U = new, solver, U
        self.energy = outcome.energies[-1] if outcome.energies else None
        self._warm = True
        self._dirty = True
        self.settled = False
        return outcome

    def remesh(self, density: str, max_vertices: int) -> MeshData:
        """Mesh a picture again at ``density`` (:data:`arap.server.pictures.DENSITIES`), keeping its pins: each stays
        at its place on the picture and keeps its weight, its target (where it is now) and its depth; the other
        constraints and the history start afresh (as on :meth:`load`). Returns the new mesh.

        Raises
        ------
        UnusableMesh
            When the mesh is not a picture's.
        """
        from arap.puppet.rings import locate_points
        from arap.server.pictures import picture_mesh

        mesh = self.require_mesh()
        if mesh.picture is None:
            raise UnusableMesh("only a picture's mesh can be meshed again")
        new, look = picture_mesh(np.array(mesh.picture), mesh.name, max_vertices, density=density)
        old = self.constraints.points
        pins: list[dict[str, Any]] = []
        if old is not None and len(old.faces):
            corners = mesh.F[old.faces]
            rest = np.einsum("kc,kcd->kd", old.barycentric, self.V[corners])
            now = np.einsum("kc,kcd->kd", old.barycentric, self.U[corners])
            faces, bary = locate_points(new.V, new.F, rest)
            for k in range(len(faces)):
                pin: dict[str, Any] = {"face": int(faces[k]), "barycentric": bary[k].tolist(),
                                       "target": now[k].tolist()}
                if np.isfinite(old.weights[k]):
                    pin["weight"] = float(old.weights[k])
                pins.append(pin)
        depth = self.pin_depth
        angles = self.pin_angles()
        self.load(new, look)
        self.pin_depth = depth
        if pins:
            self.set_constraints(None, [], [], points=pins)
            for k, angle in enumerate(angles):
                if angle is not None:
                    self.set_pin_angle(k, angle)
            if self._dirty:
                self.history.replace_current(self._snapshot())  # the pins with their angles: one step
                self._dirty = False
        return new

    def constraints_document(self) -> dict[str, Any]:
        """The current constraints in the command-line format, in the mesh file's vertex numbering (as ``arap
        deform`` reads them; :func:`arap.server.numbering.document_in_file_numbering`); with the timeline's keyframes,
        :func:`arap.server.animation_export.keyframes_document`. A picture's pins carry the angles they hold and
        their depths (:data:`arap.constraints.entries.PIN_KEYS`)."""
        from arap.constraints.entries import pin_entries

        mesh = self.require_mesh()
        doc = self.constraints.document(self.V, self.transforms)
        if doc.get("points"):
            doc["points"] = pin_entries(doc["points"], self.pin_angles(), self.pin_depth)
        return document_in_file_numbering(doc, mesh)
