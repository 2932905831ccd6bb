"""The notebook widget's built ES module (``static/widget.js``) in headless Chromium, rendered by anywidget's
``render({model, el})`` with a stand-in model whose custom messages go to and come from an ``arap.widget`` in this
process (as the kernel's comm would carry them): the mesh is drawn, and painting and a gizmo drag move the shape,
both in the page and in the widget's ``vertices``; a widget stopped in the kernel says so in the page."""

from __future__ import annotations

import base64
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Browser, BrowserContext, Frame, Page

from arap.server.client_files import client_dir
from tests.e2e.conftest import VIEWPORT, canvas_pixels, positions, wait_idle
from tests.waiting import page_wait_until, scaled_ms

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

anywidget = pytest.importorskip("anywidget")

import arap  # noqa: E402
from arap.jupyter_widget import StudioWidget  # noqa: E402
from arap.server.session import Session  # noqa: E402

ORIGIN = "http://notebook.test"
HOST = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>notebook</title></head>
<body style="margin: 0">
<div id="output"></div>
<script type="module">
import widget from './widget.js';
const listeners = new Set();
const b64 = (view) => {{
  const bytes = view instanceof ArrayBuffer ? new Uint8Array(view)
    : new Uint8Array(view.buffer, view.byteOffset, view.byteLength);
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
}};
const unb64 = (s) => {{
  const bin = atob(s);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return new DataView(bytes.buffer);  // anywidget hands buffers on as DataViews
}};
const model = {{
  get: (name) => ({{ height: {VIEWPORT["height"]} }})[name],
  send: (content, callbacks, buffers) => window.kernelReceive(content, (buffers ?? []).map(b64)),
  on: (name, cb) => listeners.add(cb),
  off: (name, cb) => listeners.delete(cb),
}};
window.rendered = widget.render({{ model, el: document.getElementById('output') }});
(async () => {{
  for (;;) {{
    for (const [content, buffers] of await window.kernelSent()) {{
      const views = buffers.map(unb64);
      for (const cb of listeners) cb(content, views);
    }}
    await new Promise((r) => setTimeout(r, 4));
  }}
}})();
</script>
</body></html>
"""


class Kernel:
    """The widget's side: what the page sends goes to the widget; what the widget sends waits for the page."""

    def __init__(self, w: StudioWidget) -> None:
        self.w = w
        self.outbox: list[tuple[dict[str, Any], list[str]]] = []
        self.lock = threading.Lock()
        self.sent_types: list[str] = []
        w.send = self._send  # type: ignore[attr-defined]

    def _send(self, content: dict[str, Any], buffers: list[Any] | None = None) -> None:
        with self.lock:
            self.outbox.append((content, [base64.b64encode(bytes(b)).decode() for b in buffers or []]))
            if "type" in content:  # a studio message, not the widget's own note
                self.sent_types.append(content["type"])

    def receive(self, content: Any, buffers: list[str]) -> None:
        self.w._receive(content, [base64.b64decode(b) for b in buffers])

    def sent(self) -> list[tuple[dict[str, Any], list[str]]]:
        with self.lock:
            out, self.outbox = self.outbox, []
        return out


def _open_page(browser: Browser, kernel: Kernel) -> tuple[BrowserContext, Page, Frame, list[str]]:
    """The stand-in notebook page with the widget's view rendered; its errors are collected."""
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
    page.expose_function("kernelReceive", kernel.receive)
    page.expose_function("kernelSent", kernel.sent)
    module = (client_dir() / "widget.js").read_text(encoding="utf-8")
    page.route(f"{ORIGIN}/notebook.html", lambda route: route.fulfill(body=HOST, content_type="text/html"))
    page.route(f"{ORIGIN}/widget.js", lambda route: route.fulfill(body=module, content_type="text/javascript"))
    page.goto(f"{ORIGIN}/notebook.html")
    element = page.wait_for_selector("iframe[data-testid=arap-widget-frame]")
    frame = element.content_frame()
    assert frame is not None
    return context, page, frame, errors


