"""Textured models in and out: every attribute but positions and normals comes back bit-identical, vertices keep the
file's numbering, seams are welded for the solve and split again, and bad files are refused clearly."""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.errors import ConstraintError, MeshError, MeshFormatError, MeshTooLargeError
from arap.io import MeshAsset, load_asset, load_asset_bytes, load_mesh, load_mesh_with_report, save_asset, save_mesh
from arap.io.assets import weld_rows
from arap.io.gltf_asset import accessor_array
from tests.io.asset_models import (
    FACE_NORMALS,
    cube_glb,
    cube_gltf,
    cube_gltf_document,
    cube_obj,
    cube_ply,
    glb_bytes,
    png,
)


def _rotation(angle: float = 0.7) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _same(a: Any, b: Any) -> bool:
    """Bit-identical arrays (NaN equal to NaN), or equal values."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return bool(a == b)


# ---------------------------------------------------------------------------------------------- OBJ
OBJ_FIELDS = ("vertex_extra", "texcoords", "face_sizes", "corner_vertices", "corner_texcoords", "polygon_materials",
              "polygon_groups", "polygon_objects", "polygon_smoothing", "objects", "smoothing", "statements")


def test_obj_round_trip_keeps_every_attribute(tmp_path: Path) -> None:
    asset = load_asset(cube_obj(tmp_path))
    assert asset.format == "obj" and asset.vertices.shape == (8, 3) and asset.faces.shape == (12, 3)
    assert asset.materials == ["red", "blue"] and asset.groups == ["front back", "sides"]
    assert asset.data.objects == ["box"] and asset.data.smoothing == ["1"]
    assert sorted(asset.textures) == ["tex/bump.png", "tex/checker.png"]
    assert asset.uvs is not None and asset.uvs.shape == (12, 3, 2)
    assert asset.data.statements == ["l 1 7"]
    # A rigid motion: positions move, normals turn with them.
    R = _rotation()
    moved = asset.vertices @ R.T + [3.0, -1.0, 0.5]
    out = tmp_path / "out"
    out.mkdir()
    written = save_asset(out / "moved.obj", asset, moved)
    assert [p.name for p in written] == ["moved.obj", "moved.mtl", "checker.png", "bump.png"]
    back = load_asset(out / "moved.obj")
    assert _same(back.vertices, moved)
    for name in ("faces", "face_materials", "face_groups", "uvs"):
        assert _same(getattr(back, name), getattr(asset, name)), name
    assert back.materials == asset.materials and back.groups == asset.groups
    for name in OBJ_FIELDS:
        assert _same(getattr(back.data, name), getattr(asset.data, name)), name
    assert back.textures == asset.textures
    assert (out / "moved.mtl").read_bytes() == (tmp_path / "cube.mtl").read_bytes()
    assert back.data.mtllibs == ["moved.mtl"]
    # Each corner's normal: its face's normal, turned (a flat-shaded cube stays flat).
    old = asset.data.normals[asset.data.corner_normals]
    new = back.data.normals[back.data.corner_normals]
    np.testing.assert_allclose(new, old @ R.T, atol=1e-12)


def test_obj_saved_as_it_is_keeps_positions_and_normals(tmp_path: Path) -> None:
    asset = load_asset(cube_obj(tmp_path))
    save_asset(tmp_path / "same.obj", asset)
    back = load_asset(tmp_path / "same.obj")
    assert _same(back.vertices, asset.vertices)
    assert _same(back.data.normals, asset.data.normals) and _same(back.data.corner_normals, asset.data.corner_normals)


def test_obj_normals_shared_across_vertices_are_split_per_vertex(tmp_path: Path) -> None:
    """One ``vn`` for every corner (a writer that deduplicates normals): after a deformation each vertex gets its
    own smooth normal."""
    V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0]])
    faces = "f 1//1 2//1 5//1\nf 2//1 3//1 5//1\nf 3//1 4//1 5//1\nf 4//1 1//1 5//1\n"
    text = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist()) + "vn 0 0 1\n" + faces
    (tmp_path / "fan.obj").write_text(text)
    asset = load_asset(tmp_path / "fan.obj")
    bent = asset.vertices.copy()
    bent[4, 2] = 0.5  # a tent: the corner normals tilt outwards, the apex stays vertical
    save_asset(tmp_path / "bent.obj", asset, bent)
    back = load_asset(tmp_path / "bent.obj")
    assert len(back.data.normals) == 5
    apex = back.data.normals[back.data.corner_normals[back.data.corner_vertices == 4][0]]
    np.testing.assert_allclose(apex, [0, 0, 1], atol=1e-12)
    corner = back.data.normals[back.data.corner_normals[back.data.corner_vertices == 0][0]]
    assert corner[2] > 0 and corner[0] < 0 and corner[1] < 0
    np.testing.assert_allclose(np.linalg.norm(back.data.normals, axis=1), 1.0)


def test_textured_obj_loads_in_file_numbering_and_constraints_hit_file_vertices(tmp_path: Path) -> None:
    """Per-corner UVs, normals, groups and materials do not renumber the ``v`` lines (they used to be split by UV
    corner and welded again); constraint indices name the file's vertices."""
    from arap import ArapSolver
    from arap.meshes.shapes import sphere

    V, F = sphere(2)
    rng = np.random.default_rng(3)
    lines = ["mtllib ball.mtl"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in V.tolist()]
    lines += [f"vt {u!r} {v!r}" for u, v in rng.random((3 * len(F), 2)).tolist()]  # a UV per corner: all seams
    lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in V.tolist()]
    for k, (a, b, c) in enumerate(F.tolist()):
        if k == 0:
            lines += ["g top", "usemtl skin"]
        if k == len(F) // 2:
            lines += ["g bottom", "usemtl cloth"]
        lines.append(f"f {a + 1}/{3 * k + 1}/{a + 1} {b + 1}/{3 * k + 2}/{b + 1} {c + 1}/{3 * k + 3}/{c + 1}")
    path = tmp_path / "ball.obj"
    path.write_text("\n".join(lines) + "\n")
    (tmp_path / "ball.mtl").write_text("newmtl skin\nnewmtl cloth\n")
    V2, F2, report = load_mesh_with_report(path)
    assert _same(V2, V) and _same(F2, F) and report.report == []
    asset = load_asset(path)
    assert _same(asset.vertices, V) and _same(asset.faces, F)
    idx = np.array([0, 5, 17, 40])
    targets = V[idx] + [0.0, 0.0, 0.3]
    solve = asset.solve_mesh()
    assert _same(solve.V, V)  # nothing to weld: the OBJ shares its vertices
    handles, goals = solve.constraints(idx, targets)
    result = ArapSolver(solve.V, solve.F, handles).solve(goals)
    np.testing.assert_allclose(result.vertices[idx], targets, atol=1e-12)
    written = save_asset(tmp_path / "out.obj", asset, result.vertices)
    back = load_asset(written[0])
    assert _same(back.vertices[idx], result.vertices[idx]) and _same(back.uvs, asset.uvs)


