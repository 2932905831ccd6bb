"""SR-ARAP (smooth rotations): α = 0 is the spokes energy, the energy matches its formula, never rises across local
and global steps, and makes neighbouring rotations agree."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from benchmarks.scenarios import pull, rigid

import arap
from arap.constraints.scenarios import bend
from arap.errors import OptionError
from arap.meshes._geometry import barycentric_areas as vertex_areas
from arap.meshes.shapes import obtuse_cylinder
from arap.method import smooth
from arap.method.colouring import colour_vertices
from arap.method.local_step import covariances as covariances_of
from arap.method.weights import edge_weight_matrix


def _reference_energy(V: np.ndarray, F: np.ndarray, U: np.ndarray, R: np.ndarray, alpha: float) -> float:
    """The formula, term by term: Σ_i Σ_j w_ij ‖e'_ij − R_i e_ij‖² + αA Σ_i Σ_j max(w_ij, 0) ‖R_i − R_j‖²."""
    W = edge_weight_matrix(V, F, "cotangent").tocoo()
    area = float(vertex_areas(V, F).sum())
    total = 0.0
    for i, j, w in zip(W.row, W.col, W.data, strict=True):
        r = (U[i] - U[j]) - R[i] @ (V[i] - V[j])
        total += w * float(r @ r)
        total += alpha * area * max(w, 0.0) * float(np.sum((R[i] - R[j]) ** 2))
    return total