@pytest.fixture
def widget_page(browser: Browser) -> Iterator[tuple[Page, Frame, StudioWidget, Kernel]]:
    if not (client_dir() / "widget.js").is_file():
        pytest.skip("the widget module is not built (./dev setup)")
    V, F = arap.builtin_mesh("cactus")
    w = arap.widget(V, F, name="cactus", height=VIEWPORT["height"])
    kernel = Kernel(w)
    context, page, frame, errors = _open_page(browser, kernel)
    frame.wait_for_function("() => window.__arap && window.__arap.ready && !window.__arap.busy", timeout=scaled_ms(60))
    try:
        yield page, frame, w, kernel
    finally:
        context.close()
        w.stop()
    assert not errors, f"errors in the page: {errors}"


def _screen_points(frame: Frame) -> np.ndarray:
    """Page coordinates of every vertex (the frame is at the page's top-left corner, without a border)."""
    pts = frame.evaluate("""() => {
        const p = window.__arap.positions();
        const r = document.getElementById('view').getBoundingClientRect();
        const out = [];
        for (let i = 0; i < p.length; i += 3) {
            const [x, y] = window.__arap.project([p[i], p[i + 1], p[i + 2]]);
            out.push([x + r.left, y + r.top]);
        }
        return out;
    }""")
    return np.asarray(pts, dtype=np.float64)


def test_the_widget_draws_the_mesh_and_a_drag_moves_it(widget_page: tuple[Page, Frame, StudioWidget, Kernel]) -> None:
    page, frame, w, kernel = widget_page
    V = w.vertices
    assert frame.evaluate("() => window.__arap.nVertices") == len(V)
    assert kernel.sent_types[:3] == ["welcome", "mesh", "state"]
    np.testing.assert_allclose(positions(frame), V, atol=1e-5)  # type: ignore[arg-type]
    wait_idle(frame)  # type: ignore[arg-type]
    px = canvas_pixels(frame)  # type: ignore[arg-type]
    rgb = px[..., :3].astype(np.int32)
    drawn = (rgb.max(axis=-1) >= 100) | (np.ptp(rgb, axis=-1) >= 40)  # not the dark background
    assert drawn.mean() > 0.01, "the mesh was not drawn"

    # anchors: a box around the bottom; a handle: a brush stroke at the top (real mouse events)
    pts = _screen_points(frame)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    xmin, xmax = pts[:, 0].min(), pts[:, 0].max()
    frame.get_by_test_id("role-fixed").click()
    page.keyboard.down("Shift")
    page.mouse.move(xmin - 10, ymax - 0.12 * (ymax - ymin))
    page.mouse.down()
    page.mouse.move(xmax + 10, ymax + 10, steps=8)
    page.mouse.up()
    page.keyboard.up("Shift")
    wait_idle(frame)  # type: ignore[arg-type]
    top = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)]
    tx, ty = top.mean(axis=0)
    frame.get_by_test_id("role-handle").click()
    page.mouse.move(tx - 6, ty + 8)
    page.mouse.down()
    page.mouse.move(tx + 6, ty + 14, steps=6)
    page.mouse.up()
    wait_idle(frame)  # type: ignore[arg-type]
    page_wait_until(page, lambda: w.constraints.fixed.size and w.constraints.handle_groups, 30,
                    "the painted selection to reach the widget")
    sel = w.constraints
    assert sel.fixed.size > 0 and len(sel.handle_groups) == 1, "the painted selection did not reach the widget"
    handle = sel.handle_groups[0]

    gizmo = frame.evaluate("() => window.__arap.gizmo()")
    assert gizmo is not None, "no gizmo on the handle group"
    cx, cy = gizmo["screen"]
    ax, ay = gizmo["axes"]["x"]
    d = np.array([ax - cx, ay - cy])
    d /= np.linalg.norm(d)
    t0 = time.perf_counter()
    page.mouse.move(ax, ay)
    page.mouse.down()
    for k in range(1, 13):
        page.mouse.move(ax + d[0] * 120 * k / 12, ay + d[1] * 120 * k / 12)
    page.mouse.up()
    wait_idle(frame)  # type: ignore[arg-type]
    frame.wait_for_function(
        "() => document.querySelector('[data-testid=settle-status]')?.dataset.status === 'settled'"
        " && !window.__arap.busy", timeout=scaled_ms(60))
    elapsed = time.perf_counter() - t0
    assert w.wait(30)
    U = w.vertices
    moved = np.linalg.norm(U[handle] - V[handle], axis=1)
    assert moved.min() > 0.05 * np.ptp(V, axis=0).max(), "the drag did not move the handle"
    np.testing.assert_allclose(U[sel.fixed], V[sel.fixed], atol=1e-6)
    np.testing.assert_allclose(positions(frame), U, atol=1e-4)  # type: ignore[arg-type]  # the page shows it
    assert "vertices" in kernel.sent_types and kernel.sent_types.count("state") >= 3
    print(f"drag and settle through the stand-in comm: {elapsed:.2f} s")


