"""Keyframes: the handles of a constraint set posed at a few times, and the poses between them.

A keyframes file is a constraints file (:mod:`arap.constraints`) with one more key::

    {
      "fixed": [...], "handles": [...], "handle_groups": [[...], [...]],   # as in a constraints file
      "keyframes": [
        {"time": 0.0, "targets": [[x, y, z], ...]},          # one target per handle, in the order of "handles"
        {"time": 1.0, "transforms": [[[4x4]], [[4x4]]]},       # or one 4×4 per handle group, applied to the rest
        ...                                                    #   positions of its handles
      ]
    }

Each keyframe may also give:

- ``"easing"``: how the handles move from this keyframe to the next: ``"linear"`` (the default, at a constant pace),
  ``"ease-in-out"`` (starting and stopping smoothly: the fraction of the way ``s`` becomes ``s² (3 - 2 s)``),
  ``"ease-in"`` (``s²``) or ``"ease-out"`` (``1 - (1 - s)²``). The pace changes; the path does not.
- ``"point_targets"``: one ``[x, y, z]`` per point handle (``"points"``, in their order): where the point handles
  are at that time. They move linearly between keyframes (with the keyframe's easing), as vertex handles do. A
  keyframe without them holds the point handles at the targets of the previous keyframe that has them (or at the
  ``"target"`` of each point before any).
- ``"point_angles"``: one angle in degrees (or ``null``) per point handle, in their order: the angle each of a
  picture's pins holds at that time (as the points' ``"angle"``, :data:`arap.constraints.entries.PIN_KEYS`: the
  studio turns a pin that holds an angle with its keyframes). A number exactly for the points that give an
  ``"angle"``, ``null`` for the others (they turn freely). A keyframe without them holds the angles of the previous
  keyframe that has them (or the points' ``"angle"`` before any). Between keyframes, the hidden ring of points that
  holds a pin's angle (:mod:`arap.puppet.rings`) moves on straight lines from its place at one keyframe
  (the pin's target, with the ring about it turned by the pin's angle) to its place at the next, with the keyframe's
  easing, as the point handles do; ``arap animate`` and the studio's animation export solve them so.
- ``"shape"``: one ``[x, y, z]`` per mesh vertex: the whole shape at that time, as it was when the keyframe was made.
  An ARAP pose is not always unique (a large turn can end in one of several shapes, depending on the way there), so
  an animation that solves the keyframe again from another path can reach another shape. With ``"shape"``,
  :func:`arap.animation.iter_frames` gives that shape as the frame at the keyframe's time and starts the next frame
  from it. The handles of the shape must be at the keyframe's targets.

Transforms apply to the handles' rest positions, or, when the document has ``"keyframe_base"`` (one ``[x, y, z]`` per
handle, in the order of ``"handles"``), to those positions: the studio writes it when its handles' poses are not
their rest positions (a selection made on a deformed shape). Pivots are then the centroids of those positions.

``targets`` may be left out of the constraints part: the handles then rest where they are until the keyframes say
otherwise. Transforms are given per group of ``handle_groups``, in order; handles in no group form one more group
after them (all handles are one group when there are no ``handle_groups``).

Between two keyframes the handles move linearly from one pose to the other, except between two ``transforms``
keyframes: there each group turns about its pivot (the centroid of its handles at rest) by the spherical linear
interpolation of the two rotations (any scale is interpolated linearly), while the pivot moves linearly, so a turn
stays a turn instead of cutting across. Before the first and after the last keyframe the handles hold still.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from arap.constraints import Constraints, load_constraints, read_json
from arap.constraints.selection import check_listed_targets
from arap.errors import ConstraintError
from arap.meshes.mesh import bounding_box
from arap.solve.partition import check_reach

__all__ = ["EASINGS", "MAX_KEYFRAMES", "Keyframe", "Keyframes", "ease", "load_keyframes"]

MAX_KEYFRAMES = 10_000
"""Most keyframes a file may hold."""
_KEYFRAME_KEYS = ("time", "targets", "transforms", "easing", "point_targets", "point_angles", "shape")
EASINGS = ("linear", "ease-in-out", "ease-in", "ease-out")
"""Names of the easings a keyframe may give (how the handles move from it to the next keyframe)."""
_SHAPE_AT_TARGETS = 1e-6
"""How far (per bounding-box diagonal) a keyframe's shape may put a handle from the keyframe's target."""
_BASE_KEY = "keyframe_base"


@dataclass(frozen=True)
class Keyframe:
    """The handles' pose at one time: ``targets`` (h, 3), or ``transforms`` (g, 4, 4) per handle group; the point
    handles' targets ``point_targets`` (p, 3) or None (held); the angles in degrees the point handles (a picture's
    pins) hold, ``point_angles`` (None per pin that turns freely), or None (none holds one); the whole ``shape``
    (n, 3) or None; the ``easing`` of the motion to the next keyframe (one of :data:`EASINGS`)."""

    time: float
    targets: NDArray[np.float64] | None = None
    transforms: NDArray[np.float64] | None = None
    easing: str = "linear"
    point_targets: NDArray[np.float64] | None = None
    shape: NDArray[np.float64] | None = None
    point_angles: tuple[float | None, ...] | None = None


def ease(easing: str, s: float) -> float:
    """The fraction of the way at the fraction ``s`` of the time between two keyframes under ``easing``.

    Raises
    ------
    ConstraintError
        ``easing`` is not one of :data:`EASINGS`.
    """
    if easing == "linear":
        return s
    if easing == "ease-in-out":
        return s * s * (3.0 - 2.0 * s)
    if easing == "ease-in":
        return s * s
    if easing == "ease-out":
        return 1.0 - (1.0 - s) * (1.0 - s)
    raise ConstraintError(f"unknown easing {easing!r}; expected one of {list(EASINGS)}"[:200])


@dataclass
class Keyframes:
    """Constraints and the keyframes that pose their handles over time.

    Attributes
    ----------
    constraints : Constraints
        The constraint set (anchors, handles, region, stiffness, point handles); its ``targets`` are the handles'
        pose before any keyframe applies.
    keys : list of Keyframe
        In increasing time.
    groups : list of (k,) int64 arrays
        Positions in ``constraints.handles`` of each group that ``transforms`` move.
    rest : (h, 3) float64 array
        Rest positions of the handles (what transforms apply to), or the document's ``keyframe_base``.
    """

    constraints: Constraints
    keys: list[Keyframe]
    groups: list[NDArray[np.int64]]
    rest: NDArray[np.float64]

    @classmethod
    def from_json(cls, data: Mapping[str, Any], V: NDArray[np.float64], n_faces: int | None = None) -> Keyframes:
        """Keyframes from a parsed keyframes document (see the module description) for the rest positions ``V``."""
        return _parse(data, np.asarray(V, dtype=np.float64), n_faces)

    @property
    def start(self) -> float:
        return self.keys[0].time

    @property
    def end(self) -> float:
        return self.keys[-1].time

    def _segment(self, t: float) -> tuple[Keyframe, Keyframe, float] | Keyframe:
        """The keyframe whose pose holds at ``t``, or the two keyframes about ``t`` and the eased fraction between."""
        keys = self.keys
        if t <= keys[0].time:
            return keys[0]
        if t >= keys[-1].time:
            return keys[-1]
        b = int(np.searchsorted([k.time for k in keys], t, side="right"))
        ka, kb = keys[b - 1], keys[b]
        return ka, kb, ease(ka.easing, (t - ka.time) / (kb.time - ka.time))

    def key_at(self, t: float) -> Keyframe | None:
        """The keyframe at time ``t`` (to a nanosecond), or None."""
        for key in self.keys:
            if abs(key.time - t) <= 1e-9 * max(1.0, abs(t)):
                return key
        return None

    def point_targets(self, t: float) -> NDArray[np.float64] | None:
        """Targets of the point handles at time ``t``, shape (p, 3), or None without point handles."""
        base = self.constraints.point_targets
        if base is None or self.constraints.points is None or not len(self.constraints.points):
            return None
        return self.blend(t, self._point_pose)

    def blend(self, t: float, value: Callable[[Keyframe], NDArray[np.float64]]) -> NDArray[np.float64]:
        """``value`` (an array per keyframe) at time ``t``: that of the keyframe whose pose holds at ``t``, or
        between two keyframes the linear blend of theirs at the eased fraction (as point handles move)."""
        seg = self._segment(t)
        if isinstance(seg, Keyframe):
            return value(seg)
        ka, kb, s = seg
        return (1.0 - s) * value(ka) + s * value(kb)

    def _point_pose(self, key: Keyframe) -> NDArray[np.float64]:
        if key.point_targets is not None:  # always so for parsed keyframes with point handles
            return key.point_targets
        held = self.constraints.point_targets
        assert held is not None
        return held

    def handle_targets(self, t: float) -> NDArray[np.float64]:
        """Targets of the handles at time ``t``, shape (h, 3), in the order of ``constraints.handles``."""
        seg = self._segment(t)
        if isinstance(seg, Keyframe):
            return self._pose(seg)
        ka, kb, s = seg
        if ka.transforms is not None and kb.transforms is not None:
            return self._turn(ka.transforms, kb.transforms, s)
        return (1.0 - s) * self._pose(ka) + s * self._pose(kb)

    def _pose(self, key: Keyframe) -> NDArray[np.float64]:
        if key.targets is not None:
            return key.targets
        assert key.transforms is not None
        out = np.empty_like(self.rest)
        for g, T in zip(self.groups, key.transforms, strict=True):
            out[g] = self.rest[g] @ T[:3, :3].T + T[:3, 3]
        return out

    def _turn(self, Ta: NDArray[np.float64], Tb: NDArray[np.float64], s: float) -> NDArray[np.float64]:
        out = np.empty_like(self.rest)
        for g, A, B in zip(self.groups, Ta, Tb, strict=True):
            pivot = self.rest[g].mean(axis=0)
            (Ra, Sa), (Rb, Sb) = _polar(A[:3, :3]), _polar(B[:3, :3])
            R = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([Ra, Rb])))([s]).as_matrix()[0]
            M = R @ ((1.0 - s) * Sa + s * Sb)
            centre = (1.0 - s) * (A[:3, :3] @ pivot + A[:3, 3]) + s * (B[:3, :3] @ pivot + B[:3, 3])
            out[g] = (self.rest[g] - pivot) @ M.T + centre
        return out


def _polar(A: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    R, S = scipy.linalg.polar(A)
    return R, S


def _check_transforms(raw: Any, n_groups: int, where: str) -> NDArray[np.float64]:
    if n_groups == 0 and isinstance(raw, list) and not raw:  # only point handles move
        return np.zeros((0, 4, 4))
    try:
        T = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConstraintError(f"{where}.transforms must be a list of 4×4 matrices of numbers") from None
    if T.shape != (n_groups, 4, 4):
        raise ConstraintError(f"{where}.transforms must hold one 4×4 matrix per handle group ({n_groups}), got shape "
                              f"{list(T.shape)}")
    if not np.isfinite(T).all():
        raise ConstraintError(f"{where}.transforms must hold finite numbers")
    if not np.allclose(T[:, 3], [0.0, 0.0, 0.0, 1.0], atol=1e-12):
        raise ConstraintError(f"{where}.transforms: the last row of each matrix must be [0, 0, 0, 1]")
    det = np.linalg.det(T[:, :3, :3])
    scale = np.abs(T[:, :3, :3]).max(axis=(1, 2)) ** 3
    if (det <= 1e-12 * np.maximum(scale, 1e-300)).any():
        k = int(np.argmax(det <= 1e-12 * np.maximum(scale, 1e-300)))
        raise ConstraintError(f"{where}.transforms[{k}] mirrors or flattens the group (determinant {det[k]:.3g}); "
                              "give a rotation, possibly with a positive scale")
    return T


def _groups(constraints: Constraints) -> list[NDArray[np.int64]]:
    handles = constraints.handles
    slot = {int(v): i for i, v in enumerate(handles)}
    groups = [np.array([slot[int(v)] for v in g], dtype=np.int64) for g in (constraints.handle_groups or []) if g]
    covered = np.zeros(len(handles), dtype=bool)
    for g in groups:
        covered[g] = True
    if (~covered).any():
        groups.append(np.flatnonzero(~covered).astype(np.int64))
    return groups


def _parse(data: Mapping[str, Any], V: NDArray[np.float64], n_faces: int | None) -> Keyframes:
    if not isinstance(data, Mapping):
        raise ConstraintError(f"a keyframes file must be a JSON object, got {type(data).__name__}")
    raw_keys = data.get("keyframes")
    if not isinstance(raw_keys, list) or not raw_keys:
        raise ConstraintError('a keyframes file needs "keyframes": a list of {"time": seconds, "targets": [...]} or '
                              '{"time": seconds, "transforms": [...]} objects')
    if len(raw_keys) > MAX_KEYFRAMES:
        raise ConstraintError(f"at most {MAX_KEYFRAMES:,} keyframes, got {len(raw_keys):,}")
    rest_of = {k: v for k, v in data.items() if k not in ("keyframes", _BASE_KEY)}
    handles_given = len(rest_of.get("handles") or []) > 0
    if handles_given and "targets" not in rest_of:
        raw_handles = rest_of["handles"]
        try:
            idx = np.asarray(raw_handles, dtype=np.int64)
            rest_of["targets"] = V[idx].tolist() if idx.ndim == 1 and ((idx >= 0) & (idx < len(V))).all() else []
        except (TypeError, ValueError, OverflowError):
            pass  # load_constraints says what is wrong with the handles
    constraints = load_constraints(rest_of, len(V), n_faces)
    h = len(constraints.handles)
    p = 0 if constraints.points is None else len(constraints.points)
    if h == 0 and p == 0:
        raise ConstraintError('keyframes pose the handles: give "handles" (the vertices the keyframes move) or '
                              '"points" (point handles)')
    held = constraints.point_targets if p else None
    held_angles = tuple(constraints.pin_angles) if constraints.pin_angles is not None else None
    groups = _groups(constraints)
    box = bounding_box(V)
    keys: list[Keyframe] = []
    for k, raw in enumerate(raw_keys):
        where = f"keyframes[{k}]"
        if not isinstance(raw, Mapping):
            raise ConstraintError(f"{where} must be an object with \"time\" and \"targets\" or \"transforms\"")
        unknown = sorted(str(key)[:40] for key in set(raw) - set(_KEYFRAME_KEYS))
        if unknown:
            raise ConstraintError(f"{where}: unknown keys {unknown}; expected {list(_KEYFRAME_KEYS)}")
        t = raw.get("time")
        if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(float(t)):
            raise ConstraintError(f"{where}.time must be a finite number of seconds, got {t!r}"[:200])
        t = float(t)
        if keys and t <= keys[-1].time:
            raise ConstraintError(f"{where}.time {t:g} is not after keyframes[{k - 1}].time {keys[-1].time:g}; "
                                  "keyframes go in increasing time")
        if ("targets" in raw) == ("transforms" in raw):
            raise ConstraintError(f'{where} needs either "targets" (one per handle) or "transforms" (one 4×4 per '
                                  "handle group), not both or neither")
        if "targets" in raw:
            try:
                T = check_listed_targets(raw["targets"], h)
            except ConstraintError as exc:
                raise ConstraintError(f"{where}: {exc}") from None
            check_reach(box, T, f"{where}.targets")
            key = Keyframe(time=t, targets=T)
        else:
            key = Keyframe(time=t, transforms=_check_transforms(raw["transforms"], len(groups), where))
        easing = raw.get("easing", "linear")
        if easing not in EASINGS:
            raise ConstraintError(f"{where}.easing must be one of {list(EASINGS)}, got {easing!r}"[:200])
        if "point_targets" in raw:
            if p == 0:
                raise ConstraintError(f'{where}.point_targets: the constraints have no point handles ("points")')
            try:
                P = check_listed_targets(raw["point_targets"], p)
            except ConstraintError as exc:
                raise ConstraintError(f"{where}.point_targets: {exc}") from None
            check_reach(box, P, f"{where}.point_targets")
            held = P
        if "point_angles" in raw:
            if p == 0:
                raise ConstraintError(f'{where}.point_angles: the constraints have no point handles ("points")')
            held_angles = _check_angles(raw["point_angles"], constraints.pin_angles, p, f"{where}.point_angles")
        shape = None if raw.get("shape") is None else _check_shape(raw["shape"], V, box, where)
        keys.append(replace(key, easing=str(easing), point_targets=held, point_angles=held_angles, shape=shape))
    rest = V[constraints.handles].copy()
    if data.get(_BASE_KEY) is not None:
        try:
            rest = check_listed_targets(data[_BASE_KEY], h)
        except ConstraintError as exc:
            raise ConstraintError(f"{_BASE_KEY}: {exc}") from None
        check_reach(box, rest, _BASE_KEY)
    frames = Keyframes(constraints=constraints, keys=keys, groups=groups, rest=rest)
    diagonal = float(np.linalg.norm(box[1] - box[0]))
    for k, key in enumerate(keys):
        if key.transforms is not None:
            check_reach(box, frames._pose(key), f"keyframes at {key.time:g} s")
        if key.shape is not None:
            off = float(np.abs(key.shape[constraints.handles] - frames._pose(key)).max(initial=0.0))
            if off > _SHAPE_AT_TARGETS * max(diagonal, 1e-300):
                raise ConstraintError(f"keyframes[{k}].shape puts a handle {off:.3g} away from the keyframe's target "
                                      "(the shape of a keyframe is the pose of its handles)")
    return frames


def _check_angles(raw: Any, pins: list[float | None] | None, p: int, where: str) -> tuple[float | None, ...]:
    """A keyframe's ``point_angles``: per point handle a finite number of degrees where the points give an
    ``"angle"`` (``pins``), null elsewhere."""
    if not isinstance(raw, list) or len(raw) != p:
        raise ConstraintError(f"{where} must be a list of one angle in degrees (or null) per point handle ({p})")
    out: list[float | None] = []
    for j, a in enumerate(raw):
        holds = pins is not None and pins[j] is not None
        if a is None:
            if holds:
                raise ConstraintError(f'{where}[{j}] is null, but points[{j}] holds an angle ("angle"): give the '
                                      "angle it holds at that time")
            out.append(None)
            continue
        if type(a) not in (int, float) or not -sys.float_info.max <= a <= sys.float_info.max:
            raise ConstraintError(f"{where}[{j}] must be a finite number of degrees or null, got "
                                  f"{json.dumps(a, default=repr)[:40]}")
        if not holds:
            raise ConstraintError(f'{where}[{j}]: points[{j}] holds no angle (it turns freely); give it an "angle" '
                                  'in "points" or null here')
        out.append(float(a))
    return tuple(out)


def _check_shape(raw: Any, V: NDArray[np.float64], box: NDArray[np.float64], where: str) -> NDArray[np.float64]:
    """A keyframe's ``shape``: one finite ``[x, y, z]`` per vertex."""
    try:
        X = np.array(raw, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ConstraintError(f"{where}.shape must be a list of [x, y, z] points, one per vertex") from None
    if X.shape != V.shape:
        raise ConstraintError(f"{where}.shape must hold one [x, y, z] per vertex ({len(V)}), got shape "
                              f"{list(X.shape)}")
    if not np.isfinite(X).all():
        raise ConstraintError(f"{where}.shape must hold finite numbers")
    check_reach(box, X, f"{where}.shape")
    X.setflags(write=False)
    return X


def load_keyframes(source: str | Path | Mapping[str, Any], V: NDArray[np.float64],
                   n_faces: int | None = None) -> Keyframes:
    """Read and validate a keyframes file (see the module description) for a mesh with rest positions ``V``.

    Parameters
    ----------
    source : path-like or mapping
        A JSON file, or its parsed content.
    V : (n, 3) float array
        Rest positions (vertex indices refer to them; transforms apply to them).
    n_faces : int or None
        Triangle count, needed for point handles.

    Raises
    ------
    ConstraintError
        Whatever :func:`arap.load_constraints` refuses, and keyframes that are not in increasing time, targets of the
        wrong count, transforms that are not 4×4 per group or that mirror, poses absurdly far away.

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> keys = arap.load_keyframes({"fixed": [0], "handles": [5], "keyframes": [
    ...     {"time": 0.0, "targets": [V[5].tolist()]}, {"time": 1.0, "targets": [[0.0, 2.0, 0.0]]}]}, V)
    >>> keys.start, keys.end
    (0.0, 1.0)
    """
    data = source if isinstance(source, Mapping) else read_json(Path(source))
    return Keyframes.from_json(data, V, n_faces)
