"""Uploads of a mesh file with the files it names (a zip, which the page makes of several files chosen or dropped
together), the notes on what the page cannot show, and OBJ and GLB exports that keep UVs, materials and textures."""

from __future__ import annotations

import io
import json
import struct
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from arap.io import load_asset
from arap.server import create_app
from tests.io.asset_models import cube_glb, cube_gltf, cube_obj, zip_of
from tests.server.helpers import StudioClient, translation
from tests.server.test_textured_mesh import appearance_arrays


@pytest.fixture
def studio(static_dir: Path) -> Iterator[StudioClient]:
    app = create_app("bar", static_dir=static_dir, allowed_hosts=["testserver"], max_upload_bytes=1 << 20)
    with TestClient(app) as client, \
            client.websocket_connect("/ws") as ws:
        s = StudioClient(ws)
        s.greet()
        yield s


def upload(studio: StudioClient, filename: str, data: bytes) -> list[Any]:
    """Upload a file; every message from its mesh frame to its state (the mesh frame first)."""
    studio.send_binary({"type": "upload", "filename": filename}, data)
    replies = [studio.read_mesh()]
    while (reply := studio.recv()).type != "state":
        replies.append(reply)
    studio.state = reply.data
    return replies


def test_an_obj_uploaded_with_its_mtl_and_texture_is_drawn_textured(studio: StudioClient, tmp_path: Path) -> None:
    cube_obj(tmp_path)
    alone = upload(studio, "cube.obj", (tmp_path / "cube.obj").read_bytes())
    assert [r.type for r in alone] == ["mesh", "appearance"], "an OBJ alone is noted"
    notes = alone[1].data["notes"]
    assert alone[1].data["render_vertices"] == 0
    assert any("'cube.mtl'" in n for n in notes) and any("zip" in n for n in notes)
    exported = _export(studio, "obj")
    assert exported.data["filename"] == "cube-deformed.obj", "nothing to bring beside it"
    source_vt = (tmp_path / "cube.obj").read_text().count("\nvt ")
    assert exported.payload.decode().count("\nvt ") == source_vt == 14, "its texture coordinates are kept"

    replies = upload(studio, "cube.zip", zip_of(tmp_path))
    assert [r.type for r in replies] == ["mesh", "appearance"]
    look = replies[1]
    assert look.data["texture_mime"] == "image/png" and look.data["render_vertices"] > len(studio.V)
    a = appearance_arrays(look, len(studio.V))
    assert a["texture"] == (tmp_path / "tex" / "checker.png").read_bytes()
    assert any("bump.png" in n for n in look.data["notes"]), "the bump map is named as not shown"
    assert replies[0].data["name"] == "cube"


def test_a_zip_naming_files_outside_it_names_them_in_a_note(studio: StudioClient, tmp_path: Path) -> None:
    (tmp_path / "secret.png").write_bytes(b"\x89PNG\r\n\x1a\n secret")
    mtl = f"newmtl m\nmap_Kd {tmp_path / 'secret.png'}\n\nnewmtl n\nmap_Kd ../secret.png\n"
    obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n" \
          "usemtl n\nf 2/2 4/1 3/3\n"
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        archive.writestr("m.obj", obj)
        archive.writestr("m.mtl", mtl)
    replies = upload(studio, "m.zip", out.getvalue())
    notes = replies[1].data["notes"]
    assert replies[1].data["texture_bytes"] == 0
    assert any("'../secret.png'" in n and "leads outside" in n for n in notes)
    assert any(str(tmp_path / "secret.png") in n for n in notes)


def test_a_refused_zip_is_one_clear_error(studio: StudioClient) -> None:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("m.obj", b"#" * (5 << 20))  # more than four times the upload limit (1 MiB), once inflated
    studio.send_binary({"type": "upload", "filename": "m.zip"}, out.getvalue())
    error = studio.error("bad_mesh")
    assert "once uncompressed" in error["message"]
    studio.send_binary({"type": "upload", "filename": "two.zip"},
                       zip_of_files({"a.obj": b"v 0 0 0\n", "b.obj": b"v 0 0 0\n"}))
    assert "one mesh file" in studio.error("bad_mesh")["message"]


