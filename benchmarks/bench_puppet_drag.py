"""Per-update latency of dragging a pin of a picture in the studio: the figure of ``bench_puppet.py`` opened as a
picture (flat textured mesh, element energy in its plane) at about 5,000 and 50,000 vertices, five pins (point
handles), the right hand dragged along a smooth path.

The studio runs in a subprocess (uvicorn on a free loopback port) with the picture as its starting mesh; a WebSocket
client (as ``bench_studio.py``'s) sends a drag, waits for its ``vertices`` frame and sends the next (a user whose
pointer follows the picture). Reported per mode (``rigid``, ``normal``, ``distort``) at the studio's default of
iterations per update (``asked_iterations``; a large mesh runs fewer where they would pass the drag's frame budget,
:data:`arap.server.solve_calls.DRAG_BUDGET_SECONDS`: ``iter`` is the mean it ran): the server's solve time per update
(``solve_ms`` of each frame), the round trip from sending the drag to receiving its frame (message in to frame out,
plus the loopback), both as median and p95 over the updates, against the targets of 16 ms at 5k and 50 ms at 50k
vertices; then the settle after the pin is released (the server's time from the release to converged, and its
iterations), against 0.2 s at 5k; and the mesher's time for the picture at each size (median of three, in this
process), against 0.5 s at 5k.

Peer: libigl's planar ARAP (``ARAP_ENERGY_TYPE_ELEMENTS``) of the same mesh, one ``arap_solve`` per update of the
iterations the studio is asked for, warm-started from its previous solution, the pins constrained at their nearest
vertices (libigl has no point handles), in this process; and for the settle, one ``arap_solve`` of as many iterations
as the studio's settle took, from libigl's shape at the last update.

Run: ``python benchmarks/bench_puppet_drag.py [--quick] [--updates N] [--modes rigid,normal] [--json OUT]``
(``--quick``: a 300 × 300 picture at about 1,000 and 5,000 vertices).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from websockets.asyncio.client import ClientConnection, connect

from arap.puppet.imagemesh import image_mesh
from arap.server.frames import decode_binary
from arap.server.messages import PARAMS
from bench_puppet import figure_picture
from benchjson import add_json_option, figure, write_results

ROOT = Path(__file__).resolve().parents[1]
TARGET_MS = {5000: 16.0, 50000: 50.0}
MESH_TARGET_S = 0.5

_SERVER = """
import sys
import numpy as np
from arap.server.pictures import picture_mesh
from arap.server.runner import make_server

picture = np.load(sys.argv[1])
mesh, look = picture_mesh(picture, "figure", 10_000_000, float(sys.argv[2]))
server, sock, url = make_server(mesh, "127.0.0.1", 0, max_vertices=10_000_000, log_level="warning")
server.config.app.state.studio.default_look = look
print(url, flush=True)
server.run(sockets=[sock])
"""


def spacing_for(img: NDArray[np.uint8], vertices: int) -> float:
    """The mesh spacing that gives about ``vertices`` vertices on the picture's opaque part (a triangular lattice)."""
    area = float((img[:, :, 3] > 0).sum())
    return float(np.sqrt(2.0 * area / (np.sqrt(3.0) * vertices)))