def test_missing_texture_and_material_files_warn_and_the_mesh_still_loads_and_writes(tmp_path: Path) -> None:
    path = cube_obj(tmp_path, texture=False)
    with pytest.warns(UserWarning) as caught:
        asset = load_asset(path)
    assert sorted(str(w.message).split(": ", 1)[1] for w in caught) == [
        "the texture 'tex/bump.png' named in 'cube.mtl' cannot be read; its reference is kept",
        "the texture 'tex/checker.png' named in 'cube.mtl' cannot be read; its reference is kept"]
    assert asset.textures == {} and asset.uvs is not None
    save_asset(tmp_path / "again.obj", asset, asset.vertices * 2)
    assert (tmp_path / "again.mtl").read_bytes() == (tmp_path / "cube.mtl").read_bytes()
    (tmp_path / "cube.mtl").unlink()
    with pytest.warns(UserWarning, match=r"material file 'cube\.mtl' cannot be read"):
        asset = load_asset(path)
    save_asset(tmp_path / "third.obj", asset)
    assert "mtllib cube.mtl" in (tmp_path / "third.obj").read_text()  # the reference is kept


# ---------------------------------------------------------------------------------------------- PLY
def test_ply_round_trip_keeps_colours_uvs_and_other_properties(tmp_path: Path) -> None:
    asset = load_asset(cube_ply(tmp_path))
    assert asset.vertices.shape == (24, 3) and asset.faces.shape == (12, 3)
    assert asset.vertex_colors is not None and asset.vertex_colors.dtype == np.uint8
    assert list(asset.textures) == ["checker.png"]
    solve = asset.solve_mesh()
    assert len(solve.V) == 8  # 24 seam copies of 8 corners
    R = _rotation(1.1)
    moved = solve.V @ R.T
    out = tmp_path / "out"
    out.mkdir()
    assert [p.name for p in save_asset(out / "c.ply", asset, moved)] == ["c.ply", "checker.png"]
    back = load_asset(out / "c.ply")
    assert _same(back.vertices, solve.file_vertices(moved))
    for name in ("faces", "uvs", "vertex_colors"):
        assert _same(getattr(back, name), getattr(asset, name)), name
    assert back.data.comments == asset.data.comments
    old_vertex, new_vertex = asset.data.element("vertex"), back.data.element("vertex")
    for prop in ("red", "green", "blue", "s", "t"):
        assert _same(new_vertex.data[prop], old_vertex.data[prop]), prop
    for prop in ("vertex_indices", "flags"):
        assert _same(back.data.element("face").data[prop], asset.data.element("face").data[prop]), prop
    normals = np.stack([new_vertex.data[k] for k in ("nx", "ny", "nz")], axis=1)
    expected = np.repeat(FACE_NORMALS, 4, axis=0) @ R.T  # hard edges stay hard: one normal per face corner
    np.testing.assert_allclose(normals, expected, atol=1e-6)
    assert normals.dtype == np.float32


