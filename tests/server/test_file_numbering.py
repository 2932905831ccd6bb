"""Constraints documents of a mesh file that repair renumbers: the studio gives them out in the file's numbering, as
``arap deform`` reads them, so that ``arap deform`` on the file gives the studio's shape."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import arap
from arap.cli import main as arap_main
from arap.io import load_mesh
from arap.server.meshdata import load_builtin, load_default, load_upload, mesh_frame
from arap.server.numbering import FileNumbering, document_in_file_numbering
from arap.server.session import Session
from tests.server.helpers import StudioClient, renumbered_bar_obj, translation

ROOT = Path(__file__).resolve().parents[2]


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def _deform(tmp_path: Path, text: str, document: dict, params: dict) -> np.ndarray:
    """``arap deform`` of the mesh file with the document; the shape written (in the file's vertex order)."""
    mesh, doc, out = tmp_path / "bar.obj", tmp_path / "c.json", tmp_path / "out.obj"
    mesh.write_text(text)
    doc.write_text(json.dumps(document))
    assert arap_main(["deform", str(mesh), "-c", str(doc), "-o", str(out), "-q", "--energy", params["energy"],
                      "--weights", params["weights"]]) == 0
    U, _ = load_mesh(out, repair=False)
    return U


def _mesh_vertices(vertex_map: np.ndarray, file_indices: list[int]) -> list[int]:
    """The mesh vertices of file vertices, each once, in order of first appearance."""
    return list(dict.fromkeys(vertex_map[np.asarray(file_indices, dtype=np.int64)].tolist()))


def test_the_map_comes_with_loaded_meshes_and_themesh_frame(tmp_path: Path, studio: StudioClient) -> None:
    text, vertex_map = renumbered_bar_obj()
    path = tmp_path / "bar.obj"
    path.write_text(text)
    mesh = load_default(path)
    assert mesh.n_vertices == 4314 and mesh.n_file_vertices == 4318
    np.testing.assert_array_equal(mesh.vertex_map, vertex_map)
    np.testing.assert_array_equal(load_upload(text.encode(), "bar.obj", 10**6).vertex_map, vertex_map)
    assert load_builtin("bar").vertex_map is None and load_default("bar").vertex_map is None
    assert studio.vertex_map is None  # the cactus keeps its numbering: no map
    studio.send_binary({"type": "upload", "filename": "bar.obj"}, text.encode())
    assert studio.read_mesh().data["file_vertices"] == len(vertex_map)
    np.testing.assert_array_equal(studio.vertex_map, vertex_map)


def test_saved_document_is_in_the_files_numbering_and_arap_deform_gives_the_settled_shape(
        studio: StudioClient, tmp_path: Path) -> None:
    text, vertex_map = renumbered_bar_obj()
    studio.send_binary({"type": "upload", "filename": "bar.obj"}, text.encode())
    studio.read_mesh()
    studio.expect("state")
    V = studio.V
    fixed, top = studio.bottom_top()
    left = [v for v in top if V[v, 0] < 0]
    right = [v for v in top if V[v, 0] >= 0]
    y = V[:, 1]
    middle = np.flatnonzero(np.abs(y - 0.5 * (y.min() + y.max())) < 0.3).tolist()
    stiffness = [{"vertices": middle, "value": 4.0}]
    welded = vertex_map[-3:].tolist()  # the mesh vertices with two file copies: lowest, middle, highest
    assert welded[0] in fixed and welded[1] in middle and welded[2] in top
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [left, right],
                 "stiffness": stiffness})
    groups = studio.expect("state").data["constraints"]["handle_groups"]
    assert groups == [left, right]
    studio.settled()
    studio.drag(0, [translation(0.8, 0.0, 0.3), translation(0.8, 0.0, 0.3)])
    studio.send({"type": "end_drag"})
    studio.expect("state")
    status, frame = studio.settled()
    assert status["status"] == "settled" and frame is not None
    studio.send({"type": "get_constraints"})
    doc = studio.expect("constraints").data["document"]

    # the indices are the file's: the dropped vertex is nowhere, every welded vertex comes with both its copies
    n_file = len(vertex_map)
    listed = [*doc["fixed"], *doc["handles"], *(i for g in doc["handle_groups"] for i in g),
              *(i for g in doc["stiffness"] for i in g["vertices"])]
    assert 0 not in listed and max(listed) < n_file
    assert {n_file - 3, welded[0] + 1} <= set(doc["fixed"])
    assert {n_file - 1, welded[2] + 1} <= set(doc["handles"])
    assert {n_file - 2, welded[1] + 1} <= set(doc["stiffness"][0]["vertices"])
    assert len(doc["fixed"]) == len(fixed) + 1 and len(doc["handles"]) == len(top) + 1
    assert _mesh_vertices(vertex_map, doc["fixed"]) == fixed
    assert [_mesh_vertices(vertex_map, g) for g in doc["handle_groups"]] == [left, right]
    assert sorted(_mesh_vertices(vertex_map, doc["stiffness"][0]["vertices"])) == sorted(middle)
    targets = np.asarray(doc["targets"])
    np.testing.assert_array_equal(targets[doc["handles"].index(n_file - 1)],
                                  targets[doc["handles"].index(welded[2] + 1)])

    U = _deform(tmp_path, text, doc, studio.state["params"])
    assert len(U) == n_file
    kept = vertex_map >= 0
    assert np.abs(U[kept] - frame[vertex_map[kept]]).max() <= 1e-6 * _diag(frame)


