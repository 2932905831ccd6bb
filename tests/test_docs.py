"""The documentation site builds with no warning (`mkdocs build --strict`) and holds the generated references."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.timeout(300)

ROOT = Path(__file__).resolve().parents[1]


def test_docs_build_strict_with_generated_references(tmp_path: Path) -> None:
    site = tmp_path / "site"
    env = os.environ | {"NO_MKDOCS_2_WARNING": "1"}
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)], cwd=ROOT,
                         capture_output=True, text=True, env=env, timeout=240)
    assert run.returncode == 0, run.stderr[-4000:]
    assert "WARNING" not in run.stderr
    api = (site / "api" / "index.html").read_text()
    for name in ("ArapSolver", "arap_energy", "save_mesh", "studio", "OptionError"):
        assert name in api
    assert "max_iterations" in api  # the docstrings' parameter sections were rendered
    cli = (site / "cli" / "index.html").read_text()
    for text in ("arap deform", "--constraints", "arap studio", "--allow-origin"):
        assert text in cli  # generated from the argument parser
    assert "bench_folds" in (site / "benchmarks" / "index.html").read_text()
    assert (site / "images" / "studio.jpg").stat().st_size > 10_000
    for page in site.rglob("*.html"):
        assert "fonts.googleapis.com" not in page.read_text(errors="replace")  # nothing fetched from a CDN
