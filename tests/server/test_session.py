"""The editing session without the network: constraints, drags, history, parameters, export and documents."""

from __future__ import annotations

import numpy as np
import pytest

from arap.io import load_mesh_bytes
from arap.server.constraints import matrices_from_json, matrices_to_json
from arap.server.errors import request_error
from arap.server.history import History, Snapshot
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_builtin
from arap.server.messages import ENERGIES, WEIGHTS
from arap.server.replies import state_message
from arap.server.session import Session
from arap.server.session_errors import ConstraintsRejected
from tests.server.helpers import column_major, rotation_z, translation


@pytest.fixture(scope="module")
def cactus() -> MeshData:
    return load_builtin("cactus")


@pytest.fixture
def session(cactus: MeshData) -> Session:
    s = Session()
    s.load(cactus)
    return s


def _bottom_top(V: np.ndarray, share: float = 0.1) -> tuple[list[int], list[int]]:
    y = V[:, 1]
    return (np.flatnonzero(y <= np.quantile(y, share)).tolist(),
            np.flatnonzero(y >= np.quantile(y, 1 - share)).tolist())


def test_matrix_conversion_is_column_major() -> None:
    M = np.arange(16.0).reshape(4, 4)
    assert matrices_from_json([column_major(M)])[0].tolist() == M.tolist()
    assert matrices_to_json(matrices_from_json([column_major(M)])) == [column_major(M)]
    T = matrices_from_json([translation(1, 2, 3)])[0]
    assert T[:3, 3].tolist() == [1, 2, 3]


def test_drag_moves_handles_rigidly_and_keeps_fixed(session: Session) -> None:
    V = session.V
    fixed, top = _bottom_top(V)
    session.set_constraints(None, fixed, [top])
    M = rotation_z(0.4, V[top].mean(axis=0), shift=(0.3, 0.1, 0))
    out = session.drag([column_major(M)])
    U = session.U
    np.testing.assert_allclose(U[top], V[top] @ M[:3, :3].T + M[:3, 3], atol=1e-12)
    np.testing.assert_array_equal(U[fixed], V[fixed])
    free = np.setdiff1d(np.arange(len(V)), fixed + top)
    assert np.abs(U[free] - V[free]).max() > 0.05
    assert out.iterations == 2 and len(out.energies) == 2 and out.solve_ms > 0
    assert session.solves == 1


def test_constraint_errors_leave_the_session_unchanged(session: Session) -> None:
    fixed, top = _bottom_top(session.V)
    session.set_constraints(None, fixed, [top])
    before = state_message(session)
    bad = [
        (None, fixed, [top, [top[0]]]),           # vertex in two groups
        (None, [*fixed, top[0]], [top]),          # fixed and handle
        (None, [*fixed, fixed[0]], [top]),        # repeated fixed
        (None, fixed, [top, []]),                 # empty group
        (None, fixed, [[len(session.V)]]),        # out of range
        ([0, 0], fixed, [top]),                   # repeated roi vertex
    ]
    for roi, f, g in bad:
        with pytest.raises(ConstraintsRejected) as info:
            session.set_constraints(roi, f, g)
        assert request_error(info.value).code == "bad_constraints", (roi, f, g)
        assert state_message(session) == before
    session.set_constraints(None, [], [top[:1], top[1:2]])   # handles alone are a valid set
    assert session.n_groups == 2


def test_rejected_constraints_leave_the_set_empty(session: Session) -> None:
    fixed, _ = _bottom_top(session.V)
    with pytest.raises(ConstraintsRejected) as info:
        session.set_constraints(None, fixed, [fixed[:3]])  # a vertex both anchor and handle
    assert request_error(info.value).code == "bad_constraints"
    assert session.constraints.is_empty


def test_nothing_to_solve_without_constraints(session: Session) -> None:
    with pytest.raises(ConstraintsRejected) as info:
        session.drag([])
    assert request_error(info.value).code == "bad_constraints"


def test_undo_redo_walks_the_history(session: Session) -> None:
    V = session.V
    fixed, top = _bottom_top(V)
    session.set_constraints(None, fixed, [top])
    session.drag([translation(0.5)])
    session.drag([translation(0.8)])
    assert session.end_drag()
    U1 = session.U.copy()
    session.drag([translation(-0.4)])
    assert session.end_drag()
    U2 = session.U.copy()
    assert not session.end_drag()
    assert session.undo() and np.array_equal(session.U, U1)
    assert session.undo() and np.array_equal(session.U, V)
    assert state_message(session)["constraints"]["fixed"] == fixed
    assert session.undo() and session.constraints.is_empty
    assert not session.undo()
    assert session.redo() and session.redo() and np.array_equal(session.U, U1)
    np.testing.assert_allclose(session.transforms[0][:3, 3], [0.8, 0, 0])
    assert session.redo() and np.array_equal(session.U, U2)
    assert not session.redo()
    # a drag after undo drops the redo states
    session.undo()
    session.drag([translation(0.1)])
    session.end_drag()
    assert not state_message(session)["can_redo"]


