"""Point handles in the studio: set_constraints takes them (checked by the library's validator), a drag moves each
by its own transform and the settled shape meets it, and they belong to the constraint set (state, document,
undo and redo, reset and apply)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.cli import main as arap_main
from arap.io import load_mesh
from arap.server.errors import request_error
from arap.server.replies import state_message
from arap.server.session import Session
from arap.server.session_errors import BadValues
from tests.server.helpers import StudioClient, column_major, rotation_z, translation

pytestmark = pytest.mark.timeout(180)

BARY = [0.2, 0.3, 0.5]


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(0) - V.min(0)))


def _bottom_and_top_face(V: np.ndarray, F: np.ndarray) -> tuple[list[int], int]:
    y = V[:, 1]
    return np.flatnonzero(y <= np.quantile(y, 0.08)).tolist(), int(np.argmax(V[F].mean(axis=1)[:, 1]))


def _on_surface(U: np.ndarray, F: np.ndarray, face: int, bary: list[float]) -> np.ndarray:
    return np.asarray(bary) @ U[F[face]]


def _point_target(V: np.ndarray, F: np.ndarray, face: int, M: np.ndarray) -> np.ndarray:
    p = _on_surface(V, F, face, BARY)
    return M[:3, :3] @ p + M[:3, 3]


def test_a_dragged_point_meets_its_target_after_settling(bar_session: Session) -> None:
    V, F = bar_session.V, bar_session.mesh.F
    fixed, face = _bottom_and_top_face(V, F)
    bar_session.set_constraints(None, fixed, [], points=[{"face": face, "barycentric": BARY}])
    assert bar_session.n_groups == 1
    assert state_message(bar_session)["constraints"]["points"] == [{"face": face, "barycentric": BARY}]
    M = rotation_z(0.5, V[F[face]].mean(axis=0), shift=(0.6, 0.0, 0.0))
    bar_session.drag([column_major(M)])
    bar_session.end_drag()
    outcome = bar_session.settle(lambda: False)
    assert outcome is not None and outcome.converged and outcome.moved > 0
    target = _point_target(V, F, face, M)
    assert np.abs(_on_surface(bar_session.U, F, face, BARY) - target).max() <= 1e-9 * _diag(V)


def test_groups_and_points_each_have_a_transform(bar_session: Session) -> None:
    V, F = bar_session.V, bar_session.mesh.F
    fixed, face = _bottom_and_top_face(V, F)
    middle = np.flatnonzero(np.abs(V[:, 1] - np.median(V[:, 1])) < 0.05 * np.ptp(V[:, 1]))[:4].tolist()
    bar_session.set_constraints(None, fixed, [middle], points=[{"face": face, "barycentric": BARY, "weight": 50.0}])
    assert bar_session.n_groups == 2 and state_message(bar_session)["constraints"]["points"][0]["weight"] == 50.0
    with pytest.raises(BadValues) as err:
        bar_session.drag([translation(0.1)])
    assert request_error(err.value).code == "bad_message"
    bar_session.drag([translation(0.0), translation(0.5)])
    np.testing.assert_allclose(bar_session.U[middle], V[middle], atol=1e-9)  # the group stays, the soft point pulls
    assert _on_surface(bar_session.U, F, face, BARY)[0] > _on_surface(V, F, face, BARY)[0] + 0.2


def test_undo_redo_reset_and_apply_keep_the_points(bar_session: Session) -> None:
    V, F = bar_session.V, bar_session.mesh.F
    fixed, face = _bottom_and_top_face(V, F)
    bar_session.set_constraints(None, fixed, [])
    points = [{"face": face, "barycentric": BARY}]
    bar_session.set_constraints(None, fixed, [], points=points)
    assert bar_session.undo()
    assert state_message(bar_session)["constraints"]["points"] == [] and bar_session.n_groups == 0
    assert bar_session.redo()
    assert state_message(bar_session)["constraints"]["points"] == points and bar_session.n_groups == 1
    M = rotation_z(0.4, V[F[face]].mean(axis=0))
    bar_session.drag([column_major(M)])
    bar_session.end_drag()
    bar_session.settle(lambda: False)
    bent = bar_session.U.copy()
    bar_session.reset()
    assert state_message(bar_session)["constraints"]["points"] == points
    np.testing.assert_array_equal(bar_session.U, V)
    assert bar_session.undo()
    np.testing.assert_array_equal(bar_session.U, bent)
    bar_session.apply()
    assert state_message(bar_session)["constraints"]["points"] == points
    np.testing.assert_array_equal(bar_session.V, bent)
    np.testing.assert_allclose(bar_session.constraints.point_pose[0], _on_surface(bent, F, face, BARY), atol=1e-12)


def test_point_targets_in_set_constraints_are_solved_at_once(bar_session: Session) -> None:
    V, F = bar_session.V, bar_session.mesh.F
    fixed, face = _bottom_and_top_face(V, F)
    target = (_on_surface(V, F, face, BARY) + np.array([0.4, 0.0, 0.0])).tolist()
    side = int(np.argmax(V[:, 0] + 0.1 * V[:, 1]))
    side_target = (V[side] + np.array([0.1, 0.0, 0.0])).tolist()
    outcome = bar_session.set_constraints(None, fixed, [[side]], targets=[side_target],
                                      points=[{"face": face, "barycentric": BARY, "target": target}])
    assert outcome is not None
    bar_session.settle(lambda: False)
    assert np.abs(_on_surface(bar_session.U, F, face, BARY) - target).max() <= 1e-9 * _diag(V)
    np.testing.assert_allclose(bar_session.U[side], side_target, atol=1e-12)
    assert bar_session.constraints_document()["points"][0]["target"] == pytest.approx(target)


def test_the_document_gives_the_same_shape_with_arap_deform(studio: StudioClient, tmp_path: Path) -> None:
    V, F = studio.V, studio.F
    fixed, face = _bottom_and_top_face(V, F)
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [],
                 "points": [{"face": face, "barycentric": BARY}, {"face": face - 1, "barycentric": [1, 0, 0],
                                                                    "weight": 20}]})
    state = studio.expect("state").data
    assert len(state["constraints"]["points"]) == 2 and len(state["transforms"]) == 2
    studio.settled()
    M = rotation_z(0.6, V[F[face]].mean(axis=0), shift=(0.3, 0.2, 0.0))
    studio.drag(0, [column_major(M), column_major(M)])
    studio.send({"type": "end_drag"})
    studio.expect("state")
    status, frame = studio.settled()
    assert status["status"] == "settled" and frame is not None
    assert np.abs(_on_surface(frame, F, face, BARY) - _point_target(V, F, face, M)).max() <= 1e-6 * _diag(V)
    studio.send({"type": "get_constraints"})
    document = studio.expect("constraints").data["document"]
    assert document["version"] == 2 and len(document["points"]) == 2 and document["points"][1]["weight"] == 20
    path = tmp_path / "c.json"
    path.write_text(json.dumps(document))
    out = tmp_path / "out.ply"
    params = studio.state["params"]
    assert arap_main(["deform", "cactus", "-c", str(path), "-o", str(out), "-q", "--energy", params["energy"],
                      "--weights", params["weights"]]) == 0
    U, _ = load_mesh(out, repair=False)
    assert np.abs(frame - U).max() <= 1e-6 * _diag(V)


@pytest.mark.parametrize(("points", "code", "match"), [
    ([{"face": 10**7, "barycentric": BARY}], "bad_constraints", "out of range"),
    ([{"face": -1, "barycentric": BARY}], "bad_constraints", "out of range"),
    ([{"face": 10**30, "barycentric": BARY}], "bad_constraints", "out of range"),
    ([{"face": 2**63, "barycentric": BARY}], "bad_constraints", "out of range"),
    ([{"face": 3, "barycentric": [0.2, 0.2, 0.2]}], "bad_constraints", "sum to 1"),
    ([{"face": 3, "barycentric": [1.5, -0.5, 0.0]}], "bad_constraints", ">= 0"),
    ([{"face": 3, "barycentric": [0.5, 0.5]}], "bad_message", "3 finite numbers"),
    ([{"face": 3, "barycentric": [[0.5], 0.5, 0]}], "bad_message", "3 finite numbers"),
    ([{"face": 3.0, "barycentric": BARY}], "bad_message", "integer"),
    ([{"face": 3}], "bad_message", "barycentric"),
    ([{"face": 3, "barycentric": BARY, "weight": 0}], "bad_message", "positive"),
    ([{"face": 3, "barycentric": BARY, "colour": 1}], "bad_message", "optionally"),
    ({"face": 3, "barycentric": BARY}, "bad_message", "list"),
    ([[3, 0.2, 0.3, 0.5]], "bad_message", "object"),
])
def test_bad_points_are_an_error_and_the_session_goes_on(studio: StudioClient, points: object, code: str,
                                                         match: str) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    studio.settled()
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top], "points": points})
    error = studio.error(code)
    assert match in error["message"] and error["request"] == "set_constraints"
    studio.ping()
    assert len(studio.drag(1, [translation(0.1)]).floats()) == len(studio.V)


def test_too_many_groups_and_points_together(studio: StudioClient) -> None:
    groups = [[i] for i in range(200)]
    points = [{"face": k, "barycentric": BARY} for k in range(100)]
    studio.send({"type": "set_constraints", "roi": None, "fixed": [], "handle_groups": groups, "points": points})
    assert "at most 256" in studio.error("bad_message")["message"]
    studio.ping()
