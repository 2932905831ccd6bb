"""``arap.studio``'s server belongs to its handle: a random token in the handle's URL, every other client refused,
and the handle reads back only a session opened with that token."""

from __future__ import annotations

import json
from urllib.parse import parse_qs, urlsplit

import httpx
import numpy as np
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

import arap
from arap.server.session import Session

pytestmark = pytest.mark.timeout(120)


def _page(url: str) -> str:
    return url.split("?")[0]


def _token(url: str) -> str:
    return parse_qs(urlsplit(url).query)["token"][0]


def _expect(ws: ClientConnection, kind: str) -> None:
    while True:
        message = ws.recv(timeout=60)
        if isinstance(message, str):
            header = json.loads(message)
            assert header["type"] != "error", header
            if header["type"] == kind:
                return


def test_the_handle_url_carries_a_fresh_random_token() -> None:
    V, F = arap.builtin_mesh("bar")
    with arap.studio(V, F, show=False) as a, arap.studio(V, F, show=False) as b:
        ta, tb = _token(a.url), _token(b.url)
        assert len(ta) >= 32 and ta != tb
        assert a.url == f"{_page(a.url)}?token={ta}" and _page(a.url).startswith("http://127.0.0.1:")
        assert a.url in a._repr_html_()  # the iframe and the new-tab link open the page with the token
    assert ta not in a._repr_html_()  # a stopped studio no longer shows it


def test_clients_without_the_token_are_refused() -> None:
    V, F = arap.builtin_mesh("bar")
    with arap.studio(V, F, show=False) as s:
        page, token = _page(s.url), _token(s.url)
        ws = page.replace("http://", "ws://") + "ws"
        assert httpx.get(page).status_code == 403
        assert httpx.get(f"{page}?token=x{token}").status_code == 403
        assert httpx.get(f"{page}healthz").status_code == 403
        assert httpx.get(f"{page}healthz", params={"token": token}).status_code == 200
        assert httpx.get(f"{page}healthz", headers={"Authorization": f"token {token}"}).status_code == 200
        assert httpx.get(s.url).status_code != 403
        for url in (ws, f"{ws}?token=", f"{ws}?token={token[:-1]}"):
            with pytest.raises(InvalidStatus) as refused:
                connect(url, origin=page.rstrip("/"), open_timeout=10).close()
            assert refused.value.response.status_code == 403
        with connect(f"{ws}?token={token}", origin=page.rstrip("/"), max_size=None) as client:
            _expect(client, "state")


def test_the_handle_reads_its_own_session_only() -> None:
    V, F = arap.builtin_mesh("bar")
    with arap.studio(V, F, show=False) as s:
        page, token = _page(s.url), _token(s.url)
        ws = page.replace("http://", "ws://") + "ws"
        with connect(f"{ws}?token={token}", origin=page.rstrip("/"), max_size=None) as mine:
            _expect(mine, "state")
            mine.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": [0, 1], "handle_groups": [[2]]}))
            _expect(mine, "state")
        # Another local client: refused, so it never becomes "the" session.
        with pytest.raises(InvalidStatus):
            connect(ws, origin=page.rstrip("/"), open_timeout=10).close()
        assert s.constraints.fixed.tolist() == [0, 1]
        # A session opened with another token (past the guard, as a bug there would let through) is never read.
        shared = s._shared
        intruder = Session()
        shared.opened(intruder, "another token")
        shared.opened(Session(), None)
        assert s._session is not intruder and s.constraints.fixed.tolist() == [0, 1]
        assert shared.latest_session("another token") is None
        np.testing.assert_array_equal(s.faces, F)
