"""Client JavaScript per ``vertices`` frame in headless Chromium, full frames against a 20% region's subset frames.

Starts the studio (as ``bench_studio.py`` does), opens it in the system's Chromium through Playwright, uploads
the mesh through the page, then sends through the page's own WebSocket a constraint set and drags: once with the
whole mesh as region of interest (full frames) and once with the top 20% along y (subset frames). It prints the
median and p95 of the JavaScript time the page spent applying each frame (``window.__arap.frameMs``: decoding
the positions, writing them into the vertex buffer, the normals and the bounds; drawing excluded), and saves a
screenshot of each run to the output folder.

Before that, upload-to-ready: from the page having the file in its file input (Playwright's transfer of the
file into the browser excluded) until the page shows the mesh and has nothing pending (ready to drag), measured
on a page of its own whose WebSocket is not relayed through Playwright. It is split into the server's parse and
repair of the same bytes (timed again in this process, median of 3), the encoding of the mesh message, the
page's JavaScript for the mesh message (``window.__arap.meshMs``) and the rest (reading the file, transfers,
waiting). Then the time from sending the first constraint set to the answer of its first drag, with the
server's factorisation time (``factor_ms``).

Usage::

    .venv/bin/python benchmarks/bench_client.py [--mesh ../shared/meshes/armadillo.obj | --sphere 134000]
        [--updates 30] [--out artifacts/bench_client]
    .venv/bin/python benchmarks/bench_client.py --quick   # a sphere of 1,000 vertices, 3 drags per constraint set:
                                                          # a check that it runs, not a measurement
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from playwright.sync_api import Browser, Page, WebSocketRoute, sync_playwright

from arap.server.meshdata import load_upload, mesh_frame
from bench_studio import DEFAULT_MESH, ROOT, server_upload_steps, sphere_obj, start_server
from benchjson import add_json_option, figure, write_results

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking"]


def _drags(page: Page, server: WebSocketRoute, roi: list[int] | None, fixed: list[int], handle: list[int],
           updates: int, seq0: int, height: float) -> tuple[list[float], float]:
    """Frame times of ``updates`` drags after a constraint set, and the time until the first was answered."""
    t0 = time.perf_counter()
    first_ms = float("nan")
    server.send(json.dumps({"type": "set_constraints", "roi": roi, "fixed": fixed, "handle_groups": [handle]}))
    seen = 0
    for k in range(1, updates + 1):
        M = np.eye(4)
        M[0, 3] = 0.1 * height * np.sin(k / 5)
        server.send(json.dumps({"type": "drag", "seq": seq0 + k, "transforms": [M.T.reshape(16).tolist()]}))
        page.wait_for_function(f"() => window.__arap.lastSeq === {seq0 + k}", timeout=300_000)
        if k == 1:
            first_ms = 1000 * (time.perf_counter() - t0)
        seen += 1
    return list(page.evaluate("() => window.__arap.frameMs"))[-seen:], first_ms


def _server_parts(mesh: Path) -> dict[str, float]:
    """The server's parse and repair of the upload, and the encoding of the mesh message (ms, median of 3)."""
    data = mesh.read_bytes()
    load, encode = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        loaded = load_upload(data, mesh.name, 10**8)
        t1 = time.perf_counter()
        mesh_frame(loaded)
        load.append(1000 * (t1 - t0))
        encode.append(1000 * (time.perf_counter() - t1))
    return {"parse_repair_ms": float(np.median(load)), "encode_ms": float(np.median(encode))}


def _upload(page: Page, mesh: Path, marks: dict[str, float] | None = None) -> float:
    """Hand ``mesh`` to the page's file input; milliseconds from the page having the file (Playwright's transfer
    of the file into the browser excluded) until it shows the mesh with nothing pending. ``marks`` receives the
    wall-clock times (ms since the epoch) of both ends."""
    page.wait_for_function("() => window.__arap && window.__arap.ready && !window.__arap.busy", timeout=120_000)
    page.get_by_test_id("file-input").set_input_files(str(mesh))
    t0, wall0 = time.perf_counter(), time.time()
    page.wait_for_function(f"() => window.__arap.ready && window.__arap.meshName.startsWith('{mesh.stem}')"
                           " && !window.__arap.busy", timeout=300_000, polling=10)
    if marks is not None:
        marks.update(given=1000 * wall0, seen=1000 * time.time())
    return 1000 * (time.perf_counter() - t0)


