"""Mesh files a hostile or careless user sends: Latin-1 text, binary junk, OBJ vertex 0, absurd coordinate scales
and files far larger than accepted (refused from their header, before the slow parse)."""

from __future__ import annotations

import numpy as np
import pytest

from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io import load_mesh_bytes, load_mesh_bytes_with_report, save_mesh_bytes
from arap.meshes.shapes import sphere
from arap.server.errors import RequestError
from arap.server.meshdata import load_upload

TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _obj(V: np.ndarray, F: np.ndarray, comment: bytes = b"") -> bytes:
    lines = [comment] + [b"v %r %r %r" % tuple(map(float, v)) for v in V] + [b"f %d %d %d" % tuple(f + 1) for f in F]
    return b"\n".join(lines) + b"\n"


def _off(V: np.ndarray, F: np.ndarray, comment: bytes = b"") -> bytes:
    lines = [b"OFF", comment, b"%d %d 0" % (len(V), len(F))] + [b"%r %r %r" % tuple(map(float, v)) for v in V]
    return b"\n".join(lines + [b"3 %d %d %d" % tuple(f) for f in F]) + b"\n"


def _ascii_stl(V: np.ndarray, F: np.ndarray, name: bytes) -> bytes:
    out = [b"solid " + name]
    for f in F:
        out += [b"facet normal 0 0 0", b"outer loop", *(b"vertex %r %r %r" % tuple(map(float, V[i])) for i in f),
                b"endloop", b"endfacet"]
    return b"\n".join([*out, b"endsolid " + name]) + b"\n"


def _ascii_ply(V: np.ndarray, F: np.ndarray, comment: bytes) -> bytes:
    head = [b"ply", b"format ascii 1.0", b"comment " + comment, b"element vertex %d" % len(V),
            b"property double x", b"property double y", b"property double z", b"element face %d" % len(F),
            b"property list uchar int vertex_indices", b"end_header"]
    body = [b"%r %r %r" % tuple(map(float, v)) for v in V] + [b"3 %d %d %d" % tuple(f) for f in F]
    return b"\n".join(head + body) + b"\n"


LATIN1 = {
    "obj": _obj(TET_V, TET_F, b"# mod\xe8le cr\xe9\xe9 \xe0 la main"),
    "off": _off(TET_V, TET_F, b"# t\xeate"),
    "stl": _ascii_stl(TET_V, TET_F, b"pi\xe8ce"),
    "ply": _ascii_ply(TET_V, TET_F, b"auteur: Jos\xe9"),
}


@pytest.mark.parametrize("fmt", sorted(LATIN1))
def test_latin1_text_loads_like_utf8(fmt: str) -> None:
    data = LATIN1[fmt]
    with pytest.raises(UnicodeDecodeError):
        data.decode("utf-8")
    V, F = load_mesh_bytes(data, fmt)
    utf8 = data.decode("latin-1").encode("utf-8")
    V8, F8 = load_mesh_bytes(utf8, fmt)
    assert len(V) == 4 and len(F) == 4
    np.testing.assert_array_equal(V, V8)
    np.testing.assert_array_equal(F, F8)
    assert {tuple(v) for v in V} == {tuple(v) for v in TET_V}


def test_binary_stl_with_a_latin1_header_loads() -> None:
    data = bytearray(save_mesh_bytes(TET_V, TET_F, "stl"))
    data[:12] = b"pi\xe8ce \xe9t\xe9 \x00\x01"
    V, F = load_mesh_bytes(bytes(data), "stl")
    assert V.shape == (4, 3) and F.shape == (4, 3)


@pytest.mark.parametrize(
    ("fmt", "message"),
    [("obj", "not an OBJ file: it holds binary data"), ("off", "not an OFF file: it holds binary data"),
     ("stl", "not an STL file: neither binary"), ("ply", "not a PLY file")],
)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_junk_gets_a_clear_message(fmt: str, message: str, seed: int) -> None:
    junk = np.random.default_rng(seed).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    with pytest.raises(MeshError, match=message) as info:  # a MeshError like every unusable mesh
        load_mesh_bytes(junk, fmt)
    assert isinstance(info.value, MeshFormatError)
    with pytest.raises(RequestError) as upload:
        load_upload(junk, f"junk.{fmt}", max_vertices=10_000)
    assert upload.value.code == "bad_mesh" and message in upload.value.message


def test_junk_after_a_plausible_start_is_refused() -> None:
    junk = np.random.default_rng(5).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    with pytest.raises(MeshFormatError, match="binary data"):
        load_mesh_bytes(b"solid x\n" + junk, "stl")
    with pytest.raises(MeshFormatError, match="binary data"):
        load_mesh_bytes(b"ply\nformat binary_little_endian 1.0\ncomment " + junk + b"\nend_header\n", "ply")