def test_undo_commits_an_unfinished_drag(session: Session) -> None:
    fixed, top = _bottom_top(session.V)
    session.set_constraints(None, fixed, [top])
    session.drag([translation(0.5)])
    dragged = session.U
    assert state_message(session)["can_undo"]
    assert session.undo() and np.array_equal(session.U, session.V)
    assert session.redo() and np.array_equal(session.U, dragged)


def test_reset_and_apply(session: Session) -> None:
    V0 = session.V
    fixed, top = _bottom_top(V0)
    session.set_constraints(None, fixed, [top])
    session.drag([translation(0.5)])
    dragged = session.U.copy()
    session.reset()
    assert np.array_equal(session.U, V0) and np.array_equal(session.transforms, np.eye(4)[None])
    session.undo()
    assert np.array_equal(session.U, dragged)
    session.apply()
    assert np.array_equal(session.V, dragged) and np.array_equal(session.U, dragged)
    # the new rest pose holds: an identity drag keeps the shape, a reset no longer goes back to V0
    session.drag([translation(0.0)])
    np.testing.assert_allclose(session.U, dragged, atol=1e-9)
    session.reset()
    np.testing.assert_allclose(session.U, dragged, atol=1e-9)
    session.undo()                                  # back before the reset: the identity drag
    session.undo()                                  # back to the applied state
    assert np.array_equal(session.V, dragged)
    session.undo()                                  # before the apply
    assert np.array_equal(session.V, V0) and np.array_equal(session.U, dragged)


def test_new_selection_mid_edit_keeps_the_shape(session: Session) -> None:
    V = session.V
    fixed, top = _bottom_top(V)
    session.set_constraints(None, fixed, [top])
    session.drag([translation(0.6)])
    U = session.U.copy()
    middle = np.flatnonzero(np.abs(V[:, 1] - np.median(V[:, 1])) < 0.05).tolist()
    middle = [v for v in middle if v not in fixed and v not in top]
    session.set_constraints(None, fixed + top, [middle])
    assert np.array_equal(session.U, U)
    session.drag([translation(0, 0, 0.2)])
    np.testing.assert_array_equal(session.U[top], U[top])                # formerly handles: fixed where they were
    np.testing.assert_allclose(session.U[middle], U[middle] + [0, 0, 0.2], atol=1e-12)
    doc = session.constraints_document()
    # the document reproduces the constraints against the rest pose
    assert doc["fixed"] == fixed
    assert doc["handles"][: len(middle)] == middle and sorted(doc["handles"][len(middle):]) == sorted(top)
    np.testing.assert_allclose(np.array(doc["targets"])[len(middle):], U[doc["handles"][len(middle):]])


def test_region_of_interest_holds_the_outside(session: Session) -> None:
    V = session.V
    y = V[:, 1]
    roi = np.flatnonzero(y > np.quantile(y, 0.5)).tolist()
    fixed = [v for v in roi if y[v] < np.quantile(y, 0.6)]
    top = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
    session.set_constraints(roi, fixed, [top])
    session.drag([translation(0.3)])
    outside = np.setdiff1d(np.arange(len(V)), roi)
    np.testing.assert_array_equal(session.U[outside], V[outside])
    assert state_message(session)["stats"]["roi_size"] == len(roi)
    moved = session.U.copy()
    # a smaller roi keeps what the larger one had moved
    session.set_constraints(top, [], [top[:5]])
    assert len(session.constraints.held) > 0
    session.drag([translation(0.0)])
    rest_of = np.setdiff1d(np.arange(len(V)), top)
    np.testing.assert_array_equal(session.U[rest_of], moved[rest_of])


def test_params_change_refactors_and_validates(session: Session) -> None:
    fixed, top = _bottom_top(session.V)
    session.set_constraints(None, fixed, [top])
    first = session.solver
    session.set_params(iterations=7)
    assert session.solver is first
    out = session.drag([translation(0.2)])
    assert out.iterations == 7
    session.set_params(energy="spokes_and_rims", weights="uniform")
    assert session.solver is not first and session.solver.energy_type == "spokes_and_rims"
    assert state_message(session)["params"] == {"iterations": 7, "energy": "spokes_and_rims", "weights": "uniform",
                                         "alpha": 0.02, "loose": "follow", "warp": "rigid"}


