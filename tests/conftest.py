"""Fixtures shared by all test folders."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]

_HYPOTHESIS_HOME = Path(tempfile.mkdtemp(prefix="arap-hypothesis-"))


def pytest_configure(config: pytest.Config) -> None:
    """Hypothesis keeps its caches in a temporary folder, never in the checkout."""
    from hypothesis.configuration import set_hypothesis_home_dir

    set_hypothesis_home_dir(_HYPOTHESIS_HOME)


def pytest_unconfigure(config: pytest.Config) -> None:
    shutil.rmtree(_HYPOTHESIS_HOME, ignore_errors=True)


@pytest.fixture(scope="session")
def shared_meshes_dir() -> Path:
    """The shared benchmark meshes (``../shared/meshes`` beside the repository); skips when absent."""
    path = REPO_ROOT.parent / "shared" / "meshes"
    if not path.is_dir():
        pytest.skip(f"shared meshes folder {path} not found")
    return path
