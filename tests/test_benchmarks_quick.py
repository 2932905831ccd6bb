"""Every benchmark runs to its end with ``--quick`` (tiny sizes, short runs: a check that it works, not a
measurement), each in a subprocess as a reader would run it. They spread over pytest-xdist's workers like other
tests: a ``--quick`` run judges no time (its exit status says only that it ran), so a benchmark beside another
test is as good a check as one alone, and one worker running all of them in turn held the whole run back."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.waiting import scaled

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = sorted(p.name for p in (ROOT / "benchmarks").glob("bench_*.py"))
IN_A_BROWSER = {"bench_client.py"}
"""Benchmarks that open the studio in the system's Chromium."""

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]


def test_the_benchmarks_are_found() -> None:
    assert {"bench_armadillo.py", "bench_studio.py", "bench_client.py"} <= set(BENCHMARKS)


@pytest.mark.parametrize("name", BENCHMARKS)
def test_the_benchmark_runs_quick(name: str, tmp_path: Path) -> None:
    if name in IN_A_BROWSER and shutil.which("chromium") is None and not Path("/usr/bin/chromium").is_file():
        pytest.skip("Chromium is not installed")
    extra = ["--out", str(tmp_path / "out")] if name == "bench_client.py" else []
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / name), "--quick", *extra], cwd=tmp_path,
                          capture_output=True, text=True, timeout=scaled(300), check=False)
    assert done.returncode == 0, (f"{name} --quick exited {done.returncode}:\n{done.stdout[-2000:]}\n"
                                  f"{done.stderr[-3000:]}")
