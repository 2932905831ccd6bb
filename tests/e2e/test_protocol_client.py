"""The page takes its controls from the generated protocol module and refuses a server of another protocol
version."""

from __future__ import annotations

import json

import pytest
from playwright.sync_api import Browser, Page, WebSocketRoute, expect

from arap.server.messages import EXPORT_FORMATS, PARAMS
from tests.e2e.conftest import VIEWPORT, wait_ready
from tests.waiting import scaled_ms

pytestmark = pytest.mark.e2e


def test_controls_follow_the_protocol(page: Page) -> None:
    slider = page.get_by_test_id("iterations")
    assert slider.get_attribute("min") == str(PARAMS["iterations"]["min"])
    assert slider.get_attribute("max") == str(PARAMS["iterations"]["max"])  # the server's range, not 20
    for name in ("energy", "weights"):
        options = page.get_by_test_id(name).locator("option")
        assert options.evaluate_all("os => os.map(o => o.value)") == PARAMS[name]["choices"]
        assert options.evaluate_all("os => os.map(o => o.textContent)") == [
            PARAMS[name]["labels"][c] for c in PARAMS[name]["choices"]]
    for fmt in EXPORT_FORMATS:
        expect(page.get_by_test_id(f"export-{fmt}")).to_have_text(f"Export {fmt.upper()}")
    slider.evaluate("e => { e.value = '60'; e.dispatchEvent(new Event('input'));"
                    " e.dispatchEvent(new Event('change')); }")
    page.wait_for_function("() => window.__arap.params.iterations === 60")  # beyond the old cap of 20
    expect(page.locator("#iterations-val")).to_have_text("60")
    alpha = page.get_by_test_id("alpha")
    expect(alpha).to_be_hidden()  # only smooth rotations has a rotation term
    page.get_by_test_id("energy").select_option("smooth_rotations")
    expect(alpha).to_be_visible()
    assert alpha.get_attribute("max") == str(PARAMS["alpha"]["max"])
    alpha.evaluate("e => { e.value = '0.1'; e.dispatchEvent(new Event('input'));"
                   " e.dispatchEvent(new Event('change')); }")
    page.wait_for_function("() => window.__arap.params.alpha === 0.1")


def test_a_server_of_another_protocol_version_is_refused(browser: Browser, server_url: str) -> None:
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()

    def relay(ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()

        def from_server(message: str | bytes) -> None:
            if isinstance(message, str) and json.loads(message).get("type") == "welcome":
                message = json.dumps(json.loads(message) | {"protocol": 999})
            ws.send(message)

        server.on_message(from_server)
        ws.on_message(lambda message: server.send(message))

    page.route_web_socket("**/ws", relay)
    page.goto(server_url)
    expect(page.get_by_test_id("status-text")).to_contain_text("reload the page", timeout=scaled_ms(30))
    expect(page.get_by_test_id("status-text")).to_contain_text("version 999")
    # the mesh and state that follow the welcome arrive, and are ignored
    page.wait_for_function("() => window.__arap.messages >= 3", timeout=scaled_ms(30))
    assert not page.evaluate("() => window.__arap.ready")
    assert page.evaluate("() => window.__arap.nVertices") == 0
    context.close()


def test_the_shape_line_tells_each_settle_status(browser: Browser, server_url: str) -> None:
    """The Shape line for each settle status (with correct plurals); a new mesh clears it, and a connection lost while
    settling does not leave it claiming to settle. The server's own settle messages are held back: the test sends
    them."""
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    route: dict[str, WebSocketRoute] = {}

    def relay(ws: WebSocketRoute) -> None:
        server = ws.connect_to_server()
        route["page"] = ws

        def from_server(message: str | bytes) -> None:
            if isinstance(message, str) and json.loads(message).get("type") == "settle":
                return
            ws.send(message)

        server.on_message(from_server)
        ws.on_message(lambda message: server.send(message))

    def settle(status: str, iterations: int, energy: float | None) -> None:
        route["page"].send(json.dumps({"type": "settle", "status": status, "iterations": iterations,
                                       "energy": energy, "seconds": 0.5}))

    page.route_web_socket("**/ws", relay)
    page.goto(server_url)
    wait_ready(page)
    shape = page.get_by_test_id("settle-status")
    expect(shape).to_have_text("–")
    cases = [
        ("settling", 0, None, "settling…"),
        ("settling", 1, 0.25, "settling… after 1 iteration, energy 0.250000"),
        ("stopped", 12, 0.2, "paused (editing) after 12 iterations, energy 0.200000"),
        ("unconverged", 3000, 2.6, "not converged after 3,000 iterations, energy 2.60000"),
        ("settled", 1, 0.1, "settled after 1 iteration, energy 0.100000"),
        ("settled", 0, 0.0, "settled, energy 0.00000"),  # after undo, redo, apply, loading: settled already
    ]
    for status, iterations, energy, text in cases:
        settle(status, iterations, energy)
        expect(shape).to_have_text(text)
        expect(shape).to_have_attribute("data-status", status)

    # a new mesh: nothing is known of its shape until the server says
    settle("settled", 86, 0.142665)
    expect(shape).to_contain_text("settled after 86 iterations")
    other = page.evaluate("() => window.__arap.builtins.find((n) => n !== window.__arap.meshName)")
    page.get_by_test_id("builtin-select").select_option(other)
    page.wait_for_function(f"() => window.__arap.meshName === {other!r}")
    expect(shape).to_have_text("–")
    expect(shape).to_have_attribute("data-status", "")

    # the connection drops while the shape settles: the line no longer says it settles
    settle("settling", 242, 0.3)
    expect(shape).to_contain_text("settling…")
    route["page"].close()
    expect(shape).to_have_attribute("data-status", "interrupted", timeout=scaled_ms(10))
    expect(shape).to_contain_text("unknown")
    expect(shape).not_to_contain_text("settling…")
    wait_ready(page)  # reconnected
    context.close()
