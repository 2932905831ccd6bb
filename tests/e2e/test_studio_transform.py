"""The handle gizmo's rotation, pivot, typed transforms, snapping and axes in headless Chromium, with real mouse and
keyboard input."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import positions, wait_idle, wait_settled
from tests.e2e.test_studio import box_select, select_anchor_and_handle
from tests.e2e.test_studio_mirror import front_point, paint_at, press_mirror, symmetric_mesh, upload
from tests.e2e.test_studio_points import _anchor_bottom, _place_point

pytestmark = pytest.mark.e2e


def matrix(elements: list[float]) -> np.ndarray:
    """A column-major 4×4 (as sent and as three.js keeps it) as a row-major array."""
    return np.asarray(elements, dtype=np.float64).reshape(4, 4).T


def transform(page: Page) -> np.ndarray:
    return matrix(page.evaluate("() => window.__arap.transforms()[window.__arap.gizmo().group]"))


def rotation_of(delta: np.ndarray) -> tuple[float, np.ndarray]:
    """Angle (degrees) and unit axis of the rotation part of a rigid transform."""
    r = delta[:3, :3]
    angle = math.degrees(math.acos(np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)))
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    n = np.linalg.norm(axis)
    return angle, axis / n if n > 0 else axis


def about(pivot: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """Rotation by `degrees` about the line through `pivot` along the unit `axis`."""
    a = math.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r = np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * (k @ k)
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = pivot - r @ pivot
    return m


def gizmo(page: Page) -> dict[str, Any]:
    g = page.evaluate("() => window.__arap.gizmo()")
    assert g is not None, "no gizmo on the handle group"
    return g


def spy_on_drags(page: Page) -> None:
    """Record the drag messages the page sends (in window.__drags)."""
    page.evaluate(
        """() => {
            window.__drags = [];
            const send = WebSocket.prototype.send;
            WebSocket.prototype.send = function (data) {
                if (typeof data === 'string' && data.includes('"drag"')) window.__drags.push(JSON.parse(data));
                return send.call(this, data);
            };
        }"""
    )


def last_drag(page: Page) -> list[list[float]]:
    return page.evaluate("() => window.__drags.filter((m) => m.type === 'drag').at(-1).transforms")


def ready_to_rotate(page: Page) -> tuple[np.ndarray, np.ndarray]:
    fixed, handle = select_anchor_and_handle(page)
    page.mouse.move(30, 300)  # over the view, away from the model
    page.keyboard.press("e")
    assert gizmo(page)["mode"] == "rotate"
    return fixed, handle


def grab_ring(page: Page, axis: str, pick: str = "first", skip: int = 0) -> tuple[float, float]:
    """Move the pointer onto the ring about `axis` (where the gizmo picks that ring); `pick`: the first such point
    of the ring (after `skip`), or the one nearest the ring's centre on screen."""
    g = gizmo(page)
    cx, cy = g["screen"]
    points = g["rings"][axis]
    order = list(range(len(points)))
    if pick == "nearest":
        order.sort(key=lambda k: math.hypot(points[k][0] - cx, points[k][1] - cy))
    found = 0
    for k in order:
        x, y = points[k]
        page.mouse.move(x, y)
        if page.evaluate("() => window.__arap.gizmo().hover") == axis.upper():
            if found == skip:
                return x, y
            found += 1
    raise AssertionError(f"the {axis} ring could not be picked")


def sweep(page: Page, start: tuple[float, float], turn_deg: float, steps: int = 12,
          modifier: str | None = None, before_release: Callable[[], None] | None = None) -> None:
    """Press at `start` and move the pointer `turn_deg` around the gizmo's centre (counter-clockwise on screen
    positive), then (after `before_release`) let go."""
    cx, cy = gizmo(page)["screen"]
    r = math.hypot(start[0] - cx, start[1] - cy)
    a0 = math.atan2(cy - start[1], start[0] - cx)
    if modifier:
        page.keyboard.down(modifier)
    page.mouse.down()
    for k in range(1, steps + 1):
        a = a0 + math.radians(turn_deg) * k / steps
        page.mouse.move(cx + r * math.cos(a), cy - r * math.sin(a))
    if before_release:
        before_release()
    page.mouse.up()
    if modifier:
        page.keyboard.up(modifier)
    wait_idle(page)


