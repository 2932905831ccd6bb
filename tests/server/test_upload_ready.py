"""Requests sent right behind an upload: answered for the new mesh, in order, with the answer a fresh session gives."""

from __future__ import annotations

import json
import logging
import time

import numpy as np
import pytest

from arap.io import save_mesh_bytes
from arap.meshes.shapes import sphere
from arap.server.meshdata import load_upload
from arap.server.session import Session
from tests.server.helpers import StudioClient, translation


def _upload() -> tuple[bytes, np.ndarray]:
    V, F = sphere(frequency=12)
    data = save_mesh_bytes(V, F, "obj")
    return data, V


def _reference(data: bytes, fixed: list[int], handle: list[int], roi: list[int] | None,
               drags: list[list[float]]) -> np.ndarray:
    """The shape a fresh session reaches on the same upload and requests."""
    session = Session()
    session.load(load_upload(data, "ball.obj", 10**6))
    session.set_constraints(roi, fixed, [handle])
    for T in drags:
        session.drag([T])
    return np.asarray(session.U, dtype="<f4").astype(np.float64)


def test_constraints_and_drags_sent_right_behind_an_upload_are_answered_for_the_new_mesh(
        studio: StudioClient) -> None:
    data, V = _upload()
    y = V[:, 1]
    fixed = np.flatnonzero(y <= np.quantile(y, 0.1)).tolist()
    handle = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
    roi = np.flatnonzero(y >= np.quantile(y, 0.05)).tolist()
    drags = [translation(0.05 * k, 0.1 * k) for k in (1, 2)]
    # nothing is read before everything is sent: the constraint set and the drags wait behind the upload
    studio.send_binary({"type": "upload", "filename": "ball.obj"}, data)
    studio.send({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [handle]})
    studio.send({"type": "drag", "seq": 1, "transforms": [drags[0]]})
    mesh = studio.read_mesh().data
    assert mesh["n_vertices"] == len(V)
    assert studio.expect("state").data["constraints"]["fixed"] == []  # the upload's state: nothing selected yet
    state = studio.expect("state").data
    assert state["constraints"]["fixed"] == fixed and state["stats"]["n_free"] > 0
    first = studio.expect("vertices")
    assert first.data["seq"] == 1
    np.testing.assert_allclose(first.floats(), _reference(data, fixed, handle, roi, drags[:1]), atol=1e-6)
    second = studio.drag(2, [drags[1]])
    np.testing.assert_allclose(second.floats(), _reference(data, fixed, handle, roi, drags), atol=1e-6)


def test_a_second_upload_right_behind_constraints_drops_them(studio: StudioClient) -> None:
    """Constraints of the previous mesh never reach the new one: after the upload a drag has nothing to move."""
    data, V = _upload()
    studio.send_binary({"type": "upload", "filename": "ball.obj"}, data)
    studio.send({"type": "set_constraints", "roi": None, "fixed": [0, 1, 2], "handle_groups": [[len(V) - 1]]})
    studio.send_binary({"type": "upload", "filename": "ball.obj"}, data)
    studio.send({"type": "drag", "seq": 7, "transforms": [translation(0.1)]})
    studio.read_mesh()
    studio.expect("state")
    studio.expect("state")
    studio.read_mesh()
    assert studio.expect("state").data["constraints"]["fixed"] == []
    studio.error("bad_message")  # no handle group for its transform


def test_an_upload_logs_the_time_of_each_step_after_its_mesh_and_state_are_sent(
        studio: StudioClient, caplog: pytest.LogCaptureFixture) -> None:
    data, V = _upload()
    caplog.set_level(logging.INFO, logger="arap.server.connection")
    before = time.time()
    studio.send_binary({"type": "upload", "filename": "ball.obj"}, data)
    assert studio.read_mesh().data["n_vertices"] == len(V)
    studio.expect("state")
    studio.ping()  # answered after the upload's handler has returned
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("upload timings ")]
    assert len(lines) == 1
    entry = json.loads(lines[0].removeprefix("upload timings "))
    assert entry["name"] == "ball" and entry["n_vertices"] == len(V)
    assert before <= entry["arrived"] <= entry["mesh_sent"] <= time.time()
    steps = ("decode_ms", "queued_ms", "parse_repair_ms", "encode_ms", "send_mesh_ms", "send_state_ms")
    assert all(entry[k] >= 0 for k in steps)
    assert 0 < entry["parse_repair_cpu_ms"] <= entry["parse_repair_ms"] + 1  # the thread's CPU time within it
    # the steps up to the mesh being sent add up to the time from arrival to then
    assert sum(entry[k] for k in steps[:-1]) == pytest.approx(1000 * (entry["mesh_sent"] - entry["arrived"]), abs=1)


def test_a_failed_upload_logs_no_timings(
        studio: StudioClient, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="arap.server.connection")
    studio.send_binary({"type": "upload", "filename": "bad.obj"}, b"v 0 0 0\nf 0 1 2\n")
    assert studio.error("bad_mesh")["request"] == "upload"
    studio.ping()
    assert not [r for r in caplog.records if r.getMessage().startswith("upload timings ")]
