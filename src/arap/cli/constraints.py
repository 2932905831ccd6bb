"""``arap constraints``: write a constraints file from vertices picked by position
(:mod:`arap.constraints.vertex_selectors`), for ``arap deform``, ``arap batch`` or the studio."""

from __future__ import annotations

import argparse

from arap.cli.common import add_selector_options, err, load_mesh_argument, out, selector_constraints
from arap.errors import ConstraintError

__all__ = ["add_parser", "run_constraints"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap constraints`` to the subcommands of ``arap``."""
    p = commands.add_parser(
        "constraints", help="write a constraints file from vertices picked by position",
        description="Write a constraints file (the format of arap deform and the studio) from selectors: "
                    "arap constraints armadillo.obj --fix 'y<0.1' --handle 'y>0.9' --move 0.2,0,0 -o c.json")
    p.add_argument("mesh", metavar="MESH", help="a surface, or a volume file (its vertices are picked, tetrahedra's "
                                               "interior ones too)")
    p.add_argument("-o", "--output", required=True, metavar="FILE.json", help="the constraints file to write")
    add_selector_options(p)
    p.set_defaults(func=run_constraints)


def run_constraints(args: argparse.Namespace) -> int:
    """``arap constraints``: 0 when written."""
    from arap.constraints import save_constraints
    from arap.io.volume import is_volume_file, volume_for_solving

    if is_volume_file(args.mesh):  # numbered as in the file: nothing is repaired
        V, label = volume_for_solving(args.mesh)[0], args.mesh
    else:
        V, _, repair, label = load_mesh_argument(args.mesh)
        if repair.renumbers:
            raise ConstraintError(f"mesh repair renumbers the vertices of {label}, and a constraints file names the "
                                  "file's: repair the mesh file first (arap info shows what repair changes)")
    constraints = selector_constraints(args, V)
    if constraints is None:
        raise ConstraintError("nothing to write: give --fix, --handle (with --move or --rotate) and/or --roi")
    save_constraints(args.output, constraints)
    groups = constraints.handle_groups or []
    roi = "" if constraints.roi is None else f", a region of {len(constraints.roi):,}"
    out(f"arap: wrote {args.output}: {len(constraints.fixed):,} fixed, {len(constraints.handles):,} handles in "
        f"{len(groups)} group{'s' if len(groups) != 1 else ''}{roi} ({label}, {len(V):,} vertices)")
    if not len(constraints.handles):
        err("arap: note: no handles: arap deform keeps the fixed vertices where they are and the rest follows them")
    return 0
