"""glTF files made to cost far more than their size: counts without the bytes behind them, primitives repeating the
same triangles, percent-encoded data URIs, deep node hierarchies and deeply nested JSON. Each is read in memory and
time in proportion to the file, or refused with one clear error (:class:`~arap.errors.MeshFormatError`)."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import textwrap
import urllib.parse
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.errors import MeshFormatError
from arap.io import gltf_container, load_asset, load_asset_bytes, load_mesh_bytes, save_asset
from arap.server.errors import RequestError
from arap.server.meshdata import load_upload
from tests.io.asset_models import glb_bytes

TRI_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4")
TRI_I = np.array([0, 1, 2], dtype="<u4")


def _triangle(**extra: Any) -> tuple[dict[str, Any], bytes]:
    """One triangle: POSITION accessor 0, indices accessor 1, in one buffer; ``extra`` updates the document."""
    blob = TRI_V.tobytes() + TRI_I.tobytes()
    document: dict[str, Any] = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "buffers": [{"byteLength": len(blob)}],
    }
    document.update(extra)
    return document, blob


def _peak_memory_of_loading(path: Path) -> tuple[int, str]:
    """Peak memory (bytes, as :mod:`tracemalloc` counts it: Python objects and NumPy arrays) of loading ``path`` with
    :func:`arap.io.load_asset` in a fresh process, and the error it gave ("" for none)."""
    code = textwrap.dedent(f"""
        import tracemalloc
        import numpy, arap.io, arap.io.gltf_asset
        tracemalloc.start()
        error = ""
        try:
            arap.io.load_asset({str(path)!r})
        except Exception as exc:
            error = type(exc).__name__ + ": " + str(exc)
        print(tracemalloc.get_traced_memory()[1], error.replace(chr(10), " "))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    peak, _, error = done.stdout.strip().partition(" ")
    return int(peak), error


@pytest.mark.parametrize(("change", "message"), [
    # a texture coordinate accessor without a buffer view (zeros by the specification) and a huge count
    (lambda d: (d["accessors"].append({"componentType": 5126, "count": 30_000_000, "type": "VEC2"}),
                d["meshes"][0]["primitives"][0]["attributes"].update(TEXCOORD_0=2)),
     r"accessor 2 has no buffer view and 30,000,000 elements, more than the 3 vertices it belongs to"),
    (lambda d: d["accessors"][0].update(count=30_000_000) or d["accessors"][0].pop("bufferView"),
     "POSITION accessor has no buffer view"),
    (lambda d: d["accessors"][1].update(count=30_000_000) or d["accessors"][1].pop("bufferView"),
     "indices have no buffer view"),
])
def test_a_huge_count_without_bytes_is_refused_before_allocating(tmp_path: Path, change: Any, message: str) -> None:
    document, blob = _triangle()
    change(document)
    data = glb_bytes(document, blob)
    assert len(data) < 1000
    path = tmp_path / "tiny.glb"
    path.write_bytes(data)
    grown, error = _peak_memory_of_loading(path)
    assert grown < 64 * 2**20, f"loading a {len(data)}-byte file took {grown / 2**20:.0f} MiB more"
    assert error.startswith("MeshFormatError") and message.replace("\\", "") in error, error
    with pytest.raises(RequestError) as info:  # the studio: one clear refusal
        load_upload(data, "tiny.glb", max_vertices=2_000_000)
    assert info.value.code == "bad_mesh"


def test_primitives_repeating_the_same_triangles_are_refused() -> None:
    """10,000 primitives naming one indices accessor: a tiny document, 10,000 times the triangles."""
    V = np.random.default_rng(0).random((1000, 3)).astype("<f4")
    I = np.random.default_rng(1).integers(0, 1000, (2000, 3)).astype("<u4")  # noqa: E741
    blob = V.tobytes() + I.tobytes()
    document, _ = _triangle()
    document["accessors"] = [{"bufferView": 0, "componentType": 5126, "count": 1000, "type": "VEC3"},
                             {"bufferView": 1, "componentType": 5125, "count": I.size, "type": "SCALAR"}]
    document["bufferViews"] = [{"buffer": 0, "byteOffset": 0, "byteLength": V.nbytes},
                               {"buffer": 0, "byteOffset": V.nbytes, "byteLength": I.nbytes}]
    document["buffers"] = [{"byteLength": len(blob)}]
    document["meshes"][0]["primitives"] = [{"attributes": {"POSITION": 0}, "indices": 1}] * 10_000
    with pytest.raises(MeshFormatError, match=r"more than 4 per vertex \(primitives repeating the same triangles"):
        load_asset_bytes(glb_bytes(document, blob), "glb")
    document["meshes"][0]["primitives"] = [{"attributes": {"POSITION": 0}, "indices": 1}] * 2  # two: still fine
    assert len(load_asset_bytes(glb_bytes(document, blob), "glb").faces) == 4000


