"""Work in the studio is never lost by accident: keyboard shortcuts stay out of form controls, replacing an edited
mesh asks first, leaving warns, the session is autosaved in the browser and restored after a reload, and the client
reconnects and restores by itself after a server restart."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Browser, Dialog, Page, expect

from tests.e2e.conftest import (
    VIEWPORT,
    _ServerThread,
    positions,
    screen_points,
    wait_idle,
    wait_ready,
    wait_settled,
)
from tests.e2e.test_studio import box_select, drag_gizmo_x, select_anchor_and_handle, sphere_obj
from tests.waiting import page_wait_until, scaled_ms

pytestmark = pytest.mark.e2e

COUNTS = "() => window.__arap.counts()"


class Dialogs:
    """Records the page's dialogs and answers them: ``accept`` True accepts, False dismisses."""

    def __init__(self, page: Page, accept: bool = False) -> None:
        self.accept = accept
        self.seen: list[tuple[str, str]] = []
        page.on("dialog", self._on_dialog)

    def _on_dialog(self, dialog: Dialog) -> None:
        self.seen.append((dialog.type, dialog.message))
        if self.accept:
            dialog.accept()
        else:
            dialog.dismiss()


def settle(page: Page) -> None:
    """Let queued key and change handlers (and any answer they caused) run."""
    # The tests that call this check that a key or change does nothing (no new mesh, no lost selection): there is no
    # event to wait for, so the handlers get a fixed time in which a wrong action would start.
    page.wait_for_timeout(300)
    wait_idle(page)


def active_tool(page: Page) -> str:
    return page.evaluate("() => document.querySelector('#tool-seg button.active').dataset.tool")


def wait_autosaved(page: Page) -> None:
    page.wait_for_function("() => window.__arap.autosave.idle && window.__arap.autosave.saves > 0",
                           timeout=scaled_ms(10))


def reload_and_restore(page: Page, mesh: str | None = None, restored: str = "true") -> None:
    """Reload the page once its session is autosaved, accept the restore offer, and wait until the restore is done
    (the mesh named ``mesh`` shown, when given, and the JavaScript condition ``restored`` true) and the page idle."""
    wait_autosaved(page)
    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    page.get_by_test_id("restore-accept").click()
    shown = "true" if mesh is None else f"window.__arap.meshName === {json.dumps(mesh)}"
    page.wait_for_function(f"() => {shown} && ({restored}) && !window.__arap.restoring")
    wait_idle(page)


def edit_session(page: Page) -> dict:
    """ROI, anchors, two handle groups and a drag, all with the mouse; returns the client's state after them."""
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    xmin, xmax = pts[:, 0].min(), pts[:, 0].max()
    page.get_by_test_id("front-only").click()  # the box reaches the back of the model too
    page.get_by_test_id("role-roi").click()
    box_select(page, xmin - 10, ymin - 10, xmax + 10, ymin + 0.93 * (ymax - ymin))
    wait_idle(page)
    fixed, _ = select_anchor_and_handle(page)
    page.get_by_test_id("new-group").click()
    mid = pts[np.abs(pts[:, 1] - (ymin + ymax) / 2) < 0.02 * (ymax - ymin)].mean(axis=0)
    page.get_by_test_id("tool-box").click()
    page.mouse.move(mid[0] - 12, mid[1] - 12)
    page.mouse.down()
    page.mouse.move(mid[0] + 12, mid[1] + 12, steps=4)
    page.mouse.up()
    wait_idle(page)
    page.get_by_test_id("group-0").click()
    drag_gizmo_x(page, 100)
    page.get_by_test_id("energy").select_option("spokes_and_rims")
    page.wait_for_function("() => window.__arap.params.energy === 'spokes_and_rims'")
    wait_idle(page)
    wait_settled(page)  # the shape goes on changing until it has settled
    state = page.evaluate("() => ({ counts: window.__arap.counts(), constraints: window.__arap.constraints(), "
                          "name: window.__arap.meshName, canUndo: window.__arap.canUndo })")
    counts = state["counts"]
    assert 0 < counts["roi"] < page.evaluate("() => window.__arap.nVertices")
    assert counts["fixed"] == len(fixed) and len(counts["groups"]) == 2 and min(counts["groups"]) > 0
    assert state["canUndo"]
    state["positions"] = positions(page)
    return state


