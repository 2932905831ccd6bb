"""A textured OBJ opened with its MTL file and texture (several files chosen at once) is drawn textured; opened
alone, a note below the view says which file it names is missing. The up-axis switch turns the view, not the data:
the exported OBJ keeps the file's coordinates."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh
from playwright.sync_api import Page, expect

from tests.e2e.conftest import positions, screen_points, wait_idle, wait_ready
from tests.e2e.test_session_safety import Dialogs
from tests.e2e.test_studio import box_select
from tests.e2e.test_studio_texture import checker_image, colour_counts

pytestmark = pytest.mark.e2e


def textured_grid_obj(folder: Path, n: int = 14) -> list[Path]:
    """A flat grid facing the camera as OBJ, with its MTL file and checker texture beside it (all the files)."""
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    F = [[r * n + c, r * n + c + 1, r * n + c + n + 1] for r in range(n - 1) for c in range(n - 1)]
    F += [[r * n + c, r * n + c + n + 1, r * n + c + n] for r in range(n - 1) for c in range(n - 1)]
    mesh = trimesh.Trimesh(V, np.array(F), process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=(V[:, :2] + 1) / 2, image=checker_image())
    folder.mkdir(parents=True, exist_ok=True)
    mesh.export(folder / "grid.obj")
    return sorted(folder.iterdir())


def test_an_obj_with_its_mtl_and_texture_and_the_up_axis(page: Page, tmp_path: Path) -> None:
    files = textured_grid_obj(tmp_path / "grid")
    assert {p.suffix for p in files} == {".obj", ".mtl", ".png"}
    obj = tmp_path / "grid" / "grid.obj"

    page.get_by_test_id("file-input").set_input_files(str(obj))
    page.wait_for_function("() => window.__arap.meshName === 'grid'")
    expect(page.get_by_test_id("load-note")).to_be_visible()
    expect(page.get_by_test_id("load-note-text")).to_contain_text("material file")
    assert page.evaluate("() => window.__arap.surface") == "plain"

    page.get_by_test_id("file-input").set_input_files([str(p) for p in files])
    page.wait_for_function("() => window.__arap.surface === 'texture' && window.__arap.textureReady")
    wait_idle(page)
    expect(page.get_by_test_id("load-note")).to_be_hidden()
    red, blue = colour_counts(page)
    assert red > 2000 and blue > 2000, f"the checker is not drawn ({red} red, {blue} blue pixels)"

    pts = screen_points(page)  # an edit, so that the session is offered back after a reload
    page.get_by_test_id("role-fixed").click()
    box_select(page, pts[:, 0].min() - 10, pts[:, 1].max() - 20, pts[:, 0].max() + 10, pts[:, 1].max() + 10)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0

    rest = positions(page)
    saves = page.evaluate("() => window.__arap.autosave.saves")
    page.get_by_test_id("up-axis").select_option("z")
    page.wait_for_function("() => window.__arap.upAxis === 'z'")
    wait_idle(page)
    np.testing.assert_array_equal(positions(page), rest)  # the view turned, not the data
    red_z, blue_z = colour_counts(page)
    assert red_z + blue_z < (red + blue) / 3, "seen from the front with Z up, the flat grid is almost edge-on"

    with page.expect_download() as info:
        page.get_by_test_id("export-obj").click()
    download = info.value
    assert download.suggested_filename == "grid-deformed.zip"
    with zipfile.ZipFile(io.BytesIO(Path(download.path()).read_bytes())) as archive:
        names = archive.namelist()
        text = archive.read("grid-deformed.obj").decode()
    assert any(n.endswith(".mtl") for n in names) and any(n.endswith(".png") for n in names)
    V = np.array([[float(x) for x in line.split()[1:4]] for line in text.splitlines() if line.startswith("v ")])
    source = trimesh.load(obj, process=False)
    np.testing.assert_allclose(V, source.vertices, atol=1e-9)
    assert not page.evaluate("() => window.__arap.errors")

    # the up axis is kept with the session, and the session's mesh comes back with its texture
    page.wait_for_function(f"() => window.__arap.autosave.idle && window.__arap.autosave.saves > {saves}")
    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    assert page.evaluate("() => window.__arap.upAxis") == "y"
    expect(page.get_by_test_id("restore-offer")).to_be_visible()
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => window.__arap.meshName === 'grid' && !window.__arap.restoring")
    page.wait_for_function("() => window.__arap.upAxis === 'z' && window.__arap.surface === 'texture'")
    expect(page.get_by_test_id("up-axis")).to_have_value("z")
