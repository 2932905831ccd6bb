"""Selectors pick the vertices a hand-written index list names, and constraints made from them equal a
hand-written constraints file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import arap
from arap.cli import main
from arap.constraints.vertex_selectors import (
    HandleSpec,
    constraints_from_selectors,
    parse_rotation,
    parse_vector,
    select,
)
from arap.errors import ConstraintError, OptionError


def _cactus() -> tuple[np.ndarray, np.ndarray]:
    return arap.builtin_mesh("cactus")


def test_selectors_equal_hand_written_index_lists() -> None:
    V, _ = _cactus()
    lo, hi = V.min(axis=0), V.max(axis=0)
    P = (V - lo) / (hi - lo)
    np.testing.assert_array_equal(select(V, "y<0.1"), np.flatnonzero(P[:, 1] < 0.1))
    np.testing.assert_array_equal(select(V, "0.4<x<=0.6"), np.flatnonzero((P[:, 0] > 0.4) & (P[:, 0] <= 0.6)))
    np.testing.assert_array_equal(select(V, "y>0.9 & z>=0.5 | x<0.05"),
                                  np.flatnonzero(((P[:, 1] > 0.9) & (P[:, 2] >= 0.5)) | (P[:, 0] < 0.05)))
    np.testing.assert_array_equal(select(V, "y > 0.9 and z >= 0.5 or x < 0.05"), select(V, "y>0.9&z>=0.5|x<0.05"))
    np.testing.assert_array_equal(select(V, "0.5>y"), np.flatnonzero(P[:, 1] < 0.5))
    np.testing.assert_array_equal(select(V, "Y<1.5"), np.flatnonzero(V[:, 1] < 1.5))  # mesh units
    np.testing.assert_array_equal(select(V, "all"), np.arange(len(V)))


@pytest.mark.parametrize(("text", "words"), [
    ("", "a selector is a condition"), ("w<0.1", "cannot read"), ("y<", "compares one coordinate"),
    ("x<y", "exactly one coordinate"), ("y<0.1 &", "empty condition"), ("0.1<0.2", "exactly one coordinate"),
    ("y<0.1)", "cannot read"), ("y" * 2000, "at most"),
])
def test_bad_selectors_are_refused_by_name(text: str, words: str) -> None:
    V, _ = _cactus()
    with pytest.raises(OptionError, match=words):
        select(V, text)


def test_handles_are_turned_about_their_centroid_then_moved() -> None:
    V, _ = _cactus()
    R = parse_rotation("z:90")
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(parse_rotation("1,1,0:180") @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    c = constraints_from_selectors(V, fixed=["y<0.1"], handles=[HandleSpec("y>0.9", move=parse_vector("0.5,0,0"),
                                                                          rotation=R)])
    top = select(V, "y>0.9")
    centre = V[top].mean(axis=0)
    np.testing.assert_array_equal(c.fixed, select(V, "y<0.1"))
    np.testing.assert_array_equal(c.handles, top)
    np.testing.assert_allclose(c.targets, (V[top] - centre) @ R.T + centre + [0.5, 0.0, 0.0])
    assert c.handle_groups == [top.tolist()]
    # a vertex picked as fixed stays fixed; groups do not overlap
    c2 = constraints_from_selectors(V, fixed=["y<0.5"], handles=[HandleSpec("y<0.6"), HandleSpec("y<0.7")])
    assert not set(c2.fixed) & set(c2.handles) and c2.handle_groups is not None
    assert not set(c2.handle_groups[0]) & set(c2.handle_groups[1])
    with pytest.raises(ConstraintError, match="picks no vertex"):
        constraints_from_selectors(V, fixed=["y<0.5"], handles=[HandleSpec("y<0.4")])
    for bad, words in (("1,2", "three numbers"), ("a,b,c", "three numbers")):
        with pytest.raises(OptionError, match=words):
            parse_vector(bad)
    for bad in ("z30", "w:30", "0,0,0:30", "z:x"):
        with pytest.raises(OptionError, match="AXIS:DEGREES"):
            parse_rotation(bad)


def test_arap_constraints_and_deform_by_position_equal_a_hand_written_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, _ = _cactus()
    P = (V - V.min(axis=0)) / (V.max(axis=0) - V.min(axis=0))
    fixed = np.flatnonzero(P[:, 1] < 0.1)
    top = np.flatnonzero(P[:, 1] > 0.9)
    hand = tmp_path / "hand.json"
    hand.write_text(json.dumps({"fixed": fixed.tolist(), "handles": top.tolist(),
                                "targets": (V[top] + [0.3, 0.0, 0.1]).tolist()}))
    picked = tmp_path / "picked.json"
    sel = ["--fix", "y<0.1", "--handle", "y>0.9", "--move", "0.3,0,0.1"]
    assert main(["constraints", "cactus", *sel, "-o", str(picked)]) == 0
    assert "fixed" in capsys.readouterr().out
    doc = json.loads(picked.read_text())
    assert doc["fixed"] == fixed.tolist() and doc["handles"] == top.tolist()
    np.testing.assert_allclose(doc["targets"], V[top] + [0.3, 0.0, 0.1])
    out_hand, out_sel = tmp_path / "a.ply", tmp_path / "b.ply"
    assert main(["deform", "cactus", "-c", str(hand), "-o", str(out_hand), "-q"]) == 0
    assert main(["deform", "cactus", *sel, "-o", str(out_sel), "-q"]) == 0
    np.testing.assert_array_equal(arap.load_mesh(out_sel)[0], arap.load_mesh(out_hand)[0])
    assert main(["deform", "cactus", "-c", str(hand), *sel, "-o", str(out_sel)]) == 1
    assert "not both" in capsys.readouterr().err
    assert main(["deform", "cactus", "-o", str(out_sel)]) == 1
    assert "--fix" in capsys.readouterr().err
    assert main(["constraints", "cactus", "--move", "1,0,0", "-o", str(picked)]) == 2
    assert "give --handle SELECTOR first" in capsys.readouterr().err
