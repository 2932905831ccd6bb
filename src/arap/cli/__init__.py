"""The ``arap`` command line: deform a mesh file, animate one, run batches, inspect a mesh, time the solver, start the
studio.

Every command takes a mesh file (the surface formats of :mod:`arap.io.formats`: OBJ, OFF, PLY, STL, GLB, glTF; and
volume meshes of tetrahedra: Medit, gmsh, VTK, TetGen) or a built-in name (``cactus``, ``bar``, ``cylinder``,
``sphere`` or ``sphere:N`` for a geodesic sphere of about N vertices). Bad input (unreadable, malformed or unusable
files and values) is reported as one line on stderr with exit status 1, bad usage by argparse with exit status 2;
never with a traceback.

Layout: this module builds the parser and runs a command (:func:`main`); each command lives in a module of its own
that adds its options (``add_parser``) and runs it (:mod:`~arap.cli.deform`, :mod:`~arap.cli.constraints`,
:mod:`~arap.cli.animate`, :mod:`~arap.cli.batch`, :mod:`~arap.cli.info`, :mod:`~arap.cli.bench`,
:mod:`~arap.cli.studio`, :mod:`~arap.cli.warmup`); :mod:`~arap.cli.common` holds what they share (output lines, exit
statuses, the mesh argument, the checks of option values). Command modules import only :mod:`~arap.cli.common`, never
this module nor one another.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

from arap import __version__
from arap.cli import animate, batch, bench, constraints, deform, info, studio, warmup, warp
from arap.cli.common import EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_USAGE, err, format_list, one_line
from arap.errors import ArapError

__all__ = ["build_parser", "main"]

logger = logging.getLogger("arap.cli")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``arap`` command."""
    parser = argparse.ArgumentParser(
        prog="arap",
        description="As-Rigid-As-Possible surface deformation (Sorkine & Alexa 2007).",
        epilog=f"MESH is a surface file ({format_list('surface')}), a volume file of tetrahedra or of planar "
               f"triangles ({format_list('volume')}), or a built-in name: cactus, bar, cylinder, sphere, sphere:N.",
    )
    parser.add_argument("--version", action="version", version=f"arap {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log what the library does")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in (deform, constraints, animate, batch, info, bench, studio, warmup, warp):  # ``arap --help``'s order
        command.add_parser(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``arap`` command; returns the exit status.

    0 on success, 1 for bad input (a file that cannot be read, parsed or used, bad values; one line on stderr),
    2 for bad usage (argparse's message), 130 when interrupted. No input makes it print a traceback (``-v`` adds
    one for unexpected internal errors).
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a usage error already printed by argparse
        return int(exc.code) if isinstance(exc.code, int) else EXIT_USAGE
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="arap: %(message)s", stream=sys.stderr)
    try:
        return int(args.func(args))
    except (ArapError, ValueError, OSError, RecursionError) as exc:
        err(f"arap: error: {one_line(exc)}")
        return EXIT_BAD_INPUT
    except MemoryError:
        err("arap: error: out of memory (the input is too large for this machine)")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        err("arap: interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:  # the command line's last resort: a bug must still not end in a bare traceback
        if args.verbose:
            logger.exception("internal error")
        err(f"arap: internal error: {type(exc).__name__}: {one_line(exc)} (run with -v for details)")
        return EXIT_BAD_INPUT
