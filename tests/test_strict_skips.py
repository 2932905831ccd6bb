"""``ARAP_TEST_STRICT=1`` turns skips into failures (CI sets it), except where the machine forbids the test."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import STRICT_ENV, strict_failure

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("workers", [[], ["-n", "2"]], ids=["one-process", "xdist-workers"])
def test_strict_runs_fail_skipped_tests(tmp_path: Path, workers: list[str]) -> None:
    """Also on pytest-xdist's workers (.ci/run's jobs): a skip there is turned into a failure before it is reported."""
    probe = tmp_path / "test_probe.py"
    probe.write_text("import pytest\n\n"
                     "def test_skipped():\n    pytest.skip('chromium is missing')\n\n"
                     "@pytest.mark.skipif(True, reason='node is not installed')\ndef test_marked():\n    pass\n\n"
                     "def test_passes():\n    pass\n")
    conftest = ROOT / "tests" / "conftest.py"
    (tmp_path / "conftest.py").write_text(conftest.read_text())
    # A skip in the call fails the test; one in the set-up (a skipif mark, a fixture) errors it: both fail the run.
    for strict, expected in (("1", "1 failed, 1 passed, 1 error"), ("0", "1 passed, 2 skipped")):
        run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *workers, str(probe)],
                             cwd=tmp_path, capture_output=True, text=True, timeout=120,
                             env={"PATH": "/usr/bin:/bin", STRICT_ENV: strict, "PYTHONPATH": str(ROOT)})
        assert expected in run.stdout, run.stdout[-2000:]
        assert (run.returncode != 0) == (strict == "1")
        if strict == "1":
            assert "chromium is missing" in run.stdout and "node is not installed" in run.stdout


def test_what_the_machine_forbids_stays_a_skip(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(STRICT_ENV, "1")
    assert strict_failure("cannot make a device node here: [Errno 1] Operation not permitted") is None
    assert strict_failure("libigl is not installed") is not None
    monkeypatch.setenv(STRICT_ENV, "0")
    assert strict_failure("libigl is not installed") is None
