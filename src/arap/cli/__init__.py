"""The ``arap`` command line: deform a mesh file, inspect one, time the solver, start the studio.

Every command takes a mesh file (OBJ, OFF, PLY, STL) or a built-in name (``cactus``, ``bar``, ``cylinder``,
``sphere`` or ``sphere:N`` for a geodesic sphere of about N vertices). Bad input (unreadable, malformed or unusable
files and values) is reported as one line on stderr with exit status 1, bad usage by argparse with exit status 2;
never with a traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from arap import __version__
from arap.cells import DEFAULT_ENERGY, ENERGY_TYPES
from arap.errors import ArapError, MeshError, MeshFormatError, OptionError
from arap.repair import RepairResult
from arap.result import ACCELERATIONS, DEFAULT_TOLERANCE, MAX_ITERATIONS, START_NAMES
from arap.smooth import DEFAULT_ALPHA, check_alpha
from arap.weights import DEFAULT_WEIGHTS, WEIGHT_TYPES

if TYPE_CHECKING:
    from arap.diagnose import MeshInfo

__all__ = ["main"]

logger = logging.getLogger("arap.cli")

DEFAULT_SPHERE = 6  # subdivisions of the built-in "sphere": 40,962 vertices



# ---------------------------------------------------------------------------------------------- output
def _out(text: str) -> None:
    """A line of command output on stdout."""
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _err(text: str) -> None:
    """A line of progress or diagnostics on stderr."""
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


def _warm_up_kernels(quiet: bool) -> dict[str, object]:
    """Compile (first run) or load the kernels before anything is timed; says so when it compiled."""
    from arap.jit import warm_up_kernels

    warm = warm_up_kernels()
    if warm.compiled and not quiet:
        _err(f"arap: compiling kernels (first run only)… {warm.seconds:.1f} s (cached in {warm.cache_dir})")
    return {"compiled": warm.compiled > 0, "seconds": warm.seconds, "cache_dir": warm.cache_dir}


# ---------------------------------------------------------------------------------------------- meshes
def _identity_report(n: int) -> RepairResult:
    return RepairResult(V=np.zeros((0, 3)), F=np.zeros((0, 3), dtype=np.int64),
                        vertex_map=np.arange(n, dtype=np.int64))


def load_mesh_argument(spec: str, *, repair: bool = True) -> tuple[np.ndarray, np.ndarray, RepairResult, str]:
    """A mesh named on the command line: a file, a built-in name, ``sphere`` or ``sphere:N``.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    repair : RepairResult
        What loading repaired (identity ``vertex_map`` for generated meshes).
    label : str
        Name for messages.
    """
    from arap.io import load_mesh_with_report
    from arap.io.paths import folder_problem
    from arap.shapes import BUILTIN_MESHES, builtin_mesh, sphere, sphere_frequency_for

    path = Path(spec)
    if path.exists():
        V, F, report = load_mesh_with_report(path, repair=repair)
        return V, F, report, str(path)
    if spec in BUILTIN_MESHES:
        V, F = builtin_mesh(spec)
        return V, F, _identity_report(len(V)), f"built-in {spec}"
    if spec == "sphere" or spec.startswith("sphere:"):
        if spec == "sphere":
            V, F = sphere(DEFAULT_SPHERE)
        else:
            try:
                wanted = int(spec.split(":", 1)[1].replace("_", "").replace(",", ""))
            except ValueError:
                raise MeshFormatError(f"bad sphere size in {spec!r}; use e.g. sphere:100000") from None
            if wanted < 12:
                raise MeshFormatError(f"sphere:{wanted} asks for fewer vertices than the smallest sphere (12); use "
                                      "e.g. sphere:100000")
            V, F = sphere(frequency=sphere_frequency_for(wanted))
        return V, F, _identity_report(len(V)), "geodesic sphere"
    problem = folder_problem(path.parent)  # a missing folder, or a file where the path needs a folder
    if problem is not None:
        raise MeshFormatError(f"{spec}: no such file ({problem})")
    raise MeshFormatError(f"{spec}: no such file (built-in meshes: {', '.join(BUILTIN_MESHES)}, sphere, sphere:N)")


# ---------------------------------------------------------------------------------------------- deform
def _cmd_deform(args: argparse.Namespace) -> int:
    from arap.cli_deform import run_deform

    return run_deform(args)


# ---------------------------------------------------------------------------------------------- info
def _info_report(V: np.ndarray, F: np.ndarray, label: str) -> tuple[MeshInfo, dict[str, Any]]:
    """What ``arap info`` reports: the mesh description and the JSON-ready report of ``arap info --json``."""
    from arap.diagnose import inspect_mesh
    from arap.mesh import check_mesh
    from arap.repair import repair_mesh

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


def _cmd_info(args: argparse.Namespace) -> int:
    V, F, _, label = load_mesh_argument(args.mesh, repair=False)
    info, report = _info_report(V, F, label)
    if args.json:
        _out(json.dumps(report, indent=2))
        return 0
    _out(label)
    for line in info.lines():
        _out(f"  {line}")
    repair = report["repair"]
    if report["ready"]:
        n = report["n_components"]
        note = "" if n <= 1 else f" (each of the {n:,} components needs a constrained vertex of its own)"
        after = repair.get("n_components", n)
        if after < n:  # e.g. an STL, whose triangles share no vertex until welded
            each = "; each needs a constrained vertex of its own" if after > 1 else ""
            note = (f" ({n:,} components as stored; {after:,} after the repair below, which arap deform and the "
                    f"studio apply on loading{each})")
        _out(f"  ready for ARAP: yes{note}")
    else:
        _out(f"  ready for ARAP: no ({report['not_ready_reason']})")
    if not repair["possible"]:
        _out(f"  repair: impossible ({repair['reason']})")
    elif not repair["changes"]:
        _out("  repair: nothing to do")
    else:
        _out(f"  repair would: {'; '.join(repair['changes'])}")
        indices = "change" if repair["renumbers_vertices"] else "stay"
        parts = repair["n_components"]
        _out(f"  after repair: {repair['n_vertices']:,} vertices, {repair['n_faces']:,} faces, {parts:,} "
             f"component{'s' if parts != 1 else ''} (vertex indices {indices})")
    return 0


# ---------------------------------------------------------------------------------------------- bench
def _cmd_bench(args: argparse.Namespace) -> int:
    from arap.cli_bench import run_bench

    return run_bench(args)


# ---------------------------------------------------------------------------------------------- studio
STUDIO_EXTRA_HINT = "pip install 'arap[studio]'"
"""How to install the studio's server stack (starlette, uvicorn, websockets)."""


