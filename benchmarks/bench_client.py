"""Client JavaScript per ``vertices`` frame in headless Chromium, full frames against a 20% region's subset frames.

Starts the studio (as ``bench_studio.py`` does), opens it in the system's Chromium through Playwright, uploads
the mesh through the page, then sends through the page's own WebSocket a constraint set and drags: once with the
whole mesh as region of interest (full frames) and once with the top 20% along y (subset frames). It prints the
median and p95 of the JavaScript time the page spent applying each frame (``window.__arap.frameMs``: decoding
the positions, writing them into the vertex buffer and the normals; drawing excluded), and saves a screenshot
of each run to the output folder.

Usage::

    .venv/bin/python benchmarks/bench_client.py [--mesh ../shared/meshes/armadillo.obj] [--updates 30]
        [--out artifacts/bench_client]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
from playwright.sync_api import Page, WebSocketRoute, sync_playwright

from bench_studio import DEFAULT_MESH, ROOT, start_server

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking"]


def _drags(page: Page, server: WebSocketRoute, roi: list[int] | None, fixed: list[int], handle: list[int],
           updates: int, seq0: int, height: float) -> list[float]:
    server.send(json.dumps({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [handle]}))
    seen = 0
    for k in range(1, updates + 1):
        M = np.eye(4)
        M[0, 3] = 0.1 * height * np.sin(k / 5)
        server.send(json.dumps({"type": "drag", "seq": seq0 + k, "transforms": [M.T.reshape(16).tolist()]}))
        page.wait_for_function(f"() => window.__arap.lastSeq === {seq0 + k}", timeout=120_000)
        seen += 1
    return list(page.evaluate("() => window.__arap.frameMs"))[-seen:]


def run(mesh: Path, updates: int, out: Path) -> dict[str, Any]:
    proc, url = start_server()
    http = url.replace("ws://", "http://").rsplit("/ws", 1)[0] + "/"
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {"mesh": mesh.name}
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, timeout=60_000)
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            route: dict[str, WebSocketRoute] = {}

            def relay(ws: WebSocketRoute) -> None:
                server = ws.connect_to_server()
                route["server"] = server
                server.on_message(lambda m: ws.send(m))
                ws.on_message(lambda m: server.send(m))

            page.route_web_socket("**/ws", relay)
            page.goto(http)
            page.wait_for_function("() => window.__arap && window.__arap.ready", timeout=120_000)
            page.get_by_test_id("file-input").set_input_files(str(mesh))
            page.wait_for_function(f"() => window.__arap.ready && window.__arap.meshName.startsWith('{mesh.stem}')"
                                   " && !window.__arap.busy", timeout=300_000)
            V = np.asarray(page.evaluate("() => window.__arap.positions()")).reshape(-1, 3)
            y = V[:, 1]
            height = float(np.ptp(y))
            handle = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
            server = route["server"]
            whole = _drags(page, server, None, np.flatnonzero(y <= np.quantile(y, 0.1)).tolist(), handle, updates,
                           1000, height)
            page.screenshot(path=str(out / f"{mesh.stem}-whole.png"))
            band = (y >= np.quantile(y, 0.8)) & (y <= np.quantile(y, 0.82))
            region = _drags(page, server, np.flatnonzero(y >= np.quantile(y, 0.8)).tolist(),
                            np.flatnonzero(band).tolist(), handle, updates, 2000, height)
            page.screenshot(path=str(out / f"{mesh.stem}-roi20.png"))
            browser.close()
        print(f"{mesh.name}: {len(V):,} vertices; client JavaScript per vertices frame (drawing excluded)")
        for label, times in (("whole mesh (full frames)", whole), ("20% region (subset frames)", region)):
            t = np.asarray(times[1:])  # the first frame of a constraint set is full in both runs
            print(f"  {label:<28} median {np.median(t):6.1f} ms, p95 {np.percentile(t, 95):6.1f} ms "
                  f"({len(t)} frames)")
            results[label] = {"median_ms": float(np.median(t)), "p95_ms": float(np.percentile(t, 95))}
        print(f"screenshots in {out}")
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", type=Path, default=DEFAULT_MESH, help="mesh file to upload")
    parser.add_argument("--updates", type=int, default=30, help="drags per constraint set")
    parser.add_argument("--out", type=Path, default=ROOT / "artifacts" / "bench_client",
                        help="folder for the screenshots")
    args = parser.parse_args()
    if not args.mesh.is_file():
        parser.error(f"mesh not found: {args.mesh}")
    run(args.mesh, args.updates, args.out)


if __name__ == "__main__":
    main()
