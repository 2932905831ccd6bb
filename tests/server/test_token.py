"""A studio with a token (always when it serves a network): every request without it is refused, HTTP and WebSocket;
the command line makes one for a non-loopback ``--host`` and prints it in the URL."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import httpx
import pytest
from starlette.testclient import TestClient, WebSocketDenialResponse
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

import arap.server
from arap.cli import build_parser, main
from arap.server import create_app, make_server, studio_url
from arap.server.guard import is_loopback_host, presented_token, token_matches
from tests.server.helpers import StudioClient
from tests.waiting import wait_until

pytestmark = pytest.mark.timeout(120)

TOKEN = "s3cret-Token_0123456789abcdefghij"


@pytest.fixture
def tokened(static_dir: Path) -> Iterator[TestClient]:
    app = create_app("bar", static_dir=static_dir, allowed_hosts=["testserver"], token=TOKEN)
    with TestClient(app) as client:
        yield client


def test_helpers() -> None:
    assert presented_token({"query_string": b"a=1&token=abc%20d", "headers": []}) == "abc d"
    assert presented_token({"query_string": b"", "headers": [(b"authorization", b"Token xyz")]}) == "xyz"
    assert presented_token({"query_string": b"", "headers": [(b"authorization", b"Bearer xyz")]}) == "xyz"
    assert presented_token({"query_string": b"", "headers": [(b"authorization", b"Basic eHl6")]}) is None
    assert token_matches("abc", "abc") and not token_matches("abd", "abc") and not token_matches(None, "abc")
    assert not token_matches("abc\udcff", "abc")  # undecodable bytes from a query do not raise
    for host, loop in (("127.0.0.1", True), ("127.3.2.1", True), ("localhost", True), ("::1", True),
                       ("0.0.0.0", False), ("::", False), ("", False), ("192.168.1.7", False), ("box.lan", False)):
        assert is_loopback_host(host) is loop, host
    assert studio_url("::", 80, token="a b/c") == "http://[::1]:80/?token=a%20b%2Fc"
    with pytest.raises(ValueError, match="token"):
        create_app("bar", token="")


@pytest.mark.parametrize("path", ["/", "/index.html", "/healthz", "/nothing-here"])
def test_http_without_the_token_is_refused(tokened: TestClient, path: str) -> None:
    for params, headers in (({}, {}), ({"token": ""}, {}), ({"token": TOKEN[:-1]}, {}), ({"token": TOKEN + "x"}, {}),
                            ({}, {"authorization": f"token {TOKEN[1:]}"})):
        refused = tokened.get(path, params=params, headers=headers)
        assert refused.status_code == 403 and "token" in refused.text, (params, headers)
    assert tokened.get(path, params={"token": TOKEN}).status_code != 403
    assert tokened.get(path, headers={"authorization": f"token {TOKEN}"}).status_code != 403


def test_the_page_and_the_client_files_load_with_the_token(tokened: TestClient) -> None:
    assert tokened.get("/", params={"token": TOKEN}).status_code == 200
    assert tokened.get("/healthz", params={"token": TOKEN}).json()["status"] == "ok"
    # The page's scripts are fetched without the token (the same code as in the package, no data).
    assert tokened.get("/assets/app.js").status_code == 200
    assert tokened.post("/assets/app.js").status_code == 403
    assert tokened.get("/assets/../index.html").status_code in (403, 404)
    # Host and Origin are still checked, token or not.
    refused = tokened.get("/", params={"token": TOKEN}, headers={"origin": "http://evil.example"})
    assert refused.status_code == 403 and "origin" in refused.text
    assert tokened.get("/assets/app.js", headers={"host": "rebound.example"}).status_code == 403


@pytest.mark.parametrize("query", ["", "?token=", f"?token={TOKEN[:-1]}", "?tok=" + TOKEN])
def test_websocket_without_the_token_is_refused(tokened: TestClient, query: str) -> None:
    with pytest.raises(WebSocketDenialResponse) as refused:
        with tokened.websocket_connect("/ws" + query):
            pass
    assert refused.value.status_code == 403 and "token" in refused.value.text


def test_websocket_with_the_token_opens_a_session(tokened: TestClient) -> None:
    with tokened.websocket_connect(f"/ws?token={TOKEN}", headers={"origin": "http://testserver"}) as ws:
        client = StudioClient(ws)
        client.greet()
        client.ping()


def test_a_loopback_server_needs_no_token_unless_given_one() -> None:
    _, sock, url = make_server("bar", "127.0.0.1", 0)
    sock.close()
    assert "token" not in url
    _, sock, url = make_server("bar", "127.0.0.1", 0, token="mine")
    sock.close()
    assert url.endswith("/?token=mine")


def _serve(host: str, **options: Any) -> tuple[Any, Any, str, threading.Thread]:
    server, sock, url = make_server("bar", host, 0, **options)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started, 30, "the server to start")
    return server, sock, url, thread


def test_a_network_server_gets_a_random_token_and_refuses_requests_without_it() -> None:
    server, sock, url, thread = _serve("0.0.0.0")
    try:
        parts = urlsplit(url)
        token = parse_qs(parts.query)["token"][0]
        assert len(token) >= 32 and parts.hostname == "127.0.0.1"
        page = f"http://127.0.0.1:{parts.port}/"
        assert httpx.get(page).status_code == 403
        assert httpx.get(f"{page}healthz").status_code == 403
        assert httpx.get(f"{page}healthz", params={"token": token}).status_code == 200
        assert httpx.get(url).status_code != 403
        ws = f"ws://127.0.0.1:{parts.port}/ws"
        with pytest.raises(InvalidStatus) as refused:
            connect(ws, open_timeout=10).close()
        assert refused.value.response.status_code == 403
        with connect(f"{ws}?token={token}", origin=page.rstrip("/"), max_size=None) as client:
            assert json.loads(client.recv(timeout=30))["type"] == "welcome"
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()
    other = make_server("bar", "0.0.0.0", 0)
    other[1].close()
    assert parse_qs(urlsplit(other[2]).query)["token"][0] != token  # a fresh one each time


def test_cli_token_option() -> None:
    assert build_parser().parse_args(["studio"]).token is None
    assert build_parser().parse_args(["studio", "--token", "abc"]).token == "abc"
    for bad in ("", "a b"):
        with pytest.raises(SystemExit) as exited:
            build_parser().parse_args(["studio", "--token", bad])
        assert exited.value.code == 2


@pytest.mark.parametrize("host", ["0.0.0.0", "192.0.2.7"])
def test_cli_prints_the_network_url_with_its_token_and_says_so(monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str], host: str) -> None:
    seen: dict[str, Any] = {}

    def fake_serve(mesh: Any, **options: Any) -> None:
        seen.update(options)
        options["on_ready"](studio_url(options["host"], 8123, "tok123"))

    monkeypatch.setattr(arap.server, "serve", fake_serve)
    monkeypatch.setattr("arap.cli.studio.warm_up_kernels", lambda quiet, first_ready=None: None)
    assert main(["studio", "--host", host, "--port", "8123"]) == 0
    out = capsys.readouterr().out
    assert seen["host"] == host and seen["token"] is None  # the server makes one for a network address
    assert "serving the network at http://" in out and ":8123/?token=tok123" in out
    assert "token" in out.split("\n", 1)[1] and "refused" in out
    if host != "0.0.0.0":
        assert f"http://{host}:8123/?token=tok123" in out


def test_cli_loopback_message_is_unchanged(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    def fake_serve(mesh: Any, **options: Any) -> None:
        options["on_ready"](studio_url(options["host"], 8000, options["token"]))

    monkeypatch.setattr(arap.server, "serve", fake_serve)
    monkeypatch.setattr("arap.cli.studio.warm_up_kernels", lambda quiet, first_ready=None: None)
    assert main(["studio"]) == 0
    assert capsys.readouterr().out.strip() == "ARAP Studio running at http://127.0.0.1:8000/  (Ctrl-C to stop)"
    assert main(["studio", "--token", "abc"]) == 0
    assert "http://127.0.0.1:8000/?token=abc" in capsys.readouterr().out


def test_ten_wrong_tokens_shut_the_address_out_for_a_minute(tokened: TestClient,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    import arap.server.guard as guard

    now = [1000.0]
    monkeypatch.setattr(guard.time, "monotonic", lambda: now[0])
    for k in range(guard.WRONG_TOKENS):
        assert "wrong token" in tokened.get("/", params={"token": f"guess-{k}"}).text
    refused = tokened.get("/", params={"token": TOKEN})
    assert refused.status_code == 403 and "too many wrong tokens" in refused.text
    now[0] += guard.WRONG_TOKEN_WINDOW + 1
    assert tokened.get("/", params={"token": TOKEN}).status_code == 200


def test_a_short_token_on_a_network_is_warned_about(monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(arap.server, "serve", lambda *a, **k: None)
    main(["studio", "bar", "--host", "0.0.0.0", "--port", "0", "--token", "abc"])
    assert "a token of 3 characters is easy to guess" in capsys.readouterr().err
    main(["studio", "bar", "--host", "0.0.0.0", "--port", "0", "--token", TOKEN])
    assert "easy to guess" not in capsys.readouterr().err


def test_cli_passes_the_export_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, Any] = {}

    def fake_serve(mesh: Any, **options: Any) -> None:
        seen.update(options)

    monkeypatch.setattr(arap.server, "serve", fake_serve)
    monkeypatch.setattr("arap.cli.studio.warm_up_kernels", lambda quiet, first_ready=None: None)
    assert main(["studio", "--max-export-mb", "300"]) == 0
    assert seen["max_export_bytes"] == 300 * 2**20
    assert main(["studio"]) == 0
    assert seen["max_export_bytes"] == 2**31
