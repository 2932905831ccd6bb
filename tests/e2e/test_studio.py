"""ARAP Studio in headless Chromium against the real server: rendering, selection with the mouse, dragging the
gizmo, export, undo/redo, constraint files and uploads."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import trimesh
from playwright.sync_api import Page, expect

from tests.e2e.conftest import (
    MAX_UPLOAD_BYTES,
    canvas_origin,
    canvas_pixels,
    positions,
    screen_points,
    wait_idle,
)
from tests.waiting import scaled_ms

pytestmark = pytest.mark.e2e

Shoot = Callable[[str], Path]


def background_mask(px: np.ndarray) -> np.ndarray:
    """Pixels that look like the empty background (dark blue-grey gradient and its grid lines)."""
    rgb = px[..., :3].astype(np.int32)
    return (rgb.max(axis=-1) < 100) & (np.ptp(rgb, axis=-1) < 40)


def read_obj_vertices(path: Path) -> np.ndarray:
    rows = [line.split()[1:4] for line in path.read_text().splitlines() if line.startswith("v ")]
    return np.asarray(rows, dtype=np.float64)


def sphere_obj(subdivisions: int = 2) -> tuple[str, int]:
    """OBJ text of an icosphere and its vertex count."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    return "\n".join(lines) + "\n", len(mesh.vertices)


def paint_stroke(page: Page, x: float, y: float, length: float = 12.0) -> None:
    """A short brush stroke with real mouse events, starting at page coordinates (x, y)."""
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + length, y + length / 2, steps=6)
    page.mouse.up()


def box_select(page: Page, x0: float, y0: float, x1: float, y1: float) -> None:
    """Shift+drag a selection rectangle."""
    page.keyboard.down("Shift")
    page.mouse.move(x0, y0)
    page.mouse.down()
    page.mouse.move((x0 + x1) / 2, (y0 + y1) / 2, steps=4)
    page.mouse.move(x1, y1, steps=4)
    page.mouse.up()
    page.keyboard.up("Shift")


def select_anchor_and_handle(page: Page) -> tuple[np.ndarray, np.ndarray]:
    """Box-select anchors at the bottom of the model, brush a handle at its top; returns (fixed, handle)."""
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    xmin, xmax = pts[:, 0].min(), pts[:, 0].max()
    page.get_by_test_id("role-fixed").click()
    box_select(page, xmin - 10, ymax - 0.12 * (ymax - ymin), xmax + 10, ymax + 10)
    wait_idle(page)
    top = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)]
    tx, ty = top.mean(axis=0)
    page.get_by_test_id("role-handle").click()
    paint_stroke(page, tx - 6, ty + 8)
    wait_idle(page)
    c = page.evaluate("() => window.__arap.constraints()")
    fixed = np.asarray(c["fixed"], dtype=np.int64)
    assert len(fixed) > 0, "box selection found no anchor vertices"
    assert len(c["handle_groups"]) == 1, "the brush stroke painted no handle vertices"
    handle = np.asarray(c["handle_groups"][0], dtype=np.int64)
    assert not np.intersect1d(fixed, handle).size
    return fixed, handle


def drag_gizmo_x(page: Page, distance: float = 120.0) -> None:
    """Press the gizmo's X arrow (projected from the handle centroid) and drag it sideways."""
    gizmo = page.evaluate("() => window.__arap.gizmo()")
    assert gizmo is not None, "no gizmo on the handle group"
    cx, cy = gizmo["screen"]
    ax, ay = gizmo["axes"]["x"]
    d = np.array([ax - cx, ay - cy])
    d /= np.linalg.norm(d)
    page.mouse.move(ax, ay)
    page.mouse.down()
    for k in range(1, 13):
        page.mouse.move(ax + d[0] * distance * k / 12, ay + d[1] * distance * k / 12)
    page.mouse.up()
    wait_idle(page)


