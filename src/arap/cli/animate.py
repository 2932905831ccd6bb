"""``arap animate``: solve a keyframed animation (:mod:`arap.animation`) and write it as numbered meshes or one
animated GLB."""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from arap.cli.common import (
    add_energy_options,
    add_iteration_options,
    check_iterations_and_tolerance,
    energy_for,
    err,
    load_mesh_argument,
)
from arap.errors import ConstraintError, MeshFormatError, OptionError
from arap.warmup import warm_up_kernels

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
    p.add_argument("mesh", metavar="MESH", help="a surface, or a volume file of tetrahedra (solved on them) or of "
                                               "planar triangles")
    p.add_argument("-k", "--keyframes", required=True, metavar="KEYS.json",
                   help='a constraints file with "keyframes": [{"time": seconds, "targets": [...]} or '
                        '{"time": seconds, "transforms": [4x4 per handle group]}, ...]; a keyframe may add '
                        '"easing" (linear, ease-in-out, ease-in, ease-out), "point_targets" (one per point handle), '
                        '"point_angles" (the angles a picture\'s pins hold, as their "angle") and "shape" (the whole '
                        'shape at that time, one [x, y, z] per vertex)')
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="frame_####.obj (numbered files in that mesh format; a volume format such as frame_####.msh "
                        "for a volume MESH) or OUT.glb (one animated glTF); a solid written to a surface format is "
                        "its boundary surface")
    p.add_argument("--fps", type=float, default=DEFAULT_FPS, help=f"frames per second (default: {DEFAULT_FPS:g})")
    add_iteration_options(p)
    p.add_argument("--exact", action="store_true",
                   help="solve every frame to convergence (-t/--tolerance), not only the frames at the keyframes")
    add_energy_options(p, elements_default=True)
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
    from arap.io.volume import is_volume_file

    path = Path(output)
    if path.suffix.lower() != ".glb":
        if "#" not in path.name:
            raise OptionError(f"{output}: write an animation to a .glb file or to numbered files (frame_####.obj)")
        if not is_volume_file(path.name):
            format_of(path.name)
        path = frame_paths(path, 1)[0]
    try:
        write_destination(path)
    except OSError as exc:
        raise MeshFormatError(f"cannot write {output}: {exc.strerror or exc}") from None


def _read_volume(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray, int] | None:
    """A volume file given as MESH, as :func:`arap.io.volume.volume_for_solving` gives it; None for other meshes."""
    from arap.io.volume import is_volume_file, volume_for_solving

    if not is_volume_file(args.mesh):
        return None
    V, T, columns = volume_for_solving(args.mesh)
    return V, T, columns


def _save_volume_animation(output: str, T: np.ndarray, columns: int, animation: Any) -> list[Path]:
    """The frames of a volume mesh written as ``arap deform`` writes one: numbered volume files, or the boundary
    surface of a solid (numbered surface files or an animated GLB)."""
    from arap.animation import frame_paths, save_animation
    from arap.io.volume import boundary_surface, is_volume_file, save_deformed_volume

    if is_volume_file(output):
        paths = frame_paths(output, len(animation.times))
        for path, frame in zip(paths, animation.vertices, strict=True):
            save_deformed_volume(path, frame, T, columns)
        return paths
    if T.shape[1] == 4:
        _, faces, kept = boundary_surface(animation.vertices[0], T)
        return save_animation(output, faces, replace(animation, vertices=animation.vertices[:, kept]))
    return save_animation(output, T, animation)


def run_animate(args: argparse.Namespace) -> int:
    """``arap animate``: the exit status."""
    from arap.animation import (
        FRAME_TOLERANCE,
        Animation,
        at_keyframes,
        frame_times,
        held_rings,
        iter_frames,
        load_keyframes,
        save_animation,
    )
    from arap.solve.solver import ArapSolver

    _check_output(args.output)
    check_iterations_and_tolerance(args.iterations, args.tolerance)
    volume = _read_volume(args)
    if volume is not None:
        V, F, label = volume[0], volume[1], args.mesh
    else:
        V, F, repair, label = load_mesh_argument(args.mesh)
        if repair.renumbers:
            raise ConstraintError(f"the keyframes name vertices of {label}, which mesh repair renumbered; repair the "
                                  "mesh file first (arap info shows what repair changes)")
    keys = load_keyframes(args.keyframes, V, len(F))
    points, rings = held_rings(keys, V, F, "arap animate")
    times = frame_times(keys, args.fps)
    c = keys.constraints
    if args.energy is None:  # the default for the mesh and every frame's targets, as arap deform picks it
        args.energy = energy_for(None, V, F, V[c.fixed], *(keys.handle_targets(float(t)) for t in times),
                                 *(keys.point_targets(float(t)) for t in times), c.point_targets)
    warm_up_kernels(args.quiet)
    solver = ArapSolver(V, F, c.constrained, energy=args.energy, weights=args.weights, roi=c.roi,
                        stiffness=c.stiffness, alpha=args.alpha, points=points)
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
                                                max_iterations=args.iterations, more_point_targets=rings)):
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
    paths = save_animation(args.output, F, animation) if volume is None else \
        _save_volume_animation(args.output, F, volume[2], animation)
    if not args.quiet:
        rest = f", the others {1e3 * seconds[1:].mean():.0f} ms on average" if len(times) > 1 else ""
        err(f"arap: {len(times)} frames solved in {total:.2f} s ({len(times) / max(total, 1e-9):.1f} frames/s; "
            f"the first {1e3 * seconds[0]:.0f} ms{rest})")
        if not converged.all():
            err(f"arap: note: {int((~converged).sum())} frames reached the iteration limit before converging")
        err(f"arap: wrote {paths[0] if len(paths) == 1 else f'{paths[0]} … {paths[-1]}'}")
    return 0
