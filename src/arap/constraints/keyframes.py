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

import math
from collections.abc import Mapping
from dataclasses import dataclass
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

__all__ = ["MAX_KEYFRAMES", "Keyframe", "Keyframes", "load_keyframes"]

MAX_KEYFRAMES = 10_000
"""Most keyframes a file may hold."""
_KEYFRAME_KEYS = ("time", "targets", "transforms")
_BASE_KEY = "keyframe_base"


@dataclass(frozen=True)
class Keyframe:
    """The handles' pose at one time: ``targets`` (h, 3), or ``transforms`` (g, 4, 4) per handle group."""

    time: float
    targets: NDArray[np.float64] | None = None
    transforms: NDArray[np.float64] | None = None


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

    def handle_targets(self, t: float) -> NDArray[np.float64]:
        """Targets of the handles at time ``t``, shape (h, 3), in the order of ``constraints.handles``."""
        keys = self.keys
        if t <= keys[0].time:
            return self._pose(keys[0])
        if t >= keys[-1].time:
            return self._pose(keys[-1])
        b = int(np.searchsorted([k.time for k in keys], t, side="right"))
        ka, kb = keys[b - 1], keys[b]
        s = (t - ka.time) / (kb.time - ka.time)
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
    if h == 0:
        raise ConstraintError('keyframes pose the handles: give "handles" (the vertices the keyframes move)')
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
            keys.append(Keyframe(time=t, targets=T))
        else:
            M = _check_transforms(raw["transforms"], len(groups), where)
            key = Keyframe(time=t, transforms=M)
            keys.append(key)
    rest = V[constraints.handles].copy()
    if data.get(_BASE_KEY) is not None:
        try:
            rest = check_listed_targets(data[_BASE_KEY], h)
        except ConstraintError as exc:
            raise ConstraintError(f"{_BASE_KEY}: {exc}") from None
        check_reach(box, rest, _BASE_KEY)
    frames = Keyframes(constraints=constraints, keys=keys, groups=groups, rest=rest)
    for key in keys:
        if key.transforms is not None:
            check_reach(box, frames._pose(key), f"keyframes at {key.time:g} s")
    return frames


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
    """
    data = source if isinstance(source, Mapping) else read_json(Path(source))
    return Keyframes.from_json(data, V, n_faces)
