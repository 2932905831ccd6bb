"""Planar solves iterate on two columns: the same results as on three (``z`` carried as zeros), rigid motions
recovered, energies that never rise, point handles met, and ``z`` exactly 0 in the results of planar (n, 3) input.
Each test checks that the two-column path ran (not a silent fall-back to three columns)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

import arap
import arap.puppet.blend as blend
import arap.solve.iteration as iteration
from arap.meshes.grids import rectangle_triangles
from arap.puppet.blend import BlendSolver

AGREE = 1e-7
"""Relative agreement of the 2- and 3-column iterations: the same arithmetic in another order, whose round-off tens of
iterations (and a stiff soft point handle) amplify to about 1e-9 with one Cholesky backend and 2e-9 with another; a
wrong path differs by far more."""


def _bend(nx: int = 24, ny: int = 12, angle: float = np.pi / 2) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                         np.ndarray]:
    """A rectangle, its left end held and its right end turned by ``angle`` about its centre."""
    V, T = rectangle_triangles(nx, ny)
    x = V[:, 0]
    left = np.flatnonzero(x <= x.min() + 1e-9)
    right = np.flatnonzero(x >= x.max() - 1e-9)
    c = V[right].mean(axis=0)
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    targets = np.concatenate([V[left], (V[right] - c) @ turn.T + c])
    return V, T, np.concatenate([left, right]), targets


@pytest.fixture
def columns(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """The column count of every right-hand side the iterations assembled (2 from the planar kernel, 3 from the
    one in space)."""
    seen: list[int] = []
    planar_rhs, planar_rhs_and_gradient = iteration.planar_rhs, iteration.planar_rhs_and_gradient
    assemble_rhs, assemble_rhs_and_gradient = iteration.assemble_rhs, iteration.assemble_rhs_and_gradient

    def record(kernel):
        def run(*args):
            seen.append(args[-1].shape[1] if kernel in (planar_rhs, assemble_rhs) else args[-2].shape[1])
            return kernel(*args)
        return run

    for name, kernel in (("planar_rhs", planar_rhs), ("planar_rhs_and_gradient", planar_rhs_and_gradient),
                         ("assemble_rhs", assemble_rhs), ("assemble_rhs_and_gradient", assemble_rhs_and_gradient)):
        monkeypatch.setattr(iteration, name, record(kernel))
    yield seen


def _three_columns(monkeypatch: pytest.MonkeyPatch, on: bool) -> None:
    monkeypatch.setattr(iteration, "_PLANAR_COLUMNS", not on)


@pytest.mark.parametrize(("acceleration", "energy"), [("lbfgs", "elements"), ("anderson", "elements"),
                                                      ("none", "elements"), ("lbfgs", "spokes_and_rims")])
def test_two_columns_give_the_three_column_results(monkeypatch: pytest.MonkeyPatch, columns: list[int],
                                                    acceleration: str, energy: str) -> None:
    V, T, b, targets = _bend()
    results = {}
    for three in (True, False):
        _three_columns(monkeypatch, three)
        columns.clear()
        solver = arap.ArapSolver(V, T, b, energy=energy)
        assert solver.prepared.iteration_columns == 2
        first = solver.solve(targets, max_iterations=25, tolerance=0, acceleration=acceleration)
        moved = targets + np.array([0.05, -0.02])
        warm = solver.solve(moved, max_iterations=10, tolerance=0, acceleration=acceleration)
        assert set(columns) == {3 if three else 2}
        results[three] = (first, warm)
    for old, new in zip(results[True], results[False], strict=True):
        assert new.vertices.shape == V.shape
        scale = np.abs(old.vertices).max()
        np.testing.assert_allclose(new.vertices, old.vertices, rtol=0, atol=AGREE * scale)
        np.testing.assert_allclose(new.energies, old.energies, rtol=AGREE, atol=1e-12 * old.energies[0])
        assert new.iterations == old.iterations


def test_rigid_motions_are_recovered(columns: list[int]) -> None:
    V, T = rectangle_triangles(16, 8)
    angle, shift = 2.0, np.array([3.0, -1.5])
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moved = V @ turn.T + shift
    b = np.array([0, 7, len(V) - 1, len(V) // 2])
    result = arap.ArapSolver(V, T, b).solve(moved[b])
    assert set(columns) == {2}
    assert result.converged
    np.testing.assert_allclose(result.vertices, moved, rtol=0, atol=1e-8)
    assert result.energies[-1] <= 1e-12


@pytest.mark.parametrize("acceleration", ["lbfgs", "anderson", "none"])
def test_energies_never_rise(columns: list[int], acceleration: str) -> None:
    V, T, b, targets = _bend(angle=np.pi / 3)
    result = arap.ArapSolver(V, T, b).solve(targets, acceleration=acceleration, max_iterations=300)
    assert set(columns) == {2}
    e = np.asarray(result.energies)
    assert (np.diff(e) <= 1e-12 * e[0]).all()


@pytest.mark.parametrize("weights", [None, [1e3]])
def test_point_handles_on_two_columns(monkeypatch: pytest.MonkeyPatch, columns: list[int],
                                      weights: list[float] | None) -> None:
    V, T, b, _ = _bend(angle=np.pi / 4)
    left = b[V[b, 0] < 1.0]
    face = int(np.argmax(V[T].mean(axis=1)[:, 0]))
    beta = np.array([[0.2, 0.3, 0.5]])
    goal = beta @ V[T[face]] + [-0.3, 0.6]
    points = (np.array([face]), beta) if weights is None else (np.array([face]), beta, weights)
    results = {}
    for three in (True, False):
        _three_columns(monkeypatch, three)
        columns.clear()
        solver = arap.ArapSolver(V, T, left, points=points)
        results[three] = solver.solve(V[left], point_targets=goal, max_iterations=40, tolerance=0)
        assert set(columns) == {3 if three else 2}
    U = results[False].vertices
    if weights is None:  # hard: met exactly
        np.testing.assert_allclose(beta @ U[T[face]], goal, rtol=0, atol=1e-9)
    np.testing.assert_allclose(U, results[True].vertices, rtol=0, atol=AGREE * np.abs(U).max())
    np.testing.assert_allclose(results[False].energies, results[True].energies, rtol=AGREE)


@pytest.mark.parametrize(("axis", "offset"), [(2, 0.0), (1, 2.5)])
def test_planar_input_in_space_keeps_its_plane_exactly(columns: list[int], axis: int, offset: float) -> None:
    V2, T, b, targets2 = _bend()
    inplane = [k for k in range(3) if k != axis]
    V = np.full((len(V2), 3), offset)  # the plane z = 0, or y = 2.5
    V[:, inplane] = V2
    targets = np.full((len(b), 3), offset)
    targets[:, inplane] = targets2
    solver = arap.ArapSolver(V, T, b, energy="elements")
    seen: list[np.ndarray] = []

    def look(k: int, e: float) -> bool:
        seen.append(solver.current_vertices())
        return True

    result = solver.solve(targets, callback=look)
    assert set(columns) == {2}
    assert result.vertices.shape == V.shape
    assert (result.vertices[:, axis] == offset).all()
    np.testing.assert_array_equal(seen[-1], result.vertices)  # the callback sees the iterate
    flat = arap.ArapSolver(V2, T, b).solve(targets2)
    np.testing.assert_allclose(result.vertices[:, inplane], flat.vertices, rtol=0, atol=AGREE * np.abs(V2).max())


def test_the_picture_warp_similarity_step_runs_on_two_columns(monkeypatch: pytest.MonkeyPatch,
                                                              columns: list[int]) -> None:
    V, T, b, targets = _bend(angle=np.pi / 4)
    shapes: list[int] = []
    step = blend.similarity_step

    def spy(cells, cell_ids, U, R, E, lam):
        shapes.append(U.shape[1])
        return step(cells, cell_ids, U, R, E, lam)

    monkeypatch.setattr(blend, "similarity_step", spy)
    results = {}
    for three in (True, False):
        _three_columns(monkeypatch, three)
        columns.clear()
        shapes.clear()
        warp = BlendSolver(arap.ArapSolver(V, T, b), 1.0)
        results[three] = warp.solve(targets, max_iterations=20, tolerance=0)
        assert set(columns) == {3 if three else 2}
        assert (3 if three else 2) in shapes
    scale = np.abs(results[True].vertices).max()
    np.testing.assert_allclose(results[False].vertices, results[True].vertices, rtol=0, atol=AGREE * scale)
    e = np.asarray(results[False].energies)
    np.testing.assert_allclose(e, results[True].energies, rtol=AGREE)
    assert (np.diff(e) <= 1e-12 * e[0]).all()


def test_surfaces_and_solids_keep_three_columns(columns: list[int]) -> None:
    V, F = arap.sphere(1)
    assert arap.ArapSolver(V, F, [0, 1]).prepared.iteration_columns == 3
    arap.ArapSolver(V, F, [0, 1]).solve(V[[0, 1]] + [0.1, 0.0, 0.0], max_iterations=3)
    assert set(columns) == {3}
    V2, T = rectangle_triangles(6, 3)
    stiffness = np.ones(len(V2))
    stiffness[V2[:, 0] > 1.0] = np.inf  # rigid regions are fitted in space
    assert arap.ArapSolver(V2, T, [0, 1], stiffness=stiffness).prepared.iteration_columns == 3
