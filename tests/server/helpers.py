"""A small protocol client around Starlette's TestClient WebSocket, transform helpers, and a live server."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from arap.server import make_server
from arap.server.frames import decode_binary, encode_binary
from tests.waiting import wait_until


@dataclass
class Reply:
    """One server message: JSON fields (text message or binary header) and the payload of a binary one."""

    data: dict[str, Any]
    payload: bytes | None = None
    positions: np.ndarray | None = None
    """All positions (float32) after a ``vertices`` frame, subset frames applied to the ones before."""

    @property
    def type(self) -> str:
        return self.data["type"]

    def floats(self) -> np.ndarray:
        if self.positions is not None:
            return self.positions.astype(np.float64)
        assert self.payload is not None
        return np.frombuffer(self.payload, dtype="<f4").reshape(-1, 3).astype(np.float64)


def apply_vertices(held: np.ndarray, movable: np.ndarray | None, header: dict[str, Any],
                   payload: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    """A client's float32 positions ``(n, 3)`` and movable list after one ``vertices`` frame, as the browser does."""
    if header["subset"] < 0:
        k = header["movable"]
        cut = len(payload) - 4 * k
        held = np.frombuffer(payload[:cut], dtype="<f4").reshape(-1, 3).copy()
        return held, (np.frombuffer(payload[cut:], dtype="<u4").astype(np.int64) if k else None)
    assert movable is not None and len(movable) == header["subset"], "subset frame without its movable list"
    held = held.copy()
    held[movable] = np.frombuffer(payload, dtype="<f4").reshape(-1, 3)
    return held, movable


def translation(dx: float, dy: float = 0.0, dz: float = 0.0) -> list[float]:
    """Column-major 4x4 translation (Three.js Matrix4.elements)."""
    M = np.eye(4)
    M[:3, 3] = (dx, dy, dz)
    return M.T.reshape(16).tolist()


