"""Meshes from other libraries (trimesh, pyvista, meshio) go into the solver, and results come out as trimesh
meshes, textured when the solve came from a textured file."""

from __future__ import annotations

import sys
import types
from pathlib import Path
from typing import Any

import meshio
import numpy as np
import pytest
import trimesh

from arap import ArapSolver, mesh_arrays
from arap.errors import MeshError
from arap.io import load_asset
from tests.io.asset_models import cube_glb, cube_ply


def test_trimesh_mesh_and_scene() -> None:
    box = trimesh.creation.box()
    V, F = mesh_arrays(box)
    assert np.array_equal(V, box.vertices) and np.array_equal(F, box.faces)
    scene = trimesh.Scene()
    scene.add_geometry(box, node_name="a")
    move = trimesh.transformations.translation_matrix([3.0, 0.0, 0.0])
    scene.add_geometry(trimesh.creation.icosphere(1), node_name="b", transform=move)
    V, F = mesh_arrays(scene)
    sphere = trimesh.creation.icosphere(1)
    assert V.shape == (8 + len(sphere.vertices), 3) and F.shape == (12 + len(sphere.faces), 3)
    np.testing.assert_allclose(V[8:], sphere.vertices + np.array([3.0, 0.0, 0.0]))  # node transform applied
    assert np.array_equal(F[12:], sphere.faces + 8)
    with pytest.raises(MeshError, match="no triangle mesh"):
        mesh_arrays(trimesh.Scene())
    with pytest.raises(MeshError, match="not both"):
        mesh_arrays(scene, F)


def test_meshio_mesh_triangles() -> None:
    points = np.random.default_rng(1).random((6, 3))
    mesh = meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]])), ("line", np.array([[0, 5]])),
                                ("triangle", np.array([[2, 3, 4], [3, 4, 5]]))])
    V, F = mesh_arrays(mesh)
    assert np.array_equal(V, points) and F.tolist() == [[0, 1, 2], [2, 3, 4], [3, 4, 5]]
    with pytest.raises(MeshError, match=r"no triangle cells \(it has quad\); triangulate it first"):
        mesh_arrays(meshio.Mesh(points, [("quad", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(MeshError, match="2-d points"):
        mesh_arrays(meshio.Mesh(points[:, :2], [("triangle", np.array([[0, 1, 2]]))]))


def _fake_pyvista(monkeypatch: pytest.MonkeyPatch) -> Any:
    """A stand-in for ``pyvista.PolyData`` (pyvista needs VTK, about 100 MB, so it is not a test dependency): the
    same attributes, and the same module and class names, which is all mesh_arrays looks at."""

    class PolyData:
        def __init__(self, points: np.ndarray, faces: np.ndarray) -> None:
            self.points = points
            self.faces = faces

        @property
        def is_all_triangles(self) -> bool:
            cells, at = [], 0
            while at < len(self.faces):
                cells.append(int(self.faces[at]))
                at += cells[-1] + 1
            return all(n == 3 for n in cells)

        def triangulate(self) -> PolyData:
            out, at = [], 0
            while at < len(self.faces):
                n = int(self.faces[at])
                poly = self.faces[at + 1:at + 1 + n]
                out += [[3, poly[0], poly[k], poly[k + 1]] for k in range(1, n - 1)]
                at += n + 1
            return PolyData(self.points, np.asarray(out).reshape(-1))

    class UnstructuredGrid:
        pass

    module = types.ModuleType("pyvista")
    for cls in (PolyData, UnstructuredGrid):
        cls.__module__ = "pyvista.core.pointset"
        setattr(module, cls.__name__, cls)
    monkeypatch.setitem(sys.modules, "pyvista", module)
    return module


def test_pyvista_polydata(monkeypatch: pytest.MonkeyPatch) -> None:
    pv = _fake_pyvista(monkeypatch)
    points = np.random.default_rng(2).random((5, 3))
    V, F = mesh_arrays(pv.PolyData(points, np.array([3, 0, 1, 2, 4, 1, 2, 3, 4])))
    assert np.array_equal(V, points) and F.tolist() == [[0, 1, 2], [1, 2, 3], [1, 3, 4]]
    V, F = mesh_arrays(pv.PolyData(points, np.array([3, 0, 1, 2, 3, 2, 3, 4])))
    assert F.tolist() == [[0, 1, 2], [2, 3, 4]]
    with pytest.raises(MeshError, match="no polygons"):
        mesh_arrays(pv.PolyData(points, np.zeros(0, dtype=int)))
    with pytest.raises(MeshError, match=r"UnstructuredGrid from pyvista is not a surface mesh.*extract_surface"):
        mesh_arrays(pv.UnstructuredGrid())


def test_other_objects_are_refused_clearly() -> None:
    with pytest.raises(MeshError, match=r"cannot take a mesh from a builtins\.object.*trimesh\.Trimesh or "
                                        r"trimesh\.Scene, pyvista\.PolyData, meshio\.Mesh"):
        mesh_arrays(object())
    with pytest.raises(MeshError, match=r"F .* is missing"):
        mesh_arrays(np.zeros((3, 3)))


def test_solver_takes_a_scene_and_a_meshio_mesh() -> None:
    sphere = trimesh.creation.icosphere(2)
    scene = trimesh.Scene(sphere)
    mesh = meshio.Mesh(np.asarray(sphere.vertices), [("triangle", np.asarray(sphere.faces))])
    for source in (scene, mesh):
        V, F = mesh_arrays(source)
        result = ArapSolver(V, F, [0, 1]).solve(V[[0, 1]] + 0.1)
        np.testing.assert_allclose(result.vertices, V + 0.1, atol=1e-8)  # a translation is rigid


def test_result_to_trimesh_keeps_the_texture_of_the_asset(tmp_path: Path) -> None:
    asset = load_asset(cube_glb(tmp_path))
    solve = asset.solve_mesh()
    handles = np.array([0, 1, 2, 8, 9, 10])  # both halves (two meshes, apart)
    result = ArapSolver(solve.V, solve.F, handles).solve(solve.V[handles] * 1.0)
    mesh = result.to_trimesh(asset)
    assert isinstance(mesh, trimesh.Trimesh)
    assert isinstance(mesh.visual, trimesh.visual.TextureVisuals)
    image = mesh.visual.material.image
    assert image is not None and image.size == (8, 8)
    # Every triangle corner keeps its texture coordinates and its (solved) position.
    assert asset.uvs is not None
    np.testing.assert_array_equal(mesh.visual.uv[mesh.faces], asset.uvs)
    np.testing.assert_allclose(mesh.vertices[mesh.faces], solve.file_vertices(result.vertices)[asset.faces])
    plain = result.to_trimesh(solve.F)
    assert plain.vertices.shape == (16, 3) and np.array_equal(plain.faces, solve.F)
    with pytest.raises(MeshError, match="faces"):
        result.to_trimesh("nothing")


def test_to_trimesh_keeps_vertex_colours(tmp_path: Path) -> None:
    path = cube_ply(tmp_path)
    text = path.read_text().replace("property float s\nproperty float t\n", "")
    lines = text.splitlines()
    start = lines.index("end_header") + 1
    for i in range(start, start + 24):
        lines[i] = " ".join(lines[i].split()[:-2])
    path.write_text("\n".join(lines) + "\n")
    asset = load_asset(path)
    assert asset.uvs is None and asset.vertex_colors is not None
    mesh = asset.to_trimesh()
    np.testing.assert_array_equal(mesh.visual.vertex_colors[:, :3], asset.vertex_colors)
