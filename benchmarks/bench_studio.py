"""Interactive throughput and latency of the studio server, measured like a user dragging a handle.

Starts the real server (uvicorn in a subprocess on a free loopback port), uploads a mesh through the WebSocket
(``upload`` message: the server never opens a path a client names), selects the whole mesh as region of interest,
fixes the lowest 10% of the vertices along y and makes the top 10% one handle group, then drags that handle along
a smooth path:

* **interactive**: send a drag, wait for its ``vertices`` frame, send the next (a user whose pointer follows the
  shape);
* **firehose**: send drags at 60 Hz regardless of answers (pointer events); the server drops stale ones.

It reports updates per second and the latency from sending a drag to receiving its vertices (median, p95) for 1
and 3 iterations per update, then runs N concurrent dragging sessions and reports how many hold ≥ 10 updates/s.

With ``--payload`` it reports instead, per mesh, upload-to-ready (upload sent until the mesh and state arrived,
and until the first drag of a constraint set was answered, first factorisation included) and the bytes and
server time per update for the whole mesh as region of interest (full frames) and for a region of the top 20%
along y (subset frames). ``--subdivide`` also runs it on the mesh subdivided once (``trimesh.remesh.subdivide``:
about 4 times the vertices, 172k for the armadillo), written to a temporary folder; ``--sphere N`` also on a
geodesic sphere of about N vertices written as OBJ. The first answer is split into the server's factorisation
(``factor_ms`` of the constraint set's ``state``) and the rest.

Usage::

    .venv/bin/python benchmarks/bench_studio.py [--mesh ../shared/meshes/armadillo.obj] [--seconds 5]
    .venv/bin/python benchmarks/bench_studio.py --payload --subdivide [--sphere 134000] [--updates 30]
    .venv/bin/python benchmarks/bench_studio.py --quick    # a sphere of 1,000 vertices, 1 s runs, 1 and 2 sessions:
                                                           # a check that it runs, not a measurement
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from websockets.asyncio.client import ClientConnection, connect

from arap.batching.locks import output_lock
from arap.io import save_mesh_bytes
from arap.meshes.shapes import sphere, sphere_frequency_for
from arap.server.client_files import CLIENT_ENV
from arap.server.frames import decode_binary, encode_binary
from benchjson import add_json_option, figure, quick_mesh, write_results

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_MESH = ROOT.parent / "shared" / "meshes" / "armadillo.obj"
TARGET_UPDATES = 30.0
TARGET_P95_MS = 50.0


@dataclass
class Run:
    """Outcome of one dragging run."""

    label: str
    updates: int = 0
    sent: int = 0
    seconds: float = 0.0
    latencies_ms: list[float] = field(default_factory=list)
    solve_ms: list[float] = field(default_factory=list)

    @property
    def rate(self) -> float:
        return self.updates / self.seconds if self.seconds else 0.0

    def pct(self, values: list[float], q: float) -> float:
        return float(np.percentile(values, q)) if values else float("nan")


# ---------------------------------------------------------------------------------------------- server
HOOKED_CLIENT = ROOT / "build" / "studio-e2e"
"""The studio client with the test hook (``window.__arap``) that the benchmarks in a browser read: the browser
tests' build (``npm run build:e2e`` in ``web/``); the packaged client has no hook."""


def hooked_client() -> Path:
    """:data:`HOOKED_CLIENT`, built first when it is missing or older than the client's sources (by one process at a
    time: others that find it stale meanwhile wait for that build, then find it fresh)."""
    built = HOOKED_CLIENT / "index.html"
    web = ROOT / "web"
    sources = [p for p in (web / "src").rglob("*") if p.is_file()] + [web / "index.html", web / "vite.config.js"]

    def stale() -> bool:
        return not built.is_file() or any(p.stat().st_mtime > built.stat().st_mtime for p in sources)

    if stale():
        HOOKED_CLIENT.parent.mkdir(parents=True, exist_ok=True)
        with output_lock(HOOKED_CLIENT):
            if stale():
                subprocess.run(["npm", "run", "build:e2e"], cwd=web, check=True, capture_output=True)
    return HOOKED_CLIENT


