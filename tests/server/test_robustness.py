"""Sessions survive hostile input: huge numbers, floods that exceed the byte budgets, bursts of drags; a closed
session's memory is released; large frames are decoded off the event loop."""

from __future__ import annotations

import gc
import json
import threading
import weakref
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient

from arap.server import connection as connection_module
from arap.server import create_app
from arap.server.budget import request_cost
from arap.server.connection import OFF_LOOP_BYTES, Connection
from tests.server.helpers import StudioClient, translation
from tests.waiting import poll_until, time_factor, wait_until

pytestmark = pytest.mark.timeout(120)

BIG = "1" + "0" * 400  # a 401-digit integer: larger than any float
HUGE = "7" * 4301  # more digits than Python converts by default
BUDGET = 256 * 1024


def _connection(http: TestClient) -> Connection:
    connections = list(http.app.state.studio.connections)  # type: ignore[attr-defined]
    assert len(connections) == 1
    return connections[0]


@pytest.mark.parametrize(
    "text",
    [
        '{"type":"drag","seq":1,"transforms":[[@,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]]}'.replace("@", BIG),
        '{"type":"drag","seq":1,"transforms":[[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,-@]]}'.replace("@", BIG),
        '{"type":"drag","seq":@,"transforms":[]}'.replace("@", BIG),
        '{"type":"set_params","iterations":@}'.replace("@", BIG),
        '{"type":"set_constraints","roi":null,"fixed":[@],"handle_groups":[[1]]}'.replace("@", BIG),
        '{"type":"set_constraints","roi":null,"fixed":[0],"handle_groups":[[1]],"targets":[[@,0,0]]}'.replace("@", BIG),
        '{"type":"drag","seq":1,"transforms":[[@]]}'.replace("@", HUGE),
        '{"type":"end_drag","x":@}'.replace("@", HUGE),
        '{"type":"undo","nested":[[[[[@]]]]]}'.replace("@", HUGE),
        "[" * 100_000,
        '{"type":"drag","seq":1,"transforms":[[1e400,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]]}',
    ],
)
def test_huge_numbers_are_answered_and_the_session_goes_on(studio: StudioClient, text: str) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.send(text)
    error = studio.error()
    assert error["code"] in ("bad_message", "bad_constraints") and len(error["message"]) < 300
    studio.ping()
    studio.drag(2, [translation(0.1)])


def test_huge_integer_in_binary_header(studio: StudioClient) -> None:
    studio.send_binary(json.loads('{"type":"upload","filename":"a.obj"}') | {"n": 0}, b"")
    studio.error("bad_message")
    header = '{"type":"upload","filename":"a.obj","n":@}'.replace("@", HUGE).encode()
    studio.ws.send_bytes(len(header).to_bytes(4, "little") + header)
    studio.error("bad_message")
    studio.ping()


def test_unexpected_decoding_failure_becomes_an_internal_error(
    studio: StudioClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(text: str, *, cooperative: bool = False, **options: Any) -> Any:
        raise KeyError("boom")

    monkeypatch.setattr(connection_module, "parse_text", broken)
    studio.send({"type": "undo"})
    assert studio.error("internal")["request"] is None
    monkeypatch.undo()
    studio.ping()


def test_large_frames_are_decoded_off_the_event_loop(studio: StudioClient, monkeypatch: pytest.MonkeyPatch) -> None:
    threads: list[tuple[int, bool]] = []
    original = connection_module.parse_text

    def spy(text: str, *, cooperative: bool = False, **options: Any) -> Any:
        threads.append((threading.get_ident(), cooperative))
        return original(text, cooperative=cooperative, **options)

    monkeypatch.setattr(connection_module, "parse_text", spy)
    fixed, top = studio.bottom_top()
    small = {"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]}
    roi = list(range(len(studio.V))) * (OFF_LOOP_BYTES // (5 * len(studio.V)) + 1)
    large = small | {"roi": roi}  # repeated indices: rejected, after decoding
    studio.send(small)
    studio.expect("state")
    studio.send(large)
    studio.error("bad_constraints")
    (loop_thread, small_cooperative), (parse_thread, large_cooperative) = threads
    assert parse_thread != loop_thread and large_cooperative and not small_cooperative
    studio.ping()


def test_drag_bursts_always_answer_the_newest_drag(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    n = 60
    for seq in range(n):
        studio.send({"type": "drag", "seq": seq, "transforms": [translation(0.01 * seq)]})
    answered: list[int] = []
    skipped = 0
    while not answered or answered[-1] != n - 1:
        reply = studio.expect("vertices")
        answered.append(reply.data["seq"])
        skipped += reply.data["skipped"]
        assert len(answered) <= n
    assert answered == sorted(answered)
    assert len(answered) + skipped == n  # every drag is either answered or reported as skipped
    studio.ping()


# ---------------------------------------------------------------------------------------------- budgets
@pytest.fixture
def budgeted(static_dir: Path) -> Iterator[TestClient]:
    app = create_app("cactus", static_dir=static_dir, allowed_hosts=["testserver"], max_queued_bytes=BUDGET,
                     max_unsent_bytes=BUDGET)
    with TestClient(app) as http:
        yield http


def test_flood_is_held_back_by_the_input_budget(budgeted: TestClient) -> None:
    with budgeted.websocket_connect("/ws") as ws:
        client = StudioClient(ws)
        client.greet()
        fixed, top = client.bottom_top()
        roi = list(range(len(client.V)))
        message = json.dumps({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [top]})
        cost = request_cost(len(message), True)
        assert cost > BUDGET // 4
        n = 20  # far past the budget if everything were queued
        for _ in range(n):
            client.send(message)
        replies = [client.recv().type for _ in range(n)]
        assert replies == ["state"] * n  # all answered, none dropped as busy
        budget = _connection(budgeted).budget
        assert cost <= budget.peak_queued <= BUDGET + cost
        assert budget.queued == 0
        client.ping()


def test_closed_session_is_released(budgeted: TestClient) -> None:
    with budgeted.websocket_connect("/ws") as ws:
        client = StudioClient(ws)
        client.greet()
        fixed, top = client.bottom_top()
        client.set_constraints(fixed, [top])
        client.drag(1, [translation(0.2)])
        connection = _connection(budgeted)
        session_ref = weakref.ref(connection.session)
        connection_ref = weakref.ref(connection)
        del connection
    wait_until(lambda: budgeted.get("/healthz").json()["sessions"] == 0, 10, "the session to end")

    def released() -> bool:
        gc.collect()
        return connection_ref() is None and session_ref() is None

    # A solve still finishing on the solver's thread may hold the session a moment after the socket closed.
    if not poll_until(released, 10 * time_factor(), 0.1):
        held = session_ref()
        holders = [] if held is None else [type(r).__name__ for r in gc.get_referrers(held)]
        alive = connection_ref() is not None
        raise AssertionError(f"the closed session is still referenced (connection alive: {alive}; "
                             f"the session's referrers: {holders})")
