"""The first run in a new environment says that it compiles, once, before the wait; ``arap warmup`` does it ahead."""

from __future__ import annotations

import importlib
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


def test_the_warm_up_plan_names_the_kernels_it_prepares() -> None:
    """Every kernel the progress counts is a compiled kernel of arap that the warm-up makes ready."""
    from numba.core.dispatcher import Dispatcher

    arap.warmup.warm_up_kernels()
    kernels = arap.warmup.FIRST_KERNELS + arap.warmup.LATER_KERNELS
    every = kernels + arap.warmup.EVERY_SOLVE_KERNELS
    assert len(set(every)) == len(every)
    for qualified in every:
        module, _, name = qualified.rpartition(".")
        assert isinstance(getattr(importlib.import_module(module), name), Dispatcher), qualified
    progress = arap.warmup.compile_progress()
    assert progress.done == progress.total == len(kernels)


def test_compile_progress_names_each_kernel_as_it_is_compiled(capsys: pytest.CaptureFixture[str]) -> None:
    import numba
    from numba.core import event

    from arap.warmup import compile_reporter

    @numba.njit(cache=False)
    def _tiny_kernel(x: float) -> float:
        return x + 1.0

    seen: list[arap.warmup.CompileProgress] = []
    during: list[arap.warmup.CompileProgress] = []

    report = compile_reporter(every=0.0)

    def progress(p: arap.warmup.CompileProgress) -> None:
        seen.append(p)
        report(p)

    with event.install_listener("numba:compile", arap.warmup._compile_listener(progress)):
        _tiny_kernel(1.0)
        during.append(arap.warmup.compile_progress())
    assert seen and seen[-1].kernel == "_tiny_kernel" and not seen[-1].compiling
    assert during[0].kernel == "_tiny_kernel"
    assert "kernels ready (compiled _tiny_kernel)" in seen[-1].describe()
    assert "arap: compiling the solver's kernels: " in capsys.readouterr().err