def assert_restored(page: Page, before: dict, rest: np.ndarray) -> None:
    """The page shows the session `before`: mesh, selection, groups, parameters and (close to) its shape."""
    after = page.evaluate("() => ({ counts: window.__arap.counts(), constraints: window.__arap.constraints(), "
                          "name: window.__arap.meshName, params: window.__arap.params })")
    assert after["name"] == before["name"]
    assert after["counts"] == before["counts"]
    assert after["constraints"] == before["constraints"]
    assert after["params"]["energy"] == "spokes_and_rims"
    expect(page.locator("#group-list li")).to_have_count(2)
    U, B = positions(page), before["positions"]
    diag = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    assert np.linalg.norm(B - rest, axis=1).max() > 0.02 * diag, "the edit did not deform the shape"
    np.testing.assert_allclose(U, B, rtol=0, atol=1e-6 * diag)
    assert page.evaluate("() => window.__arap.canUndo")
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


# ---------------------------------------------------------------------------------------------- keyboard


def test_letter_keys_in_the_model_dropdown_do_not_replace_the_mesh(page: Page) -> None:
    select_anchor_and_handle(page)
    dialogs = Dialogs(page)
    name = page.evaluate("() => window.__arap.meshName")
    counts = page.evaluate(COUNTS)
    assert any(b.startswith("b") for b in page.evaluate("() => window.__arap.builtins")), "no model starts with B"
    page.get_by_test_id("tool-orbit").click()
    select = page.get_by_test_id("builtin-select")
    select.focus()
    page.keyboard.press("b")
    page.keyboard.press("x")
    settle(page)
    assert page.evaluate("() => window.__arap.meshName") == name
    assert page.evaluate(COUNTS) == counts
    expect(select).to_have_value(name)
    assert active_tool(page) == "orbit", "a shortcut acted inside the dropdown"
    assert dialogs.seen == []
    assert page.evaluate("() => window.__arap.canUndo")


def test_shortcuts_work_after_clicking_checkboxes_buttons_and_sliders(page: Page) -> None:
    page.get_by_test_id("wireframe").click()
    page.keyboard.press("x")
    expect(page.get_by_test_id("tool-box")).to_have_class("active")
    page.get_by_text("Flat shading").click()  # the checkbox's label
    expect(page.get_by_test_id("flat-shading")).to_be_checked()
    page.keyboard.press("o")
    expect(page.get_by_test_id("tool-orbit")).to_have_class("active")
    page.get_by_test_id("fit-view").click()
    page.keyboard.press("b")
    expect(page.get_by_test_id("tool-brush")).to_have_class("active")
    page.get_by_test_id("brush-radius").click()
    page.keyboard.press("e")
    expect(page.get_by_test_id("gizmo-rotate")).to_have_class("active")
    page.get_by_test_id("role-fixed").click()
    page.keyboard.press("4")
    expect(page.get_by_test_id("role-erase")).to_have_class("active")


# ---------------------------------------------------------------------------------------------- replacing


def test_replacing_an_edited_mesh_asks_first(page: Page, tmp_path: Path) -> None:
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 80)
    wait_settled(page)
    name = page.evaluate("() => window.__arap.meshName")
    counts = page.evaluate(COUNTS)
    shape = positions(page)
    dialogs = Dialogs(page, accept=False)
    select = page.get_by_test_id("builtin-select")

    # the next model with the keyboard: cancelled, everything stays
    select.focus()
    page.keyboard.press("ArrowDown")
    settle(page)
    assert [t for t, _ in dialogs.seen] == ["confirm"]
    assert page.evaluate("() => window.__arap.meshName") == name
    expect(select).to_have_value(name)
    assert page.evaluate(COUNTS) == counts
    np.testing.assert_array_equal(positions(page), shape)
    assert page.evaluate("() => window.__arap.canUndo")

    # an upload: cancelled too
    text, _ = sphere_obj(1)
    path = tmp_path / "other.obj"
    path.write_text(text)
    page.get_by_test_id("file-input").set_input_files(str(path))
    settle(page)
    assert len(dialogs.seen) == 2 and dialogs.seen[1][0] == "confirm"
    assert page.evaluate("() => window.__arap.meshName") == name
    assert page.evaluate(COUNTS) == counts

    # accepted: the other model replaces the mesh and its edits
    dialogs.accept = True
    select.focus()
    page.keyboard.press("ArrowDown")
    page.wait_for_function(f"() => window.__arap.meshName !== {name!r}")
    wait_idle(page)
    assert len(dialogs.seen) == 3
    other = page.evaluate("() => window.__arap.meshName")
    expect(select).to_have_value(other)
    assert page.evaluate(COUNTS)["fixed"] == 0 and not page.evaluate("() => window.__arap.canUndo")

    # a mesh without edits is replaced without asking
    select.focus()
    page.keyboard.press("ArrowDown")
    page.wait_for_function(f"() => window.__arap.meshName !== {other!r}")
    wait_idle(page)
    assert len(dialogs.seen) == 3


