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