# ---------------------------------------------------------------------------------------------- glTF
def _normals_in_scene(asset: MeshAsset) -> np.ndarray:
    """Unit normals of every file vertex in scene coordinates (node transforms applied)."""
    gltf = asset.data
    out = np.zeros((len(asset.vertices), 3))
    for pos, normal in gltf.normals:
        k = gltf.positions.index(pos)
        local = accessor_array(gltf.document, gltf.buffers, normal, "test").astype(np.float64)
        world = local @ np.linalg.inv(gltf.transforms[k][:3, :3])  # (M^-T n)ᵀ = nᵀ M^-1
        out[gltf.offsets[k]:gltf.offsets[k] + len(local)] = world / np.linalg.norm(world, axis=1)[:, None]
    return out


def _position_ranges(asset: MeshAsset) -> list[tuple[int, int, int]]:
    gltf = asset.data
    ranges = []
    for acc_index in gltf.positions + [n for _, n in gltf.normals]:
        acc = gltf.document["accessors"][acc_index]
        view = gltf.document["bufferViews"][acc["bufferView"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        ranges.append((view["buffer"], start, start + 12 * acc["count"]))
    return ranges


def _without_positions(asset: MeshAsset) -> list[bytes]:
    """The buffers with the POSITION and NORMAL bytes blanked."""
    buffers = [bytearray(b) for b in asset.data.buffers]
    for buffer, start, end in _position_ranges(asset):
        buffers[buffer][start:end] = b"\0" * (end - start)
    return [bytes(b) for b in buffers]


def _document_without_bounds(asset: MeshAsset) -> dict[str, Any]:
    document = json.loads(json.dumps(asset.data.document))
    for pos in asset.data.positions:
        document["accessors"][pos].pop("min", None)
        document["accessors"][pos].pop("max", None)
    document["buffers"] = [{"byteLength": b["byteLength"]} for b in document["buffers"]]
    return document


def test_glb_with_embedded_texture_round_trip(tmp_path: Path) -> None:
    path = cube_glb(tmp_path)
    asset = load_asset(path)
    assert asset.format == "glb" and asset.vertices.shape == (24, 3) and asset.faces.shape == (12, 3)
    assert asset.materials == ["red", "textured"] and asset.groups == ["half0", "half1"]
    assert asset.face_materials.tolist() == [0] * 6 + [1] * 6
    assert list(asset.textures) == ["checker"] and asset.textures["checker"] == png(8, 8, 4)
    assert asset.vertex_colors is not None and asset.vertex_colors.shape == (24, 4)
    # The second mesh's node is turned, scaled by 2 and moved: its vertices are in scene coordinates.
    assert np.abs(asset.vertices[12:]).max() > 2.5
    solve = asset.solve_mesh()
    assert solve.V.shape == (16, 3) and solve.F.shape == (12, 3)  # 24 seam copies, 8 corners per half
    R = _rotation(0.4)
    moved = solve.V @ R.T + [0.0, 2.0, 0.0]
    save_asset(tmp_path / "moved.glb", asset, moved)
    back = load_asset(tmp_path / "moved.glb")
    np.testing.assert_allclose(back.vertices, solve.file_vertices(moved), atol=1e-5)
    for name in ("faces", "uvs", "vertex_colors", "face_materials", "face_groups"):
        assert _same(getattr(back, name), getattr(asset, name)), name
    assert back.textures == asset.textures
    assert _without_positions(back) == _without_positions(asset)
    assert _document_without_bounds(back) == _document_without_bounds(asset)
    for pos in back.data.positions:  # the bounds follow the positions
        local = accessor_array(back.data.document, back.data.buffers, pos, "test")
        assert back.data.document["accessors"][pos]["max"] == [float(x) for x in local.max(axis=0)]
    np.testing.assert_allclose(_normals_in_scene(back), _normals_in_scene(asset) @ R.T, atol=1e-6)


def test_glb_saved_unchanged_and_normals_recomputed_on_the_rest_shape(tmp_path: Path) -> None:
    asset = load_asset(cube_glb(tmp_path))
    save_asset(tmp_path / "same.glb", asset)
    assert load_asset(tmp_path / "same.glb").data.buffers == asset.data.buffers
    save_asset(tmp_path / "rest.glb", asset, asset.vertices)  # the seams keep hard edges: the cube stays flat
    back = load_asset(tmp_path / "rest.glb")
    np.testing.assert_allclose(_normals_in_scene(back), _normals_in_scene(asset), atol=1e-6)
    np.testing.assert_allclose(back.vertices, asset.vertices, atol=1e-6)


def test_gltf_with_external_buffer_and_image_and_conversions(tmp_path: Path) -> None:
    path = cube_gltf(tmp_path)
    asset = load_asset(path)
    assert asset.format == "gltf" and list(asset.textures) == ["images/checker one.png"]
    out = tmp_path / "out"
    out.mkdir()
    moved = asset.vertices * 1.5
    written = save_asset(out / "m.gltf", asset, moved)
    assert [p.relative_to(out).as_posix() for p in written] == ["m.gltf", "m.bin", "images/checker one.png"]
    back = load_asset(out / "m.gltf")
    np.testing.assert_allclose(back.vertices, moved, atol=1e-5)
    assert back.textures == asset.textures and _same(back.uvs, asset.uvs)
    assert _without_positions(back) == _without_positions(asset)
    as_glb = load_asset(save_asset(out / "m.glb", back)[0])
    assert as_glb.format == "glb" and _same(as_glb.vertices, back.vertices) and _same(as_glb.uvs, back.uvs)
    as_gltf = load_asset(save_asset(out / "again.gltf", as_glb)[0])
    assert _same(as_gltf.vertices, back.vertices) and as_gltf.data.document["buffers"][0]["uri"] == "again.bin"
    embedded = load_asset(cube_gltf(tmp_path, "inline", embedded=True))
    save_asset(out / "inline.gltf", embedded, embedded.vertices + 1)
    assert load_asset(out / "inline.gltf").data.document["buffers"][0]["uri"].startswith("data:")


def test_load_mesh_and_save_mesh_take_gltf(tmp_path: Path) -> None:
    path = cube_glb(tmp_path)
    V, F, report = load_mesh_with_report(path)
    assert V.shape == (16, 3) and F.shape == (12, 3)  # repair welds the seams
    assert report.vertex_map.shape == (24,)
    V2, _ = load_mesh(path, repair=False)
    assert V2.shape == (24, 3)
    save_mesh(tmp_path / "plain.glb", V, F)
    np.testing.assert_array_equal(load_mesh(tmp_path / "plain.glb")[0], V.astype(np.float32))
    asset = load_asset(path)
    save_mesh(tmp_path / "kept.glb", asset)  # an asset keeps its attributes
    assert load_asset(tmp_path / "kept.glb").textures == asset.textures
    save_mesh(tmp_path / "geometry.off", asset)  # in another format, its geometry
    assert load_mesh(tmp_path / "geometry.off", repair=False)[0].shape == (24, 3)
    gltf = cube_gltf(tmp_path)
    assert load_mesh(gltf)[0].shape == (16, 3)  # the external buffer is found beside the file


# ---------------------------------------------------------------------------------------------- seams
def test_seam_constraints_take_file_numbering(tmp_path: Path) -> None:
    asset = load_asset(cube_ply(tmp_path))
    solve = asset.solve_mesh()
    copies = np.flatnonzero(solve.to_solve == solve.to_solve[0])
    assert len(copies) == 3  # a cube corner: three faces, three copies
    handles, goals = solve.constraints(copies, np.zeros((3, 3)))
    assert handles.tolist() == [solve.to_solve[0]] and goals is not None and goals.shape == (1, 3)
    with pytest.raises(ConstraintError, match=r"one vertex .* different targets"):
        solve.constraints(copies, np.eye(3))
    with pytest.raises(ConstraintError, match="out of range"):
        solve.constraints([24])
    with pytest.raises(MeshError, match="positions given"):
        save_asset(tmp_path / "x.ply", asset, np.zeros((5, 3)))


def test_weld_rows_matches_unique() -> None:
    rng = np.random.default_rng(0)
    A = rng.integers(0, 4, size=(2000, 3)).astype(np.float64)
    inverse, first = weld_rows(A)
    _, ref_first, ref_inverse = np.unique(A, axis=0, return_index=True, return_inverse=True)
    assert np.array_equal(first, np.sort(ref_first))
    assert np.array_equal(A[first][inverse], A)
    assert len(set(zip(inverse.tolist(), ref_inverse.reshape(-1).tolist(), strict=True))) == len(first)
    assert np.all(np.diff(first) > 0) and inverse[0] == 0


# ---------------------------------------------------------------------------------------------- refusals
def _glb_with(change: Any) -> bytes:
    document, blob = cube_gltf_document(png())
    change(document)
    return glb_bytes(document, blob)


@pytest.mark.parametrize("name", ["KHR_draco_mesh_compression", "EXT_meshopt_compression"])
def test_compressed_gltf_is_refused_by_name(name: str) -> None:
    data = _glb_with(lambda d: d.update(extensionsUsed=[name], extensionsRequired=[name]))
    with pytest.raises(MeshFormatError, match=rf"compressed glTF \({name}\) is not supported"):
        load_asset_bytes(data, "glb")


def test_points_and_lines_only_are_refused_and_kept_beside_triangles(tmp_path: Path) -> None:
    def lines_only(document: dict[str, Any]) -> None:
        for mesh in document["meshes"]:
            for prim in mesh["primitives"]:
                prim["mode"] = 1

    with pytest.raises(MeshFormatError, match=r"no triangle primitives \(it holds only lines\)"):
        load_asset_bytes(_glb_with(lines_only), "glb")
    asset = load_asset(cube_glb(tmp_path))  # the lines primitive beside triangles is written back untouched
    lines = asset.data.document["meshes"][1]["primitives"][1]
    save_asset(tmp_path / "b.glb", asset, asset.vertices * 3)
    back = load_asset(tmp_path / "b.glb")
    assert back.data.document["meshes"][1]["primitives"][1] == lines
    assert _same(accessor_array(back.data.document, back.data.buffers, lines["indices"], "t"),
                 accessor_array(asset.data.document, asset.data.buffers, lines["indices"], "t"))


def test_malformed_gltf_is_a_format_error() -> None:
    good = _glb_with(lambda d: None)
    with pytest.raises(MeshFormatError, match="truncated"):
        load_asset_bytes(good[:-100], "glb")
    with pytest.raises(MeshFormatError, match="reads past the end of its buffer"):
        load_asset_bytes(_glb_with(lambda d: d["accessors"][0].update(count=10_000)), "glb")
    with pytest.raises(MeshFormatError, match="refers to bufferView 99"):
        load_asset_bytes(_glb_with(lambda d: d["accessors"][0].update(bufferView=99)), "glb")
    with pytest.raises(MeshFormatError, match="JSON document is malformed"):
        load_asset_bytes(good[:20] + b"}" + good[21:], "glb")
    with pytest.raises(MeshFormatError, match="sparse"):
        load_asset_bytes(_glb_with(lambda d: d["accessors"][0].update(sparse={"count": 1})), "glb")
    with pytest.raises(MeshFormatError, match="quantized"):
        load_asset_bytes(_glb_with(lambda d: d["accessors"][0].update(componentType=5123)), "glb")
    with pytest.raises(MeshFormatError, match="refers to vertex 11, but its POSITION accessor has 11"):
        load_asset_bytes(_glb_with(lambda d: d["accessors"][0].update(count=11)), "glb")
    with pytest.raises(MeshFormatError, match=r"buffer 0 .* cannot be read"):
        load_asset_bytes(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "gone.bin",
                                                                              "byteLength": 4}]}).encode(), "gltf")
    with pytest.raises(MeshFormatError, match="GLB version 1"):
        load_asset_bytes(struct.pack("<4sII", b"glTF", 1, 20) + b"\0" * 8, "glb")
    with pytest.raises(MeshTooLargeError):
        load_asset_bytes(good, "glb", max_vertices=20)


