"""Fixtures shared by all test folders."""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
from collections.abc import Generator
from pathlib import Path

import pytest

from tests.waiting import time_factor

REPO_ROOT = Path(__file__).resolve().parents[1]

_HYPOTHESIS_HOME = Path(tempfile.mkdtemp(prefix="arap-hypothesis-"))

STRICT_ENV = "ARAP_TEST_STRICT"
"""With ``ARAP_TEST_STRICT=1`` (as ``.ci/run`` sets it) a skipped test fails: a missing Chromium, Node.js, libigl,
CHOLMOD or shared meshes folder would otherwise remove a whole area of tests from a green run without a word."""
STRICT_ALLOWED = ("cannot make a device node here",)
"""Skip reasons that strict runs keep as skips: what the machine forbids rather than what set-up forgot."""


def strict_failure(reason: str) -> str | None:
    """The failure message for a skip with ``reason`` in a strict run, or None where the skip stands."""
    if os.environ.get(STRICT_ENV) != "1" or any(allowed in reason for allowed in STRICT_ALLOWED):
        return None
    return (f"skipped ({reason}), and {STRICT_ENV}=1 makes every skip fail: install what the test needs "
            "(./dev test sets it all up)")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, None, None]:
    """In strict runs (:data:`STRICT_ENV`), a skip is reported as a failure."""
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    if report.skipped and not hasattr(report, "wasxfail"):
        longrepr = report.longrepr
        reason = longrepr[2] if isinstance(longrepr, tuple) and len(longrepr) == 3 else str(longrepr)
        message = strict_failure(str(reason))
        if message is not None:
            report.outcome = "failed"
            report.longrepr = message


def pytest_configure(config: pytest.Config) -> None:
    """Hypothesis keeps its caches in a temporary folder, never in the checkout. Ctrl-C works as in a terminal:
    pytest-xdist's workers start with SIGINT ignored, which the tests of interrupted commands (and the processes
    they start, which inherit it) must not see."""
    from hypothesis.configuration import set_hypothesis_home_dir

    set_hypothesis_home_dir(_HYPOTHESIS_HOME)
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On a loaded machine each test's time limit (pytest-timeout's marker, else its ``timeout`` setting) is
    stretched as its waits are (:func:`tests.waiting.time_factor`): such a test should pass slowly, not fail."""
    factor = time_factor()
    if factor <= 1.0:
        return
    default = config.getoption("timeout", None) or config.getini("timeout")
    for item in items:
        marker = item.get_closest_marker("timeout")
        kwargs = dict(marker.kwargs) if marker is not None else {}
        seconds = kwargs.pop("timeout", marker.args[0] if marker is not None and marker.args else default)
        if seconds and float(seconds) > 0:
            item.add_marker(pytest.mark.timeout(float(seconds) * factor, **kwargs))


def pytest_unconfigure(config: pytest.Config) -> None:
    shutil.rmtree(_HYPOTHESIS_HOME, ignore_errors=True)


@pytest.fixture(scope="session")
def shared_meshes_dir() -> Path:
    """The shared benchmark meshes (``../shared/meshes`` beside the repository); skips when absent."""
    path = REPO_ROOT.parent / "shared" / "meshes"
    if not path.is_dir():
        pytest.skip(f"shared meshes folder {path} not found")
    return path
