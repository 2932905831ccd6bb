"""Who may use the studio: Host and Origin checks (cross-site WebSocket hijacking, DNS rebinding), session cap."""

from __future__ import annotations

import contextlib
import json
import logging
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from starlette.testclient import TestClient, WebSocketDenialResponse
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from arap.cli import build_parser
from arap.server import create_app
from arap.server.guard import RequestGuard, normalize_origin, split_host
from tests.server.helpers import StudioClient, serving
from tests.waiting import wait_until

pytestmark = pytest.mark.timeout(120)


def _guard(**kwargs: Any) -> RequestGuard:
    async def app(scope: Any, receive: Any, send: Any) -> None:
        raise AssertionError("not called")

    return RequestGuard(app, **kwargs)


@pytest.mark.parametrize(
    ("host", "bind", "allowed"),
    [
        ("127.0.0.1:8000", None, True),
        ("localhost:8000", None, True),
        ("LOCALHOST.:8000", "127.0.0.1", True),
        ("[::1]:8000", None, True),
        ("evil.example:8000", None, False),
        ("evil.example", "127.0.0.1", False),
        ("127.0.0.1.evil.example:8000", None, False),
        ("", None, False),
        (None, None, False),
        ("127.0.0.1:80x", None, False),
        ("192.168.1.7:8000", None, False),
        ("192.168.1.7:8000", "192.168.1.7", True),
        ("192.168.1.7:8000", "0.0.0.0", True),
        ("[fe80::1]:8000", "::", True),
        ("rebound.example:8000", "0.0.0.0", False),
    ],
)
def test_host_header(host: str | None, bind: str | None, allowed: bool) -> None:
    assert _guard(bind_host=bind).host_allowed(host) is allowed


@pytest.mark.parametrize(
    ("origin", "allowed"),
    [
        (None, True),
        ("http://127.0.0.1:8000", True),
        ("HTTP://127.0.0.1:8000", True),
        ("http://localhost:8000", False),  # another origin, even if it is this machine
        ("http://127.0.0.1:8001", False),
        ("https://127.0.0.1:8000", False),
        ("http://evil.example", False),
        ("null", False),
        ("file://", False),
        ("", False),
        ("http://trusted.example:3000", True),
        ("http://trusted.example", False),
    ],
)
def test_origin_header(origin: str | None, allowed: bool) -> None:
    guard = _guard(allow_origins=["http://trusted.example:3000"])
    assert guard.origin_allowed(origin, "127.0.0.1:8000", "ws") is allowed


def test_host_and_origin_helpers() -> None:
    assert split_host("[::1]:9000") == ("::1", 9000)
    assert split_host("Example.ORG") == ("example.org", None)
    assert normalize_origin("https://Example.org") == "https://example.org:443"
    with pytest.raises(ValueError, match="origin"):
        normalize_origin("null")
    with pytest.raises(ValueError, match="origin"):
        create_app("bar", allow_origins=["evil.example"])


# ---------------------------------------------------------------------------------------------- in process
@pytest.fixture
def guarded(static_dir: Path) -> Iterator[TestClient]:
    app = create_app("bar", static_dir=static_dir, allowed_hosts=["testserver"],
                     allow_origins=["http://trusted.example:3000"])
    with TestClient(app) as client:
        yield client


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "http://testserver:8001", "https://testserver"])
def test_foreign_origin_cannot_open_a_session(guarded: TestClient, origin: str) -> None:
    with pytest.raises(WebSocketDenialResponse) as refused:
        with guarded.websocket_connect("/ws", headers={"origin": origin}):
            pass
    assert refused.value.status_code == 403
    assert "origin" in refused.value.text and "--allow-origin" in refused.value.text


@pytest.mark.parametrize("origin", [None, "http://testserver", "http://testserver:80", "http://trusted.example:3000"])
def test_own_and_allowed_origins_open_a_session(guarded: TestClient, origin: str | None) -> None:
    headers = {"origin": origin} if origin else {}
    with guarded.websocket_connect("/ws", headers=headers) as ws:
        client = StudioClient(ws)
        client.greet()
        client.ping()


def test_foreign_host_is_refused(guarded: TestClient) -> None:
    with pytest.raises(WebSocketDenialResponse) as refused:
        with guarded.websocket_connect("/ws", headers={"host": "rebound.example:8000"}):
            pass
    assert refused.value.status_code == 403 and "host" in refused.value.text
    assert guarded.get("/", headers={"host": "rebound.example:8000"}).status_code == 403
    # the host of an allowed origin is accepted (a reverse proxy in front of the studio)
    with guarded.websocket_connect("/ws", headers={"host": "trusted.example:3000"}) as ws:
        StudioClient(ws).greet()


def test_http_requests_are_guarded_too(guarded: TestClient) -> None:
    assert guarded.get("/").status_code == 200
    assert guarded.get("/", headers={"origin": "http://testserver"}).status_code == 200
    for path in ("/", "/healthz", "/assets/app.js"):
        refused = guarded.get(path, headers={"origin": "http://evil.example"})
        assert refused.status_code == 403 and "origin" in refused.text


