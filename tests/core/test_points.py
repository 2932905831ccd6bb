"""Handles anywhere on the surface: hard points met exactly, a vertex written as a point gives the vertex handle's
result, soft points approach hard ones as their weight grows, and bad points are refused."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.constraints.scenarios import bend
from arap.errors import ConstraintError
from arap.meshes.shapes import obtuse_cylinder
from arap.method.points import check_points


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(np.ptp(V, axis=0)))


def _top_faces(V: np.ndarray, F: np.ndarray, k: int = 3) -> np.ndarray:
    """``k`` faces near the top along the longest axis, far apart from each other."""
    ax = int(np.argmax(np.ptp(V, axis=0)))
    c = V[F].mean(axis=1)[:, ax]
    order = np.argsort(-c)[: 40 * k]
    return order[:: 40][:k]


@pytest.mark.parametrize("mesh", ["cactus", "obtuse_cylinder"])
def test_hard_points_are_met(mesh: str) -> None:
    V, F = arap.builtin_mesh("cactus") if mesh == "cactus" else obtuse_cylinder(spacing=0.1)
    s = bend(V)
    fixed = s.fixed
    faces = _top_faces(V, F)
    bary = np.array([[0.2, 0.3, 0.5], [1 / 3, 1 / 3, 1 / 3], [0.6, 0.4, 0.0]])
    points = check_points(faces, bary, None, len(F))
    targets = points.positions(V, F) + np.array([0.3 * _diag(V), 0.0, 0.1 * _diag(V)])
    solver = arap.ArapSolver(V, F, fixed, points=(faces, bary))
    result = solver.solve(V[fixed], point_targets=targets)
    U = result.vertices
    assert np.abs(points.positions(U, F) - targets).max() < 1e-9 * _diag(V)
    np.testing.assert_allclose(U[fixed], V[fixed], atol=1e-12)
    assert result.converged
    # never rising, up to the rounding of the multipliers' correction near convergence
    assert np.diff(result.energies).max() <= 1e-10 * abs(result.energies[0])


def test_a_vertex_as_a_point_gives_the_vertex_handle() -> None:
    V, F = arap.builtin_mesh("cactus")
    s = bend(V)
    handle = int(s.handles[len(s.handles) // 2])
    target = s.targets[len(s.fixed) + len(s.handles) // 2]
    start = V.copy()
    start[handle] = target  # the same start for both: the vertex handle's rest pose
    vertex = arap.ArapSolver(V, F, np.append(s.fixed, handle)).solve(
        np.vstack([V[s.fixed], target]), max_iterations=60, acceleration="none", initial=start)
    f = int(np.flatnonzero((F == handle).any(axis=1))[0])
    bary = (F[f] == handle).astype(float)  # (1, 0, 0) in the corner's place
    point = arap.ArapSolver(V, F, s.fixed, points=([f], [bary])).solve(
        V[s.fixed], point_targets=[target], max_iterations=60, acceleration="none", initial=start)
    np.testing.assert_allclose(point.vertices, vertex.vertices, rtol=0, atol=1e-9 * _diag(V))
    np.testing.assert_allclose(point.energies, vertex.energies, rtol=1e-9)


def test_soft_points_approach_hard_ones() -> None:
    V, F = arap.builtin_mesh("cactus")
    s = bend(V)
    faces = _top_faces(V, F, 2)
    bary = np.array([[0.5, 0.25, 0.25], [0.1, 0.1, 0.8]])
    targets = check_points(faces, bary, None, len(F)).positions(V, F) + np.array([0.4, 0.0, 0.0])
    hard = arap.ArapSolver(V, F, s.fixed, points=(faces, bary)).solve(V[s.fixed], point_targets=targets)
    gaps = []
    for w in (0.1, 10.0, 1e4):
        soft = arap.ArapSolver(V, F, s.fixed, points=(faces, bary, [w, w]))
        r = soft.solve(V[s.fixed], point_targets=targets)
        assert np.diff(r.energies).max() <= 1e-10 * abs(r.energies[0])
        gaps.append(float(np.abs(r.vertices - hard.vertices).max()))
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 1e-3 * _diag(V)


def test_points_alone_pin_a_part() -> None:
    V, F = arap.builtin_mesh("bar")
    bottom = np.flatnonzero(V[:, 1] < 0.3)
    top_face = int(np.argmax(V[F].mean(axis=1)[:, 1]))
    with pytest.raises(arap.UnconstrainedRegionError):
        arap.ArapSolver(V, F, [], roi=None)
    solver = arap.ArapSolver(V, F, bottom, points=([top_face], [[1 / 3, 1 / 3, 1 / 3]]))
    target = V[F[top_face]].mean(axis=0) + np.array([1.0, 0.0, 0.0])
    U = solver.solve(V[bottom], point_targets=[target]).vertices
    assert np.abs(U[F[top_face]].mean(axis=0) - target).max() < 1e-9 * _diag(V)


@pytest.mark.parametrize(
    ("faces", "bary", "weights", "match"),
    [
        ([10**6], [[1, 0, 0]], None, "out of range"),
        ([2**63], [[1, 0, 0]], None, "point face 9223372036854775808 out of range"),
        ([0.5], [[1, 0, 0]], None, "integer"),
        ([0], [[0.5, 0.6, 0.0]], None, "sum to 1"),
        ([0], [[-0.1, 0.6, 0.5]], None, ">= 0"),
        ([0], [[np.nan, 0.5, 0.5]], None, "finite"),
        ([0], [[1, 0]], None, "shape"),
        ([0], [[1, 0, 0]], [0.0], "positive"),
        ([0], [[1, 0, 0]], [1.0, 2.0], "shape"),
    ],
)
def test_bad_points_are_refused(faces: list, bary: list, weights: list | None, match: str) -> None:
    V, F = arap.builtin_mesh("bar")
    with pytest.raises(ConstraintError, match=match):
        arap.ArapSolver(V, F, [0, 1, 2], points=(faces, bary, weights))


def test_point_targets_are_checked() -> None:
    V, F = arap.builtin_mesh("bar")
    bottom = np.flatnonzero(V[:, 1] < 0.3)
    solver = arap.ArapSolver(V, F, bottom, points=([len(F) - 1], [[1, 0, 0]]))
    with pytest.raises(ConstraintError, match="point_targets is missing"):
        solver.solve(V[bottom])
    with pytest.raises(ConstraintError, match="shape"):
        solver.solve(V[bottom], point_targets=np.zeros((2, 3)))
    with pytest.raises(ConstraintError, match="not independent"):
        arap.ArapSolver(V, F, bottom, points=([len(F) - 1, len(F) - 1], [[1, 0, 0], [1, 0, 0]]))
