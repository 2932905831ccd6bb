"""``arap.studio``: a background studio on the given arrays, driven over its WebSocket as the page would, read back as
arrays, stopped cleanly."""

from __future__ import annotations

import json
import socket
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import pytest
import trimesh
from websockets.sync.client import ClientConnection, connect

import arap
from arap.server.frames import decode_binary

pytestmark = pytest.mark.timeout(120)


def _recv(ws: ClientConnection) -> tuple[dict[str, Any], bytes | None]:
    message = ws.recv(timeout=60)
    if isinstance(message, str):
        return json.loads(message), None
    header, payload = decode_binary(message)
    return header, bytes(payload)


def _expect(ws: ClientConnection, kind: str) -> tuple[dict[str, Any], bytes | None]:
    while True:
        header, payload = _recv(ws)
        assert header["type"] != "error", header
        if header["type"] == kind:
            return header, payload


def _origin(url: str) -> str:
    return url.split("?")[0].rstrip("/")


def _ws_url(url: str) -> str:
    """The WebSocket address of a studio page's URL, with its token (as the page's client builds it)."""
    page, _, query = url.partition("?")
    return page.replace("http://", "ws://") + "ws" + (f"?{query}" if query else "")


def test_studio_serves_the_arrays_and_reads_the_session_back() -> None:
    V, F = arap.builtin_mesh("bar")
    s = arap.studio(V, F, name="bar", show=False)
    try:
        assert s.running and s.url.startswith("http://127.0.0.1:")
        np.testing.assert_array_equal(s.vertices, V)  # no page yet: the given mesh
        assert s.constraints.fixed.size == 0 and s.constraints.handle_groups == []
        with connect(_ws_url(s.url), origin=_origin(s.url), max_size=None) as ws:
            _expect(ws, "welcome")
            header, payload = _expect(ws, "mesh")
            assert header["name"] == "bar" and header["n_vertices"] == len(V)
            assert payload is not None
            sent = np.frombuffer(payload[: 12 * len(V)], dtype="<f4").reshape(-1, 3)
            np.testing.assert_allclose(sent, V, rtol=0, atol=1e-6 * np.abs(V).max())
            _expect(ws, "state")
            y = V[:, 1]
            fixed = np.flatnonzero(y <= y.min() + 0.05 * np.ptp(y)).tolist()
            top = np.flatnonzero(y >= y.max() - 0.05 * np.ptp(y)).tolist()
            ws.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]}))
            _expect(ws, "state")
            M = np.eye(4)
            M[:3, 3] = (0.4, 0.0, 0.1)
            ws.send(json.dumps({"type": "drag", "seq": 1, "transforms": [M.T.reshape(16).tolist()]}))
            header, payload = _expect(ws, "vertices")
            assert payload is not None
            shown = np.frombuffer(payload, dtype="<f4").reshape(-1, 3)
            ws.send(json.dumps({"type": "end_drag"}))
            _expect(ws, "state")
        U = s.vertices  # read after the page closed: the session's last shape is kept
        assert U.shape == V.shape and U.dtype == np.float64
        np.testing.assert_allclose(U[top], V[top] + [0.4, 0.0, 0.1], atol=1e-9)
        np.testing.assert_allclose(U[fixed], V[fixed], atol=1e-12)
        assert np.abs(U - V).max() > 0.1
        if header["seq"] == 1:
            assert np.abs(shown - U).max() < 0.5  # settled since, but the frame was this drag's shape
        sel = s.constraints
        assert sel.fixed.tolist() == fixed and [g.tolist() for g in sel.handle_groups] == [top]
        assert sel.roi is None
        np.testing.assert_allclose(sel.targets, V[top] + [0.4, 0.0, 0.1], atol=1e-12)
        assert sel.document["fixed"] == fixed
        np.testing.assert_array_equal(s.faces, F)
        port = urlsplit(s.url).port
    finally:
        s.stop()
    assert not s.running
    with socket.socket() as probe:  # nothing listens on the port any more (closed connections may linger)
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(("127.0.0.1", port))
        probe.listen()


def test_studio_takes_a_mesh_object_and_is_a_context_manager() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2)
    with arap.studio(mesh, show=False) as s:
        assert "iframe" in s._repr_html_() and s.url in s._repr_html_()
        np.testing.assert_array_equal(s.faces, mesh.faces)
        assert "running" in repr(s)
    assert not s.running and "stopped" in repr(s)