@pytest.mark.parametrize(
    ("faces", "line"),
    [(b"f 0 1 2\nf 1 2 4", 5), (b"f 1 2 3\n  f 4 0/1 1", 6), (b"f 1 2 3\r\nf 1 2 0\r\n", 6)],
)
def test_obj_vertex_zero_is_refused(faces: bytes, line: int) -> None:
    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n" + faces
    with pytest.raises(MeshFormatError, match=f"line {line}: a face names vertex 0, but OBJ vertex indices start at 1"):
        load_mesh_bytes(data, "obj")


def test_obj_face_beyond_the_vertices_is_named() -> None:
    """In the file's terms: OBJ counts vertices from 1, so the 9 of the file, not numpy's 0-based 8."""
    with pytest.raises(MeshFormatError, match="a face refers to vertex 9, but the file has 3 vertices"):
        load_mesh_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "obj")


def test_obj_zeros_elsewhere_are_fine() -> None:
    data = b"# f 0 1 2\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nf 1/1 2/1 3/1\nf -4 -3 -1 \n"
    V, F = load_mesh_bytes(data, "obj")
    assert len(V) == 4 and F.tolist() == [[0, 1, 2], [0, 1, 3]]


@pytest.mark.parametrize("fmt", ["obj", "off", "ply"])
@pytest.mark.parametrize(("scale", "message"), [
    (1e300, r"too large: the mesh is 1e\+300 across \(coordinates range from 0 to 1e\+300\)"),
    (1e-300, r"too small: the mesh is only 1e-300 across \(coordinates range from 0 to 1e-300\)"),
    (1e13, r"too large: .*from 1e-12 to 1e\+12 across are supported, so scale it down"),
    (1e-13, r"too small: .*so scale it up"),
])
def test_absurd_coordinate_scales_are_named(fmt: str, scale: float, message: str) -> None:
    data = save_mesh_bytes(TET_V * scale, TET_F, fmt)
    with pytest.raises(MeshError, match=message):
        load_mesh_bytes(data, fmt)


def test_a_tiny_mesh_far_from_the_origin_is_named() -> None:
    data = save_mesh_bytes(TET_V * 1e-6 + 1e5, TET_F, "ply")
    with pytest.raises(MeshError, match="too small for its distance from the origin"):
        load_mesh_bytes(data, "ply")


@pytest.mark.parametrize("scale", [1e-11, 1e11])
def test_scales_inside_the_range_load_unchanged(scale: float) -> None:
    V, F = sphere(2)
    V2, F2 = load_mesh_bytes(save_mesh_bytes(V * scale, F, "ply"), "ply")
    np.testing.assert_array_equal(V2, V * scale)
    np.testing.assert_array_equal(F2, F)


@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_studio_upload_of_absurd_scale_is_bad_mesh(scale: float) -> None:
    data = save_mesh_bytes(TET_V * scale, TET_F, "obj")
    with pytest.raises(RequestError) as info:
        load_upload(data, "tet.obj", max_vertices=1000)
    assert info.value.code == "bad_mesh" and "coordinates are too" in info.value.message


@pytest.fixture
def no_parsing(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make any full parse fail: a refusal must come from the header or a line count."""
    import arap.io.meshfile

    def parse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the file was parsed")

    monkeypatch.setattr(arap.io.meshfile, "_parse", parse)


@pytest.mark.parametrize("fmt", ["obj", "off", "ply", "stl"])
def test_too_many_vertices_refused_before_parsing(fmt: str, no_parsing: None) -> None:
    V, F = sphere(3)  # 642 vertices, 1,280 faces
    data = save_mesh_bytes(V, F, fmt)
    if fmt == "stl":
        data = _ascii_stl(V, F, b"ball") if fmt == "stl" else data
    with pytest.raises(MeshTooLargeError, match="at most 500 vertices are accepted") as info:
        load_mesh_bytes_with_report(data, fmt, max_vertices=500)
    assert info.value.count >= 640 and info.value.limit == 500


def test_binary_stl_is_counted_from_its_header(no_parsing: None) -> None:
    V, F = sphere(3)
    data = save_mesh_bytes(V, F, "stl")
    with pytest.raises(MeshTooLargeError, match="1,280 triangles"):
        load_mesh_bytes_with_report(data, "stl", max_vertices=500)


@pytest.mark.parametrize("fmt", ["obj", "off", "ply", "stl"])
def test_files_within_the_limit_still_load(fmt: str) -> None:
    V, F = sphere(3)
    V2, F2, _ = load_mesh_bytes_with_report(save_mesh_bytes(V, F, fmt), fmt, max_vertices=len(V))
    assert len(V2) == len(V) and len(F2) == len(F)
    with pytest.raises(MeshTooLargeError):
        load_mesh_bytes_with_report(save_mesh_bytes(V, F, fmt), fmt, max_vertices=len(V) - 1)


def test_upload_too_large_is_refused_before_parsing(no_parsing: None) -> None:
    V, F = sphere(3)
    with pytest.raises(RequestError) as info:
        load_upload(save_mesh_bytes(V, F, "ply"), "ball.ply", max_vertices=100)
    assert info.value.code == "too_large" and "642 vertices" in info.value.message