def test_writing_refuses_other_formats_and_special_destinations(tmp_path: Path) -> None:
    asset = load_asset(cube_glb(tmp_path))
    with pytest.raises(MeshFormatError, match="written as GLB or glTF"):
        save_asset(tmp_path / "x.obj", asset)
    (tmp_path / "folder.glb").mkdir()
    with pytest.raises(MeshFormatError, match=r"cannot write .*folder"):
        save_asset(tmp_path / "folder.glb", asset)
    with pytest.raises(MeshError, match="NaN"):
        save_asset(tmp_path / "nan.glb", asset, np.full((24, 3), np.nan))


def test_obj_reader_handles_mixed_corners_relative_indices_and_continued_lines() -> None:
    text = ("v 0 0 0 # origin\nv 1 0 0\n  v 1 1 0\nv 0 1 0\nv 0.5 0.5 1 \\\n\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
            "usemtl a\nf 1/1/1 2//1 3/3\nf -5/-3 -2/-1/-1 4\n\tf 1 4 5 3 2 # a pentagon\ng\nusemtl\nf 2/0/1 5/1/9 3\n")
    asset = load_asset_bytes(text.encode(), "obj")
    obj = asset.data
    assert obj.face_sizes.tolist() == [3, 3, 5, 3]
    assert obj.corner_vertices.tolist() == [0, 1, 2, 0, 3, 3, 0, 3, 4, 2, 1, 1, 4, 2]
    assert obj.corner_texcoords.tolist() == [0, -1, 2, 0, 2, -1, -1, -1, -1, -1, -1, -1, 0, -1]
    assert obj.corner_normals.tolist() == [0, 0, -1, -1, 0, -1, -1, -1, -1, -1, -1, 0, -1, -1]
    assert asset.materials == ["a"] and asset.face_materials.tolist() == [0, 0, 0, 0, 0, -1]
    assert asset.faces.tolist() == [[0, 1, 2], [0, 3, 3], [0, 3, 4], [0, 4, 2], [0, 2, 1], [1, 4, 2]]
    assert _same(asset.vertices[4], np.array([0.5, 0.5, 1.0]))
    with pytest.raises(MeshFormatError, match="line 2: a face names vertex -3, but only 1 come before it"):
        load_asset_bytes(b"v 0 0 0\nf 1 -3 1\nv 1 1 1\n", "obj")
    with pytest.raises(MeshFormatError, match=r"line 1: vertex '1 x 2' is not a list of numbers"):
        load_asset_bytes(b"v 1 x 2\nv 0 0 0\nv 1 1 1\nf 1 2 3\n", "obj")


