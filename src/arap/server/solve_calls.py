"""The solver calls of a studio session, with their refusals in the session's terms: a drag's solve of a fixed
number of iterations, the solve to convergence that loaded targets and settling need, and the check that targets
stay within reach of the mesh.

The solver raises the library's errors (:class:`arap.errors.ArapError`) and may, on a degenerate set-up, return
non-finite positions; these functions turn both into :mod:`arap.server.session_errors` so that the session only
decides what to keep (:class:`arap.server.session.Session`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from arap.errors import ArapError
from arap.server.records import DragOutcome, Params
from arap.server.session_errors import BadValues, SolveFailed
from arap.server.settling import FrameCallback, settle_solve
from arap.solve.result import ArapResult
from arap.solve.solver import ArapSolver

__all__ = ["LOAD_ITERATIONS", "TARGET_RANGE", "check_target_range", "checked_settle", "solve_for_targets"]

TARGET_RANGE = 1e6
"""Handle targets farther from the origin than this times (1 + the mesh's largest coordinate) are rejected."""
LOAD_ITERATIONS = 200
"""Iteration cap of the solve that answers constraints loaded with explicit targets (settling then goes on)."""


def check_target_range(points: np.ndarray, V: np.ndarray) -> None:
    """Reject target positions absurdly far from the mesh of rest positions ``V`` (:class:`BadValues`)."""
    limit = TARGET_RANGE * (1.0 + float(np.abs(V).max(initial=0.0)))
    if not np.all(np.abs(points) <= limit):
        raise BadValues(f"handle vertices would move absurdly far (beyond {limit:.3g} from the origin)")


def solve_for_targets(solver: Any, params: Params, targets: np.ndarray, initial: np.ndarray | None,
                      settle: bool = False,
                      point_targets: np.ndarray | None = None) -> tuple[np.ndarray, DragOutcome]:
    """Solve for ``targets``; the positions and what the solve did.

    ``settle`` runs until converged, at most :data:`LOAD_ITERATIONS` iterations, instead of the per-update
    iteration count (a drag update runs exactly that count).

    Raises
    ------
    BadValues
        The solver refused the targets.
    SolveFailed
        The solve produced non-finite positions.
    """
    iterations = max(params.iterations, LOAD_ITERATIONS) if settle else params.iterations
    kwargs: dict[str, Any] = {} if settle else {"tolerance": 0.0}
    try:
        result = solver.solve(targets, initial=initial, max_iterations=iterations, point_targets=point_targets,
                              **kwargs)
    except ArapError as exc:
        raise BadValues(str(exc)) from exc
    if not np.all(np.isfinite(result.vertices)):
        raise SolveFailed("the solve produced non-finite positions; the shape is unchanged")
    return result.vertices, DragOutcome(result.iterations, [float(e) for e in result.energies],
                                        1000.0 * float(result.timings.get("total", 0.0)))


def checked_settle(solver: ArapSolver, targets: np.ndarray, point_targets: np.ndarray | None,
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