def test_leaving_without_edits_does_not_ask(page: Page) -> None:
    dialogs = Dialogs(page, accept=False)
    page.get_by_test_id("fit-view").click()  # the page has been used, but nothing is edited
    with page.expect_event("close", timeout=scaled_ms(10)):
        page.close(run_before_unload=True)
    assert dialogs.seen == []


def test_leaving_an_edited_session_warns(page: Page) -> None:
    select_anchor_and_handle(page)
    counts = page.evaluate(COUNTS)
    dialogs = Dialogs(page, accept=False)
    page.close(run_before_unload=True)
    page_wait_until(page, lambda: dialogs.seen or page.is_closed(), 10, "the warning or the page closing")
    assert [t for t, _ in dialogs.seen] == ["beforeunload"]
    assert not page.is_closed()
    assert page.evaluate(COUNTS) == counts


# ---------------------------------------------------------------------------------------------- autosave


def place_pivot(page: Page, point: np.ndarray) -> list[float]:
    """Place the active group's pivot with the mouse (P, then a click) at the vertex nearest ``point``; returns
    where the gizmo's pivot is then."""
    U = positions(page)
    hit = U[np.argmin(np.linalg.norm(U - point, axis=1))]
    x, y = page.evaluate("(p) => window.__arap.project(p)", hit.tolist())
    page.mouse.move(x, y)
    page.keyboard.press("p")
    page.mouse.click(x, y)
    g = page.evaluate("() => window.__arap.gizmo()")
    assert g["pivotPlaced"], "the click did not place the pivot"
    return g["pivot"]


def test_autosave_restores_the_session_after_a_reload(page: Page) -> None:
    rest = positions(page)
    before = edit_session(page)
    handle = np.asarray(before["constraints"]["handle_groups"][0])
    below = before["positions"][handle].mean(axis=0) - np.array([0, 0.1 * np.ptp(rest[:, 1]), 0])
    pivot = place_pivot(page, below)  # placed after the drag: kept in the group's frame, saved where it is now
    wait_autosaved(page)
    Dialogs(page, accept=True)  # the warning before unloading
    page.reload()
    wait_ready(page)
    offer = page.get_by_test_id("restore-offer")
    expect(offer).to_be_visible()
    expect(offer).to_contain_text(before["name"])
    assert page.evaluate(COUNTS)["fixed"] == 0, "the fresh session should start empty"
    page.get_by_test_id("restore-accept").click()
    expect(offer).to_be_hidden()
    page.wait_for_function(f"() => window.__arap.counts().fixed === {before['counts']['fixed']}")
    wait_ready(page)
    wait_idle(page)
    assert_restored(page, before, rest)
    g = page.evaluate("() => window.__arap.gizmo()")
    assert g["group"] == 0 and g["pivotPlaced"], "the placed pivot was not restored"
    np.testing.assert_allclose(g["pivot"], pivot, rtol=0, atol=1e-9 * np.ptp(rest[:, 1]))

    # the restored session goes on: a drag moves the handles from the restored shape
    drag_gizmo_x(page, 60)
    assert np.linalg.norm(positions(page)[handle] - before["positions"][handle], axis=1).min() > 1e-3
    assert not page.evaluate("() => window.__arap.errors")

    # the restored session is saved again; after another reload, "Discard" forgets it
    wait_autosaved(page)
    page.reload()
    wait_ready(page)
    expect(offer).to_be_visible()
    page.get_by_test_id("restore-discard").click()
    expect(offer).to_be_hidden()
    assert page.evaluate(COUNTS)["fixed"] == 0
    page.reload()
    wait_ready(page)
    # the offer must not come back: the page looks for a saved session without a sign when it is done, so a wrong
    # offer gets a fixed time to appear
    page.wait_for_timeout(500)
    expect(offer).to_be_hidden()


