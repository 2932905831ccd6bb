"""The figures a benchmark measured, written as JSON for ``tools/bench_table.py`` (which makes the results table of
``docs/benchmarks.md`` from them).

Every benchmark takes ``--json [PATH]``: with a path it writes its figures there, without one to
``benchmarks/results/<benchmark>.json``. The file (written atomically) holds::

    {"schema": 1, "benchmark": "bench_settle",
     "machine": {"cpu_count": 16, "python": "3.11.7", "platform": "Linux-...", "date": "2026-11-27T02:30:00+00:00"},
     "figures": [{"name": "median release to settled", "value": 0.21, "unit": "s",
                  "peer": "target", "peer_value": 0.5, "better": "lower"}, ...],
     "data": {...}}

``figures`` are the headline numbers, one table row each: arap's ``value``, and where the benchmark measures one,
a ``peer`` (another library, a baseline, a target) with its ``peer_value`` in the same unit; ``better`` says which
way is better (the table's ratio is how many times better arap is). ``data`` is everything else the benchmark
measured, as it chooses.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
from pathlib import Path
from typing import Any

from arap.io.atomic import write_atomic

SCHEMA = 1
RESULTS_DIR = Path(__file__).resolve().parent / "results"
"""Where ``--json`` without a path writes (``<benchmark>.json``)."""


def add_json_option(parser: argparse.ArgumentParser, benchmark: str) -> None:
    """The ``--json [PATH]`` option (default path: ``RESULTS_DIR / f"{benchmark}.json"``)."""
    parser.add_argument("--json", type=Path, nargs="?", const=RESULTS_DIR / f"{benchmark}.json", default=None,
                        metavar="PATH", help=f"write the figures as JSON to PATH (default: benchmarks/results/"
                        f"{benchmark}.json)")


def figure(name: str, value: float, unit: str, peer: str | None = None, peer_value: float | None = None,
           better: str = "lower") -> dict[str, Any]:
    """One headline figure: arap's ``value`` in ``unit``, and a ``peer``'s in the same unit where measured;
    ``better``: ``"lower"`` (times) or ``"higher"`` (throughputs)."""
    if better not in ("lower", "higher"):
        raise ValueError(f"better must be 'lower' or 'higher', not {better!r}")
    out: dict[str, Any] = {"name": name, "value": float(value), "unit": unit, "better": better}
    if peer is not None and peer_value is not None:
        out["peer"] = peer
        out["peer_value"] = float(peer_value)
    return out


def quick_mesh(folder: Path, vertices: int = 1000) -> Path:
    """A built-in sphere of about ``vertices`` vertices written as OBJ in ``folder``: the mesh of the ``--quick`` runs
    of the benchmarks that read a mesh file (checks that they run, not measurements)."""
    from arap.io import save_mesh
    from arap.meshes.shapes import builtin_mesh

    path = folder / f"sphere{vertices}.obj"
    save_mesh(path, *builtin_mesh(f"sphere:{vertices}"))
    return path


def machine() -> dict[str, Any]:
    """What the figures were measured on."""
    return {"cpu_count": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform(),
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}


def write_results(path: Path, benchmark: str, figures: list[dict[str, Any]], data: Any = None) -> None:
    """Write ``figures`` (see :func:`figure`) and ``data`` of ``benchmark`` to ``path`` atomically."""
    document = {"schema": SCHEMA, "benchmark": benchmark, "machine": machine(), "figures": figures, "data": data}
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(document, indent=2, default=_plain) + "\n")
    print(f"wrote {path}")


def _plain(value: Any) -> Any:
    """numpy scalars and arrays, paths: as JSON values."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
