"""The first run in a new environment says that it compiles, once, before the wait; ``arap warmup`` does it ahead."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import arap
import arap.solve.kernel_cache
import arap.warmup
from arap.cli import main


def test_an_empty_cache_is_told_apart_from_a_warm_one(tmp_path: Path) -> None:
    code = "import arap.solve.kernel_cache as k; print(k.first_compile_pending())"
    cold = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)})
    assert cold.stdout.strip() == "True", cold.stderr
    arap.warmup.warm_up_kernels()
    assert arap.solve.kernel_cache.first_compile_pending() is False


def test_the_first_compile_is_announced_once(monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.setattr(arap.solve.kernel_cache, "_announced", False)
    monkeypatch.setattr(arap.solve.kernel_cache, "first_compile_pending", lambda: True)
    V, F = arap.builtin_mesh("bar")
    with caplog.at_level(logging.WARNING, logger="arap"):
        arap.ArapSolver(V, F, np.array([0, 1, 2]))
        arap.ArapSolver(V, F, np.array([0, 1, 2]))
    lines = [r.getMessage() for r in caplog.records if "compiling the solver's kernels" in r.getMessage()]
    assert len(lines) == 1 and "arap warmup" in lines[0]


def test_arap_warmup(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["warmup"]) == 0
    printed = capsys.readouterr().out
    assert "kernels ready" in printed or "compiled" in printed
