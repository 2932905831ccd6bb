"""The note that explains energies below 0: shown when the energy reported, live or settled, is below 0, and gone
with a new mesh."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import wait_for_page, wait_settled
from tests.e2e.test_session_safety import Dialogs
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle

pytestmark = pytest.mark.e2e


def test_the_negative_energy_note_goes_with_a_new_mesh(page: Page, shared_meshes_dir: Path) -> None:
    page.get_by_test_id("file-input").set_input_files(str(shared_meshes_dir / "decimated-knight.off"))
    wait_for_page(page, "() => window.__arap.meshName === 'decimated-knight' && !window.__arap.busy",
                  "the decimated knight to load", 60)
    select_anchor_and_handle(page)
    note = page.get_by_test_id("energy-note")
    expect(note).to_be_hidden()
    page.get_by_test_id("energy").select_option("spokes")
    wait_settled(page)
    # obtuse triangles: the settled spokes energy of the knight is below 0, and the note says why (before any drag)
    expect(page.get_by_test_id("settle-status")).to_contain_text("energy -")
    expect(note).to_be_visible()
    drag_gizmo_x(page, 30)
    wait_settled(page)
    expect(note).to_be_visible()
    Dialogs(page, accept=True)
    page.get_by_test_id("builtin-select").select_option("bar")
    wait_for_page(page, "() => window.__arap.meshName === 'bar' && !window.__arap.busy", "the bar to load", 60)
    expect(note).to_be_hidden()