def start(img: NDArray[np.uint8], spacing: float, folder: Path) -> tuple[subprocess.Popen[str], str]:
    """The studio in a subprocess with the picture as its mesh; its ws:// URL."""
    np.save(folder / "picture.npy", img)
    proc = subprocess.Popen([sys.executable, "-c", _SERVER, str(folder / "picture.npy"), repr(spacing)],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if not line.startswith("http://"):
        proc.kill()
        raise RuntimeError(f"server did not start (got {line!r})")
    return proc, line.replace("http://", "ws://") + "ws"


async def _recv(ws: ClientConnection) -> tuple[dict[str, Any], Any]:
    msg = await asyncio.wait_for(ws.recv(), 600.0)
    if isinstance(msg, str):
        return json.loads(msg), None
    return decode_binary(msg)


async def _until(ws: ClientConnection, kind: str, **match: Any) -> tuple[dict[str, Any], Any]:
    while True:
        header, payload = await _recv(ws)
        if header["type"] == "error":
            raise RuntimeError(f"the server refused: {header}")
        if header["type"] == kind and all(header.get(k) == v for k, v in match.items()):
            return header, payload


def locate(V: NDArray[np.float64], F: NDArray[np.int64], p: NDArray[np.float64]) -> tuple[int, list[float]]:
    """The triangle of point ``p`` (x, y) and its barycentric coordinates (the nearest triangle if none holds it)."""
    A, B, C = V[F[:, 0], :2], V[F[:, 1], :2], V[F[:, 2], :2]
    e1, e2, d = B - A, C - A, p - A
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    l1 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
    l2 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
    L = np.column_stack([1 - l1 - l2, l1, l2])
    t = int(np.argmax(L.min(axis=1)))
    b = np.clip(L[t], 0.0, None)
    return t, (b / b.sum()).tolist()


def path(t: float, pin: NDArray[np.float64], reach: float) -> NDArray[np.float64]:
    """Where the dragged pin is at ``t`` seconds: a smooth loop of radius ``reach`` through its rest place."""
    a = 2 * math.pi * t / 3.0
    return pin + reach * np.array([math.sin(a), 0.5 * (1 - math.cos(a))])


def translation(d: NDArray[np.float64]) -> list[float]:
    M = np.eye(4)
    M[0, 3], M[1, 3] = d[0], d[1]
    return M.T.reshape(16).tolist()


async def drag_session(url: str, pins: NDArray[np.float64], h: int, updates: int,
                       mode: str) -> dict[str, Any]:
    """Open a session, pin the picture, drag the right hand ``updates`` times; the times per update."""
    async with connect(url, compression=None, max_size=None, open_timeout=120) as ws:
        header, payload = await _until(ws, "mesh")
        n, m = header["n_vertices"], header["n_faces"]
        V = np.frombuffer(bytes(payload[: 12 * n]), dtype="<f4").reshape(n, 3).astype(np.float64)
        F = np.frombuffer(bytes(payload[12 * n: 12 * n + 12 * m]), dtype="<u4").reshape(m, 3).astype(np.int64)
        await _until(ws, "state")
        await ws.send(json.dumps({"type": "set_params", "warp": mode}))
        await _until(ws, "state")
        studio_pins = np.column_stack([pins[:, 0], h - pins[:, 1]])  # the studio's y is up
        points = [dict(zip(("face", "barycentric"), locate(V, F, p), strict=True)) for p in studio_pins]
        await ws.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": [], "handle_groups": [],
                                  "points": points}))
        state, _ = await _until(ws, "state")
        factor_ms = float(state.get("stats", {}).get("factor_ms", math.nan))
        while True:  # the new constraints settle (nothing moved: at once) before the drags start
            data, _ = await _recv(ws)
            if data["type"] == "settle" and data["status"] != "settling":
                break
        reach = 0.15 * h
        solve, trip, iterations = [], [], []
        identity = translation(np.zeros(2))
        for seq in range(updates):
            shift = path(0.05 * (seq + 1), studio_pins[2], reach) - studio_pins[2]
            transforms = [identity, identity, translation(shift), identity, identity]
            sent = time.perf_counter()
            await ws.send(json.dumps({"type": "drag", "seq": seq, "transforms": transforms}))
            frame, _ = await _until(ws, "vertices", seq=seq)
            trip.append(1000 * (time.perf_counter() - sent))
            solve.append(float(frame["solve_ms"]))
            iterations.append(int(frame["iterations"]))
        released = time.perf_counter()
        await ws.send(json.dumps({"type": "end_drag"}))
        while True:  # the settle after the release, until converged (or its cap)
            data, _ = await _recv(ws)
            if data["type"] == "settle" and data["status"] in ("settled", "unconverged"):
                break
        settle_wall = 1000 * (time.perf_counter() - released)
    return {"mode": mode, "vertices": n, "triangles": m, "factor_ms": factor_ms,
            "asked_iterations": int(PARAMS["iterations"]["default"]), "iterations": float(np.mean(iterations)),
            "solve_median_ms": float(np.median(solve)), "solve_p95_ms": float(np.percentile(solve, 95)),
            "roundtrip_median_ms": float(np.median(trip)), "roundtrip_p95_ms": float(np.percentile(trip, 95)),
            "settle_ms": 1000 * float(data["seconds"] or 0.0), "settle_wall_ms": settle_wall,
            "settle_iterations": int(data["iterations"]), "settled": data["status"] == "settled",
            "V": V, "F": F, "pins": studio_pins, "reach": reach}


