"""PLY files with texture coordinates per face corner (``property list uchar float texcoord``) and a ``comment
TextureFile`` naming an image whose name has a space, as MeshLab writes them (like trimesh's ``fuze.ply``), binary and
ASCII: read in the file's vertex numbering by every reader, described by ``arap info`` without a traceback, and shown
by the studio with their texture."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arap.io import load_asset, load_mesh
from arap.meshes.shapes import sphere
from arap.server.appearance import look_from_path
from arap.server.meshdata import load_default
from tests.io.asset_models import png


def fuze_like(folder: Path, fmt: str) -> Path:
    """A sphere with grey vertex colours, per-face texture coordinates and face colours, naming ``fuze uv.png``; as
    ASCII, its face lines hold more words than the header says, as MeshLab writes them."""
    V, F = sphere(1)
    uv = np.random.default_rng(0).random((len(F), 6)).astype("<f4")
    head = ["ply", f"format {fmt} 1.0", "comment VCGLIB generated", "comment TextureFile fuze uv.png",
            f"element vertex {len(V)}", "property float x", "property float y", "property float z",
            "property uchar red", "property uchar green", "property uchar blue", "property uchar alpha",
            f"element face {len(F)}", "property list uchar int vertex_indices", "property list uchar float texcoord",
            "property uchar red", "property uchar green", "property uchar blue", "property uchar alpha", "end_header"]
    header = ("\n".join(head) + "\n").encode()
    if fmt == "ascii":
        rows = [" ".join(repr(float(x)) for x in v.astype("<f4")) + " 192 192 192 255" for v in V]
        rows += [f"3 {f[0]} {f[1]} {f[2]} 6 " + " ".join(repr(float(x)) for x in t) + " 9 1 1 1 1 1 1 1 1 1 "
                 for f, t in zip(F, uv, strict=True)]
        body = ("\n".join(rows) + "\n").encode()
    else:
        body = b"".join(v.astype("<f4").tobytes() + bytes([192, 192, 192, 255]) for v in V)
        body += b"".join(struct.pack("<B3iB", 3, *f, 6) + t.tobytes() + bytes([9, 1, 1, 1])
                         for f, t in zip(F, uv, strict=True))
    path = folder / f"fuze_{fmt}.ply"
    path.write_bytes(header + body)
    (folder / "fuze uv.png").write_bytes(png(8, 8, 6))
    return path


@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
def test_every_reader_keeps_the_file_numbering(tmp_path: Path, fmt: str) -> None:
    path = fuze_like(tmp_path, fmt)
    n = len(sphere(1)[0])
    V, F = load_mesh(path, repair=False)
    asset = load_asset(path)
    assert len(V) == len(asset.vertices) == n
    np.testing.assert_array_equal(F, asset.faces)
    assert asset.uvs is not None and list(asset.textures) == ["fuze uv.png"]


def test_binary_and_ascii_read_alike(tmp_path: Path) -> None:
    binary = load_asset(fuze_like(tmp_path, "binary_little_endian"))
    ascii_ = load_asset(fuze_like(tmp_path, "ascii"))
    np.testing.assert_array_equal(binary.vertices, ascii_.vertices)
    np.testing.assert_array_equal(binary.faces, ascii_.faces)
    np.testing.assert_array_equal(binary.uvs, ascii_.uvs)
    face = ascii_.data.element("face")
    assert [int(face.data[c][0]) for c in ("red", "green", "blue", "alpha")] == [9, 1, 1, 1]


@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
def test_the_studio_shows_the_texture(tmp_path: Path, fmt: str) -> None:
    path = fuze_like(tmp_path, fmt)
    look = look_from_path(path, load_default(path))
    assert look is not None and look.textured and look.texture == (tmp_path / "fuze uv.png").read_bytes()


@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
def test_info_describes_it_without_a_traceback(tmp_path: Path, fmt: str) -> None:
    path = fuze_like(tmp_path, fmt)
    done = subprocess.run([sys.executable, "-m", "arap.cli", "info", str(path)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "unable to load image" not in done.stderr, done.stderr
    assert f"vertices: {len(sphere(1)[0])}" in done.stdout and "defects: none" in done.stdout
