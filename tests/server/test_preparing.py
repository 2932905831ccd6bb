"""First run: while the solver's kernels compile, a new connection is told how many are ready, by name, about once a
second, and greeted as soon as those a session needs first are."""

from __future__ import annotations

import threading

import pytest
from starlette.testclient import TestClient

import arap.warmup as jit
from arap.warmup import KERNELS_READY
from tests.server.helpers import StudioClient

pytestmark = pytest.mark.timeout(120)


def test_a_connection_is_told_the_compile_progress_until_the_kernels_are_ready(
        http: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("arap.server.connection.PREPARING_SECONDS", 0.05)
    monkeypatch.setattr(jit, "_compiling", ["_local_serial"])
    KERNELS_READY.clear()
    try:
        with http.websocket_connect("/ws") as ws:
            client = StudioClient(ws)
            seen = [client.expect("preparing").data, client.expect("preparing").data]
            KERNELS_READY.set()
            reply = client.recv()
            while reply.type == "preparing":
                reply = client.recv()
            assert reply.type == "welcome"
    finally:
        KERNELS_READY.set()
    first = seen[0]
    assert first["total"] == len(jit.FIRST_KERNELS) + len(jit.LATER_KERNELS)
    assert 0 <= first["done"] <= first["total"]
    assert first["kernel"] == "_local_serial" and first["compiling"] is True
    assert seen[1]["seconds"] >= first["seconds"] >= 0


def test_the_greeting_waits_only_for_the_kernels_a_session_needs_first(http: TestClient) -> None:
    """The warm-up announces the first kernels ready before it compiles the threaded ones; the server then greets."""
    ready_at: list[int] = []

    def first_ready() -> None:
        ready_at.append(jit.compile_progress().done)
        KERNELS_READY.set()

    KERNELS_READY.clear()
    try:
        warm = threading.Thread(target=jit.warm_up_kernels, kwargs={"first_ready": first_ready})
        warm.start()
        with http.websocket_connect("/ws") as ws:
            client = StudioClient(ws)
            reply = client.recv()
            while reply.type == "preparing":
                reply = client.recv()
            assert reply.type == "welcome"
        warm.join(timeout=100)
    finally:
        KERNELS_READY.set()
    assert ready_at and ready_at[0] >= len(jit.FIRST_KERNELS)
