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


def _turned_rectangle(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A rectangle, its left end held and its right end turned 90° about its centre."""
    V, F = arap.rectangle_triangles(nx, ny)
    x = V[:, 0]
    left, right = np.flatnonzero(x <= x.min() + 1e-9), np.flatnonzero(x >= x.max() - 1e-9)
    c = V[right].mean(axis=0)
    turn = np.array([[0.0, -1.0], [1.0, 0.0]])
    return V, F, np.concatenate([left, right]), np.concatenate([V[left], (V[right] - c) @ turn.T + c])


def _solve(V: np.ndarray, F: np.ndarray, b: np.ndarray, targets: np.ndarray, monkeypatch: pytest.MonkeyPatch,
           unfolding: bool) -> tuple[arap.ArapResult, np.ndarray]:
    """A solve from the rest pose, with or without unfolding; and the elements it turned over."""
    with monkeypatch.context() as patch:
        if not unfolding:
            patch.setattr(Unfolder, "__call__", lambda self, U: False)
        result = arap.ArapSolver(V, F, b).solve(targets, initial="rest")
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
    """The 60×30 rectangle turned 90°: L-BFGS turns three triangles over and stops at a folded minimum; opened, the
    solve goes on to a lower one with fewer folds."""
    V, F, b, targets = _turned_rectangle(60, 30)
    folded, turned_before = _solve(V, F, b, targets, monkeypatch, unfolding=False)
    result, turned = _solve(V, F, b, targets, monkeypatch, unfolding=True)
    assert len(turned_before) == 3
    assert result.converged and len(turned) < len(turned_before)
    e_folded, e = arap.arap_energy(V, F, folded.vertices), arap.arap_energy(V, F, result.vertices)
    assert e < e_folded - 1e-7 * e_folded
    # the energies rise once, where the folds were opened, and never again
    rises = np.flatnonzero(np.diff(result.energies) > 1e-12 * result.energies[0])
    assert len(rises) == 1 and rises[0] == folded.iterations - 1
    assert result.energies[-1] == pytest.approx(e, rel=1e-9)


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
