"""The cell energies against a direct, loop-by-loop evaluation of the papers' formulas."""

from __future__ import annotations

import numpy as np
import pytest
from benchmarks.reference_kernels import fit_rotations_svd

from arap.method.cells import build_cells
from arap.method.energy import arap_energy, cell_distortion, cell_energies, distortion_from_cells


def _cot(u: np.ndarray, v: np.ndarray) -> float:
    return float(np.dot(u, v) / np.linalg.norm(np.cross(u, v)))


def _reference_cells(V: np.ndarray, F: np.ndarray, energy: str) -> list[list[tuple[int, int, float]]]:
    """Cell terms built straight from the definitions, one triangle at a time."""
    cells: list[list[tuple[int, int, float]]] = [[] for _ in range(len(V))]
    for tri in F:
        for k in range(3):
            x, a, b = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            w = 0.5 * _cot(V[a] - V[x], V[b] - V[x])  # half the cotangent of the angle opposite edge (a, b)
            cells[a].append((a, b, w))
            cells[b].append((b, a, w))
            if energy == "spokes_and_rims":
                cells[x].append((a, b, w))
    return cells


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_cell_energies_match_the_definition(knight: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    V, F = knight
    U = V + 0.02 * np.random.default_rng(5).normal(size=V.shape)
    cells = _reference_cells(V, F, energy)
    S = np.zeros((len(V), 3, 3))
    for i, terms in enumerate(cells):
        for a, b, w in terms:
            S[i] += w * np.outer(V[a] - V[b], U[a] - U[b])
    R = fit_rotations_svd(S)
    expected = np.array([
        sum(w * np.sum(((U[a] - U[b]) - R[i] @ (V[a] - V[b])) ** 2) for a, b, w in terms)
        for i, terms in enumerate(cells)
    ])
    got = cell_energies(V, F, U, energy=energy)
    np.testing.assert_allclose(got, expected, rtol=1e-8, atol=1e-12)
    rest = np.array([sum(w * np.sum((V[a] - V[b]) ** 2) for a, b, w in terms) for terms in cells])
    ok = rest > 0
    distortion = cell_distortion(V, F, U, energy=energy)
    np.testing.assert_allclose(distortion[ok], expected[ok] / rest[ok], rtol=1e-8, atol=1e-12)
    assert (distortion[~ok] == 0).all()


def test_distortion_is_the_squared_stretch_and_does_not_depend_on_scale(
    icosphere: tuple[np.ndarray, np.ndarray],
) -> None:
    V, F = icosphere
    np.testing.assert_allclose(cell_distortion(V, F, 1.1 * V), 0.01, rtol=1e-9)
    U = V + 0.05 * np.random.default_rng(3).normal(size=V.shape)
    np.testing.assert_allclose(cell_distortion(7.0 * V, F, 7.0 * U), cell_distortion(V, F, U), rtol=1e-9)
    assert cell_distortion(V, F, U).max() > 0


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims", "smooth_rotations"])
def test_distortion_from_prebuilt_cells_is_cell_distortion(knight: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    V, F = knight
    U = V + 0.02 * np.random.default_rng(7).normal(size=V.shape)
    cells = build_cells(V, F, energy, "cotangent")
    np.testing.assert_allclose(distortion_from_cells(cells, V, F, U, energy, 0.05),
                               cell_distortion(V, F, U, energy=energy, alpha=0.05), rtol=1e-10, atol=1e-14)


def test_energy_is_translation_invariant_and_zero_at_rest_without_obtuse_angles(
    icosphere: tuple[np.ndarray, np.ndarray],
) -> None:
    V, F = icosphere
    assert abs(arap_energy(V, F, V)) < 1e-12
    U = V + 0.05 * np.random.default_rng(2).normal(size=V.shape)
    assert arap_energy(V, F, U + np.array([3.0, -1.0, 2.0])) == pytest.approx(arap_energy(V, F, U), rel=1e-9)
    assert arap_energy(V, F, U) > 0


def test_energy_rejects_mismatched_shapes(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(ValueError, match="shape"):
        arap_energy(V, F, V[:-1])
