"""The solver's options in one place: their names, defaults and checks.

:class:`arap.ArapSolver` takes ``energy``, ``weights`` and ``alpha``; :meth:`arap.ArapSolver.solve` takes
``max_iterations``, ``tolerance``, ``acceleration``, ``window`` and ``initial``. The library, the command line and the
studio's protocol all read the names and defaults from here, and refuse bad values with the checks here
(:class:`~arap.errors.OptionError`, naming the bad option). How the studio labels the choices is the studio's
(:mod:`arap.server.labels`).
"""

from __future__ import annotations

import math
import numbers
from typing import Literal, get_args

from arap.errors import OptionError

__all__ = [
    "ACCELERATIONS",
    "DEFAULT_ALPHA",
    "DEFAULT_ELEMENT_ENERGY",
    "DEFAULT_ENERGY",
    "DEFAULT_LBFGS_MEMORY",
    "DEFAULT_LOOSE_PARTS",
    "DEFAULT_TOLERANCE",
    "DEFAULT_WEIGHTS",
    "DEFAULT_WINDOW",
    "ENERGY_TYPES",
    "ITERATION_LIMIT",
    "LOOSE_PARTS",
    "MAX_ALPHA",
    "MAX_ITERATIONS",
    "START_NAMES",
    "SURFACE_ENERGY_TYPES",
    "WEIGHT_TYPES",
    "Acceleration",
    "EnergyType",
    "LoosePartsMode",
    "StartName",
    "WeightType",
    "check_alpha",
    "check_energy_and_weights",
    "check_loose_parts",
    "check_solve_options",
    "check_weights",
]

# ---------------------------------------------------------------------------------------------- energy and weights
EnergyType = Literal["spokes", "spokes_and_rims", "smooth_rotations", "elements"]
ENERGY_TYPES: tuple[str, ...] = get_args(EnergyType)
"""Energy names: the one list the library and the command line use."""
SURFACE_ENERGY_TYPES: tuple[str, ...] = ("spokes", "spokes_and_rims", "smooth_rotations")
"""The energies with one cell per vertex, which the studio offers for surfaces (its heat map and rigid parts read
per-vertex cells)."""
DEFAULT_ENERGY: EnergyType = "spokes_and_rims"
"""The default cells: unlike ``spokes`` with cotangent weights, they do not fold meshes with obtuse triangles, and
their energy is a sum of non-negative per-triangle terms (see ``benchmarks/bench_folds.py``)."""
DEFAULT_ELEMENT_ENERGY: EnergyType = "elements"
"""The default cells of planar meshes given with two coordinates and of tetrahedral solids: one rotation per element
(libigl's ``ARAP_ENERGY_TYPE_ELEMENTS``), the only cells a tetrahedron has."""

WeightType = Literal["cotangent", "clamped", "uniform"]
WEIGHT_TYPES: tuple[str, ...] = get_args(WeightType)
"""Weight names: the one list the library, the command line, the studio protocol and its client use."""
DEFAULT_WEIGHTS: WeightType = "cotangent"
"""The default edge weights."""


def check_weights(weights: object) -> None:
    """Refuse an unknown weights name (:class:`~arap.errors.OptionError`)."""
    if weights not in WEIGHT_TYPES:
        raise OptionError(f"unknown weights {weights!r}; expected one of {WEIGHT_TYPES}")


def check_energy_and_weights(energy: str, weights: str) -> None:
    """Refuse an unknown energy or weights name (:class:`~arap.errors.OptionError`): the one check of both names."""
    if energy not in ENERGY_TYPES:
        raise OptionError(f"unknown energy {energy!r}; expected one of {ENERGY_TYPES}")
    check_weights(weights)


# ---------------------------------------------------------------------------------------------- loose parts
LoosePartsMode = Literal["error", "hold", "follow"]
LOOSE_PARTS: tuple[str, ...] = get_args(LoosePartsMode)
"""What happens to a connected part of the mesh that no constraint reaches (a wheel beside a car body, a button on
a coat): ``error`` refuses the constraint set, naming the part; ``hold`` keeps it where it is; ``follow`` moves it
with the rigid motion of the nearest constrained part around it."""
DEFAULT_LOOSE_PARTS: LoosePartsMode = "error"
"""The library's default: a part left without constraints is most often a mistake worth naming."""


def check_loose_parts(loose: object) -> None:
    """Refuse an unknown loose-parts mode (:class:`~arap.errors.OptionError`)."""
    if loose not in LOOSE_PARTS:
        raise OptionError(f"unknown loose {loose!r}; expected one of {LOOSE_PARTS}")


