"""Fairness of the studio's decoding of large messages: a small request's latency while other sessions send 50 MiB.

Starts the real server in a subprocess (the default mesh, loopback, a free port). ``--heavy`` sessions each send
``set_constraints`` messages of ``--heavy-mib`` MiB (a fixed list of repeated vertex indices: decoded in full, then
refused by the session) one after the other, each as soon as the previous one was answered. Meanwhile one more
session sends, every ``--interval`` seconds, a ``set_constraints`` of ``--small-mib`` MiB (decoded in a worker
process too; also refused) and a tiny ``get_constraints``, and records how long each took to be answered.

Printed: the p50, p95 and max latency of the small and tiny requests, how many heavy messages were answered, and
the server's resident memory (with its decoder processes) at start, at peak and after everyone left. The target is
a small-request p95 of at most 0.5 s (the exit status is 1 when it is missed).

Everything is bounded: the run lasts ``--seconds``, every wait has a timeout, the server is stopped at the end.

Run: ``python benchmarks/bench_fairness.py [--heavy 3] [--heavy-mib 50] [--small-mib 2.6] [--seconds 20] [--quick]``
(``--quick``: one heavy session of 5 MiB messages for 3 s, and the exit status does not judge the latency: a check
that it runs, not a measurement)
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time

import numpy as np
import psutil
from websockets.asyncio.client import ClientConnection, connect

from bench_studio import Studio, start_server
from benchjson import add_json_option, figure, write_results

TIMEOUT = 120.0
TARGET_P95_S = 0.5


def constraints_text(n_vertices: int, mib: float) -> str:
    """A ``set_constraints`` of about ``mib`` MiB: vertex indices repeated (refused once decoded)."""
    per = len(str(n_vertices)) + 1
    fixed = (np.arange(int(mib * 2**20 / per)) % n_vertices).tolist()
    return json.dumps({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": []},
                      separators=(",", ":"))


async def answered(studio: Studio) -> None:
    """Wait for the answer to a request (an error, a state or constraints message)."""
    while True:
        data, _ = await asyncio.wait_for(studio.recv(), TIMEOUT)
        if data["type"] in ("error", "state", "constraints"):
            return


async def greet(ws: ClientConnection) -> Studio:
    studio = Studio(ws)
    await studio.expect("welcome")
    header, _ = await studio.expect("mesh")
    studio.V = np.zeros((header["n_vertices"], 3))
    await studio.expect("state")
    return studio


async def heavy(url: str, mib: float, until: float, started: asyncio.Event) -> int:
    """Send large messages back to back until ``until``; how many were answered."""
    async with connect(url, max_size=None, compression=None, open_timeout=TIMEOUT) as ws:
        studio = await greet(ws)
        text = constraints_text(len(studio.V), mib)
        done = 0
        started.set()
        while time.perf_counter() < until:
            await ws.send(text)
            await answered(studio)
            done += 1
        return done


async def light(url: str, mib: float, interval: float, start_at: float, until: float) -> tuple[list[float],
                                                                                                 list[float]]:
    """Small and tiny requests every ``interval`` seconds from ``start_at`` to ``until``; their latencies."""
    small: list[float] = []
    tiny: list[float] = []
    async with connect(url, max_size=None, compression=None, open_timeout=TIMEOUT) as ws:
        studio = await greet(ws)
        text = constraints_text(len(studio.V), mib)
        await asyncio.sleep(max(0.0, start_at - time.perf_counter()))
        while time.perf_counter() < until:
            t0 = time.perf_counter()
            await ws.send(text)
            await answered(studio)
            small.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            await ws.send(json.dumps({"type": "get_constraints"}))
            await answered(studio)
            tiny.append(time.perf_counter() - t0)
            await asyncio.sleep(interval)
    return small, tiny


def rss_mib(proc: psutil.Process) -> float:
    """Resident memory of the server and its children (the decoder processes), MiB."""
    total = proc.memory_info().rss
    for child in proc.children(recursive=True):
        try:
            total += child.memory_info().rss
        except psutil.Error:
            pass
    return total / 2**20


async def sample(proc: psutil.Process, stop: asyncio.Event, out: list[float]) -> None:
    while not stop.is_set():
        out.append(rss_mib(proc))
        await asyncio.sleep(0.2)


def stats(label: str, values: list[float]) -> float:
    if not values:
        print(f"{label}: no answers")
        return float("inf")
    p95 = float(np.percentile(values, 95))
    print(f"{label}: {len(values)} answered, p50 {np.median(values):.3f} s, p95 {p95:.3f} s, "
          f"max {max(values):.3f} s")
    return p95


async def run(args: argparse.Namespace) -> float:
    server, url = start_server()
    proc = psutil.Process(server.pid)
    try:
        rss_start = rss_mib(proc)
        samples: list[float] = []
        stop = asyncio.Event()
        sampler = asyncio.create_task(sample(proc, stop, samples))
        until = time.perf_counter() + args.seconds
        events = [asyncio.Event() for _ in range(args.heavy)]
        heavies = [asyncio.create_task(heavy(url, args.heavy_mib, until, e)) for e in events]
        await asyncio.wait_for(asyncio.gather(*(e.wait() for e in events)), TIMEOUT)
        start_at = time.perf_counter() + 1.0  # once the heavy messages are flowing
        small, tiny = await light(url, args.small_mib, args.interval, start_at, until)
        done = await asyncio.wait_for(asyncio.gather(*heavies), TIMEOUT)
        stop.set()
        await sampler
        await asyncio.sleep(2.0)
        rss_after = rss_mib(proc)
        server_after = proc.memory_info().rss / 2**20
    finally:
        server.terminate()
        server.wait(timeout=30)
    print(f"{args.heavy} sessions sending {args.heavy_mib:g} MiB messages back to back for {args.seconds:g} s: "
          f"{sum(done)} answered")
    p95 = stats(f"small requests ({args.small_mib:g} MiB set_constraints)", small)
    tiny_p95 = stats("tiny requests (get_constraints)", tiny)
    print(f"server RSS with its decoder processes: {rss_start:.0f} MiB at start, peak "
          f"{max(samples, default=rss_start):.0f} MiB, {rss_after:.0f} MiB after everyone left (the server alone "
          f"{server_after:.0f} MiB)")
    print(f"target: small-request p95 <= {TARGET_P95_S} s: {'met' if p95 <= TARGET_P95_S else 'MISSED'}")
    if args.json:
        write_results(args.json, "bench_fairness", [
            figure(f"small request ({args.small_mib:g} MiB) answer time, p95, beside {args.heavy} heavy sessions", p95,
                   "s", "target", TARGET_P95_S),
            figure("tiny request answer time, p95", tiny_p95, "s"),
            figure("server memory at its peak", max(samples, default=rss_start), "MiB"),
        ], {"heavy_sessions": args.heavy, "heavy_mib": args.heavy_mib, "small_mib": args.small_mib,
            "seconds": args.seconds, "heavy_answered": sum(done), "small_s": small, "tiny_s": tiny,
            "rss_mib": {"start": rss_start, "peak": max(samples, default=rss_start), "after": rss_after,
                        "server_after": server_after}})
    return p95


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--heavy", type=int, default=3, help="sessions sending large messages")
    p.add_argument("--heavy-mib", type=float, default=50.0)
    p.add_argument("--small-mib", type=float, default=2.6)
    p.add_argument("--interval", type=float, default=0.2, help="seconds between two small requests")
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--quick", action="store_true", help="one heavy session of 5 MiB messages for 3 s; exit 0")
    add_json_option(p, "bench_fairness")
    args = p.parse_args(argv)
    if args.quick:
        args.heavy, args.heavy_mib, args.seconds = 1, 5.0, 3.0
    p95 = asyncio.run(run(args))
    sys.exit(0 if args.quick or p95 <= TARGET_P95_S else 1)


if __name__ == "__main__":
    main()
