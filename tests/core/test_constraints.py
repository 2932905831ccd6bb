"""Constraint files: a valid file round-trips; every kind of bad input raises ConstraintError."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.constraints import Constraints, load_constraints, save_constraints
from arap.errors import ArapError, ConstraintError
from arap.solve.indexing import check_index_array

N = 10


def valid() -> dict[str, Any]:
    return {"fixed": [0, 1], "handles": [8, 9], "targets": [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]]}


def test_load_valid_dict_and_file(tmp_path: Path) -> None:
    c = load_constraints(valid(), N)
    np.testing.assert_array_equal(c.fixed, [0, 1])
    np.testing.assert_array_equal(c.handles, [8, 9])
    assert c.targets.shape == (2, 3) and c.targets.dtype == np.float64
    assert c.roi is None and c.handle_groups is None
    path = tmp_path / "c.json"
    path.write_text(json.dumps(valid()))
    c2 = load_constraints(path, N)
    np.testing.assert_array_equal(c2.targets, c.targets)
    c3 = load_constraints(str(path), N)
    np.testing.assert_array_equal(c3.handles, c.handles)


def test_indices_and_targets_puts_fixed_at_rest() -> None:
    V = np.arange(3 * N, dtype=float).reshape(N, 3)
    c = load_constraints(valid(), N)
    idx, T = c.indices_and_targets(V)
    np.testing.assert_array_equal(idx, [0, 1, 8, 9])
    np.testing.assert_array_equal(T[:2], V[[0, 1]])
    np.testing.assert_array_equal(T[2:], valid()["targets"])


def test_fixed_only_handles_only_roi_and_groups() -> None:
    c = load_constraints({"fixed": [3]}, N)
    assert len(c.handles) == 0 and c.targets.shape == (0, 3)
    c = load_constraints({"handles": [3], "targets": [[1, 2, 3]]}, N)
    assert len(c.fixed) == 0
    data = valid() | {"roi": [0, 1, 5, 8, 9], "handle_groups": [[8], [9]], "meta": {"mesh": "bar"}}
    c = load_constraints(data, N)
    np.testing.assert_array_equal(c.roi, [0, 1, 5, 8, 9])
    assert c.handle_groups == [[8], [9]]
    c = load_constraints({"fixed": np.array([1, 2]), "handles": np.array([3]), "targets": np.ones((1, 3))}, N)
    np.testing.assert_array_equal(c.constrained, [1, 2, 3])


def test_save_and_load_round_trip(tmp_path: Path) -> None:
    c = load_constraints(valid() | {"roi": [0, 1, 8, 9], "handle_groups": [[8, 9]]}, N)
    path = tmp_path / "out.json"
    save_constraints(path, c)
    back = load_constraints(path, N)
    for name in ("fixed", "handles", "targets", "roi"):
        np.testing.assert_array_equal(getattr(back, name), getattr(c, name))
    assert back.handle_groups == [[8, 9]]
    bad = Constraints(c.fixed, c.handles, np.full((2, 3), np.nan))
    with pytest.raises(ConstraintError, match="non-finite"):
        save_constraints(tmp_path / "bad.json", bad)


def test_remapped_follows_a_vertex_renumbering() -> None:
    c = load_constraints(valid(), N)
    vmap = np.array([5, 4, -1, 3, 2, 1, 0, 6, 7, 8])
    r = c.remapped(vmap)
    np.testing.assert_array_equal(r.fixed, [5, 4])
    np.testing.assert_array_equal(r.handles, [7, 8])
    with pytest.raises(ConstraintError, match="removed by mesh repair"):
        load_constraints({"fixed": [2]}, N).remapped(vmap)
    # a region of interest naming a vertex repair dropped (used by no face) keeps the others
    roi = load_constraints({"fixed": [0], "roi": [0, 1, 2, 3]}, N).remapped(vmap).roi
    assert roi is not None and roi.tolist() == [3, 4, 5]
    # Copies of one vertex that repair welded (an STL soup has one per triangle) count once when they agree.
    weld = np.array([0, 0, 1, 1, 2, 3, 4, 5, 6, 7])
    both_fixed = load_constraints({"fixed": [0, 1, 2]}, N).remapped(weld)
    np.testing.assert_array_equal(both_fixed.fixed, [0, 1])
    same_target = load_constraints({"handles": [2, 3, 4], "targets": [[1, 2, 3], [1, 2, 3], [0, 0, 0]],
                                    "handle_groups": [[2], [3, 4]]}, N).remapped(weld)
    np.testing.assert_array_equal(same_target.handles, [1, 2])
    np.testing.assert_array_equal(same_target.targets, [[1, 2, 3], [0, 0, 0]])
    assert same_target.handle_groups == [[1], [2]]
    with pytest.raises(ConstraintError, match=r"welded handle vertices 2 and 3 .*targets differ"):
        load_constraints({"handles": [2, 3], "targets": [[1, 2, 3], [1, 2, 4]]}, N).remapped(weld)
    with pytest.raises(ConstraintError, match="welded handle vertex 1 with a fixed vertex"):
        load_constraints({"fixed": [0], "handles": [1], "targets": [[0, 0, 0]]}, N).remapped(weld)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"fixd": [1]}, "unknown constraint keys"),
        ({"fixed": None, "handles": None}, "list of vertex indices"),
        ({"fixed": "0 1"}, "list of vertex indices"),
        ({"fixed": [0, 1.5]}, "integer vertex indices; item 1"),
        ({"fixed": [0, 1.0]}, "integer vertex indices"),
        ({"fixed": [True]}, "integer vertex indices"),
        ({"fixed": [[0, 1]]}, "integer vertex indices"),
        ({"fixed": [0, N]}, rf"out of range \[0, {N}\)"),
        ({"fixed": [-1]}, "out of range"),
        ({"handles": [8, 8], "targets": [[0, 0, 0]] * 2}, "lists 1 vertices more than once"),
        ({"fixed": [0, 8]}, "both fixed and handles"),
        ({"targets": [[0, 0, 0]]}, "has 1 points but \"handles\" has 2"),
        ({"targets": [[0, 0], [1, 1]]}, "must be \\[x, y, z\\]"),
        ({"targets": [[0, 0, "a"], [1, 1, 1]]}, "must be \\[x, y, z\\]"),
        ({"targets": np.array([[0, 0, np.nan], [1, 1, 1]])}, "non-finite"),
        ({"targets": np.array([[0, 0, np.inf], [1, 1, 1]])}, "non-finite"),
        ({"targets": np.zeros((2, 4))}, r"shape \(k, 3\)"),
        ({"targets": {"a": 1}}, "list of \\[x, y, z\\]"),
        ({"fixed": [], "handles": [], "targets": []}, "no vertex is constrained"),
        ({"roi": []}, "roi is empty"),
        ({"roi": [0, 0, 8, 9]}, "more than once"),
        ({"handle_groups": [[8, 11]]}, "out of range"),
        ({"handle_groups": 8}, "list of lists"),
        ({"handle_groups": [[8], [0]]}, r'handle_groups\[1\] names vertex 0, which is not in "handles"'),
        ({"handle_groups": [[8, 9], [9]]}, r"vertex 9 is in handle_groups\[0\] and handle_groups\[1\]"),
        ({"meta": 3}, "JSON object"),
    ],
)
def test_bad_input(change: dict[str, Any], message: str) -> None:
    data = valid() | change
    with pytest.raises(ConstraintError, match=message):
        load_constraints(data, N)


def test_missing_keys() -> None:
    with pytest.raises(ConstraintError, match='need "fixed" and/or "handles"'):
        load_constraints({"targets": []}, N)
    with pytest.raises(ConstraintError, match='without "targets"'):
        load_constraints({"handles": [1]}, N)


def test_bad_files(tmp_path: Path) -> None:
    with pytest.raises(ConstraintError, match="cannot read"):
        load_constraints(tmp_path / "missing.json", N)
    path = tmp_path / "broken.json"
    path.write_text('{"fixed": [1, 2')
    with pytest.raises(ConstraintError, match=r"not valid JSON.*line 1"):
        load_constraints(path, N)
    path.write_text('{"fixed": [1], "handles": [2], "targets": [[NaN, 0, 0]]}')
    with pytest.raises(ConstraintError, match="NaN"):
        load_constraints(path, N)
    path.write_text("[1, 2, 3]")
    with pytest.raises(ConstraintError, match="must be a JSON object"):
        load_constraints(path, N)
    path.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConstraintError, match="UTF-8"):
        load_constraints(path, N)


def test_constraint_error_is_an_arap_error() -> None:
    with pytest.raises(ArapError):
        load_constraints({}, N)


@pytest.mark.parametrize(
    ("indices", "message"),
    [
        ([1, 2**70], "out of range [0, 10) (first: item 1 = 1180591620717411303424)"),
        ([1, 10**400], "(first: item 1 = 1000000000000000000000000000000000000..."),
        (np.array([1, 2**63], dtype=np.uint64), "(first: item 1 = 9223372036854775808)"),
        (np.array([-2, 1], dtype=np.int8), "(first: item 0 = -2)"),
        (np.array([1.0, 2.0]), "got an array of float64"),
        (np.array([True]), "got an array of bool"),
        ([np.float64(1.0)], "item 0 is np.float64(1.0)"),
        ([1, np.True_], "item 1 is np.True_"),
        ("012", "must be a list of vertex indices, got str"),
        ({1, 2}, "got set"),
        (3, "got int"),
        (np.zeros((2, 2), dtype=int), "flat list of vertex indices, got an array of shape (2, 2)"),
    ],
)
def test_index_validator_edge_cases(indices: Any, message: str) -> None:
    with pytest.raises(ConstraintError) as info:
        check_index_array(indices, N, "x")
    assert message in str(info.value)


def test_index_validator_accepts_sequences_and_numpy_integers() -> None:
    assert check_index_array(range(3), N, "x").tolist() == [0, 1, 2]
    assert check_index_array((np.int32(4), 1), N, "x").tolist() == [4, 1]
    assert check_index_array(np.array([], dtype=float), N, "x").dtype == np.int64
    with pytest.raises(ConstraintError, match="roi is empty; leave it out"):
        check_index_array([], N, "roi", allow_empty=False)