def test_session_document_of_a_default_file_with_displaced_anchors(tmp_path: Path) -> None:
    """A document of a session on the operator's file (load_default): fixed vertices a former drag moved and vertices
    outside the region of interest it keeps away from rest are handles too; all in the file's numbering."""
    text, vertex_map = renumbered_bar_obj()
    path = tmp_path / "bar.obj"
    path.write_text(text)
    session = Session()
    session.load(load_default(path))
    V = session.V
    y = V[:, 1]
    bottom = np.flatnonzero(y <= np.quantile(y, 0.1)).tolist()
    top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
    session.set_constraints(None, bottom, [top])
    session.drag([translation(0.5)])
    session.end_drag()
    upper = np.flatnonzero(y > 2.0).tolist()
    session.set_constraints(upper, [v for v in upper if v not in top], [top])  # anchors where the drag put them
    session.drag([translation(0.0, 0.0, 0.4)])
    session.end_drag()
    session.settle(lambda: False)
    assert len(session.constraints.held) > 0
    doc = session.constraints_document()
    assert 0 not in doc["handles"] and 0 not in doc["roi"]
    assert len(doc["roi"]) == len(upper) + 2  # the middle and the highest vertex have two copies each
    params = {"energy": session.params.energy, "weights": session.params.weights}
    U = _deform(tmp_path, text, doc, params)
    kept = vertex_map >= 0
    assert np.abs(U[kept] - session.U[vertex_map[kept]]).max() <= 1e-6 * _diag(session.U)


def test_point_handles_on_a_repaired_mesh_are_not_saved(studio: StudioClient) -> None:
    """arap deform refuses point handles on a mesh that repair changed (they refer to the repaired triangles): the
    studio says so instead of saving a document that no reader takes."""
    text, _ = renumbered_bar_obj()
    studio.send_binary({"type": "upload", "filename": "bar.obj"}, text.encode())
    studio.read_mesh()
    studio.expect("state")
    fixed, _ = studio.bottom_top()
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [],
                 "points": [{"face": int(len(studio.F) - 1), "barycentric": [0.2, 0.3, 0.5]}]})
    studio.expect("state")
    studio.settled()
    studio.send({"type": "get_constraints"})
    error = studio.error("bad_constraints")
    assert error["request"] == "get_constraints"
    assert "point handles" in error["message"] and "repair" in error["message"]
    studio.set_constraints(fixed, [])  # without them, the document is given
    studio.send({"type": "get_constraints"})
    assert len(studio.expect("constraints").data["document"]["fixed"]) == len(fixed) + 1


