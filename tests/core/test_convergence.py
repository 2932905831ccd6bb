"""Converged results: L-BFGS and Anderson acceleration with their energy safeguards, the start for large motions,
stopping."""

from __future__ import annotations

import numpy as np
import pytest
from benchmarks.scenarios import pull, rotation

from arap import ArapSolver, arap_energy
from arap.constraints.scenarios import bend
from arap.errors import ArapError
from arap.meshes._geometry import best_rigid_transform

from .scenarios import bend_constraints, random_rigid, rises


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(0) - V.min(0)))


ACCELERATED = ["lbfgs", "anderson"]


@pytest.mark.parametrize("acceleration", ACCELERATED)
@pytest.mark.parametrize("mesh_name", ["knight", "camelhead"])
@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_accelerated_solves_never_report_a_rising_energy(request: pytest.FixtureRequest, mesh_name: str,
                                                         energy: str, acceleration: str) -> None:
    V, F = request.getfixturevalue(mesh_name)
    _, _, constrained, targets = bend_constraints(V, angle=1.2, shift=0.25)
    solver = ArapSolver(V, F, constrained, energy=energy)
    result = solver.solve(targets, max_iterations=400, tolerance=1e-9, acceleration=acceleration)
    assert result.iterations > 5
    assert not rises(result.energies).size
    assert result.energies[-1] == pytest.approx(arap_energy(V, F, result.vertices, energy), rel=1e-9, abs=1e-12)
    # Warm-started drags keep the guarantee from their second iteration on.
    moved = targets + 0.05 * _diag(V) * np.array([1.0, 0.0, 0.0])
    drag = solver.solve(moved, max_iterations=60, acceleration=acceleration)
    assert not rises(drag.energies).size  # converged: down to rounding


@pytest.mark.parametrize("acceleration", ACCELERATED)
def test_accelerated_solves_reach_the_plain_minimum_without_obtuse_triangles(
        icosphere: tuple[np.ndarray, np.ndarray], acceleration: str) -> None:
    V, F = icosphere
    _, _, constrained, targets = bend_constraints(V, axis=2, share=0.15, angle=0.8, shift=0.2)
    solver = ArapSolver(V, F, constrained)
    plain = solver.solve(targets, initial="rest", acceleration="none", tolerance=1e-11, max_iterations=20_000)
    fast = solver.solve(targets, initial="rest", tolerance=1e-11, acceleration=acceleration)
    assert plain.converged and fast.converged
    assert fast.iterations * 3 < plain.iterations
    assert np.abs(fast.vertices - plain.vertices).max() < 1e-7 * _diag(V)
    assert fast.energies[-1] == pytest.approx(plain.energies[-1], rel=1e-9)


def test_lbfgs_converges_where_anderson_stalls(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    """One vertex of the camel head pulled, paper's energy: a part drifts slowly and Anderson's extrapolations keep
    being rejected (not converged after 1,500 iterations); the default, L-BFGS, converges."""
    V, F = camelhead
    s = pull(V)
    stalled = ArapSolver(V, F, s.constrained, energy="spokes").solve(s.targets, max_iterations=1500,
                                                                     acceleration="anderson")
    result = ArapSolver(V, F, s.constrained, energy="spokes").solve(s.targets, max_iterations=1500)
    assert not stalled.converged
    assert result.converged
    assert result.energies[-1] <= stalled.energies[-1]
    assert not rises(result.energies).size  # down to rounding
    assert result.energies[-1] == pytest.approx(arap_energy(V, F, result.vertices, "spokes"), rel=1e-9)



def test_lbfgs_scales_its_initial_inverse_hessian_only_without_negative_terms(
        knight: tuple[np.ndarray, np.ndarray]) -> None:
    """Scaled steps are longer; the spokes energy with negative cotangent weights (the knight has obtuse triangles)
    has several minima, so it keeps the plain preconditioner, while spokes and rims and clamped weights
    scale it, and reach the same minimum as the plain iteration."""
    V, F = knight
    _, _, constrained, targets = bend_constraints(V, angle=0.8, shift=0.15)
    for options, scaled in (({}, True), ({"energy": "spokes", "weights": "clamped"}, True),
                            ({"energy": "spokes"}, False)):
        solver = ArapSolver(V, F, constrained, **options)
        result = solver.solve(targets, tolerance=1e-10)
        assert result.converged
        assert solver._state.history is not None
        assert (solver._state.history.scale > 1.0) is scaled, options
        if scaled:
            plain = solver.solve(targets, initial="rest", acceleration="none", tolerance=1e-10,
                                 max_iterations=20_000)
            assert np.abs(result.vertices - plain.vertices).max() < 1e-5 * _diag(V)

@pytest.mark.parametrize("cap", [1, 7, 10])
def test_lbfgs_residual_is_the_plain_step_at_the_returned_shape(knight: tuple[np.ndarray, np.ndarray],
                                                                cap: int) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V, angle=1.0, shift=0.2)
    solver = ArapSolver(V, F, constrained)
    solver.solve(targets, max_iterations=3)
    moved = targets + 0.02 * _diag(V)
    result = solver.solve(moved, max_iterations=cap, acceleration="lbfgs")  # warm, capped: as a drag
    plain = solver.global_step(solver.fit_rotations(result.vertices), moved)
    free = np.setdiff1d(np.arange(len(V)), constrained)
    expected = np.sqrt(((plain - result.vertices)[free] ** 2).sum()) / (_diag(V) * np.sqrt(len(free)))
    if cap == 1:  # a one-iteration drag reports the plain step it took, from the previous shape
        assert result.residual > 0
    else:
        assert result.residual == pytest.approx(expected, rel=1e-6)


