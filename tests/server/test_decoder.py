"""Large text frames are decoded in a worker process: same answers as small ones, long lists as arrays, a dead
worker replaced, no worker left behind."""

from __future__ import annotations

import json
import multiprocessing
import pickle
from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from arap.server import create_app
from arap.server.client_messages import SetConstraints
from arap.server.decoder import PROCESS_BYTES, FrameDecoder, arrays_from_lists
from arap.server.errors import RequestError
from arap.server.protocol import parse_text
from tests.server.helpers import StudioClient

pytestmark = pytest.mark.timeout(120)


def _decoder(http: TestClient) -> FrameDecoder:
    return http.app.state.studio.decoder  # type: ignore[attr-defined,no-any-return]


def _padded(message: dict[str, Any]) -> str:
    """The message as JSON text of more than PROCESS_BYTES (whitespace is valid JSON)."""
    text = json.dumps(message)
    return text[:-1] + " " * PROCESS_BYTES + "}"


def test_request_error_crosses_processes() -> None:
    error = pickle.loads(pickle.dumps(RequestError("bad_constraints", "fixed: out of range", "set_constraints")))
    assert (error.code, error.message, error.request) == ("bad_constraints", "fixed: out of range", "set_constraints")


def test_arrays_from_lists() -> None:
    text = ('{"type":"set_constraints","roi":[0,1,2,3],"fixed":[0],"handle_groups":[[1],[2,3]],'
            '"targets":[[0,0,1],[1,2,3],[4,5,6]]}')
    msg = arrays_from_lists(parse_text(text))
    assert isinstance(msg, SetConstraints)
    assert msg.fixed.dtype == np.int64 and msg.roi.tolist() == [0, 1, 2, 3]
    assert [g.tolist() for g in msg.handle_groups] == [[1], [2, 3]]
    assert msg.targets.shape == (3, 3) and msg.targets[2, 1] == 5.0
    huge = arrays_from_lists(parse_text('{"type":"set_constraints","roi":null,"fixed":[' + "9" * 30 + '],'
                                        '"handle_groups":[]}'))
    # beyond int64: left as a list, reported out of range later
    assert isinstance(huge, SetConstraints) and huge.fixed == [int("9" * 30)]
    undo = parse_text('{"type":"undo"}')
    assert arrays_from_lists(undo) is undo


def test_large_frame_is_decoded_in_the_worker_and_answered_like_a_small_one(studio: StudioClient,
                                                                            http: TestClient) -> None:
    fixed, top = studio.bottom_top()
    message = {"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]}
    studio.send(_padded(message))
    state = studio.expect("state").data
    assert _decoder(http).started
    assert state["constraints"]["fixed"] == fixed and state["constraints"]["handle_groups"] == [top]
    n = len(studio.V)
    studio.send(_padded(message | {"fixed": [*fixed, n + 5]}))
    assert f"vertex index {n + 5} out of range" in studio.error("bad_constraints")["message"]
    studio.send(_padded(message | {"fixed": [*fixed, fixed[0]]}))
    studio.error("bad_constraints")
    studio.send(_padded({"type": "set_params", "iterations": 10**6}))
    assert studio.error("bad_message")["request"] == "set_params"
    studio.send(_padded(message)[:-1])  # cut short: not JSON
    studio.error("bad_message")
    studio.ping()


def test_a_dead_worker_is_replaced(studio: StudioClient, http: TestClient) -> None:
    fixed, top = studio.bottom_top()
    message = {"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]}
    studio.send(_padded(message))
    studio.expect("state")
    workers = [p for p in multiprocessing.active_children() if "Spawn" in type(p).__name__]
    assert workers
    for p in workers:
        p.kill()
        p.join(10)
    studio.send(_padded(message | {"handle_groups": [top[:1]]}))
    assert studio.expect("state").data["constraints"]["handle_groups"] == [top[:1]]
    studio.send(_padded(message))
    assert studio.expect("state").data["constraints"]["handle_groups"] == [top]
    studio.ping()


def test_no_worker_outlives_the_app(static_dir: Any) -> None:
    app = create_app("cactus", static_dir=static_dir, allowed_hosts=["testserver"])
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        studio = StudioClient(ws)
        studio.greet()
        studio.send(_padded({"type": "undo"}))
        studio.expect("state")
        decoder = _decoder(http)
        assert decoder.started
    assert not decoder.started
    assert not [p for p in multiprocessing.active_children() if "Spawn" in type(p).__name__]


def test_a_worker_dying_mid_frame_costs_no_answer(studio: StudioClient, http: TestClient,
                                                  monkeypatch: pytest.MonkeyPatch,
                                                  caplog: pytest.LogCaptureFixture) -> None:
    fixed, top = studio.bottom_top()
    message = {"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]}
    studio.send(_padded(message))
    studio.expect("state")
    monkeypatch.setattr("arap.server.decoder.decode_text_frame", _exit_worker)
    studio.send(_padded(message | {"handle_groups": [top[:2]]}))
    assert studio.expect("state").data["constraints"]["handle_groups"] == [top[:2]]
    assert "the decoder process ended" in caplog.text
    monkeypatch.undo()
    studio.send(_padded(message))
    assert studio.expect("state").data["constraints"]["handle_groups"] == [top]
    assert _decoder(http).started


def _exit_worker(data: bytes, *limits: Any) -> Any:
    import os

    os._exit(3)
