"""The studio sends a textured or coloured mesh file's look (render mesh, UVs, texture, vertex colours) right after
its mesh frame, nothing more for a plain mesh, and exports the deformed model as GLB with its texture."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
from PIL import Image
from starlette.testclient import TestClient

from arap.io import load_asset
from arap.server import create_app
from arap.server.appearance import build_look, look_from_path
from arap.server.meshdata import load_default
from tests.io.asset_models import coloured_ply
from tests.server.helpers import Reply, StudioClient, translation

CHECKER = ((230, 40, 40), (40, 60, 220))


def checker_png(size: int = 64, cells: int = 4) -> bytes:
    """A two-colour checker PNG (red and blue)."""
    i, j = np.indices((size, size)) * cells // size
    img = np.where(((i + j) % 2 == 0)[..., None], CHECKER[0], CHECKER[1]).astype(np.uint8)
    out = io.BytesIO()
    Image.fromarray(img).save(out, format="PNG")
    return out.getvalue()


def is_checker(blob: bytes) -> bool:
    """The bytes are an image of the checker's pixels."""
    expected = np.asarray(Image.open(io.BytesIO(checker_png())).convert("RGB"))
    got = np.asarray(Image.open(io.BytesIO(blob)).convert("RGB"))
    return got.shape == expected.shape and bool((got == expected).all())