def test_autosave_restores_an_uploaded_mesh_with_its_applied_rest_pose(page: Page, tmp_path: Path) -> None:
    text, n = sphere_obj(2)
    path = tmp_path / "ball.obj"
    path.write_text(text)
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.meshName === 'ball'")
    wait_idle(page)
    original = positions(page)
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    xmin, xmax = pts[:, 0].min(), pts[:, 0].max()
    page.get_by_test_id("hud-toggle").click()  # the statistics cover the top left of the large sphere
    page.get_by_test_id("front-only").click()
    page.get_by_test_id("role-fixed").click()
    box_select(page, xmax + 10, ymax + 10, xmin - 10, ymax - 0.2 * (ymax - ymin))
    page.get_by_test_id("role-handle").click()
    box_select(page, xmax + 10, ymin - 10, xmin - 10, ymin + 0.2 * (ymax - ymin))
    wait_idle(page)
    counts = page.evaluate(COUNTS)
    assert counts["fixed"] > 0 and counts["groups"][0] > 0
    drag_gizmo_x(page, 60)
    page.get_by_test_id("apply").click()
    page.wait_for_function("() => window.__arap.canUndo && !window.__arap.busy")
    wait_idle(page)
    applied = positions(page)
    drag_gizmo_x(page, 60)
    shape = positions(page)
    assert np.abs(shape - applied).max() > 1e-3 and np.abs(applied - original).max() > 1e-3
    wait_autosaved(page)
    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    assert page.evaluate("() => window.__arap.meshName") != "ball"
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => window.__arap.meshName === 'ball' && !window.__arap.restoring")
    wait_idle(page)
    assert page.evaluate(COUNTS) == counts
    assert page.evaluate("() => window.__arap.nVertices") == n
    np.testing.assert_allclose(positions(page), shape, rtol=0, atol=1e-6)
    # the rest pose is the applied shape, not the uploaded one
    page.get_by_test_id("reset").click()
    page.wait_for_function("() => !window.__arap.busy")
    page_wait_until(page, lambda: np.allclose(positions(page), applied, rtol=0, atol=1e-6), 10,
                    "the shape to be back at the applied rest pose")
    wait_idle(page)
    np.testing.assert_allclose(positions(page), applied, rtol=0, atol=1e-6)
    assert not page.evaluate("() => window.__arap.errors")


def test_a_closed_tab_is_offered_but_an_open_one_is_not(page: Page) -> None:
    _, handle = select_anchor_and_handle(page)
    fixed = page.evaluate(COUNTS)["fixed"]
    wait_autosaved(page)
    other = page.context.new_page()
    other.goto(page.url)
    wait_ready(other)
    # the offer must not appear: the page looks for a saved session without a sign when it is done, so a wrong offer
    # gets a fixed time to appear
    other.wait_for_timeout(1000)
    expect(other.get_by_test_id("restore-offer")).to_be_hidden()  # the first tab is still open
    page.close()  # gone without a warning, as in a crash
    later = page.context.new_page()
    later.goto(other.url)
    wait_ready(later)
    offer = later.get_by_test_id("restore-offer")
    expect(offer).to_be_visible()
    expect(offer).to_contain_text(f"{fixed} anchors, 1 handle group")
    later.get_by_test_id("restore-accept").click()
    later.wait_for_function(f"() => window.__arap.counts().fixed === {fixed} && !window.__arap.busy")
    assert later.evaluate(COUNTS)["groups"] == [len(handle)]


# ---------------------------------------------------------------------------------------------- reconnecting


def test_reconnects_and_restores_after_a_server_restart(browser: Browser, own_server: list) -> None:
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    page_errors: list[str] = []
    page.on("pageerror", lambda exc: page_errors.append(str(exc)))
    try:
        attempts: list[object] = []
        page.on("websocket", lambda ws: attempts.append(ws))
        page.goto(own_server[-1].url)
        wait_ready(page)
        rest = positions(page)
        before = edit_session(page)
        own_server[-1].stop()
        expect(page.get_by_test_id("conn-text")).to_have_text("reconnecting…", timeout=scaled_ms(10))
        expect(page.get_by_test_id("status-text")).to_contain_text("reconnecting")
        opened = len(attempts)
        page_wait_until(page, lambda: len(attempts) >= opened + 2, 30,
                        "a few failed attempts while the server is away")
        assert not page.evaluate("() => window.__arap.connected")
        # more anchors while disconnected: they come back too
        pts = screen_points(page)
        cx, cy = pts.mean(axis=0)
        page.keyboard.press("2")
        box_select(page, cx - 15, cy - 15, cx + 15, cy + 15)
        offline = page.evaluate("() => ({ counts: window.__arap.counts(), constraints: window.__arap.constraints() })")
        assert offline["counts"]["fixed"] > before["counts"]["fixed"]
        before.update(offline)
        own_server.append(own_server[-1].restarted())
        expect(page.get_by_test_id("conn-text")).to_have_text("connected", timeout=scaled_ms(20))
        page.wait_for_function(f"() => window.__arap.counts().fixed === {before['counts']['fixed']}",
                               timeout=scaled_ms(20))
        wait_ready(page)
        wait_idle(page)
        assert_restored(page, before, rest)
        expect(page.get_by_test_id("restore-offer")).to_be_hidden()
    finally:
        context.close()
    assert not page_errors, f"errors in the page: {page_errors}"


