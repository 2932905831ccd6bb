"""Element solves open the elements they turned over and resume: lower minima, the same results where nothing
folds."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.meshes.domain import signed_measures
from arap.method.unfold import Unfolder
from arap.solve.iteration import make_iterate

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _turned_rectangle(nx: int, ny: int, hole: tuple[float, float, float] | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A rectangle (with a round hole), its left end held and its right end turned 90° about its centre."""
    V, F = arap.rectangle_triangles(nx, ny, hole=hole)
    x = V[:, 0]
    left, right = np.flatnonzero(x <= x.min() + 1e-9), np.flatnonzero(x >= x.max() - 1e-9)
    c = V[right].mean(axis=0)
    turn = np.array([[0.0, -1.0], [1.0, 0.0]])
    return V, F, np.concatenate([left, right]), np.concatenate([V[left], (V[right] - c) @ turn.T + c])


def _solve(V: np.ndarray, F: np.ndarray, b: np.ndarray, targets: np.ndarray, monkeypatch: pytest.MonkeyPatch,
           unfolding: bool, seen: list[float] | None = None) -> tuple[arap.ArapResult, np.ndarray]:
    """A solve from the rest pose, with or without unfolding (the energies passed to the callback into ``seen``);
    and the elements it turned over."""
    with monkeypatch.context() as patch:
        if not unfolding:
            patch.setattr(Unfolder, "__call__", lambda self, U: False)
            patch.setattr(Unfolder, "settled", lambda self, U, before, e, most: False, raising=False)
        callback = None if seen is None else (lambda k, e: seen.append(e) is None)
        result = arap.ArapSolver(V, F, b).solve(targets, initial="rest", callback=callback)
    lift = (lambda X: np.column_stack([X, np.zeros(len(X))])) if V.shape[1] == 2 else (lambda X: X)
    start = V.copy()
    start[b] = targets
    rest = signed_measures(lift(V), F)
    before = signed_measures(lift(start), F) / rest
    after = signed_measures(lift(result.vertices), F) / rest
    return result, np.flatnonzero((before > 0) & (after <= 0))


