"""The solver's set-up record and its add-ons: built once, never changed by a solve, one add-on per feature."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import arap
from arap import ArapSolver
from arap.solve.addons import PlainFit, PointHandles, RigidAddOn, SmoothAddOn, SmoothFit
from arap.solve.iteration import lbfgs_applies
from arap.solve.prepared import Prepared, prepare


@pytest.fixture(scope="module")
def sphere() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    V, F = arap.builtin_mesh("sphere:400")
    con = np.r_[np.flatnonzero(V[:, 1] < -0.6), np.flatnonzero(V[:, 1] > 0.7)]
    T = V[con].copy()
    T[V[con, 1] > 0] += [0.3, 0.1, 0.0]
    return V, F, con, T


def _arrays(p: Prepared) -> dict[str, bytes]:
    """Every array the record holds directly, as bytes."""
    out = {}
    for f in dataclasses.fields(p):
        value = getattr(p, f.name)
        if isinstance(value, np.ndarray):
            out[f.name] = value.tobytes()
    for name in ("a", "b", "w", "ptr"):
        out["cells." + name] = getattr(p.cells, name).tobytes()
    out["matrix"] = p.matrix.data.tobytes()
    return out


def test_the_record_is_frozen_and_solves_leave_it_unchanged(sphere) -> None:
    V, F, con, T = sphere
    solver = ArapSolver(V, F, con)
    p = solver.prepared
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.nf = 0  # type: ignore[misc]
    before = _arrays(p)
    solver.solve(T)
    solver.solve(T * 1.01, initial="rest", acceleration="anderson")
    solver.fit_rotations(solver.current_vertices())
    assert _arrays(p) == before


def test_two_solvers_on_one_record_shape_give_the_same_result(sphere) -> None:
    V, F, con, T = sphere
    a, b = ArapSolver(V, F, con), ArapSolver(V, F, con)
    a.solve(T * 0.9)  # a's state differs; a cold start must not depend on it
    ra, rb = a.solve(T, initial="rest"), b.solve(T, initial="rest")
    np.testing.assert_array_equal(ra.vertices, rb.vertices)


@pytest.mark.parametrize(("options", "kinds", "fit", "lbfgs"), [
    ({}, [], PlainFit, True),
    ({"energy": "smooth_rotations"}, [SmoothAddOn], SmoothFit, False),
    ({"stiffness": "rigid"}, [RigidAddOn], PlainFit, False),
    ({"energy": "smooth_rotations", "stiffness": "rigid"}, [SmoothAddOn, RigidAddOn], SmoothFit, False),
    ({"points": "soft"}, [PointHandles], PlainFit, True),
    ({"points": "hard"}, [PointHandles], PlainFit, False),
])
def test_each_feature_is_one_add_on_in_a_fixed_order(sphere, options, kinds, fit, lbfgs) -> None:
    V, F, con, _ = sphere
    kw = dict(options)
    if kw.get("stiffness") == "rigid":
        stiffness = np.ones(len(V))
        stiffness[(V[:, 1] > 0) & (V[:, 1] < 0.3)] = np.inf
        kw["stiffness"] = stiffness
    P = None
    if "points" in kw:
        weight = np.inf if kw["points"] == "hard" else 2.0
        bary = np.array([[0.2, 0.3, 0.5]])
        kw["points"] = (np.array([7]), bary, np.array([weight]))
        P = bary @ V[F[7]] + 0.05
    p = prepare(V, F, con, **kw)
    assert [type(a) for a in p.addons] == kinds
    assert type(p.rotation_fit) is fit
    internal_P = None if P is None else p.check_point_targets(P)
    assert lbfgs_applies(p, internal_P) is lbfgs
    assert lbfgs_applies(p, None) is (lbfgs or kw.get("points") is not None)


def test_the_solver_reads_its_options_from_the_record(sphere) -> None:
    V, F, con, _ = sphere
    stiffness = np.full(len(V), 2.0)
    solver = ArapSolver(V, F, con, energy="spokes", weights="clamped", stiffness=stiffness, alpha=0.5)
    p = solver.prepared
    assert (solver.energy_type, solver.weight_type, solver.alpha) == ("spokes", "clamped", 0.5)
    assert solver.stiffness is p.stiffness and solver.factor is p.factor
    assert solver.n_free == p.nf == len(solver.free)
    assert sorted(np.r_[solver.free, solver.nonfree]) == list(range(len(V)))
    np.testing.assert_array_equal(p.to_caller(p.rest), V)