def test_in_process_app_accepts_only_loopback_hosts_by_default(static_dir: Path) -> None:
    with TestClient(create_app("bar", static_dir=static_dir)) as client:
        assert client.get("/healthz").status_code == 403  # Host: testserver
        assert client.get("/healthz", headers={"host": "localhost:8000"}).status_code == 200


def test_session_cap_refuses_politely(static_dir: Path) -> None:
    app = create_app("bar", static_dir=static_dir, allowed_hosts=["testserver"], max_sessions=2)
    with TestClient(app) as http:
        with http.websocket_connect("/ws") as a, http.websocket_connect("/ws") as b:
            for ws in (a, b):
                StudioClient(ws).greet()
            with http.websocket_connect("/ws") as c:
                error = c.receive_json()
                assert error["type"] == "error" and error["code"] == "busy"
                assert "2 sessions" in error["message"]
                closed = c.receive()
                assert closed["type"] == "websocket.close" and closed["code"] == 1013
                assert "2 sessions" in closed["reason"]
            assert http.get("/healthz").json()["sessions"] == 2
        wait_until(lambda: http.get("/healthz").json()["sessions"] == 0, 10, "the sessions to be released")
        with http.websocket_connect("/ws") as again:
            StudioClient(again).greet()


def test_cli_options() -> None:
    args = build_parser().parse_args(["studio", "--max-sessions", "4", "--allow-origin", "http://a.example:3000",
                                      "--allow-origin", "https://b.example"])
    assert args.max_sessions == 4 and args.allow_origin == ["http://a.example:3000", "https://b.example"]
    assert build_parser().parse_args(["studio"]).max_sessions == 32
    for bad in (["--max-sessions", "0"], ["--allow-origin", "null"], ["--allow-origin", "evil.example"]):
        with pytest.raises(SystemExit) as exited:
            build_parser().parse_args(["studio", *bad])
        assert exited.value.code == 2


# ---------------------------------------------------------------------------------------------- real server
@pytest.fixture
def live() -> Iterator[tuple[Any, str]]:
    """The uvicorn server and its URL."""
    with serving(max_sessions=3) as (server, url):
        yield server, url


@pytest.fixture
def live_url(live: tuple[Any, str]) -> str:
    return live[1]


def test_live_server_refuses_cross_site_and_rebound_requests(live_url: str) -> None:
    ws_url = live_url.replace("http://", "ws://") + "ws"
    for origin in ("http://evil.example", "null"):
        with pytest.raises(InvalidStatus) as refused:
            connect(ws_url, origin=origin, open_timeout=10)  # type: ignore[arg-type]
        assert refused.value.response.status_code == 403
    with connect(ws_url, origin=live_url.rstrip("/"), open_timeout=10, max_size=None) as ws:  # type: ignore[arg-type]
        assert json.loads(ws.recv(timeout=30))["type"] == "welcome"
    port = live_url.rsplit(":", 1)[1].rstrip("/")
    assert httpx.get(live_url + "healthz", timeout=10).status_code == 200
    assert httpx.get(live_url + "healthz", headers={"host": f"localhost:{port}"}, timeout=10).status_code == 200
    rebound = httpx.get(live_url + "healthz", headers={"host": f"rebound.example:{port}"}, timeout=10)
    assert rebound.status_code == 403


def test_live_server_caps_sessions(live_url: str) -> None:
    ws_url = live_url.replace("http://", "ws://") + "ws"
    with contextlib.ExitStack() as stack:
        opened = [stack.enter_context(connect(ws_url, open_timeout=10, max_size=None)) for _ in range(3)]
        for ws in opened:
            assert json.loads(ws.recv(timeout=30))["type"] == "welcome"
        with connect(ws_url, open_timeout=10) as extra:
            error = json.loads(extra.recv(timeout=30))
            assert error["code"] == "busy"
            with pytest.raises(ConnectionClosed) as closed:
                extra.recv(timeout=30)
            rcvd = closed.value.rcvd
            assert rcvd is not None and rcvd.code == 1013 and "3 sessions" in rcvd.reason


def test_a_refused_websocket_is_logged_once_with_its_reason(live: tuple[Any, str],
                                                            caplog: pytest.LogCaptureFixture) -> None:
    """uvicorn logged every refused handshake as an ERROR without context; the studio logs the reason instead."""
    errors: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            errors.append(record)

    uvicorn_log = logging.getLogger("uvicorn.error")
    keep = Keep(level=logging.ERROR)
    uvicorn_log.addHandler(keep)
    caplog.set_level(logging.INFO, logger="arap.server.guard")
    try:
        server, live_url = live
        ws_url = live_url.replace("http://", "ws://") + "ws"
        with pytest.raises(InvalidStatus):
            connect(ws_url, origin="http://evil.example", open_timeout=10)  # type: ignore[arg-type]
        # the server's task ends (and logs what it logs) after the client has its answer
        wait_until(lambda: not server.server_state.connections and not server.server_state.tasks, 10,
                   "the server to finish the refused connection")
    finally:
        uvicorn_log.removeHandler(keep)
    assert not [r for r in errors if "handshake" in r.getMessage()]
    assert any("evil.example" in r.getMessage() and "--allow-origin" in r.getMessage() for r in caplog.records)
