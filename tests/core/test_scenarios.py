"""Bend, twist and pull: anchors and handles where they should be, and handle motions of the right kind."""

from __future__ import annotations

import numpy as np
import pytest

from arap.scenarios import SCENARIOS, bend, make_scenario, pull, twist
from arap.shapes import builtin_mesh


def _distances(P: np.ndarray) -> np.ndarray:
    return np.linalg.norm(P[:, None] - P[None], axis=2)


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenarios_pick_disjoint_anchors_and_handles(name: str) -> None:
    V, _ = builtin_mesh("bar")  # long axis y
    s = make_scenario(name, V)
    assert len(s.fixed) and len(s.handles)
    assert not np.intersect1d(s.fixed, s.handles).size
    assert s.targets.shape == (len(s.handles), 3)
    np.testing.assert_array_equal(s.constrained, np.concatenate([s.fixed, s.handles]))
    np.testing.assert_array_equal(s.all_targets(V)[: len(s.fixed)], V[s.fixed])
    assert np.abs(s.targets - V[s.handles]).max() > 0.05  # the handles move
    assert V[s.fixed, 1].min() == V[:, 1].min()  # the bottom end is anchored


def test_bend_and_twist_move_the_top_rigidly_and_pull_translates_a_patch() -> None:
    V, _ = builtin_mesh("bar")
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    b = bend(V, angle=0.5, shift=0.1)
    assert V[b.handles, 1].min() > V[b.fixed, 1].max()
    np.testing.assert_allclose(_distances(b.targets), _distances(V[b.handles]), atol=1e-12)
    # Rotated towards +z (the side axis after y) and shifted along it.
    assert (b.targets - V[b.handles])[:, 2].mean() == pytest.approx(0.1 * diag, rel=1e-9)
    t = twist(V, angle=np.pi / 2)
    np.testing.assert_allclose(_distances(t.targets), _distances(V[t.handles]), atol=1e-12)
    np.testing.assert_allclose(t.targets[:, 1], V[t.handles, 1], atol=1e-12)  # turned about the long axis
    assert np.abs(t.targets - V[t.handles]).max() > 0.5
    p = pull(V, shift=0.15)
    np.testing.assert_allclose(p.targets - V[p.handles], np.tile([0.0, 0.0, 0.15 * diag], (len(p.handles), 1)))
    assert V[p.fixed, 1].max() == V[:, 1].max()  # both ends anchored
    assert abs(np.median(V[p.handles, 1]) - 2.5) < 0.3


def test_unknown_scenario_and_bad_options() -> None:
    V, _ = builtin_mesh("bar")
    with pytest.raises(ValueError, match="unknown scenario 'stretch'"):
        make_scenario("stretch", V)
    with pytest.raises(ValueError, match="share"):
        bend(V, share=0.6)
    with pytest.raises(ValueError, match="different"):
        bend(V, axis=1, side=1)