def test_binary_ply_with_polygons_and_corner_texcoords_round_trip(tmp_path: Path) -> None:
    """Big-endian, a quad and a triangle (lists of two lengths), texture coordinates per corner."""
    header = (b"ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
              b"property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 2\n"
              b"property list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n")
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 1.5, 0.25]], dtype=">f4")
    body = b"".join(v.tobytes() + bytes([10 * i, 20 * i, 30 * i]) for i, v in enumerate(V))
    quad, tri = [0, 1, 2, 3], [3, 2, 4]
    quad_uv = (np.arange(8) / 8).astype(">f4")
    tri_uv = (np.arange(6) / 6 + 0.01).astype(">f4")
    body += bytes([4]) + np.array(quad, ">i4").tobytes() + bytes([8]) + quad_uv.tobytes()
    body += bytes([3]) + np.array(tri, ">i4").tobytes() + bytes([6]) + tri_uv.tobytes()
    (tmp_path / "poly.ply").write_bytes(header + body)
    asset = load_asset(tmp_path / "poly.ply")
    assert asset.faces.tolist() == [[0, 1, 2], [2, 3, 0], [3, 2, 4]]
    assert asset.uvs is not None
    np.testing.assert_array_equal(asset.uvs[2], tri_uv.astype(np.float64).reshape(3, 2))
    np.testing.assert_array_equal(asset.uvs[1], quad_uv.astype(np.float64).reshape(4, 2)[[2, 3, 0]])
    moved = asset.vertices + np.array([0.0, 0.0, 2.0])
    save_asset(tmp_path / "out.ply", asset, moved)
    back = load_asset(tmp_path / "out.ply")
    assert _same(back.vertices, moved)
    for name in ("faces", "uvs", "vertex_colors"):
        assert _same(getattr(back, name), getattr(asset, name)), name
    assert b"format binary_little_endian" in (tmp_path / "out.ply").read_bytes()[:40]


