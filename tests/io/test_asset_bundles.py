"""A mesh file with the files it names (MTL files, textures, glTF buffers) in one zip: read by rules that keep what
it names inside the zip, and refused whole before extracting when it is a zip bomb or names anything outside."""

from __future__ import annotations

import io
import stat
import zipfile
from pathlib import Path

import numpy as np
import pytest

from arap.errors import MeshFormatError
from arap.io import load_asset
from arap.io.assets import bundle_mesh_name, read_bundle, unpacked_bundle
from arap.io.obj_write import obj_files
from tests.io.asset_models import cube_glb, cube_gltf, cube_obj, zip_of


def test_an_obj_bundle_brings_its_mtl_and_textures(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    cube_obj(src)
    files = read_bundle(zip_of(src), max_bytes=1 << 20)
    assert set(files) == {"cube.obj", "cube.mtl", "tex/checker.png", "tex/bump.png"}
    assert bundle_mesh_name(files) == "cube.obj"
    with unpacked_bundle(files) as folder:
        asset = load_asset(folder / "cube.obj")
    assert set(asset.textures) == {"tex/checker.png", "tex/bump.png"}
    assert asset.uvs is not None and not np.isnan(asset.uvs).any()


def test_a_gltf_bundle_brings_its_buffer_and_image(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    cube_gltf(src)
    files = read_bundle(zip_of(src), max_bytes=1 << 20)
    with unpacked_bundle(files) as folder:
        asset = load_asset(folder / bundle_mesh_name(files))
    assert asset.textures and len(asset.vertices) == 24


def _zip(entries: list[tuple[zipfile.ZipInfo | str, bytes]]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        for info, data in entries:
            archive.writestr(info, data)
    return out.getvalue()


@pytest.mark.parametrize("name", ["/etc/passwd", "../up.mtl", "a/../../up.mtl", "C:/x.mtl", "..\\up.mtl"])
def test_names_leading_outside_are_refused(name: str) -> None:
    with pytest.raises(MeshFormatError, match="leads outside the archive"):
        read_bundle(_zip([("m.obj", b"v 0 0 0\n"), (name, b"x")]), max_bytes=1 << 20)


def test_links_bombs_and_crowds_are_refused_before_extracting() -> None:
    link = zipfile.ZipInfo("tex.png")
    link.create_system = 3
    link.external_attr = (stat.S_IFLNK | 0o777) << 16
    with pytest.raises(MeshFormatError, match="symbolic link"):
        read_bundle(_zip([("m.obj", b"v 0 0 0\n"), (link, b"/etc/passwd")]), max_bytes=1 << 20)
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("m.obj", b"\0" * (8 << 20))  # 8 MiB of zeros: a few kB compressed
    assert len(out.getvalue()) < 100_000
    with pytest.raises(MeshFormatError, match="once uncompressed, more than"):
        read_bundle(out.getvalue(), max_bytes=1 << 20)
    crowd = _zip([(f"f{i}.png", b"x") for i in range(20)])
    with pytest.raises(MeshFormatError, match="20 files, more than the 10"):
        read_bundle(crowd, max_bytes=1 << 20, max_files=10)
    with pytest.raises(MeshFormatError, match="both as a file and as a folder"):
        read_bundle(_zip([("a", b"1"), ("a/b.png", b"2")]), max_bytes=1 << 20)
    with pytest.raises(MeshFormatError, match="cannot be extracted"), unpacked_bundle({"x" * 300 + ".png": b""}):
        pass
    with pytest.raises(MeshFormatError, match="twice"):
        read_bundle(_zip([("a.obj", b"1"), ("./a.obj", b"2")]), max_bytes=1 << 20)
    with pytest.raises(MeshFormatError, match="not a readable zip"):
        read_bundle(b"PK\3\4 not really", max_bytes=1 << 20)


def test_a_bundle_holds_one_mesh_file() -> None:
    with pytest.raises(MeshFormatError, match="holds none"):
        bundle_mesh_name({"a.png": b""})
    with pytest.raises(MeshFormatError, match="holds 2"):
        bundle_mesh_name({"a.obj": b"", "b.glb": b""})
    assert bundle_mesh_name({"__x/a.GLB": b"", "a.bin": b""}) == "__x/a.GLB"


def test_a_name_outside_the_bundle_is_missing_with_a_warning(tmp_path: Path) -> None:
    secret = tmp_path / "secret.mtl"
    secret.write_text("newmtl stolen\nmap_Kd stolen.png\n")
    obj = f"mtllib ../secret.mtl\nmtllib {secret}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n".encode()
    files = read_bundle(_zip([("m.obj", obj)]), max_bytes=1 << 20)
    with unpacked_bundle(files) as folder, pytest.warns(UserWarning, match="secret.mtl") as caught:
        asset = load_asset(folder / "m.obj")
    assert not asset.data.mtl_files and not asset.textures
    assert any("leads outside" in str(w.message) for w in caught)


def test_a_glb_converts_to_obj_with_its_material_and_texture(tmp_path: Path) -> None:
    source = load_asset(cube_glb(tmp_path))
    moved = source.vertices * 1.5
    files = obj_files(source, moved, "out")
    assert list(files)[:2] == ["out.obj", "out.mtl"] and len(files) == 3
    out = tmp_path / "out"
    out.mkdir()
    for name, content in files.items():
        (out / name).write_bytes(content)
    back = load_asset(out / "out.obj")
    assert back.materials == source.materials == ["red", "textured"]
    np.testing.assert_allclose(back.vertices, moved, rtol=1e-12)
    np.testing.assert_array_equal(back.faces, source.faces)
    assert source.uvs is not None and back.uvs is not None
    flipped = source.uvs.copy()
    flipped[..., 1] = 1.0 - flipped[..., 1]  # glTF counts v down from the top, OBJ up from the bottom
    np.testing.assert_allclose(back.uvs, flipped, atol=1e-7)
    assert list(back.textures.values()) == [source.textures["checker"]]
    np.testing.assert_array_equal(back.face_materials, source.face_materials)
