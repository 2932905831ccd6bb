"""Loose parts (connected parts no constraint reaches): refused by default, held, or following the constrained
surface nearest to them with its rigid motion."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import arap
from arap.errors import OptionError, UnconstrainedRegionError


@pytest.fixture(scope="module")
def bar_and_box() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The built-in bar (along y, 0..5) and a small separate box beside its top."""
    V, F = arap.builtin_mesh("bar")
    box = trimesh.creation.box(extents=[0.3, 0.3, 0.3])
    Vb = np.asarray(box.vertices) + np.array([1.0, 4.6, 0.0])
    V2 = np.concatenate([V, Vb])
    F2 = np.concatenate([F, np.asarray(box.faces) + len(V)])
    y = V[:, 1]
    fixed, top = np.flatnonzero(y < 0.03), np.flatnonzero(y > 4.97)
    return V2, F2, fixed, top, len(V)


def _targets(V: np.ndarray, fixed: np.ndarray, top: np.ndarray, turn: float = 0.0) -> np.ndarray:
    c, s = np.cos(turn), np.sin(turn)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    centre = V[top].mean(axis=0)
    return np.concatenate([V[fixed], (V[top] - centre) @ R.T + centre + [1.5, 0.0, 0.0]])


def test_a_loose_part_is_refused_by_default(bar_and_box) -> None:
    V, F, fixed, top, _ = bar_and_box
    with pytest.raises(UnconstrainedRegionError, match="a connected part of 8 free vertices"):
        arap.ArapSolver(V, F, np.concatenate([fixed, top]))
    with pytest.raises(OptionError, match="unknown loose"):
        arap.ArapSolver(V, F, np.concatenate([fixed, top]), loose="drift")


def test_a_held_loose_part_stays_at_rest_and_the_rest_is_unchanged(bar_and_box) -> None:
    V, F, fixed, top, n_bar = bar_and_box
    b = np.concatenate([fixed, top])
    targets = _targets(V, fixed, top)
    U = arap.ArapSolver(V, F, b, loose="hold").solve(targets).vertices
    np.testing.assert_array_equal(U[n_bar:], V[n_bar:])
    alone = arap.ArapSolver(V[:n_bar], F[F.max(axis=1) < n_bar], b).solve(targets).vertices
    np.testing.assert_allclose(U[:n_bar], alone, atol=1e-6)  # both converged (to 1e-10 steps)


def test_a_following_part_moves_rigidly_with_the_surface_beside_it(bar_and_box) -> None:
    V, F, fixed, top, n_bar = bar_and_box
    b = np.concatenate([fixed, top])
    solver = arap.ArapSolver(V, F, b, loose="follow")
    assert [len(p) for p in solver.prepared.loose_parts] == [len(V) - n_bar]
    result = solver.solve(_targets(V, fixed, top, turn=0.5))
    U = result.vertices
    P, Q = V[n_bar:], U[n_bar:]
    # rigid: every distance within the box kept
    np.testing.assert_allclose(np.linalg.norm(Q[:, None] - Q[None], axis=2),
                               np.linalg.norm(P[:, None] - P[None], axis=2), atol=1e-9)
    # it went along with the top of the bar (moved 1.5 to the right), turned with it
    assert np.linalg.norm(Q.mean(axis=0) - P.mean(axis=0)) > 1.0
    near = np.argsort(np.linalg.norm(V[:n_bar] - P.mean(axis=0), axis=1))[:20]
    shift_bar = (U[near] - V[near]).mean(axis=0)
    assert np.linalg.norm((Q - P).mean(axis=0) - shift_bar) < 0.3
    assert arap.arap_energy(V, F, U) == pytest.approx(result.energies[-1], rel=1e-6)
    # the rigid start and a rigid motion of every constraint carry the part exactly
    c, s = np.cos(2.0), np.sin(2.0)
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    moved = solver.solve((V[b] @ R.T) + 3.0).vertices
    np.testing.assert_allclose(moved, V @ R.T + 3.0, atol=1e-8)
