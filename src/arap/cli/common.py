"""What the commands of ``arap`` share: output lines, exit statuses, the mesh argument, the kernel warm-up and the
checks of option values (each option is checked here, and only here), and a long solve's progress line and Ctrl-C.

This module imports no other module of :mod:`arap.cli`, and none of the server stack.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np

import arap.io.formats as formats
from arap.errors import ArapError, MeshFormatError, OptionError
from arap.meshes.repair import RepairResult
from arap.options import (
    DEFAULT_ALPHA,
    DEFAULT_ELEMENT_ENERGY,
    DEFAULT_ENERGY,
    DEFAULT_TOLERANCE,
    DEFAULT_WEIGHTS,
    ENERGY_TYPES,
    MAX_ITERATIONS,
    WEIGHT_TYPES,
    check_alpha,
)

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_USAGE",
    "FirstInterrupt",
    "Progress",
    "add_energy_options",
    "add_iteration_options",
    "add_selector_options",
    "alpha_value",
    "check_bench_runs",
    "check_iterations_and_tolerance",
    "energy_for",
    "err",
    "format_list",
    "load_mesh_argument",
    "one_line",
    "origin_value",
    "out",
    "positive_int",
    "selector_constraints",
    "token_value",
    "writable_destination",
]

#: Exit statuses: success, bad input (files or values), bad usage (reported by argparse), interrupted.
EXIT_OK, EXIT_BAD_INPUT, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


# ---------------------------------------------------------------------------------------------- shared options
def add_iteration_options(p: argparse.ArgumentParser) -> None:
    """``-n/--iterations`` and ``-t/--tolerance``, as :meth:`arap.ArapSolver.solve` takes them."""
    p.add_argument("-n", "--iterations", type=int, default=None,
                   help=f"maximum iterations (default: until converged, at most {MAX_ITERATIONS:,})")
    p.add_argument("-t", "--tolerance", type=float, default=DEFAULT_TOLERANCE,
                   help="converged when the plain iteration's step (RMS over the free vertices) is at most this "
                        f"many bounding-box diagonals (default: {DEFAULT_TOLERANCE:g}; 0 runs all iterations)")


class _HandleAction(argparse.Action):
    """``--handle SEL`` starts a handle group; ``--move`` and ``--rotate`` set the last one's motion."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        groups = list(getattr(namespace, "handle_specs", None) or [])
        if self.dest == "handle_specs":
            groups.append({"selector": str(values)})
        else:
            if not groups:
                parser.error(f"{option_string} moves the handle group before it: give --handle SELECTOR first")
            key = "move" if self.dest == "move" else "rotate"
            if key in groups[-1]:
                parser.error(f"{option_string} is given twice for the handle group {groups[-1]['selector']!r}")
            groups[-1] = {**groups[-1], key: str(values)}
        namespace.handle_specs = groups


def add_selector_options(p: argparse.ArgumentParser) -> None:
    """``--fix``, ``--handle`` (with ``--move`` and ``--rotate``) and ``--roi``: constraints picked by where the
    vertices lie (:mod:`arap.constraints.vertex_selectors`)."""
    g = p.add_argument_group("constraints by position (x, y, z from 0 to 1 across the mesh's bounding box; X, Y, Z in "
                             "mesh units)")
    g.add_argument("--fix", action="append", default=[], metavar="SEL",
                   help="hold the vertices SEL picks, e.g. 'y<0.1' (repeatable)")
    g.add_argument("--handle", dest="handle_specs", action=_HandleAction, metavar="SEL",
                   help="a handle group of the vertices SEL picks, e.g. 'y>0.9' (repeatable; each --move and "
                        "--rotate applies to the --handle before it)")
    g.add_argument("--move", action=_HandleAction, metavar="DX,DY,DZ",
                   help="move the handle group by this vector (mesh units)")
    g.add_argument("--rotate", action=_HandleAction, metavar="AXIS:DEG",
                   help="turn the handle group about its centroid, e.g. z:30 or 1,1,0:45 (before --move)")
    g.add_argument("--roi", default=None, metavar="SEL", help="only the vertices SEL picks move")


