"""Edges, boundary, adjacency, components and the locality order."""

from __future__ import annotations

import numpy as np

from arap.topology import (
    boundary_edges,
    connected_components,
    edge_face_counts,
    locality_order,
    unique_edges,
    vertex_adjacency,
)

# Two triangles sharing edge (1, 2), plus a separate triangle.
F = np.array([[0, 1, 2], [2, 1, 3], [4, 5, 6]])


def test_edges_and_boundary() -> None:
    edges, counts = edge_face_counts(F)
    assert len(unique_edges(F)) == 8
    assert dict(zip(map(tuple, edges.tolist()), counts.tolist(), strict=True))[(1, 2)] == 2
    assert len(boundary_edges(F)) == 7
    assert (edges[:, 0] < edges[:, 1]).all()


def test_adjacency_and_components() -> None:
    A = vertex_adjacency(F, 8)
    assert (A != A.T).nnz == 0
    assert A.diagonal().sum() == 0
    assert A[1, 2] == 1 and A[0, 3] == 0
    count, labels = connected_components(F, 8)
    assert count == 3  # two triangles glued, one triangle, one isolated vertex (7)
    assert labels[0] == labels[3] != labels[4]


def test_locality_order_is_a_permutation_that_narrows_the_bandwidth(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    V, F_cam = camelhead
    order = locality_order(F_cam, len(V))
    assert np.array_equal(np.sort(order), np.arange(len(V)))
    inv = np.empty_like(order)
    inv[order] = np.arange(len(V))
    edges = unique_edges(F_cam)
    before = np.abs(edges[:, 0] - edges[:, 1]).max()
    after = np.abs(inv[edges[:, 0]] - inv[edges[:, 1]]).max()
    assert after < before