def test_rotate_rings_follow_the_pointer_around_the_centre(page: Page) -> None:
    ready_to_rotate(page)
    units = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}
    cases = [("x", 0, 90), ("y", 0, -90), ("z", 0, 90), ("z", 3, -90), ("x", 4, -90), ("y", 2, 90),
             ("e", 0, 90), ("e", 9, -90)]
    for axis, skip, turn in cases:
        before = transform(page)
        start = grab_ring(page, axis, skip=skip)
        g = gizmo(page)
        eye = np.asarray(g["camera"]) - np.asarray(g["pivot"])
        if axis == "e":  # the view ring turns about the line of sight
            units["e"] = eye / np.linalg.norm(eye)
        sweep(page, start, turn)
        angle, rot_axis = rotation_of(transform(page) @ np.linalg.inv(before))
        assert abs(angle - 90) < 3, f"{axis} ring, {turn}° around the centre from {start}: turned {angle:.1f}°"
        assert abs(abs(rot_axis @ units[axis]) - 1) < 1e-6, f"{axis} ring turned about {rot_axis}"
        # counter-clockwise on screen turns counter-clockwise as seen from the camera
        assert np.sign(rot_axis @ units[axis]) * np.sign(units[axis] @ eye) == np.sign(turn)

    # grabbed where the ring passes next to the centre on screen, it still turns with the pointer
    before = transform(page)
    start = grab_ring(page, "x", pick="nearest")
    cx, cy = gizmo(page)["screen"]
    assert math.hypot(start[0] - cx, start[1] - cy) < 0.6 * np.ptp(np.asarray(gizmo(page)["rings"]["x"])[:, 1])
    sweep(page, start, 90)
    angle, _ = rotation_of(transform(page) @ np.linalg.inv(before))
    assert abs(angle - 90) < 3, f"grabbed beside the centre: turned {angle:.1f}°"

    # the free ball at the centre rolls like a trackball: a sideways drag turns about the screen's vertical
    before = transform(page)
    ball = [(cx + dx, cy + dy) for dy in (0, -10, 10, -20, 20, -30, 30) for dx in (0, -10, 10)]
    for bx, by in ball:
        page.mouse.move(bx, by)
        if gizmo(page)["hover"] == "XYZE":
            break
    else:
        raise AssertionError("the free ball could not be picked")
    page.mouse.down()
    for k in range(1, 7):
        page.mouse.move(bx + 10 * k, by)
    page.mouse.up()
    wait_idle(page)
    angle, rot_axis = rotation_of(transform(page) @ np.linalg.inv(before))
    assert 5 < angle < 180
    assert abs(rot_axis[1]) > 0.8, f"a sideways roll turned about {rot_axis}"
    assert not page.evaluate("() => window.__arap.errors")


