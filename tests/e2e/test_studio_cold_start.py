"""A fresh install: ``arap studio`` serves the page at once and compiles the kernels behind it; the page says that
the solver is being prepared, then edits as usual."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import pytest
from playwright.sync_api import Browser

from tests.waiting import scaled, time_factor

from .conftest import VIEWPORT, wait_for_page, wait_ready

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]


def test_the_page_comes_at_once_and_says_the_solver_is_being_prepared(browser: Browser, tmp_path: Path) -> None:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty-cache"), "PYTHONUNBUFFERED": "1"}
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "arap.cli", "studio", "cactus", "--port", "0"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    err_lines: list[str] = []
    threading.Thread(target=lambda: err_lines.extend(proc.stderr or []), daemon=True).start()
    try:
        line = proc.stdout.readline() if proc.stdout else ""
        match = re.search(r"(http://\S+)", line)
        assert match, (line, err_lines)
        url = match.group(1)
        with urllib.request.urlopen(url, timeout=scaled(30)) as answer:
            assert answer.status == 200 and b"<html" in answer.read().lower()
        page_seconds = time.monotonic() - t0
        assert not any("compiled" in e and "kernels in" in e for e in err_lines), "the page waited for the compile"
        assert any("in the background" in e for e in err_lines), err_lines
        context = browser.new_context(viewport=VIEWPORT)
        page = context.new_page()
        page.goto(url)
        wait_for_page(page, "() => document.getElementById('status-text')?.textContent.includes("
                      "'preparing the solver')", "the page to say that the solver is being prepared")
        assert "preparing the solver" in (page.text_content("#conn-text") or "")
        wait_ready(page, timeout_ms=240_000)  # the compile ends, the welcome and the mesh arrive
        assert "preparing" not in (page.text_content("#status-text") or "") or page.is_hidden("#statusbar")
        assert page.text_content("#conn-text") == "connected"
        context.close()
        factor = time_factor()  # the page comes before the compile ends, however loaded the machine
        assert page_seconds < 20 * factor, (page_seconds, factor)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
