"""The scan of benchmarks/bench_elements.py: a closed surface filled with tetrahedra, and its cache."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from arap.io.meshfile import save_mesh
from arap.meshes.domain import signed_measures
from arap.meshes.shapes import builtin_mesh
from tests.tool_modules import load_benchmark


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("bench_elements")


def _boundary_distances(bench: ModuleType, V: np.ndarray, F: np.ndarray, V_tet: np.ndarray,
                        T: np.ndarray) -> np.ndarray:
    import igl

    faces, index = bench._faces(T)
    boundary = np.unique(faces[np.bincount(index) == 1])
    return np.sqrt(np.asarray(igl.point_mesh_squared_distance(V_tet[boundary], V, F)[0]))


def test_fill_surface_gives_one_piece_of_well_shaped_tetrahedra_close_to_the_surface(bench: ModuleType) -> None:
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    V, F = builtin_mesh("sphere:1000")  # radius 1
    V_tet, T = bench.fill_surface(V, F, 3000, min_quality=0.1)
    assert 2000 <= len(T) <= 4000
    assert np.array_equal(np.unique(T), np.arange(len(V_tet)))  # every vertex used
    assert signed_measures(V_tet, T).min() > 0
    assert bench._quality(V_tet, T).min() >= 0.1 - 1e-9
    spacing = np.cbrt(6 * (4 / 3 * np.pi) / 3000)  # the lattice's
    lattice = _boundary_distances(bench, V, F, *bench.fill_surface(V, F, 3000, rounds=0))
    moved = _boundary_distances(bench, V, F, V_tet, T)
    assert np.median(moved) < 0.5 * np.median(lattice)
    assert np.median(moved) < 0.15 * spacing and moved.max() < 0.5 * spacing
    _, index = bench._faces(T)  # one piece: a walk over shared faces reaches every tetrahedron
    owner = np.repeat(np.arange(len(T)), 4)
    order = np.argsort(index, kind="stable")
    pairs = np.flatnonzero(index[order][1:] == index[order][:-1])
    graph = sp.coo_matrix((np.ones(len(pairs)), (owner[order][pairs], owner[order][pairs + 1])), shape=(len(T),) * 2)
    assert connected_components(graph, directed=False)[0] == 1


def test_fill_surface_keeps_the_largest_piece(bench: ModuleType) -> None:
    big, F = builtin_mesh("sphere:500")
    small = big * 0.3 + [3.0, 0.0, 0.0]  # a ball apart from the big one
    V_tet, T = bench.fill_surface(np.concatenate([big, small]), np.concatenate([F, F + len(big)]), 2000)
    assert V_tet[:, 0].max() < 1.5 and len(T) > 1500  # the small ball (x from 2.7) is left out


def test_scan_tetrahedra_are_cached_by_file_and_count(bench: ModuleType, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bench, "cache_folder", lambda: tmp_path / "cache")
    V, F = builtin_mesh("sphere:500")
    scan = tmp_path / "ball.obj"
    save_mesh(scan, V, F)
    V_tet, T = bench.scan_tetrahedra(scan, 1500)
    cached = list((tmp_path / "cache").rglob("scan-ball-*.npz"))
    assert len(cached) == 1
    calls: list[int] = []
    monkeypatch.setattr(bench, "fill_surface", lambda *args, **kwargs: calls.append(1))
    again = bench.scan_tetrahedra(scan, 1500)
    assert not calls and np.array_equal(again[0], V_tet) and np.array_equal(again[1], T)
    monkeypatch.undo()
    monkeypatch.setattr(bench, "cache_folder", lambda: tmp_path / "cache")
    bench.scan_tetrahedra(scan, 800)  # another count: another entry
    assert len(list((tmp_path / "cache").rglob("scan-ball-*.npz"))) == 2
