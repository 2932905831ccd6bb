"""``set_constraints`` with handle ``targets`` (command-line constraint files): solve, errors and history."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from arap.server import protocol as P
from arap.server.client_messages import SetConstraints
from arap.server.errors import RequestError, request_error
from arap.server.meshdata import load_builtin
from arap.server.session import Session
from arap.server.session_errors import BadValues
from arap.server.solve_calls import LOAD_ITERATIONS
from tests.server.helpers import StudioClient, translation

pytestmark = pytest.mark.timeout(120)

SHIFT = np.array([0.3, 0.15, -0.1])


def _set_with_targets(studio: StudioClient, fixed: list[int], groups: list[list[int]],
                      targets: Any) -> None:
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": groups,
                 "targets": targets})


def _document(studio: StudioClient) -> dict[str, Any]:
    studio.send({"type": "get_constraints"})
    return studio.expect("constraints").data["document"]


def test_targets_move_the_handles_and_solve(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    targets = studio.V[top] + SHIFT
    _set_with_targets(studio, fixed, [top], targets.tolist())
    reply = studio.expect("vertices")
    # A loaded deformation is iterated until it settles, not for one drag's worth of iterations.
    assert reply.data["seq"] == -1 and 2 < reply.data["iterations"] <= LOAD_ITERATIONS
    energies = reply.data["energies"]
    assert energies[-1] > 0
    assert np.all(np.diff(energies) <= 1e-12)
    U = reply.floats()
    np.testing.assert_allclose(U[top], targets, atol=1e-5)
    np.testing.assert_array_equal(U[fixed], studio.V[fixed])
    free = np.setdiff1d(np.arange(len(U)), fixed + top)
    assert np.abs(U[free] - studio.V[free]).max() > 0.05
    state = studio.expect("state").data
    assert state["constraints"] == {"roi": None, "fixed": fixed, "handle_groups": [top], "stiffness": None,
                                   "points": []}
    np.testing.assert_allclose(state["transforms"], [translation(0.0)])
    assert state["can_undo"] and not state["can_redo"]
    assert studio.settled()[0]["status"] == "settled"

    doc = _document(studio)
    assert doc["handles"] == top and doc["fixed"] == fixed
    np.testing.assert_allclose(doc["targets"], targets, atol=1e-12)

    # drag transforms apply to the targets
    dragged = studio.drag(1, [translation(0.1)]).floats()
    np.testing.assert_allclose(dragged[top], targets + np.array([0.1, 0, 0]), atol=1e-5)
    np.testing.assert_allclose(_document(studio)["targets"], targets + np.array([0.1, 0, 0]), atol=1e-12)


def test_targets_of_several_groups_follow_the_group_order(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    a, b = top[: len(top) // 2], top[len(top) // 2 :]
    targets = np.concatenate([studio.V[a] + SHIFT, studio.V[b] - SHIFT])
    _set_with_targets(studio, fixed, [a, b], targets.tolist())
    U = studio.expect("vertices").floats()
    np.testing.assert_allclose(U[a + b], targets, atol=1e-5)
    assert studio.expect("state").data["constraints"]["handle_groups"] == [a, b]


def test_null_or_absent_targets_keep_the_old_behaviour(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    _set_with_targets(studio, fixed, [top], None)
    assert studio.expect("state").data["constraints"]["handle_groups"] == [top]
    np.testing.assert_allclose(_document(studio)["targets"], studio.V[top], atol=1e-12)


def test_undo_and_redo_of_a_set_with_targets(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    targets = studio.V[top] + SHIFT
    _set_with_targets(studio, fixed, [top], targets.tolist())
    solved = studio.expect("vertices").floats()
    studio.expect("state")
    status, frame = studio.settled()  # the loaded deformation settles; the settled shape is the undo step
    assert status["status"] == "settled"
    solved = solved if frame is None else frame

    studio.send({"type": "undo"})
    np.testing.assert_array_equal(studio.expect("vertices").floats(), studio.V)
    state = studio.expect("state").data
    assert state["constraints"] == {"roi": None, "fixed": [], "handle_groups": [], "stiffness": None,
                                   "points": []}
    assert not state["can_undo"] and state["can_redo"]

    studio.send({"type": "redo"})
    np.testing.assert_array_equal(studio.expect("vertices").floats(), solved)
    assert studio.expect("state").data["constraints"]["handle_groups"] == [top]
    np.testing.assert_allclose(_document(studio)["targets"], targets, atol=1e-12)


BAD_TARGETS = {
    "too few": (lambda V, top: (V[top[1:]]).tolist(), "bad_message"),
    "too many": (lambda V, top: (V[[*top, 0]]).tolist(), "bad_message"),
    "2-vectors": (lambda V, top: (V[top, :2]).tolist(), "bad_message"),
    "flat list": (lambda V, top: V[top].reshape(-1).tolist(), "bad_message"),
    "strings": (lambda V, top: [["0", "0", "0"]] * len(top), "bad_message"),
    "not a list": (lambda V, top: {"x": 1}, "bad_message"),
    "absurdly far": (lambda V, top: (V[top] + 1e300).tolist(), "bad_message"),
}


@pytest.mark.parametrize("name", BAD_TARGETS)
def test_bad_targets_are_rejected_and_change_nothing(studio: StudioClient, name: str) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    before = studio.drag(1, [translation(0.2)]).floats()
    make, code = BAD_TARGETS[name]
    _set_with_targets(studio, fixed[:5], [top[:10]], make(studio.V, top[:10]))
    err = studio.error(code)
    assert err["request"] == "set_constraints" and err["message"]
    doc = _document(studio)
    assert doc["handle_groups"] == [top] and doc["fixed"] == fixed
    np.testing.assert_allclose(doc["targets"], before[top], atol=1e-5)
    studio.send({"type": "end_drag"})
    assert studio.expect("state").data["constraints"]["fixed"] == fixed


def test_nan_targets_and_bad_indices(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    text = json.dumps({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top[:1]],
                       "targets": [[0.0, 0.0, 0.0]]})
    studio.send(text.replace("0.0]", "NaN]", 1))
    studio.error("bad_message")
    _set_with_targets(studio, fixed, [[5250]], [[0.0, 0.0, 0.0]])
    studio.error("bad_constraints")
    _set_with_targets(studio, fixed, [[fixed[0]]], [[0.0, 0.0, 0.0]])
    studio.error("bad_constraints")
    doc = _document(studio)
    assert doc == {"fixed": [], "handles": [], "targets": [], "handle_groups": []}


def test_parse_targets() -> None:
    base = {"type": "set_constraints", "roi": None, "fixed": [0], "handle_groups": [[1, 2], [3]]}
    msg = P.parse_text(json.dumps({**base, "targets": [[0, 1, 2], [1.5, 2, 3], [-1, 0, 1e3]]}))
    assert isinstance(msg, SetConstraints) and msg.targets[2] == [-1, 0, 1e3]
    assert P.parse_text(json.dumps({**base, "targets": None})) == SetConstraints(None, [0], [[1, 2], [3]])
    assert P.parse_text(json.dumps(base)) == SetConstraints(None, [0], [[1, 2], [3]], targets=None)
    for bad in ([[0, 1, 2], [1, 2, 3]], [[0, 1, 2], [1, 2, 3], [1, 2]], [[0, 1, 2], [1, 2, 3], [1, 2, True]],
                [[0, 1, 2], [1, 2, 3], [1, 2, None]], [0, 1, 2], "here"):
        with pytest.raises(RequestError) as info:
            P.parse_text(json.dumps({**base, "targets": bad}))
        assert info.value.code == "bad_message" and info.value.request == "set_constraints"
    with pytest.raises(RequestError, match="Infinity"):
        P.parse_text(json.dumps({**base, "targets": [[0, 1, 2], [1, 2, 3], [1e999, 0, 0]]}))


def test_session_rejects_bad_targets_without_change() -> None:
    s = Session()
    s.load(load_builtin("cactus"))
    U, cs = s.U, s.constraints
    with pytest.raises(BadValues) as info:
        s.set_constraints(None, [0], [[1, 2]], [[0.0, 0.0, 0.0]])
    assert request_error(info.value).code == "bad_message"
    with pytest.raises(BadValues) as info:
        s.set_constraints(None, [0], [], [[0.0, 0.0, 0.0]])
    assert request_error(info.value).code == "bad_message"
    assert s.U is U and s.constraints is cs and not s.history.can_undo
    assert s.set_constraints(None, [0], [], []) is None
    assert s.U is U and s.constraints.fixed.tolist() == [0]
