"""The warp's three modes: Normal lies between Rigid and Distort, its energy falls every iteration, and its scale
term reaches both ends (λ = 0 as similar as possible, large λ as rigid as possible)."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.puppet.blend import BlendSolver, cell_scales
from tests.puppet.pictures import bar

PINS = np.array([[25.0, 100.0], [175.0, 100.0]])
STRETCHED = [None, [250.0, 100.0]]  # the bar pulled to 1.5 times its length


def _mean_area_ratio(puppet: arap.PuppetWarp, U: np.ndarray) -> float:
    V, F = puppet.mesh.vertices, puppet.mesh.triangles

    def areas(P: np.ndarray) -> np.ndarray:
        e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
        return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])

    return float(areas(U).sum() / areas(V).sum())


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