def test_studio_rejects_a_bad_mesh_before_starting() -> None:
    with pytest.raises(arap.MeshError):
        arap.studio(np.zeros((3, 3)), np.array([[0, 1, 1]]), show=False)


def test_studio_opens_pages_with_initial_constraints_solved() -> None:
    V, F = arap.builtin_mesh("bar")
    y = V[:, 1]
    fixed = np.flatnonzero(y <= y.min() + 0.05 * np.ptp(y))
    top = np.flatnonzero(y >= y.max() - 0.05 * np.ptp(y))
    half = len(top) // 2
    groups = [top[half:].tolist(), top[:half].tolist()]  # group order differs from the handles' order
    moved = V[top] + [0.5, -0.2, 0.0]
    document = {"fixed": fixed.tolist(), "handles": top.tolist(), "targets": moved.tolist(), "handle_groups": groups}
    with arap.studio(V, F, show=False, constraints=document) as s:
        with connect(_ws_url(s.url), origin=_origin(s.url), max_size=None) as ws:
            _expect(ws, "welcome")
            _expect(ws, "mesh")
            state, _ = _expect(ws, "state")
            assert state["constraints"]["fixed"] == fixed.tolist()
            assert state["constraints"]["handle_groups"] == groups  # the page adopts these
            header, payload = _expect(ws, "vertices")
            assert header["seq"] == -1  # a shape the server sent by itself, not an answer to a drag
            assert payload is not None
            shown = np.frombuffer(payload, dtype="<f4").reshape(-1, 3)
            np.testing.assert_allclose(shown[top], moved, atol=1e-5)  # the page is sent the solved shape
        U = s.vertices
        np.testing.assert_allclose(U[top], moved, atol=1e-9)
        np.testing.assert_allclose(U[fixed], V[fixed], atol=1e-12)
        sel = s.constraints
        assert [g.tolist() for g in sel.handle_groups] == groups
        order = {v: k for k, v in enumerate(top.tolist())}
        np.testing.assert_allclose(sel.targets, moved[[order[i] for i in groups[0] + groups[1]]], atol=1e-12)


def test_studio_refuses_bad_initial_constraints_before_starting() -> None:
    V, F = arap.builtin_mesh("bar")
    with pytest.raises(arap.ConstraintError, match="handles"):
        arap.studio(V, F, show=False, constraints={"fixed": [0], "handles": [len(V)], "targets": [[0, 0, 0]]})
    with pytest.raises(arap.ConstraintError, match="handle_groups"):
        arap.studio(V, F, show=False, constraints={"fixed": [0], "handles": [1, 2], "targets": [[0, 0, 0]] * 2,
                                                   "handle_groups": [[1]]})


@pytest.mark.parametrize("as_file", [True, False])
def test_a_picture_opens_for_the_puppet_warp(tmp_path: Any, as_file: bool) -> None:
    from PIL import Image

    rgba = np.zeros((60, 90, 4), dtype=np.uint8)
    rgba[10:50, 10:80] = (200, 60, 30, 255)
    path = tmp_path / "sprite.png"
    Image.fromarray(rgba, "RGBA").save(path)
    s = arap.studio(str(path) if as_file else rgba, show=False, transport="server")
    try:
        V = s.vertices
        assert V.shape[1] == 3 and np.all(V[:, 2] == 0.0) and len(V) > 50
        assert V[:, 0].min() >= 9.0 and V[:, 0].max() <= 81.0 and V[:, 1].min() >= 9.0 and V[:, 1].max() <= 51.0
        with connect(_ws_url(s.url), origin=_origin(s.url), max_size=None) as ws:
            _expect(ws, "welcome")
            header, _ = _expect(ws, "mesh")
            assert header["picture"] == [90, 60] and header["n_vertices"] == len(V)
            assert header["name"] == ("sprite" if as_file else "mesh")
            look, _ = _expect(ws, "appearance")
            assert look["texture_bytes"] > 0
    finally:
        s.stop()


def test_an_unusable_picture_is_refused(tmp_path: Any) -> None:
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"not a picture")
    with pytest.raises(arap.ArapError, match=r"broken\.png"):
        arap.studio(str(bad), show=False, transport="server")
    with pytest.raises(arap.ArapError, match=r"no opaque|empty|transparent"):
        arap.studio(np.zeros((20, 20, 4), dtype=np.uint8), show=False, transport="server")
