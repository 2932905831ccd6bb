"""Studio under load on loopback: many sessions dragging at once, cross-talk checks, server memory.

Starts the real server in a subprocess, opens ``--sessions`` WebSocket sessions, each uploading its own copy of the
mesh moved 10·i bounding-box diagonals along x, and lets all of them drag their handle for ``--seconds``. Every
answer is checked against its session: its seq, its vertex count and its place (an answer meant for another session
would lie diagonals away). With ``--large MB`` one more client sends a ``set_constraints`` message of that
size in the middle of the run, and the draggers' p95 latency in the seconds around it is printed apart. The server's
resident memory is sampled during the run and again after every session has disconnected.

Everything is bounded: each session stops after ``--seconds``, every wait has a timeout, and the server is stopped
at the end.

Run: ``python benchmarks/bench_load.py [--sessions 20] [--seconds 60] [--mesh PATH] [--large 50] [--quick]``
(``--quick``: 2 sessions for 3 s on a sphere of 1,000 vertices: a check that it runs, not a measurement)
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil
from websockets.asyncio.client import connect

from arap.io import load_mesh, save_mesh
from arap.meshes.shapes import builtin_mesh
from bench_studio import DEFAULT_MESH, Studio, start_server
from benchjson import add_json_option, figure, write_results

TIMEOUT = 120.0


async def dragger(url: str, mesh: Path, phase: float, seconds: float, start_at: float,
                  log: list[tuple[float, float]]) -> dict[str, float]:
    """One session: upload, then drag until ``start_at + seconds``; (time, latency) pairs go to ``log``."""
    async with connect(url, max_size=None, compression=None, open_timeout=TIMEOUT) as ws:
        studio = Studio(ws)
        await asyncio.wait_for(studio.setup(mesh), TIMEOUT)
        centre = float(studio.V[:, 0].mean())
        diag = float(np.linalg.norm(np.ptp(studio.V, axis=0)))
        await asyncio.sleep(max(0.0, start_at - time.perf_counter()))
        updates = crosstalk = 0
        seq = 0
        t_end = start_at + seconds
        while time.perf_counter() < t_end:
            sent = time.perf_counter()
            await studio.drag(seq, sent - start_at + phase)
            header, payload = await asyncio.wait_for(studio.expect("vertices"), TIMEOUT)
            now = time.perf_counter()
            log.append((now, 1000.0 * (now - sent)))
            U = np.frombuffer(bytes(payload or b""), dtype="<f4")
            if (header["seq"] != seq or len(U) != 3 * len(studio.V)
                    or abs(float(U[0::3].mean()) - centre) > diag):
                crosstalk += 1
            updates += 1
            seq += 1
        return {"updates_per_s": updates / seconds, "crosstalk": crosstalk}


async def large_message(url: str, mesh: Path, megabytes: float, at: float) -> float:
    """Send one ``set_constraints`` of about ``megabytes`` MB at time ``at``; seconds until it was answered."""
    async with connect(url, max_size=None, compression=None, open_timeout=TIMEOUT) as ws:
        studio = Studio(ws)
        await asyncio.wait_for(studio.setup(mesh), TIMEOUT)
        n = len(studio.V)
        count = int(megabytes * 2**20 / 7)
        fixed = (np.arange(count) % n).tolist()  # repeated indices: refused, but only after parsing it all
        await asyncio.sleep(max(0.0, at - time.perf_counter()))
        t0 = time.perf_counter()
        await ws.send(json.dumps({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": []}))
        while True:
            data, _ = await asyncio.wait_for(studio.recv(), TIMEOUT)
            if data["type"] in ("error", "state"):
                return time.perf_counter() - t0


async def sample_rss(proc: psutil.Process, stop: asyncio.Event, samples: list[float]) -> None:
    while not stop.is_set():
        samples.append(proc.memory_info().rss / 2**20)
        await asyncio.sleep(0.25)


async def run(args: argparse.Namespace, meshes: list[Path]) -> None:
    server, url = start_server()
    proc = psutil.Process(server.pid)
    try:
        rss_start = proc.memory_info().rss / 2**20
        samples: list[float] = []
        stop = asyncio.Event()
        sampler = asyncio.create_task(sample_rss(proc, stop, samples))
        log: list[tuple[float, float]] = []
        start_at = time.perf_counter() + 15.0 + 1.5 * len(meshes)  # after every session has uploaded
        big_at = start_at + args.seconds / 2
        tasks = [dragger(url, m, 0.1 * i, args.seconds, start_at, log) for i, m in enumerate(meshes)]
        big = [large_message(url, meshes[0], args.large, big_at)] if args.large else []
        results = await asyncio.gather(*tasks, *big)
        stop.set()
        await sampler
        await asyncio.sleep(2.0)
        rss_after = proc.memory_info().rss / 2**20
    finally:
        server.terminate()
        server.wait(timeout=30)
    sessions = results[: len(meshes)]
    rates = [r["updates_per_s"] for r in sessions]
    latencies = [ms for _, ms in log]
    print(f"\n{len(meshes)} sessions dragging for {args.seconds:g} s on loopback")
    print(f"updates/s per session: min {min(rates):.1f}, median {statistics.median(rates):.1f}, "
          f"max {max(rates):.1f}; latency p95 {np.percentile(latencies, 95):.0f} ms")
    print(f"answers not matching their session (cross-talk): {sum(int(r['crosstalk']) for r in sessions)}")
    print(f"server RSS: {rss_start:.0f} MB at start, peak {max(samples, default=rss_start):.0f} MB, "
          f"{rss_after:.0f} MB after every session disconnected")
    if big:
        inside = [big_at - 0.5 <= t <= big_at + results[-1] + 0.5 for t, _ in log]
        window = [ms for (_, ms), i in zip(log, inside, strict=True) if i]
        rest = [ms for (_, ms), i in zip(log, inside, strict=True) if not i]
        print(f"large message ({args.large:g} MB) answered in {results[-1]:.2f} s; other sessions' p95 latency "
              f"meanwhile {np.percentile(window, 95) if window else float('nan'):.0f} ms ({len(window)} updates), "
              f"otherwise {np.percentile(rest, 95) if rest else float('nan'):.0f} ms")
    if args.json:
        write_results(args.json, "bench_load", [
            figure(f"updates per second per session, median of {len(meshes)} sessions", statistics.median(rates),
                   "updates/s", better="higher"),
            figure(f"drag answer latency, p95, {len(meshes)} sessions", float(np.percentile(latencies, 95)), "ms"),
            figure("answers sent to the wrong session", sum(int(r["crosstalk"]) for r in sessions), "answers"),
            figure("server memory at its peak", max(samples, default=rss_start), "MB"),
        ], {"sessions": len(meshes), "seconds": args.seconds, "updates_per_s": rates,
            "rss_mb": {"start": rss_start, "peak": max(samples, default=rss_start), "after": rss_after},
            "large_message_seconds": results[-1] if big else None})


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sessions", type=int, default=20)
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--mesh", type=Path, default=DEFAULT_MESH)
    p.add_argument("--large", type=float, default=0.0, help="also send one message of this many MB (0: none)")
    p.add_argument("--quick", action="store_true", help="2 sessions for 3 s on a sphere of 1,000 vertices")
    add_json_option(p, "bench_load")
    args = p.parse_args(argv)
    if args.quick:
        args.sessions, args.seconds, args.large = 2, 3.0, 0.0
        V, F = builtin_mesh("sphere:1000")
    else:
        V, F = load_mesh(args.mesh)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    with tempfile.TemporaryDirectory() as tmp:
        meshes = []
        for i in range(args.sessions):
            path = Path(tmp) / f"session{i}.obj"
            save_mesh(path, V + np.array([10.0 * diag * i, 0.0, 0.0]), F)
            meshes.append(path)
        asyncio.run(run(args, meshes))


if __name__ == "__main__":
    main()
