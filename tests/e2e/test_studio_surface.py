"""Selection along the surface in headless Chromium with real mouse and keyboard input: the geodesic brush and the
connected patch stay on the part under the cursor, rings grow and shrink, and the region of interest grows from the
handles."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page

from tests.e2e.conftest import wait_idle

pytestmark = pytest.mark.e2e

SPACING = 0.1
GRID = 31
"""The fork: a flat GRID×GRID grid of SPACING with a slot one cell wide cut from the top down to SLOT_FLOOR."""
SLOT_COLUMN = 15
SLOT_FLOOR = 6


def fork_mesh() -> tuple[np.ndarray, np.ndarray]:
    """Two prongs one cell apart that meet only at the bottom: near in space, far along the surface."""
    idx = np.arange(GRID * GRID).reshape(GRID, GRID)  # idx[row, col], row = y
    faces = []
    for r in range(GRID - 1):
        for c in range(GRID - 1):
            if c == SLOT_COLUMN and r >= SLOT_FLOOR:
                continue
            a, b, d, e = idx[r, c], idx[r, c + 1], idx[r + 1, c], idx[r + 1, c + 1]
            faces += [(a, b, e), (a, e, d)]
    F = np.asarray(faces)
    used = np.unique(F)
    remap = np.full(GRID * GRID, -1)
    remap[used] = np.arange(len(used))
    cols, rows = np.meshgrid(np.arange(GRID), np.arange(GRID))
    V = np.column_stack([cols.ravel() * SPACING, rows.ravel() * SPACING, np.zeros(GRID * GRID)])[used]
    return V, remap[F]


def load_fork(page: Page, tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    V, F = fork_mesh()
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in V] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path = tmp_path / "fork.obj"
    path.write_text("\n".join(lines) + "\n")
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.meshName === 'fork'")
    wait_idle(page)
    shown = np.asarray(page.evaluate("() => window.__arap.positions()")).reshape(-1, 3)
    assert shown.shape == V.shape
    return shown, F


def neighbours(F: np.ndarray, n: int) -> list[set[int]]:
    out: list[set[int]] = [set() for _ in range(n)]
    for a, b, c in F:
        out[a] |= {b, c}
        out[b] |= {a, c}
        out[c] |= {a, b}
    return out


def click_at(page: Page, point: tuple[float, float, float]) -> None:
    x, y = page.evaluate("(p) => window.__arap.project(p)", list(point))
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.up()
    wait_idle(page)


def roi(page: Page) -> set[int]:
    return set(page.evaluate("() => window.__arap.constraints().roi") or [])


def clear_roi(page: Page) -> None:
    page.get_by_test_id("clear-role").click()
    wait_idle(page)


def test_surface_brush_and_connected_patch_stay_on_their_prong(page: Page, tmp_path: Path) -> None:
    V, _ = load_fork(page, tmp_path)
    slot_left = SLOT_COLUMN * SPACING
    right = V[:, 0] > slot_left + 0.5 * SPACING
    left_prong = (V[:, 0] < slot_left + 0.5 * SPACING) & (V[:, 1] > (SLOT_FLOOR + 2) * SPACING)
    # just left of the slot, high up on the left prong; the radius reaches across the slot
    point = (slot_left - 0.3 * SPACING, 2.3, 0.0)
    page.get_by_test_id("role-roi").click()
    page.get_by_test_id("brush-units").select_option("world")
    page.get_by_test_id("brush-radius").fill("8")  # 8% of the diagonal: about 3.5 cells

    click_at(page, point)
    straight = roi(page)
    assert straight & set(np.flatnonzero(right)), "the straight brush should reach across the slot"
    clear_roi(page)

    for metric in ("surface", "patch"):
        page.get_by_test_id("brush-metric").select_option(metric)
        click_at(page, point)
        got = roi(page)
        assert got, f"the {metric} brush selected nothing"
        assert not got & set(np.flatnonzero(right)), f"the {metric} brush crossed to the other prong"
        assert got <= set(np.flatnonzero(left_prong))
        # the same part as the straight ball on this side of the slot
        assert got <= straight and len(got) >= 0.6 * len(straight - set(np.flatnonzero(right)))
        clear_roi(page)
    assert not page.evaluate("() => window.__arap.errors")


def test_grow_shrink_and_roi_from_handles(page: Page, tmp_path: Path) -> None:
    V, F = load_fork(page, tmp_path)
    nbr = neighbours(F, len(V))
    page.get_by_test_id("role-roi").click()
    page.get_by_test_id("brush-metric").select_option("surface")
    click_at(page, (0.5, 0.5, 0.0))
    start = roi(page)
    assert start

    page.keyboard.press("+")
    wait_idle(page)
    grown = roi(page)
    assert grown == start | {j for i in start for j in nbr[i]}
    page.get_by_test_id("grow").click()
    wait_idle(page)
    assert roi(page) == grown | {j for i in grown for j in nbr[i]}
    # Shrink takes back exactly the layers Grow added, newest first
    page.get_by_test_id("shrink").click()
    wait_idle(page)
    assert roi(page) == grown
    page.keyboard.press("-")
    wait_idle(page)
    assert roi(page) == start
    # with no Grow to take back, Shrink takes away the members with a neighbour outside
    page.keyboard.press("-")
    wait_idle(page)
    shrunk = roi(page)
    assert shrunk == {i for i in start if nbr[i] <= start}
    # an edit after Grow: Shrink no longer knows that layer, and shrinks what is there
    page.keyboard.press("+")
    wait_idle(page)
    regrown = roi(page)
    click_at(page, (1.5, 1.5, 0.0))
    edited = roi(page)
    page.keyboard.press("-")
    wait_idle(page)
    assert roi(page) == {i for i in edited if nbr[i] <= edited}
    assert regrown <= edited
    clear_roi(page)

    # anchors under a grown handle come back when Shrink takes the layer away
    page.get_by_test_id("role-fixed").click()
    click_at(page, (0.5, 0.5, 0.0))
    page.get_by_test_id("role-handle").click()
    click_at(page, (0.5, 0.7, 0.0))
    before = page.evaluate("() => window.__arap.constraints()")
    assert before["fixed"] and before["handle_groups"][0]
    page.keyboard.press("+")
    wait_idle(page)
    fixed = set(page.evaluate("() => window.__arap.constraints().fixed"))
    assert fixed < set(before["fixed"]), "the handle grew over anchors"
    page.keyboard.press("-")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.constraints()") == before
    page.get_by_test_id("clear-all").click()
    wait_idle(page)

    # a handle on the right prong; the region of interest: two rings around it (anchors included)
    page.get_by_test_id("role-handle").click()
    click_at(page, (2.5, 2.5, 0.0))
    handles = set(page.evaluate("() => window.__arap.constraints().handle_groups[0]"))
    page.get_by_test_id("roi-amount").fill("2")
    page.get_by_test_id("roi-mode").select_option("rings")
    page.get_by_test_id("roi-from-handles").click()
    wait_idle(page)
    ring1 = handles | {j for i in handles for j in nbr[i]}
    ring2 = ring1 | {j for i in ring1 for j in nbr[i]}
    assert roi(page) == ring2

    page.get_by_test_id("roi-mode").select_option("distance")
    page.get_by_test_id("roi-amount").fill("10")
    page.get_by_test_id("roi-from-handles").click()
    wait_idle(page)
    by_distance = roi(page)
    assert handles < by_distance
    # 10% of the diagonal along the surface never reaches the left prong around the bottom of the slot
    assert all(V[i, 0] > SLOT_COLUMN * SPACING for i in by_distance)
    assert not page.evaluate("() => window.__arap.errors")