# ---------------------------------------------------------------------------------------------- undo after a restore

RECORD_SELECTIONS = """() => {
    // every selection the page shows from now on (the handle groups' sizes, at each change of the group list)
    window.__shown = [];
    const record = () => window.__shown.push(window.__arap.counts().groups.slice());
    new MutationObserver(record).observe(document.getElementById('group-list'), { childList: true, subtree: true });
    record();
}"""


def test_undo_after_a_restore_never_shows_the_set_that_put_the_shape_back(page: Page) -> None:
    """A restore first pins every moved vertex as a handle (to put the shape back exactly), then sends the saved
    selection; that pin set is no state of the user's, so undo and redo step over it."""
    rest = positions(page)
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 100)
    wait_settled(page)
    before = page.evaluate(COUNTS)
    moved = positions(page)
    n_moved = int((np.abs(moved - rest).max(axis=1) > 0).sum())
    assert n_moved > 2 * max(before["groups"]), "the drag should move many more vertices than the handle"
    reload_and_restore(page, restored=f"window.__arap.counts().fixed === {before['fixed']}")
    assert page.evaluate(COUNTS) == before
    assert page.evaluate("() => window.__arap.canUndo")
    page.evaluate(RECORD_SELECTIONS)

    # one undo: back to the state before the restore (the rest pose, nothing selected), never to the pin set
    page.keyboard.press("Control+Z")
    page.wait_for_function("() => !window.__arap.canUndo && window.__arap.canRedo && !window.__arap.busy")
    settle(page)
    diag = float(np.linalg.norm(np.ptp(rest, axis=0)))
    np.testing.assert_allclose(positions(page), rest, rtol=0, atol=1e-6 * diag)
    assert page.evaluate(COUNTS)["groups"] == [0]

    # one redo: the restored session again
    page.keyboard.press("Control+Shift+Z")
    page.wait_for_function(f"() => window.__arap.counts().fixed === {before['fixed']} && !window.__arap.busy")
    settle(page)
    assert page.evaluate(COUNTS) == before
    np.testing.assert_allclose(positions(page), moved, rtol=0, atol=1e-5 * diag)
    shown = page.evaluate("() => window.__shown")
    assert all(max(groups) < n_moved for groups in shown), f"the pin set was shown as a selection: {shown}"
    assert not page.evaluate("() => window.__arap.errors")


# ---------------------------------------------------------------------------------------------- a full server


def test_a_tab_the_full_server_refuses_says_why_and_retries_slowly(browser: Browser) -> None:
    server = _ServerThread(max_sessions=1)
    server.start()
    server.wait_started()
    context = browser.new_context(viewport=VIEWPORT)
    page_errors: list[str] = []
    try:
        first = context.new_page()
        first.goto(server.url)
        wait_ready(first)
        second = context.new_page()
        second.on("pageerror", lambda exc: page_errors.append(str(exc)))
        sockets: list[object] = []
        second.on("websocket", lambda ws: sockets.append(ws))
        second.goto(server.url)
        status = second.get_by_test_id("status-text")
        expect(status).to_contain_text("The studio server is full", timeout=scaled_ms(10))
        expect(status).to_contain_text("Close another studio tab")
        expect(status).not_to_contain_text("work is kept")  # this tab has no work yet
        expect(second.get_by_test_id("conn-text")).to_have_text("server full")
        expect(second.get_by_test_id("reconnect")).to_be_visible()
        assert [e["code"] for e in second.evaluate("() => window.__arap.errors")] == ["busy"]
        second.wait_for_timeout(3000)  # the scenario: a refused tab waits for another one to close, not a time
        assert len(sockets) == 1, f"{len(sockets)} connection attempts in 3 s: it should wait for a tab to close"
        expect(status).to_contain_text("The studio server is full")
        assert not second.evaluate("() => window.__arap.ready")

        first.close()
        second.get_by_test_id("reconnect").click()
        wait_ready(second)
        expect(second.get_by_test_id("conn-text")).to_have_text("connected")
        expect(second.get_by_test_id("statusbar")).to_be_hidden()
    finally:
        context.close()
        server.stop()
    assert not page_errors, f"errors in the page: {page_errors}"