def test_typed_rotation_about_a_placed_pivot(page: Page) -> None:
    fixed, handle = ready_to_rotate(page)
    spy_on_drags(page)
    rest = positions(page)
    # place the pivot on the surface, a little below the handle
    target = rest[handle].mean(axis=0) - np.array([0, 0.1 * np.ptp(rest[:, 1]), 0])
    hit = rest[np.argmin(np.linalg.norm(rest - target, axis=1))]
    x, y = page.evaluate("(p) => window.__arap.project(p)", hit.tolist())
    page.mouse.move(x, y)
    page.keyboard.press("p")
    assert gizmo(page)["placing"]
    page.mouse.click(x, y)
    g = gizmo(page)
    assert g["pivotPlaced"] and not g["placing"]
    pivot = np.asarray(g["pivot"])
    assert np.linalg.norm(pivot - hit) < 0.05 * np.ptp(rest[:, 1]), "the pivot is not where the click was"
    assert page.evaluate("() => window.__arap.constraints().handle_groups[0].length") == len(handle), \
        "the placing click painted"

    for key in ("r", "z", "9"):
        page.keyboard.press(key)
    assert page.evaluate("() => window.__arap.typing") == "Rotate Z: 9°"
    page.keyboard.press("0")
    expect(page.get_by_test_id("numeric-line")).to_have_text("Rotate Z: 90°")
    page.keyboard.press("Enter")
    expect(page.get_by_test_id("numeric-line")).to_be_hidden()
    wait_idle(page)
    page.wait_for_function("() => !window.__arap.busy && window.__arap.canUndo")

    expected = about(pivot, np.array([0, 0, 1.0]), 90)
    sent = last_drag(page)
    assert len(sent) == 1
    np.testing.assert_allclose(matrix(sent[0]), expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(transform(page), expected, rtol=0, atol=1e-9)  # the server's state
    # the server holds the handle there: its vertices are the rotated rest positions
    page.wait_for_function(
        "() => document.querySelector('[data-testid=settle-status]')?.dataset.status === 'settled'")
    moved = positions(page)
    want = rest[handle] @ expected[:3, :3].T + expected[:3, 3]
    np.testing.assert_allclose(moved[handle], want, atol=1e-5 * np.ptp(rest))
    np.testing.assert_allclose(moved[fixed], rest[fixed], atol=1e-6)
    np.testing.assert_allclose(gizmo(page)["pivot"], pivot, atol=1e-9)  # turning about the pivot keeps it

    # back to the centroid
    page.keyboard.press("c")
    g = gizmo(page)
    assert not g["pivotPlaced"]
    np.testing.assert_allclose(g["pivot"], moved[handle].mean(axis=0), atol=1e-6)
    assert not page.evaluate("() => window.__arap.errors")


def test_typed_move_applies_exactly_and_escape_cancels(page: Page) -> None:
    _, handle = select_anchor_and_handle(page)
    spy_on_drags(page)
    page.mouse.move(30, 300)
    before = transform(page)
    pivot_before = gizmo(page)["pivotMatrix"]
    seq = page.evaluate("() => window.__arap.lastSeq")

    # Escape: the preview goes, nothing is sent
    shown = positions(page)
    for key in ("g", "y", "5"):
        page.keyboard.press(key)
    expect(page.get_by_test_id("numeric-line")).to_have_text("Move Y: 5")
    assert gizmo(page)["pivotMatrix"] != pivot_before, "the gizmo does not preview the move"
    preview = positions(page)
    np.testing.assert_allclose(preview[handle] - shown[handle], np.tile([0, 5, 0], (len(handle), 1)), atol=1e-5)
    others = np.setdiff1d(np.arange(len(shown)), handle)
    np.testing.assert_array_equal(preview[others], shown[others])
    page.keyboard.press("Backspace")
    page.keyboard.press("Escape")
    expect(page.get_by_test_id("numeric-line")).to_be_hidden()
    assert page.evaluate("() => window.__arap.typing") is None
    np.testing.assert_array_equal(positions(page), shown)
    np.testing.assert_array_equal(transform(page), before)
    np.testing.assert_allclose(gizmo(page)["pivotMatrix"], pivot_before, atol=1e-12)
    assert page.evaluate("() => window.__drags.length") == 0
    assert page.evaluate("() => window.__arap.lastSeq") == seq
    assert page.evaluate("() => window.__arap.gizmo().mode") == "translate"

    # the axis letter was not taken as the box tool's shortcut, the digits not as roles
    expect(page.get_by_test_id("tool-box")).not_to_have_class("active")

    rest = positions(page)
    for key in ("g", "x", "0", ".", "1"):
        page.keyboard.press(key)
    expect(page.get_by_test_id("numeric-line")).to_have_text("Move X: 0.1")
    page.keyboard.press("Enter")
    wait_idle(page)
    expected = before.copy()
    expected[0, 3] += 0.1
    np.testing.assert_allclose(matrix(last_drag(page)[0]), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(transform(page), expected, rtol=0, atol=1e-12)
    page.wait_for_function(
        "() => document.querySelector('[data-testid=settle-status]')?.dataset.status === 'settled'")
    shift = positions(page)[handle] - rest[handle]
    np.testing.assert_allclose(shift, np.tile([0.1, 0, 0], (len(handle), 1)), atol=1e-5)
    expect(page.get_by_test_id("role-handle")).to_have_class("active")
    assert not page.evaluate("() => window.__arap.errors")


def test_typed_amounts_take_exponents_and_refuse_other_keys_visibly(page: Page) -> None:
    select_anchor_and_handle(page)
    spy_on_drags(page)
    page.mouse.move(30, 300)
    before = transform(page)
    line = page.get_by_test_id("numeric-line")
    for key in ("g", "y", "1", "e", "3"):
        page.keyboard.press(key)
    expect(line).to_have_text("Move Y: 1e3")  # not 13
    page.keyboard.press("e")  # a second exponent: refused, and the line says so
    expect(line).to_contain_text("Move Y: 1e3")
    expect(line).to_contain_text("“e” cannot go there")
    expect(line).to_have_class(re.compile(r"\brefused\b"))
    page.keyboard.press("Backspace")
    expect(line).to_have_text("Move Y: 1e")
    expect(line).not_to_have_class(re.compile(r"\brefused\b"))
    for key in ("-", "1"):
        page.keyboard.press(key)
    expect(line).to_have_text("Move Y: 1e-1")
    page.keyboard.press("q")
    expect(line).to_contain_text("“q” cannot go there")
    page.keyboard.press("Enter")
    wait_idle(page)
    expected = before.copy()
    expected[1, 3] += 0.1
    np.testing.assert_allclose(matrix(last_drag(page)[0]), expected, rtol=0, atol=1e-12)
    assert not page.evaluate("() => window.__arap.errors")


def test_panel_fields_apply_an_exact_rotation(page: Page) -> None:
    select_anchor_and_handle(page)
    pivot = np.asarray(gizmo(page)["pivot"])
    page.get_by_test_id("exact-mode").select_option("rotate")
    page.get_by_test_id("exact-axis").select_option("y")
    page.get_by_test_id("exact-amount").fill("-45")
    page.get_by_test_id("exact-apply").click()
    wait_idle(page)
    page.wait_for_function("() => window.__arap.canUndo")
    np.testing.assert_allclose(transform(page), about(pivot, np.array([0, 1.0, 0]), -45), rtol=0, atol=1e-9)

    # the pivot buttons: Place… waits for a click on the surface (Esc gives up), Centroid resets
    page.get_by_test_id("place-pivot").click()
    expect(page.get_by_test_id("place-pivot")).to_have_class(re.compile("active"))
    assert gizmo(page)["placing"]
    page.keyboard.press("Escape")
    assert not gizmo(page)["placing"]
    expect(page.get_by_test_id("place-pivot")).not_to_have_class(re.compile("active"))
    page.get_by_test_id("reset-pivot").click()
    assert not gizmo(page)["pivotPlaced"]


def test_snapping_with_ctrl_and_the_checkbox(page: Page) -> None:
    ready_to_rotate(page)
    step = gizmo(page)["gridStep"]
    expect(page.get_by_test_id("snap-step")).to_contain_text(f"grid {step:g}")
    mantissa = step / 10 ** math.floor(math.log10(step))
    assert any(abs(mantissa - m) < 1e-9 for m in (1, 2, 5)), step

    line = page.get_by_test_id("numeric-line")
    for modifier, turn in (("Control", 50), (None, 70)):
        if modifier is None:
            page.get_by_test_id("snap").check()
            page.mouse.move(30, 300)
        before = transform(page)
        sweep(page, grab_ring(page, "z"), turn, modifier=modifier,
              before_release=lambda: expect(line).to_have_text(re.compile(r"Rotate Z: -?(45|60|75)°")))
        expect(line).to_be_hidden()
        angle, _ = rotation_of(transform(page) @ np.linalg.inv(before))
        assert angle > 10 and abs(angle / 15 - round(angle / 15)) < 1e-6, f"snapped to {angle}°"
        assert round(angle / 15) * 15 == round(turn / 15) * 15
    page.get_by_test_id("snap").uncheck()

    # a free drag turns by any angle
    before = transform(page)
    sweep(page, grab_ring(page, "z"), 37)
    angle, _ = rotation_of(transform(page) @ np.linalg.inv(before))
    assert abs(angle - 37) < 3

    # moves land on the grid (from where the drag began)
    page.mouse.move(30, 300)
    page.keyboard.press("w")
    g = gizmo(page)
    before = transform(page)
    (cx, cy), (ax, ay) = g["screen"], g["axes"]["x"]
    d = np.array([ax - cx, ay - cy]) / math.hypot(ax - cx, ay - cy)
    page.mouse.move(ax, ay)
    page.keyboard.down("Control")
    page.mouse.down()
    for k in range(1, 9):
        page.mouse.move(ax + d[0] * 97 * k / 8, ay + d[1] * 97 * k / 8)
    page.mouse.up()
    page.keyboard.up("Control")
    wait_idle(page)
    offset = (transform(page) @ np.linalg.inv(before))[:3, 3]
    assert abs(offset[0]) >= step and abs(offset[0] / step - round(offset[0] / step)) < 1e-6, offset
    np.testing.assert_allclose(offset[1:], 0, atol=1e-12)
    assert not page.evaluate("() => window.__arap.errors")


def test_local_and_world_axes(page: Page) -> None:
    select_anchor_and_handle(page)
    page.mouse.move(30, 300)
    for key in ("r", "z", "9", "0", "Enter"):
        page.keyboard.press(key)
    wait_idle(page)
    g = gizmo(page)
    assert g["space"] == "world"
    world_y = np.asarray(g["axes"]["y"])

    page.keyboard.press("l")
    g = gizmo(page)
    assert g["space"] == "local"
    expect(page.get_by_test_id("local-axes")).to_be_checked()
    # the group turned 90° about Z: its local X is the world's Y
    np.testing.assert_allclose(g["axes"]["x"], world_y, atol=0.5)

    # a typed move along local X goes along world Y
    before = transform(page)
    for key in ("g", "x", "-", "0", ".", "1", "Enter"):
        page.keyboard.press(key)
    wait_idle(page)
    offset = (transform(page) @ np.linalg.inv(before))[:3, 3]
    np.testing.assert_allclose(offset, [0, -0.1, 0], atol=1e-12)

    # the local X ring turns about the group's own X axis (the world's Y here)
    page.mouse.move(30, 300)
    page.keyboard.press("e")
    before = transform(page)
    sweep(page, grab_ring(page, "x"), -90)
    angle, rot_axis = rotation_of(transform(page) @ np.linalg.inv(before))
    assert abs(angle - 90) < 3 and abs(abs(rot_axis[1]) - 1) < 1e-6, (angle, rot_axis)

    page.get_by_test_id("local-axes").uncheck()
    assert gizmo(page)["space"] == "world"
    assert not page.evaluate("() => window.__arap.errors")


def test_new_shortcuts_are_in_the_help(page: Page) -> None:
    page.locator("#view").focus()
    page.keyboard.press("?")
    keys = page.locator("[data-testid=help-table] kbd").all_inner_texts()
    for key in ("G", "R", "P", "C", "L", "Ctrl+drag gizmo"):
        assert key in keys, f"{key} is missing from the help"


def test_typed_rotation_moves_the_mirror_partner_mirrored(page: Page, tmp_path: Path) -> None:
    V, F = symmetric_mesh()
    shown = upload(page, tmp_path, "warped", V, F)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    mirror_of = np.asarray(press_mirror(page)["mirrorOf"])
    pts = np.asarray([page.evaluate("(p) => window.__arap.project(p)", p) for p in shown.tolist()])
    bottom = pts[:, 1] > pts[:, 1].max() - 0.15 * np.ptp(pts[:, 1])
    page.get_by_test_id("role-fixed").click()
    box_select(page, pts[bottom, 0].min() - 10, pts[bottom, 1].min(), pts[:, 0].max() + 10, pts[:, 1].max() + 10)
    wait_idle(page)
    page.get_by_test_id("role-handle").click()
    page.get_by_test_id("brush-units").select_option("world")
    page.get_by_test_id("brush-radius").fill("8")  # 8% of the diagonal: a patch, so that turning it moves it
    paint_at(page, front_point(V, 0.7))
    assert page.evaluate("() => window.__arap.partners()") == [1, 0]
    groups = page.evaluate("() => window.__arap.constraints().handle_groups")
    assert len(groups[0]) > 3
    assert sorted(int(mirror_of[i]) for i in groups[0]) == sorted(groups[1])
    assert gizmo(page)["group"] == 0
    # a pivot placed beside the group: the partner's pivot is its mirror image
    x, y = page.evaluate("(p) => window.__arap.project(p)", front_point(V, 0.45).tolist())
    page.mouse.move(x, y)
    page.keyboard.press("p")
    page.mouse.click(x, y)
    g = gizmo(page)
    assert g["pivotPlaced"] and not g["placing"]
    pivot = np.asarray(g["pivot"])
    assert page.evaluate("() => window.__arap.constraints().handle_groups") == groups

    spy_on_drags(page)
    page.mouse.move(30, 300)
    for key in ("r", "z", "9", "0"):
        page.keyboard.press(key)
    expect(page.get_by_test_id("numeric-line")).to_have_text("Rotate Z: 90°")
    page.keyboard.press("Enter")
    wait_idle(page)
    page.wait_for_function("() => !window.__arap.busy && window.__arap.canUndo")

    T = about(pivot, np.array([0, 0, 1.0]), 90)
    M = np.diag([-1.0, 1.0, 1.0, 1.0])  # the reflection in the plane x = 0
    sent = last_drag(page)
    assert len(sent) == 2, "one drag message carries both groups"
    np.testing.assert_allclose(matrix(sent[0]), T, rtol=0, atol=1e-9)
    np.testing.assert_allclose(matrix(sent[1]), M @ T @ M, rtol=0, atol=1e-9)
    # the partner turned the other way: -90° about Z through the mirrored pivot
    angle, axis = rotation_of(matrix(sent[1]))
    assert abs(angle - 90) < 1e-6 and axis @ [0, 0, 1] < -0.999
    client = np.asarray(page.evaluate("() => window.__arap.transforms()")).reshape(-1, 4, 4).transpose(0, 2, 1)
    np.testing.assert_allclose(client[1], M @ client[0] @ M, atol=1e-12)

    wait_settled(page)
    U = positions(page)
    for g, m in ((groups[0], T), (groups[1], M @ T @ M)):  # the server holds each group where its transform puts it
        np.testing.assert_allclose(U[g], V[g] @ m[:3, :3].T + m[:3, 3], atol=1e-5 * diag)
    assert np.abs(U[groups[0]] - V[groups[0]]).max() > 0.01 * diag, "the typed rotation did not move the group"
    asym = np.abs(U[mirror_of] * [-1, 1, 1] - U).max()
    assert asym < 1e-6 * diag, f"the settled shape is not symmetric: {asym / diag:.2e} of the diagonal"
    page.get_by_test_id("group-1").click()
    g = gizmo(page)
    assert g["group"] == 1 and g["pivotPlaced"]
    np.testing.assert_allclose(g["pivot"], pivot * [-1, 1, 1], atol=1e-9)
    assert not page.evaluate("() => window.__arap.errors")


def test_typed_rotation_of_a_point_handle_about_a_placed_pivot(page: Page) -> None:
    rest = positions(page)
    F = np.asarray(page.evaluate("() => window.__arap.faces()"), dtype=np.int64).reshape(-1, 3)
    diag = float(np.linalg.norm(np.ptp(rest, axis=0)))
    point = _place_point(page, _anchor_bottom(page))["point"]
    at = np.asarray(point["barycentric"]) @ rest[F[point["face"]]]
    g = gizmo(page)
    np.testing.assert_allclose(g["pivot"], at, atol=1e-5 * diag)  # the gizmo sits on the point
    # the pivot placed on the surface below the point
    target = at - np.array([0, 0.15 * np.ptp(rest[:, 1]), 0])
    hit = rest[np.argmin(np.linalg.norm(rest - target, axis=1))]
    x, y = page.evaluate("(p) => window.__arap.project(p)", hit.tolist())
    page.mouse.move(x, y)
    page.keyboard.press("p")
    page.mouse.click(x, y)
    g = gizmo(page)
    assert g["pivotPlaced"] and not g["placing"]
    pivot = np.asarray(g["pivot"])
    assert len(page.evaluate("() => window.__arap.constraints().points")) == 1, "the placing click placed a point"

    spy_on_drags(page)
    page.mouse.move(30, 300)
    for key in ("r", "z", "9", "0"):
        page.keyboard.press(key)
    expect(page.get_by_test_id("numeric-line")).to_have_text("Rotate Z: 90°")
    page.keyboard.press("Enter")
    wait_idle(page)
    expected = about(pivot, np.array([0, 0, 1.0]), 90)
    sent = last_drag(page)
    assert len(sent) == 1
    np.testing.assert_allclose(matrix(sent[0]), expected, rtol=0, atol=1e-9)
    wait_settled(page)
    want = expected[:3, :3] @ at + expected[:3, 3]
    assert np.linalg.norm(want - at) > 0.05 * diag
    U = positions(page)
    np.testing.assert_allclose(np.asarray(point["barycentric"]) @ U[F[point["face"]]], want, atol=1e-5 * diag)
    np.testing.assert_allclose(gizmo(page)["pivot"], pivot, atol=1e-9)  # turning about the pivot keeps it
    assert not page.evaluate("() => window.__arap.errors")
