"""Constraints files of version 2 carry stiffness; version-1 files still load; `arap deform` honours it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.cli import main
from arap.constraints import FORMAT_VERSION, load_constraints, save_constraints
from arap.errors import ConstraintError
from arap.io import load_mesh
from arap.meshes.shapes import builtin_mesh
from tests.core.scenarios import rigid_misfit


def _bar_document() -> tuple[np.ndarray, dict]:
    V, _ = builtin_mesh("bar")
    fixed = np.flatnonzero(V[:, 1] < 0.3)
    handles = np.flatnonzero(V[:, 1] > 4.7)
    doc = {"fixed": fixed.tolist(), "handles": handles.tolist(),
           "targets": (V[handles] + [1.5, 0.0, 0.0]).tolist()}
    return V, doc


def test_version_1_files_load_unchanged(tmp_path: Path) -> None:
    V, doc = _bar_document()
    (tmp_path / "v1.json").write_text(json.dumps(doc))
    c = load_constraints(tmp_path / "v1.json", len(V))
    assert c.stiffness is None and c.fixed.tolist() == doc["fixed"]
    assert "version" not in c.to_dict() and "stiffness" not in c.to_dict()
    assert load_constraints(doc | {"version": 1}, len(V)).stiffness is None


def test_stiffness_round_trip(tmp_path: Path) -> None:
    V, doc = _bar_document()
    middle = np.flatnonzero(np.abs(V[:, 1] - 2.5) < 0.5)
    doc |= {"version": 2, "stiffness": [{"vertices": middle[:10].tolist(), "value": 25},
                                        {"vertices": middle[10:].tolist(), "value": "rigid"}]}
    c = load_constraints(doc, len(V))
    assert c.stiffness is not None and c.stiffness[middle[0]] == 25.0 and np.isinf(c.stiffness[middle[-1]])
    assert np.count_nonzero(c.stiffness != 1.0) == len(middle)
    save_constraints(tmp_path / "c.json", c)
    saved = json.loads((tmp_path / "c.json").read_text())
    assert saved["version"] == FORMAT_VERSION
    again = load_constraints(tmp_path / "c.json", len(V))
    np.testing.assert_array_equal(again.stiffness, c.stiffness)
    per_vertex = load_constraints(doc | {"stiffness": ["rigid" if np.isinf(x) else x for x in c.stiffness.tolist()]},
                                  len(V))
    np.testing.assert_array_equal(per_vertex.stiffness, c.stiffness)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"stiffness": [{"vertices": [0], "value": 2}]}, "version"),
        ({"version": 3}, "version 3"),
        ({"version": "2"}, r'version must be a JSON integer \(1 to 2\), got "2"'),
        ({"version": 2.0}, r"version must be a JSON integer \(1 to 2\), got 2\.0"),
        ({"version": True}, r"version must be a JSON integer \(1 to 2\), got true"),
        ({"version": 2, "stiffness": [{"vertices": [0], "value": 0}]}, "positive"),
        ({"version": 2, "stiffness": [{"vertices": [0], "value": "soft"}]}, "rigid"),
        ({"version": 2, "stiffness": [{"vertices": [0], "value": True}]}, "positive"),
        ({"version": 2, "stiffness": [{"vertices": [0, 1], "value": 2}, {"vertices": [1], "value": 3}]}, "two"),
        ({"version": 2, "stiffness": [{"vertices": [10**9], "value": 2}]}, "out of range"),
        ({"version": 2, "stiffness": [1.0, 2.0]}, "one value per vertex"),
        ({"version": 2, "stiffness": {"0": 2}}, "list"),
    ],
)
def test_bad_stiffness_is_refused(change: dict, match: str) -> None:
    V, doc = _bar_document()
    with pytest.raises(ConstraintError, match=match):
        load_constraints(doc | change, len(V))


def test_deform_keeps_a_rigid_region_rigid(tmp_path: Path) -> None:
    V, doc = _bar_document()
    middle = np.flatnonzero(np.abs(V[:, 1] - 2.5) < 0.6)
    doc |= {"version": 2, "stiffness": [{"vertices": middle.tolist(), "value": "rigid"}]}
    (tmp_path / "c.json").write_text(json.dumps(doc))
    plain = {k: v for k, v in doc.items() if k not in ("version", "stiffness")}
    (tmp_path / "plain.json").write_text(json.dumps(plain))
    assert main(["deform", "bar", "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "rigid.obj"), "-q"]) == 0
    assert main(["deform", "bar", "-c", str(tmp_path / "plain.json"), "-o", str(tmp_path / "plain.obj"), "-q"]) == 0
    rigid, _ = load_mesh(tmp_path / "rigid.obj")
    bent, _ = load_mesh(tmp_path / "plain.obj")
    assert rigid_misfit(V, rigid, middle) < 1e-6
    assert rigid_misfit(V, bent, middle) > 1e-3


def test_point_handles_in_files_and_deform(tmp_path: Path) -> None:
    V, doc = _bar_document()
    _, F = builtin_mesh("bar")
    top_face = int(np.argmax(V[F].mean(axis=1)[:, 1]))
    target = (V[F[top_face]].mean(axis=0) + np.array([1.0, 0.0, 0.0])).tolist()
    doc = {"fixed": doc["fixed"], "version": 2,
           "points": [{"face": top_face, "barycentric": [1 / 3, 1 / 3, 1 / 3], "target": target}]}
    c = load_constraints(doc, len(V), len(F))
    assert c.points is not None and c.points.hard.all() and c.point_targets is not None
    save_constraints(tmp_path / "c.json", c)
    again = load_constraints(tmp_path / "c.json", len(V), len(F))
    np.testing.assert_array_equal(again.point_targets, c.point_targets)
    assert main(["deform", "bar", "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "out.obj"), "-q"]) == 0
    U, _ = load_mesh(tmp_path / "out.obj")
    assert np.abs(U[F[top_face]].mean(axis=0) - target).max() < 1e-9 * np.linalg.norm(np.ptp(V, axis=0))
    soft = doc | {"points": [doc["points"][0] | {"weight": 5.0}]}
    assert load_constraints(soft, len(V), len(F)).points.weights.tolist() == [5.0]
    for bad, match in (({"version": 1}, "version"), ({"points": [{"face": 0}]}, "barycentric"),
                       ({"points": [doc["points"][0] | {"face": 10**7}]}, "out of range"),
                       ({"points": [doc["points"][0] | {"weight": -1}]}, "positive")):
        with pytest.raises(ConstraintError, match=match):
            load_constraints(doc | bad, len(V), len(F))
    with pytest.raises(ConstraintError, match="triangle count"):
        load_constraints(doc, len(V))


@pytest.mark.parametrize(
    ("point", "stiffness", "match"),
    [
        ({"face": 10**30}, None, r"point face 1000000000000000000000000000000 out of range 0\.\.8623"),
        ({"face": 2**63}, None, r"point face 9223372036854775808 out of range"),
        ({"weight": 10**320}, None, r"points\[0\].weight .*too large"),
        ({}, [{"vertices": [0], "value": 10**320}], r"stiffness\[0\].value must be a positive number .*got 1000"),
        ({}, [10**320] * 4314, r"stiffness\[0\] must be a positive number .*got 1000"),
    ],
)
def test_integers_too_large_for_a_double_are_refused_by_name(tmp_path: Path, point: dict, stiffness: list | None,
                                                             match: str, capsys: pytest.CaptureFixture[str]) -> None:
    V, doc = _bar_document()
    doc = {"fixed": doc["fixed"], "version": 2,
           "points": [{"face": 8000, "barycentric": [1, 0, 0], "target": [0.0, 5.0, 0.0]} | point]}
    if stiffness is not None:
        doc["stiffness"] = stiffness
    with pytest.raises(ConstraintError, match=match):
        load_constraints(doc, len(V), 8624)
    (tmp_path / "c.json").write_text(json.dumps(doc))
    assert main(["deform", "bar", "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "out.obj"), "-q"]) == 1
    assert "internal error" not in capsys.readouterr().err


def test_point_targets_absurdly_far_are_refused_like_vertex_targets(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    V, doc = _bar_document()
    _, F = builtin_mesh("bar")
    doc = {"fixed": doc["fixed"], "version": 2,
           "points": [{"face": len(F) - 1, "barycentric": [1, 0, 0], "target": [1e300, 0.0, 0.0]}]}
    c = load_constraints(doc, len(V), len(F))
    with pytest.raises(ConstraintError, match="the targets lie too far from the mesh"):
        c.indices_and_targets(V)
    (tmp_path / "c.json").write_text(json.dumps(doc))
    assert main(["deform", "bar", "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "out.obj"), "-q",
                 "-n", "3"]) == 1
    assert "too far" in capsys.readouterr().err and not (tmp_path / "out.obj").exists()


def test_welded_copies_with_different_stiffness_are_named() -> None:
    """Mesh repair welds the copies of a vertex (an STL soup has one per triangle): copies painted alike count once,
    copies painted differently are refused, as handle copies with different targets are."""
    weld = np.array([0, 0, 1, 1, 2, 3])
    same = load_constraints({"version": 2, "fixed": [5], "stiffness": [2, 2, "rigid", "rigid", 1, 1]}, 6)
    np.testing.assert_array_equal(same.remapped(weld).stiffness, [2.0, np.inf, 1.0, 1.0])
    differ = load_constraints({"version": 2, "fixed": [5], "stiffness": [2, 2, 3, "rigid", 1, 1]}, 6)
    with pytest.raises(ConstraintError, match=r"welded vertices 2 and 3 .*stiffness differs: 3(\.0)? and rigid"):
        differ.remapped(weld)
