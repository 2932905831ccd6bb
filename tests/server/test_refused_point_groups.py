"""A constraint set refused for a point handle that cannot move leaves the server's handle groups as they were:
drags carry that many transforms, before and after the page sends the selection it kept and after undo."""

from __future__ import annotations

import numpy as np
import pytest

from tests.server.helpers import StudioClient, translation

pytestmark = pytest.mark.timeout(120)


def _next(studio: StudioClient, type_: str) -> dict:
    """The next message of ``type_``, past the frames and progress of settling."""
    while True:
        reply = studio.recv()
        if reply.type == type_ and not (type_ == "vertices" and reply.data["seq"] < 0):
            if type_ == "state":
                studio.state = reply.data
            return reply.data
        assert reply.type in ("settle", "vertices") and (reply.type == "settle" or reply.data["seq"] < 0), reply.data


def _drag(studio: StudioClient, seq: int, dx: float) -> None:
    studio.send({"type": "drag", "seq": seq, "transforms": [translation(dx)]})
    assert _next(studio, "vertices")["seq"] == seq


def _held_face(studio: StudioClient, fixed: list[int]) -> int:
    held = np.isin(studio.F, fixed).all(axis=1)
    return int(np.flatnonzero(held)[0])


def test_a_refused_point_handle_leaves_the_handle_groups_as_they_were(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    state = studio.set_constraints(fixed, [top])
    assert len(state["constraints"]["handle_groups"]) == 1 and len(state["transforms"]) == 1
    _drag(studio, 1, 0.05)
    studio.send({"type": "end_drag"})
    _next(studio, "state")

    face = _held_face(studio, fixed)
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top],
                 "points": [{"face": face, "barycentric": [0.2, 0.3, 0.5]}]})
    refusal = _next(studio, "error")
    assert (refusal["code"], refusal["request"]) == ("bad_constraints", "set_constraints")

    # the refused set's two groups are not the server's: a drag of one transform is answered, one of two refused
    _drag(studio, 2, 0.1)
    studio.send({"type": "drag", "seq": 3, "transforms": [translation(0.1), translation(0.0)]})
    wrong = _next(studio, "error")
    assert wrong["code"] == "bad_message"
    assert "2 transforms" in wrong["message"] and "1 handle groups" in wrong["message"]
    _drag(studio, 4, 0.12)
    studio.send({"type": "end_drag"})
    state = _next(studio, "state")
    assert state["constraints"]["points"] == [] and len(state["transforms"]) == 1

    # the page sends the selection it kept (the server's own): nothing changes, drags go on
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    _next(studio, "state")
    _drag(studio, 5, 0.15)
    studio.send({"type": "end_drag"})
    _next(studio, "state")

    studio.send({"type": "undo"})
    state = _next(studio, "state")
    assert len(state["transforms"]) == len(state["constraints"]["handle_groups"]) == 1
    _drag(studio, 6, 0.0)
