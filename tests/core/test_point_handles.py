"""Handles anywhere on the surface: hard points met exactly, a vertex written as a point gives the vertex handle's
result, soft points approach the hard result as their weight grows, the energy (with the soft penalty) never rises,
and bad points are refused."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import arap
from arap.errors import ConstraintError, UnconstrainedRegionError
from arap.scenarios import bend


@pytest.fixture(scope="module")
def cactus() -> tuple[np.ndarray, np.ndarray]:
    return arap.builtin_mesh("cactus")


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(np.ptp(V, axis=0)))


def _random_points(V: np.ndarray, F: np.ndarray, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray,
                                                                                         np.ndarray]:
    """Faces, interior barycentric coordinates and targets moved by about 10% of the diagonal."""
    rng = np.random.default_rng(seed)
    faces = rng.choice(len(F), count, replace=False)
    bary = rng.dirichlet([1.0, 1.0, 1.0], count)
    rest = np.einsum("pj,pjk->pk", bary, V[F[faces]])
    return faces, bary, rest + 0.1 * _diag(V) * rng.standard_normal((count, 3))


def test_hard_points_are_met_to_1e9_of_the_diagonal(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    faces, bary, targets = _random_points(V, F, 4)
    points = arap.PointHandles.create(faces, bary, n_faces=len(F))
    result = arap.ArapSolver(V, F, s.fixed, points=points).solve(V[s.fixed], point_targets=targets)
    assert result.converged
    assert np.abs(points.positions(result.vertices, F) - targets).max() <= 1e-9 * _diag(V)
    np.testing.assert_array_equal(result.vertices[s.fixed], V[s.fixed])


@pytest.mark.parametrize("energy", ["spokes_and_rims", "spokes"])
def test_a_vertex_as_a_point_gives_the_vertex_handle(cactus: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    V, F = cactus
    s = bend(V)
    moved = s.handles[:3]
    keep = ~np.isin(s.constrained, moved)
    faces, bary = [], []
    for h in moved:
        f = int(np.flatnonzero((F == h).any(axis=1))[0])
        faces.append(f)
        bary.append((F[f] == h).astype(float))  # (1, 0, 0) in some order
    points = arap.PointHandles.create(faces, bary, n_faces=len(F))
    by_vertex = arap.ArapSolver(V, F, s.constrained, energy=energy).solve(s.targets, tolerance=1e-12)
    by_point = arap.ArapSolver(V, F, s.constrained[keep], energy=energy, points=points).solve(
        s.targets[keep], point_targets=s.targets[~keep], tolerance=1e-12)
    assert by_vertex.converged and by_point.converged
    np.testing.assert_allclose(by_point.vertices, by_vertex.vertices, rtol=0, atol=1e-8 * _diag(V))
    assert by_point.energies[-1] == pytest.approx(by_vertex.energies[-1], rel=1e-9)


def test_soft_points_approach_the_hard_result(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    faces, bary, targets = _random_points(V, F, 3, seed=1)
    hard = arap.ArapSolver(V, F, s.fixed, points=arap.PointHandles.create(faces, bary, n_faces=len(F))).solve(
        V[s.fixed], point_targets=targets, tolerance=1e-11)
    gaps = []
    for w in (1e0, 1e2, 1e4, 1e6):
        soft = arap.PointHandles.create(faces, bary, np.full(3, w), n_faces=len(F))
        result = arap.ArapSolver(V, F, s.fixed, points=soft).solve(V[s.fixed], point_targets=targets,
                                                                   tolerance=1e-11)
        gaps.append(float(np.abs(result.vertices - hard.vertices).max()))
    assert all(b < a for a, b in itertools.pairwise(gaps))
    assert gaps[-1] < 1e-5 * _diag(V)
    assert gaps[0] > 1e-2 * _diag(V)  # a weak handle really is soft


@pytest.mark.parametrize("acceleration", ["anderson", "none"])
def test_energy_with_penalty_never_rises(cactus: tuple[np.ndarray, np.ndarray], acceleration: str) -> None:
    V, F = cactus
    s = bend(V)
    faces, bary, targets = _random_points(V, F, 4, seed=2)
    weights = np.array([np.inf, 5.0, np.inf, 50.0])
    points = arap.PointHandles.create(faces, bary, weights, n_faces=len(F))
    result = arap.ArapSolver(V, F, s.constrained, points=points).solve(
        s.targets, point_targets=targets, max_iterations=300, acceleration=acceleration)
    E = np.asarray(result.energies)
    assert np.all(np.diff(E) <= 1e-12 * E[0])
    # the reported energy is the ARAP energy plus the soft points' penalty
    misfit = points.positions(result.vertices, F) - targets
    penalty = float(np.sum(weights[[1, 3]] * np.sum(misfit[[1, 3]] ** 2, axis=1)))
    assert E[-1] == pytest.approx(arap.arap_energy(V, F, result.vertices) + penalty, rel=1e-9)
    assert np.abs(misfit[[0, 2]]).max() <= 1e-9 * _diag(V)


def test_points_alone_pin_the_mesh(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    """No vertex constraint: hard points or soft ones alone make the system positive definite."""
    V, F = cactus
    faces, bary, targets = _random_points(V, F, 3, seed=3)
    for weights in (None, np.full(3, 10.0)):
        points = arap.PointHandles.create(faces, bary, weights, n_faces=len(F))
        result = arap.ArapSolver(V, F, [], points=points).solve(np.zeros((0, 3)), point_targets=targets,
                                                               max_iterations=50)
        assert np.all(np.isfinite(result.vertices))
        assert np.all(np.diff(result.energies) <= 1e-12 * result.energies[0])
    with pytest.raises(UnconstrainedRegionError):
        arap.ArapSolver(V, F, [])


def test_warm_solves_follow_moving_points(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    faces, bary, targets = _random_points(V, F, 2, seed=4)
    points = arap.PointHandles.create(faces, bary, n_faces=len(F))
    solver = arap.ArapSolver(V, F, s.fixed, points=points)
    for step in np.linspace(0.0, 1.0, 4):
        goal = points.positions(V, F) + step * (targets - points.positions(V, F))
        result = solver.solve(V[s.fixed], point_targets=goal, max_iterations=20)
        assert np.abs(points.positions(result.vertices, F) - goal).max() <= 1e-9 * _diag(V)
    assert solver.solve(V[s.fixed]).start == "warm"  # None: the points' rest positions


@pytest.mark.parametrize(("faces", "bary", "weights", "message"), [
    ([10**6], [[1, 0, 0]], None, "out of range"),
    ([-1], [[1, 0, 0]], None, "out of range"),
    ([1.0], [[1, 0, 0]], None, "integer"),
    ([1], [[0.5, 0.6, -0.1]], None, ">= 0"),
    ([1], [[0.5, 0.6, 0.1]], None, "sum to 1"),
    ([1], [[np.nan, 0.5, 0.5]], None, "finite"),
    ([1], [[1, 0]], None, "shape"),
    ([1], [[1, 0, 0]], [0.0], "> 0"),
    ([1], [[1, 0, 0]], [np.nan], "> 0"),
    ([1], [[1, 0, 0]], [1.0, 2.0], "shape"),
])
def test_bad_points_are_refused(cactus: tuple[np.ndarray, np.ndarray], faces: list, bary: list,
                                weights: list | None, message: str) -> None:
    _, F = cactus
    with pytest.raises(ConstraintError, match=message):
        arap.PointHandles.create(faces, bary, weights, n_faces=len(F))


def test_dependent_or_decided_hard_points_are_refused(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    free = int(np.flatnonzero(~np.isin(F, s.fixed).any(axis=1))[0])
    twice = arap.PointHandles.create([free, free], [[0.2, 0.3, 0.5]] * 2, n_faces=len(F))
    with pytest.raises(ConstraintError, match="depend on each other"):
        arap.ArapSolver(V, F, s.fixed, points=twice)
    held = int(np.flatnonzero(np.isin(F, s.fixed).all(axis=1))[0])
    decided = arap.PointHandles.create([held], [[0.2, 0.3, 0.5]], n_faces=len(F))
    with pytest.raises(ConstraintError, match="cannot move"):
        arap.ArapSolver(V, F, s.fixed, points=decided)
    # soft, the same points are fine
    for faces in ([free, free], [held]):
        soft = arap.PointHandles.create(faces, [[0.2, 0.3, 0.5]] * len(faces), [1.0] * len(faces), n_faces=len(F))
        result = arap.ArapSolver(V, F, s.fixed, points=soft).solve(V[s.fixed])
        np.testing.assert_allclose(result.vertices, V, rtol=0, atol=1e-9 * _diag(V))  # at rest, nothing pulls


def test_point_targets_are_checked(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    s = bend(V)
    points = arap.PointHandles.create([3], [[1 / 3] * 3], n_faces=len(F))
    solver = arap.ArapSolver(V, F, s.fixed, points=points)
    with pytest.raises(ConstraintError, match="shape"):
        solver.solve(V[s.fixed], point_targets=np.zeros((2, 3)))
    with pytest.raises(ConstraintError, match="finite"):
        solver.solve(V[s.fixed], point_targets=[[np.inf, 0, 0]])
    with pytest.raises(ConstraintError, match="no points"):
        arap.ArapSolver(V, F, s.fixed).solve(V[s.fixed], point_targets=[[0, 0, 0]])