def test_a_mesh_file_uploaded_in_the_widget_reaches_the_kernel(
        widget_page: tuple[Page, Frame, StudioWidget, Kernel], tmp_path: Any) -> None:
    """A binary message (the upload: header and file bytes as the comm's buffer) goes through the model."""
    import trimesh

    _, frame, w, _ = widget_page
    mesh = trimesh.creation.icosphere(subdivisions=2)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    path = tmp_path / "small_sphere.obj"
    path.write_text("\n".join(lines) + "\n")
    frame.get_by_test_id("file-input").set_input_files(str(path))
    frame.wait_for_function("() => window.__arap.meshName === 'small_sphere'", timeout=scaled_ms(60))
    wait_idle(frame)  # type: ignore[arg-type]
    assert frame.evaluate("() => window.__arap.nVertices") == len(mesh.vertices)
    assert w.wait(30)
    assert w.vertices.shape == mesh.vertices.shape and w.faces.shape == mesh.faces.shape
    np.testing.assert_allclose(w.vertices, mesh.vertices, atol=1e-5)


def test_a_widget_stopped_in_the_kernel_says_so(widget_page: tuple[Page, Frame, StudioWidget, Kernel]) -> None:
    page, _, w, _ = widget_page
    assert page.query_selector("[data-testid=arap-widget-stopped]") is None
    w.stop()
    note = page.wait_for_selector("[data-testid=arap-widget-stopped]", timeout=scaled_ms(30))
    assert note is not None
    text = note.inner_text()
    assert "stopped" in text and "run the cell that made it again" in text


def test_while_the_session_is_prepared_the_view_shows_the_mesh_and_the_time_waited(
        browser: Browser, monkeypatch: pytest.MonkeyPatch) -> None:
    """On a first run the kernel compiles the solver before it greets the page: meanwhile the view shows its picture
    of the mesh and the seconds waited, then the studio once greeted."""
    if not (client_dir() / "widget.js").is_file():
        pytest.skip("the widget module is not built (./dev setup)")
    load = Session.load
    gate = threading.Event()

    def held_load(self: Session, *args: Any, **kwargs: Any) -> Any:
        gate.wait(60)
        return load(self, *args, **kwargs)

    monkeypatch.setattr(Session, "load", held_load)
    w = arap.widget(*arap.builtin_mesh("cactus"), height=VIEWPORT["height"])
    context, page, frame, errors = _open_page(browser, Kernel(w))
    try:
        note = page.wait_for_selector("[data-testid=arap-widget-preparing]", state="visible", timeout=scaled_ms(30))
        assert note is not None and "Preparing the solver" in note.inner_text()
        page.wait_for_function("() => document.querySelector('[data-testid=arap-widget-preparing] img')"
                               "?.naturalWidth === 480", timeout=scaled_ms(30))  # the kernel's picture, decoded
        page.wait_for_function("() => /[1-9][0-9]* s\\./.test(document.querySelector("  # the seconds count
                               "'[data-testid=arap-widget-preparing]').textContent)", timeout=scaled_ms(30))
        gate.set()
        frame.wait_for_function("() => window.__arap && window.__arap.ready", timeout=scaled_ms(60))
        page.wait_for_selector("[data-testid=arap-widget-preparing]", state="detached", timeout=scaled_ms(30))
        assert frame.evaluate("() => window.__arap.nVertices") == len(w.vertices)
    finally:
        gate.set()
        context.close()
        w.stop()
    assert not errors, f"errors in the page: {errors}"
