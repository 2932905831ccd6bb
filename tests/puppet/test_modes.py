"""The warp's three modes: Normal lies between Rigid and Distort, its energy falls every iteration, and its scale
term reaches both ends (λ = 0 as similar as possible, large λ as rigid as possible)."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.puppet.blend import BlendSolver, cell_scales
from tests.puppet.blend_reference import StepwiseBlend
from tests.puppet.pictures import bar

PINS = np.array([[25.0, 100.0], [175.0, 100.0]])
STRETCHED = [None, [250.0, 100.0]]  # the bar pulled to 1.5 times its length


def _areas(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _mean_area_ratio(puppet: arap.PuppetWarp, U: np.ndarray) -> float:
    V, F = puppet.mesh.vertices, puppet.mesh.triangles
    return float(_areas(U, F).sum() / _areas(V, F).sum())


def test_normal_grows_the_picture_between_rigid_and_distort() -> None:
    growth = {}
    for mode in ("rigid", "normal", "distort"):
        puppet = arap.PuppetWarp(bar(), PINS, spacing=6, mode=mode)
        growth[mode] = _mean_area_ratio(puppet, puppet.deform(STRETCHED))
    # Distort scales the bar as a whole (about 1.5² in area), Rigid keeps its height (about 1.5), Normal between.
    assert growth["distort"] > 2.0
    assert growth["rigid"] < 1.6
    assert growth["rigid"] + 0.05 < growth["normal"] < growth["distort"] - 0.2


def test_normal_energy_falls_every_iteration_and_pins_are_met() -> None:
    puppet = arap.PuppetWarp(bar(), PINS, spacing=6, mode="normal")
    solver = puppet._solver
    assert isinstance(solver, BlendSolver)
    result = solver.solve(puppet.mesh.vertices[puppet.held], point_targets=np.array([[25.0, 100.0], [150, 160]]),
                          max_iterations=60, tolerance=0.0)
    E = np.array(result.energies)
    assert result.iterations == 60
    assert np.all(np.diff(E) <= 1e-9 * E[0])
    U = result.vertices
    corners = U[puppet.mesh.triangles[puppet.faces]]
    assert np.abs(np.einsum("pc,pcx->px", puppet.barycentric, corners) - [[25, 100], [150, 160]]).max() < 1e-6


@pytest.mark.parametrize(("lam", "mode"), [(0.0, "distort"), (1e6, "rigid")])
def test_the_scale_weight_reaches_both_ends(lam: float, mode: str) -> None:
    ends = arap.PuppetWarp(bar(), PINS, spacing=8, mode=mode)
    want = ends.deform(STRETCHED)
    puppet = arap.PuppetWarp(bar(), PINS, spacing=8, mode="rigid")
    blend = BlendSolver(puppet._solver, lam)
    got = blend.solve(puppet.mesh.vertices[puppet.held], point_targets=[[25.0, 100.0], [250.0, 100.0]],
                      max_iterations=3000, tolerance=1e-9).vertices
    assert np.abs(got - want).max() < 0.05 * 150


def test_cell_scales_solve_the_cubic() -> None:
    c = np.array([0.0, 0.3, 1.0, 2.5, 40.0])
    for lam in (0.0, 0.5, 1.0, 3.0, 100.0):
        r = cell_scales(c, lam)
        assert np.all(r >= 0)
        assert np.abs(lam * r**3 + (1 - lam) * r - c).max() < 1e-9 * max(1.0, lam)


def test_an_unknown_mode_is_refused() -> None:
    with pytest.raises(arap.ArapError, match="normal"):
        arap.PuppetWarp(bar(), PINS, spacing=8, mode="bendy")  # type: ignore[arg-type]


def _turn_of_part(puppet: arap.PuppetWarp, U: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """The mean turn (degrees, counter-clockwise as seen with y down) of the triangles within ``radius`` of
    ``centre`` at rest."""
    V, F = puppet.mesh.vertices, puppet.mesh.triangles
    near = np.hypot(*(V[F].mean(axis=1) - centre).T) < radius
    E = np.stack([V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]], axis=2)[near]
    D = np.stack([U[F[:, 1]] - U[F[:, 0]], U[F[:, 2]] - U[F[:, 0]]], axis=2)[near]
    G = D @ np.linalg.inv(E)
    return float(np.degrees(np.mean(np.arctan2(-(G[:, 1, 0] - G[:, 0, 1]), G[:, 0, 0] + G[:, 1, 1]))))


@pytest.mark.parametrize("mode", ["rigid", "normal", "distort"])
def test_a_pin_with_an_angle_turns_its_surroundings(mode: str) -> None:
    pins = np.array([[40.0, 100.0], [160.0, 100.0]])
    free = arap.PuppetWarp(bar(), pins, spacing=6, mode=mode)
    assert abs(_turn_of_part(free, free.deform(), pins[1], 12)) < 0.5  # nothing moved
    held = arap.PuppetWarp(bar(), pins, spacing=6, mode=mode, angles=[None, 30.0])
    U = held.deform()
    assert abs(_turn_of_part(held, U, pins[1], 12) - 30.0) < 3.0
    pin_at = np.einsum("pc,pcx->px", held.barycentric, U[held.mesh.triangles[held.faces]])
    assert np.abs(pin_at - pins).max() < 1e-6  # the pins stay where they are
    U = held.deform(angles=[None, -45.0])
    assert abs(_turn_of_part(held, U, pins[1], 12) + 45.0) < 4.0
    with pytest.raises(arap.ArapError, match="pin 0 was made without an angle"):
        held.deform(angles=[10.0, None])
    with pytest.raises(arap.ArapError, match="one angle"):
        arap.PuppetWarp(bar(), pins, spacing=6, angles=[1.0])


@pytest.mark.parametrize("lam", [0.0, 1.0])
def test_the_compiled_solve_reaches_the_stepwise_one(lam: float) -> None:
    # The blend runs in the ARAP solver's compiled loop; the reference iterates the formulas step by step.
    puppet = arap.PuppetWarp(bar(), PINS, spacing=10, mode="rigid")
    held = puppet.mesh.vertices[puppet.held]
    targets = [[25.0, 100.0], [150.0, 160.0]]
    fast = BlendSolver(puppet._solver, lam).solve(held, point_targets=targets, max_iterations=500, tolerance=1e-6)
    slow = StepwiseBlend(puppet._solver, lam).solve(held, point_targets=targets, max_iterations=500, tolerance=1e-6)
    assert fast.converged and slow.converged
    assert np.abs(fast.vertices - slow.vertices).max() < 0.05  # pixels, of a bar 150 long
    area = float(_areas(puppet.mesh.vertices, puppet.mesh.triangles).sum())
    assert abs(fast.energies[-1] - slow.energies[-1]) < 1e-6 * area
    E = np.array(fast.energies)
    assert np.all(np.diff(E) <= 1e-9 * E[0])


@pytest.mark.parametrize("lam", [0.0, 1.0, 2.5])
def test_the_compiled_energy_is_the_formula(lam: float) -> None:
    puppet = arap.PuppetWarp(bar(), PINS, spacing=10, mode="rigid")
    V = puppet.mesh.vertices
    rng = np.random.default_rng(3)
    U = V * [1.3, 0.8] + rng.normal(scale=2.0, size=V.shape)  # stretched, squashed and shaken
    want = StepwiseBlend(puppet._solver, lam).energy(U)
    assert BlendSolver(puppet._solver, lam).energy(U) == pytest.approx(want, rel=1e-9)


def test_painted_stiffness_weighs_the_whole_blend_energy() -> None:
    # The global step's matrix carries the stiffness; the scale term of a stiffer cell weighs as much more.
    puppet = arap.PuppetWarp(bar(), PINS, spacing=10, mode="rigid")
    V, F = puppet.mesh.vertices, puppet.mesh.triangles
    U = V * [1.3, 0.8]
    points = (puppet.faces, puppet.barycentric)
    plain = BlendSolver(arap.ArapSolver(V, F, puppet.held, points=points), 1.0).energy(U)
    stiff = BlendSolver(arap.ArapSolver(V, F, puppet.held, points=points, stiffness=np.full(len(V), 3.0)), 1.0)
    assert stiff.energy(U) == pytest.approx(3.0 * plain, rel=1e-9)


def test_a_blend_solve_reports_the_solver_loops_timings() -> None:
    puppet = arap.PuppetWarp(bar(), PINS, spacing=10, mode="normal")
    result = puppet._solver.solve(puppet.mesh.vertices[puppet.held], point_targets=[[25.0, 100.0], [160, 120]],
                                  max_iterations=2)
    assert result.iterations == 2
    assert {"local", "rhs", "solve", "total"} <= set(result.timings)
    with pytest.raises(arap.ArapError, match="acceleration"):
        puppet._solver.solve(puppet.mesh.vertices[puppet.held], acceleration="fast")  # type: ignore[arg-type]


def test_the_blend_needs_a_planar_element_solver() -> None:
    V, F = arap.builtin_mesh("sphere:200")
    with pytest.raises(arap.OptionError, match="planar"):
        BlendSolver(arap.ArapSolver(V, F, [0]), 1.0)


def test_distort_is_one_linear_solve_at_the_energys_minimum() -> None:
    puppet = arap.PuppetWarp(bar(), PINS, spacing=10, mode="rigid")
    held = puppet.mesh.vertices[puppet.held]
    targets = [[25.0, 100.0], [150.0, 160.0]]
    direct = BlendSolver(puppet._solver, 0.0)
    result = direct.solve(held, point_targets=targets)
    assert result.iterations == 1 and result.converged
    assert direct.energy(result.vertices) == pytest.approx(result.energies[0], rel=1e-9)
    iterated = BlendSolver(puppet._solver, 0.0, direct=False).solve(held, point_targets=targets,
                                                                    initial=result.vertices, max_iterations=50,
                                                                    tolerance=0.0)
    area = float(_areas(puppet.mesh.vertices, puppet.mesh.triangles).sum())
    assert iterated.energies[-1] >= result.energies[0] - 1e-9 * area  # the iteration finds nothing lower
    assert np.abs(iterated.vertices - result.vertices).max() < 0.01
    corners = result.vertices[puppet.mesh.triangles[puppet.faces]]
    assert np.abs(np.einsum("pc,pcx->px", puppet.barycentric, corners) - targets).max() < 1e-6


def test_distort_with_one_pin_moves_the_picture_with_it() -> None:
    # One pin leaves the shape free to turn and scale about it: the solve takes the shape nearest the rest pose.
    puppet = arap.PuppetWarp(bar(), PINS[:1], spacing=10, mode="rigid")
    result = BlendSolver(puppet._solver, 0.0).solve(puppet.mesh.vertices[puppet.held], point_targets=[[40.0, 90.0]])
    assert result.converged
    moved = result.vertices - puppet.mesh.vertices
    assert np.abs(moved - [15.0, -10.0]).max() < 1e-3


def test_the_studios_distort_is_converged_after_one_solve() -> None:
    from arap.server.solvers import plane_solver

    puppet = arap.PuppetWarp(bar(), PINS, spacing=10, mode="rigid")
    V = np.column_stack([puppet.mesh.vertices, np.zeros(len(puppet.mesh.vertices))])
    solver = plane_solver(arap.ArapSolver(V, puppet.mesh.triangles, [], energy="elements",
                                          points=(puppet.faces, puppet.barycentric)), "distort")
    result = solver.solve(np.zeros((0, 3)), point_targets=[[25.0, 100.0, 0.0], [150.0, 160.0, 7.0]],
                          max_iterations=2)
    assert result.converged and result.iterations == 1
    assert np.abs(result.vertices[:, 2]).max() == 0.0  # the targets are put back on the plane
    assert solver.factor_seconds >= solver.inner.factor_seconds
