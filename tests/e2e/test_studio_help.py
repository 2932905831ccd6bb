"""The studio's distortion heat map, help overlay, first-run guide, iteration range and statistics panel in headless
Chromium, with real mouse and keyboard input."""

from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import Browser, Page, expect

from arap.server.messages import PARAMS
from tests.e2e.conftest import screen_points, wait_for_page, wait_idle, wait_ready
from tests.e2e.test_studio import box_select, drag_gizmo_x, select_anchor_and_handle

pytestmark = pytest.mark.e2e


def colors(page: Page) -> np.ndarray:
    return np.asarray(page.evaluate("() => window.__arap.colors()"), dtype=np.float64).reshape(-1, 3)


def test_heat_map_colours_the_distortion_and_goes_away(page: Page) -> None:
    fixed, handle = select_anchor_and_handle(page)
    drag_gizmo_x(page, 120)
    page.mouse.move(5, 5)
    wait_idle(page)
    before = colors(page)
    free = np.setdiff1d(np.arange(len(before)), np.concatenate([fixed, handle]))
    assert np.ptp(before[free], axis=0).max() < 1e-6  # one colour for every unassigned vertex

    page.get_by_test_id("heatmap").check()
    legend = page.get_by_test_id("heat-legend")
    expect(legend).to_be_visible()
    expect(page.get_by_test_id("heat-high")).not_to_have_text("")
    wait_for_page(page, "() => { const c = window.__arap.colors(); return c.some((v, i) => v !== c[i % 3]); }",
                  "the heat map's colours (vertices of different colours)")
    heat = colors(page)
    assert len(np.unique(np.round(heat[free], 3), axis=0)) > 20, "the heat map should vary over the mesh"
    np.testing.assert_array_equal(heat[fixed], before[fixed])  # anchors and handles keep their colours
    np.testing.assert_array_equal(heat[handle], before[handle])

    page.locator("#view").focus()
    page.keyboard.press("h")
    expect(legend).to_be_hidden()
    expect(page.get_by_test_id("heatmap")).not_to_be_checked()
    np.testing.assert_array_equal(colors(page), before)
    assert not page.evaluate("() => window.__arap.errors")


def test_help_overlay_lists_the_shortcuts_and_the_guide_is_remembered(page: Page) -> None:
    help_ = page.get_by_test_id("help")
    expect(help_).to_be_hidden()
    page.locator("#view").focus()
    page.keyboard.press("?")
    expect(help_).to_be_visible()
    keys = page.locator("[data-testid=help-table] kbd").all_inner_texts()
    for key in ("1", "2", "3", "4", "B", "X", "O", "N", "W", "E", "F", "+", "H", "?", "Ctrl+Z", "Shift+drag"):
        assert key in keys, f"{key} is missing from the help"
    page.keyboard.press("Escape")
    expect(help_).to_be_hidden()
    page.get_by_test_id("help-button").click()
    expect(help_).to_be_visible()
    page.get_by_test_id("help-close").click()
    expect(help_).to_be_hidden()

    guide = page.get_by_test_id("guide")
    expect(guide).to_be_visible()
    expect(guide).to_contain_text("anchor")
    page.get_by_test_id("guide-close").click()
    expect(guide).to_be_hidden()
    page.reload()
    wait_ready(page)
    expect(page.get_by_test_id("guide")).to_be_hidden()


def test_iteration_slider_spans_the_protocol_range(page: Page) -> None:
    slider = page.get_by_test_id("iterations")
    assert slider.get_attribute("min") == str(PARAMS["iterations"]["min"])
    assert slider.get_attribute("max") == str(PARAMS["iterations"]["max"])
    slider.focus()
    page.keyboard.press("End")
    top = PARAMS["iterations"]["max"]
    page.wait_for_function(f"() => window.__arap.params.iterations === {top}")
    expect(page.locator("#iterations-val")).to_have_text(str(top))


def test_statistics_panel_lets_a_box_selection_through_and_moves(page: Page) -> None:
    hud = page.get_by_test_id("hud")
    box = hud.bounding_box()
    assert box is not None
    pts = screen_points(page)
    cx, cy = np.median(pts, axis=0)
    page.get_by_test_id("role-fixed").click()
    # the rectangle starts over the statistics (their table) and ends over the middle of the model
    box_select(page, box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.4, cx + 40, cy + 40)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0
    assert page.evaluate("() => window.getSelection().toString()") == ""

    head = page.locator("#hud .hud-head")
    hb = head.bounding_box()
    assert hb is not None
    page.mouse.move(hb["x"] + 30, hb["y"] + hb["height"] / 2)
    page.mouse.down()
    page.mouse.move(hb["x"] + 230, hb["y"] + hb["height"] / 2 + 40, steps=6)
    page.mouse.up()
    moved = hud.bounding_box()
    assert moved is not None
    assert moved["x"] == pytest.approx(box["x"] + 200, abs=2) and moved["y"] == pytest.approx(box["y"] + 40, abs=2)
    page.get_by_test_id("hud-toggle").click()
    expect(page.locator("#hud-body")).to_be_hidden()
    page.get_by_test_id("hud-toggle").click()
    expect(page.locator("#hud-body")).to_be_visible()


def test_display_section_without_scrolling_and_statistics_on_narrow_windows(browser: Browser,
                                                                           server_url: str) -> None:
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    try:
        page = context.new_page()
        page.goto(server_url)
        wait_ready(page)
        for testid in ("heatmap", "wireframe", "flat-shading", "fit-view"):
            expect(page.get_by_test_id(testid)).to_be_in_viewport(ratio=1)
        assert page.evaluate("() => document.getElementById('panel').scrollTop") == 0
        expect(page.locator("#hud-body")).to_be_visible()

        page.set_viewport_size({"width": 900, "height": 700})
        expect(page.locator("#hud-body")).to_be_hidden()  # collapsed: only its title bar is left
        page.get_by_test_id("fit-view").click()
        wait_idle(page)
        hb = page.get_by_test_id("hud").bounding_box()
        assert hb is not None
        pts = screen_points(page)
        inside = ((pts[:, 0] >= hb["x"]) & (pts[:, 0] <= hb["x"] + hb["width"])
                  & (pts[:, 1] >= hb["y"]) & (pts[:, 1] <= hb["y"] + hb["height"]))
        assert inside.mean() < 0.01, "the statistics cover the model"
    finally:
        context.close()