def rotation_z(angle: float, center: np.ndarray, shift: tuple[float, float, float] = (0, 0, 0)) -> np.ndarray:
    """Row-major 4x4: rotate about the z axis through ``center``, then shift."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = center - R @ center + np.asarray(shift)
    return M


def column_major(M: np.ndarray) -> list[float]:
    return M.T.reshape(16).tolist()


@dataclass
class StudioClient:
    """Protocol-level helper around a TestClient WebSocket session."""

    ws: Any
    welcome: dict[str, Any] = field(default_factory=dict)
    V: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    F: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int64))
    state: dict[str, Any] = field(default_factory=dict)
    held: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype="<f4"))
    movable: np.ndarray | None = None
    vertex_map: np.ndarray | None = None
    """Mesh vertex of each vertex of the uploaded file when repair renumbered them (the ``mesh`` frame's map)."""

    def recv(self) -> Reply:
        message = self.ws.receive()
        assert message["type"] == "websocket.send", message
        if message.get("text") is not None:
            return Reply(json.loads(message["text"]))
        header, payload = decode_binary(message["bytes"])
        assert (len(message["bytes"]) - len(payload)) % 4 == 0, "payload not 4-byte aligned"
        reply = Reply(header, bytes(payload))
        if header["type"] == "vertices":
            self.held, self.movable = apply_vertices(self.held, self.movable, header, reply.payload)
            reply.positions = self.held
        return reply

    def expect(self, type_: str) -> Reply:
        reply = self.recv()
        # settling progress, checked in test_settle.py; compile progress before the welcome, in test_preparing.py
        while reply.type in ("settle", "preparing") and type_ != reply.type:
            reply = self.recv()
        assert reply.type == type_, f"expected {type_}, got {reply.data}"
        if type_ == "state":
            self.state = reply.data
        return reply

    def settled(self) -> tuple[dict[str, Any], np.ndarray | None]:
        """Read up to the end of a settling run: its last ``settle`` message and the last frame it streamed."""
        frame = None
        while True:
            reply = self.recv()
            if reply.type == "vertices":
                assert reply.data["seq"] == -1, reply.data
                frame = reply.floats()
            elif reply.type == "settle" and reply.data["status"] != "settling":
                return reply.data, frame
            else:
                assert reply.type == "settle", f"expected settling, got {reply.data}"

    def error(self, code: str | None = None) -> dict[str, Any]:
        reply = self.expect("error").data
        if code is not None:
            assert reply["code"] == code, reply
        return reply

    def send(self, message: dict[str, Any] | str) -> None:
        if isinstance(message, str):
            self.ws.send_text(message)
        else:
            self.ws.send_text(json.dumps(message))

    def send_binary(self, header: dict[str, Any], payload: bytes = b"") -> None:
        self.ws.send_bytes(encode_binary(header, payload))

    def read_mesh(self) -> Reply:
        reply = self.expect("mesh")
        n, m, k = reply.data["n_vertices"], reply.data["n_faces"], reply.data["file_vertices"]
        assert reply.payload is not None and len(reply.payload) == 12 * n + 12 * m + 4 * k
        self.vertex_map = np.frombuffer(reply.payload[12 * (n + m):], dtype="<i4").astype(np.int64) if k else None
        self.V = np.frombuffer(reply.payload[: 12 * n], dtype="<f4").reshape(n, 3).astype(np.float64)
        self.F = np.frombuffer(reply.payload[12 * n : 12 * (n + m)], dtype="<u4").reshape(m, 3).astype(np.int64)
        self.held = np.frombuffer(reply.payload[: 12 * n], dtype="<f4").reshape(n, 3).copy()
        self.movable = None
        return reply

    def greet(self) -> None:
        self.welcome = self.expect("welcome").data
        self.read_mesh()
        self.expect("state")

    # ------------------------------------------------------------------ common requests
    def set_constraints(self, fixed: list[int], groups: list[list[int]], roi: list[int] | None = None) -> dict:
        self.send({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": groups})
        return self.expect("state").data

    def drag(self, seq: int, transforms: list[list[float]]) -> Reply:
        self.send({"type": "drag", "seq": seq, "transforms": transforms})
        reply = self.expect("vertices")
        assert reply.data["seq"] == seq
        return reply

    def bottom_top(self, share: float = 0.1) -> tuple[list[int], list[int]]:
        """Lowest and highest ``share`` of the vertices along y."""
        y = self.V[:, 1]
        lo = np.flatnonzero(y <= np.quantile(y, share)).tolist()
        hi = np.flatnonzero(y >= np.quantile(y, 1 - share)).tolist()
        return lo, hi

    def ping(self) -> None:
        """Round trip proving the session still answers."""
        self.send({"type": "get_constraints"})
        self.expect("constraints")


@contextmanager
def running_server(**options: Any) -> Iterator[str]:
    """The studio served on a free loopback port in a thread (``make_server`` options); yields its URL."""
    with serving(**options) as (_, url):
        yield url


@contextmanager
def serving(**options: Any) -> Iterator[tuple[Any, str]]:
    """:func:`running_server` that yields the uvicorn server too, and its URL."""
    server, sock, url = make_server("bar", port=0, **options)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started, 30, "the server to start")
    try:
        yield server, url
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()



def renumbered_bar_obj() -> tuple[str, np.ndarray]:
    """:func:`renumbered_obj` of the built-in bar."""
    import arap

    return renumbered_obj(*arap.builtin_mesh("bar"))


def renumbered_obj(V: np.ndarray, F: np.ndarray) -> tuple[str, np.ndarray]:
    """OBJ text of a clean mesh that mesh repair renumbers, and the map it gives (file vertex → mesh vertex).

    The file has a vertex that no face uses first (dropped by repair), then the mesh's vertices, then copies of its
    lowest, middle and highest vertex along y, each used by one face instead of the original (welded back by
    repair). The repaired mesh is ``(V, F)`` itself.
    """
    n = len(V)
    y = V[:, 1]
    picks = [int(np.argmin(y)), int(np.argmin(np.abs(y - 0.5 * (y.min() + y.max())))), int(np.argmax(y))]
    file_V = np.concatenate([[[9.0, 9.0, 9.0]], V, V[picks]])
    file_F = F + 1
    for j, v in enumerate(picks):
        f = int(np.flatnonzero((F == v).any(axis=1))[0])
        file_F[f][file_F[f] == v + 1] = n + 1 + j
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in file_V.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in file_F.tolist()]
    vertex_map = np.concatenate([[-1], np.arange(n), picks]).astype(np.int64)
    return "\n".join(lines) + "\n", vertex_map
