"""Mesh files: round trips, file vertex order, STL welding, bytes loaders and clear errors on bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from arap.errors import MeshError, MeshFormatError
from arap.io import (
    MESH_FORMATS,
    format_of,
    load_mesh,
    load_mesh_bytes,
    load_mesh_bytes_with_report,
    load_mesh_with_report,
    save_mesh,
    save_mesh_bytes,
)
from arap.meshes.shapes import builtin_mesh, sphere


@pytest.fixture(scope="module")
def mesh() -> tuple[np.ndarray, np.ndarray]:
    """A small closed mesh with irrational coordinates (exercises printing precision)."""
    V, F = sphere(2)
    return V * np.pi + [0.1, -2.0, 3.3], F


@pytest.mark.parametrize("fmt", ["obj", "off", "ply"])
def test_exact_round_trip(tmp_path: Path, mesh: tuple[np.ndarray, np.ndarray], fmt: str) -> None:
    V, F = mesh
    path = tmp_path / f"m.{fmt}"
    save_mesh(path, V, F)
    V2, F2 = load_mesh(path)
    np.testing.assert_array_equal(V2, V)
    np.testing.assert_array_equal(F2, F)
    assert V2.dtype == np.float64 and F2.dtype == np.int64


def test_stl_soup_is_welded_back(tmp_path: Path, mesh: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = mesh
    path = tmp_path / "m.stl"
    save_mesh(path, V, F)
    raw_V, raw_F = load_mesh(path, repair=False)
    assert len(raw_V) == 3 * len(F) and len(raw_F) == len(F)  # STL stores a soup
    V2, F2, result = load_mesh_with_report(path)
    assert V2.shape == V.shape and F2.shape == F.shape
    assert result.counts["welded_vertices"] == 3 * len(F) - len(V)
    assert any("welded" in line for line in result.report)
    # Same vertices up to single precision, one loaded vertex for each original one.
    dist, match = cKDTree(V2).query(V)
    assert dist.max() < 1e-5
    assert len(np.unique(match)) == len(V)
    # Same triangles, with the same orientation.
    expected = {tuple(np.roll(f, -int(np.argmin(f)))) for f in match[F]}
    loaded = {tuple(np.roll(f, -int(np.argmin(f)))) for f in F2}
    assert loaded == expected


@pytest.mark.parametrize("fmt", MESH_FORMATS)
def test_bytes_round_trip(mesh: tuple[np.ndarray, np.ndarray], fmt: str) -> None:
    V, F = mesh
    data = save_mesh_bytes(V, F, fmt)
    assert isinstance(data, bytes) and len(data) > 100
    V2, F2 = load_mesh_bytes(data, fmt)
    assert V2.shape == V.shape and F2.shape == F.shape
    if fmt in ("glb", "gltf"):  # single precision, by the format's definition
        np.testing.assert_array_equal(V2, V.astype(np.float32))
        np.testing.assert_array_equal(F2, F)
    elif fmt != "stl":
        np.testing.assert_array_equal(V2, V)


def test_bytes_loader_report_and_type_spellings(mesh: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = mesh
    data = save_mesh_bytes(V, F, "model.OBJ")
    for spelling in ("obj", ".obj", "OBJ", "upload.obj"):
        V2, F2, result = load_mesh_bytes_with_report(data, spelling)
        np.testing.assert_array_equal(V2, V)
        np.testing.assert_array_equal(F2, F)
        assert result.report == []


@pytest.mark.parametrize(
    ("name", "n_vertices", "n_faces"),
    [("armadillo.obj", 43_243, 86_482), ("camelhead.off", 11_381, 22_704), ("decimated-knight.off", 502, 1_000)],
)
def test_shared_meshes_keep_file_vertex_order(shared_meshes_dir: Path, name: str, n_vertices: int,
                                              n_faces: int) -> None:
    path = shared_meshes_dir / name
    V, F, result = load_mesh_with_report(path)
    assert V.shape == (n_vertices, 3) and F.shape == (n_faces, 3)
    assert result.report == []
    # The first vertex lines of the file, in order.
    text = path.read_text().splitlines()
    if name.endswith(".obj"):
        rows = [line.split()[1:4] for line in text if line.startswith("v ")][:5]
    else:
        rows = [line.split()[:3] for line in text[2:7]]
    np.testing.assert_array_equal(V[:5], np.array(rows, dtype=float))
    np.testing.assert_array_equal(load_mesh(path, repair=False)[0], V)


def test_polygons_are_triangulated(tmp_path: Path) -> None:
    off = "OFF\n5 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 1.5 0\n5 0 1 2 4 3\n"
    V, F = load_mesh_bytes(off.encode(), "off")
    assert F.shape == (3, 3) and len(V) == 5
    obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
    V, F, result = load_mesh_bytes_with_report(obj.encode(), "obj")
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3]])
    assert result.counts["triangulated_polygons"] == 0  # the parser already split the quad


def test_ply_polygons_are_triangulated() -> None:
    header = ("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
              "element face 2\nproperty list uchar int vertex_indices\nend_header\n")
    body = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 1.5 0\n4 0 1 2 3\n4 3 2 4 0\n"
    V, F = load_mesh_bytes((header + body).encode(), "ply")
    assert len(V) == 5
    assert sorted(map(tuple, F.tolist())) == [(0, 1, 2), (0, 2, 3), (3, 2, 4), (3, 4, 0)]


def test_obj_with_texture_coordinates_keeps_vertex_order() -> None:
    obj = (
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\nvn 0 0 1\n"
        "f 4/1/1 1/2/1 2/3/1\nf 4/5/1 2/2/1 3/4/1\n"
    )
    V, F = load_mesh_bytes(obj.encode(), "obj")
    np.testing.assert_array_equal(V, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_array_equal(F, [[3, 0, 1], [3, 1, 2]])


def test_obj_groups_share_vertices() -> None:
    obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng a\nusemtl red\nf 1 2 3\ng b\nusemtl blue\nf 1 3 4\n"
    V, F = load_mesh_bytes(obj.encode(), "obj")
    assert len(V) == 4
    assert sorted(map(tuple, F.tolist())) == [(0, 1, 2), (0, 2, 3)]


def test_builtin_mesh_survives_every_format(tmp_path: Path) -> None:
    V, F = builtin_mesh("cactus")
    for fmt in MESH_FORMATS:
        path = tmp_path / f"cactus.{fmt}"
        save_mesh(path, V, F)
        V2, F2 = load_mesh(path)
        assert V2.shape == V.shape and F2.shape == F.shape, fmt


# ---------------------------------------------------------------------------------------------- errors
def test_unknown_extension(tmp_path: Path, mesh: tuple[np.ndarray, np.ndarray]) -> None:
    with pytest.raises(MeshFormatError, match=r"unsupported mesh format 'xyz'.*obj, off, ply, stl"):
        load_mesh(tmp_path / "a.xyz")
    with pytest.raises(MeshFormatError, match="unsupported mesh format 'readme'"):
        format_of("README")
    assert format_of("C:\\models\\Bunny.PLY") == "ply"
    with pytest.raises(MeshFormatError, match="unsupported"):
        save_mesh(tmp_path / "a.fbx", *mesh)
    with pytest.raises(MeshFormatError, match="unsupported"):
        load_mesh_bytes(b"", "exe")


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MeshFormatError, match="cannot read"):
        load_mesh(tmp_path / "nothing.obj")


@pytest.mark.parametrize(
    ("data", "fmt", "message"),
    [
        (b"garbage", "off", "cannot parse"),
        (b"garbage", "ply", "not a PLY file"),
        (b"", "obj", "no vertices"),
        (b"", "stl", "no vertices"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", "obj", "no faces"),
        (b"OFF\n3 0 0\n0 0 0\n1 0 0\n1 1 0\n", "off", "no faces"),
        (b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "off", "or a truncated file"),
    ],
)
def test_bad_content(data: bytes, fmt: str, message: str) -> None:
    with pytest.raises(MeshFormatError, match=message):
        load_mesh_bytes(data, fmt)


@pytest.mark.parametrize("fmt", ["off", "ply"])
def test_a_truncated_file_is_refused_not_loaded_with_faces_missing(mesh: tuple[np.ndarray, np.ndarray],
                                                                    fmt: str) -> None:
    """A file cut inside its last face loses that face without a word from the parser: fewer faces than its
    header announces is refused as truncated."""
    V, F = mesh
    if fmt == "off":
        data = save_mesh_bytes(V, F, "off")
    else:  # an ASCII PLY, whose parser reads what is there (a binary one is refused for its length)
        header = (f"ply\nformat ascii 1.0\nelement vertex {len(V)}\nproperty double x\nproperty double y\n"
                  f"property double z\nelement face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
        vertices = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
        data = (header + vertices + "".join(f"3 {a} {b} {c}\n" for a, b, c in F.tolist())).encode()
    assert len(load_mesh_bytes(data, fmt)[1]) == len(F)
    cut = data[:data.rstrip().rfind(b" ")]  # the last face loses its last index
    with pytest.raises(MeshFormatError, match=rf"header announces {len(F):,} faces, but only {len(F) - 1:,} could "
                                              r"be read \(a truncated file\?\)"):
        load_mesh_bytes(cut, fmt)


def test_an_obj_cut_inside_a_vertex_line_is_a_format_error() -> None:
    """Two coordinates on the last line: a mesh format error saying the file ends early, not numpy's reshape
    error."""
    with pytest.raises(MeshFormatError, match=r"cannot parse .* as OBJ: the file ends early"):
        load_mesh_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 0 0.", "obj")


@pytest.mark.parametrize("last", [b"f 2 4", b"f 2/1/1 4/1/1\r", b"  f 2", b"f", b"f 2 4 # cut"])
def test_an_obj_face_of_fewer_than_three_vertices_is_refused_not_dropped(last: bytes) -> None:
    """A file cut inside its last face line: the parser would drop the short face without a word (3 of the 4
    triangles loaded); the error names the line."""
    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 1 3 4\n" + last
    with pytest.raises(MeshFormatError, match=r"mesh\.obj, line 8: a face with fewer than 3 vertices"):
        load_mesh_bytes_with_report(data, "obj", name="mesh.obj")
    # Whole faces, polygons, indented lines and texture/normal indices load.
    whole = b"v 2 0 0\nv 2 1 0\n  f 2/1/1 5/1/1 6/1/1\nf 5 6 4 2\n"
    V, F = load_mesh_bytes(data[: -len(last)] + whole, "obj", repair=False)
    assert len(V) == 6 and len(F) == 6


@pytest.mark.parametrize("lines", [b"  f 2 5 6\nf 5 6 4 2\n", b"f 2 5 6\n\tf 5 6 4 2\n",
                                   b"f 2 5 6 # side\nf 5 6 4 2#quad\n# end\n"])
def test_indented_or_commented_face_lines_load_beside_polygons(lines: bytes) -> None:
    """An indented face line in a file with a polygon: every face loads (the general parser dropped it); a comment
    after a face is a comment (it failed to parse)."""
    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nv 2 0 0\nv 2 1 0\n" + lines
    V, F = load_mesh_bytes(data, "obj", repair=False)
    assert len(V) == 6
    assert sorted(map(tuple, F.tolist())) == [(0, 1, 2), (1, 3, 2), (1, 4, 5), (3, 1, 4), (4, 5, 3)]


def test_bad_file_on_disk_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.off"
    path.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    with pytest.raises(MeshFormatError, match=r"broken\.off"):
        load_mesh(path)


def test_unrepairable_content_is_a_mesh_error() -> None:
    obj = b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"
    with pytest.raises(MeshError, match="cannot be repaired"):
        load_mesh_bytes(obj, "obj")


def test_save_rejects_bad_arrays(tmp_path: Path) -> None:
    with pytest.raises(MeshError, match="shape"):
        save_mesh(tmp_path / "a.obj", np.zeros((3, 2)), [[0, 1, 2]])
    with pytest.raises(MeshError, match="out of range"):
        save_mesh(tmp_path / "a.obj", np.zeros((3, 3)), [[0, 1, 3]])
    for ext in ("obj", "off", "ply", "stl"):  # a file with NaN would not load again
        with pytest.raises(MeshError, match="1 vertices have NaN or infinite coordinates \\(vertex 2"):
            save_mesh(tmp_path / f"a.{ext}", np.array([[0.0, 0, 0], [1, 0, 0], [0, np.nan, 0]]), [[0, 1, 2]])
    assert not list(tmp_path.iterdir())


def test_a_folder_is_not_a_mesh_file(tmp_path: Path) -> None:
    (tmp_path / "scans.obj").mkdir()
    with pytest.raises(MeshFormatError, match="is a folder, not a mesh file"):
        load_mesh(tmp_path / "scans.obj")


def test_binary_ply_with_polygons_of_several_sizes() -> None:
    """trimesh's parser refuses a binary PLY whose faces are quads and triangles; it loads."""
    header = (b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
              b"property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n")
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 1.5, 0]], dtype="<f4")
    body = V.tobytes() + bytes([4]) + np.array([0, 1, 2, 3], "<i4").tobytes()
    body += bytes([3]) + np.array([3, 2, 4], "<i4").tobytes()
    V2, F2 = load_mesh_bytes(header + body, "ply")
    np.testing.assert_array_equal(V2, V.astype(np.float64))
    assert sorted(map(tuple, F2.tolist())) == [(0, 1, 2), (2, 3, 0), (3, 2, 4)]
    with pytest.raises(MeshFormatError, match="PLY"):
        load_mesh_bytes(header + body[:-3], "ply")


