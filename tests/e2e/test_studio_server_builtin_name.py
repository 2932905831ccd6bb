"""A mesh the server was started with from a file named like a built-in model (``arap studio bar.obj``) is that file,
not the built-in: a reload's restore brings the file's mesh back with the saved shape, the model list names it as a
file, and the built-in of the same name can still be chosen from the list."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Browser, Page

from arap.io import save_mesh
from tests.e2e.conftest import _ServerThread, page_on_server, positions, wait_idle, wait_settled
from tests.e2e.test_session_safety import reload_and_restore
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.e2e.test_studio_model_list import SHOWN

pytestmark = pytest.mark.e2e

N = 12
"""The grid's vertices each way: N * N vertices, unlike the built-in bar."""


def _grid_named_bar(folder: Path) -> Path:
    """A flat square grid facing the camera, saved as ``bar.obj``."""
    x, y = np.meshgrid(np.linspace(-1, 1, N), np.linspace(-1, 1, N))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(N * N)], axis=1)
    F = [[a, a + 1, a + N + 1] for a in (r * N + c for r in range(N - 1) for c in range(N - 1))]
    F += [[a, a + N + 1, a + N] for a in (r * N + c for r in range(N - 1) for c in range(N - 1))]
    path = folder / "bar.obj"
    save_mesh(path, V, np.array(F))
    return path


@pytest.fixture
def started_with_bar_obj(browser: Browser, tmp_path: Path) -> Iterator[Page]:
    """A page of a studio server started with ``bar.obj`` (a grid, not the built-in bar) as its mesh."""
    with page_on_server(browser, _ServerThread(default_mesh=_grid_named_bar(tmp_path))) as page:
        wait_idle(page)
        yield page


def test_a_restore_brings_back_the_file_named_like_a_built_in(started_with_bar_obj: Page) -> None:
    page = started_with_bar_obj
    assert page.evaluate("() => [window.__arap.meshName, window.__arap.nVertices]") == ["bar", N * N]
    assert page.evaluate(SHOWN) == "bar (file)"
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 80)
    wait_settled(page)
    shape = positions(page)

    reload_and_restore(page, "bar")
    assert page.evaluate("() => window.__arap.nVertices") == N * N, "the restore loaded the built-in bar"
    scale = float(np.ptp(shape, axis=0).max())
    assert np.allclose(positions(page), shape, atol=1e-4 * scale), "the restore did not bring the saved shape back"
    assert page.evaluate(SHOWN) == "bar (file)"

    # the built-in bar is another model: the list loads it in place of the file
    page.get_by_test_id("builtin-select").select_option("bar")
    page.wait_for_function(f"() => window.__arap.meshName === 'bar' && window.__arap.nVertices !== {N * N}")
    wait_idle(page)
    assert page.evaluate(SHOWN) == "bar"
