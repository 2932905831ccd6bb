"""Region of interest: outside vertices never move and the linear system has the size of the free ROI."""

from __future__ import annotations

import numpy as np
import pytest

from arap.method.energy import arap_energy
from arap.solve.solver import ArapSolver

from .scenarios import bend_constraints


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_roi_solve_leaves_outside_untouched(camelhead: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    V, F = camelhead
    axis = int(np.argmax(V.max(0) - V.min(0)))
    x = V[:, axis]
    lo, hi = np.quantile(x, [0.4, 0.9])
    roi = np.flatnonzero(x >= lo)
    handle = np.flatnonzero(x >= hi)
    targets = V[handle] + np.array([0.0, 0.05, 0.02]) * np.ptp(x)
    solver = ArapSolver(V, F, handle, energy=energy, roi=roi)
    assert solver.system_size == len(roi) - len(handle)
    assert solver.reduced_matrix().shape == (len(roi) - len(handle),) * 2
    result = solver.solve(targets, max_iterations=20)
    outside = np.setdiff1d(np.arange(len(V)), roi)
    np.testing.assert_array_equal(result.vertices[outside], V[outside])
    np.testing.assert_array_equal(result.vertices[handle], targets)
    moved = np.linalg.norm(result.vertices - V, axis=1) > 1e-9
    assert moved[np.setdiff1d(roi, handle)].any()
    assert np.all(np.diff(result.energies) <= 1e-12)
    assert result.energies[-1] == pytest.approx(arap_energy(V, F, result.vertices, energy=energy), rel=1e-9)


def test_roi_equal_to_whole_mesh_matches_no_roi(knight: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = knight
    _, _, constrained, targets = bend_constraints(V)
    a = ArapSolver(V, F, constrained).solve(targets, max_iterations=8).vertices
    b = ArapSolver(V, F, constrained, roi=np.arange(len(V))).solve(targets, max_iterations=8).vertices
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.linalg.norm(np.ptp(V, axis=0)))  # to round-off


def test_roi_without_constraints_is_pinned_by_its_border(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    # Without obtuse triangles the rest pose is the energy minimum, so a ROI held only by its border stays put.
    V, F = icosphere
    roi = np.flatnonzero(V[:, 1] > np.median(V[:, 1]))
    result = ArapSolver(V, F, [], roi=roi).solve(np.zeros((0, 3)), max_iterations=3)
    np.testing.assert_allclose(result.vertices, V, atol=1e-9)
