"""``arap info``: describe a mesh, its defects and what repair would change, as text or as JSON; with ``--png``, draw
it into a PNG picture too (``-c`` marks a constraints file's anchors and handles in it)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import TYPE_CHECKING, Any

import numpy as np

from arap.cli.common import err, load_mesh_argument, out, positive_int, writable_destination
from arap.errors import ArapError, MeshError

if TYPE_CHECKING:
    from arap.diagnose import MeshInfo

__all__ = ["add_parser", "info_report", "run_info", "volume_report"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap info`` and its options to the subcommands of ``arap``."""
    p = commands.add_parser("info", help="describe a mesh and its defects",
                            description="Counts, components, boundary, defects, negative cotangent weights, and what "
                                        "repair would change.")
    p.add_argument("mesh", metavar="MESH")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    g = p.add_argument_group("picture")
    g.add_argument("--png", default=None, metavar="OUT.png",
                   help="also draw the mesh, shaded, into this PNG file (as arap.show does)")
    g.add_argument("-c", "--constraints", default=None, metavar="FILE.json",
                   help="with --png: mark this constraints file's anchors (red), handle groups and region of interest "
                        "in the picture, in the studio's colours")
    g.add_argument("--width", type=positive_int, default=640, help="picture width in pixels (default: 640)")
    g.add_argument("--height", type=positive_int, default=480, help="picture height in pixels (default: 480)")
    g.add_argument("--azimuth", type=float, default=None, metavar="DEG",
                   help="view from this many degrees right of the front (+z) (default: 30)")
    g.add_argument("--elevation", type=float, default=None, metavar="DEG",
                   help="view from this many degrees above (default: 20)")
    p.set_defaults(func=run_info)


def info_report(V: np.ndarray, F: np.ndarray, label: str) -> tuple[MeshInfo, dict[str, Any]]:
    """What ``arap info`` reports: the mesh description and the JSON-ready report of ``arap info --json``."""
    from arap.diagnose import inspect_mesh
    from arap.meshes.mesh import check_mesh
    from arap.meshes.repair import repair_mesh

    info = inspect_mesh(V, F)
    report: dict[str, Any] = {"mesh": label}
    for key, value in dataclasses.asdict(info).items():
        report[key] = value.tolist() if isinstance(value, np.ndarray) else value
    report.update(n_components=info.n_components, closed=info.closed, problems=info.problems)
    try:
        check_mesh(V, F)
        report["ready"], report["not_ready_reason"] = True, None
    except MeshError as exc:
        report["ready"], report["not_ready_reason"] = False, str(exc)
    try:
        fixed = repair_mesh(V, F)
    except MeshError as exc:
        report["repair"] = {"possible": False, "reason": str(exc)}
    else:
        renumbers = fixed.renumbers
        repaired = inspect_mesh(fixed.V, fixed.F) if fixed.report else info
        report["repair"] = {"possible": True, "changes": list(fixed.report), "n_vertices": len(fixed.V),
                            "n_faces": len(fixed.F), "renumbers_vertices": renumbers,
                            "n_components": repaired.n_components}
    return info, report


def volume_report(V: np.ndarray, T: np.ndarray, label: str) -> dict[str, Any]:
    """What ``arap info`` reports on a volume file: counts, boundary faces, element measures, and whether the solver
    takes it (tetrahedra, or planar triangles, with ``energy="elements"``)."""
    from arap.io.volume import boundary_faces
    from arap.meshes.domain import check_domain, signed_measures

    report: dict[str, Any] = {"mesh": label, "n_vertices": len(V), "dimension": int(V.shape[1])}
    if T.shape[1] == 4:
        report["n_tetrahedra"] = len(T)
        in_range = bool(len(T)) and int(T.min()) >= 0 and int(T.max()) < len(V)
        report["n_boundary_faces"] = len(boundary_faces(T)) if in_range else None
        volumes = signed_measures(V, T) / 6.0 if in_range else np.zeros(0)
        report.update(min_volume=float(volumes.min()) if len(volumes) else None,
                      max_volume=float(volumes.max()) if len(volumes) else None,
                      total_volume=float(np.abs(volumes).sum()))
    else:
        report["n_triangles"] = len(T)
    try:
        domain = check_domain(V, T, elements=True)
        report["kind"], report["ready"], report["not_ready_reason"] = domain.kind, True, None
    except MeshError as exc:
        report["kind"], report["ready"], report["not_ready_reason"] = None, False, str(exc)
    return report