def upload_timeline(page_at: dict[str, float], server: dict[str, Any], mesh_js_ms: float) -> list[tuple[str, float]]:
    """Upload-to-ready split into its steps (ms), from the page's wall-clock marks and the server's log line."""
    steps: list[tuple[str, float]] = [("file input set until the page's change handler", page_at["chosen"]
                                       - page_at.get("given", float("nan"))),
                                      ("page reads the file", page_at["read"] - page_at["chosen"]),
                                      ("page frames and hands it to its WebSocket", page_at["sent"] - page_at["read"])]
    if server:
        arrived = 1000 * server["arrived"]
        mesh_sent = 1000 * server["mesh_sent"]
        steps += [("transfer to the server (until received whole)", arrived - page_at["sent"]),
                  ("server: frame decoded", server["decode_ms"]), ("server: waiting in the queue", server["queued_ms"]),
                  ("server: parse and repair (in place, under load)", server["parse_repair_ms"]),
                  ("… of which the thread's CPU time", server.get("parse_repair_cpu_ms", float("nan"))),
                  ("server: mesh message encoded", server["encode_ms"]),
                  ("server: mesh message handed to the socket", server["send_mesh_ms"]),
                  ("transfer to the page (until its message event)", page_at["received"] - mesh_sent)]
    else:
        steps.append(("transfer, server and transfer back", page_at["received"] - page_at["sent"]))
    steps += [("page JavaScript for the mesh message", mesh_js_ms),
              ("first frame drawn (SwiftShader)", page_at.get("drawn", float("nan")) - page_at["shown"]),
              ("until the benchmark sees the page ready", page_at.get("seen", float("nan"))
               - page_at.get("drawn", float("nan")))]
    return steps


def _upload_to_ready(browser: Browser, http: str, mesh: Path,
                     log: Path) -> tuple[float, float, list[tuple[str, float]]]:
    """Upload-to-ready on a page of its own whose WebSocket is not relayed through Playwright (a relayed one
    carries every byte through this process), the page's JavaScript time for the mesh message, and the steps."""
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.goto(http)
    marks: dict[str, float] = {}
    ready_ms = _upload(page, mesh, marks)
    mesh_js_ms = float(page.evaluate("() => (typeof window.__arap.meshMs === 'number' ? window.__arap.meshMs : NaN)"))
    if not page.evaluate("() => window.__arap.uploadAt !== undefined"):  # a client without the marks
        page.close()
        return ready_ms, mesh_js_ms, []
    page.wait_for_function("() => window.__arap.uploadAt.drawn !== undefined", timeout=60_000)
    page_at = {**page.evaluate("() => window.__arap.uploadAt"), **marks}
    page.close()
    time.sleep(0.2)  # the server's log line is written after the state is sent
    shown = [("upload to mesh shown, drawing excluded (page has the file → its JavaScript done)",
              page_at["shown"] - page_at["given"])]
    return ready_ms, mesh_js_ms, shown + upload_timeline(page_at, server_upload_steps(log, mesh.stem), mesh_js_ms)