def _cmd_studio(args: argparse.Namespace) -> int:
    try:
        import starlette  # noqa: F401
        import uvicorn  # noqa: F401
        import websockets  # noqa: F401

        from arap.server import serve
    except ImportError as exc:
        missing = exc.name or ""
        if missing.split(".")[0] in ("", "arap"):
            raise
        _err(f"arap: error: the studio needs its server packages, and {missing} is not installed: "
             f"{STUDIO_EXTRA_HINT}")
        return EXIT_USAGE
    from arap.server.guard import is_loopback_host

    _warm_up_kernels(quiet=False)  # compile before serving, not on the first drag

    def announce(url: str) -> None:
        if is_loopback_host(args.host):
            _out(f"ARAP Studio running at {url}  (Ctrl-C to stop)")
            return
        network = _network_url(url, args.host)
        _out(f"ARAP Studio serving the network at {network}  (Ctrl-C to stop)")
        if network != url:
            _out(f"  on this machine: {url}")
        _out("  The token in this URL is required: requests without it are refused. Anyone who has the URL can use "
             "the studio and read its meshes; share it only with them, and stop the studio when done "
             "(plain HTTP: the network can see it).")

    try:
        serve(args.mesh, host=args.host, port=args.port, open_browser=args.open, max_sessions=args.max_sessions,
              allow_origins=args.allow_origin, on_ready=announce, token=args.token)
    except KeyboardInterrupt:
        _err("stopped")
    return 0


def _network_url(url: str, host: str) -> str:
    """The studio's URL as other machines reach it: for a wildcard address (whose ``url`` names loopback), this
    machine's address on its default route, when one is found."""
    import socket
    from urllib.parse import urlsplit, urlunsplit

    bound = host.strip("[]")
    if bound not in ("", "0.0.0.0", "::"):
        return url
    family, probe = (socket.AF_INET6, "2001:db8::1") if bound == "::" else (socket.AF_INET, "192.0.2.1")
    try:
        with socket.socket(family, socket.SOCK_DGRAM) as s:
            s.connect((probe, 9))  # no packet is sent: this only picks the outgoing interface
            address = str(s.getsockname()[0])
    except OSError:
        return url
    if address.startswith(("127.", "::1")) or address in ("0.0.0.0", "::"):
        return url
    parts = urlsplit(url)
    netloc = f"[{address}]" if ":" in address else address
    return urlunsplit(parts._replace(netloc=f"{netloc}:{parts.port}"))


def _token(text: str) -> str:
    if not text or any(c.isspace() for c in text):
        raise argparse.ArgumentTypeError("a token must be non-empty, without spaces")
    return text


