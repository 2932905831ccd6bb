"""The frame-time budget of drag updates: a large mesh stops iterating once the next iteration would pass it (at least
one iteration), a small one runs every iteration asked for, and settling is not limited. The time is a fake clock
that each reading moves on: no test depends on how fast the machine is."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from arap.server import solve_calls
from arap.server.constraints import matrices_from_json
from arap.server.meshdata import load_builtin
from arap.server.pictures import picture_mesh
from arap.server.records import Params
from arap.server.session import Session
from arap.server.solve_calls import DRAG_BUDGET_SECONDS, DRAG_BUDGET_VERTICES, DragBudget, solve_for_targets
from tests.server.helpers import translation

pytestmark = pytest.mark.timeout(180)


def _ticking(step: float) -> Callable[[], float]:
    """A clock that moves on by ``step`` seconds each time it is read (the solve reads it once at its start and once
    after each iteration: every iteration then takes ``step``)."""
    now = [0.0]

    def clock() -> float:
        now[0] += step
        return now[0]

    return clock


def _picture_session(warp: str = "rigid") -> tuple[Session, list[list[float]]]:
    """A pinned picture (a disc, two pins) and the drag that moves its right pin."""
    y, x = np.mgrid[:80, :80]
    img = np.zeros((80, 80, 4), dtype=np.uint8)
    img[(x - 40) ** 2 + (y - 40) ** 2 < 32**2] = [200, 60, 60, 255]
    mesh, look = picture_mesh(img, "disc", 100_000, 6.0)
    s = Session()
    s.load(mesh, look)
    s.set_params(warp=warp)
    centre = mesh.V[mesh.F].mean(axis=1)
    third = [1 / 3, 1 / 3, 1 / 3]
    left, right = int(np.argmin(centre[:, 0])), int(np.argmax(centre[:, 0]))
    s.set_constraints(None, [], [], points=[{"face": left, "barycentric": third},
                                             {"face": right, "barycentric": third}])
    return s, [translation(0.0), translation(8.0, 5.0)]


def _surface_session() -> tuple[Session, list[list[float]]]:
    """The cactus, its bottom fixed and its top a handle, and the drag that moves the top."""
    s = Session()
    s.load(load_builtin("cactus"))
    y = s.V[:, 1]
    fixed = np.flatnonzero(y <= np.quantile(y, 0.1)).tolist()
    top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
    s.set_constraints(None, fixed, [top])
    return s, [translation(0.3, 0.1)]


SESSIONS = {"picture": _picture_session, "surface": _surface_session}


@pytest.mark.parametrize("kind", SESSIONS)
@pytest.mark.parametrize(("step", "expected"), [(0.015, 2), (0.011, 3), (1.0, 1)])
def test_a_drag_update_stops_before_the_iteration_that_would_pass_the_budget(
        monkeypatch: pytest.MonkeyPatch, kind: str, step: float, expected: int) -> None:
    # 40 ms: iterations of 15 ms give 2 (a third would end at 45 ms), of 11 ms 3; one of a second still runs.
    monkeypatch.setattr(solve_calls, "DRAG_BUDGET", DragBudget(0.040, 0, _ticking(step)))
    s, drag = SESSIONS[kind]()
    s.set_params(iterations=6)
    out = s.drag(drag)
    assert out.iterations == expected and len(out.energies) == expected
    assert np.all(np.isfinite(s.U)) and s.energy == out.energies[-1]
    s.end_drag()
    settled = s.settle(lambda: False)  # the settle after the release is not limited: it converges
    assert settled is not None and settled.converged and settled.iterations > 1


@pytest.mark.parametrize("kind", SESSIONS)
def test_small_meshes_run_every_iteration_asked_for_however_slow(monkeypatch: pytest.MonkeyPatch,
                                                                 kind: str) -> None:
    monkeypatch.setattr(solve_calls, "DRAG_BUDGET", DragBudget(clock=_ticking(1.0)))  # a second per iteration
    s, drag = SESSIONS[kind]()
    assert s.solver is not None and s.solver.n_free < DRAG_BUDGET_VERTICES
    for iterations in (2, 5):
        s.set_params(iterations=iterations)
        assert s.drag(drag).iterations == iterations


@pytest.mark.parametrize("warp", ["normal", "distort"])
def test_every_warp_mode_keeps_to_the_budget(monkeypatch: pytest.MonkeyPatch, warp: str) -> None:
    monkeypatch.setattr(solve_calls, "DRAG_BUDGET", DragBudget(0.040, 0, _ticking(0.015)))
    s, drag = _picture_session(warp)
    s.set_params(iterations=6)
    out = s.drag(drag)
    assert out.iterations == (2 if warp == "normal" else 1)  # distort: one linear solve, converged
    assert np.all(np.isfinite(s.U))


def test_the_budget_counts_the_solve_from_its_start_and_applies_to_large_solvers_only() -> None:
    ticks = iter([10.0, 10.015, 10.036])
    within = DragBudget(0.040, 0, lambda: next(ticks)).callback(n_free=10, iterations=5)
    assert within is not None
    assert within(1, 0.0) is True  # 15 ms so far: the second iteration would end at 30 ms
    assert within(2, 0.0) is False  # 36 ms so far, 18 a piece: the third would end at 54 ms
    budget = DragBudget(0.040, 100, _ticking(1.0))
    assert budget.callback(n_free=99, iterations=5) is None and budget.callback(n_free=100, iterations=1) is None
    assert DragBudget().seconds == DRAG_BUDGET_SECONDS


def test_solve_for_targets_takes_a_budget_and_settling_ignores_it() -> None:
    s, drag = _surface_session()
    solver, cs = s.solver, s.constraints
    assert solver is not None
    targets = cs.targets(matrices_from_json(drag))
    slow = DragBudget(0.040, 0, _ticking(1.0))
    _, dragged = solve_for_targets(solver, Params(iterations=4), targets, s.U, point_targets=None, budget=slow)
    assert dragged.iterations == 1
    _, settled = solve_for_targets(solver, Params(iterations=4), targets, s.U, settle=True, budget=slow)
    assert settled.iterations > 4
