"""Energies compared: spokes, spokes and rims, and smooth rotations (SR-ARAP) on the shared scans.

1. Cost per iteration on the armadillo (bend scenario, the plain local/global iteration, all energies in the same
   run, median of ``--repeats``): SR-ARAP (with the solver's rotation steps and sweeps per local step,
   :data:`arap.method.smooth.STEPS` and :data:`arap.method.smooth.SWEEPS`) against spokes.
2. A single vertex pulled by 20% of the bounding-box diagonal along the longest axis, the lowest 10% anchored
   (`pull` of `benchmarks/scenarios.py`), solved from the rest pose with the default acceleration until converged
   (at most ``--max-iterations``): folded adjacent-face pairs added to the rest shape's (normals' dot < −0.5), the
   largest change of a dihedral angle, the iterations, whether the solve converged, its seconds (set-up and solve: the
   time to converge, or to reach the cap) and milliseconds per iteration, and the final energy.
3. With ``--screenshots DIR``: the three results of each mesh rendered by the studio in headless Chromium and put
   side by side (``DIR/MESH.jpg``, spokes | spokes and rims | smooth rotations).

Run: ``python benchmarks/bench_energies.py [--max-iterations 2000] [--screenshots benchmarks/out/energies] [--quick]``
(``--quick``: a built-in sphere of 1,000 vertices, 2 iterations, one run, pulls of at most 30 iterations: a check
that it runs, not a measurement).
"""

from __future__ import annotations

import argparse
import base64
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from arap.constraints.scenarios import bend
from arap.io import load_mesh, save_mesh
from arap.meshes.shapes import builtin_mesh
from arap.method.smooth import STEPS, SWEEPS
from arap.solve.solver import ArapSolver
from benchjson import add_json_option, figure, write_results
from folds import folded_pairs, max_dihedral_change
from scenarios import pull

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"
MESHES = ("decimated-knight.off", "camelhead.off", "armadillo.obj")
ENERGIES = ("spokes", "spokes_and_rims", "smooth_rotations")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]


def per_iteration(path: Path, iterations: int, repeats: int) -> dict[str, float]:
    """Median milliseconds per plain iteration of each energy on one mesh (bend scenario)."""
    V, F = load_mesh(path)
    s = bend(V)
    solvers = {e: ArapSolver(V, F, s.constrained, energy=e) for e in ENERGIES}
    times: dict[str, list[float]] = {e: [] for e in ENERGIES}
    for solver in solvers.values():  # warm-up (compilation, thread choice)
        solver.solve(s.targets, max_iterations=3, tolerance=0, acceleration="none", initial="rest")
    for _ in range(repeats):
        for e, solver in solvers.items():  # interleaved, so that load from other processes falls on all alike
            t = time.perf_counter()
            solver.solve(s.targets, max_iterations=iterations, tolerance=0, acceleration="none", initial="rest")
            times[e].append(1000.0 * (time.perf_counter() - t) / iterations)
    return {e: statistics.median(v) for e, v in times.items()}


def pulled(path: Path, max_iterations: int) -> tuple[np.ndarray, np.ndarray, list[dict[str, object]], list]:
    """Rest mesh, and per energy the pulled result and its figures."""
    V, F = load_mesh(path)
    s = pull(V, distance=0.2)
    rest_folds = folded_pairs(V, F)
    rows, shapes = [], []
    for e in ENERGIES:
        t = time.perf_counter()
        result = ArapSolver(V, F, s.constrained, energy=e).solve(s.targets, max_iterations=max_iterations)
        U = result.vertices
        shapes.append(U)
        rows.append({"energy": e, "folds": folded_pairs(U, F) - rest_folds, "rest_folds": rest_folds,
                     "dihedral": np.degrees(max_dihedral_change(V, U, F)), "iterations": result.iterations,
                     "converged": result.converged, "seconds": time.perf_counter() - t,
                     "energy_value": result.energies[-1] if result.energies else float("nan")})
    return V, F, rows, shapes


