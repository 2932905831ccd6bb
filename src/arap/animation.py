"""Keyframe animation: the handles posed at a few times, every frame between them solved to convergence.

A keyframes file is a constraints file (:mod:`arap.constraints`) with one more key::

    {
      "fixed": [...], "handles": [...], "handle_groups": [[...], [...]],   # as in a constraints file
      "keyframes": [
        {"time": 0.0, "targets": [[x, y, z], ...]},          # one target per handle, in the order of "handles"
        {"time": 1.0, "transforms": [[[4x4]], [[4x4]]]},       # or one 4×4 per handle group, applied to the rest
        ...                                                    #   positions of its handles
      ]
    }

``targets`` may be left out of the constraints part: the handles then rest where they are until the keyframes say
otherwise. Transforms are given per group of ``handle_groups``, in order; handles in no group form one more group
after them (all handles are one group when there are no ``handle_groups``).

Between two keyframes the handles move linearly from one pose to the other, except between two ``transforms``
keyframes: there each group turns about its pivot (the centroid of its handles at rest) by the spherical linear
interpolation of the two rotations (any scale is interpolated linearly), while the pivot moves linearly, so a turn
stays a turn instead of cutting across. Before the first and after the last keyframe the handles hold still.

Every frame is solved to convergence, starting from the previous frame (:func:`iter_frames`), so the frames at the
keyframe times are the shapes :func:`arap.ArapSolver.solve` gives for those targets.

Example
-------
>>> import numpy as np, arap
>>> V, F = arap.builtin_mesh("bar")
>>> y = V[:, 1]
>>> fixed, top = np.flatnonzero(y < 0.2), np.flatnonzero(y > 4.8)
>>> keys = Keyframes.from_json({"fixed": fixed.tolist(), "handles": top.tolist(), "keyframes": [
...     {"time": 0.0, "targets": V[top].tolist()}, {"time": 0.5, "targets": (V[top] + [1, 0, 0]).tolist()}]}, V)
>>> animation = animate(V, F, keys, fps=10)
>>> animation.vertices.shape, bool(animation.converged.all())
((6, 4314, 3), True)
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from arap.constraints import Constraints, load_constraints, read_json
from arap.errors import ConstraintError, OptionError
from arap.mesh import bounding_box
from arap.options import DEFAULT_TOLERANCE
from arap.partition import check_reach
from arap.result import ArapResult
from arap.selection import check_targets

__all__ = ["DEFAULT_FPS", "MAX_FRAMES", "MAX_KEYFRAMES", "Animation", "Keyframe", "Keyframes", "animate",
           "frame_paths", "frame_times", "iter_frames", "load_keyframes", "save_animation"]

DEFAULT_FPS = 30.0
"""Frames per second when none is given."""
MAX_KEYFRAMES = 10_000
"""Most keyframes a file may hold."""
MAX_FRAMES = 100_000
"""Most frames one animation may have (about an hour at 30 frames per second)."""

_KEYFRAME_KEYS = ("time", "targets", "transforms")


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
        Rest positions of the handles (what transforms apply to).
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


@dataclass
class Animation:
    """Solved frames.

    Attributes
    ----------
    times : (N,) float64 array
        Seconds of each frame.
    vertices : (N, n, 3) float64 array
        Each frame's positions.
    iterations : (N,) int64 array
    converged : (N,) bool array
    seconds : (N,) float64 array
        Solve time of each frame (the first includes no set-up: see ``setup_seconds``).
    setup_seconds : float
        Construction of the solver (factorisation).
    """

    times: NDArray[np.float64]
    vertices: NDArray[np.float64]
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    seconds: NDArray[np.float64]
    setup_seconds: float


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
    rest_of = {k: v for k, v in data.items() if k != "keyframes"}
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
                T = check_targets(raw["targets"], h)
            except ConstraintError as exc:
                raise ConstraintError(f"{where}: {exc}") from None
            check_reach(box, T, f"{where}.targets")
            keys.append(Keyframe(time=t, targets=T))
        else:
            M = _check_transforms(raw["transforms"], len(groups), where)
            key = Keyframe(time=t, transforms=M)
            keys.append(key)
    rest = V[constraints.handles].copy()
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


def frame_times(keyframes: Keyframes, fps: float = DEFAULT_FPS) -> NDArray[np.float64]:
    """Times of the frames: from the first keyframe to the last, ``1 / fps`` apart, both ends included.

    Raises
    ------
    OptionError
        ``fps`` not a positive finite number, or more than :data:`MAX_FRAMES` frames.
    """
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not math.isfinite(fps) or fps <= 0:
        raise OptionError(f"fps must be a positive number, got {fps!r}")
    span = keyframes.end - keyframes.start
    count = math.floor(span * fps + 1e-9) + 1
    if count > MAX_FRAMES:
        raise OptionError(f"{span:g} s at {fps:g} frames per second is {count:,} frames, more than {MAX_FRAMES:,}")
    times = keyframes.start + np.arange(count) / float(fps)
    if times[-1] < keyframes.end - 1e-9 / fps:  # the last keyframe is a frame of its own
        times = np.append(times, keyframes.end)
    return times


def iter_frames(solver: Any, keyframes: Keyframes, V: NDArray[np.float64], times: NDArray[np.float64],
                **solve_options: Any) -> Iterator[tuple[float, ArapResult]]:
    """Solve the frames at ``times`` one after another, each starting from the previous one.

    Parameters
    ----------
    solver : ArapSolver
        Built for ``keyframes.constraints`` (its ``constrained`` is ``fixed`` then ``handles``).
    keyframes : Keyframes
    V : (n, 3) float array
        Rest positions.
    times : (N,) float array
    **solve_options
        Passed to :meth:`arap.ArapSolver.solve` (``tolerance``, ``max_iterations``, ...).

    Yields
    ------
    (float, ArapResult)
        Each frame's time and solution.
    """
    c = keyframes.constraints
    fixed = V[c.fixed]
    for t in times:
        targets = np.concatenate([fixed, keyframes.handle_targets(float(t))])
        yield float(t), solver.solve(targets, point_targets=c.point_targets, **solve_options)


def animate(V: NDArray[np.float64], F: NDArray[np.integer], keyframes: Keyframes | str | Path | Mapping[str, Any],
            fps: float = DEFAULT_FPS, *, tolerance: float = DEFAULT_TOLERANCE, max_iterations: int | None = None,
            **solver_options: Any) -> Animation:
    """Solve an animation: every frame between the first and the last keyframe, to convergence.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    keyframes : Keyframes, path-like or mapping
        Keyframes, or a keyframes file (see the module description) or its parsed content.
    fps : float
        Frames per second.
    tolerance, max_iterations
        As for :meth:`arap.ArapSolver.solve`.
    **solver_options
        Passed to :class:`arap.ArapSolver` (``energy``, ``weights``, ``backend``, ``alpha``); the region of interest,
        stiffness and point handles come from the keyframes' constraints.

    Returns
    -------
    Animation
    """
    from arap.solver import ArapSolver

    V = np.asarray(V, dtype=np.float64)
    keys = keyframes if isinstance(keyframes, Keyframes) else load_keyframes(keyframes, V, len(F))
    times = frame_times(keys, fps)
    c = keys.constraints
    t0 = time.perf_counter()
    solver = ArapSolver(V, F, c.constrained, roi=c.roi, stiffness=c.stiffness, points=c.points, **solver_options)
    setup = time.perf_counter() - t0
    frames = np.empty((len(times), len(V), 3))
    iterations = np.zeros(len(times), dtype=np.int64)
    converged = np.zeros(len(times), dtype=bool)
    seconds = np.zeros(len(times))
    for k, (_, result) in enumerate(iter_frames(solver, keys, V, times, tolerance=tolerance,
                                                max_iterations=max_iterations)):
        frames[k] = result.vertices
        iterations[k] = result.iterations
        converged[k] = result.converged
        seconds[k] = result.timings["total"]
    return Animation(times=times, vertices=frames, iterations=iterations, converged=converged, seconds=seconds,
                     setup_seconds=setup)


def frame_paths(pattern: str | Path, count: int) -> list[Path]:
    """The files of ``count`` numbered frames: the last run of ``#`` in the file name becomes the frame number.

    The number is zero-padded to the run's length, or longer when the count needs it (``frame_####.obj`` gives
    ``frame_0000.obj``, ``frame_0001.obj``, ...).

    Raises
    ------
    OptionError
        No ``#`` in the file name.
    """
    path = Path(pattern)
    runs = list(re.finditer("#+", path.name))
    if not runs:
        raise OptionError(f"{path.name}: a numbered output needs #### in its file name (frame_####.obj)")
    run = runs[-1]
    width = max(len(run.group()), len(str(max(count - 1, 0))))
    return [path.with_name(path.name[:run.start()] + f"{k:0{width}d}" + path.name[run.end():]) for k in range(count)]


def save_animation(output: str | Path, F: NDArray[np.integer], animation: Animation) -> list[Path]:
    """Write an animation: one animated GLB (``output`` ends in ``.glb``, see :mod:`arap.io.animated_gltf`) or
    numbered mesh files (``output`` has ``####`` in its name, in the format of its extension).

    Every file is written atomically. Returns the paths written.

    Raises
    ------
    OptionError
        ``output`` is neither.
    """
    from arap.io.animated_gltf import save_animation_glb
    from arap.io.meshfile import save_mesh

    path = Path(output)
    if path.suffix.lower() == ".glb":
        save_animation_glb(path, F, animation.times, animation.vertices)
        return [path]
    if "#" not in path.name:
        raise OptionError(f"{path.name}: write an animation to a .glb file or to numbered files (frame_####.obj)")
    paths = frame_paths(path, len(animation.times))
    for p, frame in zip(paths, animation.vertices, strict=True):
        save_mesh(p, frame, F)
    return paths
