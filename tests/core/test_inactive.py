"""The energy of the cells no free vertex touches, kept up to date as targets change (arap.method.inactive)."""

from __future__ import annotations

import numpy as np
import pytest

from arap.method.cells import build_cells
from arap.method.inactive import InactiveCells
from arap.method.local_step import local_step
from arap.solve.solver import ArapSolver
from tests.core.scenarios import random_rigid


def direct(solver: ArapSolver, targets: np.ndarray) -> float:
    """Energy of the solver's inactive cells with the constrained vertices at ``targets``, computed from scratch."""
    n = solver.n_vertices
    U = solver.prepared.rest.copy()
    U[solver.prepared.nf:] = solver.prepared.fixed_positions(targets)
    inactive = np.setdiff1d(np.arange(n), solver.prepared.active)
    E = np.zeros(n)
    local_step(solver.prepared.cells, inactive, U, np.empty((n, 3, 3)), E)
    return float(E[inactive].sum())


def at_targets(solver: ArapSolver, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    U = solver.prepared.rest.copy()
    U[solver.prepared.nf:] = solver.prepared.fixed_positions(targets)
    return U, targets


@pytest.fixture
def sphere_solver(icosphere: tuple[np.ndarray, np.ndarray]) -> tuple[ArapSolver, np.ndarray, np.ndarray]:
    """Bottom cap fixed, top cap a handle: both caps hold inactive cells."""
    V, F = icosphere
    fixed = np.flatnonzero(V[:, 2] < -0.6)
    handle = np.flatnonzero(V[:, 2] > 0.6)
    solver = ArapSolver(V, F, np.concatenate([fixed, handle]), energy="spokes")
    return solver, fixed, handle


def test_energy_follows_any_change_of_targets(sphere_solver: tuple) -> None:
    solver, fixed, _ = sphere_solver
    cells: InactiveCells = solver.prepared.inactive
    rest = solver.V[solver.constrained].copy()
    rng = np.random.default_rng(3)
    T = rest.copy()
    assert cells.energy(*at_targets(solver, T)) == pytest.approx(direct(solver, T), abs=1e-14)
    for k in range(6):  # non-rigid moves of a few rows, then of all handle rows, then back to rest
        T = T.copy()
        rows = rng.choice(len(T), size=5, replace=False) if k < 3 else np.arange(len(fixed), len(T))
        T[rows] += 0.05 * rng.normal(size=(len(rows), 3))
        value = cells.energy(*at_targets(solver, T))
        assert value == pytest.approx(direct(solver, T), rel=1e-10, abs=1e-14)
        assert value > 0
    assert cells.energy(*at_targets(solver, rest)) == pytest.approx(direct(solver, rest), abs=1e-12)


def test_a_rigid_move_of_the_handle_recomputes_no_cell(sphere_solver: tuple) -> None:
    solver, fixed, _ = sphere_solver
    cells: InactiveCells = solver.prepared.inactive
    T = solver.V[solver.constrained].copy()
    h = np.arange(len(fixed), len(T))
    T[h] += 0.1 * np.random.default_rng(0).normal(size=(len(h), 3))  # deformed first: its energy is not the rest's
    start = cells.energy(*at_targets(solver, T))
    assert cells.recomputed > 0
    for seed in range(4):  # as a drag moves the handle group: one rigid motion per call
        R, t = random_rigid(seed)
        T2 = T.copy()
        T2[h] = T[h] @ R.T + t
        value = cells.energy(*at_targets(solver, T2))
        assert cells.recomputed == 0, "a rigid move of the whole group needs no cell"
        assert value == pytest.approx(direct(solver, T2), rel=1e-10)
        assert value == pytest.approx(start, rel=1e-10)
        T = T2
    # the same motion on all but one handle vertex is not rigid for the cells around that vertex
    R, t = random_rigid(9)
    T2 = T.copy()
    T2[h[1:]] = T[h[1:]] @ R.T + t
    value = cells.energy(*at_targets(solver, T2))
    assert cells.recomputed > 0
    assert value == pytest.approx(direct(solver, T2), rel=1e-10)


def test_a_cell_holding_moved_and_unmoved_vertices_is_recomputed(icosphere: tuple) -> None:
    # Everything constrained: every cell is inactive. Moving one half rigidly changes the cells across the cut.
    V, F = icosphere
    n = len(V)
    cells = build_cells(V, F, "spokes", "cotangent")
    inactive = InactiveCells(cells, np.zeros(0, dtype=np.int64), np.arange(n), V)
    top = V[:, 2] > 0
    R, t = random_rigid(1)
    T = V.copy()
    T[top] = V[top] @ R.T + t
    E = np.zeros(n)
    local_step(cells, np.arange(n), T, np.empty((n, 3, 3)), E)
    assert inactive.energy(T, T) == pytest.approx(float(E.sum()), rel=1e-10)
    assert 0 < inactive.recomputed < top.sum(), "only the cells across the cut change"
    assert float(E.sum()) > 1e-3