def textured_grid(n: int = 6) -> trimesh.Trimesh:
    """A flat n×n grid in the xy plane with UVs (its x and y), textured with the checker."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    F = []
    for r in range(n - 1):
        for c in range(n - 1):
            a = r * n + c
            F += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    mesh = trimesh.Trimesh(V, np.array(F), process=False)
    uv = V[:, :2].copy()
    image = Image.open(io.BytesIO(checker_png()))
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=image)
    return mesh


def textured_box() -> trimesh.Trimesh:
    """A box whose faces each have their own UVs (seams everywhere: 24 render vertices on 8 positions)."""
    box = trimesh.creation.box()
    V = box.vertices[box.faces].reshape(-1, 3)
    F = np.arange(len(V)).reshape(-1, 3)
    uv = np.tile([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], (len(F), 1))
    uv[1::2] = np.tile([[0.1, 0.9], [0.9, 0.1], [0.5, 0.5]], (len(F) // 2, 1)).reshape(-1, 2)[: len(uv[1::2])]
    mesh = trimesh.Trimesh(V, F, process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.open(io.BytesIO(checker_png())))
    return mesh


@pytest.fixture
def box_glb(tmp_path: Path) -> Path:
    path = tmp_path / "box.glb"
    path.write_bytes(textured_box().export(file_type="glb"))
    return path


@pytest.fixture
def grid_glb(tmp_path: Path) -> Path:
    path = tmp_path / "grid.glb"
    path.write_bytes(textured_grid().export(file_type="glb"))
    return path


def appearance_arrays(reply: Reply, n_vertices: int) -> dict[str, Any]:
    """The arrays of an ``appearance`` frame."""
    h = reply.data
    p = reply.payload
    assert p is not None
    r, t = h["render_vertices"], h["render_faces"]
    o = 0
    out: dict[str, Any] = {}
    out["map"] = np.frombuffer(p[o:o + 4 * r], dtype="<u4").astype(np.int64)
    o += 4 * r
    out["uv"] = np.frombuffer(p[o:o + 8 * r], dtype="<f4").reshape(-1, 2)
    o += 8 * r
    out["faces"] = np.frombuffer(p[o:o + 12 * t], dtype="<u4").reshape(-1, 3).astype(np.int64)
    o += 12 * t
    if h["colors"]:
        out["colors"] = np.frombuffer(p[o:o + 3 * n_vertices], dtype=np.uint8).reshape(-1, 3)
        o += 3 * n_vertices
    out["texture"] = p[o:o + h["texture_bytes"]]
    assert o + h["texture_bytes"] == len(p)
    return out


@pytest.fixture
def connect(static_dir: Path) -> Iterator[Any]:
    clients: list[Any] = []

    def open_studio(mesh: Any) -> tuple[StudioClient, list[Reply]]:
        """A session greeted on ``mesh``; also every message between its mesh frame and its state."""
        client = TestClient(create_app(mesh, static_dir=static_dir, allowed_hosts=["testserver"]))
        client.__enter__()
        clients.append(client)
        ctx = client.websocket_connect("/ws")
        ws = ctx.__enter__()
        clients.append(ctx)
        studio = StudioClient(ws)
        studio.welcome = studio.expect("welcome").data
        studio.read_mesh()
        between = []
        while (reply := studio.recv()).type != "state":
            between.append(reply)
        studio.state = reply.data
        return studio, between

    yield open_studio
    for c in reversed(clients):
        c.__exit__(None, None, None)


def test_textured_glb_sends_the_render_mesh_and_texture(connect: Any, box_glb: Path) -> None:
    studio, between = connect(box_glb)
    assert [r.type for r in between] == ["appearance"]
    look = between[0]
    a = appearance_arrays(look, len(studio.V))
    assert look.data["texture_mime"] == "image/png" and look.data["notes"] == []
    asset = load_asset(box_glb)
    assert a["texture"] == next(iter(asset.textures.values())), "the texture is sent as stored"
    assert is_checker(a["texture"])
    assert len(studio.V) == 8, "the solver sees the welded box"
    assert look.data["render_vertices"] == len(a["map"]) > len(studio.V)
    assert look.data["render_faces"] == len(asset.faces) == 12
    # every render vertex sits on the solved vertex it follows, and the render triangles are the file's
    stored = asset.vertices
    corners = a["map"][a["faces"]]
    np.testing.assert_allclose(studio.V[corners], stored[asset.faces], atol=1e-6)
    # its UVs are the file's corner UVs (glTF convention: as stored)
    np.testing.assert_allclose(a["uv"][a["faces"]], asset.uvs, atol=1e-6)


def test_render_vertices_follow_the_drag(connect: Any, grid_glb: Path) -> None:
    studio, between = connect(grid_glb)
    a = appearance_arrays(between[0], len(studio.V))
    assert set(np.unique(a["map"])) == set(range(len(studio.V)))
    lo, hi = studio.bottom_top(0.2)
    studio.set_constraints(lo, [hi])
    moved = studio.drag(1, [translation(0.0, 0.3, 0.2)]).floats()
    render = moved[a["map"]]  # what the page gathers from each frame
    assert np.abs(render - studio.V[a["map"]]).max() > 0.1
    np.testing.assert_array_equal(render[a["faces"]], moved[a["map"][a["faces"]]])


def test_plain_meshes_send_nothing_more(connect: Any, tmp_path: Path) -> None:
    _, between = connect("bar")
    assert between == []
    plain = tmp_path / "plain.glb"
    plain.write_bytes(trimesh.creation.icosphere(subdivisions=1).export(file_type="glb"))
    _, between = connect(plain)
    assert between == []


def test_vertex_colours_of_a_ply(connect: Any, tmp_path: Path) -> None:
    path = coloured_ply(tmp_path / "ball.ply")
    studio, between = connect(path)
    assert [r.type for r in between] == ["appearance"]
    h = between[0].data
    assert h["colors"] and h["render_vertices"] == 0 and h["texture_bytes"] == 0
    colors = appearance_arrays(between[0], len(studio.V))["colors"]
    up = studio.V[:, 2] > 0
    assert (colors[up] == [255, 0, 0]).all() and (colors[~up] == [0, 0, 255]).all()


def test_uploads_carry_their_look(connect: Any, box_glb: Path, tmp_path: Path) -> None:
    studio, _ = connect("bar")
    studio.send_binary({"type": "upload", "filename": "box.glb"}, box_glb.read_bytes())
    studio.read_mesh()
    look = studio.expect("appearance")
    assert is_checker(appearance_arrays(look, len(studio.V))["texture"])
    studio.expect("state")
    ply = coloured_ply(tmp_path / "ball.ply")
    studio.send_binary({"type": "upload", "filename": "ball.ply"}, ply.read_bytes())
    studio.read_mesh()
    assert studio.expect("appearance").data["colors"]
    studio.expect("state")
    studio.send({"type": "load_builtin", "name": "bar"})
    studio.read_mesh()
    studio.expect("state")  # a built-in model has no look


def test_an_over_large_texture_is_left_out_with_a_note(box_glb: Path) -> None:
    mesh = load_default(box_glb)
    look = build_look(load_asset(box_glb), mesh, max_texture_bytes=100)
    assert look is not None and not look.textured and look.texture == b""
    assert len(look.notes) == 1 and "more than the" in look.notes[0] and "MiB" in look.notes[0]
    assert look_from_path(box_glb, mesh) is not None and look_from_path(box_glb, mesh).textured  # type: ignore


def test_glb_export_keeps_the_uvs_and_texture(connect: Any, grid_glb: Path, tmp_path: Path) -> None:
    studio, _ = connect(grid_glb)
    lo, hi = studio.bottom_top(0.2)
    studio.set_constraints(lo, [hi])
    moved = studio.drag(1, [translation(0.0, 0.0, 0.4)]).floats()
    studio.send({"type": "end_drag"})
    studio.expect("state")
    studio.send({"type": "export", "format": "glb"})
    while (reply := studio.recv()).type != "export":  # the shape settles first
        if reply.type == "vertices":
            moved = reply.floats()
    assert reply.data["filename"] == "grid-deformed.glb" and reply.data["mime"] == "model/gltf-binary"
    out = tmp_path / "out.glb"
    assert reply.payload is not None
    out.write_bytes(reply.payload)
    back = load_asset(out)
    source = load_asset(grid_glb)
    assert back.uvs is not None
    np.testing.assert_allclose(back.uvs, source.uvs, atol=1e-6)
    assert any(is_checker(t) for t in back.textures.values())
    vmap = load_default(grid_glb).vertex_map
    np.testing.assert_allclose(back.vertices, moved if vmap is None else moved[vmap], atol=1e-5)
    assert np.abs(back.vertices[:, 2]).max() > 0.1, "the export has the deformed shape"


def test_glb_export_of_plain_and_coloured_meshes(connect: Any, tmp_path: Path) -> None:
    studio, _ = connect("bar")
    studio.send({"type": "export", "format": "glb"})
    reply = studio.expect("export")
    assert reply.payload is not None and reply.payload[:4] == b"glTF"
    studio, _ = connect(coloured_ply(tmp_path / "ball.ply"))
    studio.send({"type": "export", "format": "glb"})
    reply = studio.expect("export")
    out = tmp_path / "ball.glb"
    assert reply.payload is not None
    out.write_bytes(reply.payload)
    back = load_asset(out)
    assert back.vertex_colors is not None and len(back.vertices) == len(studio.V)


def test_ply_and_obj_exports_of_their_own_sources_keep_the_attributes(connect: Any, tmp_path: Path) -> None:
    studio, _ = connect(coloured_ply(tmp_path / "ball.ply"))
    studio.send({"type": "export", "format": "ply"})
    reply = studio.expect("export")
    assert reply.payload is not None
    (tmp_path / "out.ply").write_bytes(reply.payload)
    back = load_asset(tmp_path / "out.ply")
    source = load_asset(tmp_path / "ball.ply")
    assert back.vertex_colors is not None
    np.testing.assert_array_equal(back.vertex_colors, source.vertex_colors)

    obj = tmp_path / "grid.obj"
    textured_grid().export(obj)  # OBJ + MTL + texture beside it
    studio, _ = connect(obj)
    lo, hi = studio.bottom_top(0.2)
    studio.set_constraints(lo, [hi])
    studio.drag(1, [translation(0.0, 0.0, 0.4)])
    studio.send({"type": "end_drag"})
    studio.expect("state")
    studio.send({"type": "export", "format": "obj"})
    while (reply := studio.recv()).type != "export":  # the shape settles first
        pass
    assert reply.payload is not None
    text = reply.payload.decode()
    assert "mtllib" in text and "usemtl" in text and "vt " in text, "texture references and UVs kept"
    (tmp_path / "grid-deformed.obj").write_bytes(reply.payload)  # beside the original MTL and texture
    back = load_asset(tmp_path / "grid-deformed.obj")
    source = load_asset(obj)
    assert back.uvs is not None and source.uvs is not None
    np.testing.assert_array_equal(back.uvs, source.uvs)
    assert back.textures, "the MTL beside it still names the texture"
    assert np.abs(back.vertices - source.vertices).max() > 0.1, "the export has the deformed shape"

    studio, _ = connect("bar")  # a plain mesh: geometry, as before
    studio.send({"type": "export", "format": "obj"})
    reply = studio.expect("export")
    assert reply.payload is not None and b"mtllib" not in reply.payload


def rest_export_format(filename: str) -> str | None:
    """The export format the page asks for after an apply of a mesh with a look uploaded as ``filename`` (its
    ``restExportFormat``, run by node)."""
    snapshot = Path(__file__).resolve().parents[2] / "web" / "src" / "snapshot.js"
    script = (f"import {{ restExportFormat }} from {json.dumps(snapshot.as_uri())};\n"
              f"console.log(JSON.stringify(restExportFormat({{kind: 'file', filename: {json.dumps(filename)}}})));\n")
    done = subprocess.run(["node", "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60,
                          check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
@pytest.mark.parametrize("source", ["grid.glb", "grid.zip", "grid.obj", "ball.ply"])
def test_the_rest_pose_an_apply_made_is_kept_as_a_file_that_uploads_again_with_its_look(
        connect: Any, tmp_path: Path, source: str) -> None:
    # after an apply, the page keeps the new rest pose of a mesh with a look (a restore uploads it again) as the
    # export in the format restExportFormat picks: the same mesh, vertex numbering and look come back from it
    fmt = rest_export_format(source)
    assert fmt is not None
    assert rest_export_format("cat.png") is None and rest_export_format("part.stl") is None
    if source.endswith(".glb"):
        data = textured_grid().export(file_type="glb")
    elif source.endswith(".ply"):
        data = coloured_ply(tmp_path / "ball.ply").read_bytes()
    elif source.endswith(".obj"):
        data = textured_grid().export(file_type="obj").encode()  # alone: UVs and a material it cannot read
    else:
        textured_grid().export(tmp_path / "grid.obj")  # OBJ + MTL + texture, uploaded as a zip as the page does
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w") as z:
            for path in tmp_path.iterdir():
                z.write(path, path.name)
        data = buffer.getvalue()

    def look_of(studio: StudioClient) -> dict[str, Any]:
        look = appearance_arrays(studio.expect("appearance"), len(studio.V))
        if source.endswith(".ply"):
            assert "colors" in look
        elif not source.endswith(".obj"):
            assert len(look["uv"]) > 0 and is_checker(look["texture"])
        studio.expect("state")
        return look

    studio, _ = connect("bar")
    studio.send_binary({"type": "upload", "filename": source}, data)
    studio.read_mesh()
    first = look_of(studio)
    lo, hi = studio.bottom_top(0.2)
    studio.set_constraints(lo, [hi])
    studio.drag(1, [translation(0.0, 0.3, 0.4)])
    studio.send({"type": "end_drag"})
    studio.expect("state")
    studio.settled()
    studio.send({"type": "apply"})
    studio.expect("state")
    rest = studio.held.astype(np.float64)
    assert np.abs(rest - studio.V).max() > 0.1
    studio.send({"type": "export", "format": fmt})
    while (reply := studio.recv()).type != "export":
        pass
    assert reply.payload is not None
    again, _ = connect("bar")
    again.send_binary({"type": "upload", "filename": reply.data["filename"]}, reply.payload)
    again.read_mesh()
    back = look_of(again)
    assert again.V.shape == rest.shape and again.F.shape == studio.F.shape
    np.testing.assert_allclose(again.V, rest, rtol=0, atol=1e-5)
    np.testing.assert_array_equal(again.F, studio.F)
    for name in ("uv", "colors"):
        if name in first:
            np.testing.assert_allclose(back[name], first[name], rtol=0, atol=1e-6)
