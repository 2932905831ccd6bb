"""Mesh validation, repair and inspection: every defect gets its own error or repair."""

from __future__ import annotations

import numpy as np
import pytest

from arap.diagnose import inspect_mesh
from arap.errors import MeshError
from arap.meshes.mesh import (
    check_mesh,
    degenerate_faces,
    triangulate_polygons,
)
from arap.meshes.repair import repair_mesh
from arap.meshes.shapes import sphere

# A closed tetrahedron, outward-oriented.
TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def grid(n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """An open n×n grid of squares split into triangles, in the z = 0 plane."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    V = np.stack([i.ravel(), j.ravel(), np.zeros(i.size)], axis=1).astype(float)
    idx = (i * (n + 1) + j)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return V, F


# ---------------------------------------------------------------------------------------------- check_mesh
def test_check_mesh_returns_canonical_types() -> None:
    V, F = check_mesh(TET_V.astype(np.float32).T.copy().T, TET_F.astype(np.int32))
    assert V.dtype == np.float64 and V.flags.c_contiguous and V.shape == (4, 3)
    assert F.dtype == np.int64 and F.shape == (4, 3)
    np.testing.assert_array_equal(F, TET_F)


def test_check_mesh_rejects_quads_with_a_hint() -> None:
    with pytest.raises(MeshError, match="quads must be triangulated"):
        check_mesh(TET_V, np.array([[0, 1, 2, 3]]))


@pytest.mark.parametrize(
    ("V", "F", "message"),
    [
        (np.zeros((4, 2)), TET_F, r"shape \(n, 3\)"),
        (np.zeros(12), TET_F, r"shape \(n, 3\)"),
        (TET_V, TET_F[:, :2], r"triangles of shape \(m, 3\)"),
        (TET_V, TET_F.astype(float) + 0.5, "integers"),
        (TET_V, TET_F.astype(bool), "integers"),
        (np.array([["a", "b", "c"]] * 4), TET_F, "real numbers"),
        (np.zeros((0, 3)), np.zeros((0, 3), dtype=int), "empty"),
        (TET_V, np.zeros((0, 3), dtype=int), "empty"),
    ],
)
def test_check_mesh_shapes_and_types(V: np.ndarray, F: np.ndarray, message: str) -> None:
    with pytest.raises(MeshError, match=message):
        check_mesh(V, F)


def test_check_mesh_non_finite_says_how_many_and_first() -> None:
    V = TET_V.copy()
    V[2, 1] = np.nan
    V[3, 0] = np.inf
    with pytest.raises(MeshError, match=r"2 vertices have NaN or infinite coordinates \(first: vertex 2\)"):
        check_mesh(V, TET_F)


def test_check_mesh_out_of_range_and_negative() -> None:
    with pytest.raises(MeshError, match=r"1 faces have vertex indices out of range \[0, 4\) \(first: face 3"):
        check_mesh(TET_V, np.vstack([TET_F[:3], [1, 2, 4]]))
    with pytest.raises(MeshError, match="out of range"):
        check_mesh(TET_V, np.vstack([TET_F, [-1, 2, 3]]))


def test_check_mesh_repeated_vertex() -> None:
    with pytest.raises(MeshError, match=r"1 faces repeat a vertex \(first: face 4 = \[1, 1, 2\]\).*repair_mesh"):
        check_mesh(TET_V, np.vstack([TET_F, [1, 1, 2]]))


def test_check_mesh_zero_area_face_relative_to_bbox() -> None:
    V = np.vstack([TET_V, [0.5, 0.5, 0.0]])  # on the segment from vertex 1 to vertex 2
    F = np.vstack([TET_F, [1, 2, 4]])
    with pytest.raises(MeshError, match=r"1 faces have zero area \(first: face 4 = \[1, 2, 4\]\).*repair_mesh"):
        check_mesh(V, F)
    # The tolerance is relative: the same well-shaped mesh scaled far down is still accepted.
    check_mesh(TET_V * 1e-9, TET_F)
    # A sliver that is thin but not degenerate passes.
    V2 = np.vstack([TET_V, [0.5, 0.5, 1e-4]])
    check_mesh(V2, F)


def test_degenerate_faces_mask() -> None:
    V = np.vstack([TET_V, [0.5, 0.5, 0.0]])
    F = np.vstack([TET_F, [1, 2, 4], [0, 0, 1]])
    np.testing.assert_array_equal(degenerate_faces(V, F), [False] * 4 + [True, True])


# ---------------------------------------------------------------------------------------------- triangulate
def test_triangulate_polygons_fan() -> None:
    np.testing.assert_array_equal(triangulate_polygons(np.array([[0, 1, 2, 3]])), [[0, 1, 2], [0, 2, 3]])
    out = triangulate_polygons([[0, 1, 2], [3, 4, 5, 6, 7]])
    np.testing.assert_array_equal(out, [[0, 1, 2], [3, 4, 5], [3, 5, 6], [3, 6, 7]])
    with pytest.raises(MeshError, match="at least 3"):
        triangulate_polygons([[0, 1]])


# ---------------------------------------------------------------------------------------------- repair
def test_repair_keeps_clean_mesh_unchanged() -> None:
    V, F = grid()
    r = repair_mesh(V, F)
    np.testing.assert_array_equal(r.V, V)
    np.testing.assert_array_equal(r.F, F)
    np.testing.assert_array_equal(r.vertex_map, np.arange(len(V)))
    assert r.report == [] and not r.changed


def test_repair_welds_triangle_soup_keeping_first_occurrence_order() -> None:
    V, F = grid(3)
    soup_V = V[F.ravel()]
    soup_F = np.arange(len(soup_V)).reshape(-1, 3)
    r = repair_mesh(soup_V, soup_F)
    assert len(r.V) == len(V) and len(r.F) == len(F)
    assert r.counts["welded_vertices"] == len(soup_V) - len(V)
    assert any("welded" in line for line in r.report)
    # The first soup vertex of every weld group survives, in soup order.
    first = np.unique(F.ravel(), return_index=True)[1]
    np.testing.assert_array_equal(r.V, soup_V[np.sort(first)])
    # Faces describe the same triangles.
    np.testing.assert_allclose(r.V[r.F], soup_V[soup_F])
    assert r.vertex_map.min() >= 0
    np.testing.assert_array_equal(r.V[r.vertex_map], soup_V)
    check_mesh(r.V, r.F)


def test_repair_welds_within_tolerance_only() -> None:
    V = np.vstack([TET_V, TET_V[3] + [1e-12, 0, 0]])
    F = np.vstack([TET_F[:3], [1, 2, 4]])
    r = repair_mesh(V, F)
    assert len(r.V) == 4 and r.counts["welded_vertices"] == 1
    assert r.vertex_map[4] == 3
    exact = repair_mesh(V, F, weld_tolerance=0.0)
    assert len(exact.V) == 5 and exact.counts["welded_vertices"] == 0


def test_repair_drops_degenerate_duplicate_faces_and_unused_vertices() -> None:
    V = np.vstack([TET_V, [0.5, 0.5, 0.0], [9.0, 9.0, 9.0]])  # 4: collinear point, 5: unused
    F = np.vstack([TET_F, [1, 2, 4], [0, 0, 3], [1, 3, 0], [3, 1, 0]])
    r = repair_mesh(V, F)
    assert r.counts["degenerate_faces"] == 1
    assert r.counts["repeated_vertex_faces"] == 1
    assert r.counts["duplicate_faces"] == 2
    assert r.counts["unreferenced_vertices"] == 2
    np.testing.assert_array_equal(r.F, TET_F)
    np.testing.assert_array_equal(r.V, TET_V)
    np.testing.assert_array_equal(r.vertex_map, [0, 1, 2, 3, -1, -1])
    assert len(r.report) == 4
    check_mesh(r.V, r.F)


def test_repair_triangulates_polygons() -> None:
    V, _ = grid(1)
    r = repair_mesh(V, np.array([[0, 2, 3, 1]]))
    assert len(r.F) == 2 and r.counts["triangulated_polygons"] == 1
    r2 = repair_mesh(V, [[0, 2, 3], [0, 3, 1]])
    np.testing.assert_array_equal(r2.F, [[0, 2, 3], [0, 3, 1]])


def test_repair_drops_unused_nan_but_rejects_used_nan() -> None:
    V = np.vstack([TET_V, [np.nan, 0, 0]])
    r = repair_mesh(V, TET_F)
    assert len(r.V) == 4 and r.vertex_map[4] == -1
    with pytest.raises(MeshError, match="cannot be repaired"):
        repair_mesh(V, np.vstack([TET_F, [0, 1, 4]]))


def test_repair_rejects_out_of_range_and_all_degenerate() -> None:
    with pytest.raises(MeshError, match="out of range"):
        repair_mesh(TET_V, np.array([[0, 1, 7]]))
    with pytest.raises(MeshError, match="no valid face"):
        repair_mesh(TET_V, np.array([[0, 0, 1]]))


# ---------------------------------------------------------------------------------------------- inspect
def test_inspect_closed_mesh() -> None:
    info = inspect_mesh(TET_V, TET_F)
    assert (info.n_vertices, info.n_faces, info.n_edges) == (4, 4, 6)
    assert info.closed and info.boundary_edges == 0 and info.euler_characteristic == 2
    assert info.component_sizes == [4] and info.n_components == 1
    assert info.problems == []
    assert info.diagonal == pytest.approx(np.sqrt(3))
    text = str(info)
    assert "closed" in text and "defects: none" in text


def test_inspect_counts_every_defect() -> None:
    V, F = grid(2)  # 9 vertices, 8 faces, open with one boundary loop of 8 edges
    far = V + np.array([10.0, 0, 0])  # a second component
    V2 = np.vstack([V, far, [[np.nan, 0, 0], V[0], [5.0, 5, 5]]])  # 18: NaN, 19: duplicate of 0, 20: unused
    F2 = np.vstack([F, F + 9, [[19, 1, 4]], [[0, 0, 1]], F[:1], [[0, 1, 2]]])
    info = inspect_mesh(V2, F2)
    assert info.component_sizes == [10, 9]
    assert info.nonfinite_vertices == 1
    assert info.duplicate_vertices == 1
    assert info.repeated_vertex_faces == 1
    assert info.degenerate_faces == 1  # [0, 1, 2] is collinear
    assert info.duplicate_faces == 1
    assert info.unreferenced_vertices == 2  # the NaN vertex and vertex 20
    assert not info.closed and info.boundary_loops >= 2
    assert info.non_manifold_edges >= 1  # the duplicate face doubles its edges
    assert len(info.problems) == 7


def test_inspect_boundary_loops_and_out_of_range() -> None:
    V, F = grid(3)
    info = inspect_mesh(V, np.vstack([F, [[0, 1, 99]]]))
    assert info.out_of_range_faces == 1
    assert info.boundary_edges == 12 and info.boundary_loops == 1
    assert "open: 12 boundary edges in 1 loops" in "\n".join(info.lines())


def test_inspect_negative_weight_share() -> None:
    # A flat quad split along its long diagonal has an obtuse angle opposite it on both sides: negative weight.
    V = np.array([[0.0, 0, 0], [1, 0.2, 0], [2, 0, 0], [1, -0.2, 0]])
    F = np.array([[0, 3, 2], [0, 2, 1]])
    info = inspect_mesh(V, F)
    assert info.negative_weight_share == pytest.approx(1 / 5)
    assert inspect_mesh(TET_V, TET_F).negative_weight_share == 0.0


def test_inspect_reports_nearly_flat_faces() -> None:
    from arap.meshes.shapes import sphere

    V, F = sphere(2)
    info = inspect_mesh(V, F)
    assert info.flat_faces == 0 and "nearly flat" not in "\n".join(info.lines())
    # Split three faces around a point 1e-4 of an edge's length off its midpoint: one nearly flat cap each.
    extra, faces = [], [F[3:]]
    for a, b, c in F[:3]:
        m = len(V) + len(extra)
        extra.append(0.5 * (V[a] + V[b]) + 1e-4 * np.linalg.norm(V[b] - V[a]) * (V[c] - 0.5 * (V[a] + V[b])))
        faces.append(np.array([[a, b, m], [b, c, m], [c, a, m]]))
    capped = inspect_mesh(np.vstack([V, extra]), np.vstack(faces))
    assert capped.flat_faces == 3 and capped.lowest_weight < -1e3
    assert "3 nearly flat faces (an angle above 179°" in "\n".join(capped.lines())


@pytest.mark.parametrize("seed", range(6))
def test_welding_along_a_direction_finds_the_groups_a_kd_tree_finds(seed: int) -> None:
    from arap.meshes._weld import _unique_face_mask, _weld_groups, _weld_groups_tree

    rng = np.random.default_rng(seed)
    V = rng.normal(size=(400, 3)).round(seed % 3)  # rounded: many points share coordinates
    copies = rng.integers(0, len(V), size=150)
    V = np.concatenate([V, V[copies] + rng.normal(size=(150, 3)) * [0.0, 1e-12, 1e-3][seed % 3]])
    V[rng.integers(0, len(V), size=5)] *= -1.0
    V = V[rng.permutation(len(V))]
    for tol in (0.0, 1e-9, 1e-6, 0.05):
        np.testing.assert_array_equal(_weld_groups(V, tol), _weld_groups_tree(V, tol))
    F = rng.integers(0, len(V), size=(500, 3))
    F = np.concatenate([F, F[rng.integers(0, 500, size=40)][:, ::-1]])
    first = [sorted(f) not in [sorted(g) for g in F[:i]] for i, f in enumerate(F.tolist())]
    np.testing.assert_array_equal(_unique_face_mask(F), first)


def test_info_on_a_closed_surface_with_a_nan_vertex() -> None:
    """The faces of a non-finite vertex are left out of the topology, and said to be: the vertex is not "used by no
    face"."""
    V, F = sphere(1)
    V = V.copy()
    V[5, 0] = np.nan
    info = inspect_mesh(V, F)
    uses = int(np.any(F == 5, axis=1).sum())
    assert info.unreferenced_vertices == 0 and info.nonfinite_faces == uses
    assert any(f"({uses} faces use them; the topology above leaves those faces out)" in p for p in info.problems)


def test_in_input_order_moves_vertices_of_dropped_faces_with_their_neighbours() -> None:
    """A vertex used only by faces that repair dropped (a zero-area sliver with a vertex in the middle of an edge, a
    face repeating a vertex) follows the face's kept vertices, so the written file has no spike back to the rest
    pose; a vertex no face uses stays where it was."""
    V, F = grid(2)
    a, b = F[0][0], F[0][1]
    n = len(V)
    V2 = np.vstack([V, 0.25 * V[a] + 0.75 * V[b], V[a] + [0.0, 0.0, 0.1], [[5.0, 5.0, 5.0]]])
    F2 = np.vstack([F, [a, n, b], [a, a, n + 1]])
    r = repair_mesh(V2, F2)
    assert r.vertex_map[n:].tolist() == [-1, -1, -1]
    U = r.V @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).T + [3.0, 0.0, 0.0]  # turned, moved
    out = r.in_input_order(U)
    assert out is not None
    W, G = out
    np.testing.assert_array_equal(G, F2)
    np.testing.assert_allclose(W[n], 0.25 * W[a] + 0.75 * W[b], atol=1e-12)  # still on its edge
    np.testing.assert_allclose(W[n + 1], W[a] + [0.0, 0.0, 0.1], atol=1e-12)
    np.testing.assert_array_equal(W[n + 2], [5.0, 5.0, 5.0])
