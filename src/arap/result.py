"""What :meth:`arap.ArapSolver.solve` takes and returns: option names, defaults and the result record."""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError

__all__ = ["ACCELERATIONS", "DEFAULT_LBFGS_MEMORY", "DEFAULT_TOLERANCE", "DEFAULT_WINDOW", "MAX_ITERATIONS",
           "ROUNDING_FLOOR", "START_NAMES", "Acceleration", "ArapResult", "IterationCallback", "StartName",
           "check_solve_options", "rounding_floor"]

IterationCallback = Callable[[int, float], "bool | None"]
Acceleration = Literal["lbfgs", "anderson", "none"]
ACCELERATIONS: tuple[str, ...] = ("lbfgs", "anderson", "none")
StartName = Literal["auto", "rest", "rigid"]
START_NAMES: tuple[str, ...] = ("auto", "rest", "rigid")

#: Default convergence tolerance of :meth:`ArapSolver.solve`: root-mean-square step of the plain iteration relative
#: to the bounding-box diagonal. The step underestimates the distance to the minimum along the energy's soft modes
#: by a factor of about 1,000 at the worst vertex: on the armadillo, five drags settled as the studio settles them and
#: the same constraints solved from a cold start (as ``arap deform`` does) ended up to 3.7e-6 diagonals apart at
#: 1e-9, and at most 4.1e-7 at 1e-10 (13-27% more iterations), within the 1e-6 the two must agree to.
DEFAULT_TOLERANCE = 1e-10
#: The least tolerance of :meth:`ArapSolver.solve`, in units of the rounding of the largest coordinate the solve
#: handles (relative to the diagonal): targets placed ``k`` diagonals beyond the mesh leave the plain step a rounding
#: floor of about 6-11 ``ε k`` (measured at ``k`` = 1e6 and 1e9), which a tolerance of 1e-10 would never reach from
#: ``k`` ≈ 1e5 on. Within ordinary reach (``k`` below about 7,000) the floor is below the default tolerance.
ROUNDING_FLOOR = 64.0
#: Hard cap on iterations when ``max_iterations`` is None.
MAX_ITERATIONS = 10_000
#: Default Anderson window (iterates used).
DEFAULT_WINDOW = 5
#: Default L-BFGS memory (curvature pairs kept): with 8 pairs it needed as few iterations as Anderson on the meshes
#: where Anderson converges steadily (with 5, up to 1.8× more).
DEFAULT_LBFGS_MEMORY = 8


@dataclass
class ArapResult:
    """Outcome of :meth:`ArapSolver.solve`.

    Attributes
    ----------
    vertices : (n, 3) float64 array
        Deformed positions; constrained vertices are exactly at their targets.
    energies : list of float
        ARAP energy (with optimal rotations) after each iteration.
    iterations : int
        Iterations run.
    converged : bool
        True if the last iteration's plain step was within ``tolerance`` (see :meth:`ArapSolver.solve`); False when
        the iteration cap or the callback stopped it first.
    timings : dict of str to float
        Seconds spent, summed over iterations: ``local`` (covariances, rotations, energy), ``rhs``, ``solve``,
        ``acceleration``, and ``total`` for the whole call.
    residual : float
        Root-mean-square step of the plain iteration at the last iterate, relative to the bounding-box diagonal
        (NaN if no iteration ran).
    start : {"warm", "rest", "rigid", "given"}
        Where the iteration started (see ``initial``).
    rejected : int
        Accelerated steps rejected by the energy safeguard: Anderson extrapolations, or L-BFGS line searches that
        found no lower energy (the plain step was taken instead).
    """

    vertices: NDArray[np.float64]
    energies: list[float]
    iterations: int
    converged: bool
    timings: dict[str, float] = field(default_factory=dict)
    residual: float = float("nan")
    start: str = "rest"
    rejected: int = 0


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
    tol = _number(tolerance)
    if not (tol is not None and tol >= 0):
        raise OptionError(f"tolerance must be a number >= 0, got {tolerance!r}")
    if acceleration not in ACCELERATIONS:
        raise OptionError(f"unknown acceleration {acceleration!r}; expected one of {ACCELERATIONS}")
    size = _number(window)
    if not (window is None or (size is not None and size.is_integer() and size >= 1)):
        raise OptionError(f"window must be a positive integer or None, got {window!r}")
    return MAX_ITERATIONS if cap is None else int(cap)


def rounding_floor(diagonal: float, *targets: NDArray[np.float64] | None) -> float:
    """The least meaningful tolerance of a solve: :data:`ROUNDING_FLOOR` times the rounding of the largest
    coordinate, relative to the diagonal (the plain step cannot fall below it).

    Parameters
    ----------
    diagonal : float
        The mesh's bounding-box diagonal; the rest shape lies within it of the solver's origin.
    *targets : (k, 3) float arrays or None
        Target positions, relative to the solver's origin.

    Returns
    -------
    float

    Example
    -------
    >>> rounding_floor(1.0, np.zeros((2, 3))) < DEFAULT_TOLERANCE < rounding_floor(1.0, np.full((2, 3), 1e6))
    True
    """
    reach = diagonal
    for X in targets:
        if X is not None and X.size:
            reach = max(reach, -float(X.min()), float(X.max()))  # whole-array reductions: fast on (k, 3) arrays
    return ROUNDING_FLOOR * float(np.finfo(np.float64).eps) * reach / diagonal