def test_the_unfolder_opens_only_what_the_solve_turned_over() -> None:
    # a square fan of four triangles about its free centre, pushed out across the bottom edge: that one opens
    rest = np.array([[0.5, 0.5, 0], [0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    T = np.array([[1, 2, 0], [2, 3, 0], [3, 4, 0], [4, 1, 0]])
    U = rest.copy()
    U[0, :2] = [0.5, -0.3]
    unfold = Unfolder(T, rest, rest, nf=1)
    assert unfold.turned_over(U).tolist() == [0]
    assert unfold(U) and unfold.turned_over(U).size == 0
    np.testing.assert_allclose(U[0], rest[0], atol=1e-12)
    # inverted at the start (by the targets): left to the energy
    start = U.copy()
    start[0, :2] = [0.5, -0.3]
    U = start.copy()
    assert not Unfolder(T, rest, start, nf=1)(U) and np.array_equal(U, start)


def test_a_solve_that_turned_elements_over_resumes_to_a_lower_minimum(monkeypatch: pytest.MonkeyPatch) -> None:
    """The 60×30 rectangle turned 90°: L-BFGS turns three triangles over and stops at a folded minimum; opened once
    the energy settles, the solve goes on to a lower one with fewer folds, in fewer iterations than the folded
    solve and a second solve from its result would take."""
    V, F, b, targets = _turned_rectangle(60, 30)
    folded, turned_before = _solve(V, F, b, targets, monkeypatch, unfolding=False)
    result, turned = _solve(V, F, b, targets, monkeypatch, unfolding=True)
    assert len(turned_before) == 3
    assert result.converged and len(turned) < len(turned_before)
    e_folded, e = arap.arap_energy(V, F, folded.vertices), arap.arap_energy(V, F, result.vertices)
    assert e < e_folded - 1e-7 * e_folded
    # the energies rise once, where the folds were opened, and never again
    rises = np.flatnonzero(np.diff(result.energies) > 1e-12 * result.energies[0])
    assert len(rises) == 1 and rises[0] < folded.iterations - 1  # opened before the folded solve converged
    assert result.energies[-1] == pytest.approx(e, rel=1e-9)
    assert result.iterations <= folded.iterations + 20  # opening after convergence took 32 more


# The rectangles (and the strip with a hole) turned 90°: the elements libigl's elements solver (1,000 iterations from
# the same start) ends with turned over, and the iterations the solve took when it opened folds only once converged.
LIBIGL_TURNED = {(60, 30): 1, (80, 40): 2, (100, 50): 2, (120, 60): 2}
ITERATIONS_BEFORE = {(60, 30): 89, (80, 40): 94, (100, 50): 109, (120, 60): 119}


@pytest.mark.parametrize("nx, ny", [(60, 30), (80, 40), (100, 50), (120, 60)])
def test_unfolding_ends_no_higher_and_no_more_folded_than_libigl(monkeypatch: pytest.MonkeyPatch, nx: int,
                                                                 ny: int) -> None:
    """Opened or not (the opened run is given up when it settles no lower, or with more folds: the strip with a hole
    would reach a lower minimum with three folds), the result is no higher than the solve that never opens folds,
    has no more elements turned over than that solve or libigl, and takes fewer iterations than opening after
    convergence did; every iteration is counted."""
    V, F, b, targets = _turned_rectangle(nx, ny, hole=(1.0, 0.5, 0.25) if nx == 120 else None)
    folded, turned_before = _solve(V, F, b, targets, monkeypatch, unfolding=False)
    seen: list[float] = []
    result, turned = _solve(V, F, b, targets, monkeypatch, unfolding=True, seen=seen)
    assert result.converged
    e_folded, e = arap.arap_energy(V, F, folded.vertices), arap.arap_energy(V, F, result.vertices)
    assert e <= e_folded + 1e-9 * e_folded
    assert len(turned) <= min(len(turned_before), LIBIGL_TURNED[nx, ny])
    assert result.iterations < ITERATIONS_BEFORE[nx, ny]
    assert seen == result.energies and result.iterations == len(seen)
    assert result.energies[-1] == pytest.approx(e, rel=1e-9)
    assert len(np.flatnonzero(np.diff(result.energies) > 1e-12 * result.energies[0])) <= 1


def test_a_given_up_opening_is_counted(monkeypatch: pytest.MonkeyPatch) -> None:
    """The 80×40 rectangle turned 90°: opened, the solve settles back at the folded minimum and goes back to where it
    opened; the iterations it spent are in the result (the callback saw them all), which ends at the folded
    minimum."""
    V, F, b, targets = _turned_rectangle(80, 40)
    folded, _ = _solve(V, F, b, targets, monkeypatch, unfolding=False)
    seen: list[float] = []
    result, _ = _solve(V, F, b, targets, monkeypatch, unfolding=True, seen=seen)
    assert result.iterations == len(result.energies) == len(seen) > folded.iterations
    assert seen == result.energies
    assert arap.arap_energy(V, F, result.vertices) == pytest.approx(arap.arap_energy(V, F, folded.vertices), rel=1e-9)
    assert result.energies[-1] == pytest.approx(arap.arap_energy(V, F, result.vertices), rel=1e-9)


def test_surface_element_solves_never_unfold(monkeypatch: pytest.MonkeyPatch) -> None:
    """A surface's element solve builds no unfolder: its result is bit-identical with the unfolding unreachable."""
    V, F = arap.sphere(2)
    b = np.array([0, int(np.argmin(V[:, 2]))])
    targets = V[b] + [[0.0, 0.0, 0.4], [0.0, 0.0, 0.0]]
    reference = arap.ArapSolver(V, F, b, energy="elements").solve(targets, initial="rest", max_iterations=300)

    def unreachable(*args: object) -> None:
        raise AssertionError("a surface solve built an unfolder")

    with monkeypatch.context() as patch:
        patch.setattr(Unfolder, "__init__", unreachable)
        result = arap.ArapSolver(V, F, b, energy="elements").solve(targets, initial="rest", max_iterations=300)
    assert result.iterations == reference.iterations and result.energies == reference.energies
    assert np.array_equal(result.vertices, reference.vertices)


def test_solves_without_folds_are_unchanged(monkeypatch: pytest.MonkeyPatch) -> None:
    """A twisted bar of tetrahedra turns nothing over: the same iterations and result with or without unfolding."""
    V, T = arap.box_tetrahedra(10, 2, 2)
    x = V[:, 0]
    left, right = np.flatnonzero(x <= x.min() + 1e-9), np.flatnonzero(x >= x.max() - 1e-9)
    c = V[right].mean(axis=0)
    a = 2 * np.pi / 3
    R = np.array([[1.0, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    b, targets = np.concatenate([left, right]), np.concatenate([V[left], (V[right] - c) @ R.T + c])
    plain, turned_plain = _solve(V, T, b, targets, monkeypatch, unfolding=False)
    result, turned = _solve(V, T, b, targets, monkeypatch, unfolding=True)
    assert len(turned_plain) == len(turned) == 0
    assert result.iterations == plain.iterations
    np.testing.assert_allclose(result.vertices, plain.vertices, rtol=0, atol=1e-12 * np.ptp(V))


def test_only_planar_and_solid_element_solves_unfold() -> None:
    V, F = arap.builtin_mesh("bar")
    y = V[:, 1]
    b = np.flatnonzero((y == y.min()) | (y == y.max()))
    V2, F2, b2, _ = _turned_rectangle(12, 6)
    V3 = arap.box_tetrahedra(4, 2, 2)
    for solver, unfolds in ((arap.ArapSolver(V, F, b), False), (arap.ArapSolver(V, F, b, energy="elements"), False),
                            (arap.ArapSolver(V2, F2, b2, energy="spokes_and_rims"), False),
                            (arap.ArapSolver(V2, F2, b2), True), (arap.ArapSolver(*V3, np.arange(8)), True)):
        p = solver.prepared
        U = p.rest.copy()
        it = make_iterate(p, solver._state.local, U, U[p.nf:].copy(), None, 0.0, 1, 1e-6, None,
                          {"local": 0.0, "rhs": 0.0, "solve": 0.0, "acceleration": 0.0})
        assert (it.unfold is not None) == unfolds


def test_a_solve_that_never_looks_for_folds_measures_no_orientation(monkeypatch: pytest.MonkeyPatch) -> None:
    # a drag's capped run (and any run with hard point handles) never opens folds: it pays for no orientation, which
    # on a 50k-vertex picture cost more than an iteration
    import arap.method.unfold as unfold_module

    calls = []
    measured = unfold_module.signed_measures
    monkeypatch.setattr(unfold_module, "signed_measures", lambda V, T: calls.append(1) or measured(V, T))
    V, F, b, targets = _turned_rectangle(12, 6)
    solver = arap.ArapSolver(V, F, b)
    solver.solve(targets, max_iterations=2, tolerance=0.0)
    assert calls == []


def test_the_start_is_the_shape_the_solve_began_from_even_when_moved_in_place() -> None:
    rest = np.array([[0.5, 0.5, 0], [0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    T = np.array([[1, 2, 0], [2, 3, 0], [3, 4, 0], [4, 1, 0]])
    U = rest.copy()
    unfold = Unfolder(T, rest, U, nf=1)
    U[0, :2] = [0.5, -0.3]  # the solve moves its iterate, which is the start it was given, in place
    assert unfold.turned_over(U).tolist() == [0]


def test_a_callback_that_stops_the_opened_run_leaves_the_solve_there(monkeypatch: pytest.MonkeyPatch) -> None:
    """Stopped two iterations into the opened run, the solve returns there: every iteration the callback saw, and
    the energy of the iterate returned last."""
    V, F, b, targets = _turned_rectangle(60, 30)
    full, _ = _solve(V, F, b, targets, monkeypatch, unfolding=True)
    opened_at = int(np.flatnonzero(np.diff(full.energies) > 1e-12 * full.energies[0])[0]) + 2  # the first opened
    stop_at = opened_at + 2
    seen: list[float] = []
    result = arap.ArapSolver(V, F, b).solve(targets, initial="rest",
                                            callback=lambda k, e: seen.append(e) is None and k < stop_at)
    assert not result.converged and result.iterations == len(seen) == stop_at
    assert result.energies == seen == full.energies[:stop_at]
    assert result.energies[-1] == pytest.approx(arap.arap_energy(V, F, result.vertices), rel=1e-9)
