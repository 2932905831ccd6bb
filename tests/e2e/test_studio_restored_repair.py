"""A session on a mesh that repair changed keeps knowing it when it is restored from the PLY the page wrote of it
(after Apply, the saved mesh is that PLY, which loads without repairs): point handles of a constraints file, which
name the file's triangles, are still refused, and point handles placed on it are not saved."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import screen_points, wait_idle, wait_ready
from tests.e2e.test_session_safety import Dialogs, wait_autosaved
from tests.e2e.test_studio import sphere_obj
from tests.e2e.test_studio_points import _anchor_bottom, _place_point

pytestmark = pytest.mark.e2e


def _sphere_with_a_repeated_face(tmp_path: Path) -> Path:
    text, _ = sphere_obj(3)
    last_face = [line for line in text.splitlines() if line.startswith("f ")][-1]
    path = tmp_path / "twice.obj"
    path.write_text(text.rstrip("\n") + "\n" + last_face + "\n")  # repair drops the copy; the numbering stays
    return path


def test_a_session_restored_from_its_ply_stays_repaired(page: Page, tmp_path: Path) -> None:
    page.get_by_test_id("file-input").set_input_files(str(_sphere_with_a_repeated_face(tmp_path)))
    page.wait_for_function("() => window.__arap.meshName === 'twice'")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.repaired")
    _anchor_bottom(page)
    page.get_by_test_id("apply").click()  # the saved mesh is now the PLY of the applied shape
    wait_idle(page)
    wait_autosaved(page)

    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => window.__arap.meshName === 'twice' && !window.__arap.restoring")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0
    assert page.evaluate("() => window.__arap.repaired"), "the restored session forgot that repair changed the mesh"

    doc = tmp_path / "points.json"
    doc.write_text(json.dumps({"version": 2, "fixed": [0], "points": [{"face": 5, "barycentric": [0.2, 0.3, 0.5]}]}))
    page.get_by_test_id("constraints-input").set_input_files(str(doc))
    expect(page.get_by_test_id("status-text")).to_contain_text("mesh repair")

    # nor are the point handles placed on it saved: the server, given the PLY, saw no repair
    _place_point(page, screen_points(page))
    page.get_by_test_id("save-constraints").click()
    expect(page.get_by_test_id("status-text")).to_contain_text("Point handles cannot be saved")
