"""The page applies subset ``vertices`` frames in place: its vertex buffer ends bitwise equal to a full frame."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Browser, WebSocketRoute

from arap.server.frames import decode_binary
from tests.e2e.conftest import VIEWPORT, positions, wait_ready
from tests.server.helpers import translation
from tests.waiting import page_wait_until, scaled_ms

pytestmark = pytest.mark.e2e


def _ply_vertices(data: bytes) -> np.ndarray:
    """Vertices of a binary little-endian PLY with double coordinates (the studio's export)."""
    head, _, body = data.partition(b"end_header\n")
    match = re.search(rb"element vertex (\d+)", head)
    assert match is not None and b"property double x" in head
    n = int(match.group(1))
    return np.frombuffer(body[: 24 * n], dtype="<f8").reshape(n, 3)


def test_the_page_holds_the_full_frame_positions_after_subset_frames(browser: Browser, server_url: str) -> None:
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    page = context.new_page()
    seen: list[dict[str, Any]] = []
    exported: list[bytes] = []
    route: dict[str, WebSocketRoute] = {}

    def relay(ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()
        route["server"] = server

        def from_server(message: str | bytes) -> None:
            if isinstance(message, bytes):
                header, payload = decode_binary(message)
                if header["type"] == "vertices":
                    seen.append(header)
                elif header["type"] == "export":
                    exported.append(bytes(payload))
            ws.send(message)

        server.on_message(from_server)
        ws.on_message(lambda message: server.send(message))

    page.route_web_socket("**/ws", relay)
    page.goto(server_url)
    wait_ready(page)
    V = positions(page)
    y = V[:, 1]
    roi = np.flatnonzero(y >= np.quantile(y, 0.5)).tolist()
    fixed = np.flatnonzero((y >= np.quantile(y, 0.5)) & (y <= np.quantile(y, 0.6))).tolist()
    top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
    server = route["server"]
    server.send(json.dumps({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [top]}))
    for seq in range(1, 7):
        server.send(json.dumps({"type": "drag", "seq": seq, "transforms": [translation(0.2 * seq, 0.1 * seq)]}))
        page.wait_for_function(f"() => window.__arap.lastSeq === {seq}", timeout=scaled_ms(30))
    held = positions(page).astype("<f4")
    normals = np.asarray(page.evaluate("() => window.__arap.normals()")).reshape(-1, 3)
    faces = np.asarray(page.evaluate("() => window.__arap.faces()")).reshape(-1, 3)
    server.send(json.dumps({"type": "export", "format": "ply"}))
    page_wait_until(page, lambda: exported, 30, "the export answer")
    assert any(h["subset"] >= 0 and h["seq"] >= 0 for h in seen), "the drags should be answered by subset frames"
    full = _ply_vertices(exported[0]).astype("<f4")  # what a full frame of this shape carries
    assert not np.array_equal(full, V.astype("<f4")), "the shape did not move"
    np.testing.assert_array_equal(held.view("<u4"), full.view("<u4"))
    # the normals updated around the moved region are those of the whole shape
    P = held.astype(np.float64)
    face_normals = np.cross(P[faces[:, 2]] - P[faces[:, 1]], P[faces[:, 0]] - P[faces[:, 1]])
    expected = np.zeros_like(P)
    for k in range(3):
        np.add.at(expected, faces[:, k], face_normals)
    expected /= np.maximum(np.linalg.norm(expected, axis=1, keepdims=True), 1e-300)
    assert np.abs(normals - expected).max() < 1e-3
    context.close()


def test_normals_kept_per_frame_equal_a_full_recomputation(browser: Browser, server_url: str) -> None:
    """After subset frames (normals recomputed only around the moved vertices), after a full frame and after
    subset frames again, every normal and the bounds equal those recomputed from the whole shape."""
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    route: dict[str, WebSocketRoute] = {}
    kinds: list[int] = []

    def relay(ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()
        route["server"] = server

        def from_server(message: str | bytes) -> None:
            if isinstance(message, bytes):
                header, _ = decode_binary(message)
                if header["type"] == "vertices" and header["seq"] >= 0:
                    kinds.append(header["subset"])
            ws.send(message)

        server.on_message(from_server)
        ws.on_message(lambda message: server.send(message))

    page.route_web_socket("**/ws", relay)
    page.goto(server_url)
    wait_ready(page)
    V = positions(page)
    y = V[:, 1]
    roi = np.flatnonzero(y >= np.quantile(y, 0.6)).tolist()
    fixed = np.flatnonzero((y >= np.quantile(y, 0.6)) & (y <= np.quantile(y, 0.65))).tolist()
    top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
    server = route["server"]

    def check(label: str) -> None:
        # one evaluation: no frame (settling streams them) can land between the readings
        got = page.evaluate("() => { const a = window.__arap; return { kept: a.normals(), full: "
                            "a.recomputedNormals(), pos: a.positions(), bounds: a.bounds() }; }")
        kept = np.asarray(got["kept"], dtype=np.float32)
        full = np.asarray(got["full"], dtype=np.float32)
        assert len(kept) == 3 * len(V)
        np.testing.assert_allclose(kept, full, rtol=0, atol=1e-6, err_msg=label)
        P = np.asarray(got["pos"], dtype=np.float64).reshape(-1, 3)
        b = got["bounds"]
        np.testing.assert_allclose(b["min"], P.min(axis=0), rtol=0, atol=1e-6, err_msg=label)
        np.testing.assert_allclose(b["max"], P.max(axis=0), rtol=0, atol=1e-6, err_msg=label)
        radius = np.linalg.norm(P - np.asarray(b["center"]), axis=1).max()
        assert abs(b["radius"] - radius) < 1e-5 * max(1.0, radius), label

    seq = 0
    for rounds, region in ((4, roi), (3, None), (4, roi)):  # subset frames, full frames, subset frames again
        server.send(json.dumps({"type": "set_constraints", "roi": region, "fixed": fixed, "handle_groups": [top]}))
        for _ in range(rounds):
            seq += 1
            server.send(json.dumps({"type": "drag", "seq": seq, "transforms": [translation(0.1 * seq, 0.05 * seq)]}))
            page.wait_for_function(f"() => window.__arap.lastSeq === {seq}", timeout=scaled_ms(30))
        check(f"after drag {seq} (region {'20%' if region else 'whole mesh'})")
        server.send(json.dumps({"type": "end_drag"}))
    assert kinds[:4][0] < 0 and all(k >= 0 for k in kinds[1:4]), f"expected a full frame then subset frames: {kinds}"
    assert all(k < 0 for k in kinds[4:7]), f"the whole mesh as region should give full frames: {kinds}"
    assert any(k >= 0 for k in kinds[8:]), kinds
    context.close()
