"""Fixtures for the solver tests: generated meshes and the shared real meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

REPO = Path(__file__).resolve().parents[2]
SHARED_MESHES = REPO.parent / "shared" / "meshes"


def load_real(name: str) -> tuple[np.ndarray, np.ndarray]:
    """A mesh from ../shared/meshes in file vertex order; skips the test if the folder is absent."""
    path = SHARED_MESHES / name
    if not path.exists():
        pytest.skip(f"shared mesh {path} not available")
    m = trimesh.load(path, process=False, force="mesh")
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def icosphere() -> tuple[np.ndarray, np.ndarray]:
    """A subdivided icosahedron: near-equilateral triangles, no obtuse angle (all cotangent weights > 0)."""
    m = trimesh.creation.icosphere(subdivisions=3)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def knight() -> tuple[np.ndarray, np.ndarray]:
    return load_real("decimated-knight.off")


@pytest.fixture(scope="session")
def camelhead() -> tuple[np.ndarray, np.ndarray]:
    return load_real("camelhead.off")


@pytest.fixture(scope="session")
def armadillo() -> tuple[np.ndarray, np.ndarray]:
    return load_real("armadillo.obj")
