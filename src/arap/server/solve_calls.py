"""The solver calls of a studio session, with their refusals in the session's terms: a drag's solve of a fixed
number of iterations within a frame's time (:class:`DragBudget`), the solve to convergence that loaded targets and
settling need, and the check that targets stay within reach of the mesh.

The solver raises the library's errors (:class:`arap.errors.ArapError`) and may, on a degenerate set-up, return
non-finite positions; these functions turn both into :mod:`arap.server.session_errors` so that the session only
decides what to keep (:class:`arap.server.session.Session`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from arap.errors import ArapError
from arap.server.records import DragOutcome, Params
from arap.server.session_errors import BadValues, SolveFailed
from arap.server.settling import FrameCallback, settle_solve
from arap.server.solvers import StudioSolver
from arap.solve.result import ArapResult, IterationCallback

__all__ = ["DRAG_BUDGET", "DRAG_BUDGET_SECONDS", "DRAG_BUDGET_VERTICES", "LOAD_ITERATIONS", "TARGET_RANGE",
           "DragBudget", "check_target_range", "checked_settle", "solve_for_targets"]

TARGET_RANGE = 1e6
"""Handle targets farther from the origin than this times (1 + the mesh's largest coordinate) are rejected."""
LOAD_ITERATIONS = 200
"""Iteration cap of the solve that answers constraints loaded with explicit targets (settling then goes on)."""
DRAG_BUDGET_SECONDS = 0.040
"""Server time a drag update's solve may take before it stops iterating: 25 updates a second, and of the 50 ms that a
dragged pin of a 50,000-vertex picture may lag, 10 ms left for the message, the frame's encoding and its transfer.
The settle after the release iterates on to convergence."""
DRAG_BUDGET_VERTICES = 10_000
"""Solvers with fewer free vertices than this run every iteration a drag update asks for, whatever the time: at
5,000 vertices an iteration takes 3 to 4 ms, so the budget would only cut many iterations per update, which the user
asked for; and the shape a small mesh's drag reaches does not depend on the machine's load."""


@dataclass(frozen=True)
class DragBudget:
    """The frame-time budget of a drag update: it runs at least one iteration, and stops before the one that would
    end past ``seconds`` (by the mean time of the iterations so far, the solve's set-up included), on solvers of at
    least ``min_free`` free vertices.

    Parameters
    ----------
    seconds : float
        The budget (see :data:`DRAG_BUDGET_SECONDS`).
    min_free : int
        Smaller solvers are not limited (see :data:`DRAG_BUDGET_VERTICES`).
    clock : callable
        Seconds from an arbitrary origin (a test gives a clock of its own).

    Example
    -------
    Iterations of 30 ms against 40 ms: the second would end at 60 ms, so the solve stops after the first.

    >>> ticks = iter([0.0, 0.03, 0.06])
    >>> stop = DragBudget(0.04, 0, lambda: next(ticks)).callback(n_free=10, iterations=2)
    >>> stop(1, 0.0)
    False
    """

    seconds: float = DRAG_BUDGET_SECONDS
    min_free: int = DRAG_BUDGET_VERTICES
    clock: Callable[[], float] = time.perf_counter

    def callback(self, n_free: int, iterations: int) -> IterationCallback | None:
        """The solver's iteration callback for a drag update of ``iterations`` on ``n_free`` free vertices, its
        clock started now; None when the budget does not apply (a small solver, or a single iteration)."""
        if n_free < self.min_free or iterations <= 1:
            return None
        start = self.clock()

        def within(iteration: int, energy: float) -> bool:
            spent = self.clock() - start
            return spent + spent / iteration <= self.seconds  # False: the next iteration would pass the budget

        return within


DRAG_BUDGET = DragBudget()
"""The budget of the studio's drag updates."""


def check_target_range(points: np.ndarray, V: np.ndarray) -> None:
    """Reject target positions absurdly far from the mesh of rest positions ``V`` (:class:`BadValues`)."""
    limit = TARGET_RANGE * (1.0 + float(np.abs(V).max(initial=0.0)))
    if not np.all(np.abs(points) <= limit):
        raise BadValues(f"handle vertices would move absurdly far (beyond {limit:.3g} from the origin)")


def solve_for_targets(solver: StudioSolver, params: Params, targets: np.ndarray, initial: np.ndarray | None,
                      settle: bool = False, point_targets: np.ndarray | None = None,
                      budget: DragBudget | None = None) -> tuple[np.ndarray, DragOutcome]:
    """Solve for ``targets``; the positions and what the solve did.

    ``settle`` runs until converged, at most :data:`LOAD_ITERATIONS` iterations, instead of the per-update
    iteration count: a drag update runs that count, or fewer, at least one, on a large mesh whose iterations would
    pass the frame-time ``budget`` (None: :data:`DRAG_BUDGET`).

    Raises
    ------
    BadValues
        The solver refused the targets.
    SolveFailed
        The solve produced non-finite positions.
    """
    iterations = max(params.iterations, LOAD_ITERATIONS) if settle else params.iterations
    kwargs: dict[str, Any] = {}
    if not settle:
        kwargs["tolerance"] = 0.0
        kwargs["callback"] = (DRAG_BUDGET if budget is None else budget).callback(int(solver.n_free), iterations)
    try:
        result = solver.solve(targets, initial=initial, max_iterations=iterations, point_targets=point_targets,
                              **kwargs)
    except ArapError as exc:
        raise BadValues(str(exc)) from exc
    if not np.all(np.isfinite(result.vertices)):
        raise SolveFailed("the solve produced non-finite positions; the shape is unchanged")
    return result.vertices, DragOutcome(result.iterations, [float(e) for e in result.energies],
                                        1000.0 * float(result.timings.get("total", 0.0)))


def checked_settle(solver: StudioSolver, targets: np.ndarray, point_targets: np.ndarray | None,
                   initial: np.ndarray | None, shown: np.ndarray, diagonal: float, interrupted: Callable[[], bool],
                   on_frame: FrameCallback | None) -> tuple[ArapResult, bool]:
    """:func:`arap.server.settling.settle_solve`, its failures as :class:`BadValues` (the solver refused) and
    :class:`SolveFailed` (non-finite positions)."""
    try:
        result, stopped = settle_solve(solver, targets, point_targets, initial, shown, diagonal, interrupted,
                                       on_frame)
    except ArapError as exc:
        raise BadValues(str(exc)) from exc
    if not np.all(np.isfinite(result.vertices)):
        raise SolveFailed("settling produced non-finite positions; the shape is unchanged")
    return result, stopped