def test_percent_decoding_matches_the_standard_library() -> None:
    rng = np.random.default_rng(3)
    alphabet = list("%%%%abcAF09zg/ é")
    for size in [*range(12), 50, 1000]:
        for _ in range(200 if size < 50 else 20):
            text = "".join(rng.choice(alphabet, size))
            assert gltf_container.percent_decoded(text) == urllib.parse.unquote_to_bytes(text), text
    payload = rng.integers(0, 256, 3 * 2**20, dtype=np.uint8).tobytes()  # across several pieces
    encoded = urllib.parse.quote_from_bytes(payload, safe="")
    assert gltf_container.percent_decoded(encoded) == payload


def test_a_percent_encoded_data_uri_is_read_in_bounded_memory(tmp_path: Path) -> None:
    """A 12 MB URI (4 MB of data): the standard library's decoding holds a list of 4 million pieces."""
    payload = np.random.default_rng(4).integers(0, 256, 4 * 2**20, dtype=np.uint8).tobytes()
    document, blob = _triangle()
    document["buffers"].append({"byteLength": len(payload),
                                "uri": "data:application/octet-stream," + "".join(f"%{b:02X}" for b in payload)})
    path = tmp_path / "percent.glb"
    path.write_bytes(glb_bytes(document, blob))
    asset = load_asset(path)
    assert asset.data.buffers[1] == payload
    grown, error = _peak_memory_of_loading(path)
    assert error == ""
    size = path.stat().st_size
    assert grown < 10 * size, f"{grown / 2**20:.0f} MiB for a {size / 2**20:.0f} MiB file"
    save_asset(tmp_path / "again.glb", asset)  # an embedded data URI stays as it is
    assert load_asset(tmp_path / "again.glb").data.buffers[1] == payload


def _chain(n: int) -> bytes:
    document, blob = _triangle()
    document["nodes"] = [{"children": [i + 1], "translation": [0.5, 0, 0]} for i in range(n)] + [{"mesh": 0}]
    return glb_bytes(document, blob)


def test_a_deep_node_chain_is_refused_clearly() -> None:
    with pytest.raises(MeshFormatError, match="node hierarchy is more than 1024 levels deep"):
        load_asset_bytes(_chain(100_000), "glb")
    with pytest.raises(RequestError) as info:
        load_upload(_chain(100_000), "chain.glb", max_vertices=1000)
    assert info.value.code == "bad_mesh" and "levels deep" in info.value.message


def test_a_chain_within_the_limit_is_placed_by_every_node() -> None:
    asset = load_asset_bytes(_chain(1000), "glb")
    np.testing.assert_allclose(asset.vertices, TRI_V + np.array([500.0, 0, 0]))


@pytest.mark.parametrize("depth", [65, 100_000])  # the limit is 64 levels
def test_deeply_nested_json_is_a_clear_error(depth: int) -> None:
    document, blob = _triangle()
    text = json.dumps(document)[:-1] + ', "extras": ' + "[" * depth + "]" * depth + "}"
    data = _glb_with_text(text.encode(), blob)
    with pytest.raises(MeshFormatError, match="nested too deeply"):
        load_asset_bytes(data, "glb")
    with pytest.raises(MeshFormatError, match="nested too deeply"):
        load_mesh_bytes(data, "glb")
    with pytest.raises(RequestError) as info:
        load_upload(data, "deep.glb", max_vertices=1000)
    assert info.value.code == "bad_mesh"


def test_json_within_the_depth_limit_loads() -> None:
    assert gltf_container.MAX_JSON_DEPTH == 64
    depth = 62
    document, blob = _triangle(extras=json.loads("[" * depth + "]" * depth))
    assert len(load_asset_bytes(glb_bytes(document, blob), "glb").faces) == 1


def _glb_with_text(text: bytes, blob: bytes) -> bytes:
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def _png_header(width: int, height: int) -> bytes:
    """A PNG file announcing ``width`` x ``height`` pixels, with almost no pixel data."""
    import zlib

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 16)) + \
        chunk(b"IEND", b"")


def test_a_texture_announcing_too_many_pixels_is_not_decoded(tmp_path: Path) -> None:
    from arap.io.assets import MAX_TEXTURE_PIXELS
    from tests.io.asset_models import cube_obj

    asset = load_asset(cube_obj(tmp_path))
    asset.textures = {"huge.png": _png_header(12_000, 12_000)}
    assert 12_000 * 12_000 > MAX_TEXTURE_PIXELS
    with pytest.warns(UserWarning, match=r"the texture 'huge\.png' is 12,000 x 12,000 pixels"):
        mesh = asset.to_trimesh()
    image = mesh.visual.material.image  # trimesh's default picture, or none
    assert image is None or image.size != (12_000, 12_000)