def test_loads_and_renders_default_model(page: Page, shoot: Shoot) -> None:
    state = page.evaluate("() => ({ name: __arap.meshName, n: __arap.nVertices, builtins: __arap.builtins })")
    assert state["builtins"], "welcome listed no built-in meshes"
    assert state["name"] == state["builtins"][0]
    assert state["n"] > 100
    expect(page.get_by_test_id("conn-text")).to_have_text("connected")
    expect(page.get_by_test_id("mesh-info")).to_contain_text(f"{state['n']:,} vertices")
    expect(page.locator("#st-vertices")).to_have_text(f"{state['n']:,}")
    wait_idle(page)
    shoot("01-default-model")
    px = canvas_pixels(page)
    covered = 1.0 - background_mask(px).mean()
    assert covered > 0.03, f"only {covered:.1%} of the view differs from the background"
    # the model is in the middle of the view after fit-to-view
    h, w = px.shape[:2]
    centre = background_mask(px[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4])
    assert centre.mean() < 0.97


def test_select_drag_export_undo(page: Page, shoot: Shoot, tmp_path: Path) -> None:
    rest = positions(page)
    diag = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    fixed, handle = select_anchor_and_handle(page)
    counts = page.evaluate("() => window.__arap.counts()")
    assert counts["fixed"] == len(fixed) and counts["groups"][0] == len(handle)
    expect(page.get_by_test_id("group-list")).to_contain_text(f"{len(handle)} v")
    shoot("02-selection")
    before_px = canvas_pixels(page)
    ox, oy = canvas_origin(page)
    hp = screen_points(page)[handle] - (ox, oy)

    drag_gizmo_x(page)
    assert page.evaluate("() => window.__arap.lastSeq") > 0, "no drag was answered"
    assert page.evaluate("() => window.__arap.canUndo")
    shoot("03-dragged")
    moved = positions(page)
    handle_shift = np.linalg.norm(moved[handle] - rest[handle], axis=1)
    assert handle_shift.min() > 0.02 * diag, f"handle moved only {handle_shift.min():.4g} (diagonal {diag:.3g})"
    assert np.abs(moved[fixed] - rest[fixed]).max() < 1e-6, "anchors moved"
    free = np.setdiff1d(np.arange(len(rest)), np.concatenate([fixed, handle]))
    assert np.abs(moved[free] - rest[free]).max() > 1e-3 * diag, "the free vertices did not follow"

    # the picture changed where the handle was
    after_px = canvas_pixels(page)
    x0, y0 = np.floor(hp.min(axis=0) - 20).astype(int).clip(0)
    x1, y1 = np.ceil(hp.max(axis=0) + 20).astype(int)
    region = np.abs(after_px[y0:y1, x0:x1, :3].astype(int) - before_px[y0:y1, x0:x1, :3].astype(int))
    changed = int((region.max(axis=-1) > 40).sum())
    assert changed > 100, f"only {changed} pixels changed around the handle"

    # stats and the energy plot were fed by the solve
    expect(page.locator("#st-iter")).not_to_have_text("–")
    expect(page.locator("#st-latency")).not_to_have_text("–")

    # exported OBJ has the deformed shape
    with page.expect_download() as info:
        page.get_by_test_id("export-obj").click()
    download = info.value
    assert download.suggested_filename.endswith(".obj")
    obj_path = tmp_path / download.suggested_filename
    download.save_as(obj_path)
    exported = read_obj_vertices(obj_path)
    assert exported.shape == rest.shape
    assert np.abs(exported - moved).max() < 1e-4 * diag
    assert np.abs(exported[fixed] - rest[fixed]).max() < 1e-4 * diag
    assert np.linalg.norm(exported[handle] - rest[handle], axis=1).min() > 0.02 * diag

    # after the release the server settled the shape, and the statistics say so
    expect(page.get_by_test_id("settle-status")).to_have_attribute("data-status", "settled", timeout=scaled_ms(30))
    expect(page.get_by_test_id("settle-status")).to_contain_text("settled")

    # undo restores the rest pose, redo (keyboard) the deformation
    page.get_by_test_id("undo").click()
    page.wait_for_function("() => window.__arap.canRedo === true")
    wait_idle(page)
    assert np.abs(positions(page) - rest).max() < 1e-6
    shoot("04-undone")
    page.locator("#view").focus()
    page.keyboard.press("Control+Shift+Z")
    page.wait_for_function("() => window.__arap.canRedo === false")
    wait_idle(page)
    assert np.abs(positions(page) - moved).max() < 1e-6
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def test_constraints_file_round_trip(page: Page, tmp_path: Path, shoot: Shoot) -> None:
    rest = positions(page)
    order = np.argsort(rest[:, 1])
    k = max(1, len(rest) // 20)
    doc = {"fixed": sorted(order[:k].tolist()), "handles": sorted(order[-k:].tolist()),
           "targets": rest[np.sort(order[-k:])].tolist()}
    path = tmp_path / "cli-constraints.json"
    path.write_text(json.dumps(doc))
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    page.wait_for_function(f"() => window.__arap.counts().fixed === {k}")
    wait_idle(page)
    counts = page.evaluate("() => window.__arap.counts()")
    assert counts["groups"] == [k]
    shoot("05-constraints-loaded")

    drag_gizmo_x(page, 80)
    assert page.evaluate("() => window.__arap.lastSeq") > 0

    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    assert info.value.suggested_filename.endswith(".json")
    saved_path = tmp_path / info.value.suggested_filename
    info.value.save_as(saved_path)
    saved = json.loads(saved_path.read_text())
    assert sorted(saved["fixed"]) == doc["fixed"]
    assert sorted(saved["handle_groups"][0]) == doc["handles"]
    targets = np.asarray(saved["targets"])[: len(doc["handles"])]
    assert np.abs(targets - rest[saved["handles"][: len(doc["handles"])]]).max() > 0, "targets do not show the drag"

    # a document that does not parse is reported, and the selection stays
    bad = tmp_path / "broken.json"
    bad.write_text("{not json")
    page.get_by_test_id("constraints-input").set_input_files(str(bad))
    expect(page.get_by_test_id("statusbar")).to_be_visible()
    expect(page.get_by_test_id("status-text")).to_contain_text("broken.json")
    assert page.evaluate("() => window.__arap.counts().fixed") == k


def test_constraints_file_targets_move_the_handles(page: Page, tmp_path: Path) -> None:
    rest = positions(page)
    order = np.argsort(rest[:, 1])
    k = max(1, len(rest) // 20)
    fixed, handles = np.sort(order[:k]), np.sort(order[-k:])
    shift = 0.1 * np.ptp(rest, axis=0).max() * np.array([1.0, 0.5, 0.0])
    targets = rest[handles] + shift
    path = tmp_path / "cli-targets.json"
    path.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": targets.tolist()}))
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    page.wait_for_function(f"() => window.__arap.counts().fixed === {k}")
    wait_idle(page)
    U = positions(page)
    np.testing.assert_allclose(U[handles], targets, atol=1e-4)
    np.testing.assert_array_equal(U[fixed], rest[fixed])
    np.testing.assert_allclose(page.evaluate("() => window.__arap.gizmo().centroid"), targets.mean(axis=0),
                               atol=1e-4)
    assert page.evaluate("() => window.__arap.canUndo")

    # a file saved by the studio restores the groups and the deformation
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    saved = tmp_path / "saved.json"
    info.value.save_as(saved)
    page.get_by_test_id("reset").click()
    page.wait_for_function("() => !window.__arap.busy")
    page.wait_for_function(f"() => window.__arap.positions()[{3 * int(handles[0])}] === {float(rest[handles[0], 0])}")
    wait_idle(page)
    np.testing.assert_array_equal(positions(page)[handles], rest[handles])
    page.get_by_test_id("constraints-input").set_input_files(str(saved))
    page.wait_for_function(
        f"() => Math.abs(window.__arap.positions()[{3 * int(handles[0])}] - {float(targets[0, 0])}) < 1e-4")
    wait_idle(page)
    np.testing.assert_allclose(positions(page)[handles], targets, atol=1e-4)
    c = page.evaluate("() => window.__arap.constraints()")
    assert c["handle_groups"] == [handles.tolist()] and c["fixed"] == fixed.tolist()
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


@pytest.mark.parametrize(("stiffness", "message"), [
    ([2.0, 2.0, 1.0], "lists one value per vertex"),
    ("per-vertex-zero", "stiffness[3]"),
    ([{"vertices": [10**6], "value": 5}], "vertex 1000000"),
    ([{"vertices": [3, 4], "value": 5}, {"vertices": [4], "value": "rigid"}], "vertex 4 is given two stiffness"),
])
def test_constraints_file_with_bad_stiffness_is_refused(page: Page, tmp_path: Path, stiffness: object,
                                                        message: str) -> None:
    """Painted stiffness that arap deform refuses is not loaded in part: the file is reported, nothing changes."""
    n = len(positions(page))
    if stiffness == "per-vertex-zero":
        stiffness = [1.0] * n
        stiffness[3] = 0  # type: ignore[index]
    path = tmp_path / "stiff.json"
    path.write_text(json.dumps({"version": 2, "fixed": [0, 1], "stiffness": stiffness}))
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    expect(page.get_by_test_id("status-text")).to_contain_text("stiff.json")
    expect(page.get_by_test_id("status-text")).to_contain_text(message)
    assert page.evaluate("() => window.__arap.counts().fixed") == 0
    assert page.evaluate("() => window.__arap.constraints().stiffness") is None


def test_upload_obj_with_file_input(page: Page, tmp_path: Path, shoot: Shoot) -> None:
    text, n = sphere_obj(2)
    path = tmp_path / "small_sphere.obj"
    path.write_text(text)
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.meshName === 'small_sphere'")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.nVertices") == n
    expect(page.get_by_test_id("mesh-info")).to_contain_text("small_sphere")
    # the steps of the upload, marked on the wall clock as the page went through them (bench_client prints them)
    page.wait_for_function("() => window.__arap.uploadAt.drawn !== undefined")
    at = page.evaluate("() => window.__arap.uploadAt")
    steps = ["chosen", "read", "sent", "received", "shown", "drawn"]
    assert [at[k] for k in steps] == sorted(at[k] for k in steps)
    assert at["shown"] - at["received"] == pytest.approx(page.evaluate("() => window.__arap.meshMs"), abs=1)
    shoot("06-uploaded")
    assert 1.0 - background_mask(canvas_pixels(page)).mean() > 0.03


def test_upload_by_drag_and_drop(page: Page) -> None:
    text, n = sphere_obj(1)
    transfer = page.evaluate_handle(
        """(text) => {
            const dt = new DataTransfer();
            dt.items.add(new File([text], 'dropped.obj', { type: 'text/plain' }));
            return dt;
        }""",
        text,
    )
    page.dispatch_event("#viewport", "dragenter", {"dataTransfer": transfer})
    expect(page.locator("#drop-overlay")).to_be_visible()
    page.dispatch_event("#viewport", "drop", {"dataTransfer": transfer})
    page.wait_for_function("() => window.__arap.meshName === 'dropped'")
    expect(page.locator("#drop-overlay")).to_be_hidden()
    assert page.evaluate("() => window.__arap.nVertices") == n


def test_oversized_upload_is_refused_with_a_message(page: Page, tmp_path: Path, shoot: Shoot) -> None:
    name = page.evaluate("() => window.__arap.meshName")
    assert page.evaluate("() => window.__arap.limits.max_upload_bytes") == MAX_UPLOAD_BYTES
    text, _ = sphere_obj(1)
    path = tmp_path / "huge.obj"
    path.write_text(text + "# padding\n" * (MAX_UPLOAD_BYTES // 10 + 1))
    assert path.stat().st_size > MAX_UPLOAD_BYTES
    page.get_by_test_id("file-input").set_input_files(str(path))
    bar = page.get_by_test_id("statusbar")
    expect(bar).to_be_visible()
    expect(page.get_by_test_id("status-text")).to_contain_text("too large")
    shoot("07-oversized-upload")
    assert page.evaluate("() => window.__arap.meshName") == name
    page.get_by_test_id("status-close").click()
    expect(bar).to_be_hidden()


def test_unreadable_upload_reports_the_server_error(page: Page, tmp_path: Path) -> None:
    name = page.evaluate("() => window.__arap.meshName")
    path = tmp_path / "garbage.off"
    path.write_text("this is not an OFF file\n")
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.errors.length > 0")
    errors = page.evaluate("() => window.__arap.errors")
    assert errors[-1]["code"] == "bad_mesh" and errors[-1]["request"] == "upload"
    expect(page.get_by_test_id("statusbar")).to_be_visible()
    wait_idle(page)
    assert page.evaluate("() => window.__arap.meshName") == name


def test_selection_tools_and_groups(page: Page, shoot: Shoot) -> None:
    n = page.evaluate("() => window.__arap.nVertices")
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    mid = pts[np.abs(pts[:, 1] - (ymin + ymax) / 2) < 0.02 * (ymax - ymin)]
    mx, my = mid.mean(axis=0)
    top = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)].mean(axis=0)
    counts = "() => window.__arap.counts()"

    # region of interest: brush, Ctrl+brush subtracts, invert, clear
    page.get_by_test_id("role-roi").click()
    paint_stroke(page, mx, my, 30)
    wait_idle(page)
    painted = page.evaluate(counts)["roi"]
    assert 0 < painted < n
    page.keyboard.down("Control")
    paint_stroke(page, mx, my, 2)
    page.keyboard.up("Control")
    wait_idle(page)
    roi = page.evaluate(counts)["roi"]
    assert 0 < roi < painted
    expect(page.get_by_test_id("sel-counts")).to_contain_text(f"ROI: {roi:,}")
    page.get_by_test_id("invert-role").click()
    wait_idle(page)
    assert page.evaluate(counts)["roi"] == n - roi
    page.get_by_test_id("clear-role").click()
    wait_idle(page)
    assert page.evaluate(counts)["roi"] == 0
    expect(page.get_by_test_id("sel-counts")).to_contain_text("whole mesh")

    # two handle groups with their own colours; the box tool fills the second
    page.get_by_test_id("role-handle").click()
    paint_stroke(page, top[0] - 6, top[1] + 8)
    wait_idle(page)
    page.get_by_test_id("new-group").click()
    page.get_by_test_id("tool-box").click()
    page.mouse.move(mx - 15, my - 15)
    page.mouse.down()
    page.mouse.move(mx + 15, my + 15, steps=5)
    page.mouse.up()
    wait_idle(page)
    groups = page.evaluate(counts)["groups"]
    assert len(groups) == 2 and min(groups) > 0
    swatches = page.locator("#group-list .swatch")
    expect(swatches).to_have_count(2)
    colours = [swatches.nth(i).evaluate("e => getComputedStyle(e).backgroundColor") for i in range(2)]
    assert colours[0] != colours[1]
    server = page.evaluate("() => window.__arap.constraints()")
    assert [len(g) for g in server["handle_groups"]] == groups
    shoot("08-two-groups")

    # the eraser clears any role
    page.get_by_test_id("tool-brush").click()
    page.get_by_test_id("role-erase").click()
    paint_stroke(page, top[0] - 6, top[1] + 8)
    wait_idle(page)
    assert page.evaluate(counts)["groups"][0] < groups[0]
    assert not page.evaluate("() => window.__arap.errors")


def test_solver_parameters_and_gizmo_modes(page: Page) -> None:
    page.get_by_test_id("energy").select_option("spokes")
    page.wait_for_function("() => window.__arap.params.energy === 'spokes'")
    page.get_by_test_id("weights").select_option("uniform")
    page.wait_for_function("() => window.__arap.params.weights === 'uniform'")
    page.get_by_test_id("iterations").evaluate(
        "e => { e.value = '7'; e.dispatchEvent(new Event('input')); e.dispatchEvent(new Event('change')); }"
    )
    page.wait_for_function("() => window.__arap.params.iterations === 7")
    expect(page.locator("#iterations-val")).to_have_text("7")

    select_anchor_and_handle(page)
    page.locator("#view").focus()
    page.keyboard.press("e")
    assert page.evaluate("() => window.__arap.gizmo().mode") == "rotate"
    expect(page.get_by_test_id("gizmo-rotate")).to_have_class("active")
    page.keyboard.press("w")
    assert page.evaluate("() => window.__arap.gizmo().mode") == "translate"
    drag_gizmo_x(page, 60)
    header = page.evaluate("() => window.__arap.lastSeq")
    assert header > 0
    assert not page.evaluate("() => window.__arap.errors")


def test_the_panel_does_not_scroll_sideways(page: Page) -> None:
    """Every control of the side panel fits its width (the panel scrolls only up and down)."""
    layout = page.evaluate(
        """() => {
            const panel = document.getElementById('panel');
            const right = panel.getBoundingClientRect().left + panel.clientLeft + panel.clientWidth;
            const out = [];
            for (const el of panel.querySelectorAll('select, input, button')) {
                const r = el.getBoundingClientRect();
                if (r.width && r.right > right + 0.5) out.push(`${el.id || el.dataset.testid} ends at ${r.right}`);
            }
            return { out, right, scrollWidth: panel.scrollWidth, clientWidth: panel.clientWidth };
        }"""
    )
    assert not layout["out"], f"past the panel's right edge ({layout['right']}): {layout['out']}"
    assert layout["scrollWidth"] <= layout["clientWidth"], layout