def selector_constraints(args: argparse.Namespace, V: np.ndarray) -> Any:
    """The :class:`arap.Constraints` the selector options give, or None when none was given."""
    from arap.constraints.vertex_selectors import HandleSpec, constraints_from_selectors, parse_rotation, parse_vector

    specs = getattr(args, "handle_specs", None) or []
    if not args.fix and not specs and args.roi is None:
        return None
    handles = [HandleSpec(s["selector"], move=parse_vector(s["move"]) if "move" in s else None,
                          rotation=parse_rotation(s["rotate"]) if "rotate" in s else None) for s in specs]
    return constraints_from_selectors(V, fixed=args.fix, handles=handles, roi=args.roi)


def add_energy_options(p: argparse.ArgumentParser, *, elements_default: bool = False) -> None:
    """``--energy``, ``--weights`` and ``--alpha``, as :class:`arap.ArapSolver` takes them.

    ``elements_default``: the command also takes solids and flat meshes, whose default is ``elements``; the
    energy is then None when not given (the command picks the default for its input with :func:`energy_for`).
    """
    if elements_default:
        p.add_argument("--energy", choices=ENERGY_TYPES, default=None,
                       help=f"cell definition (default: {DEFAULT_ELEMENT_ENERGY} for solids and for flat meshes in a "
                            "plane of constant coordinate, such as a picture's, deformed in their plane as the studio "
                            f"does, unless the constraints move them out of it; {DEFAULT_ENERGY} for other surfaces; "
                            "spokes is the 2007 paper's)")
    else:
        p.add_argument("--energy", choices=ENERGY_TYPES, default=DEFAULT_ENERGY,
                       help=f"cell definition (default: {DEFAULT_ENERGY}; spokes is the 2007 paper's)")
    p.add_argument("--weights", choices=WEIGHT_TYPES, default=DEFAULT_WEIGHTS,
                   help=f"edge weights (default: {DEFAULT_WEIGHTS})")
    p.add_argument("--alpha", type=alpha_value, default=DEFAULT_ALPHA,
                   help=f"weight of the rotation term of smooth_rotations (SR-ARAP), relative to the surface area "
                        f"(default: {DEFAULT_ALPHA})")


# ---------------------------------------------------------------------------------------------- output
def out(text: str) -> None:
    """A line of command output on stdout."""
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def err(text: str) -> None:
    """A line of progress or diagnostics on stderr."""
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


