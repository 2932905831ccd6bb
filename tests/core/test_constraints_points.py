"""Constraints files of version 3 carry point handles (face, barycentric coordinates, target, optional weight); older
files still load; `arap deform` meets hard points and pulls soft ones."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.cli import main
from arap.constraints import load_constraints, save_constraints
from arap.errors import ConstraintError
from arap.io import load_mesh
from arap.shapes import builtin_mesh


def _bar_points_document() -> tuple[np.ndarray, np.ndarray, dict]:
    """The bar, its bottom fixed, two points near its top pulled sideways (one hard, one soft)."""
    V, F = builtin_mesh("bar")
    fixed = np.flatnonzero(V[:, 1] < 0.3)
    centroids = V[F].mean(axis=1)
    top = np.flatnonzero(centroids[:, 1] > 4.6)[:2]
    bary = [[0.2, 0.3, 0.5], [0.6, 0.2, 0.2]]
    rest = np.einsum("pj,pjk->pk", np.asarray(bary), V[F[top]])
    targets = rest + np.array([1.0, 0.0, 0.0])
    doc = {"version": 3, "fixed": fixed.tolist(), "points": [
        {"face": int(top[0]), "barycentric": bary[0], "target": targets[0].tolist()},
        {"face": int(top[1]), "barycentric": bary[1], "target": targets[1].tolist(), "weight": 50.0},
    ]}
    return V, F, doc


def test_version_1_files_load_without_points(tmp_path: Path) -> None:
    V, F = builtin_mesh("bar")
    doc = {"fixed": [0, 1, 2], "handles": [40], "targets": [V[40].tolist()]}
    (tmp_path / "v1.json").write_text(json.dumps(doc))
    c = load_constraints(tmp_path / "v1.json", len(V), len(F))
    assert len(c.point_faces) == 0 and c.point_handles(len(F)) is None
    assert "points" not in c.to_dict() and "version" not in c.to_dict()


def test_points_round_trip(tmp_path: Path) -> None:
    V, F, doc = _bar_points_document()
    c = load_constraints(doc, len(V), len(F))
    assert c.point_faces.tolist() == [p["face"] for p in doc["points"]]
    assert np.isinf(c.point_weights[0]) and c.point_weights[1] == 50.0
    save_constraints(tmp_path / "c.json", c)
    saved = json.loads((tmp_path / "c.json").read_text())
    assert saved["version"] == 3 and "weight" not in saved["points"][0]
    again = load_constraints(tmp_path / "c.json", len(V), len(F))
    for name in ("point_faces", "point_barycentric", "point_targets", "point_weights"):
        np.testing.assert_array_equal(getattr(again, name), getattr(c, name))
    hard = load_constraints(doc | {"points": [doc["points"][0] | {"weight": "hard"}]}, len(V), len(F))
    assert hard.point_weights.tolist() == [np.inf]


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"version": 2}, '"points" needs "version": 3'),
        ({"points": {"face": 0}}, "list"),
        ({"points": [{"face": 0, "barycentric": [1, 0, 0]}]}, '"target"'),
        ({"points": [{"face": 0, "barycentric": [1, 0, 0], "target": [0, 0, 0], "colour": 1}]}, '"target"'),
        ({"points": [{"face": 10**7, "barycentric": [1, 0, 0], "target": [0, 0, 0]}]}, "out of range"),
        ({"points": [{"face": 0, "barycentric": [0.5, 0.4, 0], "target": [0, 0, 0]}]}, "sum to 1"),
        ({"points": [{"face": 0, "barycentric": [1, 0, 0], "target": [0, 0]}]}, "target"),
        ({"points": [{"face": 0, "barycentric": [1, 0, 0], "target": [0, 0, 0], "weight": 0}]}, "weight"),
        ({"points": [{"face": 0, "barycentric": [1, 0, 0], "target": [0, 0, 0], "weight": "soft"}]}, "weight"),
    ],
)
def test_bad_points_are_refused(change: dict, match: str) -> None:
    V, F, doc = _bar_points_document()
    with pytest.raises(ConstraintError, match=match):
        load_constraints(doc | change, len(V), len(F))


def test_points_need_the_face_count() -> None:
    V, _, doc = _bar_points_document()
    with pytest.raises(ConstraintError, match="face count"):
        load_constraints(doc, len(V))


def test_deform_meets_hard_points_and_pulls_soft_ones(tmp_path: Path) -> None:
    V, F, doc = _bar_points_document()
    (tmp_path / "c.json").write_text(json.dumps(doc))
    assert main(["deform", "bar", "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "out.obj"), "-q"]) == 0
    U, _ = load_mesh(tmp_path / "out.obj")
    c = load_constraints(doc, len(V), len(F))
    points = c.point_handles(len(F))
    assert points is not None
    reached = points.positions(U, F)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    assert np.abs(reached[0] - c.point_targets[0]).max() <= 1e-6 * diag  # through an OBJ file's digits
    start = points.positions(V, F)[1]
    gap = np.linalg.norm(reached[1] - c.point_targets[1])
    assert 0 < gap < 0.5 * np.linalg.norm(c.point_targets[1] - start)
    np.testing.assert_allclose(U[c.fixed], V[c.fixed], atol=1e-6 * diag)
