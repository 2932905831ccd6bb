"""Keyframe animation: every frame between the first and the last keyframe solved, each from the previous frame,
and written as numbered meshes or one animated GLB.

The keyframes (a constraints file with ``"keyframes"``, and how poses are interpolated between them) are described
in :mod:`arap.constraints.keyframes`. The frames at the keyframe times are always solved to convergence
(``tolerance``), so they are the shapes :func:`arap.ArapSolver.solve` gives for those targets, except at keyframes
that carry their ``"shape"``: that shape is the frame, exactly, and the next frame starts from it. Point handles
follow the keyframes' ``"point_targets"``, and each keyframe's ``"easing"`` sets the pace to the next one. By default
(``exact=True``) so is every other frame. With ``exact=False`` (the default of ``arap animate``), the frames between
keyframes stop at the looser :data:`FRAME_TOLERANCE`: a few times fewer iterations, and shapes within about 1e-3 of
the bounding-box diagonal of the converged ones (``benchmarks/bench_animation.py`` measures both).

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
>>> fast = animate(V, F, keys, fps=10, exact=False)
>>> fast.at_key.tolist()
[True, False, False, False, False, True]
>>> bool(np.abs(fast.vertices - animation.vertices).max() < 1e-3 * np.linalg.norm(np.ptp(V, axis=0)))
True
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from arap.constraints.keyframes import MAX_KEYFRAMES, Keyframe, Keyframes, load_keyframes
from arap.errors import ConstraintError, OptionError
from arap.options import DEFAULT_TOLERANCE
from arap.solve.result import ArapResult

if TYPE_CHECKING:
    from arap.method.points import PointConstraints
    from arap.puppet.rings import PinRings
    from arap.solve.solver import ArapSolver

__all__ = ["DEFAULT_FPS", "FRAME_TOLERANCE", "MAX_FRAMES", "MAX_KEYFRAMES", "Animation", "Keyframe", "Keyframes",
           "animate", "at_keyframes", "frame_paths", "frame_times", "held_rings", "iter_frames", "load_keyframes",
           "ring_targets", "save_animation"]

DEFAULT_FPS = 30.0
"""Frames per second when none is given."""
MAX_FRAMES = 100_000
"""Most frames one animation may have (about an hour at 30 frames per second)."""
FRAME_TOLERANCE = 1e-6
"""Tolerance of the frames between keyframes with ``exact=False``, in the units of :meth:`arap.ArapSolver.solve`'s
``tolerance`` (the plain step, root mean square, per bounding-box diagonal). Started from the previous frame, such
frames took 2.6-3 times fewer iterations than converged ones and were within 5.4e-4 of the diagonal of them (largest
vertex distance; a 60° turn and back over 2 s on the cactus at 30 fps and the camel head at 15 fps), which is below a
pixel where the mesh spans a thousand."""


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
        Whether each frame reached its tolerance: ``tolerance``, or with ``exact=False`` ``frame_tolerance`` for the
        frames between keyframes.
    seconds : (N,) float64 array
        Solve time of each frame (the first includes no set-up: see ``setup_seconds``).
    setup_seconds : float
        Construction of the solver (factorisation).
    at_key : (N,) bool array or None
        The frames at keyframe times (solved to ``tolerance`` in any case); None when not known.

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> keys = {"fixed": [0], "handles": [5], "keyframes": [
    ...     {"time": 0.0, "targets": [V[5].tolist()]}, {"time": 0.5, "targets": [[0.0, 2.0, 0.0]]}]}
    >>> animation = arap.animate(V, F, keys, fps=4)
    >>> len(animation.times), bool(animation.converged.all()), animation.vertices[-1, 5].round(6).tolist()
    (3, True, [0.0, 2.0, 0.0])
    """

    times: NDArray[np.float64]
    vertices: NDArray[np.float64]
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    seconds: NDArray[np.float64]
    setup_seconds: float
    at_key: NDArray[np.bool_] | None = None


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