def _alpha(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    try:
        return check_alpha(value)
    except OptionError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _origin(text: str) -> str:
    from arap.server.guard import normalize_origin

    try:
        normalize_origin(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


# ---------------------------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``arap`` command."""
    parser = argparse.ArgumentParser(
        prog="arap",
        description="As-Rigid-As-Possible surface deformation (Sorkine & Alexa 2007).",
        epilog="MESH is a file (.obj .off .ply .stl) or a built-in name: cactus, bar, cylinder, sphere, sphere:N.",
    )
    parser.add_argument("--version", action="version", version=f"arap {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log what the library does")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("deform", help="deform a mesh with a constraints file",
                       description="Deform MESH so the handles reach their targets and the fixed vertices stay.")
    p.add_argument("mesh", metavar="MESH")
    p.add_argument("-c", "--constraints", required=True, metavar="FILE.json",
                   help='JSON with "fixed", "handles", "targets" and optionally "roi" (file vertex indices)')
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output mesh file (.obj .off .ply .stl)")
    p.add_argument("-n", "--iterations", type=int, default=None,
                   help=f"maximum iterations (default: until converged, at most {MAX_ITERATIONS:,})")
    p.add_argument("-t", "--tolerance", type=float, default=DEFAULT_TOLERANCE,
                   help="converged when the plain iteration's step (RMS over the free vertices) is at most this "
                        f"many bounding-box diagonals (default: {DEFAULT_TOLERANCE:g}; 0 runs all iterations)")
    p.add_argument("--start", default="auto", metavar="{" + ",".join(START_NAMES) + "} or SHAPE",
                   help="starting pose: the rest pose, its best-fit rigid motion onto the targets, whichever has the "
                        "lower energy (default: auto), or a mesh file with MESH's vertices and triangles (or an STL "
                        "of its triangles), e.g. a shape exported from the studio (where the energy has several "
                        "minima, the solve then ends in that shape's)")
    p.add_argument("--acceleration", choices=ACCELERATIONS, default="lbfgs",
                   help="L-BFGS preconditioned by the global step (Liu et al. 2017), Anderson acceleration (Peng et "
                        "al. 2018) or the plain iteration (default: lbfgs)")
    p.add_argument("--energy", choices=ENERGY_TYPES, default=DEFAULT_ENERGY,
                   help=f"cell definition (default: {DEFAULT_ENERGY}; spokes is the 2007 paper's)")
    p.add_argument("--weights", choices=WEIGHT_TYPES, default=DEFAULT_WEIGHTS,
                   help=f"edge weights (default: {DEFAULT_WEIGHTS})")
    p.add_argument("--alpha", type=_alpha, default=DEFAULT_ALPHA,
                   help=f"weight of the rotation term of smooth_rotations (SR-ARAP), relative to the surface area "
                        f"(default: {DEFAULT_ALPHA})")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=_cmd_deform)

    p = sub.add_parser("info", help="describe a mesh and its defects",
                       description="Counts, components, boundary, defects, negative cotangent weights, and what "
                                   "repair would change.")
    p.add_argument("mesh", metavar="MESH")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("bench", help="time the solver on a mesh",
                       description="Fix the lowest 10% along the longest axis, move the top 10% (connected parts with "
                                   "neither stay at rest), and time the precompute and the iterations.")
    p.add_argument("mesh", metavar="MESH", nargs="?", default="sphere",
                   help="default: a geodesic sphere of 40,962 vertices")
    p.add_argument("-n", "--iterations", type=int, default=10, help="iterations per run (default: 10)")
    p.add_argument("-r", "--repeats", type=int, default=3, help="runs; the median is reported (default: 3)")
    p.add_argument("--energy", choices=ENERGY_TYPES, default=DEFAULT_ENERGY)
    p.add_argument("--weights", choices=WEIGHT_TYPES, default=DEFAULT_WEIGHTS)
    p.add_argument("--alpha", type=_alpha, default=DEFAULT_ALPHA, help="rotation term weight of smooth_rotations")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("studio", help="start the browser modeler",
                       description="Serve ARAP Studio; open the printed URL in a browser.")
    p.add_argument("mesh", metavar="MESH", nargs="?", default=None,
                   help="mesh every session starts with: a file or a built-in name (default: the first built-in)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to bind (default: 127.0.0.1, this machine only); any other address serves the "
                        "network and requires a token")
    p.add_argument("--port", type=int, default=8000, help="TCP port (default: 8000; 0 picks a free one)")
    p.add_argument("--open", action="store_true", help="open the studio in the default browser")
    p.add_argument("--max-sessions", type=_positive_int, default=32, metavar="N",
                   help="most sessions (browser tabs) at once; more are refused (default: 32)")
    p.add_argument("--allow-origin", action="append", default=[], type=_origin, metavar="ORIGIN",
                   help="let pages from ORIGIN (http(s)://host[:port]) use the studio; repeatable (default: only "
                        "the studio's own pages)")
    p.add_argument("--token", type=_token, default=None, metavar="TOKEN",
                   help="secret every page and client must present (?token=TOKEN in the printed URL); default: a "
                        "random one when --host is not a loopback address, none on this machine only")
    p.set_defaults(func=_cmd_studio)
    return parser


#: Exit statuses: success, bad input (files or values), bad usage (reported by argparse), interrupted.
EXIT_OK, EXIT_BAD_INPUT, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 500 else text[:497] + "..."


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
        _err(f"arap: error: {_one_line(exc)}")
        return EXIT_BAD_INPUT
    except MemoryError:
        _err("arap: error: out of memory (the input is too large for this machine)")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        _err("arap: interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:  # the command line's last resort: a bug must still not end in a bare traceback
        if args.verbose:
            logger.exception("internal error")
        _err(f"arap: internal error: {type(exc).__name__}: {_one_line(exc)} (run with -v for details)")
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