def screenshots(out: Path, name: str, F: np.ndarray, shapes: list[np.ndarray]) -> Path:
    """Render each shape in the studio (headless Chromium) and save them side by side as ``out/name.png``."""
    from playwright.sync_api import sync_playwright

    from arap.server import make_server
    from arap.server.client_files import CLIENT_ENV
    from bench_studio import hooked_client

    os.environ[CLIENT_ENV] = str(hooked_client())  # the page's test hook tells when the mesh is shown
    server, sock, url = make_server(None, "127.0.0.1", 0, max_upload_bytes=200 * 2**20)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    images = []
    try:
        with tempfile.TemporaryDirectory() as tmp, sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=FLAGS)
            for energy, U in zip(ENERGIES, shapes, strict=True):
                path = Path(tmp) / f"{name}-{energy}.obj"
                save_mesh(path, U, F)
                page = browser.new_page(viewport={"width": 900, "height": 700})
                page.goto(url)
                ready = "() => window.__arap && window.__arap.ready && !window.__arap.busy"
                page.wait_for_function(ready, timeout=120_000)
                page.set_input_files("#file-input", str(path))
                page.wait_for_function(f"() => window.__arap.meshName === {path.stem!r}", timeout=120_000)
                page.wait_for_function(ready, timeout=120_000)
                # the statistics and the first-run guide would cover the model
                if not page.evaluate("() => document.querySelector('#hud').classList.contains('collapsed')"):
                    page.click("#hud-toggle")
                if page.is_visible("#guide"):
                    page.click("[data-testid=guide-close]")
                page.wait_for_timeout(300)
                images.append(page.locator("#view").screenshot(type="png"))
                page.close()
            sheet = browser.new_page(viewport={"width": 1500, "height": 560})
            cells = "".join(
                f'<figure><img src="data:image/png;base64,{base64.b64encode(img).decode()}">'
                f"<figcaption>{energy.replace('_', ' ')}</figcaption></figure>"
                for energy, img in zip(ENERGIES, images, strict=True))
            sheet.set_content("<style>body{margin:0;display:flex;background:#1b1f27;color:#ddd;font:16px sans-serif}"
                              "figure{margin:4px;flex:1;text-align:center}img{width:100%}</style>" + cells)
            out.mkdir(parents=True, exist_ok=True)
            target = out / f"{name}.jpg"
            sheet.screenshot(path=str(target), full_page=True, type="jpeg", quality=80)
            browser.close()
    finally:
        server.should_exit = True
        thread.join(10)
    return target


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--meshes", type=Path, nargs="*", default=[SHARED / m for m in MESHES])
    p.add_argument("--iterations", type=int, default=20, help="iterations per timing run (default: 20)")
    p.add_argument("--repeats", type=int, default=5, help="timing runs; the median is printed (default: 5)")
    p.add_argument("--max-iterations", type=int, default=2000, help="cap of the pull solves (default: 2000)")
    p.add_argument("--screenshots", type=Path, default=None, metavar="DIR", help="save side-by-side renders here")
    p.add_argument("--quick", action="store_true",
                   help="a built-in sphere of 1,000 vertices, 2 iterations, one run, pulls of at most 30 iterations")
    add_json_option(p, "bench_energies")
    args = p.parse_args(argv)
    if args.quick:
        with tempfile.TemporaryDirectory() as tmp:
            sphere = Path(tmp) / "sphere.off"
            save_mesh(sphere, *builtin_mesh("sphere:1000"))
            quick = [*(argv or sys.argv[1:]), "--meshes", str(sphere), "--iterations", "2", "--repeats", "1",
                     "--max-iterations", "30"]
            return main([a for a in quick if a != "--quick"])
    missing = [m for m in args.meshes if not m.exists()]
    if missing:
        print(f"missing meshes: {', '.join(map(str, missing))}", file=sys.stderr)
        return 2

    timing_mesh = args.meshes[-1]
    ms = per_iteration(timing_mesh, args.iterations, args.repeats)
    print(f"\nPer iteration on {timing_mesh.name} (bend, plain iteration, median of {args.repeats} runs; "
          f"smooth rotations: {STEPS} rotation steps and {SWEEPS} sweeps per local step):")
    print("| energy | ms per iteration | ÷ spokes |")
    print("|---|---|---|")
    for e in ENERGIES:
        print(f"| {e} | {ms[e]:.2f} | {ms[e] / ms['spokes']:.2f} |")

    print(f"\nOne vertex pulled by 20% of the diagonal, solved until converged (at most {args.max_iterations}):")
    print("| mesh | energy | folded pairs added (rest) | max dihedral change | iterations | converged | seconds "
          "| ms per iteration | final energy |")
    print("|---|---|---|---|---|---|---|---|---|")
    pulls: dict[str, list[dict[str, Any]]] = {}
    for path in args.meshes:
        _, F, rows, shapes = pulled(path, args.max_iterations)
        pulls[path.stem] = rows
        for r in rows:
            print(f"| {path.stem} | {r['energy']} | {r['folds']:+d} ({r['rest_folds']}) | {r['dihedral']:.0f}° | "
                  f"{r['iterations']} | {'yes' if r['converged'] else 'no'} | {r['seconds']:.1f} | "
                  f"{1000 * r['seconds'] / max(r['iterations'], 1):.2f} | {r['energy_value']:.6g} |")
        if args.screenshots is not None:
            print(f"  rendered: {screenshots(args.screenshots, path.stem, F, shapes)}")
    if args.json:
        write_results(args.json, "bench_energies", [
            figure(f"time per iteration, {e} energy, {timing_mesh.name}", ms[e], "ms", "spokes energy", ms["spokes"])
            for e in ENERGIES if e != "spokes"] + [figure(f"time per iteration, spokes energy, {timing_mesh.name}",
                                                          ms["spokes"], "ms")],
            {"ms_per_iteration": ms, "pulled": pulls})
    return 0


if __name__ == "__main__":
    sys.exit(main())