def run(mesh: Path, updates: int, out: Path) -> dict[str, Any]:
    log = out / "server.log"
    log.unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    proc, url = start_server(log, hook=True)
    http = url.replace("ws://", "http://").rsplit("/ws", 1)[0] + "/"
    results: dict[str, Any] = {"mesh": mesh.name}
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, timeout=60_000)
            ready_ms, mesh_js_ms, timeline = _upload_to_ready(browser, http, mesh, log)
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            route: dict[str, WebSocketRoute] = {}

            factor_ms: list[float] = []

            def relay(ws: WebSocketRoute) -> None:
                server = ws.connect_to_server()
                route["server"] = server

                def from_server(m: str | bytes) -> None:
                    if isinstance(m, str) and '"state"' in m[:64]:
                        factor_ms.append(float(json.loads(m).get("stats", {}).get("factor_ms") or 0.0))
                    ws.send(m)

                server.on_message(from_server)
                ws.on_message(lambda m: server.send(m))

            page.route_web_socket("**/ws", relay)
            page.goto(http)
            _upload(page, mesh)
            V = np.asarray(page.evaluate("() => window.__arap.positions()")).reshape(-1, 3)
            y = V[:, 1]
            height = float(np.ptp(y))
            handle = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
            server = route["server"]
            states = len(factor_ms)
            whole, first_ms = _drags(page, server, None, np.flatnonzero(y <= np.quantile(y, 0.1)).tolist(), handle,
                                     updates, 1000, height)
            factor = max(factor_ms[states:], default=float("nan"))  # the constraint set's state
            page.screenshot(path=str(out / f"{mesh.stem}-whole.png"))
            band = (y >= np.quantile(y, 0.8)) & (y <= np.quantile(y, 0.82))
            region, _ = _drags(page, server, np.flatnonzero(y >= np.quantile(y, 0.8)).tolist(),
                               np.flatnonzero(band).tolist(), handle, updates, 2000, height)
            page.screenshot(path=str(out / f"{mesh.stem}-roi20.png"))
            browser.close()
        parts = _server_parts(mesh)
        rest = ready_ms - parts["parse_repair_ms"] - parts["encode_ms"] - mesh_js_ms
        print(f"{mesh.name}: {len(V):,} vertices, {mesh.stat().st_size / 2**20:.1f} MiB")
        print(f"  upload to ready {ready_ms:.0f} ms: server parse and repair {parts['parse_repair_ms']:.0f} ms, "
              f"mesh message encoded {parts['encode_ms']:.0f} ms, page JavaScript for the mesh {mesh_js_ms:.0f} ms, "
              f"rest (file read, transfers, waiting) {rest:.0f} ms")
        for k, (label, ms) in enumerate(timeline):
            print(f"  {label}: {ms:.0f} ms" if k == 0 else f"    {label:<50} {ms:8.1f} ms")
        print(f"  first constraint set to its first drag answered {first_ms:.0f} ms (factorisation {factor:.0f} ms)")
        results.update(upload_steps_ms=dict(timeline), upload_to_ready_ms=ready_ms, mesh_js_ms=mesh_js_ms,
                       first_drag_ms=first_ms,
                       factor_ms=factor, **parts)
        print("  client JavaScript per vertices frame (drawing excluded)")
        for label, times in (("whole mesh (full frames)", whole), ("20% region (subset frames)", region)):
            t = np.asarray(times[1:])  # the first frame of a constraint set is full in both runs
            print(f"    {label:<28} median {np.median(t):6.1f} ms, p95 {np.percentile(t, 95):6.1f} ms "
                  f"({len(t)} frames)")
            results[label] = {"median_ms": float(np.median(t)), "p95_ms": float(np.percentile(t, 95))}
        print(f"screenshots in {out}")
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    return results


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", type=Path, default=DEFAULT_MESH, help="mesh file to upload")
    parser.add_argument("--sphere", type=int, default=0, metavar="N",
                        help="upload a geodesic sphere of about N vertices (OBJ) instead of --mesh")
    parser.add_argument("--updates", type=int, default=30, help="drags per constraint set")
    parser.add_argument("--out", type=Path, default=ROOT / "artifacts" / "bench_client",
                        help="folder for the screenshots")
    parser.add_argument("--quick", action="store_true", help="a sphere of 1,000 vertices, 3 drags per constraint set")
    add_json_option(parser, "bench_client")
    args = parser.parse_args(argv)
    if args.quick:
        args.sphere, args.updates = 1000, 3
    if args.sphere:
        with tempfile.TemporaryDirectory() as tmp:
            mesh = sphere_obj(args.sphere, Path(tmp))
            results = run(mesh, args.updates, args.out)
    else:
        if not args.mesh.is_file():
            parser.error(f"mesh not found: {args.mesh}")
        mesh = args.mesh
        results = run(mesh, args.updates, args.out)
    if args.json:
        whole, region = results.get("whole mesh (full frames)"), results.get("20% region (subset frames)")
        figures = []
        if whole and region:
            figures = [figure(f"client JavaScript per frame, 20% region moving, median, {mesh.name}",
                              region["median_ms"], "ms", "whole mesh moving", whole["median_ms"]),
                       figure(f"client JavaScript per frame, 20% region moving, p95, {mesh.name}", region["p95_ms"],
                              "ms", "whole mesh moving", whole["p95_ms"])]
        write_results(args.json, "bench_client", figures, {"mesh": mesh.name, "results": results})


if __name__ == "__main__":
    main()
