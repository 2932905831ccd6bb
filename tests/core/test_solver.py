"""The solver: rigid invariance, monotone energy, agreement with libigl, exact constraints, warm starts."""

from __future__ import annotations

import numpy as np
import pytest

from arap.method.energy import arap_energy
from arap.options import ENERGY_TYPES, WEIGHT_TYPES
from arap.solve.solver import ArapSolver

from .scenarios import bend_constraints, random_rigid


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(0) - V.min(0)))


@pytest.mark.parametrize("energy", ENERGY_TYPES)
@pytest.mark.parametrize("weights", WEIGHT_TYPES)
def test_rigid_motion_of_all_constraints_moves_the_mesh_rigidly(
    icosphere: tuple[np.ndarray, np.ndarray], energy: str, weights: str
) -> None:
    V, F = icosphere
    Q, t = random_rigid(1)
    _, _, constrained, _ = bend_constraints(V, axis=2, share=0.15)
    solver = ArapSolver(V, F, constrained, energy=energy, weights=weights)
    result = solver.solve(V[constrained] @ Q.T + t, max_iterations=200)
    expected = V @ Q.T + t
    assert np.abs(result.vertices - expected).max() < 1e-9 * _diag(V)
    # No obtuse triangle: the rest energy is zero, and so is the energy of a rigid motion.
    assert abs(result.energies[-1]) < 1e-12 * _diag(V) ** 2
    # The rigid motion of the rest pose is a fixed point of the iteration.
    again = solver.solve(V[constrained] @ Q.T + t, initial=expected, max_iterations=3)
    assert np.abs(again.vertices - expected).max() < 1e-12 * _diag(V)


