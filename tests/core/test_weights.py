"""Cotangent weights and the Laplacian: identities and agreement with libigl."""

from __future__ import annotations

import numpy as np
import pytest

from arap.method.cells import build_cells, system_matrix
from arap.method.weights import cotangent_laplacian, edge_weight_matrix


def test_laplacian_symmetric_zero_row_sums_psd(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = camelhead
    L = cotangent_laplacian(V, F)
    assert abs(L - L.T).max() < 1e-12
    assert np.abs(np.asarray(L.sum(axis=1))).max() < 1e-9
    x = np.random.default_rng(0).normal(size=(len(V), 3))
    assert np.einsum("ij,ij->", x, L @ x) > 0
    # Obtuse triangles give some negative weights on this scan.
    W = edge_weight_matrix(V, F)
    assert (W.data < 0).any()


def test_matches_libigl_cotmatrix(knight: tuple[np.ndarray, np.ndarray]) -> None:
    igl = pytest.importorskip("igl")
    V, F = knight
    L = cotangent_laplacian(V, F)
    L_igl = -igl.cotmatrix(V, F)
    assert abs(L - L_igl).max() < 1e-10


def test_single_triangle_boundary_edges_have_one_term() -> None:
    V = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    F = np.array([[0, 1, 2]])
    W = edge_weight_matrix(V, F).toarray()
    # The angle at vertex 0 is 90°, so edge (1, 2) has weight ½ cot 90° = 0.
    assert W[1, 2] == pytest.approx(0.0, abs=1e-15)
    # Edge (0, 1) is opposite vertex 2: ½ cot(atan(2)) = ½ · ½.
    assert W[0, 1] == pytest.approx(0.25)
    assert W[0, 2] == pytest.approx(0.5 * 2.0)


def test_uniform_weights_are_one_inside_half_on_boundary(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = camelhead
    W = edge_weight_matrix(V, F, "uniform")
    assert set(np.unique(W.data).round(12)) == {0.5, 1.0}


@pytest.mark.parametrize(("energy", "factor"), [("spokes", 2.0), ("spokes_and_rims", 3.0)])
def test_system_matrix_is_a_multiple_of_the_laplacian(knight: tuple[np.ndarray, np.ndarray], energy: str,
                                                      factor: float) -> None:
    V, F = knight
    L = system_matrix(build_cells(V, F, energy), len(V))
    assert abs(L - factor * cotangent_laplacian(V, F)).max() < 1e-9
