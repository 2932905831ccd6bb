"""A studio with a token (a network's, a notebook's): the page opened with ``?token=`` loads its scripts and passes
the token to its WebSocket; without it the page is refused."""

from __future__ import annotations

import pytest
from playwright.sync_api import Browser

from tests.e2e.conftest import VIEWPORT, _build_client, _ServerThread, wait_ready

pytestmark = pytest.mark.timeout(180)

TOKEN = "e2e-Token_0123456789abcdefghijklmnop"


def test_the_page_opened_with_the_token_connects(browser: Browser) -> None:
    reason = _build_client()
    if reason is not None:
        pytest.skip(reason)
    server = _ServerThread(token=TOKEN)
    server.start()
    server.wait_started()
    context = browser.new_context(viewport=VIEWPORT)
    try:
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        sockets: list[str] = []
        page.on("websocket", lambda ws: sockets.append(ws.url))
        refused = page.goto(server.url)
        assert refused is not None and refused.status == 403
        page.goto(f"{server.url}?token={TOKEN}")
        wait_ready(page)
        assert sockets and all(url.endswith(f"/ws?token={TOKEN}") for url in sockets)
        assert page.evaluate("() => window.__arap.positions().length") > 0
        assert not errors
    finally:
        context.close()
        server.stop()
