"""The studio's keyframe timeline: keyframes of the handle groups' transforms, scrubbing, playback, autosave, the
animated GLB export and the saved document that ``arap animate`` renders; the page interpolates as
arap.constraints.keyframes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect
from scipy.spatial.transform import Rotation

from arap.animation import animate
from arap.constraints.keyframes import Keyframes
from arap.io import load_mesh
from arap.server.meshdata import load_builtin
from tests.animated_glb import glb_frames
from tests.e2e.conftest import positions, wait_idle, wait_ready, wait_settled
from tests.e2e.test_session_safety import Dialogs, wait_autosaved
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.waiting import scaled_ms

pytestmark = pytest.mark.e2e




def timeline(page: Page) -> dict:
    return page.evaluate("() => window.__arap.timeline")


def seek(page: Page, ms: float) -> None:
    """Scrub to ``ms`` and let the shape settle there."""
    page.evaluate(f"() => window.__arap.seek({ms})")
    wait_idle(page)
    wait_settled(page)


def test_keyframes_scrub_play_restore_export(page: Page, tmp_path: Path) -> None:
    name = page.evaluate("() => window.__arap.meshName")
    rest = positions(page)
    diag = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    fixed, handle = select_anchor_and_handle(page)
    wait_settled(page)

    # a keyframe at 0 s with the handles at rest; the playhead to 1 s, a drag, a keyframe there
    page.get_by_test_id("tl-add").click()
    expect(page.get_by_test_id("tl-count")).to_have_text("1 keyframe")
    seek(page, 1000)
    assert np.abs(positions(page) - rest).max() < 1e-6  # one keyframe: the handles hold its pose
    drag_gizmo_x(page, 90)
    wait_settled(page)
    page.locator("#view").focus()
    page.keyboard.press("k")
    expect(page.get_by_test_id("tl-count")).to_have_text("2 keyframes")
    tl = timeline(page)
    assert [k["ms"] for k in tl["keys"]] == [0, 1000]
    moved_to = positions(page)
    shift = moved_to[handle] - rest[handle]
    assert np.linalg.norm(shift, axis=1).min() > 0.02 * diag
    expect(page.get_by_test_id("tl-marker")).to_have_count(2)

    # scrubbing to 0.5 s puts the handles halfway (a translation) and the shape between the two
    seek(page, 500)
    half = positions(page)
    np.testing.assert_allclose(half[handle], rest[handle] + 0.5 * shift, atol=1e-4 * diag)
    np.testing.assert_allclose(half[fixed], rest[fixed], atol=1e-6 * diag)
    free = np.setdiff1d(np.arange(len(rest)), np.concatenate([fixed, handle]))
    to_rest = np.linalg.norm(half[free] - rest[free], axis=1).max()
    to_end = np.linalg.norm(half[free] - moved_to[free], axis=1).max()
    full = np.linalg.norm(moved_to[free] - rest[free], axis=1).max()
    assert 0.2 * full < to_rest < 0.8 * full and 0.2 * full < to_end < 0.8 * full

    # a click on a marker goes to its keyframe; a mouse scrub on the bar moves the playhead and sends drags
    page.get_by_test_id("tl-marker").nth(1).click()
    wait_idle(page)
    assert timeline(page)["timeMs"] == 1000
    bar = page.get_by_test_id("tl-bar").bounding_box()
    assert bar is not None
    sent = timeline(page)["dragsSent"]
    y = bar["y"] + 3
    page.mouse.move(bar["x"] + 0.1 * bar["width"], y)
    page.mouse.down()
    for k in range(1, 9):
        page.mouse.move(bar["x"] + (0.1 + 0.1 * k / 8) * bar["width"], y)
    page.mouse.up()
    wait_idle(page)
    tl = timeline(page)
    assert tl["dragsSent"] > sent + 3 and abs(tl["timeMs"] - 0.2 * tl["durationMs"]) < 0.02 * tl["durationMs"]

    # play advances frames, loops and pauses
    seq = page.evaluate("() => window.__arap.lastSeq")
    page.get_by_test_id("tl-play").click()
    page.wait_for_function("() => window.__arap.timeline.framesShown >= 6", timeout=scaled_ms(20))
    page.wait_for_function(f"() => window.__arap.lastSeq > {seq} + 3", timeout=scaled_ms(20))
    page.get_by_test_id("tl-play").click()
    assert not timeline(page)["playing"]
    wait_idle(page)
    wait_settled(page)

    # a reload restores the keyframes with the session (autosave)
    seek(page, 500)
    saved = timeline(page)
    wait_autosaved(page)
    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    assert timeline(page)["keys"] == []
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => !window.__arap.restoring && window.__arap.timeline.keys.length === 2",
                           timeout=scaled_ms(30))
    wait_idle(page)
    wait_settled(page)
    tl = timeline(page)
    assert [k["ms"] for k in tl["keys"]] == [0, 1000] and tl["timeMs"] == saved["timeMs"]
    assert [k["shapeVertices"] for k in tl["keys"]] == [len(rest)] * 2  # the page keeps each keyframe's shape
    np.testing.assert_allclose(positions(page), half, atol=1e-4 * diag)
    # the keyframes still pose the handles as they did before the reload, and give back the shapes kept with them
    seek(page, 1000)
    np.testing.assert_allclose(positions(page)[handle], moved_to[handle], atol=1e-4 * diag)
    np.testing.assert_allclose(positions(page), moved_to, atol=1e-5 * diag)
    seek(page, 0)
    np.testing.assert_allclose(positions(page)[handle], rest[handle], atol=1e-4 * diag)

    # export: an animated GLB of every frame from 0 s to 1 s at the frame rate
    fps = tl["fps"]
    with page.expect_download(timeout=scaled_ms(120)) as info:
        page.get_by_test_id("tl-export").click()
    glb = tmp_path / info.value.suggested_filename
    info.value.save_as(glb)
    assert glb.suffix == ".glb"
    V, _ = load_mesh(glb)
    assert V.shape == rest.shape
    times, frames = glb_frames(glb.read_bytes())
    assert len(frames) == fps + 1
    np.testing.assert_allclose(times, np.arange(fps + 1) / fps, atol=1e-6)
    np.testing.assert_allclose(frames[0][handle], rest[handle], atol=1e-4 * diag)
    np.testing.assert_allclose(frames[-1][handle], moved_to[handle], atol=1e-4 * diag)
    expect(page.get_by_test_id("tl-progress")).to_contain_text(f"{fps + 1} frames")

    # the saved constraints document renders the same animation with arap animate
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    path = tmp_path / "keys.json"
    info.value.save_as(path)
    document = json.loads(path.read_text())
    assert [k["time"] for k in document["keyframes"]] == [0.0, 1.0]
    mesh = load_builtin(name)
    offline = animate(mesh.V, mesh.F, document, fps=fps)
    assert offline.vertices.shape == frames.shape
    np.testing.assert_allclose(offline.vertices, frames, atol=1e-4 * diag)
    assert "keyframe_base" in document  # the restored selection was made on the deformed shape

    # loading the document puts the keyframes back on the timeline, posing the handles as before
    for ms in (0, 1000):
        page.evaluate(f"() => window.__arap.seek({ms})")
        page.get_by_test_id("tl-delete").click()
    expect(page.get_by_test_id("tl-count")).to_have_text("no keyframes")
    wait_idle(page)
    page.get_by_test_id("constraints-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.timeline.keys.length === 2")
    wait_idle(page)
    wait_settled(page)
    assert [k["ms"] for k in timeline(page)["keys"]] == [0, 1000]
    seek(page, 1000)
    np.testing.assert_allclose(positions(page)[handle], moved_to[handle], atol=1e-4 * diag)
    seek(page, 0)
    np.testing.assert_allclose(positions(page)[handle], rest[handle], atol=1e-4 * diag)

    # Apply makes the shape a quarter of the way the rest pose: the keyframes still pose the handles as before
    seek(page, 250)
    page.get_by_test_id("apply").click()
    wait_idle(page)
    wait_settled(page)
    seek(page, 1000)
    np.testing.assert_allclose(positions(page)[handle], moved_to[handle], atol=1e-4 * diag)
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def test_the_page_interpolates_as_arap_keyframes(page: Page) -> None:
    V = load_builtin("bar").V
    rng = np.random.default_rng(7)
    groups = [[0, 5, 9, 40], [100, 120, 140]]
    handles = [v for g in groups for v in g]

    def transform() -> np.ndarray:
        M = np.eye(4)
        M[:3, :3] = Rotation.random(random_state=rng).as_matrix() @ np.diag(rng.uniform(0.7, 1.4, 3))
        M[:3, 3] = rng.normal(size=3)
        return M

    times_ms = [0, 400, 1000]
    mats = [[transform() for _ in groups] for _ in times_ms]
    document = {"fixed": [2000], "handles": handles, "handle_groups": groups, "keyframes": [
        {"time": ms / 1000, "transforms": [M.tolist() for M in Ms]} for ms, Ms in zip(times_ms, mats, strict=True)]}
    keys = Keyframes.from_json(document, V)
    pivots = [V[g].mean(axis=0).tolist() for g in groups]
    js_keys = [{"ms": ms, "transforms": [M.T.reshape(16).tolist() for M in Ms]}
               for ms, Ms in zip(times_ms, mats, strict=True)]
    for t in (-0.1, 0.0, 0.13, 0.4, 0.55, 0.77, 1.0, 1.2):
        out = page.evaluate("([k, p, t]) => window.__arap.interpolate(k, p, t)", [js_keys, pivots, t])
        got = np.concatenate([V[g] @ np.asarray(m).reshape(4, 4).T[:3, :3].T + np.asarray(m).reshape(4, 4).T[:3, 3]
                              for g, m in zip(groups, out, strict=True)])
        np.testing.assert_allclose(got, keys.handle_targets(t), atol=1e-12, err_msg=f"at {t} s")


def test_the_page_eases_as_arap_keyframes(page: Page) -> None:
    V = load_builtin("bar").V
    group = [0, 5, 9, 40]
    pivot = V[group].mean(axis=0)
    turned = np.eye(4)
    turned[:3, :3] = Rotation.from_rotvec([0.0, 0.0, 1.2]).as_matrix()
    turned[:3, 3] = pivot - turned[:3, :3] @ pivot + [0.3, 0.0, 0.0]
    mats = [np.eye(4), turned, np.eye(4)]
    easings = ["ease-in-out", "ease-in", "linear"]
    times_ms = [0, 500, 1000]
    document = {"fixed": [2000], "handles": group, "keyframes": [
        {"time": ms / 1000, "transforms": [M.tolist()], "easing": e} for ms, M, e in zip(times_ms, mats, easings,
                                                                                          strict=True)]}
    keys = Keyframes.from_json(document, V)
    js_keys = [{"ms": ms, "transforms": [M.T.reshape(16).tolist()], "easing": e}
               for ms, M, e in zip(times_ms, mats, easings, strict=True)]
    for t in (0.1, 0.25, 0.4, 0.6, 0.9):
        out = page.evaluate("([k, p, t]) => window.__arap.interpolate(k, p, t)", [js_keys, [pivot.tolist()], t])
        m = np.asarray(out[0]).reshape(4, 4).T
        np.testing.assert_allclose(V[group] @ m[:3, :3].T + m[:3, 3], keys.handle_targets(t), atol=1e-12,
                                   err_msg=f"at {t} s")


def test_the_timeline_in_sight_typed_times_ends_keyed_shapes_and_easing(page: Page, tmp_path: Path) -> None:
    page.set_viewport_size({"width": 1400, "height": 900})
    in_sight = page.evaluate("""() => ['tl-bar', 'btn-tl-add', 'btn-tl-export', 'tl-time-input'].map((id) => {
        const r = document.getElementById(id).getBoundingClientRect();
        return r.top >= 0 && r.bottom <= window.innerHeight && r.height > 0; })""")
    assert all(in_sight), f"the timeline is out of sight at 1400×900: {in_sight}"

    rest = positions(page)
    diag = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    _fixed, handle = select_anchor_and_handle(page)
    wait_settled(page)
    page.get_by_test_id("tl-add").click()
    expect(page.get_by_test_id("tl-count")).to_have_text("1 keyframe")

    # a typed time moves the playhead; R Z 45 there, and a keyframe of that shape
    page.get_by_test_id("tl-time-input").fill("1")
    page.get_by_test_id("tl-time-input").press("Enter")
    wait_idle(page)
    assert timeline(page)["timeMs"] == 1000
    page.evaluate("() => document.activeElement?.blur()")  # keys go to the view, not the time field
    page.mouse.move(30, 300)  # a typed rotation starts with the pointer over the view
    for key in ("r", "z", "4", "5"):
        page.keyboard.press(key)
    expect(page.get_by_test_id("numeric-line")).to_have_text("Rotate Z: 45°")
    page.keyboard.press("Enter")
    expect(page.get_by_test_id("numeric-line")).to_be_hidden()
    wait_idle(page)
    wait_settled(page)
    page.get_by_test_id("tl-add").click()
    expect(page.get_by_test_id("tl-count")).to_have_text("2 keyframes")
    wait_idle(page)
    wait_settled(page)
    keyed = positions(page)
    assert np.abs(keyed[handle] - rest[handle]).max() > 0.01 * diag

    # back to the start and to the key again: the shape that was keyed
    seek(page, 0)
    np.testing.assert_allclose(positions(page), rest, atol=1e-6 * diag)
    seek(page, 1000)
    assert np.abs(positions(page) - keyed).max() <= 1e-6 * diag

    # a click at the bar's end is the end of the clip; a scrub that starts on the first marker scrubs
    page.get_by_test_id("tl-duration").fill("2")
    page.get_by_test_id("tl-duration").press("Enter")
    bar = page.get_by_test_id("tl-bar").bounding_box()
    assert bar is not None
    y = bar["y"] + bar["height"] / 2
    page.mouse.click(bar["x"] + bar["width"] - 0.5, y)
    wait_idle(page)
    assert timeline(page)["timeMs"] == 2000
    first = page.get_by_test_id("tl-marker").first.bounding_box()
    assert first is not None
    page.mouse.move(first["x"] + first["width"] / 2, first["y"] + first["height"] / 2)
    page.mouse.down()
    assert timeline(page)["timeMs"] == 0
    for k in range(1, 6):
        page.mouse.move(bar["x"] + 0.05 * k * bar["width"], y)
    page.mouse.up()
    wait_idle(page)
    assert abs(timeline(page)["timeMs"] - 500) <= 20, timeline(page)["timeMs"]
    wait_settled(page)

    # the keyframe at the playhead: its time typed, its easing chosen; both go into the saved document
    seek(page, 1000)
    page.get_by_test_id("tl-key-time").fill("1.5")
    page.get_by_test_id("tl-key-time").press("Enter")
    wait_idle(page)
    seek(page, 0)
    page.get_by_test_id("tl-easing").select_option("ease-in-out")
    keys = timeline(page)["keys"]
    assert [k["ms"] for k in keys] == [0, 1500] and [k["easing"] for k in keys] == ["ease-in-out", "linear"]
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    path = tmp_path / "keys.json"
    info.value.save_as(path)
    document = json.loads(path.read_text())
    assert [k["time"] for k in document["keyframes"]] == [0.0, 1.5]
    assert document["keyframes"][0]["easing"] == "ease-in-out"
    np.testing.assert_allclose(document["keyframes"][1]["shape"], keyed, atol=1e-6 * diag)

    # the export's frame at the key is the keyed shape
    page.get_by_test_id("tl-fps").fill("4")
    page.get_by_test_id("tl-fps").press("Enter")
    with page.expect_download(timeout=scaled_ms(120)) as info:
        page.get_by_test_id("tl-export").click()
    glb = tmp_path / info.value.suggested_filename
    info.value.save_as(glb)
    _, frames = glb_frames(glb.read_bytes())
    assert len(frames) == 7
    assert np.abs(frames[-1] - keyed).max() <= 1e-5 * diag
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def test_a_point_handle_is_animated_like_a_handle_group(page: Page, tmp_path: Path) -> None:
    from tests.e2e.test_studio_points import _anchor_bottom, _faces, _on_surface, _place_point

    rest = positions(page)
    F = _faces(page)
    diag = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    point = _place_point(page, _anchor_bottom(page))["point"]
    wait_settled(page)
    page.get_by_test_id("tl-add").click()  # a point handle alone is enough for keyframes
    expect(page.get_by_test_id("tl-count")).to_have_text("1 keyframe")
    seek(page, 1000)
    drag_gizmo_x(page, 90)
    wait_settled(page)
    page.get_by_test_id("tl-add").click()
    expect(page.get_by_test_id("tl-count")).to_have_text("2 keyframes")
    wait_idle(page)
    wait_settled(page)
    start, end = _on_surface(rest, F, point), _on_surface(positions(page), F, point)
    assert np.linalg.norm(end - start) > 0.02 * diag
    seek(page, 500)  # the point halfway, on a straight line
    np.testing.assert_allclose(_on_surface(positions(page), F, point), (start + end) / 2, atol=1e-4 * diag)

    page.get_by_test_id("tl-fps").fill("4")
    page.get_by_test_id("tl-fps").press("Enter")
    with page.expect_download(timeout=scaled_ms(120)) as info:
        page.get_by_test_id("tl-export").click()
    glb = tmp_path / info.value.suggested_filename
    info.value.save_as(glb)
    _, frames = glb_frames(glb.read_bytes())
    assert len(frames) == 5
    where = np.array([_on_surface(U, F, point) for U in frames])
    expected = start + np.linspace(0.0, 1.0, 5)[:, None] * (end - start)
    np.testing.assert_allclose(where, expected, atol=1e-4 * diag)
    assert not page.evaluate("() => window.__arap.errors"), "the server reported errors"


def test_a_picture_animation_exports_as_an_animated_gif(page: Page, tmp_path: Path) -> None:
    import io

    from PIL import Image

    from tests.e2e.test_studio_picture import _picture
    from tests.e2e.test_studio_texture import upload

    upload(page, _picture(tmp_path / "bar-picture.png"), "texture")
    select_anchor_and_handle(page)
    wait_settled(page)
    page.get_by_test_id("tl-add").click()
    seek(page, 500)
    drag_gizmo_x(page, 80)
    wait_settled(page)
    page.get_by_test_id("tl-add").click()
    expect(page.get_by_test_id("tl-count")).to_have_text("2 keyframes")
    wait_idle(page)
    wait_settled(page)
    page.get_by_test_id("tl-fps").fill("8")
    page.get_by_test_id("tl-fps").press("Enter")
    page.get_by_test_id("tl-format").select_option("gif")
    with page.expect_download(timeout=scaled_ms(120)) as info:
        page.get_by_test_id("tl-export").click()
    assert info.value.suggested_filename == "bar-picture_animation.gif"
    out = tmp_path / "out.gif"
    info.value.save_as(out)
    gif = Image.open(io.BytesIO(out.read_bytes()))
    assert gif.format == "GIF" and gif.size == (160, 160) and gif.n_frames == 5
    assert not page.evaluate("() => window.__arap.errors")
