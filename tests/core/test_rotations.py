"""The batched rotation fit agrees with the SVD recipe, reflections and rank-deficient cases included."""

from __future__ import annotations

import numpy as np
import pytest

from arap.rotations import fit_rotations, fit_rotations_svd


def _stack(kind: str, k: int = 4000) -> np.ndarray:
    rng = np.random.default_rng(7)
    S = rng.normal(size=(k, 3, 3))
    if kind == "reflection":
        S *= -np.sign(np.linalg.det(S))[:, None, None]
    elif kind == "rank2":
        S[:, :, 2] = 0.0
        S = S @ np.linalg.qr(rng.normal(size=(3, 3)))[0]
    elif kind == "near_rotation":
        Q = np.linalg.qr(rng.normal(size=(k, 3, 3)))[0]
        Q *= np.sign(np.linalg.det(Q))[:, None, None]
        S = np.swapaxes(Q, 1, 2) @ (np.eye(3) + 0.05 * rng.normal(size=(k, 3, 3)))
    return S


@pytest.mark.parametrize("kind", ["general", "reflection", "rank2", "near_rotation"])
def test_matches_svd_with_reflection_fix(kind: str) -> None:
    S = _stack(kind)
    R = fit_rotations(S)
    R_ref = fit_rotations_svd(S)
    assert np.abs(R - R_ref).max() < 1e-9
    assert np.allclose(np.swapaxes(R, 1, 2) @ R, np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0, atol=1e-12)


def test_reflection_case_is_a_proper_rotation_and_optimal() -> None:
    S = _stack("reflection", 500)
    R = fit_rotations(S)
    assert (np.linalg.det(R) > 0).all()
    best = np.einsum("kij,kji->k", R, S)
    rng = np.random.default_rng(1)
    for _ in range(20):
        Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        Q *= np.sign(np.linalg.det(Q))
        assert (np.einsum("ij,kji->k", Q, S) <= best + 1e-12).all()


def test_rank1_and_zero_matrices_give_optimal_rotations() -> None:
    rng = np.random.default_rng(3)
    S = rng.normal(size=(300, 3, 1)) @ rng.normal(size=(300, 1, 3))
    S[:10] = 0.0
    R = fit_rotations(S)
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(R[:10], np.eye(3))
    # The optimum is not unique for rank 1, but its value is.
    got = np.einsum("kij,kji->k", R, S)
    ref = np.einsum("kij,kji->k", fit_rotations_svd(S), S)
    assert np.allclose(got, ref, rtol=1e-9, atol=1e-12)


def test_rejects_wrong_shape() -> None:
    with pytest.raises(ValueError, match=r"\(k, 3, 3\)"):
        fit_rotations(np.zeros((4, 2, 3)))
