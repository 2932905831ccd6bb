"""``arap deform``: deform a mesh file with a constraints file, with progress lines, a clean stop on Ctrl-C and
the result written in the input file's vertex order."""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import arap.options
from arap.cli.common import (
    EXIT_INTERRUPTED,
    FirstInterrupt,
    Progress,
    add_energy_options,
    add_iteration_options,
    add_selector_options,
    check_iterations_and_tolerance,
    energy_for,
    err,
    format_list,
    load_mesh_argument,
    selector_constraints,
    writable_destination,
)
from arap.errors import ArapError, ConstraintError, MeshError, MeshFormatError, UnconstrainedRegionError
from arap.meshes.repair import RepairResult
from arap.options import (
    ACCELERATIONS,
    START_NAMES,
)
from arap.warmup import warm_up_kernels

if TYPE_CHECKING:
    from arap.solve.result import ArapResult

__all__ = ["add_parser", "run_deform"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap deform`` and its options to the subcommands of ``arap``."""
    p = commands.add_parser("deform", help="deform a mesh with a constraints file",
                            description="Deform MESH so the handles reach their targets and the fixed vertices stay. "
                                        f"MESH is a surface, or a volume file ({format_list('volume')}) of "
                                        "tetrahedra or of planar triangles.")
    p.add_argument("mesh", metavar="MESH")
    p.add_argument("--solid", action="store_true",
                   help="MESH is a closed surface: fill it with tetrahedra (fTetWild; pip install 'arap[solid]'), "
                        "deform the solid and write the surface following it (or the solid, to a volume format); "
                        "constraints by position, picked among the solid's vertices")
    p.add_argument("--edge-length", type=float, default=0.05, metavar="SHARE",
                   help="with --solid: target edge length of the tetrahedra, a share of the bounding-box diagonal "
                        "(default: 0.05)")
    p.add_argument("-c", "--constraints", default=None, metavar="FILE.json",
                   help='JSON with "fixed", "handles", "targets" and optionally "roi" (file vertex indices); or give '
                        "the constraints by position with --fix, --handle, --move, --rotate and --roi")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help=f"output mesh file ({format_list('surface')}; a textured input keeps its UVs and "
                        f"materials in its own format), or a volume file ({format_list('volume')}); a solid "
                        "written to a surface format is its boundary surface")
    add_iteration_options(p)
    p.add_argument("--start", default="auto", metavar="{" + ",".join(START_NAMES) + "} or SHAPE",
                   help="starting pose: the rest pose, its best-fit rigid motion onto the targets, whichever has the "
                        "lower energy (default: auto), or a mesh file with MESH's vertices and triangles (or an STL "
                        "of its triangles), e.g. a shape exported from the studio (where the energy has several "
                        "minima, the solve then ends in that shape's)")
    p.add_argument("--acceleration", choices=ACCELERATIONS, default="lbfgs",
                   help="L-BFGS preconditioned by the global step (Liu et al. 2017), Anderson acceleration (Peng et "
                        "al. 2018) or the plain iteration (default: lbfgs)")
    add_energy_options(p, elements_default=True)
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    add_selector_options(p)
    p.set_defaults(func=run_deform)


def _start_shape(spec: str, repair: RepairResult, F: np.ndarray, label: str) -> np.ndarray:
    """The positions of a ``--start`` mesh file, in the order of the (repaired) mesh being deformed, whose triangles
    are ``F``: the file has the mesh file's vertices (as ``arap deform`` writes them) or the repaired mesh's (as the
    studio exports them), or is an STL of the mesh file's or the repaired mesh's triangles in their order."""
    from arap.io import format_of, load_mesh
    from arap.io.paths import folder_problem

    path = Path(spec)
    if not path.exists():
        problem = folder_problem(path.parent)  # a missing folder, or a file where the path needs a folder
        why = "" if problem is None else f" ({problem})"
        raise ArapError(f"--start must be one of {', '.join(START_NAMES)} or a mesh file; {spec} does not "
                        f"exist{why}")
    try:
        U, G = load_mesh(path, repair=False)
    except (MeshFormatError, MeshError) as exc:
        raise MeshFormatError(f"--start: {exc}") from None
    n_file, n_mesh = len(repair.vertex_map), int(repair.vertex_map.max(initial=-1)) + 1
    same = "the start must be a shape of the same mesh"
    if format_of(path.name) == "stl":  # a triangle soup: each corner is a vertex of the mesh's triangles
        if len(G) == len(F):
            corners = F.ravel()
        elif repair.input_F is not None and len(G) == len(repair.input_F):
            corners = repair.vertex_map[repair.input_F.ravel()]
        else:
            after = f" ({len(F):,} after repair)" if repair.input_F is not None else ""
            n_file_faces = len(repair.input_F) if repair.input_F is not None else len(F)
            raise ArapError(f"--start {spec} has {len(G):,} triangles, but {label} has {n_file_faces:,}{after}: {same}")
        U = U[G.ravel()]
        _check_finite(U, corners >= 0, spec, np.arange(len(U)) // 3, "triangle")
        out = np.zeros((n_mesh, 3))
        out[corners[corners >= 0]] = U[corners >= 0]
        spread = float(np.abs(U[corners >= 0] - out[corners[corners >= 0]]).max(initial=0.0))
        if spread > 1e-5 * max(float(np.linalg.norm(np.ptp(out, axis=0))), 1e-300):
            raise ArapError(f"--start {spec} has the triangle count of {label}, but its triangles are not the mesh's "
                            f"in their order (corners of one vertex lie {spread:.3g} apart): {same}")
        return out
    if len(U) == n_file:
        kept = repair.vertex_map >= 0
        _check_finite(U, kept, spec, np.arange(n_file), "vertex")
        out = np.empty((n_mesh, 3))
        out[repair.vertex_map[kept]] = U[kept]
        G = repair.vertex_map[G]
    elif len(U) == n_mesh:
        _check_finite(U, np.ones(n_mesh, dtype=bool), spec, np.arange(n_mesh), "vertex")
        out = U
    else:
        after = f" ({n_mesh:,} after repair)" if n_mesh != n_file else ""
        raise ArapError(f"--start {spec} has {len(U):,} vertices, but {label} has {n_file:,}{after}: {same}")
    # Every triangle of the mesh must be one of the start's (the start may keep faces repair dropped).
    G = np.sort(G[(G >= 0).all(axis=1)], axis=1)
    mine = np.unique(np.sort(F, axis=1), axis=0)
    if len(np.unique(np.vstack([G, mine]), axis=0)) != len(np.unique(G, axis=0)):
        raise ArapError(f"--start {spec} has the vertex count of {label} but not its triangles: {same}, with its "
                        "vertices in the mesh file's order or the repaired mesh's")
    return out


def _check_finite(U: np.ndarray, used: np.ndarray, spec: str, names: np.ndarray, what: str) -> None:
    """Refuse a ``--start`` whose used rows ``U[used]`` are not finite, naming the first bad one as ``what`` number
    ``names[row]``."""
    bad = used & ~np.isfinite(U).all(axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise ArapError(f"--start {spec}: {what} {int(names[first])} has NaN or infinite coordinates; the start must "
                        "be a finite shape (as arap deform or the studio write it)")


def _in_file_numbering(exc: UnconstrainedRegionError, repair: RepairResult) -> UnconstrainedRegionError:
    """The error with its sample vertices named by their (first) index in the mesh file, as the constraints file
    names them, rather than by their index in the repaired mesh."""
    mesh_vertices, first = np.unique(repair.vertex_map, return_index=True)
    in_file = first[np.searchsorted(mesh_vertices, exc.vertices)]
    sample = [int(i) for i in in_file]
    message = str(exc).replace(f"vertices {exc.vertices}", f"vertices {sample} of the file", 1)
    return UnconstrainedRegionError(message, vertices=sample, size=exc.size)


def _note_flat_faces(V: np.ndarray, F: np.ndarray, energy: str, weights: str) -> None:
    """Warn that nearly flat triangles can make the spokes energies fold or blow up (their cotangent weights are
    large and negative); spokes and rims, and clamped or uniform weights, have no negative terms."""
    if energy == "spokes_and_rims" or weights != "cotangent":
        return
    from arap.diagnose import FLAT_ANGLE_DEGREES, flat_faces

    count = flat_faces(V, F)
    if count:
        err(f"arap: note: {count:,} faces are nearly flat (an angle above {FLAT_ANGLE_DEGREES:g}°): their cotangent "
             f"weights are large and negative, and {energy} can fold or blow up the shape there; --energy "
             "spokes_and_rims (the default) cannot")


def _read_input(spec: str) -> tuple[np.ndarray, np.ndarray, RepairResult, str, Any]:
    """The mesh argument as :func:`~arap.cli.common.load_mesh_argument` reads it, with the
    :class:`arap.io.assets.MeshAsset` of a glTF or GLB file read on the way (the mesh reader reads the file as an asset
    anyway, so it is read once); None for the other inputs."""
    from arap.io.assets import load_asset
    from arap.io.meshfile import mesh_of_asset

    path = Path(spec)
    if path.suffix.lower() in (".glb", ".gltf") and path.is_file():
        asset = load_asset(path)
        V, F, repair = mesh_of_asset(asset, name=str(path))
        return V, F, repair, str(path), asset
    V, F, repair, label = load_mesh_argument(spec)
    return V, F, repair, label, None


def _textured_input(mesh: str, output: str, quiet: bool, asset: Any = None) -> Any:
    """The input as a :class:`arap.io.assets.MeshAsset` when it carries what a deformation keeps (texture
    coordinates, colours, materials, groups, a glTF scene) and the output is of its format family, so that the output
    keeps them; else None (the geometry alone is written, with a note when attributes are left behind). ``asset``:
    the input's asset when it was read already."""
    import arap.io.formats as formats
    from arap.io.assets import asset_format, load_asset

    try:
        source, target = asset_format(mesh), asset_format(output)
    except MeshFormatError:
        return None
    if asset is None:
        if not Path(mesh).is_file():
            return None
        asset = load_asset(mesh)
    family = {name: formats.family(name) for name in formats.names("surface", asset=True)}
    kept = asset.format in ("glb", "gltf") or asset.uvs is not None or asset.vertex_colors is not None \
        or bool(asset.materials) or bool(asset.groups)
    if not kept:
        return None
    if family[source] != family[target]:
        if not quiet:
            err(f"arap: note: {output} gets the geometry only: texture coordinates, colours and materials are kept "
                f"when writing {'GLB or glTF' if family[source] == 'gltf' else source.upper()}, as {mesh} is")
        return None
    return asset


@dataclass(frozen=True)
class _Elements:
    """What ``arap deform`` solves on when it is not the input surface: a volume file's tetrahedra or triangles, or
    the tetrahedra filling the input surface (``--solid``) with the surface's vertices embedded in them."""

    V: np.ndarray  # (n, 3): a planar mesh read with two coordinates gets z = 0
    T: np.ndarray  # (m, 4) tetrahedra or (m, 3) triangles
    columns: int  # coordinates per vertex in the file
    tets: np.ndarray | None = None  # --solid: the tetrahedron of each surface vertex
    barycentric: np.ndarray | None = None  # --solid: its barycentric coordinates there

    @property
    def word(self) -> str:
        return "tetrahedra" if self.T.shape[1] == 4 else "triangles"

    def follow(self, U: np.ndarray) -> np.ndarray:
        """``--solid``: the surface's vertices in the deformed solid ``U``."""
        from arap.meshes.tetrahedralize import interpolate_points

        assert self.tets is not None and self.barycentric is not None
        return interpolate_points(U, self.T, self.tets, self.barycentric)


def _read_volume(spec: str) -> _Elements:
    """A volume file given as MESH (tetrahedra, or triangles: planar ones are deformed in their plane)."""
    from arap.io.volume import volume_for_solving

    V, T, columns = volume_for_solving(spec)
    return _Elements(V=V, T=T, columns=columns)


def _fill(V: np.ndarray, F: np.ndarray, label: str, args: argparse.Namespace) -> _Elements:
    """``--solid``: the tetrahedra filling the surface, with the surface's vertices embedded in them."""
    from arap.meshes.tetrahedralize import embed_points, tetrahedralize

    t0 = time.perf_counter()
    V_tet, T = tetrahedralize(V, F, edge_length=args.edge_length)
    tets, barycentric = embed_points(V_tet, T, V)
    if not args.quiet:
        err(f"arap: filled {label} with {len(T):,} tetrahedra ({len(V_tet):,} vertices) in "
            f"{time.perf_counter() - t0:.1f} s; its {len(V):,} vertices follow the solid")
    return _Elements(V=V_tet, T=T, columns=3, tets=tets, barycentric=barycentric)


def _check_output_type(output: str) -> bool:
    """Whether the output is a volume file; refuses a type that is neither a volume nor a surface format."""
    from arap.io import format_of
    from arap.io.volume import is_volume_file

    if output.endswith(("/", os.sep)) or (os.path.isdir(output) and not os.path.islink(output)):
        raise MeshFormatError(f"cannot write {output}: it is a folder; give the output file's name, such as "
                              f"{os.path.join(output, 'deformed.obj')}")

    if is_volume_file(output):
        return True
    format_of(output)
    return False


def _write_elements(output: str, elements: _Elements, U: np.ndarray) -> np.ndarray:
    """Write the deformed volume mesh (tetrahedra or triangles) ``U``: as a volume file, or as its (boundary)
    surface; the positions written."""
    from arap.io.volume import save_deformed_volume

    return save_deformed_volume(output, U, elements.T, elements.columns)


def run_deform(args: argparse.Namespace) -> int:
    """``arap deform``: solve the constraints file's problem on the mesh and write the result; the exit status."""
    from arap.constraints import load_constraints
    from arap.io import format_of, save_mesh
    from arap.io.assets import save_asset
    from arap.io.volume import is_volume_file, save_volume_mesh
    from arap.puppet.rings import held_points
    from arap.solve.solver import ArapSolver

    # Fail before any work on an unsupported output type, a missing folder (or a file where a folder should be), or
    # an output that is not a regular file (a folder, a FIFO, a device, or a symbolic link to one).
    volume_out = _check_output_type(args.output)
    writable_destination(args.output)
    check_iterations_and_tolerance(args.iterations, args.tolerance)
    if args.solid and args.constraints is not None:
        raise ConstraintError("with --solid give the constraints by position (--fix, --handle ...): they pick the "
                              "solid's vertices, which a constraints file cannot name")
    elements: _Elements | None = None
    asset = None
    if not args.solid and is_volume_file(args.mesh):
        elements = _read_volume(args.mesh)
        V, F, label = elements.V, elements.T, args.mesh
        repair = RepairResult.identity(V)
    else:
        V, F, repair, label, read_asset = _read_input(args.mesh)
        if not (args.solid and volume_out):
            asset = _textured_input(args.mesh, args.output, args.quiet, read_asset)
        if args.solid:
            elements = _fill(V, F, label, args)
    solve_V, solve_F = (V, F) if elements is None else (elements.V, elements.T)
    n_file = len(repair.vertex_map)
    picked = selector_constraints(args, solve_V)  # by position, on the loaded mesh: in its numbering already
    if (picked is None) == (args.constraints is None):
        raise ConstraintError("give the constraints either as a file (-c FILE.json) or by position (--fix, --handle "
                              "...), not both" if picked is not None else "give the constraints as a file "
                              "(-c FILE.json) or by position (--fix 'y<0.1' --handle 'y>0.9' --move 0.2,0,0)")
    constraints = picked if picked is not None else load_constraints(args.constraints, n_file, len(F))
    renumbered = repair.renumbers
    if repair.report and constraints.points is not None and len(constraints.points):
        raise ConstraintError("point handles refer to the file's triangles, which mesh repair changed; repair the "
                              "mesh file first (arap info shows what repair changes)")
    if repair.report and not args.quiet:
        err(f"arap: repaired {label}: {'; '.join(repair.report)}")
    if renumbered and picked is None:  # a file names the file's vertices
        constraints = constraints.remapped(repair.vertex_map)
        if not args.quiet:
            err("arap: vertex indices changed by the repair; constraints were renumbered to match")
    indices, targets = constraints.indices_and_targets(solve_V)
    # A picture's pins that hold an angle bring their hidden rings (on a flat mesh; refused elsewhere).
    points, point_targets = held_points(constraints, solve_V, solve_F, "arap deform")
    # The default energy: elements for a solid, and for a flat mesh (a picture's) that the targets keep in its plane.
    args.energy = energy_for(args.energy, solve_V, solve_F, targets, point_targets)
    if elements is not None and args.start not in START_NAMES:
        raise ArapError(f"--start takes {', '.join(START_NAMES)} for solids and volume files; a start shape file is "
                        "for surfaces")
    start = args.start if args.start in START_NAMES else _start_shape(args.start, repair, F, label)

    warm_up_kernels(args.quiet)
    try:
        solver = ArapSolver(solve_V, solve_F, indices, energy=args.energy, weights=args.weights, roi=constraints.roi,
                            stiffness=constraints.stiffness, alpha=args.alpha, points=points)
    except UnconstrainedRegionError as exc:
        if not renumbered or elements is not None:
            raise
        raise _in_file_numbering(exc, repair) from None
    if not args.quiet:
        counts = f"{len(V):,} vertices, {len(F):,} faces" if elements is None else \
            f"{len(solve_V):,} vertices, {len(solve_F):,} {elements.word}"
        err(f"arap: {label}: {counts}; {len(constraints.fixed):,} fixed, "
             f"{len(constraints.handles):,} handles; precompute {1e3 * solver.factor_seconds:.0f} ms")
        if elements is None:
            _note_flat_faces(V, F, args.energy, args.weights)
    if solver.n_free == 0:  # even with -q: the result is the constraints alone, which is rarely what was meant
        where = "of the region of interest " if constraints.roi is not None else ""
        err(f"arap: warning: no vertex {where}is free to move (every one is fixed or a handle): the handles jump to "
            "their targets and nothing follows them; leave vertices out of \"fixed\" and \"handles\""
            f"{' or widen the region' if constraints.roi is not None else ''}")
    progress = Progress(args.iterations, sys.stderr, enabled=not args.quiet)
    interrupt = FirstInterrupt()
    stopped_at: list[int] = []  # the iteration after which the callback stopped the solve

    def callback(iteration: int, energy: float) -> bool:
        progress(iteration, energy)
        if interrupt.requested:
            stopped_at.append(iteration)
            return False
        return True

    t0 = time.perf_counter()
    # A first Ctrl-C stops the solve at the end of its iteration; one that comes later, while the output is written,
    # is only noted, so that the output is written in full and the exit status says so.
    with interrupt:
        try:
            result = solver.solve(targets, initial=start, max_iterations=args.iterations,
                                  tolerance=args.tolerance, callback=callback, acceleration=args.acceleration,
                                  point_targets=point_targets)
        finally:
            progress.close()
        seconds = time.perf_counter() - t0
        if not np.isfinite(result.vertices).all():
            raise ArapError("the solve produced non-finite positions; nothing was written")
        back = None
        if elements is not None and (volume_out or elements.tets is None):  # the volume mesh, or its surface
            U_out = _write_elements(args.output, elements, result.vertices)
        else:
            U_surface = result.vertices if elements is None else elements.follow(result.vertices)
            U_out, F_out = U_surface, F
            # The output keeps the file's vertex order and count, as its constraints do (an STL has no vertex
            # identity: its welded vertices are the mesh).
            back = repair.in_input_order(U_surface) if renumbered and format_of(args.mesh) != "stl" else None
            if back is not None:
                U_out, F_out = back
            if asset is not None and len(U_out) == len(asset.vertices):
                save_asset(args.output, asset, U_out)
            elif volume_out:
                save_volume_mesh(args.output, U_out, F_out)
            else:
                save_mesh(args.output, U_out, F_out)
    # The solve was cut short only when Ctrl-C stopped it before it converged or ran its last iteration: a Ctrl-C
    # during the last iteration, after it, or while the output was written leaves the complete result written.
    cap = args.iterations if args.iterations is not None else arap.options.MAX_ITERATIONS
    if stopped_at and not result.converged and result.iterations < cap:
        err(f"arap: interrupted after {result.iterations} iterations: wrote the last iterate to {args.output} "
             f"(not converged: residual {result.residual:.2g}, tolerance {args.tolerance:g})")
        return EXIT_INTERRUPTED
    try:
        _report(args, result, seconds, label, U_out, back, repair, renumbered)
    except KeyboardInterrupt:
        interrupt.requested = True
    if interrupt.requested:
        err(f"arap: interrupted at the end of the solve: {args.output} was written in full")
    return 0


def _report(args: argparse.Namespace, result: ArapResult, seconds: float, label: str, U_out: np.ndarray,
            back: tuple[np.ndarray, np.ndarray] | None, repair: RepairResult, renumbered: bool) -> None:
    """The lines ``arap deform`` prints after a complete solve whose result was written."""
    from arap.io import format_of

    if not args.quiet:
        if result.energies:
            per_it = 1e3 * seconds / max(result.iterations, 1)
            status = ("converged" if result.converged else "every iteration run (tolerance 0)" if not args.tolerance
                      else f"iteration limit reached, not converged (residual {result.residual:.2g}, tolerance "
                      f"{args.tolerance:g})")
            err(f"arap: {result.iterations} iterations in {seconds:.2f} s ({per_it:.1f} ms/iteration), "
                 f"energy {result.energies[0]:.6g} -> {result.energies[-1]:.6g}, {status}")
            if not result.converged and args.tolerance and args.iterations is None:
                other = "" if args.energy == "spokes_and_rims" else ("; spokes_and_rims (the default energy) often "
                                                                     "converges much sooner on such meshes")
                err(f"arap: note: the shape written is the last iterate; raise --iterations to go on{other}")
            if min(result.energies) < 0:
                err(f"arap: note: the energy is below 0 because {args.energy} with {args.weights} weights has "
                     "negative terms on obtuse triangles (see 'Energy and weights' in docs/solver.md); "
                     "spokes_and_rims is never negative")
        in_file_order = (f" in the vertex order of {label} ({len(U_out):,} vertices)"
                         if back is not None and Path(args.output).suffix.lower() != ".stl" else "")  # no STL vertices
        err(f"arap: wrote {args.output}{in_file_order}")
        if back is None and renumbered and format_of(args.mesh) != "stl" and repair.input_V is not None:
            nan = int(np.argmax(~np.isfinite(repair.input_V).all(axis=1)))
            err(f"arap: note: {args.output} has the repaired mesh's {len(U_out):,} vertices, not in the vertex "
                 f"order of {label}: its vertex {nan}, used by no face, has NaN or infinite coordinates, which "
                 "cannot be written; remove it from the file to keep the numbering")