def test_gltf_missing_image_warns_and_still_writes(tmp_path: Path) -> None:
    path = cube_gltf(tmp_path)
    (tmp_path / "images" / "checker one.png").unlink()
    with pytest.warns(UserWarning, match=r"the texture 'images/checker%20one\.png' cannot be read"):
        asset = load_asset(path)
    assert asset.textures == {}
    written = save_asset(tmp_path / "again.gltf", asset, asset.vertices * 2)
    assert [p.name for p in written] == ["again.gltf", "again.bin"]
    with pytest.warns(UserWarning, match="cannot be read"):  # still missing, still referenced
        again = load_asset_bytes((tmp_path / "again.gltf").read_bytes(), "gltf", folder=tmp_path)
    assert again.data.document["images"] == asset.data.document["images"]


def _plane_glb(V: np.ndarray, F: np.ndarray, N: np.ndarray, UV: np.ndarray) -> bytes:
    blob = bytearray()
    views, accessors = [], []
    for array, kind, component in ((V, "VEC3", 5126), (N, "VEC3", 5126), (UV, "VEC2", 5126),
                                   (F.reshape(-1), "SCALAR", 5125)):
        data = np.ascontiguousarray(array, dtype="<u4" if component == 5125 else "<f4").tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        accessors.append({"bufferView": len(views) - 1, "componentType": component, "count": len(array) if
                          kind != "SCALAR" else F.size, "type": kind})
        blob += data
    accessors[0]["min"], accessors[0]["max"] = V.min(axis=0).tolist(), V.max(axis=0).tolist()
    document = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                            "indices": 3}]}],
                "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob)}]}
    return glb_bytes(document, bytes(blob))