def test_export_round_trips(session: Session) -> None:
    fixed, top = _bottom_top(session.V)
    session.set_constraints(None, fixed, [top])
    session.drag([translation(0.5)])
    for fmt in ("obj", "ply"):
        name, mime, data = session.export(fmt)
        assert name == f"cactus-deformed.{fmt}" and mime
        V, F = load_mesh_bytes(data, fmt, repair=False)
        assert V.shape == session.U.shape
        np.testing.assert_allclose(V, session.U, atol=1e-12)
        np.testing.assert_array_equal(F, session.mesh.F)  # type: ignore[union-attr]


def test_constraints_document_format(session: Session) -> None:
    fixed, top = _bottom_top(session.V)
    session.set_constraints(None, fixed, [top[:3], top[3:]])
    M = rotation_z(0.2, np.zeros(3))
    session.drag([translation(0.1), column_major(M)])
    doc = session.constraints_document()
    assert set(doc) == {"fixed", "handles", "targets", "handle_groups"}
    assert doc["handles"] == top and doc["handle_groups"] == [top[:3], top[3:]] and doc["fixed"] == fixed
    T = np.array(doc["targets"])
    np.testing.assert_allclose(T[:3], session.V[top[:3]] + [0.1, 0, 0])
    np.testing.assert_allclose(T[3:], session.V[top[3:]] @ M[:3, :3].T)
    np.testing.assert_allclose(T, session.U[top], atol=1e-12)
    session.set_constraints([*fixed, *top], fixed, [top])
    assert session.constraints_document()["roi"] == [*fixed, *top]


def test_history_memory_cap() -> None:
    h = History(max_steps=100, max_bytes=10 * 24 * 1000)
    V = np.zeros((1000, 3))
    s0 = Session()
    s0.load(MeshData.make("z", V, np.array([[0, 1, 2]])))
    h.clear(s0.history.current)
    for i in range(30):
        U = np.full((1000, 3), float(i))
        h.push(Snapshot(1, s0.V, U, s0.constraints, s0.transforms))
    assert 2 <= len(h) < 30
    assert h.nbytes() <= 10 * 24 * 1000
    assert h.current.U[0, 0] == 29
    steps = 0
    while h.undo() is not None:
        steps += 1
    assert steps == len(h) - 1


def test_history_step_cap() -> None:
    s = Session(max_history_steps=3)
    s.load(load_builtin("bar"))
    fixed, top = _bottom_top(s.V)
    s.set_constraints(None, fixed, [top])
    for i in range(5):
        s.drag([translation(0.1 * i)])
        s.end_drag()
    assert len(s.history) == 3
    assert s.undo() and s.undo() and not s.undo()


def test_every_energy_and_weighting_solves(cactus: MeshData) -> None:
    fixed, top = _bottom_top(cactus.V)
    for energy in ENERGIES:
        for weights in WEIGHTS:
            s = Session()
            s.load(cactus)
            s.set_params(energy=energy, weights=weights)
            s.set_constraints(None, fixed, [top])
            s.drag([translation(0.2)])
            assert np.all(np.isfinite(s.U))


def test_loose_parts_follow_by_default_and_can_stay(cactus: MeshData) -> None:
    """A model in two pieces: the piece no constraint reaches goes along with the constrained one (or stays)."""
    V, F = cactus.V, cactus.F
    beside = V + np.array([np.ptp(V[:, 0]) * 1.2, 0.0, 0.0])  # a second cactus, nothing constrained on it
    s = Session()
    s.load(MeshData.make("two cacti", np.concatenate([V, beside]), np.concatenate([F, F + len(V)])))
    fixed, top = _bottom_top(V)
    s.set_constraints(None, fixed, [top])
    s.drag([translation(0.5)])  # refused before: the second cactus had no constraint
    P, Q = beside[::50], s.U[len(V):][::50]
    assert np.abs(Q - P).max() > 0.05  # it went along
    np.testing.assert_allclose(np.linalg.norm(Q[:, None] - Q[None], axis=2),
                               np.linalg.norm(P[:, None] - P[None], axis=2), atol=1e-9)  # as one rigid piece
    s.set_params(loose="hold")
    s.drag([translation(0.6)])
    np.testing.assert_array_equal(s.U[len(V):], beside)