def zip_of_files(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        for name, content in files.items():
            archive.writestr(name, content)
    return out.getvalue()


def _export(studio: StudioClient, fmt: str) -> Any:
    studio.send({"type": "export", "format": fmt})
    while (reply := studio.recv()).type != "export":  # the shape settles first
        pass
    return reply


def _deform(studio: StudioClient) -> None:
    lo, hi = studio.bottom_top(0.2)
    studio.set_constraints(lo, [hi])
    studio.drag(1, [translation(0.0, 0.4, 0.0)])
    studio.send({"type": "end_drag"})
    studio.expect("state")


def test_obj_export_of_a_glb_writes_the_mtl_and_texture_in_a_zip(studio: StudioClient, tmp_path: Path) -> None:
    glb = cube_glb(tmp_path)
    upload(studio, "cube.glb", glb.read_bytes())
    _deform(studio)
    reply = _export(studio, "obj")
    assert reply.data["filename"] == "cube-deformed.zip" and reply.data["mime"] == "application/zip"
    out = tmp_path / "out"
    with zipfile.ZipFile(io.BytesIO(reply.payload)) as archive:
        assert archive.namelist() == ["cube-deformed.obj", "cube-deformed.mtl", "checker.png"]
        archive.extractall(out)
    back = load_asset(out / "cube-deformed.obj")
    source = load_asset(glb)
    assert back.uvs is not None and len(back.uvs) == len(source.faces)
    assert back.materials == ["red", "textured"]
    assert back.textures["checker.png"] == source.textures["checker"]
    assert np.abs(back.vertices - source.vertices).max() > 0.05, "the export has the deformed shape"


def test_obj_and_glb_exports_of_an_uploaded_textured_obj(studio: StudioClient, tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    cube_obj(src)
    upload(studio, "cube.zip", zip_of(src))
    reply = _export(studio, "obj")
    assert reply.data["filename"] == "cube-deformed.zip"
    with zipfile.ZipFile(io.BytesIO(reply.payload)) as archive:
        names = set(archive.namelist())
        assert {"cube-deformed.obj", "cube-deformed.mtl", "tex/checker.png"} <= names
        archive.extractall(tmp_path / "out")
    back = load_asset(tmp_path / "out" / "cube-deformed.obj")
    assert back.uvs is not None and back.textures

    glb = _export(studio, "glb").payload
    length = struct.unpack_from("<I", glb, 12)[0]
    document = json.loads(glb[20:20 + length])
    assert [m.get("name") for m in document["materials"]] == ["blue"], "the material most triangles use"


def test_a_gltf_with_its_buffer_and_image_in_a_zip(studio: StudioClient, tmp_path: Path) -> None:
    cube_gltf(tmp_path)
    replies = upload(studio, "cube.zip", zip_of(tmp_path))
    assert [r.type for r in replies] == ["mesh", "appearance"]
    assert replies[1].data["texture_bytes"] > 0
    np.testing.assert_allclose(np.ptp(studio.V, axis=0).max(), np.ptp(load_asset(tmp_path / "cube.gltf").vertices,
                                                                       axis=0).max(), rtol=1e-6)


def test_a_mesh_shown_by_two_nodes_is_drawn_twice_with_a_note(studio: StudioClient, tmp_path: Path) -> None:
    from tests.io.asset_models import instanced_glb

    replies = upload(studio, "instanced.glb", instanced_glb(tmp_path).read_bytes())
    notes = replies[1].data["notes"]
    assert any("2 instances were made separate parts" in n for n in notes)
    assert studio.V[:, 0].max() > 4.0, "the second instance is drawn where its node puts it"


def test_the_diffuse_texture_is_shown_when_a_bump_map_comes_first(studio: StudioClient, tmp_path: Path) -> None:
    cube_obj(tmp_path)
    mtl = (tmp_path / "cube.mtl").read_text()
    (tmp_path / "cube.mtl").write_text("newmtl first\nbump tex/bump.png\n\n" + mtl)
    replies = upload(studio, "cube.zip", zip_of(tmp_path))
    texture = appearance_arrays(replies[1], len(studio.V))["texture"]
    assert texture == (tmp_path / "tex" / "checker.png").read_bytes()


def test_material_features_the_page_does_not_draw_are_noted(studio: StudioClient) -> None:
    from tests.io.asset_models import cube_gltf_document, glb_bytes, png

    document, blob = cube_gltf_document(png(8, 8, 4))
    document["materials"][1]["normalTexture"] = {"index": 0}
    document["materials"][1]["extensions"] = {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0}}
    document["extensionsUsed"] = ["KHR_materials_clearcoat"]
    notes = upload(studio, "coat.glb", glb_bytes(document, blob))[1].data["notes"]
    assert any("KHR_materials_clearcoat" in n for n in notes)
    assert any("normalTexture not shown" in n for n in notes)