# ---------------------------------------------------------------------------------------------- smooth rotations
DEFAULT_ALPHA = 0.02
"""Default weight of the rotation term (CGAL's ``SRE_ARAP`` default), relative to the surface area."""

MAX_ALPHA = 1e3
"""Largest ``alpha``. Already at 1 the rotation term holds neighbouring rotations together so strongly that larger
values hardly change the shape (the cactus bend: energy 0.69956 at 1e3, 0.69960 at 1e6), while far larger ones lose
the data term to round-off: at 1e12 the iteration stopped after 2 iterations at 0.734, and at 1e300 the rotation
step's matrix could not be factorised."""


def check_alpha(alpha: object) -> float:
    """Refuse an ``alpha`` that is not a number between 0 and :data:`MAX_ALPHA` (:class:`~arap.errors.OptionError`)."""
    if not (isinstance(alpha, int | float) and math.isfinite(alpha) and 0 <= alpha <= MAX_ALPHA):
        raise OptionError(f"alpha must be a number from 0 to {MAX_ALPHA:g}, got {alpha!r}")
    return float(alpha)


# ---------------------------------------------------------------------------------------------- solve
Acceleration = Literal["lbfgs", "anderson", "none"]
ACCELERATIONS: tuple[str, ...] = ("lbfgs", "anderson", "none")
StartName = Literal["auto", "rest", "rigid"]
START_NAMES: tuple[str, ...] = ("auto", "rest", "rigid")

#: Default convergence tolerance of :meth:`ArapSolver.solve`: root-mean-square step of the plain iteration relative
#: to the bounding-box diagonal. The step underestimates the distance to the minimum along the energy's soft modes
#: by a factor of about 1,000 at the worst vertex: on the armadillo, five drags settled as the studio settles them and
#: the same constraints solved from a cold start (as ``arap deform`` does) ended up to 3.7e-6 diagonals apart at
#: 1e-9, and at most 4.1e-7 at 1e-10 (for somewhat more iterations), within the 1e-6 the two must agree to.
DEFAULT_TOLERANCE = 1e-10
#: Hard cap on iterations when ``max_iterations`` is None.
MAX_ITERATIONS = 10_000
#: Largest ``max_iterations`` a solve takes: ten million iterations of a 40k-vertex scan take about a day, so a larger
#: cap (with ``tolerance=0``, which runs them all) is a mistake that would never return, not a request.
ITERATION_LIMIT = 10_000_000
#: Default Anderson window (iterates used).
DEFAULT_WINDOW = 5
#: Default L-BFGS memory (curvature pairs kept): with 8 pairs it needed as few iterations as Anderson on the meshes
#: where Anderson converges steadily (with 5, markedly more; ``benchmarks/bench_convergence.py`` compares the two).
DEFAULT_LBFGS_MEMORY = 8


def _number(value: object) -> float | None:
    """``value`` as a float if it is a real number (``3``, ``2.5``, ``np.int64(3)``; not ``True`` or ``"3"``), else
    None."""
    return float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else None


def check_solve_options(max_iterations: object, tolerance: object, acceleration: object, window: object) -> int:
    """Check the options of :meth:`arap.ArapSolver.solve` (:class:`~arap.errors.OptionError` naming the bad one) and
    return the iteration cap (``MAX_ITERATIONS`` for ``max_iterations=None``)."""
    cap = _number(max_iterations)
    if not (max_iterations is None or (cap is not None and cap.is_integer() and cap >= 0)):
        raise OptionError(f"max_iterations must be a non-negative integer or None, got {max_iterations!r}")
    if cap is not None and cap > ITERATION_LIMIT:
        raise OptionError(f"max_iterations must be at most {ITERATION_LIMIT:,} (a solve that long would not return), "
                          f"got {max_iterations!r}; None iterates until converged")
    tol = _number(tolerance)
    if not (tol is not None and tol >= 0):
        raise OptionError(f"tolerance must be a number >= 0, got {tolerance!r}")
    if acceleration not in ACCELERATIONS:
        raise OptionError(f"unknown acceleration {acceleration!r}; expected one of {ACCELERATIONS}")
    size = _number(window)
    if not (window is None or (size is not None and size.is_integer() and size >= 1)):
        raise OptionError(f"window must be a positive integer or None, got {window!r}")
    return MAX_ITERATIONS if cap is None else int(cap)
