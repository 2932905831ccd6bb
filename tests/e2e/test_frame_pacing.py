"""The page draws vertices frames at the rate it can: a frame received waits for the next animation frame and a
newer one replaces it, so a page slower than the server's stream still shows the final shape as soon as the server
says that it settled (and exactly that shape, across dropped full and subset frames)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from playwright.sync_api import Browser, WebSocketRoute, expect

from arap.server.frames import encode_binary
from arap.server.liveframes import still_frame_header
from tests.e2e.conftest import VIEWPORT, positions, wait_for_page, wait_ready
from tests.waiting import scaled_ms, time_factor

pytestmark = pytest.mark.e2e

SLOW_MS = 40
"""Extra JavaScript time each applied frame takes: the page draws at most 25 shapes a second."""

MARK_SETTLED = """() => {
  const cell = document.querySelector('[data-testid=settle-status]');
  window.__shownSettled = null;
  new MutationObserver(() => {
    if (cell.dataset.status === 'settled' && window.__shownSettled === null) {
      window.__shownSettled = { at: Date.now(), positions: Array.from(window.__arap.positions()) };
    }
  }).observe(cell, { attributes: true, childList: true, characterData: true, subtree: true });
}"""


def _full(U: np.ndarray, movable: np.ndarray) -> bytes:
    header = still_frame_header(-1, -1, len(movable))
    return encode_binary(header, U.astype("<f4").tobytes(), movable.astype("<u4").tobytes())


def _subset(U: np.ndarray, movable: np.ndarray) -> bytes:
    return encode_binary(still_frame_header(-1, len(movable), 0), U[movable].astype("<f4").tobytes())


def _settle(status: str, iterations: int) -> str:
    return json.dumps({"type": "settle", "status": status, "iterations": iterations, "energy": 0.5 / iterations,
                       "seconds": None if status == "settling" else 1.0})


def test_a_slow_page_shows_the_settled_shape_promptly(browser: Browser, server_url: str) -> None:
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    route: dict[str, WebSocketRoute] = {}

    def relay(ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()
        route["page"] = ws
        server.on_message(lambda message: ws.send(message))
        ws.on_message(lambda message: server.send(message))

    page.route_web_socket("**/ws", relay)
    page.goto(server_url)
    wait_ready(page)
    V = positions(page).astype(np.float64)
    n = len(V)
    rng = np.random.default_rng(3)
    first = np.sort(rng.choice(n, n // 2, replace=False))  # the movable vertices of the first full frame
    second = np.sort(rng.choice(n, n // 3, replace=False))  # and of the second
    page.evaluate(MARK_SETTLED)
    page.evaluate(f"() => window.__arap.slowDrawing({SLOW_MS})")
    before = page.evaluate("() => window.__arap.frames")

    # the shape as the protocol defines it: a full frame sets every vertex, a subset frame its movable ones
    shown = V.copy()
    frames: list[bytes | str] = []
    count = 0
    for movable in (first, second):
        for k in range(60):
            count += 1
            U = V + 0.002 * count * np.array([1.0, 0.5, -0.25]) + 0.01 * rng.standard_normal((n, 3))
            if k == 0:
                frames.append(_full(U, movable))
                shown = U.copy()
            else:
                frames.append(_subset(U, movable))
                shown[movable] = U[movable]
            frames.append(_settle("settling", 10 * count))
    page_ws = route["page"]
    started = time.time()
    for message in frames:
        page_ws.send(message)
    sent = time.time()
    page_ws.send(_settle("settled", 10 * count))
    settled_sent = time.time()
    wait_for_page(page, "() => window.__shownSettled !== null", "the page to show the settled shape", 60)
    result = page.evaluate("() => window.__shownSettled")
    lag_ms = result["at"] - settled_sent * 1000.0
    frames_seen = page.evaluate("() => window.__arap.frames")
    received = frames_seen["received"] - before["received"]
    applied = frames_seen["applied"] - before["applied"]
    print(f"sent {count} frames in {1000 * (sent - started):.0f} ms; settled shown {lag_ms:.0f} ms after it was "
          f"sent; {applied} of {received} frames applied")
    assert received == count
    # exactly the last shape, bit for bit, although most frames (full ones among them) were never applied
    np.testing.assert_array_equal(np.asarray(result["positions"], dtype="<f4").view("<u4"),
                                  shown.reshape(-1).astype("<f4").view("<u4"))
    assert applied < count / 2, "a page slower than the stream should skip the frames it cannot draw"
    # sooner than applying every frame would take (count * SLOW_MS = 4.8 s). The lag includes the relay through
    # Playwright, which a loaded machine slows most: the bound is stretched by the load factor, and the frames
    # skipped (above) are what shows that the page kept up.
    factor = time_factor()
    assert lag_ms < count * SLOW_MS * factor, (f"the page showed the settled shape {lag_ms:.0f} ms after the server "
                                               f"said so (load factor {factor:.3g})")
    page.evaluate("() => window.__arap.slowDrawing(0)")
    context.close()


def test_the_settling_badge_follows_the_settle_messages(browser: Browser, server_url: str) -> None:
    """Over the view, the settling's progress (iterations and energy) while it runs, then how it ended."""
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    route: dict[str, WebSocketRoute] = {}

    def relay(ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()
        route["page"] = ws
        server.on_message(lambda message: ws.send(message))
        ws.on_message(lambda message: server.send(message))

    page.route_web_socket("**/ws", relay)
    page.goto(server_url)
    wait_ready(page)
    badge = page.get_by_test_id("settle-badge")
    route["page"].send(_settle("settled", 1).replace('"iterations": 1', '"iterations": 0'))
    expect(page.get_by_test_id("settle-status")).to_have_attribute("data-status", "settled")
    expect(badge).to_be_hidden()  # a shape settled already (after undo, redo or loading) is no news
    route["page"].send(_settle("settling", 20))
    expect(badge).to_be_visible()
    expect(badge).to_have_text("Settling… after 20 iterations, energy 0.0250000")
    route["page"].send(_settle("settling", 50))
    expect(badge).to_have_text("Settling… after 50 iterations, energy 0.0100000")
    route["page"].send(_settle("settled", 80))
    expect(badge).to_have_text("Settled after 80 iterations, energy 0.00625000")
    expect(badge).to_be_hidden(timeout=scaled_ms(5))
    context.close()
