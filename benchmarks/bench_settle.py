"""Studio: time from releasing a drag (``end_drag``) to the ``settled`` message, over the WebSocket.

Starts the real server, uploads the mesh (default: the armadillo), fixes the lowest 10% of the vertices along y
and makes the top 10% a handle group, then repeats: drag the handle to a new pose in a few steps (one iteration
each, as a mouse drag does), release, and time until the server says ``settled``. Printed: the median and
worst release-to-settled time, the settling iterations and the frames streamed meanwhile.

Run: ``python benchmarks/bench_settle.py [--mesh PATH] [--drags 5] [--quick]`` (``--quick``: 2 drags on a sphere of
1,000 vertices: a check that it runs, not a measurement)
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import tempfile
import time
from pathlib import Path

from websockets.asyncio.client import connect

from bench_studio import DEFAULT_MESH, Studio, start_server
from benchjson import add_json_option, figure, quick_mesh, write_results

TIMEOUT = 120.0


async def release_to_settled(studio: Studio, seq: int, t: float) -> tuple[float, int, int]:
    """Drag to the pose at time ``t`` in 5 steps, release; seconds until settled, iterations, frames."""
    for k in range(5):
        await studio.drag(seq + k, t * (k + 1) / 5)
        while (await studio.recv())[0]["type"] != "vertices":
            pass
    await studio.ws.send(json.dumps({"type": "end_drag"}))
    t0 = time.perf_counter()
    frames = 0
    while True:
        data, _ = await asyncio.wait_for(studio.recv(), TIMEOUT)
        if data["type"] == "vertices":
            frames += 1
        elif data["type"] == "settle" and data["status"] != "settling":
            return time.perf_counter() - t0, int(data["iterations"]), frames


async def run(mesh: Path, drags: int) -> list[tuple[float, int, int]]:
    proc, url = start_server()
    try:
        async with connect(url, max_size=None, compression=None) as ws:
            studio = Studio(ws)
            await asyncio.wait_for(studio.setup(mesh), TIMEOUT)
            results = []
            for i in range(drags):
                results.append(await release_to_settled(studio, 10 * i, 0.3 + 0.4 * i))
            return results
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mesh", type=Path, default=DEFAULT_MESH)
    p.add_argument("--drags", type=int, default=5)
    p.add_argument("--quick", action="store_true", help="2 drags on a sphere of 1,000 vertices")
    add_json_option(p, "bench_settle")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        if args.quick:
            args.mesh, args.drags = quick_mesh(Path(tmp)), 2
        results = asyncio.run(run(args.mesh, args.drags))
    seconds = [r[0] for r in results]
    print(f"\nRelease to settled on {args.mesh.name} ({args.drags} drags)")
    print(f"{'drag':>5}{'seconds':>10}{'iterations':>12}{'frames':>8}")
    for i, (s, it, fr) in enumerate(results):
        print(f"{i + 1:>5}{s:>10.3f}{it:>12}{fr:>8}")
    print(f"median {statistics.median(seconds):.3f} s, worst {max(seconds):.3f} s (target ≤ 0.5 s)")
    if args.json:
        write_results(args.json, "bench_settle", [
            figure(f"release to settled, median, {args.mesh.name}", statistics.median(seconds), "s", "target", 0.5),
            figure(f"release to settled, worst, {args.mesh.name}", max(seconds), "s", "target", 0.5),
        ], {"mesh": args.mesh.name, "drags": [{"seconds": s, "iterations": it, "frames": fr} for s, it, fr in results]})


if __name__ == "__main__":
    main()