def _run_volume_info(args: argparse.Namespace) -> int:
    """``arap info`` on a volume file: counts and measures (text or JSON)."""
    from arap.io.volume import load_volume_mesh

    if args.png is not None or args.constraints is not None:
        raise ArapError("--png and -c draw surfaces; for a volume file write its boundary surface first (arap "
                        "deform ... -o surface.obj)")
    V, T = load_volume_mesh(args.mesh)
    report = volume_report(V, T, args.mesh)
    if args.json:
        out(json.dumps(report, indent=2))
        return 0
    out(args.mesh)
    out(f"  {report['n_vertices']:,} vertices ({report['dimension']}-d)")
    if T.shape[1] == 4:
        out(f"  {report['n_tetrahedra']:,} tetrahedra, {report['n_boundary_faces'] or 0:,} boundary faces")
        if report["min_volume"] is not None:
            out(f"  tetrahedron volume: min {report['min_volume']:.6g}, max {report['max_volume']:.6g} "
                f"(total {report['total_volume']:.6g})")
    else:
        out(f"  {report['n_triangles']:,} triangles")
    if report["ready"]:
        what = {"solid": "a solid", "planar": "a planar mesh, deformed in its plane",
                "surface": "a surface in space"}[report["kind"]]
        out(f"  ready for ARAP: yes ({what}, energy elements)")
    else:
        out(f"  ready for ARAP: no ({report['not_ready_reason']})")
    return 0


def _check_destination(path: str) -> None:
    """Refuse a PNG destination that cannot be written (a folder, a FIFO, a missing folder) before any work."""
    writable_destination(path, ArapError)


def _picture(args: argparse.Namespace, V: np.ndarray, F: np.ndarray) -> Any:
    """The picture of ``arap info --png``, with the constraints file's marks."""
    from arap.render.camera import DEFAULT_AZIMUTH, DEFAULT_ELEVATION
    from arap.render.show import show

    azimuth = DEFAULT_AZIMUTH if args.azimuth is None else args.azimuth
    elevation = DEFAULT_ELEVATION if args.elevation is None else args.elevation
    return show(V, F, constraints=args.constraints, width=args.width, height=args.height, azimuth=azimuth,
                elevation=elevation)


def run_info(args: argparse.Namespace) -> int:
    """``arap info``: print the description of the mesh (text or JSON); the exit status."""
    from arap.io.volume import is_volume_file

    if is_volume_file(args.mesh):
        return _run_volume_info(args)
    if args.png is None and args.constraints is not None:
        raise ArapError("-c/--constraints marks the constraints in the picture: give --png OUT.png too")
    if args.png is not None:
        _check_destination(args.png)
    V, F, _, label = load_mesh_argument(args.mesh, repair=False)
    picture = None if args.png is None else _picture(args, V, F)  # before any output: bad constraints stop here
    info, report = info_report(V, F, label)
    if picture is not None:
        try:
            picture.save(args.png)
        except OSError as exc:
            raise ArapError(f"cannot write {args.png}: {exc.strerror or exc}") from None
        err(f"arap: wrote {args.png} ({picture.width}x{picture.height})")
    if args.json:
        out(json.dumps(report, indent=2))
        return 0
    out(label)
    for line in info.lines():
        out(f"  {line}")
    repair = report["repair"]
    if report["ready"]:
        n = report["n_components"]
        note = "" if n <= 1 else f" (each of the {n:,} components needs a constrained vertex of its own)"
        after = repair.get("n_components", n)
        if after < n:  # e.g. an STL, whose triangles share no vertex until welded
            each = "; each needs a constrained vertex of its own" if after > 1 else ""
            note = (f" ({n:,} components as stored; {after:,} after the repair below, which arap deform and the "
                    f"studio apply on loading{each})")
        out(f"  ready for ARAP: yes{note}")
    else:
        out(f"  ready for ARAP: no ({report['not_ready_reason']})")
    if not repair["possible"]:
        out(f"  repair: impossible ({repair['reason']})")
    elif not repair["changes"]:
        out("  repair: nothing to do")
    else:
        out(f"  repair would: {'; '.join(repair['changes'])}")
        indices = "change" if repair["renumbers_vertices"] else "stay"
        parts = repair["n_components"]
        out(f"  after repair: {repair['n_vertices']:,} vertices, {repair['n_faces']:,} faces, {parts:,} "
            f"component{'s' if parts != 1 else ''} (vertex indices {indices})")
    return 0