def one_line(exc: BaseException) -> str:
    """An exception's message on one line of at most 500 characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 500 else text[:497] + "..."


# ---------------------------------------------------------------------------------------------- meshes
def energy_for(given: str | None, V: np.ndarray, T: np.ndarray, *targets: np.ndarray | None) -> str:
    """The energy a command deforms the mesh ``(V, T)`` with: ``--energy`` when given, else the default for the mesh
    and every target position of its constraints (:func:`arap.meshes.domain.default_energy`: ``elements`` for
    tetrahedra and for a flat mesh that the targets keep in its plane, the surface energy otherwise)."""
    from arap.meshes.domain import default_energy

    if given is not None:
        return given
    given_targets = [np.asarray(t, dtype=np.float64).reshape(-1, 3) for t in targets if t is not None]
    return default_energy(V, T, np.concatenate(given_targets) if given_targets else None)


def format_list(kind: formats.Kind) -> str:
    """The extensions of the formats of ``kind`` for help texts (``.obj .off .ply ...``), from
    :mod:`arap.io.formats`."""
    return " ".join(formats.suffixes(kind))



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
    from arap.meshes.shapes import BUILTIN_MESHES, builtin_mesh

    path = Path(spec)
    if path.exists():
        V, F, report = load_mesh_with_report(path, repair=repair)
        return V, F, report, str(path)
    if spec in BUILTIN_MESHES:
        V, F = builtin_mesh(spec)
        return V, F, RepairResult.identity(V, F), f"built-in {spec}"
    if spec == "sphere" or spec.startswith("sphere:"):
        try:
            V, F = builtin_mesh(spec)
        except OptionError as exc:
            raise MeshFormatError(str(exc)) from None
        return V, F, RepairResult.identity(V, F), "geodesic sphere"
    problem = folder_problem(path.parent)  # a missing folder, or a file where the path needs a folder
    if problem is not None:
        raise MeshFormatError(f"{spec}: no such file ({problem})")
    raise MeshFormatError(f"{spec}: no such file (built-in meshes: {', '.join(BUILTIN_MESHES)}, sphere, sphere:N)")


# ---------------------------------------------------------------------------------------------- option values
# Argument types: argparse reports what they refuse as bad usage (exit status 2).
def alpha_value(text: str) -> float:
    """``--alpha``: a number that the library's own check accepts."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    try:
        return check_alpha(value)
    except OptionError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def positive_int(text: str) -> int:
    """An integer of at least 1 (``arap studio --max-sessions``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def token_value(text: str) -> str:
    """``arap studio --token``: non-empty, without spaces."""
    if not text or any(c.isspace() for c in text):
        raise argparse.ArgumentTypeError("a token must be non-empty, without spaces")
    return text


def origin_value(text: str) -> str:
    """``arap studio --allow-origin``: an origin the studio's guard accepts (``http(s)://host[:port]``)."""
    from arap.server.guard import normalize_origin

    try:
        normalize_origin(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


# Checks once the arguments are parsed: what they refuse is bad input (exit status 1).
def writable_destination(path: str | Path, error: type[ArapError] = MeshFormatError) -> Path:
    """Where an output will be written, refused before any work (``error`` naming ``path``) when it cannot be: a
    missing folder, a file where a folder should be, a folder, a FIFO or a device as the output, an unwritable
    folder."""
    import os

    from arap.io.paths import write_destination

    try:
        destination = write_destination(path)
    except OSError as exc:
        raise error(f"cannot write {path}: {exc.strerror or exc}") from None
    if not os.access(destination.parent, os.W_OK):
        raise error(f"cannot write {path}: the folder {destination.parent} is not writable")
    return destination


def check_iterations_and_tolerance(iterations: int | None, tolerance: float) -> None:
    """``arap deform -n/--iterations`` (None: until converged) and ``-t/--tolerance``."""
    if iterations is not None and iterations < 0:
        raise ArapError(f"--iterations must be >= 0, got {iterations}")
    if not tolerance >= 0:
        raise ArapError(f"--tolerance must be >= 0, got {tolerance}")


def check_bench_runs(iterations: int, repeats: int) -> None:
    """``arap bench -n/--iterations`` and ``-r/--repeats``."""
    if iterations < 1 or repeats < 1:
        raise ArapError("--iterations and --repeats must be >= 1")


# ---------------------------------------------------------------------------------------------- long commands
class Progress:
    """Per-iteration line on a stream: ``iteration k/N  energy E  change r``."""

    def __init__(self, total: int | None, stream: TextIO, enabled: bool) -> None:
        self.total = total
        self.stream = stream
        self.enabled = enabled
        self.tty = enabled and stream.isatty()
        self.previous: float | None = None
        self.start = time.perf_counter()
        self.last_line = 0.0

    def __call__(self, iteration: int, energy: float) -> None:
        if not self.enabled:
            return
        change = "" if self.previous is None else (
            f"  change {abs(self.previous - energy) / max(abs(self.previous), 1e-300):.2e}")
        self.previous = energy
        elapsed = time.perf_counter() - self.start
        # Without a terminal, a line per half second at most: a converging solve runs hundreds of iterations.
        if not self.tty and iteration > 1 and elapsed - self.last_line < 0.5:
            return
        self.last_line = elapsed
        of = "" if self.total is None else f"/{self.total}"
        line = f"iteration {iteration}{of}  energy {energy:.9g}{change}  ({elapsed:.2f} s)"
        if self.tty:
            self.stream.write("\r" + line.ljust(78))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty and self.previous is not None:
            self.stream.write("\n")
            self.stream.flush()


class FirstInterrupt:
    """While active (a ``with`` block in the main thread): the first Ctrl-C only sets :attr:`requested`, so that a
    solve can stop at the end of its iteration and its iterate be written; a second one interrupts at once."""

    def __init__(self) -> None:
        self.requested = False
        self._previous: Any = None

    def _handle(self, signum: int, frame: object) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, self._previous)

    def __enter__(self) -> FirstInterrupt:
        # Only Python's own handlers are replaced: an ignored SIGINT (a job started with it ignored) stays ignored,
        # and a handler installed outside Python could not be put back.
        if threading.current_thread() is threading.main_thread() and callable(signal.getsignal(signal.SIGINT)):
            self._previous = signal.signal(signal.SIGINT, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._previous is not None and not self.requested:
            signal.signal(signal.SIGINT, self._previous)