class IglPeer:
    """libigl's planar ARAP of the studio's mesh, the pins at their nearest vertices: per drag update one
    warm-started ``arap_solve`` of the iterations the studio is asked for, and the settle after the release as
    ``arap_solve`` of as many iterations as the studio's settle took, from the last update's shape."""

    def __init__(self, V: NDArray[np.float64], F: NDArray[np.int64], pins: NDArray[np.float64]) -> None:
        import igl

        self.igl = igl
        self.V2 = np.ascontiguousarray(V[:, :2])
        self.F = np.ascontiguousarray(F)
        self.b = np.array([int(np.argmin(np.hypot(*(self.V2 - p).T))) for p in pins], dtype=np.int64)
        self.data = igl.ARAPData()
        self.data.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS
        self.data.max_iter = 1
        igl.arap_precomputation(self.V2, self.F, 2, self.b, self.data)
        self.U = self.V2.copy()
        self.targets = self.V2[self.b].copy()

    def drag(self, reach: float, updates: int, iterations: int) -> dict[str, float]:
        """Times (ms) of the drag's updates, median and p95."""
        self.data.max_iter = max(iterations, 1)
        times = []
        for seq in range(updates):
            self.targets = self.V2[self.b].copy()
            self.targets[2] = path(0.05 * (seq + 1), self.V2[self.b[2]], reach)
            t0 = time.perf_counter()
            self.U = np.asarray(self.igl.arap_solve(self.targets, self.data, self.U), dtype=np.float64)
            times.append(1000 * (time.perf_counter() - t0))
        return {"igl_median_ms": float(np.median(times)), "igl_p95_ms": float(np.percentile(times, 95))}

    def settle(self, iterations: int) -> float:
        """Time (ms) of ``iterations`` iterations from the last update's shape (which is kept)."""
        self.data.max_iter = max(iterations, 1)
        t0 = time.perf_counter()
        self.igl.arap_solve(self.targets, self.data, self.U)
        return 1000 * (time.perf_counter() - t0)