def test_lbfgs_keeps_the_plain_minimum_with_soft_points_and_warm_drags(
        icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    """Soft point handles add their matrix and right-hand side to the gradient: L-BFGS must agree with the plain
    iteration there too, and warm 1-iteration drags (stale rotations) must not break it."""
    V, F = icosphere
    fixed, _, _, _ = bend_constraints(V, axis=2, share=0.15)
    faces = np.array([3, 40, 77])
    bary = np.array([[0.2, 0.3, 0.5], [1 / 3, 1 / 3, 1 / 3], [0.6, 0.2, 0.2]])
    points = (faces, bary, np.array([50.0, 50.0, 50.0]))
    rest = np.einsum("pk,pkj->pj", bary, V[F[faces]])
    P = rest + np.array([0.0, 0.0, 0.3]) * _diag(V)
    solver = ArapSolver(V, F, fixed, points=points)
    for k in range(1, 4):
        solver.solve(V[fixed], point_targets=rest + (P - rest) * k / 4, max_iterations=1, acceleration="lbfgs")
    fast = solver.solve(V[fixed], point_targets=P, tolerance=1e-11, acceleration="lbfgs")
    plain = ArapSolver(V, F, fixed, points=points).solve(V[fixed], point_targets=P, initial="rest",
                                                         acceleration="none", tolerance=1e-11, max_iterations=20_000)
    assert fast.converged and plain.converged
    assert np.all(np.diff(fast.energies) <= 1e-12 * abs(fast.energies[0]))
    assert np.abs(fast.vertices - plain.vertices).max() < 1e-7 * _diag(V)


@pytest.mark.parametrize("degrees", [90.0, 170.0, 180.0])
@pytest.mark.parametrize("case", ["icosphere-spokes", "camelhead-spokes_and_rims"])
def test_a_rigid_motion_of_the_constraints_is_reached_at_once(request: pytest.FixtureRequest, case: str,
                                                              degrees: float) -> None:
    mesh_name, energy = case.split("-")
    V, F = request.getfixturevalue(mesh_name)
    R = rotation([0.3, -1.0, 0.5], np.radians(degrees))
    t = np.array([0.5, -2.0, 1.0]) * _diag(V)
    moved = V @ R.T + t
    constrained = np.random.default_rng(0).choice(len(V), 40, replace=False)
    result = ArapSolver(V, F, constrained, energy=energy).solve(moved[constrained])
    assert result.start == "rigid"
    assert result.converged and result.iterations <= 10
    assert np.abs(result.vertices - moved).max() <= 1e-8 * _diag(V)
    # From the rest pose the plain iteration does not get there (this is what the start is for).
    if degrees >= 170.0:
        stuck = ArapSolver(V, F, constrained, energy=energy).solve(moved[constrained], initial="rest",
                                                                   max_iterations=10)
        assert np.abs(stuck.vertices - moved).max() > 1e-3 * _diag(V)


def test_the_start_is_chosen_by_energy(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    solver = ArapSolver(V, F, constrained)
    starts = {name: solver.solve(targets, initial=name, max_iterations=0) for name in ("rest", "rigid")}
    e0 = {name: solver.energy(r.vertices) for name, r in starts.items()}
    solver.reset()
    auto = solver.solve(targets, max_iterations=0)
    assert auto.start == min(e0, key=e0.__getitem__)
    np.testing.assert_array_equal(auto.vertices, starts[auto.start].vertices)


def test_stopping_is_honest(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V, angle=1.0)
    solver = ArapSolver(V, F, constrained)
    short = solver.solve(targets, initial="rest", max_iterations=3)
    assert not short.converged and short.iterations == 3 and short.residual > 1e-9
    full = solver.solve(targets, initial="rest")
    assert full.converged and full.residual <= 1e-9
    again = solver.solve(targets, initial=full.vertices, tolerance=1e-9)
    assert again.iterations <= 2
    fixed_count = solver.solve(targets, initial="rest", tolerance=0.0, max_iterations=25)
    assert fixed_count.iterations == 25 and not fixed_count.converged


def test_current_vertices_during_the_callback(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    solver = ArapSolver(V, F, constrained)
    seen: dict[int, np.ndarray] = {}

    def callback(iteration: int, energy: float) -> None:
        seen[iteration] = solver.current_vertices()
        assert solver.energy(seen[iteration]) == pytest.approx(energy, rel=1e-9, abs=1e-12)

    result = solver.solve(targets, initial="rest", max_iterations=12, callback=callback)
    np.testing.assert_array_equal(seen[12], result.vertices)
    partial = solver.solve(targets, initial="rest", max_iterations=5)
    # Equal up to rounding: the rotation fit starts its Newton iteration from the previous call's rotations.
    np.testing.assert_allclose(seen[5], partial.vertices, rtol=0, atol=1e-9 * _diag(V))
    np.testing.assert_array_equal(solver.current_vertices(), partial.vertices)


def test_bad_options_are_arap_errors(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    solver = ArapSolver(V, F, [0, 1, 2])
    T = V[[0, 1, 2]]
    for kwargs in ({"acceleration": "nesterov"}, {"window": 0}, {"initial": "middle"}, {"tolerance": -1.0},
                   {"max_iterations": 2.5}, {"tolerance": "1"}, {"tolerance": None}, {"tolerance": True},
                   {"max_iterations": "3"}, {"max_iterations": [1]}, {"window": "5"}, {"window": 2.5}):
        with pytest.raises(ArapError):
            solver.solve(T, **kwargs)
    solver.solve(T, max_iterations=np.int64(2), tolerance=np.float32(1e-6), window=np.int32(3))  # NumPy numbers


def test_a_cold_start_does_not_depend_on_earlier_solves(knight: tuple[np.ndarray, np.ndarray]) -> None:
    """The same cold solve gives the same result to the last bit, whatever the solver did before (the rotation
    fits start their search from identities, not from the rotations an earlier solve left)."""
    V, F = knight
    s = bend(V, angle=1.5, shift=0.3)
    other = bend(V, angle=-0.7, shift=0.1)
    solver = ArapSolver(V, F, s.constrained, energy="spokes")
    first = solver.solve(s.targets, initial="rigid", max_iterations=60)
    solver.solve(other.targets)
    solver.reset()
    again = solver.solve(s.targets, initial="rigid", max_iterations=60)
    assert first.energies == again.energies
    np.testing.assert_array_equal(first.vertices, again.vertices)


def test_best_rigid_transform_handles_degenerate_point_sets() -> None:
    rng = np.random.default_rng(3)
    R, t = random_rigid(4)
    P = rng.normal(size=(10, 3))
    R_fit, t_fit = best_rigid_transform(P, P @ R.T + t)
    np.testing.assert_allclose(R_fit, R, atol=1e-12)
    np.testing.assert_allclose(t_fit, t, atol=1e-12)
    # Collinear points: the smallest rotation that aligns the line, exact on the points.
    line = np.outer(np.linspace(-1, 1, 5), [1.0, 2.0, 0.5])
    R_fit, t_fit = best_rigid_transform(line, line @ R.T + t)
    np.testing.assert_allclose(line @ R_fit.T + t_fit, line @ R.T + t, atol=1e-12)
    assert np.linalg.det(R_fit) == pytest.approx(1.0)
    # Reversed line (half a turn) and a single point (translation only).
    R_fit, t_fit = best_rigid_transform(line, -line)
    np.testing.assert_allclose(line @ R_fit.T + t_fit, -line, atol=1e-12)
    R_fit, t_fit = best_rigid_transform(P[:1], P[:1] + 1.0)
    np.testing.assert_allclose(R_fit, np.eye(3))
    np.testing.assert_allclose(t_fit, 1.0)


def test_lbfgs_starts_with_plain_steps_and_keeps_the_lower_minimum(armadillo: tuple[np.ndarray, np.ndarray]) -> None:
    """From a cold start the first ``PLAIN_START`` iterations are those of the plain iteration (to rounding); on the
    armadillo bend (spokes, negative cotangent weights, several minima) L-BFGS then settles below the minimum the
    plain iteration reaches (−0.0228249 after 2,554 iterations), where L-BFGS from the first step settled at
    −0.0227986. A warm start keeps L-BFGS from its first step."""
    from benchmarks.scenarios import make_scenario

    from arap.solve.loops import PLAIN_START

    V, F = armadillo
    s = make_scenario("bend", V)
    plain = ArapSolver(V, F, s.constrained, energy="spokes").solve(s.targets, max_iterations=PLAIN_START,
                                                                   acceleration="none", initial="rigid")
    solver = ArapSolver(V, F, s.constrained, energy="spokes")
    result = solver.solve(s.targets, initial="rigid")
    np.testing.assert_allclose(result.energies[:PLAIN_START], plain.energies, rtol=1e-9)  # two code paths
    assert result.converged and result.energies[-1] < -0.02283
    # warm: the first two steps are plain (the first has stale rotations, so no curvature pair), the third L-BFGS
    moved = s.targets.copy()
    moved[len(s.fixed):] += 0.01 * _diag(V)
    warm = solver.solve(moved, max_iterations=3)
    reference = ArapSolver(V, F, s.constrained, energy="spokes")
    reference.solve(s.targets, initial="rigid")
    warm_plain = reference.solve(moved, max_iterations=3, acceleration="none")
    np.testing.assert_allclose(warm.energies[:2], warm_plain.energies[:2], rtol=1e-10)
    assert abs(warm.energies[2] - warm_plain.energies[2]) > 1e-9 * abs(warm_plain.energies[2])


def test_a_settled_drag_and_a_cold_solve_agree_on_the_armadillo(armadillo: tuple[np.ndarray, np.ndarray]) -> None:
    """The studio settles a drag from where the drag left the shape; ``arap deform`` solves the saved constraints
    from a cold start. With the default tolerance both must end within 1e-6 of the diagonal at every vertex (with the
    former 1e-9 the armadillo's first two drags ended 3.7e-6 and 3.1e-6 apart: the plain step understates the
    distance to the minimum along soft modes by about 1,000 at the worst vertex)."""
    V, F = armadillo
    y = V[:, 1]
    fixed, handle = np.flatnonzero(y <= np.quantile(y, 0.1)), np.flatnonzero(y >= np.quantile(y, 0.9))
    centre, height = V[handle].mean(axis=0), float(np.ptp(y))

    def targets(t: float) -> np.ndarray:
        a, angle = 0.25 * height, 0.35 * np.sin(2 * np.pi * t / 3.0)
        c, s = np.cos(angle), np.sin(angle)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        shift = np.array([a * np.sin(np.pi * t), 0.1 * a * np.sin(2 * np.pi * t / 1.5), 0.0])
        return np.concatenate([V[fixed], (V[handle] - centre) @ R.T + centre + shift])

    constrained = np.concatenate([fixed, handle])
    studio, cold = ArapSolver(V, F, constrained), ArapSolver(V, F, constrained)
    studio.solve(targets(0.0))
    for t in (0.3, 0.7):
        for k in range(1, 6):  # the drag: one iteration per mouse event
            studio.solve(targets(t * k / 5), max_iterations=1, tolerance=0)
        settled = studio.solve(targets(t))
        cold.reset()
        reference = cold.solve(targets(t))
        assert settled.converged and reference.converged
        assert np.abs(settled.vertices - reference.vertices).max() < 1e-6 * _diag(V)
