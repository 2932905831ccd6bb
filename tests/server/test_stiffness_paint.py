"""Painted stiffness in the studio's bar_session: it reaches the solver (a rigid band stays rigid under a drag), it is
part of the constraint set (state, constraints document, undo and redo, reset and apply), and bad paint is
refused with the bar_session unchanged."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.constraints import load_constraints
from arap.method.rigid import rigid_regions
from arap.server.client_messages import SetConstraints
from arap.server.errors import RequestError, request_error
from arap.server.meshdata import load_upload
from arap.server.protocol import parse_text
from arap.server.replies import state_message
from arap.server.session import Session
from arap.server.session_errors import ConstraintsRejected
from tests.core.scenarios import rigid_misfit
from tests.server.helpers import column_major, rotation_z


def _setup(V: np.ndarray) -> tuple[list[int], list[int], np.ndarray]:
    y = V[:, 1]
    fixed = np.flatnonzero(y <= np.quantile(y, 0.08)).tolist()
    top = np.flatnonzero(y >= np.quantile(y, 0.92)).tolist()
    middle = np.flatnonzero(np.abs(y - np.median(y)) < 0.12 * np.ptp(y))
    return fixed, top, middle


def _bend(bar_session: Session, top: list[int]) -> np.ndarray:
    V = bar_session.V
    M = rotation_z(0.6, V[top].mean(axis=0), shift=(1.0, 0.0, 0.0))
    bar_session.drag([column_major(M)])
    return bar_session.U


def test_a_rigid_band_stays_rigid(bar_session: Session) -> None:
    V = bar_session.V
    fixed, top, middle = _setup(V)
    bar_session.set_constraints(None, fixed, [top])
    assert rigid_misfit(V, _bend(bar_session, top), middle) > 1e-3
    bar_session.reset()
    bar_session.set_constraints(None, fixed, [top], stiffness=[{"vertices": middle.tolist(), "value": "rigid"}])
    assert np.isinf(bar_session.constraints.stiffness[middle]).sum() == len(middle)
    assert bar_session.solver.stiffness is not None
    assert rigid_misfit(V, _bend(bar_session, top), middle) < 1e-6


def test_stiffness_in_state_document_and_history(bar_session: Session) -> None:
    V = bar_session.V
    fixed, top, middle = _setup(V)
    bar_session.set_constraints(None, fixed, [top])
    paint = [{"vertices": middle[:5].tolist(), "value": 20.0}, {"vertices": middle[5:].tolist(), "value": "rigid"}]
    bar_session.set_constraints(None, fixed, [top], stiffness=paint)
    assert state_message(bar_session)["constraints"]["stiffness"] == paint
    doc = bar_session.constraints_document()
    assert doc["version"] == 2 and doc["stiffness"] == paint
    loaded = load_constraints(json.loads(json.dumps(doc)), len(V))
    np.testing.assert_array_equal(loaded.stiffness, bar_session.constraints.stiffness)
    assert bar_session.undo() and bar_session.constraints.stiffness is None
    assert state_message(bar_session)["constraints"]["stiffness"] is None
    assert "stiffness" not in bar_session.constraints_document()
    assert bar_session.redo() and state_message(bar_session)["constraints"]["stiffness"] == paint
    _bend(bar_session, top)
    bar_session.end_drag()
    bar_session.reset()
    assert state_message(bar_session)["constraints"]["stiffness"] == paint
    _bend(bar_session, top)
    bar_session.apply()
    assert state_message(bar_session)["constraints"]["stiffness"] == paint


def test_unpainted_stiffness_is_no_stiffness(bar_session: Session) -> None:
    fixed, top, middle = _setup(bar_session.V)
    bar_session.set_constraints(None, fixed, [top], stiffness=[{"vertices": middle.tolist(), "value": 1.0}])
    assert bar_session.constraints.stiffness is None and bar_session.solver.stiffness is None
    assert bar_session.set_constraints(None, fixed, [top], stiffness=[]) is None  # the same selection: nothing to do
    assert not bar_session.history.can_redo


@pytest.mark.parametrize(("paint", "match"), [
    ([{"vertices": [10**6], "value": 2.0}], "out of range"),
    ([{"vertices": [3], "value": 2.0}, {"vertices": [3], "value": 4.0}], "two stiffness values"),
])
def test_bad_paint_leaves_the_session_unchanged(bar_session: Session, paint: list, match: str) -> None:
    fixed, top, _ = _setup(bar_session.V)
    bar_session.set_constraints(None, fixed, [top])
    before = bar_session.constraints
    with pytest.raises(ConstraintsRejected, match=match) as err:
        bar_session.set_constraints(None, fixed, [top], stiffness=paint)
    assert request_error(err.value).code == "bad_constraints" and bar_session.constraints is before


@pytest.mark.parametrize(("stiffness", "ok"), [
    (None, True),
    ([{"vertices": [1, 2], "value": 3.5}, {"vertices": [4], "value": "rigid"}], True),
    ([{"vertices": [1], "value": 0}], False),
    ([{"vertices": [1], "value": "soft"}], False),
    ([{"vertices": [1.5], "value": 2}], False),
    ([{"vertices": [1]}], False),
    ({"vertices": [1], "value": 2}, False),
])
def test_protocol_checks_the_paint(stiffness: object, ok: bool) -> None:
    text = json.dumps({"type": "set_constraints", "roi": None, "fixed": [0], "handle_groups": [[1]],
                       "stiffness": stiffness})
    if ok:
        msg = parse_text(text)
        assert isinstance(msg, SetConstraints) and msg.stiffness == stiffness
    else:
        with pytest.raises(RequestError) as err:
            parse_text(text)
        assert err.value.code == "bad_message"


def test_paint_the_energy_cannot_take_is_refused_with_the_session_unchanged(shared_meshes_dir: Path) -> None:
    """The paper's spokes energy with a rigid band on a scan with obtuse triangles has no minimum: the studio says
    why and what to choose instead, and keeps the previous constraint set."""
    data = (shared_meshes_dir / "decimated-knight.off").read_bytes()
    session = Session()
    session.load(load_upload(data, "decimated-knight.off", 10**6))
    session.set_params(energy="spokes")
    fixed, top, middle = _setup(session.V)
    session.set_constraints(None, fixed, [top])
    before = session.constraints
    paint = [{"vertices": middle.tolist(), "value": "rigid"}]
    with pytest.raises(ConstraintsRejected, match="spokes_and_rims") as err:
        session.set_constraints(None, fixed, [top], stiffness=paint)
    assert request_error(err.value).code == "bad_constraints" and session.constraints is before
    session.set_params(energy="spokes_and_rims")
    session.set_constraints(None, fixed, [top], stiffness=paint)
    U = _bend(session, top)
    mask = np.zeros(len(session.V), dtype=bool)
    mask[middle] = True
    labels = rigid_regions(session.mesh.F, mask)  # the knight's band is several parts, each rigid on its own
    for k in range(labels.max() + 1):
        assert rigid_misfit(session.V, U, np.flatnonzero(labels == k)) < 1e-6


def test_undo_to_paint_the_energy_cannot_take_says_why_a_drag_cannot_solve(shared_meshes_dir: Path) -> None:
    """Undo back to painted stiffness after switching to the spokes energy (with which that paint has no minimum on
    the knight) keeps the step; a drag then names the reason and the way out, not an empty selection."""
    data = (shared_meshes_dir / "decimated-knight.off").read_bytes()
    session = Session()
    session.load(load_upload(data, "decimated-knight.off", 10**6))
    fixed, top, middle = _setup(session.V)
    session.set_constraints(None, fixed, [top], stiffness=[{"vertices": middle.tolist(), "value": "rigid"}])
    session.set_constraints(None, fixed, [top])
    session.set_params(energy="spokes")
    assert session.undo() and session.constraints.stiffness is not None
    with pytest.raises(ConstraintsRejected, match=r"cannot be solved with the spokes energy.*spokes_and_rims") as err:
        session.drag([column_major(np.eye(4))])
    assert request_error(err.value).code == "bad_constraints"
    session.set_params(energy="spokes_and_rims")  # the way out works
    _bend(session, top)
    assert session.redo() is False  # the drag is an unfinished step