def test_stiffness_per_vertex_gets_the_files_length() -> None:
    V, _ = arap.builtin_mesh("bar")
    _, vertex_map = renumbered_bar_obj()
    numbering = FileNumbering(vertex_map, len(V))
    values: list[float | str] = [1.0] * len(V)
    values[int(vertex_map[-1])] = "rigid"
    values[5] = 3.0
    out = numbering.stiffness(values)
    assert len(out) == len(vertex_map) and out[0] == 1.0
    assert out[6] == 3.0 and out[-1] == "rigid" and out[int(vertex_map[-1]) + 1] == "rigid"
    np.testing.assert_array_equal(numbering.copies(np.array([int(vertex_map[-1]), 5])),
                                  [int(vertex_map[-1]) + 1, len(vertex_map) - 1, 6])


def test_documents_of_meshes_that_keep_their_numbering_are_unchanged(bar_session: Session) -> None:
    V = bar_session.V
    bar_session.set_constraints(None, [0, 1], [[int(np.argmax(V[:, 1]))]])
    doc = bar_session.constraints.document(bar_session.V, bar_session.transforms)
    assert document_in_file_numbering(doc, bar_session.mesh) is doc  # type: ignore[arg-type]
    assert bar_session.constraints_document() == doc


@pytest.mark.parametrize("value", [2.0, "rigid"])
def test_a_studio_document_loads_into_arap_deform_as_the_studio_had_it(value: object, tmp_path: Path) -> None:
    """The painted stiffness of both copies of a welded vertex agrees, so arap deform takes it."""
    text, vertex_map = renumbered_bar_obj()
    path = tmp_path / "bar.obj"
    path.write_text(text)
    session = Session()
    session.load(load_default(path))
    y = session.V[:, 1]
    welded = int(vertex_map[-2])
    session.set_constraints(None, np.flatnonzero(y <= 0.2).tolist(), [np.flatnonzero(y >= 4.8).tolist()],
                            stiffness=[{"vertices": [welded], "value": value}])
    doc = session.constraints_document()
    assert doc["stiffness"] == [{"vertices": [welded + 1, len(vertex_map) - 2], "value": value}]
    loaded = arap.load_constraints(doc, len(vertex_map)).remapped(vertex_map)
    assert loaded.stiffness is not None
    np.testing.assert_array_equal(loaded.stiffness, session.constraints.stiffness)


NODE_SCRIPT = """
import { readFileSync, writeFileSync } from 'fs';
import { decodeBinary, meshArrays } from '%(web)s/frames.js';
import { encodePly } from '%(web)s/snapshot.js';
const bytes = readFileSync('%(dir)s/mesh.bin');
const m = meshArrays(decodeBinary(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length)));
writeFileSync('%(dir)s/map.json', JSON.stringify(Array.from(m.vertexMap)));
writeFileSync('%(dir)s/again.ply', Buffer.from(encodePly(m.positions, m.faces, m.vertexMap)));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_client_gets_the_map_and_its_saved_sessions_keep_it(tmp_path: Path) -> None:
    """The page reads the map from the mesh frame; a saved session of a mesh it has no file of (the server's default
    mesh, or a shape made the rest pose) is uploaded again as a PLY in the file's numbering, repaired into the same
    mesh with the same map, so that its documents keep the file's numbering."""
    text, vertex_map = renumbered_bar_obj()
    mesh = load_upload(text.encode(), "bar.obj", 10**6)
    (tmp_path / "mesh.bin").write_bytes(mesh_frame(mesh))
    script = tmp_path / "check.mjs"
    script.write_text(NODE_SCRIPT % {"web": ROOT / "web" / "src", "dir": tmp_path})
    done = subprocess.run(["node", str(script)], capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "map.json").read_text()) == vertex_map.tolist()
    again = load_upload((tmp_path / "again.ply").read_bytes(), "bar.ply", 10**6)
    np.testing.assert_array_equal(again.vertex_map, vertex_map)
    np.testing.assert_array_equal(again.F, mesh.F)
    np.testing.assert_array_equal(again.V, mesh.V.astype(np.float32))
