"""Running the real server (uvicorn on a free loopback port) and its URL helper."""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest
from websockets.sync.client import connect

from arap.server import bind_socket, studio_url
from arap.server.frames import decode_binary, encode_binary
from tests.server.helpers import running_server

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize(
    ("host", "port", "url"),
    [
        ("127.0.0.1", 8000, "http://127.0.0.1:8000/"),
        ("0.0.0.0", 8123, "http://127.0.0.1:8123/"),
        ("localhost", 80, "http://localhost:80/"),
        ("::", 9000, "http://[::1]:9000/"),
        ("::1", 9000, "http://[::1]:9000/"),
        ("[::1]", 9000, "http://[::1]:9000/"),
    ],
)
def test_studio_url(host: str, port: int, url: str) -> None:
    assert studio_url(host, port) == url


def test_bind_socket_picks_a_free_port_and_reports_a_busy_one() -> None:
    sock = bind_socket("127.0.0.1", 0)
    try:
        host, port = sock.getsockname()[:2]
        assert host == "127.0.0.1" and port > 0
        with pytest.raises(OSError):
            bind_socket("127.0.0.1", port).close()
    finally:
        sock.close()


@pytest.fixture
def live_url() -> Iterator[str]:
    with running_server(max_upload_bytes=100_000) as url:
        yield url


def test_live_server_refuses_compression_and_serves_the_protocol(live_url: str) -> None:
    assert live_url.startswith("http://127.0.0.1:")
    ws_url = live_url.replace("http://", "ws://") + "ws"
    with connect(ws_url, compression="deflate", max_size=None) as ws:
        assert ws.response is not None
        assert "permessage-deflate" not in (ws.response.headers.get("Sec-WebSocket-Extensions") or "")
        welcome = json.loads(ws.recv())
        assert welcome["type"] == "welcome" and welcome["limits"]["max_upload_bytes"] == 100_000
        header, payload = decode_binary(ws.recv())
        n = header["n_vertices"]
        V = np.frombuffer(bytes(payload[: 12 * n]), dtype="<f4").reshape(n, 3)
        assert json.loads(ws.recv())["type"] == "state"
        y = V[:, 1]
        fixed = np.flatnonzero(y <= np.quantile(y, 0.1)).tolist()
        top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
        ws.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]}))
        assert json.loads(ws.recv())["type"] == "state"
        # The new constraints settle (the shape is already at rest, so no frame is needed).
        while (status := json.loads(ws.recv()))["status"] == "settling":
            pass
        assert status == {**status, "type": "settle", "status": "settled"}
        M = np.eye(4)
        M[1, 3] = 0.5
        ws.send(json.dumps({"type": "drag", "seq": 9, "transforms": [M.T.reshape(16).tolist()]}))
        header, payload = decode_binary(ws.recv())
        assert header["type"] == "vertices" and header["seq"] == 9
        U = np.frombuffer(bytes(payload), dtype="<f4").reshape(n, 3)
        np.testing.assert_allclose(U[top], V[top] + [0, 0.5, 0], atol=1e-5)
        # an upload over the cap but within the frame limit is answered, not dropped
        ws.send(encode_binary({"type": "upload", "filename": "big.obj"}, b"#" * 200_000))
        error = json.loads(ws.recv())
        assert error["code"] == "too_large"


def test_live_server_health(live_url: str) -> None:
    import httpx

    health = httpx.get(live_url + "healthz", timeout=10).json()
    assert health["status"] == "ok"
