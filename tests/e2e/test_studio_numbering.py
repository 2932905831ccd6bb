"""Constraints documents of a mesh file that repair renumbers (a vertex no face uses, duplicated vertices): the
studio reads and writes them in the file's numbering, as arap deform does."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from playwright.sync_api import Page, expect

from tests.e2e.conftest import positions, wait_idle
from tests.server.helpers import renumbered_obj

pytestmark = pytest.mark.e2e


def _upload(page: Page, tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Upload an egg that repair renumbers; its vertices and the map repair gives (file vertex → mesh vertex)."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    V = np.asarray(sphere.vertices) * [1.0, 2.0, 1.0]
    text, vertex_map = renumbered_obj(V, np.asarray(sphere.faces))
    path = tmp_path / "egg.obj"
    path.write_text(text)
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.meshName === 'egg'")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.nVertices") == len(V)
    return V, vertex_map


def _load(page: Page, path: Path, document: dict) -> None:
    path.write_text(json.dumps(document))
    page.get_by_test_id("constraints-input").set_input_files(str(path))


def _selection(page: Page) -> dict:
    c = page.evaluate("() => window.__arap.constraints()")
    return {"fixed": sorted(c["fixed"]), "groups": [sorted(g) for g in c["handle_groups"]],
            "stiffness": [(sorted(s["vertices"]), s["value"]) for s in c["stiffness"] or []]}


def test_documents_use_the_files_numbering_both_ways(page: Page, tmp_path: Path) -> None:
    V, vertex_map = _upload(page, tmp_path)
    n_file = len(vertex_map)
    y = V[:, 1]
    bottom = np.flatnonzero(y <= np.quantile(y, 0.1))
    top = np.flatnonzero(y >= np.quantile(y, 0.9))
    middle = np.flatnonzero(np.abs(y) < 0.1)
    low, mid, high = vertex_map[-3:].tolist()  # each has two copies in the file: v + 1 and the one at the end
    assert low in bottom and mid in middle and high in top
    # written for the file by hand: the lowest vertex named by its copy only, the highest by both
    fixed = [n_file - 3 if v == low else v + 1 for v in bottom.tolist()]
    handles = [*(top + 1).tolist(), n_file - 1]
    shift = np.array([0.3, 0.2, 0.0])
    targets = [(V[vertex_map[i]] + shift).tolist() for i in handles]
    stiff = [*(middle + 1).tolist(), n_file - 2]
    _load(page, tmp_path / "by-hand.json", {"version": 2, "fixed": fixed, "handles": handles, "targets": targets,
                                            "stiffness": [{"vertices": stiff, "value": 3.0}]})
    page.wait_for_function(f"() => window.__arap.counts().fixed === {len(bottom)}")
    wait_idle(page)
    loaded = _selection(page)
    assert loaded == {"fixed": bottom.tolist(), "groups": [top.tolist()], "stiffness": [(middle.tolist(), 3.0)]}
    np.testing.assert_allclose(positions(page)[top], V[top] + shift, atol=1e-4)
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"

    # the studio's document names every file copy, and loading it back restores the same selection and shape
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    saved_path = tmp_path / "saved.json"
    info.value.save_as(saved_path)
    saved = json.loads(saved_path.read_text())
    assert sorted(saved["fixed"]) == sorted([*(bottom + 1).tolist(), n_file - 3])
    assert sorted(saved["handles"]) == sorted(handles)
    assert sorted(saved["stiffness"][0]["vertices"]) == sorted(stiff)
    shape = positions(page)
    page.get_by_test_id("reset").click()
    page.wait_for_function(f"() => window.__arap.positions()[{3 * high}] === {np.float32(V[high, 0])}")
    wait_idle(page)
    page.get_by_test_id("constraints-input").set_input_files(str(saved_path))
    page.wait_for_function(f"() => Math.abs(window.__arap.positions()[{3 * high}] - {shape[high, 0]}) < 1e-4")
    wait_idle(page)
    assert _selection(page) == loaded
    np.testing.assert_allclose(positions(page), shape, atol=1e-4)
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


@pytest.mark.parametrize(("document", "message"), [
    ({"fixed": [0, 5]}, "fixed vertex 0 of the file"),
    ("welded", "are copies of one vertex"),
])
def test_documents_that_do_not_fit_the_repaired_mesh_are_refused(page: Page, tmp_path: Path, document: object,
                                                                 message: str) -> None:
    V, vertex_map = _upload(page, tmp_path)
    if document == "welded":  # one copy of the highest vertex fixed, the other a handle
        high = int(vertex_map[-1])
        document = {"fixed": [high + 1], "handles": [len(vertex_map) - 1], "targets": [V[high].tolist()]}
    _load(page, tmp_path / "bad.json", document)  # type: ignore[arg-type]
    expect(page.get_by_test_id("status-text")).to_contain_text("bad.json")
    expect(page.get_by_test_id("status-text")).to_contain_text(message)
    assert page.evaluate("() => window.__arap.counts().fixed") == 0
