"""What a studio session holds, and the bookkeeping every request shares: the mesh, rest pose, shape, constraint
set, solver and parameters, the undo history's snapshots, and the refusals of constraint sets and solvers with their
vertices numbered as in the mesh file.

:class:`SessionState` is the base of :class:`arap.server.session.Session`, whose methods are the requests; it is
kept apart so that the requests read as what they change, not how the state is kept consistent.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from arap.meshes.mesh import bounding_box
from arap.server.appearance import Look
from arap.server.constraints import ConstraintSet, identity_transforms
from arap.server.history import History, Snapshot
from arap.server.mesh_model import MeshData
from arap.server.numbering import message_in_file_numbering
from arap.server.records import Params
from arap.server.session_errors import ConstraintsRejected, NoMesh
from arap.server.solvers import SolverCache

__all__ = ["SessionState"]

logger = logging.getLogger("arap.server.session")


class SessionState:
    """What one client's editing session holds (see :class:`arap.server.session.Session` for its requests).

    Parameters
    ----------
    max_history_steps : int
        Undo steps kept.
    max_history_bytes : int
        Memory budget of the undo history.
    """

    def __init__(self, max_history_steps: int = 100, max_history_bytes: int = 512 * 2**20) -> None:
        self.mesh: MeshData | None = None
        self.look: Look | None = None
        """The mesh file's colours, texture and render mesh (None for a plain mesh)."""
        self.params = Params()
        self.history = History(max_history_steps, max_history_bytes)
        self._rest_counter = 0
        self._solvers = SolverCache()
        self.solver: Any = None
        self._unsolvable: str | None = None
        """Why the solver rejected the constraints an undo or redo restored (``solver`` is then None)."""
        self._warm = False
        self._dirty = False
        self.rest_id = 0
        self.V = np.zeros((0, 3))
        self.U = self.V
        self.constraints = ConstraintSet.empty(self.V)
        self.transforms = identity_transforms(0)
        self.solves = 0
        self.settled = True
        self.energy: float | None = 0.0
        """Energy of the shape ``U`` when known (0 at a rest pose)."""
        self._diagonal = (-1, 0.0)  # (rest_id, the rest pose's bounding-box diagonal)
        self.pin_depth: list[int] = []
        """A picture's depth per point handle (pin): larger ones' parts are drawn over smaller ones' (none: 0)."""

    def _require_mesh(self) -> MeshData:
        if self.mesh is None:
            raise NoMesh("no mesh is loaded")
        return self.mesh

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

    def _new_rest_id(self) -> int:
        self._rest_counter += 1
        return self._rest_counter

    def _solver_for(self, rest_id: int, V: np.ndarray, cs: ConstraintSet, params: Params) -> Any:
        """A factorised solver for the constraint set (cached), or None when nothing is constrained.

        Raises ConstraintsRejected when the solver rejects the constraints.
        """
        try:
            mesh = self._require_mesh()
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
            return ConstraintSet.build(rest, pose, roi, fixed, groups, faces=self._require_mesh().F, **kwargs)
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

    @property
    def needs_settle(self) -> bool:
        """True when the shape may not be converged and no drag is under way (see
        :meth:`arap.server.session.Session.settle`)."""
        return not self.settled and not self._dirty and self.solver is not None and self.mesh is not None

    def solver_moved_on(self) -> None:
        """The solver was used for other shapes (an animation export): the next solve starts from the shape shown,
        not from the solver's last solution."""
        self._warm = False

    @property
    def can_undo(self) -> bool:
        """Whether undo has a step to go back to (an unfinished drag counts as one)."""
        return self.history.can_undo or self._dirty

    @property
    def can_redo(self) -> bool:
        return self.history.can_redo and not self._dirty