def at_keyframes(keyframes: Keyframes, times: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Which of ``times`` are keyframe times (to a nanosecond): the frames solved to convergence in any case."""
    times = np.asarray(times, dtype=np.float64)
    keys = np.array([k.time for k in keyframes.keys], dtype=np.float64)
    return np.abs(times[:, None] - keys[None, :]).min(axis=1, initial=np.inf) <= 1e-9 * np.maximum(1.0, np.abs(times))


def iter_frames(solver: ArapSolver, keyframes: Keyframes, V: NDArray[np.float64], times: NDArray[np.float64], *,
                exact: bool = True, frame_tolerance: float = FRAME_TOLERANCE,
                more_point_targets: Callable[[float], NDArray[np.float64]] | None = None,
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
    exact : bool
        Solve every frame to ``tolerance``. False: only the frames at keyframe times; the others stop at
        ``frame_tolerance`` (see :data:`FRAME_TOLERANCE`), a few times sooner.
    frame_tolerance : float
        Tolerance of the frames between keyframes with ``exact=False`` (never below ``tolerance``).
    more_point_targets : callable or None
        The targets at a time of point handles the solver holds after the keyframes' (``solver`` built with them
        after ``keyframes.constraints.points``): the hidden rings of a picture's pins that hold an angle (``arap
        animate``: :func:`held_rings`).
    **solve_options
        Passed to :meth:`arap.ArapSolver.solve` (``tolerance``, ``max_iterations``, ...).

    Yields
    ------
    (float, ArapResult)
        Each frame's time and solution.

    Raises
    ------
    OptionError
        ``frame_tolerance`` not a number >= 0.
    """
    if isinstance(frame_tolerance, bool) or not isinstance(frame_tolerance, int | float) or not frame_tolerance >= 0:
        raise OptionError(f"frame_tolerance must be a number >= 0, got {frame_tolerance!r}")
    c = keyframes.constraints
    fixed = V[c.fixed]
    at_key = at_keyframes(keyframes, times)
    tolerance = solve_options.pop("tolerance", DEFAULT_TOLERANCE)
    between = tolerance if exact or tolerance == 0 else max(float(frame_tolerance), float(tolerance))
    for t, key in zip(times, at_key, strict=True):
        targets = np.concatenate([fixed, keyframes.handle_targets(float(t))])
        points = keyframes.point_targets(float(t))
        if points is None:
            points = c.point_targets
        if more_point_targets is not None:
            more = more_point_targets(float(t))
            points = more if points is None else np.concatenate([points, more])
        keyed = keyframes.key_at(float(t)) if key else None
        shape = None if keyed is None else keyed.shape
        if shape is not None:
            yield float(t), _keyed(solver, targets, points, shape)
            continue
        yield float(t), solver.solve(targets, point_targets=points, tolerance=tolerance if key else between,
                                     **solve_options)


def held_rings(keyframes: Keyframes, V: NDArray[np.float64], F: NDArray[np.integer], command: str = "arap.animate"
               ) -> tuple[PointConstraints | None, Callable[[float], NDArray[np.float64]] | None]:
    """The point handles a solve of ``keyframes`` on the mesh ``V``, ``F`` holds, and the targets at a time of those
    after the keyframes' own: the document's point handles, then the hidden rings of a picture's pins that hold an
    angle (:func:`arap.puppet.rings.held_points`, as the studio holds them) and :func:`ring_targets`; without such
    pins, the document's point handles and None.

    Raises
    ------
    ConstraintError
        A pin holds an angle on a mesh that is not flat in a plane of constant z, or too near the shape's edge
        (``command`` names the command that refuses it).
    """
    from arap.puppet.rings import held_points, pin_rings

    c = keyframes.constraints
    points, _ = held_points(c, V, F, command)
    if points is c.points or c.points is None:  # no pin holds an angle
        return c.points, None
    W, T = np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64)
    angles = [None if a is None else math.radians(a) for a in c.pin_angles or []]
    return points, ring_targets(keyframes, pin_rings(W, T, c.points.positions(W, T), angles))


def ring_targets(keyframes: Keyframes, rings: PinRings) -> Callable[[float], NDArray[np.float64]]:
    """The targets at a time of the hidden rings of a picture's pins that hold an angle (``rings``:
    :func:`arap.puppet.rings.pin_rings` on the rest pose of the keyframes' mesh): at each keyframe each ring point at
    its pin's target plus its rest offset turned by the angle the pin holds then (``"point_angles"``), between two
    keyframes blended from one to the other with the keyframe's easing, as the pins' targets are
    (:mod:`arap.constraints.keyframes`). ``arap animate`` and the studio's animation export both solve them so.

    Raises
    ------
    ConstraintError
        A keyframe gives no angle for a pin that has a ring.
    """
    held = {int(k) for k in np.unique(rings.pin)}

    def at_key(key: Keyframe) -> NDArray[np.float64]:
        angles, targets = key.point_angles, key.point_targets
        if angles is None or targets is None or any(angles[k] is None for k in held):
            raise ConstraintError(f"the keyframe at {key.time:g} s gives no angle for a pin that holds one")
        return rings.targets(targets, [None if a is None else math.radians(a) for a in angles])

    at_keys = {id(key): at_key(key) for key in keyframes.keys}
    return lambda t: keyframes.blend(t, lambda key: at_keys[id(key)])


