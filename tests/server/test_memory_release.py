"""Sessions whose clients leave give their memory back: a session settling its shape stops when its client goes,
and the server's resident memory returns near where it was before the sessions came."""

from __future__ import annotations

import gc
import json
import threading
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import psutil
import pytest
from websockets.sync.client import connect

from arap.server import make_server
from arap.server.memory import release_memory
from arap.server.messages import ClientMessage
from arap.server.session import Session
from tests.server.helpers import StudioClient, translation
from tests.waiting import poll_until, scaled, wait_until

pytestmark = pytest.mark.timeout(120)

SESSIONS = 4
BALLAST = 2**23  # float64: 64 MiB per settling session, standing in for a large mesh's factor and history
SLOW_SECONDS = 20.0


@contextmanager
def _server() -> Iterator[str]:
    server, sock, url = make_server("bar", port=0)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    wait_until(lambda: server.started, 30, "the server to start")
    try:
        yield url
    finally:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()


def _sessions(url: str) -> int:
    with urllib.request.urlopen(url + "healthz", timeout=10) as response:
        return int(json.loads(response.read())["sessions"])


def _recv(ws: Any, type_: str) -> dict[str, Any]:
    while True:
        message = ws.recv(timeout=60)
        if isinstance(message, str):
            data: dict[str, Any] = json.loads(message)
            if data["type"] == type_:
                return data
            assert data["type"] in ("settle", "state"), data
        elif type_ in ("mesh", "vertices") and message[4:].lstrip().startswith(b'{"type":"' + type_.encode()):
            return {"type": type_}


def _edit_and_leave(url: str, settling: threading.Semaphore | None = None) -> None:
    """Connect, drag the top of the bar, release (the server starts settling) and leave at once (once
    ``settling`` is released, when given)."""
    with connect(url.replace("http://", "ws://") + "ws", max_size=None, close_timeout=1) as ws:
        _recv(ws, "welcome")
        _recv(ws, "mesh")
        _recv(ws, "state")
        ws.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": list(range(20)),
                            "handle_groups": [list(range(4200, 4314))]}))
        _recv(ws, "state")
        ws.send(json.dumps({"type": "drag", "seq": 1, "transforms": [translation(0.3)]}))
        _recv(ws, "vertices")
        ws.send(json.dumps({"type": "end_drag"}))
        _recv(ws, "state")
        _recv(ws, "settle")  # settling has started
        if settling is not None:
            assert settling.acquire(timeout=30)


def _rss() -> float:
    release_memory()
    return float(psutil.Process().memory_info().rss)


def test_sessions_that_leave_while_settling_give_their_memory_back(monkeypatch: pytest.MonkeyPatch) -> None:
    settle, end_drag = Session.settle, Session.end_drag
    slow = threading.Event()
    settling = threading.Semaphore(0)
    released: set[int] = set()

    def end_drag_and_mark(self: Session) -> None:
        end_drag(self)
        if slow.is_set():
            released.add(id(self))

    def settle_slowly(self: Session, interrupted: Any, on_frame: Any = None) -> Any:
        """After the drag ends, settling holds BALLAST bytes until interrupted (or SLOW_SECONDS)."""
        if id(self) in released:
            released.discard(id(self))
            ballast = np.ones(BALLAST)
            settling.release()
            poll_until(interrupted, SLOW_SECONDS)  # held until the session is interrupted (or SLOW_SECONDS)
            del ballast
        return settle(self, interrupted, on_frame)

    monkeypatch.setattr(Session, "end_drag", end_drag_and_mark)
    monkeypatch.setattr(Session, "settle", settle_slowly)
    with _server() as url:
        _edit_and_leave(url)  # warm: imports, compiled kernels, thread pools
        wait_until(lambda: _sessions(url) == 0, 10, "the warm-up session to end")
        gc.collect()
        before = _rss()
        slow.set()
        for _ in range(SESSIONS):
            _edit_and_leave(url, settling)
        deadline = time.monotonic() + scaled(5)  # an idle machine's seconds, longer under load
        poll_until(lambda: _sessions(url) == 0, max(0.0, deadline - time.monotonic()), interval=0.05)
        assert _sessions(url) == 0, "sessions went on after their clients left"
        # the server hands the memory back itself once each session is freed
        poll_until(lambda: float(psutil.Process().memory_info().rss) <= 1.5 * before,
                   max(0.0, deadline - time.monotonic()), interval=0.05)
        after = float(psutil.Process().memory_info().rss)
        assert after <= 1.5 * before, f"{after / 2**20:.0f} MiB after the sessions left, {before / 2**20:.0f} before"


def test_a_refused_constraint_set_is_freed_at_once(studio: StudioClient) -> None:
    """Without reference cycles: a refused message of many indices is not kept until the garbage collector runs."""
    gc.collect()
    gc.disable()
    try:
        n = len(studio.V)
        studio.send({"type": "set_constraints", "roi": None, "fixed": [*range(100), n + 5], "handle_groups": []})
        assert "out of range" in studio.error("bad_constraints")["message"]
        studio.ping()
        alive = [o for o in gc.get_objects() if isinstance(o, ClientMessage) and o.type == "set_constraints"]
        assert not alive, "the refused message is still in memory"
    finally:
        gc.enable()
