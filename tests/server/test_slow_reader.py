"""A page that reads slowly keeps its connection through a long settle of a large mesh: the server sends a
``vertices`` frame only once the client has taken the one before, keeps only the newest shape waiting, and the
keepalive pings are never stuck behind a backlog of frames."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import pytest
import trimesh
from websockets.sync.client import connect

import arap
from arap.server import make_server
from arap.server.frames import decode_binary
from arap.server.mesh_model import MeshData
from arap.server.runner import kernel_unsent_bytes
from tests.server.helpers import apply_vertices, translation
from tests.waiting import scaled, wait_until

pytestmark = pytest.mark.timeout(240)

READ_BYTES_PER_SECOND = 1_000_000
"""The slow page: about two frames of the test mesh a second (a large scan's frames are read at ~1.5 a second)."""
RECEIVE_BUFFER = 64 * 1024
"""The page's socket receive buffer: small, so that what the server queues stays in the server's socket."""


def _mesh() -> MeshData:
    """The built-in cylinder subdivided once: 26k vertices, 310 KB vertices frames, slow to settle when bent."""
    V, F = arap.builtin_mesh("cylinder")
    V, F = trimesh.remesh.subdivide(V, F)
    return MeshData.make("tall", V, F)


@contextmanager
def _studio(mesh: MeshData) -> Iterator[tuple[Any, str]]:
    """The studio served in a thread with keepalive pings every second (a pong must come within 10 s)."""
    server, sock, url = make_server(mesh, port=0)
    server.config.ws_ping_interval = 1.0
    server.config.ws_ping_timeout = 10.0
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started, 30, "the server to start")
    try:
        yield server, url
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()


def _queued_bytes(server: Any) -> int:
    """Bytes the server has written to its WebSocket connections that their clients have not taken: the transports'
    buffers and the sockets' unacknowledged send queues."""
    total = 0
    for protocol in list(server.server_state.connections):
        transport = getattr(protocol, "transport", None)
        if transport is None or transport.is_closing():
            continue
        total += transport.get_write_buffer_size() + kernel_unsent_bytes(transport.get_extra_info("socket"))
    return total


def _connect(url: str) -> Any:
    """A WebSocket client connection to the studio at ``url`` (a context manager) through a socket with a small
    receive buffer, whose library reads ahead at most one message: what the client does not take stays queued in
    the server's socket, and the server's pings are answered only once the messages before them are read."""
    parts = urlsplit(url)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
    sock.connect((parts.hostname, parts.port))
    return connect(f"ws://{parts.hostname}:{parts.port}/ws", sock=sock, compression=None, max_queue=1,
                   max_size=None, ping_interval=None, proxy=None, open_timeout=scaled(30))


class _SlowPage:
    """A client that, once ``slow``, takes ``READ_BYTES_PER_SECOND`` to read each message, holding the frames as the
    page does."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.held = np.zeros((0, 3), dtype="<f4")
        self.movable: np.ndarray | None = None
        self.frames = 0
        self.slow = False

    def recv(self) -> dict[str, Any]:
        message = self.ws.recv(timeout=scaled(60))
        if self.slow:
            time.sleep(len(message) / READ_BYTES_PER_SECOND)
        if isinstance(message, str):
            return json.loads(message)
        header, payload = decode_binary(message)
        if header["type"] == "mesh":
            n = header["n_vertices"]
            self.held = np.frombuffer(bytes(payload[: 12 * n]), dtype="<f4").reshape(n, 3).copy()
            self.movable = None
        elif header["type"] == "vertices":
            self.held, self.movable = apply_vertices(self.held, self.movable, header, bytes(payload))
            self.frames += 1
        return header

    def expect(self, kind: str) -> dict[str, Any]:
        while True:
            message = self.recv()
            if message["type"] == kind:
                return message
            assert message["type"] in ("settle", "vertices", "appearance"), message

    def settled(self) -> dict[str, Any]:
        while True:
            message = self.recv()
            if message["type"] == "settle" and message["status"] != "settling":
                return message
            assert message["type"] in ("settle", "vertices"), message

    def send(self, message: dict[str, Any]) -> None:
        self.ws.send(json.dumps(message))


def test_a_slow_page_keeps_its_connection_and_gets_the_settled_shape() -> None:
    mesh = _mesh()
    frame_bytes = 12 * mesh.n_vertices
    with _studio(mesh) as (server, url), ExitStack() as stack:
        page = _SlowPage(stack.enter_context(_connect(url)))
        page.expect("welcome")
        page.expect("mesh")
        page.expect("state")
        V = page.held.astype(np.float64)
        y = V[:, 1]
        fixed = np.flatnonzero(y <= np.quantile(y, 0.05)).tolist()
        top = np.flatnonzero(y >= np.quantile(y, 0.95)).tolist()
        page.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
        page.expect("state")
        page.settled()
        diagonal = float(np.linalg.norm(np.ptp(V, axis=0)))
        page.send({"type": "drag", "seq": 0, "transforms": [translation(0.6 * diagonal, -0.2 * diagonal)]})
        page.expect("vertices")
        page.send({"type": "end_drag"})
        page.expect("state")  # settling starts

        peak = [0]
        done = threading.Event()

        def sample() -> None:
            while not done.is_set():
                peak[0] = max(peak[0], _queued_bytes(server))
                time.sleep(0.005)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        page.slow = True
        started = time.monotonic()
        try:
            status = page.settled()
        finally:
            done.set()
            sampler.join()
        seconds = time.monotonic() - started
        page.slow = False
        connection = next(iter(server.config.app.state.studio.connections))
        superseded = getattr(connection, "superseded", None)
        print(f"settled after {status['iterations']} iterations in {seconds:.1f} s; {page.frames} frames read, "
              f"{superseded} superseded; at most {peak[0]:,} bytes queued ({frame_bytes:,} a frame)")
        assert status["status"] == "settled", status
        # never more than the newest frame waiting for the slow page (and the small messages around it)
        assert peak[0] <= 1.5 * frame_bytes, f"{peak[0]:,} bytes queued for the page, frames of {frame_bytes:,}"
        assert superseded, "the settle should be long enough for the page to miss shapes"
        # the page holds the settled shape: the session's, to the float32 rounding of the frames
        U = connection.session.U
        assert np.abs(page.held - U).max() <= 1e-6 * diagonal
        # and its connection still answers
        page.send({"type": "get_constraints"})
        page.expect("constraints")
