"""Textured models are read and written through the format registry: each asset format's record in
:mod:`arap.io.formats` names its reader, writer and upload hint, so a textured format is added in one place."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import arap.io.formats as formats
from arap.errors import MeshFormatError
from arap.io.assets import (
    ASSET_FORMATS,
    MeshAsset,
    asset_format,
    bundle_mesh_name,
    load_asset,
    load_asset_bytes,
    may_have_attributes,
    save_asset,
)
from arap.io.ply_asset import read_ply_asset, write_ply_asset
from tests.io.asset_models import cube_glb, cube_obj, cube_ply

HINTS: list[bytes] = []
"""The bytes the test format's hint was asked about."""


def read_test_ply(data: bytes, label: str, folder: Path | None, max_vertices: int | None) -> MeshAsset:
    """The test format's reader: a PLY file read as a ``tply`` asset."""
    asset = read_ply_asset(data, label, folder, max_vertices)
    asset.format = "tply"
    return asset


def write_test_ply(path: Path, asset: MeshAsset, V: Any) -> list[Path]:
    """The test format's writer: the asset written as PLY."""
    return write_ply_asset(path, asset, V)


def hint_test_ply(data: bytes) -> bool:
    HINTS.append(data)
    return data.startswith(b"ply")


@pytest.fixture
def test_format(monkeypatch: pytest.MonkeyPatch) -> formats.FileFormat:
    """A textured format ``tply`` (``.tply``) added to the registry, and only there."""
    record = formats.FileFormat("tply", "Test PLY", "surface", (".tply",), asset_reader=f"{__name__}:read_test_ply",
                                asset_writer=f"{__name__}:write_test_ply", asset_hint=f"{__name__}:hint_test_ply")
    monkeypatch.setattr(formats, "FORMATS", (*formats.FORMATS, record))
    monkeypatch.setitem(formats._BY_NAME, record.name, record)
    monkeypatch.setitem(formats._BY_SUFFIX, record.suffix, record)
    HINTS.clear()
    return record


def test_every_asset_format_names_a_reader_and_a_writer() -> None:
    assert ASSET_FORMATS == ("obj", "ply", "glb", "gltf")
    for name in ASSET_FORMATS:
        record = formats.get(name)
        assert record.asset and callable(record.function("asset_reader")) and callable(record.function("asset_writer"))
    for name in ("off", "stl"):
        assert not formats.get(name).asset and formats.get(name).function("asset_reader") is None


def test_a_textured_format_added_to_the_registry_is_read_and_written(test_format: formats.FileFormat,
                                                                      tmp_path: Path) -> None:
    source = cube_ply(tmp_path)
    path = tmp_path / "cube.tply"
    path.write_bytes(source.read_bytes())
    assert asset_format(path) == "tply"
    asset = load_asset(path)
    assert asset.format == "tply" and asset.uvs is not None
    np.testing.assert_array_equal(asset.vertices, load_asset(source).vertices)
    moved = asset.vertices + np.array([0.5, 0.0, 0.0])
    out = tmp_path / "moved.tply"
    assert save_asset(out, asset, moved) == [out]
    again = load_asset(out)
    np.testing.assert_allclose(again.vertices, moved, atol=1e-6)
    np.testing.assert_array_equal(again.uvs, asset.uvs)
    with pytest.raises(MeshFormatError, match="written as"):
        save_asset(tmp_path / "moved.ply", asset, moved)  # another family
    with pytest.warns(UserWarning, match="checker.png"):  # no folder to read the texture from
        assert load_asset_bytes(path.read_bytes(), ".tply").format == "tply"
    assert may_have_attributes(b"ply\n", "model.TPLY") and HINTS == [b"ply\n"]
    assert bundle_mesh_name(["tex/a.png", "model.tply"]) == "model.tply"


def test_a_format_without_asset_functions_is_refused_as_an_asset(tmp_path: Path) -> None:
    with pytest.raises(MeshFormatError, match=r"textured mesh format 'stl'.*supported: obj, ply, glb, gltf"):
        asset_format("model.stl")
    with pytest.raises(MeshFormatError, match="unsupported textured mesh format 'tply'"):
        load_asset_bytes(b"ply\n", "tply")
    asset = load_asset(cube_ply(tmp_path))
    with pytest.raises(MeshFormatError, match="unsupported textured mesh format 'off'"):
        save_asset(tmp_path / "out.off", asset)
    assert not (tmp_path / "out.off").exists()


def test_uploads_are_looked_at_by_their_formats_hint(tmp_path: Path) -> None:
    plain_obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    assert not may_have_attributes(plain_obj, "obj")
    assert may_have_attributes(cube_obj(tmp_path).read_bytes(), "obj")  # texture coordinates and an mtllib
    assert may_have_attributes(b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n", "model.obj")  # colours
    ply = cube_ply(tmp_path).read_bytes()
    assert may_have_attributes(ply, "ply")
    assert not may_have_attributes(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n", "ply")
    assert may_have_attributes(cube_glb(tmp_path).read_bytes(), ".glb")  # glTF has no hint: always looked at
    assert may_have_attributes(b"{}", "gltf")
    assert not may_have_attributes(b"solid x\nendsolid x\n", "stl")  # attributes of STL are not kept
    assert not may_have_attributes(b"", "txt")