# ---------------------------------------------------------------------------------------------- the format registry
def test_every_format_list_comes_from_the_registry() -> None:
    from arap.cli import build_parser
    from arap.io import ASSET_FORMATS, VOLUME_FORMATS, formats
    from arap.server import messages
    from arap.server.mesh_model import EXPORT_MIME
    from arap.server.pictures import PICTURE_EXTENSIONS

    assert MESH_FORMATS == formats.names("surface") == ("obj", "off", "ply", "stl", "glb", "gltf")
    assert ASSET_FORMATS == formats.names("surface", asset=True)
    assert VOLUME_FORMATS == tuple(s[1:] for s in formats.suffixes("volume"))
    assert messages.UPLOAD_EXTENSIONS == formats.upload_suffixes()
    assert messages.EXPORT_FORMATS == formats.export_names()
    assert PICTURE_EXTENSIONS == formats.suffixes("picture")
    assert EXPORT_MIME == {"obj": "model/obj", "ply": "application/octet-stream", "glb": "model/gltf-binary"}
    assert {formats.get(name).mime for name in EXPORT_MIME} <= set(formats.mime_types().values())
    # The command line's help names every surface and volume extension, once each list.
    help_text = " ".join(build_parser().format_help().split())
    assert " ".join(formats.suffixes("surface")) in help_text and " ".join(formats.suffixes("volume")) in help_text
    # Every function a record names exists.
    for fmt in formats.FORMATS:
        for role in ("reader", "writer", "screen", "vertex_count", "face_count"):
            if getattr(fmt, role):
                assert callable(fmt.function(role)), (fmt.name, role)