def _keyed(solver: ArapSolver, targets: NDArray[np.float64], points: NDArray[np.float64] | None,
           shape: NDArray[np.float64]) -> ArapResult:
    """The frame of a keyframe with a shape: that shape, which the solver's next solve starts from."""
    t0 = time.perf_counter()
    result = solver.solve(targets, initial=shape, max_iterations=0, point_targets=points)
    return replace(result, vertices=np.array(shape, dtype=np.float64), iterations=0, converged=True,
                   timings={**result.timings, "total": time.perf_counter() - t0})


def animate(V: NDArray[np.float64], F: NDArray[np.integer], keyframes: Keyframes | str | Path | Mapping[str, Any],
            fps: float = DEFAULT_FPS, *, tolerance: float = DEFAULT_TOLERANCE, max_iterations: int | None = None,
            exact: bool = True, frame_tolerance: float = FRAME_TOLERANCE, **solver_options: Any) -> Animation:
    """Solve an animation: every frame between the first and the last keyframe, each from the previous one (by default
    to convergence).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    keyframes : Keyframes, path-like or mapping
        Keyframes, or a keyframes file (see the module description) or its parsed content.
    fps : float
        Frames per second.
    tolerance, max_iterations
        As for :meth:`arap.ArapSolver.solve`: ``tolerance`` is that of every frame, or with ``exact=False`` of the
        frames at keyframe times.
    exact : bool
        Solve every frame to ``tolerance``. False (``arap animate``'s default): the frames between keyframes stop at
        ``frame_tolerance``, a few times sooner.
    frame_tolerance : float
        Tolerance of the frames between keyframes with ``exact=False`` (see :data:`FRAME_TOLERANCE`).
    **solver_options
        Passed to :class:`arap.ArapSolver` (``energy``, ``weights``, ``backend``, ``alpha``); the region of interest,
        stiffness and point handles come from the keyframes' constraints.

    Returns
    -------
    Animation

    Examples
    --------
    The handle goes up over a second, five frames a second; each frame starts from the one before:

    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> keys = {"fixed": [0], "handles": [5], "keyframes": [
    ...     {"time": 0.0, "targets": [V[5].tolist()]}, {"time": 1.0, "targets": [[0.0, 2.0, 0.0]]}]}
    >>> animation = arap.animate(V, F, keys, fps=5)
    >>> animation.times.round(2).tolist(), animation.vertices.shape
    ([0.0, 0.2, 0.4, 0.6, 0.8, 1.0], (6, 42, 3))
    """
    from arap.solve.solver import ArapSolver

    V = np.asarray(V, dtype=np.float64)
    keys = keyframes if isinstance(keyframes, Keyframes) else load_keyframes(keyframes, V, len(F))
    times = frame_times(keys, fps)
    c = keys.constraints
    t0 = time.perf_counter()
    points, rings = held_rings(keys, V, F)
    solver = ArapSolver(V, F, c.constrained, roi=c.roi, stiffness=c.stiffness, points=points, **solver_options)
    setup = time.perf_counter() - t0
    frames = np.empty((len(times), len(V), 3))
    iterations = np.zeros(len(times), dtype=np.int64)
    converged = np.zeros(len(times), dtype=bool)
    seconds = np.zeros(len(times))
    for k, (_, result) in enumerate(iter_frames(solver, keys, V, times, exact=exact, frame_tolerance=frame_tolerance,
                                                tolerance=tolerance, max_iterations=max_iterations,
                                                more_point_targets=rings)):
        frames[k] = result.vertices
        iterations[k] = result.iterations
        converged[k] = result.converged
        seconds[k] = result.timings["total"]
    return Animation(times=times, vertices=frames, iterations=iterations, converged=converged, seconds=seconds,
                     setup_seconds=setup, at_key=at_keyframes(keys, times))


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