def test_gltf_uv_seam_with_one_normal_stays_smooth(tmp_path: Path) -> None:
    """A strip of two squares whose middle edge is a UV seam (its vertices repeated with the same normal): bent
    along the seam, both copies get the same normal, from the triangles on both sides."""
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    N = np.tile([0.0, 0.0, 1.0], (8, 1))
    UV = np.array([[0, 0], [0.5, 0], [0.5, 1], [0, 1], [0.6, 0], [1, 0], [1, 1], [0.6, 1]])
    (tmp_path / "strip.glb").write_bytes(_plane_glb(V, F, N, UV))
    asset = load_asset(tmp_path / "strip.glb")
    solve = asset.solve_mesh()
    assert len(solve.V) == 6
    bent = solve.V.copy()
    bent[[1, 2], 2] = 0.5  # the seam goes up: a roof
    save_asset(tmp_path / "roof.glb", asset, bent)
    normals = _normals_in_scene(load_asset(tmp_path / "roof.glb"))
    np.testing.assert_array_equal(normals[1], normals[4])
    # The smooth normal of the welded surface: the area-weighted triangle normals on both sides of the seam.
    a, b, c = (bent[solve.F[:, k]] for k in range(3))
    around = np.cross(b - a, c - a)[(solve.F == 1).any(axis=1)].sum(axis=0)
    np.testing.assert_allclose(normals[1], around / np.linalg.norm(around), atol=1e-6)
    assert normals[0][0] < 0 and normals[5][0] > 0 and normals[1][0] > 0  # the right side has two triangles there


