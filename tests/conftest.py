"""Fixtures shared by all test folders."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def shared_meshes_dir() -> Path:
    """The shared benchmark meshes (``../shared/meshes`` beside the repository); skips when absent."""
    path = REPO_ROOT.parent / "shared" / "meshes"
    if not path.is_dir():
        pytest.skip(f"shared meshes folder {path} not found")
    return path
