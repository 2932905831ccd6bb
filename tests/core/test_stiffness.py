"""Painted stiffness (the paper's cell weights w_i): weights scale the energy, stiff regions bend less, rigid regions
stay rigid, the energy never rises, and bad values are refused."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.constraints.scenarios import bend
from arap.errors import OptionError
from arap.meshes.shapes import obtuse_cylinder
from arap.method.rigid import rigid_regions
from arap.method.stiffness import RIGID_STIFFNESS, check_stiffness
from tests.core.scenarios import rigid_misfit


def _band(V: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Vertices between the quantiles ``lo`` and ``hi`` along the longest axis."""
    y = V[:, int(np.argmax(np.ptp(V, axis=0)))]
    a, b = np.quantile(y, [lo, hi])
    return np.flatnonzero((y > a) & (y < b))


@pytest.fixture(scope="module")
def cactus() -> tuple[np.ndarray, np.ndarray]:
    return arap.builtin_mesh("cactus")


def test_unit_stiffness_is_the_plain_energy(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    plain = arap.ArapSolver(V, F, s.constrained).solve(s.targets, max_iterations=30)
    ones = arap.ArapSolver(V, F, s.constrained, stiffness=np.ones(len(V))).solve(s.targets, max_iterations=30)
    np.testing.assert_allclose(ones.vertices, plain.vertices, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ones.energies, plain.energies, rtol=1e-9)


def test_uniform_stiffness_scales_the_energy_not_the_shape(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    plain = arap.ArapSolver(V, F, s.constrained).solve(s.targets, max_iterations=40)
    scaled = arap.ArapSolver(V, F, s.constrained, stiffness=np.full(len(V), 7.0)).solve(s.targets,
                                                                                       max_iterations=40)
    np.testing.assert_allclose(scaled.vertices, plain.vertices, rtol=0, atol=1e-9)
    np.testing.assert_allclose(scaled.energies, 7.0 * np.asarray(plain.energies), rtol=1e-9)
    U = scaled.vertices
    assert arap.arap_energy(V, F, U, stiffness=np.full(len(V), 7.0)) == pytest.approx(
        7.0 * arap.arap_energy(V, F, U), rel=1e-10)


def test_a_stiff_region_bends_less(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V, angle=1.0, shift=0.2)
    region = _band(V, 0.45, 0.65)
    labels = rigid_regions(F, np.isin(np.arange(len(V)), region))
    trunk = np.flatnonzero(labels == np.argmax(np.bincount(labels[labels >= 0])))
    misfit = {}
    for value in (1.0, 30.0):
        stiffness = np.ones(len(V))
        stiffness[region] = value
        result = arap.ArapSolver(V, F, s.constrained, stiffness=stiffness).solve(s.targets)
        assert np.all(np.diff(result.energies) <= 1e-12 * result.energies[0])
        misfit[value] = rigid_misfit(V, result.vertices, trunk)
    assert misfit[30.0] < 0.5 * misfit[1.0]


@pytest.mark.parametrize("mesh", ["cactus", "obtuse_cylinder"])
def test_rigid_regions_stay_rigid(mesh: str, cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus if mesh == "cactus" else obtuse_cylinder(spacing=0.1)
    s = bend(V, angle=1.0, shift=0.2)
    region = _band(V, 0.45, 0.65)
    stiffness = np.ones(len(V))
    stiffness[region] = np.inf
    solver = arap.ArapSolver(V, F, s.constrained, stiffness=stiffness)
    result = solver.solve(s.targets)
    assert result.converged
    assert np.all(np.diff(result.energies) <= 1e-12 * abs(result.energies[0]))
    labels = rigid_regions(F, np.isinf(stiffness))
    for k in range(labels.max() + 1):
        assert rigid_misfit(V, result.vertices, np.flatnonzero(labels == k)) < 1e-6
    free = np.setdiff1d(np.arange(len(V)), np.concatenate([region, s.constrained]))
    assert np.abs(result.vertices[free] - V[free]).max() > 0.05 * np.linalg.norm(np.ptp(V, axis=0))  # it did bend
    R = solver.fit_rotations(result.vertices)
    for k in range(labels.max() + 1):  # one rotation per rigid region
        members = np.flatnonzero(labels == k)
        np.testing.assert_allclose(R[members], np.broadcast_to(R[members[0]], R[members].shape), atol=1e-12)


def test_check_stiffness() -> None:
    weights, rigid = check_stiffness([1.0, 3.0, np.inf], 3)
    assert weights.tolist() == [1.0, 3.0, 3.0 * RIGID_STIFFNESS] and rigid.tolist() == [False, False, True]
    for bad, match in (([1.0, 2.0], "shape"), ([1.0, 0.0, 1.0], "positive"), ([1.0, -2.0, 1.0], "positive"),
                       ([1.0, np.nan, 1.0], "positive"), (["a", 1, 1], "numbers"),
                       ([1.0, 1e300, 1.0], "at most 1e\\+06 .*vertex 1.*rigid")):
        with pytest.raises(OptionError, match=match):
            check_stiffness(bad, 3)


@pytest.mark.parametrize("energy", ["spokes", "smooth_rotations"])
def test_stiffness_with_negative_weights_is_refused_with_the_way_out(
        energy: str, knight: tuple[np.ndarray, np.ndarray]) -> None:
    """With obtuse triangles, unequal cell weights on the spoke energies can leave them without a minimum (the
    system matrix is indefinite; on the knight from a stiffness of 10): the error says so and names what works,
    which then does."""
    V, F = knight
    s = bend(V, angle=1.0, shift=0.2)
    stiffness = np.ones(len(V))
    stiffness[_band(V, 0.0, 0.3)] = 10.0
    with pytest.raises(OptionError, match=r"spokes_and_rims.*clamped"):
        arap.ArapSolver(V, F, s.constrained, energy=energy, stiffness=stiffness)
    arap.ArapSolver(V, F, s.constrained, energy=energy, stiffness=np.full(len(V), 10.0))  # equal weights: fine
    for kw in ({"energy": "spokes_and_rims"}, {"energy": energy, "weights": "clamped"}):
        result = arap.ArapSolver(V, F, s.constrained, stiffness=stiffness, **kw).solve(s.targets)
        assert result.converged
