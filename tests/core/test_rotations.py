"""The batched rotation fit agrees with the SVD recipe, reflections and rank-deficient cases included."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from benchmarks.reference_kernels import fit_rotations_scalar, fit_rotations_svd

from arap.method.rotations import BLOCK
from arap.method.rotations import rotations_from_covariances as fit_rotations


def _scalar(S: np.ndarray) -> np.ndarray:
    R = np.empty_like(S)
    fit_rotations_scalar(np.ascontiguousarray(S), R)
    return R


FITS: dict[str, Callable[[np.ndarray], np.ndarray]] = {"blocks": fit_rotations, "scalar": _scalar}


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


@pytest.mark.parametrize("path", FITS)
@pytest.mark.parametrize("kind", ["general", "reflection", "rank2", "near_rotation"])
def test_matches_svd_with_reflection_fix(kind: str, path: str) -> None:
    S = _stack(kind)
    R = FITS[path](S)
    R_ref = fit_rotations_svd(S)
    assert np.abs(R - R_ref).max() < 1e-9
    assert np.allclose(np.swapaxes(R, 1, 2) @ R, np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0, atol=1e-12)


@pytest.mark.parametrize("kind", ["general", "reflection", "rank2", "near_rotation"])
def test_blocks_agree_with_the_cell_by_cell_fit(kind: str) -> None:
    S = _stack(kind, 3 * BLOCK + 5)  # a partial last block
    assert np.abs(fit_rotations(S) - _scalar(S)).max() < 1e-12


@pytest.mark.parametrize("path", FITS)
def test_reflection_case_is_a_proper_rotation_and_optimal(path: str) -> None:
    S = _stack("reflection", 500)
    R = FITS[path](S)
    assert (np.linalg.det(R) > 0).all()
    best = np.einsum("kij,kji->k", R, S)
    rng = np.random.default_rng(1)
    for _ in range(20):
        Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        Q *= np.sign(np.linalg.det(Q))
        assert (np.einsum("ij,kji->k", Q, S) <= best + 1e-12).all()


@pytest.mark.parametrize("path", FITS)
def test_rank1_and_zero_matrices_give_optimal_rotations(path: str) -> None:
    rng = np.random.default_rng(3)
    S = rng.normal(size=(300, 3, 1)) @ rng.normal(size=(300, 1, 3))
    S[:10] = 0.0
    R = FITS[path](S)
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(R[:10], np.eye(3))
    # The optimum is not unique for rank 1, but its value is.
    got = np.einsum("kij,kji->k", R, S)
    ref = np.einsum("kij,kji->k", fit_rotations_svd(S), S)
    assert np.allclose(got, ref, rtol=1e-9, atol=1e-12)


def test_degenerate_cells_inside_a_block_do_not_disturb_their_neighbours() -> None:
    """Cells that need the careful path (zero, rank 1, repeated eigenvalue) share SIMD blocks with ordinary ones."""
    S = _stack("general", 2 * BLOCK)
    rng = np.random.default_rng(5)
    odd = rng.choice(len(S), size=40, replace=False)
    S[odd[:10]] = 0.0
    S[odd[10:25]] = rng.normal(size=(15, 3, 1)) @ rng.normal(size=(15, 1, 3))
    # Reflections with σ2 = σ3: the two top eigenvalues of Horn's matrix are equal, the optimum is not unique.
    Q = np.linalg.qr(rng.normal(size=(15, 3, 3)))[0]
    S[odd[25:]] = Q @ np.diag([2.0, 1.0, -1.0]) @ np.swapaxes(Q, 1, 2)
    R = fit_rotations(S)
    ordinary = np.setdiff1d(np.arange(len(S)), odd)
    assert np.abs(R[ordinary] - fit_rotations_svd(S[ordinary])).max() < 1e-9
    got = np.einsum("kij,kji->k", R, S)
    ref = np.einsum("kij,kji->k", fit_rotations_svd(S), S)
    assert np.allclose(got, ref, rtol=1e-9, atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)


def test_rejects_wrong_shape() -> None:
    with pytest.raises(ValueError, match=r"\(k, 3, 3\)"):
        fit_rotations(np.zeros((4, 2, 3)))
