"""One settling run of a studio session: the current constraints iterated until converged, with its progress
reported at a bounded rate (see :meth:`arap.server.session.Session.settle`)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from arap.server.solvers import StudioSolver
from arap.solve.result import ArapResult

__all__ = ["SETTLE_FRAME_MOTION", "SETTLE_FRAME_SECONDS", "SETTLE_ITERATIONS", "FrameCallback", "settle_solve"]

SETTLE_FRAME_SECONDS = 1.0 / 30.0
"""Least time between two intermediate frames streamed while settling (at most 30 per second)."""
SETTLE_FRAME_MOTION = 1e-4
"""An intermediate frame carries the shape only when some vertex moved farther than this times the rest pose's
bounding-box diagonal since the last shape sent: a tenth of a pixel with the whole model 1,000 pixels across.
Settling creeps for its last half: on a scan such as the armadillo the shape moves less than this per frame interval
in many of the frames (``benchmarks/bench_settle.py`` counts the frames of each settle), each a whole shape (0.5 MB for
the armadillo) to send and for the client to upload and draw, on the cores the solve uses."""
SETTLE_ITERATIONS = 3000
"""Most iterations of one settling run: past them the shape is left as reached (reported not converged)."""

FrameCallback = Callable[[np.ndarray | None, int, float], None]
"""``on_frame(vertices, iteration, energy)``: vertices None when only the progress is new."""


def settle_solve(solver: StudioSolver, targets: np.ndarray, point_targets: np.ndarray | None,
                 initial: np.ndarray | None, shown: np.ndarray, diagonal: float, interrupted: Callable[[], bool],
                 on_frame: FrameCallback | None) -> tuple[ArapResult, bool]:
    """Solve until converged (at most :data:`SETTLE_ITERATIONS`), reporting progress and stopping on request.

    Parameters
    ----------
    solver : StudioSolver
    targets, point_targets : arrays
        The constraints' targets (see :meth:`arap.ArapSolver.solve`).
    initial : (n, 3) float array or None
        Start (None: the solver's warm start).
    shown : (n, 3) float array
        The shape the client shows now.
    diagonal : float
        Bounding-box diagonal of the rest pose.
    interrupted : callable
        Polled after every iteration; True stops at once.
    on_frame : callable or None
        Called at most every :data:`SETTLE_FRAME_SECONDS` with the iterate, or with None for it when no vertex
        moved more than :data:`SETTLE_FRAME_MOTION` of ``diagonal`` since the last shape given (or ``shown``).

    Returns
    -------
    (ArapResult, bool)
        The solver's result, and whether ``interrupted`` stopped it.
    """
    last_frame = time.perf_counter()
    visible = SETTLE_FRAME_MOTION * diagonal
    stopped = False

    def callback(iteration: int, energy: float) -> bool:
        nonlocal last_frame, shown, stopped
        if interrupted():
            stopped = True
            return False
        now = time.perf_counter()
        if on_frame is not None and now - last_frame >= SETTLE_FRAME_SECONDS:
            last_frame = now
            U = solver.current_vertices()
            moved = float(np.abs(U - shown).max(initial=0.0)) > visible
            if moved:
                shown = U
            on_frame(U if moved else None, iteration, energy)  # None: progress only, no visible change
        return True

    result = solver.solve(targets, initial=initial, callback=callback, max_iterations=SETTLE_ITERATIONS,
                          point_targets=point_targets)
    return result, stopped
