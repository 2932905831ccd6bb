"""A glTF mesh shown by several nodes (a truck's wheels) is drawn once per node: each further node's instance gets
its own copy of the vertices, placed by its transform, after every first copy; writing keeps each instance's
shape by giving it its own mesh."""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.io import load_asset, load_mesh, save_asset
from arap.io.gltf_container import node_matrix
from tests.io.asset_models import cube_glb, instanced_glb


def _document(path: Path) -> dict:
    data = path.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    return json.loads(data[20:20 + length])


def test_each_node_showing_a_mesh_gets_its_own_vertices(tmp_path: Path) -> None:
    plain = load_asset(cube_glb(tmp_path))
    with pytest.warns(UserWarning, match="shown by 2 nodes: its 2 instances were made separate parts"):
        asset = load_asset(instanced_glb(tmp_path))
    assert len(plain.vertices) == 24 and len(asset.vertices) == 36
    np.testing.assert_array_equal(asset.vertices[:24], plain.vertices), "the first copies keep their numbering"
    np.testing.assert_array_equal(asset.faces[:len(plain.faces)], plain.faces)
    # the copy is mesh 0's accessor placed by the second node's transform (its parent moves by 0.5 in x)
    M = node_matrix({"translation": [0.5, 0, 0]}) @ node_matrix(_document(tmp_path / "instanced.glb")["nodes"][3])
    first = node_matrix({"translation": [0.5, 0, 0]})
    local = asset.vertices[:12] - first[:3, 3]
    np.testing.assert_allclose(asset.vertices[24:], local @ M[:3, :3].T + M[:3, 3], atol=1e-6)
    assert len(asset.faces) == len(plain.faces) + 6
    assert asset.uvs is not None and not np.isnan(asset.uvs).any()
    np.testing.assert_array_equal(asset.uvs[len(plain.faces):], plain.uvs[:6])
    assert asset.vertex_colors is not None and len(asset.vertex_colors) == 36
    V, F = load_mesh(tmp_path / "instanced.glb", repair=False)
    assert len(V) == 36 and len(F) == len(asset.faces), "the solver's reading draws both instances too"


def test_a_mesh_shown_by_very_many_nodes_is_refused_before_copying(tmp_path: Path, monkeypatch: Any) -> None:
    import arap.io.gltf_asset as gltf_asset
    from arap.errors import MeshFormatError

    monkeypatch.setattr(gltf_asset, "MAX_INSTANCED_VERTICES", 30)
    with pytest.raises(MeshFormatError, match="more than 30 vertices once each instance is a part of its own"):
        load_asset(instanced_glb(tmp_path))


def test_each_instance_is_written_with_its_own_shape(tmp_path: Path) -> None:
    with pytest.warns(UserWarning):
        asset = load_asset(instanced_glb(tmp_path))
    moved = asset.vertices.copy()
    moved[24:] += [0.0, 0.0, 1.0]  # only the second wheel rises
    moved[:12] *= 1.1
    out = tmp_path / "out.glb"
    save_asset(out, asset, moved)
    document = _document(out)
    assert len(document["meshes"]) == 3 and document["nodes"][3]["mesh"] == 2
    back = load_asset(out)  # no instances any more: no warning
    np.testing.assert_allclose(back.vertices, moved, atol=1e-5)
    np.testing.assert_array_equal(back.faces, asset.faces)
    # the second instance only moved: its recomputed normals, in its node's frame, are the file's own
    np.testing.assert_allclose(_normals(back, 2), _normals(asset, 0), atol=1e-5)
    np.testing.assert_allclose(_normals(back, 0), _normals(asset, 0), atol=1e-5)

    unchanged = tmp_path / "same.glb"
    save_asset(unchanged, asset)
    assert _document(unchanged)["nodes"][3]["mesh"] == 0, "written as it is: still one mesh in two nodes"


def _normals(asset, mesh: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    from arap.io.gltf_container import accessor_array

    document = asset.data.document
    normal = document["meshes"][mesh]["primitives"][0]["attributes"]["NORMAL"]
    return np.asarray(accessor_array(document, asset.data.buffers, normal, "test"), dtype=np.float64)
