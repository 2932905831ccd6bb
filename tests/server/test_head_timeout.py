"""Connections that never finish a request (slowloris) are closed after a bounded time; requests that did finish,
kept-alive connections between requests and WebSockets are not cut."""

from __future__ import annotations

import asyncio
import json
import select
import socket
import threading
import time
from collections.abc import Iterator
from urllib.parse import urlsplit

import pytest
import uvicorn
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol
from websockets.sync.client import connect

from arap.server import bind_socket, create_app, make_server
from arap.server.headtimeout import DEFAULT_HEAD_TIMEOUT, head_timeout_protocol
from tests.waiting import wait_until

pytestmark = pytest.mark.timeout(120)

TIMEOUT = 1.0
"""Head timeout of the servers under test (seconds)."""


def _serve(base: type[asyncio.Protocol]) -> Iterator[int]:
    app = create_app("bar")
    config = uvicorn.Config(app, http=head_timeout_protocol(TIMEOUT, base), log_level="warning", lifespan="off",
                            ws_per_message_deflate=False)
    server = uvicorn.Server(config)
    sock = bind_socket("127.0.0.1", 0)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started, 30, "the server to start")
    try:
        yield int(sock.getsockname()[1])
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()


@pytest.fixture(params=[HttpToolsProtocol, H11Protocol], ids=["httptools", "h11"])
def port(request: pytest.FixtureRequest) -> Iterator[int]:
    yield from _serve(request.param)


def _closed_by_server(sock: socket.socket) -> bool:
    """Whether the server closed the connection (what is readable is an end of stream, or a reset)."""
    try:
        return sock.recv(65536) == b""
    except (ConnectionResetError, BlockingIOError):
        return True


def _wait_closed(socks: list[socket.socket], limit: float, trickle: socket.socket | None = None) -> list[float]:
    """Seconds until each socket was closed by the server (inf when still open after ``limit``); ``trickle`` is sent
    a byte of a header every 0.2 s meanwhile."""
    start = time.monotonic()
    closed = [float("inf")] * len(socks)
    open_ = dict(enumerate(socks))
    next_byte = start
    while open_ and time.monotonic() - start < limit:
        if trickle is not None and time.monotonic() >= next_byte:
            try:
                trickle.send(b"x")
            except OSError:
                pass
            next_byte += 0.2
        readable, _, _ = select.select(list(open_.values()), [], [], 0.05)
        for k, s in list(open_.items()):
            if s in readable and _closed_by_server(s):
                closed[k] = time.monotonic() - start
                del open_[k]
    return closed


def test_half_sent_requests_are_closed_in_bounded_time(port: int) -> None:
    heads = [b"", b"GET / HT", b"GET / HTTP/1.1\r\n", f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode(),
             b"GET /ws HTTP/1.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"]
    socks = []
    try:
        for k in range(100):
            s = socket.create_connection(("127.0.0.1", port), timeout=10)
            s.sendall(heads[k % len(heads)]) if heads[k % len(heads)] else None
            socks.append(s)
        slow = socket.create_connection(("127.0.0.1", port), timeout=10)
        slow.sendall(b"GET / HTTP/1.1\r\nX-Slow: ")
        socks.append(slow)
        closed = _wait_closed(socks, TIMEOUT + 6, trickle=slow)
        assert max(closed) <= TIMEOUT + 4, f"{sum(t == float('inf') for t in closed)} connections still open"
        # The slow client kept sending bytes: the deadline counts from its first one, not its last.
        assert closed[-1] <= TIMEOUT + 2
    finally:
        for s in socks:
            s.close()


def _get(sock: socket.socket, port: int) -> dict[str, object]:
    sock.sendall(f"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
    data = b""
    while not data.endswith(b"}"):
        chunk = sock.recv(65536)
        assert chunk, "closed before the answer"
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 200")
    result: dict[str, object] = json.loads(body)
    return result


def test_complete_requests_are_answered_and_a_next_half_sent_one_is_closed(port: int) -> None:
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        assert _get(s, port)["status"] == "ok"
        # the scenario: idle between requests for longer than the head timeout; uvicorn's keep-alive timeout (5 s)
        # applies, not ours
        time.sleep(TIMEOUT * 1.5)
        assert _get(s, port)["status"] == "ok"
        s.sendall(b"GET /healthz HTTP/1.1\r\nHo")
        closed = _wait_closed([s], TIMEOUT + 6)
        assert closed[0] <= TIMEOUT + 2  # well before the keep-alive timeout


def test_a_websocket_outlives_the_head_timeout(port: int) -> None:
    with connect(f"ws://127.0.0.1:{port}/ws", max_size=None) as ws:
        assert json.loads(ws.recv(timeout=30))["type"] == "welcome"
        time.sleep(TIMEOUT * 2.5)  # the scenario: a WebSocket idle for longer than the head timeout is not cut
        ws.send(json.dumps({"type": "get_constraints"}))
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            message = ws.recv(timeout=30)
            if isinstance(message, str) and json.loads(message)["type"] == "constraints":
                break
        else:
            pytest.fail("no answer")


def test_the_studio_server_has_a_head_timeout_by_default() -> None:
    assert 0 < DEFAULT_HEAD_TIMEOUT <= 15
    server, sock, url = make_server("bar", "127.0.0.1", 0)
    sock.close()
    protocol = server.config.http
    assert isinstance(protocol, type) and getattr(protocol, "head_timeout", None) == DEFAULT_HEAD_TIMEOUT
    server, sock, url = make_server("bar", "127.0.0.1", 0, head_timeout=2.5)
    sock.close()
    assert getattr(server.config.http, "head_timeout", None) == 2.5 and urlsplit(url).port
    with pytest.raises(ValueError, match="positive"):
        head_timeout_protocol(0)