def test_the_registry_finds_a_format_by_name_suffix_or_file_name() -> None:
    from arap.io import formats

    assert formats.get("Model.OBJ").name == formats.get(".obj").name == formats.get("obj").name == "obj"
    assert formats.get("bar.ELE").name == formats.get("bar.node").name == "tetgen"
    assert formats.get("photo.jpeg").kind == "picture" and formats.get("photo.jpeg").mime == "image/jpeg"
    assert formats.find("bar.msh", "surface") is None
    with pytest.raises(MeshFormatError, match="unsupported surface format 'msh'"):
        formats.get("bar.msh", "surface")


def _marked_off(V: np.ndarray, F: np.ndarray) -> bytes:
    """An OFF writer that marks its files (for the registry test)."""
    from arap.io.meshfile import off_bytes

    return b"# marked\n" + off_bytes(V, F)


def test_readers_and_writers_are_the_registrys(monkeypatch: pytest.MonkeyPatch) -> None:
    """save_mesh_bytes and load_mesh_bytes pick a format's writer and reader through its record: a record naming
    other functions is what they call."""
    import dataclasses

    from arap.io import formats

    off = formats.get("off")
    V, F = builtin_mesh("bar")
    plain = save_mesh_bytes(V, F, "off")
    monkeypatch.setitem(formats._BY_NAME, "off", dataclasses.replace(off, writer=f"{__name__}:_marked_off",
                                                                     reader="arap.io.meshfile:read_stl"))
    assert save_mesh_bytes(V, F, "off") == b"# marked\n" + plain
    with pytest.raises(MeshFormatError, match="not an STL file"):  # the STL reader given OFF text
        load_mesh_bytes(plain, "off")
