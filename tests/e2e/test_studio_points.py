"""The studio's point-handle mode and stiffness brush with real mouse input: a click places a point handle that
the gizmo drags and the settled shape meets; painted stiffness reaches the server and stiffens the shape; both
travel through a saved constraints file into a fresh page."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from playwright.sync_api import Browser, Page, expect

from tests.e2e.conftest import VIEWPORT, positions, screen_points, wait_idle, wait_ready, wait_settled
from tests.e2e.test_session_safety import Dialogs, wait_autosaved
from tests.e2e.test_studio import Shoot, box_select, drag_gizmo_x, paint_stroke

pytestmark = pytest.mark.e2e


def _diag(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def _faces(page: Page) -> np.ndarray:
    return np.asarray(page.evaluate("() => window.__arap.faces()"), dtype=np.int64).reshape(-1, 3)


def _anchor_bottom(page: Page) -> np.ndarray:
    """Box-select anchors at the bottom of the model; returns the screen points of every vertex."""
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    xmin, xmax = pts[:, 0].min(), pts[:, 0].max()
    page.get_by_test_id("role-fixed").click()
    box_select(page, xmin - 10, ymax - 0.12 * (ymax - ymin), xmax + 10, ymax + 10)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0
    return pts


def _place_point(page: Page, pts: np.ndarray) -> dict:
    """Click the surface near the top of the model in point-handle mode; returns the new point handle."""
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    top = pts[pts[:, 1] <= ymin + 0.08 * (ymax - ymin)]
    x, y = np.median(top, axis=0)
    page.keyboard.press("5")
    assert page.evaluate("() => window.__arap.role") == "point"
    page.mouse.click(x, y + 4)
    wait_idle(page)
    handles = [h for h in page.evaluate("() => window.__arap.pointHandles()") if h]
    assert len(handles) == 1, "the click placed no point handle"
    return handles[0]


def _saved_document(page: Page, tmp_path: Path, name: str) -> tuple[dict, Path]:
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    path = tmp_path / name
    info.value.save_as(path)
    return json.loads(path.read_text()), path


def _on_surface(U: np.ndarray, F: np.ndarray, point: dict) -> np.ndarray:
    return np.asarray(point["barycentric"]) @ U[F[point["face"]]]


def test_a_clicked_point_handle_is_dragged_and_met(page: Page, tmp_path: Path, browser: Browser,
                                                   server_url: str, shoot: Shoot) -> None:
    rest = positions(page)
    F = _faces(page)
    diag = _diag(rest)
    pts = _anchor_bottom(page)
    handle = _place_point(page, pts)
    point = handle["point"]
    assert abs(sum(point["barycentric"]) - 1) < 1e-12 and min(point["barycentric"]) >= 0
    assert point["weight"] is None
    c = page.evaluate("() => window.__arap.constraints()")
    assert c["points"] == [{"face": point["face"], "barycentric": point["barycentric"]}]
    # placing it was one undo step
    page.keyboard.press("Control+Z")
    page.wait_for_function("() => window.__arap.constraints().points.length === 0")
    wait_idle(page)
    page.keyboard.press("Control+Shift+Z")
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.constraints()") == c
    gizmo = page.evaluate("() => window.__arap.gizmo()")
    assert gizmo is not None and gizmo["group"] == page.evaluate("() => window.__arap.activeGroup")
    np.testing.assert_allclose(gizmo["centroid"], _on_surface(rest, F, point), atol=1e-5 * diag)

    shoot("points-01-placed")
    drag_gizmo_x(page)
    assert page.evaluate("() => window.__arap.lastSeq") > 0, "no drag was answered"
    wait_settled(page)
    shoot("points-02-dragged")
    U = positions(page)
    doc, saved = _saved_document(page, tmp_path, "points.json")
    assert doc["version"] == 2 and len(doc["points"]) == 1
    target = np.asarray(doc["points"][0]["target"])
    moved = np.linalg.norm(target - _on_surface(rest, F, point))
    assert moved > 0.02 * diag, f"the point's target moved only {moved:.3g}"
    assert np.abs(_on_surface(U, F, point) - target).max() < 1e-5 * diag, "the shape misses the point target"
    marker = page.evaluate("() => window.__arap.pointHandles()")[handle_index(page)]["screen"]
    expected = page.evaluate("(p) => window.__arap.project(p)", target.tolist())
    assert np.hypot(marker[0] - expected[0], marker[1] - expected[1]) < 2.0, "the marker did not follow the surface"

    # the saved file puts the point handle and the shape back in a fresh page
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    fresh = context.new_page()
    try:
        fresh.goto(server_url)
        wait_ready(fresh)
        fresh.get_by_test_id("constraints-input").set_input_files(str(saved))
        fresh.wait_for_function("() => window.__arap.constraints().points.length === 1")
        wait_idle(fresh)
        wait_settled(fresh)
        assert fresh.evaluate("() => window.__arap.constraints().points") == c["points"]
        assert np.abs(positions(fresh) - U).max() < 1e-4 * diag
        assert not fresh.evaluate("() => window.__arap.errors"), "the server reported errors"
    finally:
        context.close()

    # Ctrl+click on the marker removes it
    x, y = page.evaluate("() => window.__arap.pointHandles()")[handle_index(page)]["screen"]
    page.keyboard.down("Control")
    page.mouse.click(x, y)
    page.keyboard.up("Control")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.constraints().points") == []
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def handle_index(page: Page) -> int:
    return next(k for k, h in enumerate(page.evaluate("() => window.__arap.pointHandles()")) if h)


def test_painted_stiffness_reaches_the_server_and_stiffens(page: Page, tmp_path: Path, browser: Browser,
                                                           server_url: str) -> None:
    rest = positions(page)
    diag = _diag(rest)
    pts = _anchor_bottom(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    top = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)]
    page.get_by_test_id("role-handle").click()
    tx, ty = top.mean(axis=0)
    paint_stroke(page, tx - 6, ty + 8)
    wait_idle(page)
    middle = np.flatnonzero(np.abs(pts[:, 1] - (ymin + 0.5 * (ymax - ymin))) < 0.2 * (ymax - ymin))

    drag_gizmo_x(page)
    wait_settled(page)
    soft = positions(page)
    page.get_by_test_id("undo").click()
    page.wait_for_function("() => window.__arap.canRedo === true")
    wait_idle(page)

    # paint the middle rigid with the mouse (three strokes across it)
    page.keyboard.press("6")
    page.get_by_test_id("stiffness-rigid").check()
    assert page.evaluate("() => window.__arap.role") == "stiffness"
    xs = pts[middle, 0]
    y0, y1 = pts[middle, 1].min(), pts[middle, 1].max()
    for y in np.linspace(y0, y1, int(np.ceil((y1 - y0) / 24)) + 1):
        page.mouse.move(xs.min(), y)
        page.mouse.down()
        page.mouse.move(xs.max(), y, steps=8)
        page.mouse.up()
    wait_idle(page)
    stiffness = page.evaluate("() => window.__arap.constraints().stiffness")
    assert stiffness and stiffness[-1]["value"] == "rigid" and len(stiffness[-1]["vertices"]) > 10
    painted = np.asarray(stiffness[-1]["vertices"])
    doc, saved = _saved_document(page, tmp_path, "stiff.json")
    assert doc["version"] == 2 and doc["stiffness"] == stiffness, "the server does not hold the paint"

    drag_gizmo_x(page)
    wait_settled(page)
    stiff = positions(page)

    def misfit(U: np.ndarray) -> float:
        """How far the painted vertices are from a rigid motion of their rest positions."""
        A, B = rest[painted] - rest[painted].mean(0), U[painted] - U[painted].mean(0)
        u, _, vt = np.linalg.svd(A.T @ B)
        R = (u @ vt).T
        return float(np.abs(A @ R.T - B).max())

    assert misfit(stiff) < 0.2 * misfit(soft), (misfit(stiff), misfit(soft))
    assert misfit(stiff) < 1e-4 * diag

    # the eraser paints back to 1
    page.get_by_test_id("undo").click()  # back at rest, where the strokes were painted
    page.wait_for_function("() => window.__arap.canRedo === true")
    wait_idle(page)
    page.get_by_test_id("stiffness-erase").check()
    inside = pts[painted]
    x, y = inside[np.argmin(np.linalg.norm(inside - np.median(inside, axis=0), axis=1))]
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 6, y + 3, steps=4)
    page.mouse.up()
    wait_idle(page)
    after = page.evaluate("() => window.__arap.constraints().stiffness")
    assert sum(len(g["vertices"]) for g in after or []) < len(painted)

    # a fresh page loads the saved paint
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    fresh = context.new_page()
    try:
        fresh.goto(server_url)
        wait_ready(fresh)
        fresh.get_by_test_id("constraints-input").set_input_files(str(saved))
        fresh.wait_for_function("() => (window.__arap.constraints().stiffness || []).length > 0")
        wait_idle(fresh)
        assert fresh.evaluate("() => window.__arap.constraints().stiffness") == stiffness
        assert not fresh.evaluate("() => window.__arap.errors"), "the server reported errors"
    finally:
        context.close()
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def test_point_handles_and_paint_are_autosaved_and_restored(page: Page) -> None:
    pts = _anchor_bottom(page)
    page.keyboard.press("6")
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    band = pts[np.abs(pts[:, 1] - (ymin + 0.5 * (ymax - ymin))) < 0.02 * (ymax - ymin)]
    x, y = band[np.argmin(np.linalg.norm(band - np.median(band, axis=0), axis=1))]
    paint_stroke(page, x, y)
    wait_idle(page)
    expect(page.locator("#point-weight")).to_be_hidden()  # each mode shows its own settings
    page.keyboard.press("5")
    expect(page.get_by_test_id("stiffness-row")).to_be_hidden()
    page.locator("#point-weight").fill("25")
    page.locator("#point-weight").press("Enter")  # takes the weight and gives the keys back to the shortcuts
    _place_point(page, pts)
    before = page.evaluate("() => window.__arap.constraints()")
    assert before["stiffness"] and before["stiffness"][0]["value"] == 10
    assert len(before["points"]) == 1 and before["points"][0]["weight"] == 25
    expect(page.get_by_test_id("group-list")).to_contain_text("soft 25")
    wait_autosaved(page)
    Dialogs(page, accept=True)  # the warning before unloading
    page.reload()
    wait_ready(page)
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    wait_ready(page)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.constraints()") == before
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def test_an_energy_the_paint_rules_out_is_refused_and_the_menu_shows_the_one_in_use(
        page: Page, tmp_path: Path, shared_meshes_dir: Path) -> None:
    """On a scan with obtuse triangles, the paper's spokes energy has no minimum with a rigid band: switching to it
    is refused with the reason, and the energy menu goes back to the energy the server still uses."""
    page.get_by_test_id("file-input").set_input_files(str(shared_meshes_dir / "decimated-knight.off"))
    page.wait_for_function("() => window.__arap.meshName === 'decimated-knight'")
    wait_ready(page)
    rest = positions(page)
    y = rest[:, 1]
    order = np.argsort(y)
    k = len(rest) // 10
    middle = np.flatnonzero(np.abs(y - np.median(y)) < 0.1 * np.ptp(y))
    doc = {"version": 2, "fixed": sorted(order[:k].tolist()), "handles": sorted(order[-k:].tolist()),
           "stiffness": [{"vertices": middle.tolist(), "value": "rigid"}]}
    path = tmp_path / "knight-rigid.json"
    path.write_text(json.dumps(doc))
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    page.wait_for_function(f"() => window.__arap.counts().fixed === {k}")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.constraints().stiffness")
    assert page.evaluate("() => window.__arap.params.energy") == "spokes_and_rims"

    page.get_by_test_id("energy").select_option("spokes")
    page.wait_for_function("() => window.__arap.errors.length > 0")
    expect(page.get_by_test_id("status-text")).to_contain_text("spokes_and_rims")
    expect(page.get_by_test_id("energy")).to_have_value("spokes_and_rims")
    assert page.evaluate("() => window.__arap.params.energy") == "spokes_and_rims"
    # the session goes on with the energy in use
    page.get_by_test_id("energy").select_option("smooth_rotations")  # spoke cells too: refused the same way
    page.wait_for_function("() => window.__arap.errors.length > 1")
    expect(page.get_by_test_id("energy")).to_have_value("spokes_and_rims")


def test_a_refused_point_handle_leaves_the_selection_and_its_error_goes(page: Page) -> None:
    """A point handle on a triangle whose corners are all anchors cannot move: the server refuses it; the page drops
    it (saying which), later edits go through, and the error goes once the server accepts a new selection."""
    _anchor_bottom(page)
    fixed = set(page.evaluate("() => window.__arap.constraints().fixed"))
    F = _faces(page)
    V = positions(page)
    held = np.asarray([all(int(i) in fixed for i in f) for f in F])
    centres = V[F[held]].mean(axis=1)
    on_screen = np.asarray([page.evaluate("(p) => window.__arap.project(p)", c.tolist()) for c in centres])
    x, y = on_screen[np.argmin(np.linalg.norm(on_screen - np.median(on_screen, axis=0), axis=1))]
    page.keyboard.press("5")
    page.mouse.click(x, y)
    page.wait_for_function("() => window.__arap.errors.length > 0")
    wait_idle(page)
    errors = page.evaluate("() => window.__arap.errors")
    assert [(e["code"], e["request"]) for e in errors] == [("bad_constraints", "set_constraints")], errors
    assert page.evaluate("() => window.__arap.constraints().points") == [], "the refused point stayed"
    status = page.get_by_test_id("status-text")
    expect(status).to_contain_text("Removed point 1")
    expect(status).to_contain_text("anchor")

    # the rest of the session goes on: a handle, a drag, no further refusal
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    tx, ty = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)].mean(axis=0)
    page.get_by_test_id("role-handle").click()
    paint_stroke(page, tx - 6, ty + 8)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().groups[0]") > 0
    expect(page.get_by_test_id("statusbar")).to_be_hidden()  # the server accepted a new selection
    drag_gizmo_x(page)
    wait_settled(page)
    assert page.evaluate("() => window.__arap.lastSeq") > 0, "no drag was answered"
    assert len(page.evaluate("() => window.__arap.errors")) == 1
    expect(page.get_by_test_id("statusbar")).to_be_hidden()


def _two_spheres(tmp_path: Path) -> Path:
    mesh = trimesh.creation.icosphere(subdivisions=2)
    shift = np.array([1.5, 0.0, 0.0])
    V = np.vstack([mesh.vertices - shift, mesh.vertices + shift])
    F = np.vstack([mesh.faces, mesh.faces + len(mesh.vertices)])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in V] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path = tmp_path / "pair.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_refused_selection_is_explained_where_it_matters_and_the_error_clears(page: Page, tmp_path: Path) -> None:
    """On two separate spheres a handle on one alone leaves the other free and unpinned: with loose parts set to
    refuse, the server refuses the set. A drag then says why on its own; anchoring the other sphere is accepted and
    takes the error away."""
    page.get_by_test_id("file-input").set_input_files(str(_two_spheres(tmp_path)))
    page.wait_for_function("() => window.__arap.meshName === 'pair'")
    wait_idle(page)
    page.get_by_test_id("loose").select_option("error")  # loose parts follow by default: ask to be told instead
    wait_idle(page)
    pts = screen_points(page)
    n = len(pts) // 2
    left, right = pts[:n].mean(axis=0), pts[n:].mean(axis=0)
    page.get_by_test_id("role-handle").click()
    paint_stroke(page, left[0] - 6, left[1])
    page.wait_for_function("() => window.__arap.errors.length > 0")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.errors")[0]["code"] == "bad_constraints"
    refusal = page.evaluate("() => window.__arap.errors")[0]["message"]
    status = page.get_by_test_id("status-text")
    expect(status).to_contain_text(refusal)
    assert page.evaluate("() => window.__arap.counts().groups[0]") > 0, "the handle stays for the user to fix"

    page.get_by_test_id("status-close").click()
    drag_gizmo_x(page)
    expect(status).to_contain_text("Cannot drag: the server refused the current selection")
    expect(status).to_contain_text(refusal)  # the reason, not "see the previous message"
    assert page.evaluate("() => window.__arap.lastSeq") < 0, "a drag was sent"

    page.get_by_test_id("role-fixed").click()
    paint_stroke(page, right[0] - 6, right[1])
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0
    expect(page.get_by_test_id("statusbar")).to_be_hidden()
    assert len(page.evaluate("() => window.__arap.errors")) == 1
    drag_gizmo_x(page)
    assert page.evaluate("() => window.__arap.lastSeq") > 0, "no drag was answered"


@pytest.mark.parametrize("typed", ["1e", "--2"])
def test_a_point_weight_that_is_no_number_is_refused_visibly(page: Page, typed: str) -> None:
    """Text that is no number leaves the field empty and sends no change: it is refused with a message, not
    taken as a hard handle."""
    page.keyboard.press("5")
    field = page.get_by_test_id("point-weight")
    field.click()
    page.keyboard.type(typed)
    assert page.evaluate("() => document.getElementById('point-weight').validity.badInput")
    page.keyboard.press("Enter")
    expect(page.get_by_test_id("status-text")).to_contain_text("Point weight must be a positive number")
    expect(field).to_have_value("")
    assert not page.evaluate("() => document.getElementById('point-weight').validity.badInput")
