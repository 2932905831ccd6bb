"""The studio over its WebSocket (in process): greeting, editing, history, export, uploads and sessions."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from starlette.testclient import TestClient

from arap.io import load_mesh_bytes
from arap.method.energy import cell_distortion
from arap.server import create_app
from arap.server.messages import PARAMS, PROTOCOL_VERSION
from tests.server.helpers import StudioClient, column_major, rotation_z, translation

pytestmark = pytest.mark.timeout(120)


def test_greeting(studio: StudioClient) -> None:
    w = studio.welcome
    assert w["protocol"] == PROTOCOL_VERSION
    assert "cactus" in w["builtin_meshes"]
    assert w["limits"]["max_upload_bytes"] == 50 * 2**20 and w["limits"]["max_vertices"] == 2_000_000
    assert w["params"] == {k: v["default"] for k, v in PARAMS.items()}
    assert studio.V.shape == (5250, 3) and studio.F.shape == (10496, 3)
    assert studio.F.max() == len(studio.V) - 1
    assert studio.state["stats"]["n_vertices"] == 5250
    assert studio.state["can_undo"] is False and studio.state["constraints"]["handle_groups"] == []


def test_constraints_and_drag(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    state = studio.set_constraints(fixed, [top])
    assert state["constraints"] == {"roi": None, "fixed": fixed, "handle_groups": [top], "stiffness": None,
                                   "points": []}
    assert state["stats"]["n_free"] == 5250 - len(fixed) - len(top)
    assert state["stats"]["factor_ms"] > 0 and state["can_undo"]
    M = rotation_z(0.5, studio.V[top].mean(axis=0), shift=(0.2, 0, 0.1))
    reply = studio.drag(1, [column_major(M)])
    h = reply.data
    assert h["iterations"] == 2 and len(h["energies"]) == 2 and h["solve_ms"] > 0 and h["skipped"] == 0
    assert h["ms_per_iteration"] == pytest.approx(h["solve_ms"] / 2, rel=0.01)
    U = reply.floats()
    np.testing.assert_allclose(U[top], studio.V[top] @ M[:3, :3].T + M[:3, 3], atol=1e-5)
    np.testing.assert_array_equal(U[fixed], studio.V[fixed])
    assert np.linalg.norm(U - studio.V, axis=1).max() > 0.1
    studio.send({"type": "end_drag"})
    state = studio.expect("state").data
    np.testing.assert_allclose(state["transforms"][0], column_major(M))


def test_undo_redo_reset_apply(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.drag(1, [translation(0.4)])
    studio.send({"type": "end_drag"})
    assert studio.expect("state").data["can_undo"]
    # Released, the shape settles; the settled shape is the undo step.
    status, dragged = studio.settled()
    assert status["status"] == "settled" and dragged is not None

    studio.send({"type": "undo"})
    reply = studio.expect("vertices")
    assert reply.data["seq"] == -1
    np.testing.assert_array_equal(reply.floats(), studio.V)
    studio.expect("state")
    assert studio.state["can_redo"] and studio.state["constraints"]["fixed"] == fixed

    studio.send({"type": "redo"})
    np.testing.assert_array_equal(studio.expect("vertices").floats(), dragged)
    studio.expect("state")
    assert not studio.state["can_redo"]

    studio.send({"type": "reset"})
    np.testing.assert_array_equal(studio.expect("vertices").floats(), studio.V)
    studio.expect("state")
    studio.send({"type": "undo"})
    np.testing.assert_array_equal(studio.expect("vertices").floats(), dragged)
    studio.expect("state")

    studio.send({"type": "apply"})
    studio.expect("state")   # the positions do not change, so no vertices frame
    # the applied shape is the new rest pose: identity transforms keep it
    np.testing.assert_allclose(studio.drag(2, [translation(0.0)]).floats(), dragged, atol=1e-5)
    studio.send({"type": "reset"})
    np.testing.assert_allclose(studio.expect("vertices").floats(), dragged, atol=1e-5)
    studio.expect("state")

    # undo with nothing to undo only answers state
    studio.send({"type": "redo"})
    assert studio.expect("state").data["can_redo"] is False


def test_export(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    U = studio.drag(5, [translation(0.3, 0.2)]).floats()
    for fmt in ("obj", "ply"):
        studio.send({"type": "export", "format": fmt})
        reply = studio.expect("export")
        assert reply.data["filename"] == f"cactus-deformed.{fmt}" and reply.data["mime"]
        V, F = load_mesh_bytes(reply.payload or b"", fmt, repair=False)
        assert V.shape == (5250, 3)
        np.testing.assert_allclose(V, U, atol=1e-5)
        np.testing.assert_array_equal(F, studio.F)


def test_get_constraints(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.drag(1, [translation(0.25)])
    studio.send({"type": "get_constraints"})
    doc = studio.expect("constraints").data["document"]
    assert doc["fixed"] == fixed and doc["handles"] == top and doc["handle_groups"] == [top]
    np.testing.assert_allclose(doc["targets"], studio.V[top] + [0.25, 0, 0], atol=1e-6)
    assert "roi" not in doc


def test_get_distortion(studio: StudioClient) -> None:
    studio.send({"type": "get_distortion"})
    rest = studio.expect("distortion")
    values = np.frombuffer(rest.payload or b"", dtype="<f4")
    assert values.shape == (5250,) and rest.data["max"] == pytest.approx(float(values.max()))
    assert values.max() < 1e-5  # the rest pose is rigid
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    U = studio.drag(1, [translation(0.25)]).floats().reshape(-1, 3)
    studio.send({"type": "get_distortion"})
    bent = studio.expect("distortion")
    values = np.frombuffer(bent.payload or b"", dtype="<f4")
    np.testing.assert_allclose(values, cell_distortion(studio.V, studio.F, U), rtol=1e-3, atol=1e-6)
    assert 0 < bent.data["high"] <= bent.data["max"] == pytest.approx(float(values.max()))


MALFORMED_TEXT = [
    ("not json", "bad_message"),
    ("[1, 2, 3]", "bad_message"),
    ('{"type": "teleport"}', "bad_message"),
    ('{"type": "drag", "seq": "1", "transforms": []}', "bad_message"),
    ('{"type": "drag", "seq": 1, "transforms": [[NaN,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]}', "bad_message"),
    ('{"type": "drag", "seq": 1, "transforms": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], '
     '[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]}', "bad_message"),
    ('{"type": "drag", "seq": 1, "transforms": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 1e308,0,0,1]]}', "bad_message"),
    ('{"type": "set_constraints", "roi": null, "fixed": [5250], "handle_groups": []}', "bad_constraints"),
    ('{"type": "set_constraints", "roi": [-1], "fixed": [], "handle_groups": []}', "bad_constraints"),
    ('{"type": "set_constraints", "roi": null, "fixed": [1, 1], "handle_groups": []}', "bad_constraints"),
    ('{"type": "set_constraints", "roi": null, "fixed": [1], "handle_groups": [[1]]}', "bad_constraints"),
    ('{"type": "set_constraints", "roi": null, "fixed": "all", "handle_groups": []}', "bad_message"),
    ('{"type": "set_params", "iterations": 1000}', "bad_message"),
    ('{"type": "load_builtin", "name": "teapot"}', "bad_message"),
    ('{"type": "upload", "filename": "x.obj"}', "bad_message"),
    ('{"type": "export", "format": "../../etc/passwd"}', "bad_message"),
]


def test_malformed_messages_get_errors_and_the_session_continues(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    before = studio.drag(1, [translation(0.2)]).floats()
    for text, code in MALFORMED_TEXT:
        studio.send(text)
        err = studio.error(code)
        assert err["message"], text
        studio.ping()
    garbage = [b"\x00", b"\xff\xff\xff\xff" + b"x" * 8, b"\x04\x00\x00\x00nope", b"\x08\x00\x00\x00[1, 2]  ",
               b"\x1c\x00\x00\x00" + b'{"type": "drag", "seq": 1}  ']
    for frame in garbage:
        studio.ws.send_bytes(frame)
        studio.error("bad_message")
        studio.ping()
    # nothing changed: the last drag still stands and a new one works
    studio.send({"type": "get_constraints"})
    doc = studio.expect("constraints").data["document"]
    np.testing.assert_allclose(doc["targets"], before[top], atol=1e-5)
    after = studio.drag(2, [translation(0.3)]).floats()
    np.testing.assert_allclose(after[top], studio.V[top] + [0.3, 0, 0], atol=1e-5)


def test_error_names_the_request(studio: StudioClient) -> None:
    studio.send('{"type": "drag", "seq": 1, "transforms": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]}')
    err = studio.error("bad_message")
    assert err["request"] == "drag" and "0 handle groups" in err["message"]
    studio.send({"type": "drag", "seq": 1, "transforms": []})
    err = studio.error("bad_constraints")
    assert err["request"] == "drag"


def _mesh_bytes(kind: str) -> tuple[bytes, int]:
    ball = trimesh.creation.icosphere(subdivisions=2)
    buf = io.BytesIO()
    ball.export(buf, file_type=kind)
    return buf.getvalue(), len(ball.vertices)


@pytest.mark.parametrize("kind", ["obj", "stl", "ply", "off"])
def test_upload(studio: StudioClient, kind: str) -> None:
    data, n = _mesh_bytes(kind)
    studio.send_binary({"type": "upload", "filename": f"C:\\Users\\me\\my ball.{kind.upper()}"}, data)
    mesh = studio.read_mesh().data
    assert mesh["n_vertices"] == n and mesh["name"] == "my ball"
    if kind == "stl":
        assert any("weld" in line for line in mesh["report"]), mesh["report"]
    state = studio.expect("state").data
    assert state["stats"]["n_vertices"] == n and not state["can_undo"]
    lo, hi = studio.bottom_top(0.2)
    studio.set_constraints(lo, [hi])
    U = studio.drag(1, [translation(0, 0.5)]).floats()
    np.testing.assert_allclose(U[hi], studio.V[hi] + [0, 0.5, 0], atol=1e-5)


def test_upload_errors(studio: StudioClient) -> None:
    studio.send_binary({"type": "upload", "filename": "notes.txt"}, b"hello")
    assert "unsupported" in studio.error("bad_mesh")["message"]
    studio.send_binary({"type": "upload", "filename": "broken.obj"}, b"this is not a mesh\n")
    studio.error("bad_mesh")
    studio.send_binary({"type": "upload", "filename": "broken.stl"}, b"\x00" * 90)
    studio.error("bad_mesh")
    # the session still has the cactus
    studio.send({"type": "export", "format": "obj"})
    assert studio.expect("export").data["filename"].startswith("cactus")


_OPENED: list[str] = []


def _record_opens(event: str, args: tuple) -> None:
    if event == "open" and "arap-upload-canary" in str(args[0]):
        _OPENED.append(str(args[0]))


def test_uploads_never_open_client_named_paths(studio: StudioClient, tmp_path: Path) -> None:
    canary = tmp_path / "arap-upload-canary"
    canary.mkdir()
    (canary / "secret.mtl").write_text("newmtl leaked\n")
    (canary / "secret.obj").write_bytes(_mesh_bytes("obj")[0])
    sys.addaudithook(_record_opens)
    _OPENED.clear()
    data, n = _mesh_bytes("obj")
    text = f"mtllib {canary / 'secret.mtl'}\nmtllib ../arap-upload-canary/secret.mtl\nusemtl leaked\n".encode()
    studio.send_binary({"type": "upload", "filename": str(canary / "secret.obj")}, text + data)
    assert studio.read_mesh().data["n_vertices"] == n
    studio.expect("state")
    with open(canary / "secret.mtl") as f:    # the hook does see opens
        f.read()
    assert _OPENED == [str(canary / "secret.mtl")]


def test_size_limits(static_dir: Path) -> None:
    data, _ = _mesh_bytes("obj")
    app = create_app("bar", max_upload_bytes=len(data) - 1, max_vertices=10_000, static_dir=static_dir,
                     allowed_hosts=["testserver"])
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        c = StudioClient(ws)
        c.greet()
        assert c.welcome["limits"]["max_upload_bytes"] == len(data) - 1
        c.send_binary({"type": "upload", "filename": "ball.obj"}, data)
        assert c.error("too_large")["request"] == "upload"
        c.ping()
    small = create_app("bar", max_vertices=100, static_dir=static_dir, allowed_hosts=["testserver"])
    with TestClient(small) as http, http.websocket_connect("/ws") as ws:
        c = StudioClient(ws)
        c.greet()
        c.send_binary({"type": "upload", "filename": "ball.obj"}, data)
        assert "at most 100" in c.error("too_large")["message"]
        c.ping()


def test_load_builtin(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.send({"type": "load_builtin", "name": "bar"})
    assert studio.read_mesh().data["name"] == "bar"
    state = studio.expect("state").data
    assert state["constraints"]["fixed"] == [] and not state["can_undo"]
    assert len(studio.V) == state["stats"]["n_vertices"] != 5250


def test_set_params(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.send({"type": "set_params", "iterations": 5, "energy": "spokes_and_rims"})
    assert studio.expect("state").data["params"] == {"iterations": 5, "energy": "spokes_and_rims",
                                                     "weights": "cotangent", "alpha": 0.02, "loose": "follow",
                                                     "warp": "rigid"}
    assert studio.drag(1, [translation(0.1)]).data["iterations"] == 5


def test_smooth_rotations_and_alpha(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.send({"type": "set_params", "energy": "smooth_rotations", "alpha": 0.1})
    assert studio.expect("state").data["params"]["alpha"] == 0.1
    first = studio.drag(1, [translation(0.3)]).floats()
    studio.send({"type": "set_params", "alpha": 0.5})
    assert studio.expect("state").data["params"] == {"iterations": 2, "energy": "smooth_rotations",
                                                     "weights": "cotangent", "alpha": 0.5, "loose": "follow",
                                                     "warp": "rigid"}
    studio.send({"type": "drag", "seq": 2, "transforms": [translation(0.3)]})
    second = studio.expect("vertices").floats()
    assert abs(second - first).max() > 1e-6  # a stiffer rotation term gives another shape
    for bad in (-0.1, 2, "0.5", None):
        studio.send({"type": "set_params", "alpha": bad})
        assert "alpha" in studio.error("bad_message")["message"]


def test_sessions_are_independent(http: TestClient) -> None:
    with http.websocket_connect("/ws") as wa, http.websocket_connect("/ws") as wb:
        a, b = StudioClient(wa), StudioClient(wb)
        a.greet()
        b.greet()
        assert http.get("/healthz").json()["sessions"] == 2
        fixed, top = a.bottom_top()
        a.set_constraints(fixed, [top])
        b.send({"type": "load_builtin", "name": "bar"})
        b.read_mesh()
        b.expect("state")
        Ua = a.drag(1, [translation(0.5)]).floats()
        b.send({"type": "drag", "seq": 1, "transforms": []})
        b.error("bad_constraints")
        bf, bt = b.bottom_top()
        b.set_constraints(bf, [bt])
        Ub = b.drag(1, [translation(-0.5)]).floats()
        assert Ua.shape == (5250, 3) and Ub.shape == b.V.shape
        np.testing.assert_allclose(Ub[bt], b.V[bt] - [0.5, 0, 0], atol=1e-5)
        a.send({"type": "undo"})
        a.expect("vertices")
        assert a.expect("state").data["constraints"]["fixed"] == fixed
        b.send({"type": "get_constraints"})
        assert b.expect("constraints").data["document"]["fixed"] == bf


def test_drags_are_coalesced(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.send({"type": "set_params", "iterations": 30})
    studio.expect("state")
    n = 60
    for seq in range(n):
        studio.send({"type": "drag", "seq": seq, "transforms": [translation(0.01 * seq)]})
    seqs, skipped = [], 0
    while not seqs or seqs[-1] != n - 1:
        reply = studio.expect("vertices")
        seqs.append(reply.data["seq"])
        skipped += reply.data["skipped"]
    assert seqs == sorted(seqs) and seqs[-1] == n - 1
    assert len(seqs) <= n // 4, f"{len(seqs)} solves for {n} drags"
    assert len(seqs) + skipped == n
    np.testing.assert_allclose(reply.floats()[top], studio.V[top] + [0.01 * (n - 1), 0, 0], atol=1e-5)
    studio.ping()   # nothing else was queued


def test_full_queue_answers_busy(static_dir: Path) -> None:
    app = create_app("cactus", max_pending=2, static_dir=static_dir, allowed_hosts=["testserver"])
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        c = StudioClient(ws)
        c.greet()
        fixed, top = c.bottom_top()
        c.set_constraints(fixed, [top])
        c.settled()
        c.send({"type": "set_params", "iterations": 100})
        c.expect("state")
        c.send({"type": "drag", "seq": 0, "transforms": [translation(0.3)]})
        for _ in range(6):
            c.send({"type": "get_constraints"})
        replies: list = []
        while len(replies) < 7:
            reply = c.recv()
            if reply.type != "settle":
                replies.append(reply)
        kinds = [r.type for r in replies]
        assert kinds.count("vertices") == 1
        busy = [r.data for r in replies if r.type == "error"]
        assert busy and all(e["code"] == "busy" and e["request"] == "get_constraints" for e in busy)
        assert kinds.count("constraints") + len(busy) == 6
        c.ping()


def test_static_client_and_health(http: TestClient) -> None:
    page = http.get("/")
    assert page.status_code == 200 and "<title>studio</title>" in page.text
    assert http.get("/assets/app.js").text == "console.log('studio');"
    assert http.get("/assets/missing.js").status_code == 404
    assert http.get("/../pyproject.toml").status_code == 404
    health = http.get("/healthz").json()
    assert health["status"] == "ok" and health["client_built"] is True


def test_unbuilt_client_page(tmp_path: Path) -> None:
    app = create_app("bar", static_dir=tmp_path / "nothing", allowed_hosts=["testserver"])
    with TestClient(app) as http:
        page = http.get("/")
        assert page.status_code == 503 and "./dev setup" in page.text
        assert http.get("/assets/app.js").status_code == 404
        assert http.get("/healthz").json()["client_built"] is False


def test_bad_default_mesh_fails_early(tmp_path: Path) -> None:
    bad = tmp_path / "nothing.obj"
    bad.write_text("not a mesh")
    with pytest.raises(ValueError, match=r"nothing\.obj"):
        create_app(bad)
    with pytest.raises(ValueError, match="positive"):
        create_app("bar", max_upload_bytes=0)
