"""Mirror editing in headless Chromium with real mouse and keyboard input: the mirror plane and the vertex
correspondence are found on symmetric meshes (also about a tilted plane away from the origin) and not on an
asymmetric one, the brush paints both sides, a handle group painted on one side gets a partner on the other, and
dragging it sends the mirrored transform so that the settled shape is symmetric."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect
from scipy.spatial.transform import Rotation

from arap.meshes import shapes
from tests.e2e.conftest import positions, wait_idle, wait_settled
from tests.e2e.test_session_safety import reload_and_restore
from tests.e2e.test_studio import box_select, drag_gizmo_x

pytestmark = pytest.mark.e2e


def symmetric_mesh() -> tuple[np.ndarray, np.ndarray]:
    """A warped sphere, exactly symmetric about the plane x = 0 and about no other plane."""
    V, F = shapes.sphere(frequency=10)
    W = np.column_stack([1.3 * V[:, 0], 0.8 * V[:, 1] + 0.35 * (V[:, 2] + 0.5) ** 2, V[:, 2]])
    return W, F


def asymmetric_mesh() -> tuple[np.ndarray, np.ndarray]:
    """A noisy ellipsoid (nearly symmetric by itself) bent and twisted out of every mirror symmetry."""
    B, F = shapes.scan_blob(0, n=600)
    x, y, z = B.T
    return np.column_stack([x + 0.3 * (y + 0.4) ** 2, y, z + 0.25 * (y + 0.2) ** 3 + 0.2 * x * y]), F


def mirror_pairs(V: np.ndarray) -> np.ndarray:
    """The vertex at (-x, y, z) of each vertex (every vertex has one)."""
    key = {tuple(v): i for i, v in enumerate(V)}
    out = np.asarray([key.get((-v[0], v[1], v[2]), -1) for v in V])
    assert (out >= 0).all()
    return out


def upload(page: Page, tmp_path: Path, name: str, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in V.tolist()] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path = tmp_path / f"{name}.obj"
    path.write_text("\n".join(lines) + "\n")
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function(f"() => window.__arap.meshName === {name!r}")
    wait_idle(page)
    shown = positions(page)
    assert shown.shape == V.shape
    return shown


def mirror_state(page: Page) -> dict:
    return page.evaluate("() => window.__arap.mirror()")


def press_mirror(page: Page) -> dict:
    page.keyboard.press("m")
    wait_idle(page)
    return mirror_state(page)


def reflect(P: np.ndarray, plane: dict) -> np.ndarray:
    n = np.asarray(plane["normal"])
    p0 = np.asarray(plane["point"])
    return P - 2.0 * ((P - p0) @ n)[:, None] * n


def paint_at(page: Page, point: np.ndarray) -> None:
    """One dab of the brush (a click) on a point of the mesh."""
    x, y = page.evaluate("(p) => window.__arap.project(p)", point.tolist())
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.up()
    wait_idle(page)


def front_point(V: np.ndarray, x: float) -> np.ndarray:
    """A vertex facing the camera (large z) near the given x."""
    near = np.abs(V[:, 0] - x) < 0.15
    return V[np.flatnonzero(near)[np.argmax(V[near, 2])]]


def test_plane_and_correspondence_found_or_refused(page: Page, tmp_path: Path) -> None:
    V, F = symmetric_mesh()
    expected = mirror_pairs(V)
    upload(page, tmp_path, "warped", V, F)
    assert mirror_state(page)["mirrorOf"] is None, "the plane is found only when mirror editing is turned on"
    m = press_mirror(page)
    assert m["on"] and m["active"] and m["visible"]
    assert m["plane"]["normal"] == [1, 0, 0]
    assert abs(m["plane"]["point"][0]) < 1e-12
    assert m["matched"] == 1.0
    mirror_of = np.asarray(m["mirrorOf"])
    np.testing.assert_array_equal(mirror_of, expected)
    np.testing.assert_array_equal(mirror_of[mirror_of], np.arange(len(V)))
    expect(page.get_by_test_id("mirror-status")).to_contain_text("symmetric: 100% of the vertices matched")
    assert m["ms"] < 2000

    # the same mesh turned and moved: the plane is tilted and away from the origin (found by the principal axes)
    R = Rotation.from_euler("xyz", [0.3, 0.7, -0.4]).as_matrix()
    t = np.array([0.5, -2.0, 3.0])
    shown = upload(page, tmp_path, "tilted", V @ R.T + t, F)
    m = mirror_state(page)
    assert m["on"] and m["active"], "mirror editing stays on for a new mesh with a plane"
    normal = np.asarray(m["plane"]["normal"])
    assert abs(abs(normal @ R[:, 0]) - 1) < 1e-9
    assert abs(normal @ (np.asarray(m["plane"]["point"]) - t)) < 1e-5
    mirror_of = np.asarray(m["mirrorOf"])
    np.testing.assert_array_equal(mirror_of, expected)
    diag = np.linalg.norm(np.ptp(shown, axis=0))
    assert np.abs(reflect(shown, m["plane"]) - shown[mirror_of]).max() < 1e-5 * diag

    # approximately symmetric (noise of a few thousandths of the diagonal): found with a larger tolerance
    noisy = V + np.random.default_rng(1).normal(scale=0.004, size=V.shape)
    shown = upload(page, tmp_path, "noisy", noisy, F)
    m = mirror_state(page)
    diag = np.linalg.norm(np.ptp(shown, axis=0))
    assert m["active"] and m["matched"] >= 0.9 and m["tolerance"] > 2e-3 * diag
    assert abs(abs(m["plane"]["normal"][0]) - 1) < 1e-4
    mirror_of = np.asarray(m["mirrorOf"])
    matched = mirror_of >= 0
    np.testing.assert_array_equal(mirror_of[mirror_of[matched]], np.flatnonzero(matched))
    assert (mirror_of[matched] == expected[matched]).all()

    # an asymmetric shape (a scanned ellipsoid, bent and twisted): no plane, mirror editing goes off until an axis
    # plane is picked
    B, FB = asymmetric_mesh()
    upload(page, tmp_path, "blob", B, FB)
    m = mirror_state(page)
    assert not m["on"] and not m["active"] and not m["visible"] and m["plane"] is None
    assert m["matched"] < 0.9
    expect(page.get_by_test_id("mirror-status")).to_contain_text("no symmetry found")
    expect(page.get_by_test_id("statusbar")).to_be_visible()
    expect(page.get_by_test_id("status-text")).to_contain_text("No mirror symmetry found")
    assert not press_mirror(page)["on"], "auto detection keeps refusing"
    page.get_by_test_id("mirror-axis").select_option("x")
    page.get_by_test_id("mirror-on").check()
    m = mirror_state(page)
    assert m["on"] and m["active"] and m["axis"] == "x" and m["plane"]["normal"] == [1, 0, 0]
    expect(page.get_by_test_id("mirror-status")).to_contain_text("partly symmetric")
    assert not page.evaluate("() => window.__arap.errors")


def test_brush_paints_both_sides_with_mirror_on(page: Page, tmp_path: Path) -> None:
    V, F = symmetric_mesh()
    upload(page, tmp_path, "warped", V, F)
    target = front_point(V, 0.7)
    page.get_by_test_id("brush-units").select_option("world")
    page.get_by_test_id("brush-radius").fill("6")  # 6% of the diagonal: a few vertices
    page.get_by_test_id("role-roi").click()
    paint_at(page, target)
    alone = set(page.evaluate("() => window.__arap.constraints().roi"))
    assert len(alone) > 3 and all(V[i, 0] > 0.2 for i in alone), "with mirror off the brush paints one side"
    page.get_by_test_id("clear-all").click()
    wait_idle(page)

    m = press_mirror(page)
    mirror_of = np.asarray(m["mirrorOf"])
    paint_at(page, target)
    roi = set(page.evaluate("() => window.__arap.constraints().roi"))
    assert roi == alone | {int(mirror_of[i]) for i in alone}
    # Ctrl takes the region away on both sides again
    page.keyboard.down("Control")
    paint_at(page, target)
    page.keyboard.up("Control")
    assert page.evaluate("() => window.__arap.constraints().roi") is None

    # a handle group: its mirror image becomes a partner group
    page.get_by_test_id("role-handle").click()
    paint_at(page, target)
    c = page.evaluate("() => window.__arap.constraints()")
    assert len(c["handle_groups"]) == 2
    g0, g1 = (set(g) for g in c["handle_groups"])
    assert g0 == alone and g1 == {int(mirror_of[i]) for i in g0}
    assert page.evaluate("() => window.__arap.partners()") == [1, 0]
    expect(page.get_by_test_id("group-1")).to_contain_text("Group 2 ⇄ 1")
    # mirror off: a dab on the partner's side paints only that side, into the active group
    press_mirror(page)
    page.get_by_test_id("group-0").click()
    paint_at(page, front_point(V, -0.3))
    c = page.evaluate("() => window.__arap.constraints()")
    left = {i for i in c["handle_groups"][0] if V[i, 0] < 0}
    assert left and len(c["handle_groups"]) == 2
    assert set(c["handle_groups"][0]) == g0 | left and set(c["handle_groups"][1]) == g1 - left
    assert not page.evaluate("() => window.__arap.errors")


def test_dragging_a_group_moves_its_partner_mirrored(page: Page, tmp_path: Path) -> None:
    V, F = symmetric_mesh()
    shown = upload(page, tmp_path, "warped", V, F)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    m = press_mirror(page)
    mirror_of = np.asarray(m["mirrorOf"])
    pts = np.asarray([page.evaluate("(p) => window.__arap.project(p)", p) for p in shown.tolist()])
    bottom = pts[:, 1] > pts[:, 1].max() - 0.15 * np.ptp(pts[:, 1])
    page.get_by_test_id("role-fixed").click()
    box_select(page, pts[bottom, 0].min() - 10, pts[bottom, 1].min(), pts[:, 0].max() + 10, pts[:, 1].max() + 10)
    wait_idle(page)
    fixed = set(page.evaluate("() => window.__arap.constraints().fixed"))
    assert fixed and fixed == {int(mirror_of[i]) for i in fixed}, "mirrored box selection gives symmetric anchors"
    page.get_by_test_id("role-handle").click()
    paint_at(page, front_point(V, 0.7))
    assert page.evaluate("() => window.__arap.partners()") == [1, 0]

    drag_gizmo_x(page)
    wait_settled(page)
    transforms = np.asarray(page.evaluate("() => window.__arap.transforms()")).reshape(-1, 4, 4).transpose(0, 2, 1)
    T, P = transforms[0], transforms[1]
    assert abs(T[0, 3]) > 0.05 * diag, "the drag did not move the group"
    Mx = np.diag([-1.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(P, Mx @ T @ Mx, atol=1e-12)

    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    path = tmp_path / "saved.json"
    info.value.save_as(path)
    doc = json.loads(path.read_text())
    assert doc["meta"]["mirror_partners"] == [[0, 1]]
    groups = doc["handle_groups"]
    assert sorted(int(mirror_of[i]) for i in groups[0]) == sorted(groups[1])
    target = dict(zip(doc["handles"], np.asarray(doc["targets"]), strict=False))
    for i in groups[0]:
        j = int(mirror_of[i])
        np.testing.assert_allclose(target[j], target[i] * [-1, 1, 1], rtol=0, atol=1e-9)
        assert np.linalg.norm(target[i] - V[i]) > 0.05 * diag

    U = positions(page)
    assert np.abs(U - V).max() > 0.05 * diag
    asym = np.abs(U[mirror_of] * [-1, 1, 1] - U).max()
    assert asym < 1e-6 * diag, f"the settled shape is not symmetric: {asym / diag:.2e} of the diagonal"

    # apply: the deformed shape is the new rest pose, and the plane is found again on it (still symmetric)
    before = page.evaluate("() => JSON.stringify(window.__arap.mirror().plane)")
    page.get_by_test_id("apply").click()
    page.wait_for_function("(p) => JSON.stringify(window.__arap.mirror().plane) !== p", arg=before)
    wait_idle(page)
    after = mirror_state(page)
    assert after["active"] and after["matched"] == 1.0 and after["plane"]["normal"] == [1, 0, 0]
    np.testing.assert_array_equal(after["mirrorOf"], mirror_of)
    applied = page.evaluate("() => JSON.stringify(window.__arap.mirror().plane)")

    # undo and redo of the apply bring back each rest pose's plane
    plane_is = "(p) => JSON.stringify(window.__arap.mirror().plane) === p"
    page.get_by_test_id("undo").click()
    page.wait_for_function(plane_is, arg=before)
    wait_idle(page)
    page.get_by_test_id("redo").click()
    page.wait_for_function(plane_is, arg=applied)
    wait_idle(page)
    assert mirror_state(page)["active"]

    # the pairing comes back with the file
    page.get_by_test_id("group-delete-1").click()
    page.get_by_test_id("group-delete-0").click()
    wait_idle(page)
    assert page.evaluate("() => window.__arap.partners()") == [-1]
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    wait_idle(page)
    assert page.evaluate("() => window.__arap.partners()")[:2] == [1, 0]
    assert page.evaluate("() => window.__arap.constraints().handle_groups")[:2] == groups
    assert not page.evaluate("() => window.__arap.errors")


def test_pairs_survive_an_undo_and_a_reload(page: Page, tmp_path: Path) -> None:
    V, F = symmetric_mesh()
    upload(page, tmp_path, "warped", V, F)
    press_mirror(page)
    page.get_by_test_id("role-handle").click()
    paint_at(page, front_point(V, 0.7))
    page.get_by_test_id("role-roi").click()
    paint_at(page, front_point(V, -0.5))  # away from the gizmo
    assert page.evaluate("() => window.__arap.constraints().roi")
    page.keyboard.press("Control+z")
    page.wait_for_function("() => window.__arap.constraints().roi === null && !window.__arap.busy")
    # the groups were rebuilt from the server's constraints: the mirror images are paired again
    assert page.evaluate("() => window.__arap.partners()") == [1, 0]
    groups = page.evaluate("() => window.__arap.constraints().handle_groups")

    reload_and_restore(page, "warped")
    assert page.evaluate("() => window.__arap.constraints().handle_groups") == groups
    assert page.evaluate("() => window.__arap.partners()") == [1, 0]
    assert not page.evaluate("() => window.__arap.errors")


def test_a_point_handle_beside_a_mirrored_pair(page: Page, tmp_path: Path) -> None:
    """A point handle placed first (so that it is client group 0, but the last group on the server) is not mirrored
    and keeps its target, while a drag of a mirrored pair painted after it still moves the partner by the mirrored
    transform and the file pairs the right handle groups."""
    V, F = symmetric_mesh()
    shown = upload(page, tmp_path, "warped", V, F)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    m = press_mirror(page)
    mirror_of = np.asarray(m["mirrorOf"])
    pts = np.asarray([page.evaluate("(p) => window.__arap.project(p)", p) for p in shown.tolist()])
    bottom = pts[:, 1] > pts[:, 1].max() - 0.15 * np.ptp(pts[:, 1])
    page.get_by_test_id("role-fixed").click()
    box_select(page, pts[bottom, 0].min() - 10, pts[bottom, 1].min(), pts[:, 0].max() + 10, pts[:, 1].max() + 10)
    wait_idle(page)

    # a point handle on the front, in the middle: a click in point mode (not mirrored: one handle)
    page.keyboard.press("5")
    x, y = page.evaluate("(p) => window.__arap.project(p)", front_point(V, 0.0).tolist())
    page.mouse.click(x + 3, y + 3)
    wait_idle(page)
    handles = page.evaluate("() => window.__arap.pointHandles()")
    assert [h is not None for h in handles] == [True], "the click placed no point handle (or more than one)"
    point = handles[0]["point"]
    faces = np.asarray(page.evaluate("() => window.__arap.faces()"), dtype=np.int64).reshape(-1, 3)
    rest_point = np.asarray(point["barycentric"]) @ shown[faces[point["face"]]]

    # a new vertex group painted on one side gets its partner on the other: client groups [point, A, A's partner]
    page.keyboard.press("n")
    paint_at(page, front_point(V, 0.7))
    assert page.evaluate("() => window.__arap.partners()") == [-1, 2, 1]
    assert page.evaluate("() => window.__arap.activeGroup") == 1
    c = page.evaluate("() => window.__arap.constraints()")
    assert len(c["handle_groups"]) == 2 and len(c["points"]) == 1
    assert sorted(int(mirror_of[i]) for i in c["handle_groups"][0]) == sorted(c["handle_groups"][1])

    drag_gizmo_x(page)
    assert page.evaluate("() => window.__arap.lastSeq") > 0, "no drag was answered"
    wait_settled(page)
    transforms = np.asarray(page.evaluate("() => window.__arap.transforms()")).reshape(-1, 4, 4).transpose(0, 2, 1)
    np.testing.assert_array_equal(transforms[0], np.eye(4))
    T, P = transforms[1], transforms[2]
    assert abs(T[0, 3]) > 0.05 * diag, "the drag did not move the group"
    Mx = np.diag([-1.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(P, Mx @ T @ Mx, atol=1e-12)

    # what the server holds: the partner's targets are the mirror image, the point handle's target did not move
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    path = tmp_path / "saved.json"
    info.value.save_as(path)
    doc = json.loads(path.read_text())
    assert doc["meta"]["mirror_partners"] == [[0, 1]]
    groups = doc["handle_groups"]
    target = dict(zip(doc["handles"], np.asarray(doc["targets"]), strict=False))
    for i in groups[0]:
        np.testing.assert_allclose(target[int(mirror_of[i])], target[i] * [-1, 1, 1], rtol=0, atol=1e-9)
        assert np.linalg.norm(target[i] - V[i]) > 0.05 * diag
    assert len(doc["points"]) == 1 and doc["points"][0]["face"] == point["face"]
    np.testing.assert_allclose(doc["points"][0]["target"], rest_point, rtol=0, atol=1e-6 * diag)
    U = positions(page)
    assert np.abs(np.asarray(point["barycentric"]) @ U[faces[point["face"]]] - rest_point).max() < 1e-5 * diag

    # loaded back, the vertex groups come first and are paired again; the point handle follows, unpaired
    page.get_by_test_id("clear-all").click()
    wait_idle(page)
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    wait_idle(page)
    assert page.evaluate("() => window.__arap.partners()") == [1, 0, -1]
    assert page.evaluate("() => window.__arap.constraints().handle_groups") == groups
    assert not page.evaluate("() => window.__arap.errors")
