"""Unknown option names raise OptionError (an ArapError), and the library takes trimesh meshes as well as arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

import arap
from arap.errors import ArapError, ConstraintError, MeshError, OptionError
from arap.io import load_mesh, save_mesh
from arap.meshes.shapes import sphere
from arap.sparse.linsolve import factorize


@pytest.fixture
def box() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=2)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda V, F: arap.ArapSolver(V, F, [0], energy="spokes-and-rims"), "unknown energy"),
        (lambda V, F: arap.ArapSolver(V, F, [0], weights="cot"), "unknown weights"),
        (lambda V, F: arap.ArapSolver(V, F, [0]).solve(V[[0]], initial="best"), "unknown initial"),
        (lambda V, F: arap.ArapSolver(V, F, [0]).solve(V[[0]], acceleration="fast"), "unknown acceleration"),
        (lambda V, F: arap.ArapSolver(V, F, [0]).solve(V[[0]], window=0), "window"),
        (lambda V, F: arap.ArapSolver(V, F, [0]).solve(V[[0]], tolerance=-1.0), "tolerance"),
        (lambda V, F: arap.ArapSolver(V, F, [0]).solve(V[[0]], tolerance=0, max_iterations=10**12),
         "would not return"),
        (lambda V, F: arap.arap_energy(V, F, V, energy="rims"), "unknown energy"),
        (lambda V, F: arap.cell_energies(V, F, V, weights="mean"), "unknown weights"),
        (lambda V, F: factorize(arap.cotangent_laplacian(V, F), backend="mumps"), "unknown backend"),
        (lambda V, F: arap.builtin_mesh("teapot"), "unknown built-in mesh"),
        (lambda V, F: sphere(600), "vertices, more than"),
        (lambda V, F: sphere(frequency=0), ">= 1"),
    ],
)
def test_unknown_options_raise_option_error(icosphere: tuple[np.ndarray, np.ndarray], call, match: str) -> None:
    V, F = icosphere
    with pytest.raises(OptionError, match=match) as info:
        call(V, F)
    assert isinstance(info.value, ArapError)


def test_energy_inputs_raise_arap_errors(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(ArapError, match="shape of V"):
        arap.arap_energy(V, F, V[:-1])
    with pytest.raises(ArapError, match="non-finite"):
        arap.arap_energy(V, F, np.full_like(V, np.nan))
    with pytest.raises(ArapError, match="missing"):
        arap.arap_energy(V, F)
    with pytest.raises(MeshError):
        arap.arap_energy(V, F[:, :2], V)


def test_solver_takes_a_trimesh_mesh(box: trimesh.Trimesh) -> None:
    V, F = np.asarray(box.vertices), np.asarray(box.faces)
    fixed = np.flatnonzero(V[:, 1] < -0.6)
    handle = np.flatnonzero(V[:, 1] > 0.6)
    constrained = np.concatenate([fixed, handle])
    targets = V[constrained].copy()
    targets[len(fixed):] += [0.3, 0.1, 0.0]
    expected = arap.ArapSolver(V, F, constrained).solve(targets, max_iterations=20).vertices
    for solver in (arap.ArapSolver(box, constrained), arap.ArapSolver(box, constrained=constrained)):
        np.testing.assert_array_equal(solver.solve(targets, max_iterations=20).vertices, expected)
    with pytest.raises(ConstraintError, match="missing"):
        arap.ArapSolver(box)
    with pytest.raises(MeshError, match="not both"):
        arap.ArapSolver(box, F, constrained)
    with pytest.raises(MeshError, match=r"F \(the triangles\) is missing"):
        arap.ArapSolver(V, constrained=constrained)


def test_energy_takes_mesh_objects(box: trimesh.Trimesh) -> None:
    V, F = np.asarray(box.vertices), np.asarray(box.faces)
    U = V * [1.2, 1.0, 0.9]
    deformed = trimesh.Trimesh(U, F, process=False)
    expected = arap.arap_energy(V, F, U)
    assert expected > 0
    # equal up to the summation order the kernels' thread choice may change
    assert arap.arap_energy(box, U) == pytest.approx(expected, rel=1e-12)
    assert arap.arap_energy(box, deformed) == pytest.approx(expected, rel=1e-12)
    assert arap.arap_energy(V, F, deformed) == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(arap.cell_energies(box, U=U), arap.cell_energies(V, F, U), rtol=1e-12, atol=0)


def test_save_mesh_takes_a_mesh_object(box: trimesh.Trimesh, tmp_path: Path) -> None:
    save_mesh(tmp_path / "a.obj", box)
    V, F = load_mesh(tmp_path / "a.obj")
    np.testing.assert_array_equal(V, box.vertices)
    np.testing.assert_array_equal(F, box.faces)
    with pytest.raises(MeshError, match="not both"):
        save_mesh(tmp_path / "b.obj", box, F)
    assert not (tmp_path / "b.obj").exists()
