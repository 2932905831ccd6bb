"""Take the documentation's studio screenshot (docs/images/studio.jpg) in headless Chromium.

Run from the repository root with the client built (``./dev setup``): ``.venv/bin/python tools/docs_screenshots.py``.
It serves the built-in cactus, loads a constraints file (anchors at the bottom, the top moved and turned) and saves
the page once the shape has settled.
"""

from __future__ import annotations

import json
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from playwright.sync_api import sync_playwright

import arap
from arap.server import make_server

OUT = Path(__file__).resolve().parents[1] / "docs" / "images" / "studio.jpg"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]


def constraints_document(V: np.ndarray) -> dict[str, object]:
    y = V[:, 1]
    fixed = np.flatnonzero(y <= y.min() + 0.08 * np.ptp(y))
    handles = np.flatnonzero(y >= y.max() - 0.12 * np.ptp(y))
    top = V[handles].mean(axis=0)
    a = np.radians(35)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    targets = (V[handles] - top) @ R.T + top + np.array([0.45, -0.25, 0.0]) * np.ptp(y)
    return {"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": targets.tolist()}


def main() -> None:
    V, _ = arap.builtin_mesh("cactus")
    server, sock, url = make_server("cactus", "127.0.0.1", 0)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    try:
        with tempfile.TemporaryDirectory() as tmp, sync_playwright() as pw:
            path = Path(tmp) / "cactus-bend.json"
            path.write_text(json.dumps(constraints_document(V)))
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=FLAGS)
            page = browser.new_page(viewport={"width": 1280, "height": 780})
            page.goto(url)
            page.wait_for_function("() => window.__arap && window.__arap.ready && !window.__arap.busy", timeout=60_000)
            page.set_input_files("#constraints-input", str(path))
            page.wait_for_function("() => document.querySelector('[data-testid=settle-status]')"
                                   ".textContent.startsWith('settled')", timeout=60_000)
            page.wait_for_timeout(500)
            OUT.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(OUT), type="jpeg", quality=82)
            browser.close()
    finally:
        server.should_exit = True
        thread.join(10)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