def test_interleaved_gltf_attributes_are_written_in_place(tmp_path: Path) -> None:
    """POSITION and NORMAL in one buffer view with a byte stride: new positions and normals go to their own bytes
    and the texture coordinates between them stay."""
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype="<f4")
    N = np.tile(np.float32([0, 0, 1]), (4, 1))
    UV = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype="<f4")
    rows = np.zeros(4, dtype=[("p", "<f4", 3), ("uv", "<f4", 2), ("n", "<f4", 3)])
    rows["p"], rows["uv"], rows["n"] = V, UV, N
    indices = np.array([0, 1, 2, 0, 2, 3], dtype="<u2")
    blob = rows.tobytes() + indices.tobytes()
    document = {
        "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "NORMAL": 2}, "indices": 3}]}],
        "accessors": [{"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 4, "type": "VEC2"},
                      {"bufferView": 0, "byteOffset": 20, "componentType": 5126, "count": 4, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": rows.nbytes, "byteStride": 32},
                        {"buffer": 0, "byteOffset": rows.nbytes, "byteLength": indices.nbytes}],
        "buffers": [{"byteLength": len(blob)}]}
    (tmp_path / "quad.glb").write_bytes(glb_bytes(document, blob))
    asset = load_asset(tmp_path / "quad.glb")
    R = _rotation(0.3)
    save_asset(tmp_path / "turned.glb", asset, asset.vertices @ R.T)
    back = load_asset(tmp_path / "turned.glb")
    written = np.frombuffer(back.data.buffers[0][:rows.nbytes], dtype=rows.dtype)
    np.testing.assert_allclose(written["p"], V @ R.T.astype(np.float32), atol=1e-6)
    np.testing.assert_allclose(written["n"], np.tile(R[:, 2], (4, 1)), atol=1e-6)
    assert written["uv"].tobytes() == UV.tobytes()
    assert back.data.buffers[0][rows.nbytes:] == asset.data.buffers[0][rows.nbytes:]


@pytest.mark.parametrize("change", [
    lambda d: d.update(meshes=5),
    lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION="zero"),
    lambda d: d["accessors"][0].update(type="VEC7"),
    lambda d: d["bufferViews"][0].update(byteOffset=-8),
    lambda d: d["nodes"][2].update(matrix=[1, 2, 3]),
    lambda d: d["meshes"][0]["primitives"][0].update(mode="strip"),
    lambda d: d.update(buffers=[{"byteLength": 10**12}]),
])
def test_malformed_documents_are_format_errors(change: Any) -> None:
    with pytest.raises(MeshFormatError, match="cannot read uploaded mesh as glTF"):
        load_asset_bytes(_glb_with(change), "glb")


@pytest.mark.parametrize("data", [b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n",
                                  b"ply\nformat ascii 1.0\nelement vertex 1\nproperty blob x\nend_header\n1\n",
                                  b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nproperty float x\n"
                                  b"property float y\nproperty float z\nend_header\n\x00\x00"])
def test_malformed_ply_is_a_format_error(data: bytes) -> None:
    with pytest.raises(MeshFormatError, match="PLY"):
        load_asset_bytes(data, "ply")


def _random_obj(seed: int) -> str:
    rng = np.random.default_rng(seed)
    n, t, q = int(rng.integers(4, 9)), int(rng.integers(0, 6)), int(rng.integers(0, 4))
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in rng.normal(size=(n, 3)).tolist()]
    lines += [f"vt {u!r} {v!r}" for u, v in rng.random((t, 2)).tolist()]
    lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in rng.normal(size=(q, 3)).tolist()]
    for _ in range(int(rng.integers(1, 8))):
        pick = rng.random()
        if pick < 0.2:
            lines.append(f"usemtl m{int(rng.integers(0, 3))}")
        elif pick < 0.35:
            lines.append(f"g part {int(rng.integers(0, 3))}")
        elif pick < 0.45:
            lines.append(f"o thing{int(rng.integers(0, 2))}")
        elif pick < 0.55:
            lines.append(rng.choice(["s 1", "s off", "s 2"]))
        size = int(rng.integers(3, 6))
        corners = []
        for v in rng.choice(n, size=min(size, n), replace=False).tolist():
            vt = str(int(rng.integers(1, t + 1))) if t and rng.random() < 0.7 else ""
            vn = str(int(rng.integers(1, q + 1))) if q and rng.random() < 0.7 else ""
            corners.append(f"{v + 1}/{vt}/{vn}" if vn else f"{v + 1}/{vt}" if vt else str(v + 1))
        lines.append("f " + " ".join(corners))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", range(40))
def test_random_obj_files_round_trip(tmp_path: Path, seed: int) -> None:
    (tmp_path / "r.obj").write_text(_random_obj(seed))
    asset = load_asset(tmp_path / "r.obj")
    moved = asset.vertices * 1.25 + 0.5
    for name, V in (("same.obj", None), ("moved.obj", moved)):
        save_asset(tmp_path / name, asset, V)
        back = load_asset(tmp_path / name)
        assert _same(back.vertices, asset.vertices if V is None else moved)
        for field in ("faces", "face_materials", "face_groups", "uvs"):
            assert _same(getattr(back, field), getattr(asset, field)), field
        assert back.materials == asset.materials and back.groups == asset.groups
        for field in OBJ_FIELDS:
            assert _same(getattr(back.data, field), getattr(asset.data, field)), field
        has = asset.data.corner_normals >= 0
        assert _same(back.data.corner_normals >= 0, has)
        if V is None:
            assert _same(back.data.normals[back.data.corner_normals[has]],
                         asset.data.normals[asset.data.corner_normals[has]])
