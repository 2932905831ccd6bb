"""The energy ``arap deform``, ``arap animate`` and ``arap batch`` take when none is given: the element energy for a
flat mesh file that the constraints keep in its plane (as the studio deforms a picture), the surface energy for a
surface in space and for a flat sheet bent out of its plane."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.cli import main
from arap.meshes.domain import default_energy


def _grid(n: int = 7, plane: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A unit square of (n-1)² pairs of triangles, in the plane where coordinate ``plane`` is 0.5."""
    x, y = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n))
    flat = np.c_[x.ravel(), y.ravel()]
    V = np.insert(flat, plane, 0.5, axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    F = np.concatenate([np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]])
    return V, F


@pytest.mark.parametrize("plane", [0, 1, 2])
def test_a_flat_mesh_takes_the_element_energy_in_any_plane_of_constant_coordinate(plane: int) -> None:
    V, F = _grid(plane=plane)
    assert default_energy(V, F) == "elements"
    assert default_energy(V, F, V[:3] + 0.1 * (np.arange(3) != plane)) == "elements"  # targets in the plane


def test_a_surface_in_space_a_bent_sheet_and_a_folded_sheet_take_the_surface_energy() -> None:
    V, F = _grid()
    bumpy = V.copy()
    bumpy[10, 2] += 0.1
    assert default_energy(bumpy, F) == "spokes_and_rims"
    assert default_energy(V, F, V[:2] + np.array([0.0, 0.0, 0.2])) == "spokes_and_rims"  # a target out of its plane
    folded = F.copy()
    folded[0] = folded[0, [0, 2, 1]]
    assert default_energy(V, folded) == "spokes_and_rims"
    assert default_energy(np.eye(4, 3), np.array([[0, 1, 2, 3]])) == "elements"  # tetrahedra


def _deform(tmp_path: Path, mesh: Path, name: str, *options: str) -> np.ndarray:
    from arap.io import load_mesh

    out = tmp_path / f"{name}.obj"
    assert main(["deform", str(mesh), "--fix", "x<0.01", "--handle", "x>0.99", *options, "-o", str(out), "-q"]) == 0
    return load_mesh(out, repair=False)[0]


def test_arap_deform_bends_a_flat_mesh_in_its_plane_with_the_element_energy_by_default(tmp_path: Path) -> None:
    from arap.io import save_mesh

    V, F = _grid()
    mesh = tmp_path / "sheet.obj"
    save_mesh(mesh, V, F)
    move = ("--move", "0,0.4,0", "--rotate", "z:30")
    default = _deform(tmp_path, mesh, "default", *move)
    elements = _deform(tmp_path, mesh, "elements", *move, "--energy", "elements")
    surface = _deform(tmp_path, mesh, "surface", *move, "--energy", "spokes_and_rims")
    np.testing.assert_allclose(default, elements, atol=1e-6)
    assert np.abs(default - surface).max() > 1e-3  # the two energies give other shapes
    np.testing.assert_allclose(default[:, 2], 0.5)
    # Moved out of its plane, the sheet bends in space with the surface energy (elements keep it in its plane).
    up = ("--move", "0,0,0.3")
    np.testing.assert_allclose(_deform(tmp_path, mesh, "up", *up),
                               _deform(tmp_path, mesh, "up_surface", *up, "--energy", "spokes_and_rims"), atol=1e-6)


def test_arap_deform_keeps_the_surface_energy_for_a_surface_in_space(tmp_path: Path) -> None:
    from arap.io import save_mesh

    V, F = _grid()
    V[:, 2] += 0.2 * np.sin(3.0 * V[:, 0]) * V[:, 1]
    mesh = tmp_path / "curved.obj"
    save_mesh(mesh, V, F)
    move = ("--move", "0,0.3,0")
    np.testing.assert_allclose(_deform(tmp_path, mesh, "default", *move),
                               _deform(tmp_path, mesh, "surface", *move, "--energy", "spokes_and_rims"), atol=1e-6)


def test_a_batch_job_without_an_energy_deforms_a_flat_mesh_as_arap_deform_does(tmp_path: Path) -> None:
    from arap.io import load_mesh, save_mesh

    V, F = _grid()
    save_mesh(tmp_path / "sheet.obj", V, F)
    fixed = np.flatnonzero(V[:, 0] < 0.01)
    handles = np.flatnonzero(V[:, 0] > 0.99)
    for name, move in (("flat", [0.0, 0.4, 0.0]), ("up", [0.0, 0.0, 0.3])):
        doc = {"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": (V[handles] + move).tolist()}
        (tmp_path / f"{name}.json").write_text(json.dumps(doc))
    (tmp_path / "jobs.jsonl").write_text("".join(json.dumps({"mesh": "sheet.obj", "constraints": f"{name}.json",
                                                             "output": f"{name}.obj"}) + "\n"
                                                 for name in ("flat", "up")))
    assert main(["batch", str(tmp_path / "jobs.jsonl"), "--backend", "serial", "-q"]) == 0
    for name, energy in (("flat", "elements"), ("up", "spokes_and_rims")):
        out = tmp_path / f"{name}_{energy}.obj"
        assert main(["deform", str(tmp_path / "sheet.obj"), "-c", str(tmp_path / f"{name}.json"), "-o", str(out),
                     "-q", "--energy", energy]) == 0
        np.testing.assert_allclose(load_mesh(tmp_path / f"{name}.obj", repair=False)[0],
                                   load_mesh(out, repair=False)[0], atol=1e-6)
