"""One validator, one answer: the library, the command line and the studio's session layer accept and refuse the
same constraint selections, with the same message."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.cli import main
from arap.constraints import load_constraints
from arap.errors import ConstraintError
from arap.io import load_mesh
from arap.server.constraints import ConstraintSet
from arap.server.meshdata import MeshData
from arap.server.protocol import RequestError
from arap.server.session import Session
from arap.shapes import builtin_mesh
from arap.solver import ArapSolver

V, F = builtin_mesh("bar")
N = len(V)
BOTTOM = np.flatnonzero(V[:, 1] < 0.3).tolist()
TOP = np.flatnonzero(V[:, 1] > 4.7).tolist()

BAD: list[tuple[dict[str, Any], str]] = [
    ({"fixed": [1.0]}, "fixed must be a flat list of integer vertex indices; item 0 is 1.0"),
    ({"fixed": [0, 2.5]}, "fixed must be a flat list of integer vertex indices; item 1 is 2.5"),
    ({"fixed": [True]}, "item 0 is True"),
    ({"fixed": ["3"]}, "item 0 is '3'"),
    ({"fixed": [[3]]}, "item 0 is [3]"),
    ({"fixed": [N]}, f"fixed has 1 indices out of range [0, {N}) (first: item 0 = {N})"),
    ({"fixed": [-1]}, "fixed has 1 indices out of range"),
    ({"fixed": [10**30]}, "(first: item 0 = 1000000000000000000000000000000)"),
    ({"fixed": [3, 3]}, "fixed lists 1 vertices more than once (first: 3)"),
    ({"fixed": [0], "roi": []}, "roi is empty"),
    ({"fixed": [0], "roi": [0, 1, 1]}, "roi lists 1 vertices more than once"),
    ({"fixed": [0], "roi": [0, 1.0]}, "roi must be a flat list of integer vertex indices; item 1 is 1.0"),
    ({"fixed": [0], "roi": [0, N]}, "roi has 1 indices out of range"),
    ({"fixed": [3], "handles": [3], "targets": [[0, 0, 0]]}, "vertex 3 is in both fixed and handles"),
    ({"fixed": [0], "handles": [5, 5], "targets": [[0, 0, 0]] * 2}, "handles lists 1 vertices more than once"),
    ({"fixed": [0], "handles": [5.0], "targets": [[0, 0, 0]]}, "handles must be a flat list of integer"),
]


def _server_message(case: dict[str, Any]) -> str:
    handles = case.get("handles", [])
    with pytest.raises(RequestError) as info:
        ConstraintSet.build(V, V, case.get("roi"), case.get("fixed", []), [handles] if handles else [])
    assert info.value.code == "bad_constraints"
    session = Session()
    session.load(MeshData.make("bar", V, F))
    with pytest.raises(RequestError) as again:
        session.set_constraints(case.get("roi"), case.get("fixed", []), [handles] if handles else [])
    assert (again.value.code, again.value.message) == ("bad_constraints", info.value.message)
    assert session.constraints.is_empty
    return info.value.message.replace("handle group 0", "handles")


def _cli_message(case: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps(case))
    assert main(["deform", "bar", "-c", str(cfile), "-o", str(tmp_path / "o.obj")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("arap: error: ")
    return err.removeprefix("arap: error: ")


@pytest.mark.parametrize(("case", "expected"), BAD)
def test_same_refusal_everywhere(case: dict[str, Any], expected: str, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConstraintError) as library:
        load_constraints(case, N)
    message = str(library.value)
    assert expected in message
    assert _server_message(case) == message
    assert _cli_message(case, tmp_path, capsys) == message
    if "handles" not in case:  # the solver sees fixed vertices and handles as one list, "constrained"
        with pytest.raises(ConstraintError) as solver:
            ArapSolver(V, F, case["fixed"], roi=case.get("roi"))
        assert str(solver.value).replace("constrained", "fixed") == message


def test_handles_outside_the_region_of_interest_are_accepted_everywhere(tmp_path: Path) -> None:
    """A handle outside the ROI is a constrained vertex like any other: it reaches its target, the free vertices
    outside the ROI stay at rest (the studio's own documents hold such handles for vertices it keeps displaced)."""
    roi = np.flatnonzero(V[:, 1] < 4.0).tolist()
    handles = TOP  # all outside the ROI
    targets = (V[handles] + [0.5, 0, 0]).tolist()
    case = {"fixed": BOTTOM, "handles": handles, "targets": targets, "roi": roi}
    c = load_constraints(case, N)
    assert set(c.handles.tolist()).isdisjoint(roi)
    cs = ConstraintSet.build(V, V, roi, BOTTOM, [handles])
    assert len(cs.groups) == 1
    session = Session()
    session.load(MeshData.make("bar", V, F))
    session.set_constraints(roi, BOTTOM, [handles], targets)
    np.testing.assert_allclose(session.U[handles], targets, atol=1e-9)
    indices, all_targets = c.indices_and_targets(V)
    U = ArapSolver(V, F, indices, roi=c.roi).solve(all_targets, max_iterations=3).vertices
    np.testing.assert_allclose(U[handles], targets, atol=1e-9)
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps(case))
    assert main(["deform", "bar", "-c", str(cfile), "-o", str(tmp_path / "o.ply"), "-n", "3", "-q"]) == 0
    U_cli, _ = load_mesh(tmp_path / "o.ply")
    np.testing.assert_allclose(U_cli, U, atol=1e-9)
    outside = np.setdiff1d(np.arange(N), np.concatenate([roi, handles]))
    np.testing.assert_array_equal(U_cli[outside], V[outside])


def test_studio_documents_load_in_the_library() -> None:
    """What the studio saves (handles for displaced vertices outside the ROI included) the library reads back."""
    session = Session()
    session.load(MeshData.make("bar", V, F))
    session.set_constraints(None, BOTTOM, [TOP], (V[TOP] + [0.5, 0, 0]).tolist())
    roi = np.flatnonzero(V[:, 1] < 2.5).tolist()
    session.set_constraints(roi, BOTTOM, [TOP[:3]])  # the displaced top outside the new ROI is held
    doc = session.constraints_document()
    c = load_constraints(doc, N)
    assert len(c.handles) > 3 and not set(c.handles.tolist()) <= set(roi)


@pytest.mark.parametrize(("point", "expected"), [
    ({"face": len(F), "barycentric": [0.2, 0.3, 0.5]}, f"point face {len(F)} out of range"),
    ({"face": 0, "barycentric": [0.2, 0.2, 0.2]}, "barycentric coordinates of point 0 must be >= 0 and sum to 1"),
    ({"face": 0, "barycentric": [1.5, -0.5, 0.0]}, "barycentric coordinates of point 0 must be >= 0 and sum to 1"),
])
def test_point_handles_are_refused_alike_by_files_and_the_studio(point: dict[str, Any], expected: str) -> None:
    with pytest.raises(ConstraintError, match=expected):
        load_constraints({"fixed": BOTTOM, "version": 2, "points": [point | {"target": [0.0, 0.0, 0.0]}]}, N, len(F))
    session = Session()
    session.load(MeshData.make("bar", V, F))
    with pytest.raises(RequestError, match=expected) as err:
        session.set_constraints(None, BOTTOM, [], points=[point])
    assert err.value.code == "bad_constraints"
