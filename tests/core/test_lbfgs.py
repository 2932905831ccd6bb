"""L-BFGS directions (arap.solve.lbfgs): the two-loop recursion equals the BFGS inverse-Hessian update written out,
pairs of non-positive curvature are refused, and the window keeps the newest pairs."""

from __future__ import annotations

import numpy as np
import pytest

from arap.errors import ArapError
from arap.solve.lbfgs import MAX_SCALE, LbfgsHistory, step_dot, subtract_norm


def _bfgs_inverse(H0: np.ndarray, pairs: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """H_{k+1} = (I − ρ s yᵀ) H_k (I − ρ y sᵀ) + ρ s sᵀ, applied oldest pair first."""
    H = H0.copy()
    eye = np.eye(len(H0))
    for s, y in pairs:
        rho = 1.0 / float(s @ y)
        H = (eye - rho * np.outer(s, y)) @ H @ (eye - rho * np.outer(y, s)) + rho * np.outer(s, s)
    return H


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    Q = rng.normal(size=(n, n))
    return Q @ Q.T + n * np.eye(n)


def _feed(history: LbfgsHistory, rng: np.random.Generator, Q: np.ndarray, count: int,
          M: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` random steps on the quadratic with Hessian ``Q`` into ``history`` (each accepted), with the excess
    ``sᵀ(M s − y)`` when a system matrix ``M`` is given; returns the pairs ``(s, y)``."""
    n = len(Q)
    pairs = []
    x, g = np.zeros((n, 1)), np.zeros((n, 1))
    for _ in range(count):
        s = rng.normal(size=n)
        y = Q @ s
        excess = None if M is None else float(s @ (M @ s) - s @ y)
        assert history.update(x + s[:, None], x, g + y[:, None], g, excess)
        x, g = x + s[:, None], g + y[:, None]
        pairs.append((s, y))
    return pairs


@pytest.mark.parametrize("window", [1, 3, 8])
def test_two_loop_equals_the_written_out_update(window: int) -> None:
    rng = np.random.default_rng(window)
    n = 12
    H0 = np.linalg.inv(_spd(rng, n))  # the preconditioner: the inverse of an SPD "system matrix"
    Q = _spd(rng, n)  # the Hessian the pairs come from, so sᵀy > 0
    history = LbfgsHistory(window)
    pairs = _feed(history, rng, Q, 6)
    g = rng.normal(size=n)
    d = history.direction(g[:, None].copy(), lambda q: H0 @ q)
    expected = -_bfgs_inverse(H0, pairs[-window:]) @ g
    np.testing.assert_allclose(d[:, 0], expected, rtol=1e-10, atol=1e-12)
    assert len(history) == min(window, 6)



@pytest.mark.parametrize("flatness", [1.0, 2.5, 40.0])
def test_the_initial_inverse_hessian_is_scaled_by_the_last_pairs_curvature(flatness: float) -> None:
    """With ``excess = sᵀ(H₀⁻¹s − y)`` the directions are those of the written-out update with ``γ H₀``, γ the
    Barzilai-Borwein ratio ``sᵀH₀⁻¹s / sᵀy`` of the newest pair clipped to [1, MAX_SCALE]."""
    rng = np.random.default_rng(7)
    n = 9
    M = _spd(rng, n)  # the "system matrix": H₀ = M⁻¹
    Q = M / flatness  # an energy flatter than M by this factor
    history = LbfgsHistory(4)
    pairs = _feed(history, rng, Q, 3, M)
    gamma = min(max(flatness, 1.0), MAX_SCALE)
    assert history.scale == pytest.approx(gamma, rel=1e-12)
    g = rng.normal(size=n)
    d = history.direction(g[:, None].copy(), lambda q: np.linalg.solve(M, q))
    np.testing.assert_allclose(d[:, 0], -_bfgs_inverse(gamma * np.linalg.inv(M), pairs) @ g, rtol=1e-9, atol=1e-12)
    history.reset()
    assert history.scale == 1.0


def test_step_dot() -> None:
    rng = np.random.default_rng(2)
    a, b, c = (rng.normal(size=(30, 3)) for _ in range(3))
    assert step_dot(a, b, c) == pytest.approx(float(((a - b) * c).sum()), rel=1e-13)

def test_an_empty_history_gives_the_preconditioned_gradient_step() -> None:
    g = np.array([[1.0, -2.0], [3.0, 0.5]])
    d = LbfgsHistory(4).direction(g, lambda q: 0.5 * q)
    np.testing.assert_array_equal(d, -0.5 * g)


def test_pairs_without_positive_curvature_are_refused() -> None:
    history = LbfgsHistory(3)
    zero = np.zeros((1, 2))
    s = np.array([[1.0, 0.0]])
    assert not history.update(s, zero, np.array([[-1.0, 0.0]]), zero)
    assert not history.update(s, zero, np.array([[0.0, 1.0]]), zero)
    assert len(history) == 0
    assert history.update(s, zero, np.array([[2.0, 0.0]]), zero)
    history.reset()
    assert len(history) == 0


def test_the_window_must_be_a_positive_integer() -> None:
    for bad in (0, -1, 2.5):
        with pytest.raises(ArapError):
            LbfgsHistory(bad)  # type: ignore[arg-type]


def test_a_full_window_keeps_the_newest_pairs_after_a_refusal() -> None:
    """A refused pair takes the oldest pair's slot without corrupting the others: the direction equals the written-out
    update over the pairs still held."""
    rng = np.random.default_rng(11)
    n = 10
    Q = _spd(rng, n)
    history = LbfgsHistory(3)
    pairs = _feed(history, rng, Q, 4)
    x, g = np.zeros((n, 1)), np.zeros((n, 1))
    s = rng.normal(size=n)
    assert not history.update(x + s[:, None], x, g - s[:, None], g)  # sᵀy < 0: refused
    assert len(history) == 2
    g = rng.normal(size=n)
    d = history.direction(g[:, None].copy(), lambda q: q.copy())
    np.testing.assert_allclose(d[:, 0], -_bfgs_inverse(np.eye(n), pairs[-2:]) @ g, rtol=1e-10, atol=1e-12)


def test_subtract_norm_writes_into_any_layout() -> None:
    """A back-substitution may return a Fortran-ordered array: the difference must land in it all the same."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(50, 3))
    for d in (rng.normal(size=(50, 3)), np.asfortranarray(rng.normal(size=(50, 3)))):
        expected = d - x
        assert subtract_norm(d, x) == pytest.approx(np.linalg.norm(expected), rel=1e-14)
        np.testing.assert_array_equal(d, expected)


def test_subtract_norm_places_the_step_in_the_same_pass() -> None:
    """With ``out``, the step ``x + (d − x)`` lands in ``out`` (any layout) exactly as ``np.add`` would write it."""
    rng = np.random.default_rng(6)
    x = rng.normal(size=(40, 3))
    for d in (rng.normal(size=(40, 3)), np.asfortranarray(rng.normal(size=(40, 3)))):
        expected = d - x
        out = np.full((40, 3), np.nan)
        assert subtract_norm(d, x, out) == pytest.approx(np.linalg.norm(expected), rel=1e-14)
        np.testing.assert_array_equal(d, expected)
        np.testing.assert_array_equal(out, np.add(x, expected))
    # in place: the step written over the iterate it starts from (the plain iteration's use)
    d, y = rng.normal(size=(40, 3)), x.copy()
    expected = d - x
    assert subtract_norm(d, y, y) == pytest.approx(np.linalg.norm(expected), rel=1e-14)
    np.testing.assert_array_equal(y, np.add(x, expected))