async def measure(img: NDArray[np.uint8], pins: NDArray[np.float64], vertices: int, updates: int,
                  modes: list[str]) -> list[dict[str, Any]]:
    rows = []
    drag: dict[str, float] | None = None
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        proc, url = start(img, spacing_for(img, vertices), Path(tmp))
        started = time.perf_counter() - t0
        try:
            for mode in modes:
                r = await drag_session(url, pins, img.shape[0], updates, mode)
                V, F, studio_pins, reach = r.pop("V"), r.pop("F"), r.pop("pins"), r.pop("reach")
                try:
                    peer = IglPeer(V, F, studio_pins)
                except ImportError:
                    peer = None
                if peer is not None:  # the same drag (it leaves libigl at the last update's shape), then the settle
                    updates_ms = peer.drag(reach, updates, r["asked_iterations"])
                    drag = drag if drag is not None else updates_ms  # the first mode's: libigl's is one energy
                    r.update(drag)
                    r["igl_settle_ms"] = peer.settle(r["settle_iterations"])
                r["asked"] = vertices
                r["server_start_s"] = started
                rows.append(r)
        finally:
            proc.terminate()
            proc.wait(30)
    return rows


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a 300 x 300 picture at about 1,000 and 5,000 vertices")
    p.add_argument("--updates", type=int, default=60, help="drag updates per mode and size (default: 60)")
    p.add_argument("--modes", default="rigid,normal,distort", help="warp modes, comma-separated")
    p.add_argument("--sizes", default=None, help="vertex counts, comma-separated (default: 5000,50000)")
    add_json_option(p, "bench_puppet_drag")
    args = p.parse_args(argv)
    size, counts = (300, [1000, 5000]) if args.quick else (1000, [5000, 50000])
    if args.sizes:
        counts = [int(c) for c in args.sizes.split(",")]
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    img, pins, _ = figure_picture(size)
    print(f"{size}x{size} cut-out, 5 pins, the right hand dragged; {args.updates} updates per mode")
    print(f"{'vertices':>9} {'mode':>8} {'iter':>5} {'solve med':>9} {'p95':>6} {'trip med':>8} {'p95':>6} "
          f"{'target':>6} {'igl med':>7} {'p95':>6} {'settle':>7} {'iter':>5} {'igl':>7}")
    rows, figures = [], []
    for count in counts:
        spacing = spacing_for(img, count)
        mesh_times = []
        for _ in range(3):
            t0 = time.perf_counter()
            image_mesh(img, spacing)
            mesh_times.append(time.perf_counter() - t0)
        mesh_s = float(np.median(mesh_times))
        print(f"{'':>9} meshing the picture: {1000 * mesh_s:.0f} ms (median of 3; target at 5k: "
              f"{1000 * MESH_TARGET_S:.0f} ms)")
        for r in asyncio.run(measure(img, pins, count, args.updates, modes)):
            r["mesh_s"] = mesh_s
            rows.append(r)
            target = TARGET_MS.get(count, math.nan)
            peer = (f"{r['igl_median_ms']:>7.1f} {r['igl_p95_ms']:>6.1f}" if "igl_median_ms" in r
                    else f"{'(no libigl)':>14}")
            settle = f"{r['settle_ms']:>7.1f} {r['settle_iterations']:>5}{'' if r['settled'] else '!'}"
            igl_settle = f"{r['igl_settle_ms']:>7.1f}" if "igl_settle_ms" in r else ""
            print(f"{r['vertices']:>9,} {r['mode']:>8} {r['iterations']:>5.2f} {r['solve_median_ms']:>9.1f} "
                  f"{r['solve_p95_ms']:>6.1f} {r['roundtrip_median_ms']:>8.1f} {r['roundtrip_p95_ms']:>6.1f} "
                  f"{target:>6.0f} {peer} {settle} {igl_settle}")
            n = f"{r['vertices'] / 1000:.0f}k vertices"
            figures.append(figure(f"puppet drag: {r['mode']} update round trip (median), {n}",
                                  r["roundtrip_median_ms"] / 1000, "s", "libigl arap_solve per update",
                                  r["igl_median_ms"] / 1000 if "igl_median_ms" in r else None))
            figures.append(figure(f"puppet drag: {r['mode']} server solve per update (median), {n}",
                                  r["solve_median_ms"] / 1000, "s", "libigl arap_solve per update",
                                  r["igl_median_ms"] / 1000 if "igl_median_ms" in r else None))
            figures.append(figure(f"puppet drag: {r['mode']} settle after release, {n}", r["settle_ms"] / 1000, "s",
                                  "libigl arap_solve of as many iterations",
                                  r["igl_settle_ms"] / 1000 if "igl_settle_ms" in r else None))
    if args.json is not None:
        write_results(args.json, "bench_puppet_drag", figures, rows)


if __name__ == "__main__":
    main()
