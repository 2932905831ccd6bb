"""One validator, one answer: the library, the command line and the studio's session layer accept and refuse the
same constraint selections, with the same message; the solver's options are named, defaulted and checked in
arap.options only."""

from __future__ import annotations

import ast
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import arap.options
from arap.cli import main
from arap.constraints import load_constraints
from arap.errors import ConstraintError, OptionError
from arap.io import load_mesh
from arap.meshes.shapes import builtin_mesh
from arap.method.cells import build_cells
from arap.method.weights import corner_weights, edge_weight_matrix
from arap.options import (
    DEFAULT_ENERGY,
    DEFAULT_WEIGHTS,
    check_alpha,
    check_energy_and_weights,
    check_solve_options,
    check_weights,
)
from arap.server.constraints import ConstraintSet
from arap.server.errors import request_error
from arap.server.mesh_model import MeshData
from arap.server.session import Session
from arap.server.session_errors import ConstraintsRejected
from arap.solve.solver import ArapSolver

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
    with pytest.raises(ConstraintsRejected) as info:
        ConstraintSet.build(V, V, case.get("roi"), case.get("fixed", []), [handles] if handles else [])
    assert request_error(info.value).code == "bad_constraints"
    session = Session()
    session.load(MeshData.make("bar", V, F))
    with pytest.raises(ConstraintsRejected) as again:
        session.set_constraints(case.get("roi"), case.get("fixed", []), [handles] if handles else [])
    assert (request_error(again.value).code, again.value.message) == ("bad_constraints", info.value.message)
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
    with pytest.raises(ConstraintsRejected, match=expected) as err:
        session.set_constraints(None, BOTTOM, [], points=[point])
    assert request_error(err.value).code == "bad_constraints"


# ---------------------------------------------------------------------------------------------- solver options
SRC = Path(arap.__file__).parent


def _top_level_names(path: Path) -> set[str]:
    """The names a module defines at its top level (functions, classes, assignments; not imports)."""
    names: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {n.id for target in node.targets for n in ast.walk(target) if isinstance(n, ast.Name)}
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names


def _definitions() -> dict[str, list[str]]:
    where: dict[str, list[str]] = {}
    for path in sorted(SRC.rglob("*.py")):
        for name in _top_level_names(path):
            where.setdefault(name, []).append(path.relative_to(SRC).as_posix())
    return where


def test_each_option_name_default_and_check_is_defined_once() -> None:
    """The solver's option vocabulary (names, defaults, checks) is defined in arap/options.py and nowhere else; the
    command line's checks of its option values in arap/cli/common.py; the studio's labels in arap/server/labels.py."""
    where = _definitions()
    homes = {name: "options.py" for name in arap.options.__all__}
    homes |= {name: "cli/common.py" for name in ("alpha_value", "positive_int", "token_value", "origin_value",
                                                  "check_iterations_and_tolerance", "check_bench_runs")}
    homes |= {"ENERGY_LABELS": "server/labels.py", "WEIGHT_LABELS": "server/labels.py"}
    for name, home in homes.items():
        assert where.get(name) == [home], f"{name} is defined in {where.get(name)}, expected only in {home}"


def test_the_library_refuses_bad_options_with_the_checks_of_arap_options() -> None:
    def message(call: Callable[[], object]) -> str:
        with pytest.raises(OptionError) as info:
            call()
        return str(info.value)

    energy = message(lambda: check_energy_and_weights("twist", DEFAULT_WEIGHTS))
    assert "unknown energy 'twist'" in energy
    assert message(lambda: ArapSolver(V, F, BOTTOM, energy="twist")) == energy  # type: ignore[arg-type]
    assert message(lambda: build_cells(V, F, energy="twist")) == energy
    weights = message(lambda: check_weights("heavy"))
    assert "unknown weights 'heavy'" in weights
    assert message(lambda: check_energy_and_weights(DEFAULT_ENERGY, "heavy")) == weights
    assert message(lambda: ArapSolver(V, F, BOTTOM, weights="heavy")) == weights  # type: ignore[arg-type]
    assert message(lambda: corner_weights(V, F, "heavy")) == weights
    assert message(lambda: edge_weight_matrix(V, F, "heavy")) == weights
    alpha = message(lambda: check_alpha(-1.0))
    assert alpha.startswith("alpha must be a number from 0 to")
    assert message(lambda: ArapSolver(V, F, BOTTOM, energy="smooth_rotations", alpha=-1.0)) == alpha
    solver = ArapSolver(V, F, BOTTOM)
    for options in ({"acceleration": "fast"}, {"tolerance": -1.0}, {"max_iterations": 2.5}, {"window": 0}):
        checked = {"max_iterations": None, "tolerance": 0.0, "acceleration": "lbfgs", "window": None} | options
        expected = message(lambda checked=checked: check_solve_options(**checked))  # type: ignore[misc]
        assert message(lambda options=options: solver.solve(V[BOTTOM], **options)) == expected  # type: ignore[misc]


def test_the_command_line_refuses_a_bad_alpha_with_the_library_message(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(OptionError) as library:
        check_alpha(-1.0)
    for command in (["deform", "bar", "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "o.obj")], ["bench"]):
        assert main([*command, "--alpha", "-1"]) == 2
        assert f"argument --alpha: {library.value}" in capsys.readouterr().err
