"""``arap animate``: solve a keyframed animation (:mod:`arap.animation`) and write it as numbered meshes or one
animated GLB."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from arap.cli.common import (
    add_energy_options,
    add_iteration_options,
    check_iterations_and_tolerance,
    err,
    load_mesh_argument,
    warm_up_kernels,
)
from arap.errors import ConstraintError, MeshFormatError, OptionError

__all__ = ["add_parser", "run_animate"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap animate`` and its options to the subcommands of ``arap``."""
    from arap.animation import DEFAULT_FPS, FRAME_TOLERANCE

    p = commands.add_parser("animate", help="solve a keyframed animation",
                            description="Pose MESH's handles at keyframes and solve every frame between them, each "
                                        "from the previous frame: the frames at the keyframes to convergence, the "
                                        f"others to tolerance {FRAME_TOLERANCE:g} (within about 1e-3 of the mesh's "
                                        "size of converged frames, a few times faster; --exact solves every frame to "
                                        "convergence).")
    p.add_argument("mesh", metavar="MESH")
    p.add_argument("-k", "--keyframes", required=True, metavar="KEYS.json",
                   help='a constraints file with "keyframes": [{"time": seconds, "targets": [...]} or '
                        '{"time": seconds, "transforms": [4x4 per handle group]}, ...]; a keyframe may add '
                        '"easing" (linear, ease-in-out, ease-in, ease-out), "point_targets" (one per point handle) '
                        'and "shape" (the whole shape at that time, one [x, y, z] per vertex)')
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="frame_####.obj (numbered files in that mesh format) or OUT.glb (one animated glTF)")
    p.add_argument("--fps", type=float, default=DEFAULT_FPS, help=f"frames per second (default: {DEFAULT_FPS:g})")
    add_iteration_options(p)
    p.add_argument("--exact", action="store_true",
                   help="solve every frame to convergence (-t/--tolerance), not only the frames at the keyframes")
    add_energy_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run_animate)


def _duration(seconds: float) -> str:
    """``40 ms``, ``2.5 s``, ``12 s``, ``3 min 20 s``, ``1 h 05 min``."""
    seconds = max(float(seconds), 0.0)
    if seconds < 1:
        return f"{1e3 * seconds:.0f} ms"
    if seconds < 10:
        return f"{seconds:.1f} s"
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def _check_output(output: str) -> None:
    """Fail before any work on an output that is neither a .glb nor numbered mesh files in an existing folder."""
    from arap.animation import frame_paths
    from arap.io import format_of
    from arap.io.paths import write_destination

    path = Path(output)
    if path.suffix.lower() != ".glb":
        if "#" not in path.name:
            raise OptionError(f"{output}: write an animation to a .glb file or to numbered files (frame_####.obj)")
        format_of(path.name)
        path = frame_paths(path, 1)[0]
    try:
        write_destination(path)
    except OSError as exc:
        raise MeshFormatError(f"cannot write {output}: {exc.strerror or exc}") from None


def run_animate(args: argparse.Namespace) -> int:
    """``arap animate``: the exit status."""
    from arap.animation import (
        FRAME_TOLERANCE,
        Animation,
        at_keyframes,
        frame_times,
        iter_frames,
        load_keyframes,
        save_animation,
    )
    from arap.solve.solver import ArapSolver

    _check_output(args.output)
    check_iterations_and_tolerance(args.iterations, args.tolerance)
    V, F, repair, label = load_mesh_argument(args.mesh)
    if repair.renumbers:
        raise ConstraintError(f"the keyframes name vertices of {label}, which mesh repair renumbered; repair the mesh "
                              "file first (arap info shows what repair changes)")
    keys = load_keyframes(args.keyframes, V, len(F))
    times = frame_times(keys, args.fps)
    warm_up_kernels(args.quiet)
    c = keys.constraints
    solver = ArapSolver(V, F, c.constrained, energy=args.energy, weights=args.weights, roi=c.roi,
                        stiffness=c.stiffness, alpha=args.alpha, points=c.points)
    if not args.quiet:
        how = ("every frame to convergence" if args.exact else
               f"keyframes to convergence, the frames between to tolerance {FRAME_TOLERANCE:g}; --exact: all to "
               "convergence")
        err(f"arap: {label}: {len(V):,} vertices; {len(keys.keys)} keyframes, {len(times)} frames at {args.fps:g} "
            f"fps ({how}); precompute {1e3 * solver.factor_seconds:.0f} ms")
    frames = np.empty((len(times), len(V), 3))
    iterations = np.zeros(len(times), dtype=np.int64)
    converged = np.zeros(len(times), dtype=bool)
    seconds = np.zeros(len(times))
    at_key = at_keyframes(keys, times)
    t0 = time.perf_counter()
    for k, (t, result) in enumerate(iter_frames(solver, keys, V, times, exact=args.exact, tolerance=args.tolerance,
                                                max_iterations=args.iterations)):
        frames[k], iterations[k], converged[k] = result.vertices, result.iterations, result.converged
        seconds[k] = result.timings["total"]
        if not args.quiet:
            # What is left at the mean time of the frames so far that started from the frame before (the first one
            # starts from the rest pose: it may take far more or far fewer iterations than the others).
            typical = seconds[1:k + 1].mean() if k else seconds[0]
            left = (len(times) - k - 1) * typical
            eta = f"; about {_duration(left)} left" if 0 < k < len(times) - 1 or len(times) == 2 else ""
            err(f"arap: frame {k + 1}/{len(times)} at {t:.3f} s: {result.iterations} iterations"
                f"{'' if result.converged else ' (not converged)'} in {_duration(seconds[k])}{eta}")
            if k == min(1, len(times) - 2):
                err(f"arap: expected time for the {len(times)} frames: about {_duration(seconds[:k + 1].sum() + left)} "
                    f"(the frames left × this frame's {_duration(seconds[k])}; updated on every frame)")
    total = time.perf_counter() - t0
    animation = Animation(times=times, vertices=frames, iterations=iterations, converged=converged, seconds=seconds,
                          setup_seconds=solver.factor_seconds, at_key=at_key)
    paths = save_animation(args.output, F, animation)
    if not args.quiet:
        rest = f", the others {1e3 * seconds[1:].mean():.0f} ms on average" if len(times) > 1 else ""
        err(f"arap: {len(times)} frames solved in {total:.2f} s ({len(times) / max(total, 1e-9):.1f} frames/s; "
            f"the first {1e3 * seconds[0]:.0f} ms{rest})")
        if not converged.all():
            err(f"arap: note: {int((~converged).sum())} frames reached the iteration limit before converging")
        err(f"arap: wrote {paths[0] if len(paths) == 1 else f'{paths[0]} … {paths[-1]}'}")
    return 0