def test_rigid_motion_on_a_scan_is_equivariant(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    # With negative cotangent weights the rest pose is not the minimiser, but the solver commutes with rigid motions:
    # moving the constraints (and the start) rigidly moves the result by the same motion.
    V, F = camelhead
    Q, t = random_rigid(2)
    _, _, constrained, targets = bend_constraints(V)
    solver = ArapSolver(V, F, constrained, energy="spokes")
    still = solver.solve(V[constrained], initial=V, max_iterations=5)
    moved = solver.solve(V[constrained] @ Q.T + t, initial=V @ Q.T + t, max_iterations=5)
    assert np.abs(moved.vertices - (still.vertices @ Q.T + t)).max() < 1e-9 * _diag(V)
    np.testing.assert_allclose(moved.energies, still.energies, rtol=1e-9)
    rest = arap_energy(V, F, V, energy="spokes")
    assert rest < 0  # negative cotangent weights: the paper's energy is below zero even at rest
    assert still.energies[-1] <= rest
    bent = solver.solve(targets, initial=V, max_iterations=5)
    bent_moved = solver.solve(targets @ Q.T + t, initial=V @ Q.T + t, max_iterations=5)
    assert np.abs(bent_moved.vertices - (bent.vertices @ Q.T + t)).max() < 1e-9 * _diag(V)


@pytest.mark.parametrize("mesh_name", ["knight", "camelhead", "armadillo"])
@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_energy_never_rises_across_local_or_global_step(
    request: pytest.FixtureRequest, mesh_name: str, energy: str
) -> None:
    V, F = request.getfixturevalue(mesh_name)
    _, _, constrained, targets = bend_constraints(V, angle=0.9)
    solver = ArapSolver(V, F, constrained, energy=energy)
    U = V.copy()
    U[constrained] = targets
    R = solver.fit_rotations(V)
    scale = _diag(V) ** 2 * 1e-12
    for _ in range(8):
        before_local = solver.energy(U, R)
        R = solver.fit_rotations(U)
        after_local = solver.energy(U, R)
        assert after_local <= before_local + scale
        U_next = solver.global_step(R, targets)
        after_global = solver.energy(U_next, R)
        assert after_global <= after_local + scale
        U = U_next
    result = solver.solve(targets, max_iterations=15)
    assert np.all(np.diff(result.energies) <= scale)


def test_reported_energy_is_arap_energy(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    for energy in ("spokes", "spokes_and_rims"):
        result = ArapSolver(V, F, constrained, energy=energy).solve(targets, max_iterations=6)
        assert result.energies[-1] == pytest.approx(arap_energy(V, F, result.vertices, energy), rel=1e-10)
    np.testing.assert_array_equal(result.vertices[constrained], targets)


def _igl_arap(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, iterations: int) -> np.ndarray:
    igl = pytest.importorskip("igl")
    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_SPOKES
    data.max_iter = iterations
    igl.arap_precomputation(V, F, 3, b.astype(np.int64), data)
    return np.asarray(igl.arap_solve(bc, data, V.copy()))


def test_agrees_with_libigl_without_obtuse_triangles(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    _, _, constrained, targets = bend_constraints(V, axis=2, share=0.15, angle=0.5, shift=0.1)
    ours = ArapSolver(V, F, constrained, energy="spokes").solve(targets, initial=V, max_iterations=300,
                                                                tolerance=0.0, acceleration="none").vertices
    theirs = _igl_arap(V, F, constrained, targets, 300)
    assert np.abs(ours - theirs).max() < 1e-5 * _diag(V)
    assert arap_energy(V, F, ours, "spokes") == pytest.approx(arap_energy(V, F, theirs, "spokes"), rel=1e-4)
    np.testing.assert_array_equal(ours[constrained], targets)


def test_energy_agrees_with_libigl_on_a_scan(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    solver = ArapSolver(V, F, constrained, energy="spokes")
    plain = solver.solve(targets, initial=V, max_iterations=300, tolerance=0.0, acceleration="none").vertices
    theirs = _igl_arap(V, F, constrained, targets, 300)
    e_plain, e_theirs = arap_energy(V, F, plain, "spokes"), arap_energy(V, F, theirs, "spokes")
    # Same iteration, same start: the same energy (libigl fits rotations in single precision).
    assert e_plain == pytest.approx(e_theirs, rel=1e-4)
    # The default (accelerated, until converged) ends at least as low.
    solver.reset()
    converged = solver.solve(targets)
    assert converged.converged
    assert arap_energy(V, F, converged.vertices, "spokes") <= e_theirs + 1e-12


def test_warm_start_and_tolerance(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    solver = ArapSolver(V, F, constrained)
    first = solver.solve(targets, max_iterations=1000, tolerance=1e-8)
    assert first.converged and first.iterations < 1000 and first.start in ("rest", "rigid")
    # The next call starts from the previous solution: it is converged at once.
    again = solver.solve(targets, max_iterations=50, tolerance=1e-8)
    assert again.converged and again.iterations <= 2 and again.start == "warm"
    assert again.energies[-1] == pytest.approx(first.energies[-1], rel=1e-8)
    # An explicit initial guess overrides the warm start.
    cold = solver.solve(targets, initial=V, max_iterations=1)
    assert cold.start == "given" and cold.energies[0] > first.energies[-1]
    assert solver.solve(targets, initial="rest", max_iterations=1).energies[0] == pytest.approx(
        cold.energies[0], rel=1e-12)
    # After reset the start is chosen again, as on the first call.
    solver.reset()
    assert solver.solve(targets, max_iterations=1).energies[0] == pytest.approx(first.energies[0], rel=1e-12)


def test_callback_can_stop_early(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    seen: list[tuple[int, float]] = []

    def callback(iteration: int, energy: float) -> bool:
        seen.append((iteration, energy))
        return iteration < 3

    result = ArapSolver(V, F, constrained).solve(targets, max_iterations=20, callback=callback)
    assert result.iterations == 3
    assert [k for k, _ in seen] == [1, 2, 3]
    assert [e for _, e in seen] == result.energies


def test_backends_agree(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    a = ArapSolver(V, F, constrained, backend="cholespy").solve(targets, max_iterations=5).vertices
    b = ArapSolver(V, F, constrained, backend="scipy").solve(targets, max_iterations=5).vertices
    assert np.abs(a - b).max() < 1e-9 * _diag(V)


@pytest.mark.parametrize("distance", [1e6, 1e9])
def test_targets_far_beyond_the_mesh_converge_at_the_rounding_of_their_coordinates(
        knight: tuple[np.ndarray, np.ndarray], distance: float) -> None:
    """Every constraint carried ``distance`` diagonals away by one translation: the rigid start is the answer, but
    the plain step's rounding at such coordinates (about 1e-9 of the diagonal at 1e6) is above the default
    tolerance, and the solve used to run its 10,000 iterations and report no convergence."""
    V, F = knight
    _, _, constrained, _ = bend_constraints(V)
    diagonal = _diag(V)
    shift = np.array([distance * diagonal, 0.0, 0.0])
    result = ArapSolver(V, F, constrained).solve(V[constrained] + shift)
    assert result.converged and result.iterations <= 3
    assert np.abs(result.vertices - (V + shift)).max() <= 1e-13 * distance * diagonal


@pytest.mark.parametrize("energy", ["spokes_and_rims", "smooth_rotations"])
def test_a_mesh_far_from_the_origin_solves_as_at_the_origin(knight: tuple[np.ndarray, np.ndarray],
                                                             energy: str) -> None:
    """Scans in map coordinates sit 1e6–1e8 units from the origin: the solver holds them relative to their centre,
    so the same shape converges as fast and to the same result (a sphere at 1e7 used to run into the iteration cap,
    its tolerance of 1e-9 of the size being below the rounding of its absolute coordinates)."""
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    near = ArapSolver(V, F, constrained, energy=energy).solve(targets)
    shift = np.array([5e6, -4e7, 1e8])
    solver = ArapSolver(V + shift, F, constrained, energy=energy)
    far = solver.solve(targets + shift)
    diagonal = np.linalg.norm(V.max(0) - V.min(0))
    assert near.converged and far.converged
    # The shifted targets keep only ~1e-8 of the knight's size exactly (1e8 + x), which moves the last iterations
    # (by 5 of 32 with the other Cholesky backend).
    assert abs(far.iterations - near.iterations) <= max(2, 0.25 * near.iterations)
    assert np.abs((far.vertices - shift) - near.vertices).max() <= 1e-7 * diagonal  # rounding of 1e8: 1.5e-8
    np.testing.assert_array_equal(far.vertices[constrained], targets + shift)  # constraints met exactly
    np.testing.assert_array_equal(solver.current_vertices(), far.vertices)
    R = solver.fit_rotations(far.vertices)
    np.testing.assert_allclose(solver.global_step(R, targets + shift) - shift, near.vertices, rtol=0,
                               atol=1e-6 * diagonal)