def start_server(log: Path | None = None, hook: bool = False) -> tuple[subprocess.Popen[str], str]:
    """Run the studio in a subprocess on a free port; its ws:// URL. With ``log``, the server's INFO lines about
    the connections (e.g. each upload's step times) are written to that file; with ``hook``, it serves the client
    with the test hook (:func:`hooked_client`)."""
    code = ("import sys\nfrom arap.server import serve\n"
            "serve(port=0, log_level='warning', on_ready=lambda url: print(url, flush=True))\n")
    if log is not None:
        code = ("import logging\nimport sys\nh = logging.FileHandler(sys.argv[1])\nh.setLevel(logging.INFO)\n"
                "lg = logging.getLogger('arap.server.connection')\nlg.setLevel(logging.INFO)\nlg.addHandler(h)\n"
                + code)
    env = {**os.environ, CLIENT_ENV: str(hooked_client())} if hook else None
    proc = subprocess.Popen([sys.executable, "-c", code, *([str(log)] if log is not None else [])],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT, env=env)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if not line.startswith("http://"):
        proc.kill()
        raise RuntimeError(f"server did not start (got {line!r})")
    return proc, line.replace("http://", "ws://") + "ws"


# ---------------------------------------------------------------------------------------------- client
class Studio:
    """A minimal protocol client."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.V = np.zeros((0, 3))
        self.handle: list[int] = []
        self.center = np.zeros(3)
        self.height = 1.0

    async def recv(self) -> tuple[dict[str, Any], memoryview | None]:
        msg = await self.ws.recv()
        if isinstance(msg, str):
            return json.loads(msg), None
        return decode_binary(msg)

    async def expect(self, type_: str) -> tuple[dict[str, Any], memoryview | None]:
        data, payload = await self.recv()
        while data["type"] == "settle" and type_ != "settle":  # settling progress between requests
            data, payload = await self.recv()
        if data["type"] != type_:
            raise RuntimeError(f"expected {type_}, got {data}")
        return data, payload

    async def setup(self, mesh: Path) -> None:
        await self.expect("welcome")
        await self.expect("mesh")
        await self.expect("state")
        await self.ws.send(encode_binary({"type": "upload", "filename": mesh.name}, mesh.read_bytes()))
        header, payload = await self.expect("mesh")
        await self.expect("state")
        n = header["n_vertices"]
        assert payload is not None
        self.V = np.frombuffer(bytes(payload[: 12 * n]), dtype="<f4").reshape(n, 3).astype(np.float64)
        y = self.V[:, 1]
        fixed = np.flatnonzero(y <= np.quantile(y, 0.1)).tolist()
        self.handle = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
        self.center = self.V[self.handle].mean(axis=0)
        self.height = float(np.ptp(y))
        await self.ws.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": fixed,
                                       "handle_groups": [self.handle]}))
        await self.expect("state")
        while True:  # the new constraints settle (frames may come) before the drags start
            data, _ = await asyncio.wait_for(self.recv(), 120.0)
            if data["type"] == "settle" and data["status"] != "settling":
                break

    async def set_iterations(self, k: int) -> None:
        await self.ws.send(json.dumps({"type": "set_params", "iterations": k}))
        await self.expect("state")

    def transform(self, t: float) -> list[float]:
        """Handle transform at time ``t`` (s): a sway and a slight twist, like a hand moving the head."""
        a = 0.25 * self.height
        angle = 0.35 * math.sin(2 * math.pi * t / 3.0)
        c, s = math.cos(angle), math.sin(angle)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        M = np.eye(4)
        M[:3, :3] = R
        shift = np.array([a * math.sin(2 * math.pi * t / 2.0), 0.1 * a * math.sin(2 * math.pi * t / 1.5), 0.0])
        M[:3, 3] = self.center - R @ self.center + shift
        return M.T.reshape(16).tolist()

    async def drag(self, seq: int, t: float) -> None:
        await self.ws.send(json.dumps({"type": "drag", "seq": seq, "transforms": [self.transform(t)]}))

    async def interactive(self, seconds: float, label: str, seq0: int = 0) -> Run:
        run = Run(label)
        start = time.perf_counter()
        seq = seq0
        while time.perf_counter() - start < seconds:
            sent = time.perf_counter()
            await self.drag(seq, sent - start)
            header, _ = await self.expect("vertices")
            assert header["seq"] == seq
            run.latencies_ms.append(1000 * (time.perf_counter() - sent))
            run.solve_ms.append(header["solve_ms"])
            run.updates += 1
            seq += 1
        run.sent = run.updates
        run.seconds = time.perf_counter() - start
        return run

    async def firehose(self, seconds: float, label: str, hz: float = 60.0, seq0: int = 0) -> Run:
        run = Run(label)
        sent_at: dict[int, float] = {}
        start = time.perf_counter()
        done = asyncio.Event()
        last_seq = seq0

        async def sender() -> None:
            nonlocal last_seq
            seq = seq0
            while time.perf_counter() - start < seconds:
                sent_at[seq] = time.perf_counter()
                await self.drag(seq, sent_at[seq] - start)
                last_seq = seq
                seq += 1
                await asyncio.sleep(max(0.0, start + (seq - seq0) / hz - time.perf_counter()))
            done.set()

        async def receiver() -> None:
            # The server answers the newest drag and drops stale ones, so the last answer may arrive before the
            # sender has finished sleeping: stop on the newest seq answered, whichever side finishes last.
            answered = seq0 - 1
            while not (done.is_set() and answered >= last_seq):
                if time.perf_counter() > start + seconds + 30.0:
                    raise RuntimeError(f"no answer to drag {last_seq} within 30 s (newest answered: {answered})")
                try:
                    header, _ = await asyncio.wait_for(self.expect("vertices"), 0.05)
                except TimeoutError:
                    continue
                answered = max(answered, header["seq"])
                run.latencies_ms.append(1000 * (time.perf_counter() - sent_at[header["seq"]]))
                run.solve_ms.append(header["solve_ms"])
                run.updates += 1

        await asyncio.gather(sender(), receiver())
        run.sent = last_seq - seq0 + 1
        run.seconds = time.perf_counter() - start
        return run


async def open_session(url: str, mesh: Path) -> tuple[ClientConnection, Studio]:
    ws = await connect(url, compression=None, max_size=None, open_timeout=60)
    studio = Studio(ws)
    await studio.setup(mesh)
    return ws, studio


# ---------------------------------------------------------------------------------------------- scenarios
async def single(url: str, mesh: Path, seconds: float, iterations: list[int]) -> list[Run]:
    ws, studio = await open_session(url, mesh)
    runs = []
    try:
        print(f"mesh {mesh.name}: {len(studio.V):,} vertices, handle {len(studio.handle):,} vertices",
              flush=True)
        await studio.set_iterations(1)
        await studio.interactive(1.0, "warm-up")
        seq = 100_000
        for k in iterations:
            await studio.set_iterations(k)
            runs.append(await studio.interactive(seconds, f"interactive, {k} it", seq))
            seq += 100_000
            runs.append(await studio.firehose(seconds, f"firehose 60 Hz, {k} it", seq0=seq))
            seq += 100_000
    finally:
        await ws.close()
    return runs


async def concurrent(url: str, mesh: Path, seconds: float, n: int, iterations: int) -> list[Run]:
    sessions = [await open_session(url, mesh) for _ in range(n)]
    try:
        for _, s in sessions:
            await s.set_iterations(iterations)
            await s.interactive(0.5, "warm-up")
        return list(await asyncio.gather(*(s.interactive(seconds, f"session {i}", 10**6)
                                           for i, (_, s) in enumerate(sessions))))
    finally:
        for ws, _ in sessions:
            await ws.close()


def print_runs(runs: list[Run]) -> None:
    print(f"\n{'run':<26} {'updates/s':>10} {'sent':>6} {'answered':>9} {'latency med':>12} {'p95':>8} "
          f"{'solve med':>10}")
    for r in runs:
        print(f"{r.label:<26} {r.rate:>10.1f} {r.sent:>6} {r.updates:>9} {r.pct(r.latencies_ms, 50):>10.1f}ms "
              f"{r.pct(r.latencies_ms, 95):>6.1f}ms {r.pct(r.solve_ms, 50):>8.1f}ms")


# ---------------------------------------------------------------------------------------------- payload
async def _drags(studio: Studio, roi: list[int] | None, fixed: list[int], updates: int) -> dict[str, float]:
    """Set a constraint set, then ``updates`` interactive drags; first-answer time, bytes and server time."""
    ws = studio.ws
    t0 = time.perf_counter()
    await ws.send(json.dumps({"type": "set_constraints", "roi": roi, "fixed": fixed,
                              "handle_groups": [studio.handle]}))
    await studio.drag(1, 0.0)
    sizes: list[int] = []
    solve: list[float] = []
    first_ms = math.nan
    factor_ms = math.nan
    for seq in range(1, updates + 1):
        if seq > 1:
            await studio.drag(seq, 0.05 * seq)
        while True:
            msg = await asyncio.wait_for(ws.recv(), 300.0)
            if isinstance(msg, str) and seq == 1:
                data = json.loads(msg)
                if data["type"] == "state":
                    factor_ms = float(data["stats"]["factor_ms"])
            if isinstance(msg, bytes):
                header, _ = decode_binary(msg)
                if header["type"] == "vertices" and header["seq"] == seq:
                    break
        if seq == 1:
            first_ms = 1000 * (time.perf_counter() - t0)
        sizes.append(len(msg))
        solve.append(float(header["solve_ms"]))
    await ws.send(json.dumps({"type": "end_drag"}))
    return {"first_answer_ms": first_ms, "factor_ms": factor_ms, "first_bytes": sizes[0],
            "bytes_per_update": float(np.median(sizes[1:])),
            "server_solve_ms": float(np.median(solve[1:]))}


def server_upload_steps(log: Path | None, name: str) -> dict[str, Any]:
    """The step times the server logged for its last upload of ``name`` (see :func:`start_server`), or {}."""
    found: dict[str, Any] = {}
    if log is None or not log.is_file():
        return found
    for line in log.read_text(errors="replace").splitlines():
        if "upload timings " in line:
            entry = json.loads(line.split("upload timings ", 1)[1])
            if entry.get("name") == name:
                found = entry
    return found


async def payload_report(url: str, mesh: Path, updates: int, log: Path | None = None) -> dict[str, Any]:
    """Upload-to-ready, and bytes and server time per update with full frames and with a 20% region."""
    ws = await connect(url, compression=None, max_size=None, open_timeout=60)
    try:
        studio = Studio(ws)
        await studio.expect("welcome")
        await studio.expect("mesh")
        await studio.expect("state")
        data = mesh.read_bytes()
        t0 = time.perf_counter()
        await ws.send(encode_binary({"type": "upload", "filename": mesh.name}, data))
        header, payload = await asyncio.wait_for(studio.expect("mesh"), 300.0)
        await studio.expect("state")
        shown_ms = 1000 * (time.perf_counter() - t0)
        received = time.time()
        n = header["n_vertices"]
        assert payload is not None
        studio.V = np.frombuffer(bytes(payload[: 12 * n]), dtype="<f4").reshape(n, 3).astype(np.float64)
        y = studio.V[:, 1]
        studio.handle = np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()
        studio.center = studio.V[studio.handle].mean(axis=0)
        studio.height = float(np.ptp(y))
        await studio.set_iterations(1)
        whole = await _drags(studio, None, np.flatnonzero(y <= np.quantile(y, 0.1)).tolist(), updates)
        ready_ms = shown_ms + whole["first_answer_ms"]
        band = (y >= np.quantile(y, 0.8)) & (y <= np.quantile(y, 0.82))
        region = await _drags(studio, np.flatnonzero(y >= np.quantile(y, 0.8)).tolist(),
                              np.flatnonzero(band).tolist(), updates)
    finally:
        await ws.close()
    out = {"mesh": mesh.name, "n_vertices": n, "upload_bytes": len(data), "upload_to_mesh_ms": shown_ms,
           "upload_to_first_answer_ms": ready_ms, "whole": whole, "roi20": region}
    print(f"\n{mesh.name}: {n:,} vertices, upload {len(data) / 2**20:.1f} MiB", flush=True)
    print(f"  upload to mesh shown {shown_ms:.0f} ms; to the first drag answered {ready_ms:.0f} ms (constraint set "
          f"to first answer {whole['first_answer_ms']:.0f} ms, of which factorisation {whole['factor_ms']:.0f} ms)")
    steps = server_upload_steps(log, mesh.stem)
    if steps:
        out["server_steps"] = steps
        keys = ("decode_ms", "queued_ms", "parse_repair_ms", "parse_repair_cpu_ms", "encode_ms", "send_mesh_ms",
                "send_state_ms")
        print("  server: " + ", ".join(f"{k.removesuffix('_ms').replace('_', ' ')} {steps.get(k, float('nan')):.0f} ms"
                                       for k in keys)
              + f"; upload sent to frame received and mesh sent to mesh and state received "
              f"{shown_ms - 1000 * (steps['mesh_sent'] - steps['arrived']) - steps['send_state_ms']:.0f} ms "
              f"(of which the state {1000 * (received - steps['mesh_sent']):.0f} ms after the mesh was sent)")
    for label, r in (("whole mesh (full frames)", whole), ("20% region (subset frames)", region)):
        print(f"  {label:<28} {r['bytes_per_update'] / 1024:>9.1f} KiB/update (first frame "
              f"{r['first_bytes'] / 1024:.1f} KiB), server solve {r['server_solve_ms']:.1f} ms/update")
    return out


def subdivided(mesh: Path, folder: Path) -> Path:
    """The mesh subdivided once (every triangle split in four), written as PLY into ``folder``."""
    import trimesh

    loaded = trimesh.load(mesh, force="mesh", process=False)
    V, F = trimesh.remesh.subdivide(np.asarray(loaded.vertices), np.asarray(loaded.faces))
    out = folder / f"{mesh.stem}-subdivided.ply"
    trimesh.Trimesh(V, F, process=False).export(out)
    return out


def sphere_obj(n_vertices: int, folder: Path) -> Path:
    """A geodesic sphere of about ``n_vertices`` vertices written as OBJ (the format of large scans)."""
    V, F = sphere(frequency=sphere_frequency_for(n_vertices))
    out = folder / f"sphere{round(len(V) / 1000)}k.obj"
    out.write_bytes(save_mesh_bytes(V, F, "obj"))
    return out


async def payload_main(args: argparse.Namespace) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "server.log"
        proc, url = start_server(log)
        try:
            meshes = [args.mesh] + ([subdivided(args.mesh, Path(tmp))] if args.subdivide else [])
            if args.sphere:
                meshes.append(sphere_obj(args.sphere, Path(tmp)))
            return {"payload": [await payload_report(url, m, args.updates, log) for m in meshes]}
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()


async def main_async(args: argparse.Namespace) -> dict[str, Any]:
    if args.payload:
        return await payload_main(args)
    proc, url = start_server()
    results: dict[str, Any] = {"mesh": str(args.mesh), "cpus": os.cpu_count()}
    try:
        runs = await single(url, args.mesh, args.seconds, args.iterations)
        print_runs(runs)
        one = next(r for r in runs if r.label == "interactive, 1 it")
        ok = one.rate >= TARGET_UPDATES and one.pct(one.latencies_ms, 95) <= TARGET_P95_MS
        print(f"\ntarget at 1 iteration (interactive): >= {TARGET_UPDATES:.0f} updates/s and p95 <= "
              f"{TARGET_P95_MS:.0f} ms: {'met' if ok else 'NOT met'} ({one.rate:.1f} updates/s, p95 "
              f"{one.pct(one.latencies_ms, 95):.1f} ms)")
        results["single"] = [{"label": r.label, "updates_per_s": r.rate, "sent": r.sent, "answered": r.updates,
                              "latency_median_ms": r.pct(r.latencies_ms, 50),
                              "latency_p95_ms": r.pct(r.latencies_ms, 95),
                              "solve_median_ms": r.pct(r.solve_ms, 50)} for r in runs]
        print(f"\nconcurrent sessions ({args.concurrent_iterations} iteration(s) per update, interactive)")
        print(f"{'sessions':>8} {'updates/s each':>32} {'min':>6} {'>= 10/s':>8} {'p95 latency':>12}")
        results["concurrent"] = []
        for n in args.sessions:
            cr = await concurrent(url, args.mesh, args.seconds, n, args.concurrent_iterations)
            rates = [r.rate for r in cr]
            holding = sum(r >= 10.0 for r in rates)
            p95 = max(r.pct(r.latencies_ms, 95) for r in cr)
            shown = " ".join(f"{x:.1f}" for x in rates)
            print(f"{n:>8} {shown:>32} {min(rates):>6.1f} {holding:>5}/{n:<2} {p95:>10.1f}ms", flush=True)
            results["concurrent"].append({"sessions": n, "updates_per_s": rates, "holding_10": holding,
                                          "worst_p95_ms": p95})
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
    return results


def studio_figures(results: dict[str, Any]) -> list[dict[str, Any]]:
    """The headline figures of ``results`` (either mode) for ``--json``."""
    figures = []
    for p in results.get("payload", []):
        where = f"{p['mesh']} ({p['n_vertices']:,} vertices)"
        figures.append(figure(f"upload to first drag answered, {where}", p["upload_to_first_answer_ms"], "ms"))
        figures.append(figure(f"bytes per update, 20% region moving, {where}", p["roi20"]["bytes_per_update"] / 1024,
                              "KiB", "whole mesh moving", p["whole"]["bytes_per_update"] / 1024))
    for r in results.get("single", []):
        figures.append(figure(f"updates per second, {r['label']}", r["updates_per_s"], "updates/s", "target",
                              TARGET_UPDATES if r["label"] == "interactive, 1 it" else None, better="higher"))
        figures.append(figure(f"drag latency p95, {r['label']}", r["latency_p95_ms"], "ms", "target",
                              TARGET_P95_MS if r["label"] == "interactive, 1 it" else None))
    for c in results.get("concurrent", []):
        figures.append(figure(f"sessions holding 10 updates/s, of {c['sessions']} dragging at once",
                              c["holding_10"], "sessions", "all", c["sessions"], better="higher"))
    return figures


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", type=Path, default=DEFAULT_MESH, help="mesh file to upload")
    parser.add_argument("--seconds", type=float, default=5.0, help="duration of each run")
    parser.add_argument("--iterations", type=int, nargs="+", default=[1, 3], help="iterations per update")
    parser.add_argument("--sessions", type=int, nargs="+", default=[1, 2, 4, 8], help="concurrent sessions")
    parser.add_argument("--concurrent-iterations", type=int, default=1, help="iterations per update when "
                        "several sessions drag at once")
    add_json_option(parser, "bench_studio")
    parser.add_argument("--payload", action="store_true", help="report upload-to-ready and bytes per update "
                        "(full frames vs a 20%% region) instead of throughput")
    parser.add_argument("--subdivide", action="store_true", help="with --payload, also the mesh subdivided once")
    parser.add_argument("--sphere", type=int, default=0, metavar="N", help="with --payload, also a geodesic "
                        "sphere of about N vertices (OBJ)")
    parser.add_argument("--updates", type=int, default=30, help="drags per constraint set with --payload")
    parser.add_argument("--quick", action="store_true", help="a sphere of 1,000 vertices, 1 s runs, 1 and 2 sessions")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        if args.quick:
            args.mesh, args.seconds, args.iterations, args.sessions = quick_mesh(Path(tmp)), 1.0, [1], [1, 2]
            args.updates, args.subdivide, args.sphere = 5, False, 0
        if not args.mesh.is_file():
            parser.error(f"mesh not found: {args.mesh}")
        results = asyncio.run(main_async(args))
    if args.json:
        write_results(args.json, "bench_studio", studio_figures(results), results)


if __name__ == "__main__":
    main()