def test_energy_matches_the_formula(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    s = bend(V)
    solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations", alpha=0.05)
    U = solver.solve(s.targets, max_iterations=5).vertices
    rng = np.random.default_rng(1)
    R = np.linalg.qr(rng.normal(size=(len(V), 3, 3)))[0]
    R *= np.sign(np.linalg.det(R))[:, None, None]
    assert solver.energy(U, R) == pytest.approx(_reference_energy(V, F, U, R, 0.05), rel=1e-10)
    R_opt = solver.fit_rotations(U)
    assert solver.energy(U) == pytest.approx(_reference_energy(V, F, U, R_opt, 0.05), rel=1e-10)


@pytest.mark.parametrize("mesh", ["knight", "cactus"])
def test_alpha_zero_is_the_spokes_energy(mesh: str, knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight if mesh == "knight" else arap.builtin_mesh("cactus")
    s = bend(V)
    # the plain iteration: Anderson's extrapolation would amplify differences of summation order
    spokes = arap.ArapSolver(V, F, s.constrained, energy="spokes").solve(s.targets, max_iterations=40,
                                                                       acceleration="none")
    smooth = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations", alpha=0.0).solve(
        s.targets, max_iterations=40, acceleration="none")
    # two code paths: equal to round-off, which 40 iterations (and another CPU or Cholesky backend) may grow
    diagonal = float(np.linalg.norm(V.max(0) - V.min(0)))
    np.testing.assert_allclose(smooth.vertices, spokes.vertices, rtol=0, atol=1e-9 * diagonal)
    np.testing.assert_allclose(smooth.energies, spokes.energies, rtol=1e-9, atol=1e-15)
    U = spokes.vertices
    assert arap.arap_energy(V, F, U, energy="smooth_rotations", alpha=0.0) == pytest.approx(
        arap.arap_energy(V, F, U, energy="spokes"), rel=1e-9)


@pytest.mark.parametrize("mesh", ["knight", "camelhead", "obtuse_cylinder"])
def test_energy_never_rises_across_local_and_global_steps(mesh: str, request: pytest.FixtureRequest) -> None:
    V, F = obtuse_cylinder(spacing=0.1) if mesh == "obtuse_cylinder" else request.getfixturevalue(mesh)
    s = pull(V)
    solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations")
    U = solver.solve(s.targets, max_iterations=1, acceleration="none").vertices
    R = solver.fit_rotations(U)
    scale = abs(solver.energy(U, R))
    for _ in range(8):
        before = solver.energy(U, R)
        R = solver.fit_rotations(U, start=R)   # local step: one block-coordinate sweep
        after_local = solver.energy(U, R)
        U = solver.global_step(R, s.targets)   # global step
        after_global = solver.energy(U, R)
        assert after_local <= before + 1e-12 * scale
        assert after_global <= after_local + 1e-12 * scale
    result = solver.solve(s.targets, max_iterations=200)  # Anderson-accelerated, with its energy safeguard
    assert np.all(np.diff(result.energies) <= 1e-12 * abs(result.energies[0]))


def test_rotations_agree_more_than_with_spokes(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    s = pull(V, distance=0.2)
    W = edge_weight_matrix(V, F, "cotangent").tocoo()
    spread = {}
    for energy in ("spokes", "smooth_rotations"):
        solver = arap.ArapSolver(V, F, s.constrained, energy=energy)
        U = solver.solve(s.targets).vertices
        R = arap.ArapSolver(V, F, s.constrained, energy="spokes").fit_rotations(U)
        spread[energy] = float(np.sum(np.maximum(W.data, 0) * np.sum((R[W.row] - R[W.col]) ** 2, axis=(1, 2))))
    assert spread["smooth_rotations"] < 0.8 * spread["spokes"]


def test_colouring_separates_neighbours(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    W = edge_weight_matrix(V, F, "cotangent").tocsr()
    colour = colour_vertices(W.indptr, W.indices)
    rows = np.repeat(np.arange(len(V)), np.diff(W.indptr))
    assert np.all(colour[rows] != colour[W.indices]) and colour.max() < 16


def test_bad_alpha() -> None:
    V, F = arap.builtin_mesh("bar")
    for alpha in (-1.0, np.nan, np.inf, "big", 1e12):  # 1e12: round-off stopped the iteration early, at 0.734
        with pytest.raises(OptionError, match="alpha"):
            arap.ArapSolver(V, F, [0], energy="smooth_rotations", alpha=alpha)  # type: ignore[arg-type]


def test_energy_never_rises_with_painted_stiffness(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    """Stiffness scales the spokes term of each cell, not the (symmetric) rotation term: the local step stays exact.
    (All cotangent weights of the icosphere are positive: with negative ones, a per-cell stiffness can make the
    spokes system indefinite.)"""
    V, F = icosphere
    s = pull(V)
    stiffness = np.where(V[:, 1] > np.median(V[:, 1]), 2.0, 1.0)
    solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations", stiffness=stiffness)
    U = solver.solve(s.targets, max_iterations=1, acceleration="none").vertices
    R = solver.fit_rotations(U)
    scale = abs(solver.energy(U, R))
    for _ in range(6):
        before = solver.energy(U, R)
        R = solver.fit_rotations(U, start=R)
        after_local = solver.energy(U, R)
        U = solver.global_step(R, s.targets)
        assert after_local <= before + 1e-12 * scale
        assert solver.energy(U, R) <= after_local + 1e-12 * scale
    result = solver.solve(s.targets, max_iterations=100)
    assert np.all(np.diff(result.energies) <= 1e-12 * abs(result.energies[0]))


def test_sweep_does_not_depend_on_the_thread_count(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    """Windows that run at once share no edge, so threads change neither rotations, energies nor their sum."""
    V, F = camelhead
    s = pull(V, distance=0.2)
    solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations")
    U = solver.prepared.to_internal(solver.solve(s.targets, max_iterations=3, acceleration="none").vertices)
    sm, c = solver.prepared.rotation_fit.smooth, solver.prepared.cells
    assert sm is not None and len(sm._group_ptr) > 2  # several windows, in more than one group
    runs = []
    saved = numba.get_num_threads()
    try:
        for (covariances, sweep), threads in (((smooth._covariances_serial, smooth._sweep_serial), 1),
                                              ((smooth._covariances_parallel, smooth._sweep_parallel), 1),
                                              ((smooth._covariances_parallel, smooth._sweep_parallel),
                                               min(2, numba.config.NUMBA_NUM_THREADS))):
            numba.set_num_threads(threads)
            S, d = np.full((len(V), 9), np.nan), np.full(len(V), np.nan)
            covariances(sm._order, c.ptr, c.a, c.b, c.w, c.we, c.rest_sq, U, S, d)
            R, E, term = solver._state.local.R.copy(), np.zeros(len(V)), np.zeros(len(V))
            # a sweep without the rotation term, then one that evaluates it
            totals = [sweep(sm._group_ptr, sm._win_ptr, sm._run_ptr, sm._order, sm._nptr, sm._nmid, sm._nidx,
                            sm._nq, S, d, 2.0 * sm.coef, R, E, term, final) for final in (False, True)]
            runs.append((S, d, R, E, term, totals[1]))
    finally:
        numba.set_num_threads(saved)
    for run in runs[1:]:
        assert all(np.array_equal(x, y) for x, y in zip(run[:5], runs[0][:5], strict=True))
        assert run[5] == runs[0][5]
    S, _, R, E, term, total = runs[0]
    # the covariances are those of the cells at their sweep positions
    np.testing.assert_allclose(S.reshape(-1, 3, 3), covariances_of(c, U)[sm._order], rtol=1e-12, atol=1e-15)
    # the rotation term summed during the sweep is the one evaluated afterwards, and the total is data plus term
    assert term.sum() == pytest.approx(sm.rotation_term(R, np.empty(len(V))), rel=1e-10)
    assert total == pytest.approx(E.sum() + term.sum(), rel=1e-12)


def test_solve_converges_and_anderson_never_raises_the_energy(knight: tuple[np.ndarray, np.ndarray]) -> None:
    """The local step's rotation step lets the coupled rotations keep up with the positions, so a single-vertex pull
    converges at the default tolerance; a rejected Anderson step restarts from the rotations it had."""
    V, F = knight
    s = pull(V)
    for acceleration in ("anderson", "none"):
        solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations")
        result = solver.solve(s.targets, max_iterations=2000, acceleration=acceleration)
        assert result.converged, (acceleration, result.iterations, result.residual)
        assert np.all(np.diff(result.energies) <= 1e-12 * abs(result.energies[0]))


def test_sweeps_reuse_the_covariances_exactly(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    """Several sweeps of one local step (covariances computed once, the rotation term summed in the last sweep only)
    give bitwise the rotations and energy of as many single sweeps, and each sweep lowers the energy."""
    V, F = camelhead
    s = pull(V, distance=0.2)
    solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations")
    U = solver.prepared.to_internal(solver.solve(s.targets, max_iterations=3, acceleration="none").vertices)
    sm = solver.prepared.rotation_fit.smooth
    assert sm is not None
    n = len(V)
    R_once, R_each = solver._state.local.R.copy(), solver._state.local.R.copy()
    E, term = np.empty(n), np.empty(n)
    energies = [sm.local_step(U, R_each, E, term) for _ in range(4)]
    E_each, term_each = E.copy(), term.copy()
    total = sm.relax(U, R_once, E, term, 4)
    assert np.array_equal(R_once, R_each) and np.array_equal(E, E_each) and np.array_equal(term, term_each)
    assert total == energies[-1]
    assert np.all(np.diff(energies) <= 1e-12 * abs(energies[0]))
    assert np.diff(energies).min() < 0


def test_cold_start_from_one_rotation_field(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    """A cold start sweeps from the best rotation of the whole shape: a rigid motion of all constraints is exact
    after one iteration, and a pulled vertex does not trap the rotations in a state of far higher energy (from each
    cell's own best rotation the camel head was at 16 after 10 iterations and 4.5 after 100)."""
    V, F = camelhead
    moved = rigid(V)
    solver = arap.ArapSolver(V, F, moved.constrained, energy="smooth_rotations")
    result = solver.solve(moved.targets, max_iterations=3)
    assert result.start == "rigid" and result.energies[0] < 1e-12
    s = pull(V, distance=0.2)
    solver = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations")
    result = solver.solve(s.targets, max_iterations=10)
    assert result.energies[-1] < 0.08


def test_the_energy_of_a_shape_on_a_scan_with_obtuse_triangles(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    """``arap_energy`` minimises over the coupled rotations from the per-cell fits and from the best single
    rotation: on the camel head the per-cell start alone settled at 20.8 for the rest shape (the identity gives 0)
    and at 10.5 for a solve the solver ended at 0.067."""
    V, F = camelhead
    assert arap.arap_energy(V, F, V, energy="smooth_rotations") <= 1e-12
    s = pull(V, distance=0.2)
    result = arap.ArapSolver(V, F, s.constrained, energy="smooth_rotations").solve(s.targets)
    assert arap.arap_energy(V, F, result.vertices, energy="smooth_rotations") <= result.energies[-1] * (1 + 1e-9)
