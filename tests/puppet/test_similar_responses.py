"""The Distort mode's minimum from its responses to the moving targets (``z₀ + J u``) is the minimum solved
directly, for every kind of constraint a picture can hold, and a drag then solves nothing."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

import arap
import arap.puppet.similar as similar
from arap.puppet.blend import BlendSolver
from tests.puppet.pictures import ring

AGREE = 1e-6
"""Largest difference of the two solutions, relative to the picture's size: round-off of a system regularised by
``ε`` = 1e-8 (one pin leaves the turn and scale about it to ``ε``), about 1e-8 of the size."""


def _picture() -> tuple[np.ndarray, np.ndarray]:
    puppet = arap.PuppetWarp(ring(), [[100.0, 25.0]], spacing=8, mode="rigid")
    return puppet.mesh.vertices, puppet.mesh.triangles


def _blend(constrained: list[int], pins: int, seed: int) -> tuple[BlendSolver, np.ndarray, np.ndarray | None]:
    """A Distort solver of the ring picture with ``constrained`` vertices and ``pins`` hard point handles, and
    moved targets for both."""
    V, F = _picture()
    rng = np.random.default_rng(seed)
    faces = rng.choice(len(F), size=pins, replace=False)
    bary = rng.dirichlet(np.ones(3), size=pins)
    solver = arap.ArapSolver(V, F, constrained, energy="elements", points=(faces, bary) if pins else None)
    targets = V[constrained] + rng.normal(scale=10.0, size=(len(constrained), 2))
    P = None
    if pins:
        P = np.einsum("pc,pcx->px", bary, V[F[faces]]) + rng.normal(scale=15.0, size=(pins, 2))
    return BlendSolver(solver, 0.0), targets, P


@pytest.mark.parametrize(("constrained", "pins"), [([], 5), ([0, 1, 2], 0), ([3, 40], 3), ([], 1)])
def test_the_responses_give_the_direct_minimum(constrained: list[int], pins: int,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    by_responses, targets, P = _blend(constrained, pins, seed=len(constrained) + 7 * pins)
    assert by_responses.similar is not None and by_responses.similar._responses is not None
    monkeypatch.setattr(similar, "RESPONSE_ENTRIES", 0)
    direct, _, _ = _blend(constrained, pins, seed=len(constrained) + 7 * pins)
    assert direct.similar is not None and direct.similar._responses is None
    size = float(np.ptp(direct.V, axis=0).max())
    for scale in (1.0, -0.5, 3.0):  # the minimum is affine in the targets: any of them, not only those probed
        rest = by_responses.V[constrained]
        T = rest + scale * (targets - rest)
        Q = None if P is None else P * scale
        a = by_responses.solve(T, point_targets=Q)
        b = direct.solve(T, point_targets=Q)
        assert a.converged and a.iterations == 1
        assert np.abs(a.vertices - b.vertices).max() <= AGREE * size
        assert a.energies[0] == pytest.approx(b.energies[0], rel=1e-6, abs=1e-9 * size ** 2)
        if Q is not None and pins:
            met = by_responses.solver.prepared.points
            assert met is not None
            reached = met.positions(a.vertices, by_responses.F)
            assert np.abs(reached - Q).max() <= AGREE * size  # hard pins exact


def test_a_drag_by_responses_solves_no_system() -> None:
    blend, targets, P = _blend([], 5, seed=3)
    sim = blend.similar
    assert sim is not None

    class Refused:
        backend = "refused"
        timings: ClassVar[dict[str, float]] = {}

        def solve(self, B: np.ndarray) -> np.ndarray:
            raise AssertionError("a drag by responses must not back-substitute")

    sim.factor = Refused()  # type: ignore[assignment]
    assert P is not None
    for step in np.linspace(0.0, 1.0, 4):
        result = blend.solve(targets, point_targets=P * step + (1 - step) * P[::-1])
        assert np.all(np.isfinite(result.vertices))


def test_too_many_moving_targets_solve_directly(monkeypatch: pytest.MonkeyPatch) -> None:
    V, _ = _picture()
    nf = len(V) - 3
    monkeypatch.setattr(similar, "RESPONSE_ENTRIES", 2 * nf * 2 * 3 - 1)  # one number short of 3 vertices' responses
    blend, targets, _ = _blend([0, 1, 2], 0, seed=0)
    assert blend.similar is not None and blend.similar._responses is None
    monkeypatch.setattr(similar, "RESPONSE_ENTRIES", 2 * nf * 2 * 3)
    fits, _, _ = _blend([0, 1, 2], 0, seed=0)
    assert fits.similar is not None and fits.similar._responses is not None
    a, b = blend.solve(targets), fits.solve(targets)
    assert np.abs(a.vertices - b.vertices).max() <= AGREE * float(np.ptp(V, axis=0).max())


@pytest.mark.parametrize("restart", [similar.RESTART, 7])
def test_a_long_drag_of_one_pin_stays_the_direct_minimum(restart: int, monkeypatch: pytest.MonkeyPatch) -> None:
    # A drag moves one pin: each solve adds that pin's responses to the previous minimum, summing all of them again
    # every ``RESTART`` solves; the round-off carried along must stay that of one solve.
    monkeypatch.setattr(similar, "RESTART", restart)
    blend, targets, P = _blend([5], 4, seed=11)
    monkeypatch.setattr(similar, "RESPONSE_ENTRIES", 0)
    direct, _, _ = _blend([5], 4, seed=11)
    assert P is not None and blend.similar is not None and blend.similar._responses is not None
    size = float(np.ptp(direct.V, axis=0).max())
    Q = P.copy()
    for k in range(300):
        Q[2] = P[2] + 20.0 * np.array([np.cos(k / 17.0), np.sin(k / 11.0)])
        if k == 150:
            Q[0] += 3.0  # another pin moves once
        a = blend.solve(targets, point_targets=Q)
        if k % 50 == 49:
            b = direct.solve(targets, point_targets=Q)
            assert np.abs(a.vertices - b.vertices).max() <= AGREE * size
    assert blend.similar._updates < restart


def test_the_complex_factor_solves_the_real_system(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("sksparse.cholmod")
    monkeypatch.setenv("ARAP_BACKEND", "")
    monkeypatch.setattr(similar, "RESPONSE_ENTRIES", 0)
    complex_, targets, P = _blend([2, 9], 3, seed=5)
    assert complex_.similar is not None and isinstance(complex_.similar.factor, similar.HermitianFactor)
    monkeypatch.setenv("ARAP_BACKEND", "cholespy" if "cholespy" in similar.available_backends() else "scipy")
    real, _, _ = _blend([2, 9], 3, seed=5)
    assert real.similar is not None and not isinstance(real.similar.factor, similar.HermitianFactor)
    a, b = complex_.solve(targets, point_targets=P), real.solve(targets, point_targets=P)
    assert np.abs(a.vertices - b.vertices).max() <= AGREE * float(np.ptp(real.V, axis=0).max())
    rng = np.random.default_rng(0)
    B = rng.normal(size=(2 * complex_.similar.p.nf, 3))
    X = complex_.similar.factor.solve(B)
    assert X.shape == B.shape
    Y = real.similar.factor.solve(B)
    assert np.abs(X - Y).max() <= 1e-6 * np.abs(Y).max()
