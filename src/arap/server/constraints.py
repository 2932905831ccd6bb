"""A studio constraint set: region of interest, fixed vertices and handle groups, with their target positions.

Constraints refer to a *pose*: the deformed shape at the moment they were accepted (the rest pose on a fresh
mesh). Fixed vertices stay at their pose positions, handle group ``g`` goes to ``transforms[g]`` applied to its
pose positions, and vertices outside the region of interest that the pose had moved away from the rest pose stay
where they are. Changing the selection in the middle of an edit therefore keeps the current shape instead of
snapping back to the rest pose; the energy is still measured against the rest pose.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from arap.constraints import check_selection, points_from_json, stiffness_from_json, stiffness_to_json
from arap.errors import ConstraintError
from arap.method.points import PointConstraints
from arap.puppet.rings import PinRings
from arap.server.session_errors import ConstraintsRejected

__all__ = ["ConstraintSet", "identity_transforms", "matrices_from_json", "matrices_to_json", "turn_of"]


def identity_transforms(n_groups: int) -> np.ndarray:
    """``(n_groups, 4, 4)`` identity matrices."""
    return np.tile(np.eye(4), (n_groups, 1, 1))


def matrices_from_json(matrices: Sequence[Sequence[float]]) -> np.ndarray:
    """Column-major 16-number lists (Three.js ``Matrix4.elements``) to ``(g, 4, 4)`` row-major matrices."""
    if not len(matrices):
        return np.zeros((0, 4, 4))
    return np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4).transpose(0, 2, 1).copy()


def matrices_to_json(T: np.ndarray) -> list[list[float]]:
    """Inverse of :func:`matrices_from_json`."""
    return [m.T.reshape(16).tolist() for m in T]


def _digest(*arrays: np.ndarray | None, stiffness: np.ndarray | None = None,
            points: PointConstraints | None = None) -> bytes:
    h = hashlib.blake2b(digest_size=16)
    h.update(b"s:none;" if stiffness is None else b"s:" + np.ascontiguousarray(stiffness, dtype=np.float64).tobytes())
    if points is not None:
        h.update(b"p:" + np.ascontiguousarray(points.faces, dtype=np.int64).tobytes())
        h.update(np.ascontiguousarray(points.barycentric, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(points.weights, dtype=np.float64).tobytes() + b";")
    for a in arrays:
        if a is None:
            h.update(b"none;")
        else:
            h.update(np.ascontiguousarray(a, dtype=np.int64).tobytes())
            h.update(b";")
    return h.digest()


_NO_POINTS = np.zeros((0, 3))
_NO_POINTS.setflags(write=False)


def turn_of(transforms: np.ndarray) -> np.ndarray:
    """The turn about z (radians, counter-clockwise seen from +z) of each of ``transforms`` ``(g, 4, 4)``."""
    T = np.asarray(transforms, dtype=np.float64).reshape(-1, 4, 4)
    return np.arctan2(T[:, 1, 0], T[:, 0, 0])


@dataclass(frozen=True, eq=False)
class ConstraintSet:
    """Validated constraints of a session (treat as immutable).

    Attributes
    ----------
    roi : (r,) int64 array or None
        Region of interest; None is the whole mesh.
    fixed : (f,) int64 array
    groups : tuple of (h_g,) int64 arrays
        Handle groups.
    pose : (n, 3) float64 array
        Positions the constraints refer to (with the handle vertices at the targets they were given, if any).
    held : (p,) int64 array
        Vertices outside the region of interest whose pose differs from the rest pose; held at their pose.
    constrained : (k,) int64 array
        ``fixed``, then every group, then ``held``: the solver's constrained vertices in target order.
    stiffness : (n,) float64 array or None
        Painted stiffness (the cell weights of :class:`arap.ArapSolver`; ``inf``: rigid), or None for all 1.
    points : PointConstraints or None
        Point handles (a triangle and barycentric coordinates each; :mod:`arap.method.points`), or None for none. Each
        is a handle group of its own: its transform follows those of :attr:`groups`.
    point_pose : (p, 3) float64 array
        Positions the point handles' transforms apply to: where the pose puts them on the surface, or the targets
        they were given.
    """

    roi: np.ndarray | None
    fixed: np.ndarray
    groups: tuple[np.ndarray, ...]
    pose: np.ndarray
    held: np.ndarray
    constrained: np.ndarray
    stiffness: np.ndarray | None = None
    points: PointConstraints | None = None
    point_pose: np.ndarray = field(default_factory=lambda: _NO_POINTS)
    rings: PinRings | None = None

    @classmethod
    def build(
        cls,
        rest: np.ndarray,
        pose: np.ndarray,
        roi: Sequence[int] | None,
        fixed: Sequence[int],
        groups: Sequence[Sequence[int]],
        handle_positions: np.ndarray | None = None,
        stiffness: Any = None,
        points: Any = None,
        faces: np.ndarray | None = None,
    ) -> ConstraintSet:
        """Validate a constraint set for a mesh.

        Parameters
        ----------
        rest : (n, 3) array
            Rest pose.
        pose : (n, 3) array
            Current deformed positions (the constraints' reference).
        roi : list of int or None
        fixed : list of int
        groups : list of lists of int
        handle_positions : (h, 3) array or None
            Positions of the handle vertices (groups concatenated) that the transforms apply to instead of their
            ``pose`` positions; the set's :attr:`pose` is then a copy of ``pose`` with these positions put in.
        stiffness : list of {"vertices": [...], "value": v} or None
            Painted stiffness (v > 0 or ``"rigid"``; 1 elsewhere), as in constraints files; None: all 1.
        points : list of {"face": f, "barycentric": [a, b, c], "weight"?: w, "target"?: [x, y, z]} or None
            Point handles (no weight: a hard one), as in constraints files but with an optional target: the
            position the point's transform applies to (default: where ``pose`` puts the point).
        faces : (m, 3) int array or None
            The mesh's triangles; needed with ``points``.

        Returns
        -------
        ConstraintSet

        Raises
        ------
        ConstraintsRejected
            With the message of :func:`arap.constraints.check_selection` (the validator the
            library and the command line use): indices that are not integers or out of range, a vertex repeated
            within or across ``fixed`` and the groups, a repeated ROI vertex, an empty handle group or an empty
            ROI; or the message of :func:`arap.constraints.stiffness_from_json` for bad stiffness, or of
            :func:`arap.constraints.points_from_json` for bad point handles.
        """
        n = len(rest)
        try:
            fixed_arr, group_list, roi_arr = check_selection(n, fixed, groups, roi)
            painted = None if stiffness is None else stiffness_from_json(list(stiffness), n)
            pts, point_targets, given = None, None, None
            if points:
                if faces is None:
                    raise ConstraintError("point handles need the mesh's triangles")
                pts, point_targets, given = points_from_json(list(points), len(faces), require_target=False)
        except ConstraintError as exc:
            raise ConstraintsRejected(str(exc)) from exc
        group_arrs = tuple(group_list)
        if handle_positions is not None and group_arrs:
            pose = np.array(pose, dtype=np.float64)
            pose[np.concatenate(group_arrs)] = np.asarray(handle_positions, dtype=np.float64).reshape(-1, 3)
            pose.setflags(write=False)
        point_pose = _NO_POINTS
        if pts is not None and faces is not None and point_targets is not None:
            point_pose = pts.positions(np.asarray(pose, dtype=np.float64), np.asarray(faces))
            point_pose[given] = point_targets[given]
            point_pose.setflags(write=False)
        held = np.zeros(0, dtype=np.int64)
        if roi_arr is not None:
            outside = np.ones(n, dtype=bool)
            outside[roi_arr] = False
            for a in (fixed_arr, *group_list):
                outside[a] = False
            outside &= np.any(pose != rest, axis=1)
            held = np.flatnonzero(outside).astype(np.int64)
        constrained = np.concatenate([fixed_arr, *group_arrs, held]).astype(np.int64)
        if painted is not None and np.all(painted == 1.0):
            painted = None
        for frozen in (fixed_arr, *group_arrs, held, painted):
            if frozen is not None:
                frozen.setflags(write=False)
        return cls(roi_arr, fixed_arr, group_arrs, pose, held, constrained, painted, pts, point_pose)

    @classmethod
    def empty(cls, pose: np.ndarray) -> ConstraintSet:
        """No constraints at all (a fresh mesh)."""
        z = np.zeros(0, dtype=np.int64)
        return cls(None, z, (), pose, z, z)

    # ------------------------------------------------------------------ queries
    @property
    def n_points(self) -> int:
        """Number of point handles."""
        return 0 if self.points is None else len(self.points)

    @property
    def n_groups(self) -> int:
        """Number of transforms a drag gives: the handle groups, then one per point handle."""
        return len(self.groups) + self.n_points

    @property
    def is_empty(self) -> bool:
        """True when nothing is constrained (no fixed vertex, no handle, no point handle)."""
        return not len(self.fixed) and not self.groups and not self.n_points

    def same_selection(self, other: ConstraintSet) -> bool:
        """True if ``other`` selects the same roi, fixed vertices and groups (poses aside)."""
        return self.selection_digest() == other.selection_digest()

    def selection_digest(self) -> bytes:
        """Hash of the selection (roi, fixed, groups, stiffness)."""
        return _digest(self.roi, self.fixed, *self.groups, np.asarray([len(g) for g in self.groups]),
                       stiffness=self.stiffness, points=self.points)

    def solver_digest(self) -> bytes:
        """Hash of what the solver's factorisation depends on (constrained vertices, roi, stiffness, points)."""
        return _digest(self.roi, self.constrained, stiffness=self.stiffness, points=self.solver_points)

    @property
    def solver_points(self) -> PointConstraints | None:
        """The point handles the solver holds: :attr:`points`, then the rings of the pins that hold an angle."""
        if self.rings is None or not len(self.rings.pin) or self.points is None:
            return self.points
        p, r = self.points, self.rings.points
        return PointConstraints(np.concatenate([p.faces, r.faces]), np.concatenate([p.barycentric, r.barycentric]),
                                np.concatenate([p.weights, r.weights]))

    def pin_angles(self, transforms: np.ndarray) -> list[float | None]:
        """Per point handle, the angle (radians) it holds under ``transforms`` ``(g, 4, 4)``, or None (turns freely)."""
        if self.rings is None:
            return [None] * self.n_points
        turn = turn_of(transforms[len(self.groups):])
        return [None if a is None else float(a + t) for a, t in zip(self.rings.angles, turn, strict=True)]

    def solver_point_targets(self, transforms: np.ndarray) -> np.ndarray | None:
        """Targets of :attr:`solver_points` under ``transforms``: :meth:`point_targets`, then each ring point at its
        pin's pose turned by the pin's angle, moved by the pin's transform."""
        targets = self.point_targets(transforms)
        if targets is None or self.rings is None or not len(self.rings.pin):
            return targets
        rings = self.rings
        pose = rings.targets(self.point_pose)  # each ring point at its pin's pose, turned by the pin's angle
        T = transforms[len(self.groups):][rings.pin]
        return np.concatenate([targets, np.einsum("pij,pj->pi", T[:, :3, :3], pose) + T[:, :3, 3]])

    def handle_targets(self, transforms: np.ndarray) -> np.ndarray:
        """Targets of the handle vertices (groups concatenated) under ``transforms`` ``(g, 4, 4)``."""
        parts = []
        for g, idx in enumerate(self.groups):
            M = transforms[g]
            parts.append(self.pose[idx] @ M[:3, :3].T + M[:3, 3])
        return np.concatenate(parts) if parts else np.zeros((0, 3))

    def point_targets(self, transforms: np.ndarray) -> np.ndarray | None:
        """Targets of the point handles under ``transforms`` ``(g, 4, 4)`` (theirs follow the groups'), or None."""
        if not self.n_points:
            return None
        T = transforms[len(self.groups):]
        targets: np.ndarray = np.einsum("pij,pj->pi", T[:, :3, :3], self.point_pose) + T[:, :3, 3]
        return targets

    def points_json(self, transforms: np.ndarray | None = None) -> list[dict[str, Any]]:
        """The point handles as ``[{"face", "barycentric", "weight"?}]`` (no weight: hard), with ``"target"``
        under ``transforms`` when given."""
        if self.points is None:
            return []
        targets = None if transforms is None else self.point_targets(transforms)
        out = []
        for k, (f, b, w) in enumerate(zip(self.points.faces, self.points.barycentric, self.points.weights,
                                          strict=True)):
            item: dict[str, Any] = {"face": int(f), "barycentric": [float(x) for x in b]}
            if targets is not None:
                item["target"] = [float(x) for x in targets[k]]
            if not np.isinf(w):
                item["weight"] = float(w)
            out.append(item)
        return out

    def targets(self, transforms: np.ndarray) -> np.ndarray:
        """Targets of :attr:`constrained`, in order, under ``transforms`` ``(g, 4, 4)``."""
        return np.concatenate([self.pose[self.fixed], self.handle_targets(transforms), self.pose[self.held]])

    def stiffness_json(self) -> list[dict[str, Any]] | None:
        """The painted stiffness as ``[{"vertices": [...], "value": v}]`` (None when all 1)."""
        return None if self.stiffness is None else stiffness_to_json(self.stiffness)

    def to_json(self) -> dict[str, Any]:
        """The selection as sent in ``state`` messages."""
        return {
            "roi": None if self.roi is None else self.roi.tolist(),
            "fixed": self.fixed.tolist(),
            "handle_groups": [g.tolist() for g in self.groups],
            "stiffness": self.stiffness_json(),
            "points": self.points_json(),
        }

    def document(self, rest: np.ndarray, transforms: np.ndarray) -> dict[str, Any]:
        """Constraints document in the command-line format.

        ``handles`` lists the handle groups' vertices in group order with their current ``targets``; fixed
        vertices and vertices outside the region of interest that the current pose keeps away from the rest pose
        follow them (with their pose positions as targets), so that the document reproduces the current
        constraints against the rest pose. ``fixed`` lists the fixed vertices that are at rest.
        """
        handles = [np.concatenate(self.groups) if self.groups else np.zeros(0, dtype=np.int64)]
        targets = [self.handle_targets(transforms)]
        displaced = np.any(self.pose[self.fixed] != rest[self.fixed], axis=1)
        extra = np.concatenate([self.fixed[displaced], self.held])
        handles.append(extra)
        targets.append(self.pose[extra])
        doc: dict[str, Any] = {
            "fixed": self.fixed[~displaced].tolist(),
            "handles": np.concatenate(handles).tolist(),
            "targets": np.concatenate(targets).tolist(),
            "handle_groups": [g.tolist() for g in self.groups],
        }
        if self.roi is not None:
            doc["roi"] = self.roi.tolist()
        if self.stiffness is not None:
            doc["version"] = 2
            doc["stiffness"] = self.stiffness_json()
        if self.n_points:
            doc["version"] = 2
            doc["points"] = self.points_json(transforms)
        return doc
