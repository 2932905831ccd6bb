"""A picture's pins in the page: a loaded constraints document gives them their angles and depths (and Save
constraints writes them), their depths order the drawing in the surface views without the texture too, and holding
Alt near the active pin shows that a turn is armed."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from playwright.sync_api import Page

from tests.e2e.conftest import canvas_pixels, positions, wait_idle, wait_settled
from tests.e2e.test_studio_texture import show, upload


def _squares(path: Path) -> Path:
    """A red square and a blue one side by side, apart, on a transparent background (120 × 60)."""
    rgba = np.zeros((60, 120, 4), dtype=np.uint8)
    rgba[10:50, 10:50] = [230, 40, 40, 255]
    rgba[10:50, 70:110] = [40, 60, 230, 255]
    Image.fromarray(rgba, "RGBA").save(path)
    return path


def _document(page: Page, depth: list[int], angle: float | None = None) -> dict[str, Any]:
    """A pin on each square (the left one's painted rigid), the right one moved over the left one's right part."""
    V = positions(page)
    F = np.asarray(page.evaluate("() => window.__arap.faces()"), dtype=np.int64).reshape(-1, 3)
    centre = V[F].mean(axis=1)
    pins = []
    for k, (x, y) in enumerate(((30.0, 30.0), (90.0, 30.0))):
        face = int(np.argmin(np.hypot(centre[:, 0] - x, centre[:, 1] - y)))
        target = centre[face] + ([0.0, 0.0, 0.0] if k == 0 else [-40.0, 0.0, 0.0])
        pin: dict[str, Any] = {"face": face, "barycentric": [1 / 3, 1 / 3, 1 / 3], "target": target.tolist(),
                               "depth": depth[k]}
        if k == 0 and angle is not None:
            pin["angle"] = angle
        pins.append(pin)
    left = np.flatnonzero(V[:, 0] < 60).tolist()
    return {"version": 2, "points": pins, "stiffness": [{"vertices": left, "value": "rigid"}]}


def _load(page: Page, tmp_path: Path, doc: dict[str, Any], name: str) -> None:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    page.get_by_test_id("constraints-input").set_input_files(str(path))


def test_a_loaded_document_gives_the_pins_their_angle_and_depth_and_save_keeps_them(page: Page,
                                                                                  tmp_path: Path) -> None:
    upload(page, _squares(tmp_path / "squares.png"), "texture")
    _load(page, tmp_path, _document(page, [0, 1], angle=30.0), "turned.json")
    page.wait_for_function("() => window.__arap.picturePins().angles[0] !== null && "
                           "window.__arap.picturePins().angles[0] !== undefined", timeout=30_000)
    wait_idle(page)
    pins = page.evaluate("() => window.__arap.picturePins()")
    assert abs(pins["angles"][0] - 30.0) < 1e-6 and pins["angles"][1] is None
    assert pins["depth"] == [0, 1] and pins["drawFirst"] is not None
    wait_settled(page)
    with page.expect_download() as info:
        page.get_by_test_id("save-constraints").click()
    saved = tmp_path / "saved.json"
    info.value.save_as(saved)
    doc = json.loads(saved.read_text())
    assert abs(doc["points"][0]["angle"] - 30.0) < 1e-6 and "angle" not in doc["points"][1]
    assert [p["depth"] for p in doc["points"]] == [0, 1]
    assert not page.evaluate("() => window.__arap.errors")


def _overlap_document(page: Page, depth: int) -> dict[str, Any]:
    """The left square held (its vertices fixed: drawn in the anchors' red) and a pin on the right one, moved over
    the left one's right part, of depth ``depth`` (the left square, without a pin, has depth 0)."""
    V = positions(page)
    F = np.asarray(page.evaluate("() => window.__arap.faces()"), dtype=np.int64).reshape(-1, 3)
    centre = V[F].mean(axis=1)
    face = int(np.argmin(np.hypot(centre[:, 0] - 90.0, centre[:, 1] - 30.0)))
    target = (centre[face] + [-40.0, 0.0, 0.0]).tolist()
    return {"version": 2, "fixed": np.flatnonzero(V[:, 0] < 60).tolist(),
            "points": [{"face": face, "barycentric": [1 / 3, 1 / 3, 1 / 3], "target": target, "depth": depth}]}


def _anchored_and_plain(page: Page) -> tuple[int, int]:
    """Pixels of the view that show the held square (the anchors' red), and the plain grey one."""
    px = canvas_pixels(page)[..., :3].astype(np.int32)
    r, g, b = px[..., 0], px[..., 1], px[..., 2]
    red = (r > g + 60) & (r > b + 60)
    grey = (r > 100) & (np.abs(r - g) < 14) & (np.abs(g - b) < 20)
    return int(red.sum()), int(grey.sum())


def test_pin_depths_order_the_drawing_without_the_texture(page: Page, tmp_path: Path) -> None:
    upload(page, _squares(tmp_path / "squares.png"), "texture")
    show(page, "plain")
    documents = {d: _overlap_document(page, d) for d in (1, -1)}  # on the rest pose

    def counts_with(depth: int, first: int | None) -> tuple[int, int, int]:
        _load(page, tmp_path, documents[depth], f"depth{depth}.json")
        page.wait_for_function(f"() => ![null, {first if first is not None else 'null'}].includes("
                               "window.__arap.picturePins().drawFirst)", timeout=30_000)
        wait_idle(page)
        wait_settled(page)
        page.evaluate("() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))")
        return (*_anchored_and_plain(page), page.evaluate("() => window.__arap.picturePins().drawFirst"))

    red_back, grey_front, first = counts_with(1, None)  # the pin's square in front
    red_front, grey_back, _ = counts_with(-1, first)  # behind
    assert page.evaluate("() => window.__arap.surface") == "plain"
    assert red_front > red_back + 50 and grey_front > grey_back + 50, (red_back, grey_front, red_front, grey_back)
    assert not page.evaluate("() => window.__arap.errors")


def _armed(page: Page) -> tuple[bool, str]:
    """Whether the ring about the active pin shows, and the view's cursor."""
    return tuple(page.evaluate("() => [!document.getElementById('pin-turn-ring').hidden, "
                         "document.querySelector('[data-testid=canvas]').style.cursor]"))  # type: ignore[return-value]


def test_holding_alt_near_the_active_pin_shows_the_turn_is_armed(page: Page, tmp_path: Path) -> None:
    from tests.e2e.conftest import screen_points

    upload(page, _squares(tmp_path / "squares.png"), "texture")
    pts = screen_points(page)
    left, right = pts[:, 0].min(), pts[:, 0].max()
    y = float(np.median(pts[:, 1]))
    page.mouse.click(left + (right - left) * 20 / 100, y)  # a pin on the red square: the active pin
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    px, py = page.evaluate("() => window.__arap.pointHandles()[0].screen")
    page.mouse.move(px + 60, py + 10)
    assert _armed(page) == (False, "")  # no Alt: nothing armed
    page.keyboard.down("Alt")
    page.wait_for_function("() => !document.getElementById('pin-turn-ring').hidden")
    shown, cursor = _armed(page)
    assert shown and cursor.startswith("url(")
    ring = page.get_by_test_id("pin-turn-ring").bounding_box()
    assert ring is not None and abs(ring["x"] + ring["width"] / 2 - px) < 3 and abs(ring["y"] + ring["height"] / 2
                                                                                   - py) < 3
    page.mouse.move(px + 200, py + 10)  # beyond the 150 px reach, Alt still held
    page.wait_for_function("() => document.getElementById('pin-turn-ring').hidden")
    assert _armed(page) == (False, "")
    page.mouse.move(px + 40, py - 30)  # back within reach
    page.wait_for_function("() => !document.getElementById('pin-turn-ring').hidden")
    page.keyboard.up("Alt")
    page.wait_for_function("() => document.getElementById('pin-turn-ring').hidden")
    assert _armed(page) == (False, "")
    assert not page.evaluate("() => window.__arap.errors")


def test_a_loaded_timeline_moves_and_turns_the_pins_as_its_keyframes_do(page: Page, tmp_path: Path) -> None:
    """A saved timeline of a picture: per keyframe the pins' targets and the angles they hold. Loaded, the timeline
    poses the pins as the keyframes say: the held pin at its target, turned by its angle there."""
    from tests.e2e.test_studio_timeline import seek, timeline

    upload(page, _squares(tmp_path / "squares.png"), "texture")
    doc = _document(page, [0, 1], angle=30.0)
    del doc["stiffness"]
    doc |= {"fixed": [], "handles": [], "targets": [], "handle_groups": []}  # as the studio saves a picture's pins
    start = [p["target"] for p in doc["points"]]
    lifted = [[start[0][0], start[0][1] + 6.0, start[0][2]], start[1]]
    doc["keyframes"] = [{"time": 0.0, "transforms": [], "point_targets": start, "point_angles": [30.0, None]},
                        {"time": 1.0, "transforms": [], "point_targets": lifted, "point_angles": [120.0, None]}]
    _load(page, tmp_path, doc, "timeline.json")
    page.wait_for_function("() => window.__arap.timeline.keys.length === 2", timeout=30_000)
    page.wait_for_function("() => window.__arap.picturePins().angles[0] !== null && "
                           "window.__arap.picturePins().angles[0] !== undefined", timeout=30_000)
    wait_idle(page)
    assert [len(k["transforms"]) for k in timeline(page)["keys"]] == [2, 2]  # one per pin
    assert page.evaluate("() => window.__arap.picturePins().depth") == [0, 1]

    F = np.asarray(page.evaluate("() => window.__arap.faces()"), dtype=np.int64).reshape(-1, 3)
    pin = doc["points"][0]

    def pin_and_angle() -> tuple[np.ndarray, float]:
        where = np.asarray(pin["barycentric"]) @ positions(page)[F[pin["face"]]]
        return where, float(page.evaluate("() => window.__arap.picturePins().angles[0]"))

    seek(page, 1000)
    where, angle = pin_and_angle()
    np.testing.assert_allclose(where, lifted[0], atol=1e-3)
    assert abs(angle - 120.0) < 1e-6, angle
    seek(page, 0)
    where, angle = pin_and_angle()
    np.testing.assert_allclose(where, start[0], atol=1e-3)
    assert abs(angle - 30.0) < 1e-6, angle
    assert not page.evaluate("() => window.__arap.errors")
