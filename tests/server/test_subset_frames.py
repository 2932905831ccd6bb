"""Subset ``vertices`` frames: a client applying them holds bitwise the float32 positions full frames give."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from arap.server import create_app
from arap.server.constraints import ConstraintSet
from arap.server.liveframes import VertexStream, movable_vertices
from tests.server.helpers import Reply, StudioClient, translation


def _script(c: StudioClient) -> tuple[list[Reply], list[np.ndarray]]:
    """Drag a region of interest around, end the drag, let it settle and drag again.

    Returns every vertices frame, and the client's positions after each answer (settling streams a number of
    frames that depends on time; the positions after it do not).
    """
    frames: list[Reply] = []
    checkpoints: list[np.ndarray] = []
    y = c.V[:, 1]
    roi = np.flatnonzero(y >= np.quantile(y, 0.5)).tolist()
    fixed = np.flatnonzero((y >= np.quantile(y, 0.5)) & (y <= np.quantile(y, 0.6))).tolist()
    top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()

    def read_until(type_: str) -> None:
        while True:
            reply = c.recv()
            if reply.type == "vertices":
                frames.append(reply)
            if reply.type == type_ and (type_ != "settle" or reply.data["status"] != "settling"):
                checkpoints.append(c.held.copy())
                return

    c.send({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [top]})
    read_until("state")
    read_until("settle")
    for seq in range(1, 6):
        c.send({"type": "drag", "seq": seq, "transforms": [translation(0.3 * seq, 0.1 * seq)]})
        read_until("vertices")
    c.send({"type": "end_drag"})
    read_until("state")
    read_until("settle")
    for seq in range(6, 9):
        c.send({"type": "drag", "seq": seq, "transforms": [translation(-0.2 * seq)]})
        read_until("vertices")
    return frames, checkpoints


def _run(static_dir: Path, subset_frames: bool) -> tuple[list[Reply], list[np.ndarray]]:
    app = create_app("cactus", static_dir=static_dir, allowed_hosts=["testserver"], subset_frames=subset_frames)
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        client = StudioClient(ws)
        client.greet()
        return _script(client)


def test_subset_frames_give_the_positions_of_full_frames(static_dir: Path) -> None:
    partial, held = _run(static_dir, True)
    full, expected = _run(static_dir, False)
    assert all(r.data["subset"] == -1 and r.data["movable"] == 0 for r in full)
    assert len(held) == len(expected)
    for a, b in zip(held, expected, strict=True):
        np.testing.assert_array_equal(a.view("<u4"), b.view("<u4"))
    subsets = [r for r in partial if r.data["subset"] >= 0]
    assert len([r for r in subsets if r.data["seq"] >= 0]) >= 6, "drags of a region should get subset frames"
    n = len(expected[0])
    for r in subsets:
        assert r.payload is not None and len(r.payload) == 12 * r.data["subset"] < 12 * n


def test_the_first_frame_of_a_region_is_full_and_lists_its_movable_vertices(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    roi = sorted(set(range(len(studio.V) // 2, len(studio.V))) | set(top))
    studio.send({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [top]})
    studio.expect("state")
    frames = []
    studio.settled()  # may stream frames of this constraint set
    for seq in (1, 2, 3):
        studio.send({"type": "drag", "seq": seq, "transforms": [translation(0.4 * seq)]})
    while not frames or frames[-1].data["seq"] != 3:
        reply = studio.recv()
        if reply.type == "vertices":
            frames.append(reply)
    expected = sorted((set(roi) | set(top)) - set(fixed))
    assert studio.movable is not None and studio.movable.tolist() == expected
    assert all(r.data["subset"] in (-1, len(expected)) for r in frames)
    assert frames[-1].data["subset"] == len(expected) and frames[-1].data["movable"] == 0


def test_a_whole_mesh_constraint_set_has_only_full_frames(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.settled()
    for seq in (1, 2):
        reply = studio.drag(seq, [translation(0.3 * seq)])
        assert reply.data["subset"] == -1 and reply.data["movable"] == 0


def test_the_stream_falls_back_to_a_full_frame_when_a_still_vertex_moves() -> None:
    V = np.arange(30, dtype=np.float64).reshape(10, 3)
    cs = ConstraintSet.build(V, V, [4, 5, 6, 7], [4], [[7]])
    movable = movable_vertices(cs, 10)
    assert movable is not None and movable.tolist() == [5, 6, 7]
    stream = VertexStream()
    stream.reset(V)
    assert stream.encode(V, cs)[:2] == (-1, 3)
    U = V.copy()
    U[5] += 1.0
    subset, _, parts = stream.encode(U, cs)
    assert subset == 3 and np.frombuffer(parts[0], dtype="<f4").reshape(3, 3)[0].tolist() == U[5].tolist()
    U[0] += 1.0  # outside the movable vertices: the client must get everything
    assert stream.encode(U, cs)[0] == -1
    stream.reset(None)
    assert stream.encode(U, cs)[0] == -1


@pytest.mark.parametrize("roi", [None, list(range(10))])
def test_no_movable_list_without_a_proper_region(roi: list[int] | None) -> None:
    V = np.zeros((10, 3))
    assert movable_vertices(ConstraintSet.build(V, V, roi, [0], [[9]]), 10) is None


def test_a_region_with_nothing_movable_has_only_full_frames() -> None:
    """Every vertex of the region fixed: a full frame cannot list an empty movable list (``movable`` 0 means none),
    so no subset frame of zero positions may follow it (the client would have no list to apply it to)."""
    V = np.arange(30, dtype=np.float64).reshape(10, 3)
    cs = ConstraintSet.build(V, V, [2, 3], [2, 3], [])
    assert movable_vertices(cs, 10) is None
    stream = VertexStream()
    stream.reset(V)
    assert [stream.encode(V, cs)[:2] for _ in range(3)] == [(-1, 0)] * 3


def test_frames_of_an_interrupted_settle_arrive_before_the_next_answer(static_dir: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Settling frames are sent by a task of their own; a slow socket must not let one of them arrive after the
    answer to the request that interrupted the settle (a frame of the old constraint set would be applied to the
    new one's movable vertices)."""
    import asyncio
    import time

    from arap.server.connection import Connection
    from arap.server.session import Session

    until_taken = Connection._until_taken
    settle = Session.settle

    async def slow_socket(self: Connection) -> None:
        await asyncio.sleep(0.3)  # the scenario: a slow socket holds every frame back
        await until_taken(self)

    def slow_settle(self: Session, interrupted: Any, on_frame: Any = None) -> Any:
        def polled() -> bool:
            # the scenario: iterations as slow as a large mesh's, so the settle is still running when the request
            # comes
            time.sleep(0.01)
            return bool(interrupted())
        return settle(self, polled, on_frame)

    monkeypatch.setattr(Connection, "_until_taken", slow_socket)
    monkeypatch.setattr(Session, "settle", slow_settle)
    app = create_app("cactus", static_dir=static_dir, allowed_hosts=["testserver"])
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        c = StudioClient(ws)
        c.greet()
        y = c.V[:, 1]
        roi = np.flatnonzero(y >= np.quantile(y, 0.4)).tolist()
        fixed = np.flatnonzero((y >= np.quantile(y, 0.4)) & (y <= np.quantile(y, 0.5))).tolist()
        top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
        c.send({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [top]})
        c.expect("state")
        c.send({"type": "drag", "seq": 1, "transforms": [translation(2.0, 1.0)]})
        c.expect("vertices")
        c.send({"type": "end_drag"})
        c.expect("state")
        while True:  # settling has streamed a frame: interrupt it with another constraint set
            reply = c.recv()
            if reply.type == "settle" and reply.data["iterations"] > 0:
                break
            assert not (reply.type == "settle" and reply.data["status"] != "settling"), "settled before a frame"
        c.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top[: len(top) // 2]]})
        while (reply := c.recv()).type != "state":
            pass  # frames of the interrupted settle: the client applies them (apply_vertices checks each one)
        frames_after = 0
        while True:
            reply = c.recv()
            if reply.type == "vertices":
                # The new constraint set's first frame is a full one: a subset frame before it is a stale one.
                assert frames_after or reply.data["subset"] < 0, "a frame of the interrupted settle came late"
                frames_after += 1
            if reply.type == "settle" and reply.data["status"] != "settling":
                break
        assert frames_after >= 1
