"""Edges, boundary, adjacency, components and the locality order."""

from __future__ import annotations

import numpy as np

from arap.diagnose import inspect_mesh
from arap.meshes.shapes import sphere
from arap.meshes.topology import (
    boundary_edges,
    connected_components,
    edge_face_counts,
    locality_order,
    non_manifold_vertices,
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


def test_non_manifold_vertices_are_where_sheets_meet_at_a_point() -> None:
    """A bow-tie and two spheres sharing one vertex have one; a closed sphere, an open patch and a fin (three faces
    on an edge) have none."""
    V, F = sphere(2)
    n = len(V)
    assert len(non_manifold_vertices(F, n)) == 0
    assert len(non_manifold_vertices(F[: len(F) // 2], n)) == 0  # an open patch: boundary vertices are half discs
    fin = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]])
    assert len(non_manifold_vertices(fin, 5)) == 0
    assert non_manifold_vertices(np.array([[0, 1, 2], [0, 3, 4]]), 5).tolist() == [0]
    touching = np.vstack([F, np.where(F == 0, 0, F + n)])  # a second copy of the sphere sharing vertex 0
    assert non_manifold_vertices(touching, 2 * n).tolist() == [0]
    info = inspect_mesh(np.vstack([V, V + np.array([3.0, 0.0, 0.0])]), touching)
    assert not info.closed and info.non_manifold_vertices == 1
