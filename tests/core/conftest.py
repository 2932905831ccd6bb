"""Fixtures for the solver tests: generated meshes and the shared real meshes (file vertex order)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh


def _load(directory: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.load(directory / name, process=False, force="mesh")
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def icosphere() -> tuple[np.ndarray, np.ndarray]:
    """A subdivided icosahedron: near-equilateral triangles, no obtuse angle (all cotangent weights > 0)."""
    m = trimesh.creation.icosphere(subdivisions=3)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def knight(shared_meshes_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    return _load(shared_meshes_dir, "decimated-knight.off")


@pytest.fixture(scope="session")
def camelhead(shared_meshes_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    return _load(shared_meshes_dir, "camelhead.off")


@pytest.fixture(scope="session")
def armadillo(shared_meshes_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    return _load(shared_meshes_dir, "armadillo.obj")
