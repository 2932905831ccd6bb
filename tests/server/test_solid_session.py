"""A tetrahedral solid in the studio's session: drawn by its boundary, deformed through its tetrahedra."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import arap
from arap.server.heatmap import distortion_frame
from arap.server.meshdata import builtin_names, load_builtin
from arap.server.session import Session
from tests.server.helpers import StudioClient, rotation_z, translation


@pytest.fixture
def session() -> Session:
    s = Session()
    s.load(load_builtin("solid bar"))
    return s


def _ends(s: Session) -> tuple[list[int], list[int]]:
    """Boundary vertices at the bottom and at the top (the ones a user can pick)."""
    assert s.mesh is not None
    on_surface = np.unique(s.mesh.F)
    y = s.V[on_surface, 1]
    return on_surface[y <= y.min() + 1e-9].tolist(), on_surface[y >= y.max() - 1e-9].tolist()


def test_the_solid_bar_is_built_in_and_drawn_by_its_boundary(session: Session) -> None:
    assert "solid bar" in builtin_names()
    mesh = session.mesh
    assert mesh is not None and mesh.elements is not None and mesh.elements.shape[1] == 4
    assert len(np.unique(mesh.F)) < mesh.n_vertices  # interior vertices are not drawn
    # the boundary is closed: every edge in two triangles
    edges = np.sort(np.concatenate([mesh.F[:, [0, 1]], mesh.F[:, [1, 2]], mesh.F[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2)


def test_a_drag_deforms_the_tetrahedra_and_the_inside_follows(session: Session) -> None:
    bottom, top = _ends(session)
    session.set_constraints(None, bottom, [top])
    M = rotation_z(0.6, session.V[top].mean(axis=0), shift=(0.8, 0.0, 0.0))
    session.drag([M.T.ravel().tolist()])
    session.end_drag()
    assert session.solver is not None and session.solver.energy_type == "elements"
    assert session.solver.prepared.cells.n_cells == len(session.mesh.elements)  # type: ignore[union-attr]
    outcome = session.settle(lambda: False)
    assert outcome is not None and outcome.converged
    U, V = session.U, session.V
    np.testing.assert_allclose(U[top], V[top] @ M[:3, :3].T + M[:3, 3], atol=1e-9)
    inside = np.setdiff1d(np.arange(len(V)), np.unique(session.mesh.F))  # type: ignore[union-attr]
    assert np.abs(U[inside] - V[inside]).max() > 0.1
    # settled: the same solve from the shape shown stays there
    again = arap.ArapSolver(V, session.mesh.elements, bottom + top)  # type: ignore[union-attr]
    np.testing.assert_allclose(again.solve(U[bottom + top], initial=U).vertices, U, atol=1e-6)
    header, payload = distortion_frame(session)
    values = np.frombuffer(payload, dtype="<f4")
    assert values.shape == (len(V),) and header["max"] > 0 and np.all(values >= 0)


def test_a_point_handle_on_the_boundary_lands_on_its_target(session: Session) -> None:
    bottom, _ = _ends(session)
    mesh = session.mesh
    assert mesh is not None
    face = int(np.argmax(mesh.V[mesh.F].mean(axis=1)[:, 1]))  # a triangle on the top
    beta = [0.2, 0.3, 0.5]
    target = (np.array(beta) @ mesh.V[mesh.F[face]] + [0.5, 0.2, 0.0]).tolist()
    session.set_constraints(None, bottom, [], points=[{"face": face, "barycentric": beta, "target": target}])
    session.settle(lambda: False)
    np.testing.assert_allclose(np.array(beta) @ session.U[mesh.F[face]], target, atol=1e-8)
    session.drag([translation(0.0)])


# ---------------------------------------------------------------------------------------------- uploaded volume files
@pytest.mark.parametrize("ext", ["msh", "mesh", "vtu", "vtk"])
def test_an_uploaded_volume_file_opens_as_a_solid(studio: StudioClient, tmp_path: Path, ext: str) -> None:
    """A volume file uploaded to the studio: drawn by its boundary, solved on its tetrahedra, their count in the
    mesh message; a drag moves the handles and the inside follows."""
    pytest.importorskip("meshio")
    V, T = arap.box_tetrahedra(2, 6, 2, size=(1.0, 3.0, 1.0))
    arap.save_volume_mesh(tmp_path / f"bar.{ext}", V, T)
    studio.send_binary({"type": "upload", "filename": f"bar.{ext}"}, (tmp_path / f"bar.{ext}").read_bytes())
    mesh = studio.read_mesh().data
    assert mesh["name"] == "bar" and mesh["n_vertices"] == len(V) and mesh["n_tetrahedra"] == len(T)
    assert mesh["n_faces"] == len(arap.boundary_faces(T))
    assert any(f"{len(T):,} tetrahedra" in line for line in mesh["report"])
    studio.expect("state")
    lo, hi = studio.bottom_top(0.05)
    assert set(lo + hi) <= set(np.unique(studio.F).tolist())  # picked on the boundary drawn
    studio.set_constraints(lo, [hi])
    U = studio.drag(1, [translation(0.4)]).floats()
    np.testing.assert_allclose(U[hi], studio.V[hi] + [0.4, 0, 0], atol=1e-5)
    inside = np.setdiff1d(np.arange(len(V)), np.unique(studio.F))
    assert len(inside) and np.abs(U[inside, 0] - studio.V[inside, 0]).max() > 0.05  # the interior follows


def test_a_surface_upload_has_no_tetrahedra_and_a_bad_volume_file_is_refused(studio: StudioClient) -> None:
    pytest.importorskip("meshio")
    V, F = arap.builtin_mesh("bar")
    studio.send_binary({"type": "upload", "filename": "bar.obj"}, arap.save_mesh_bytes(V, F, "obj"))
    assert studio.read_mesh().data["n_tetrahedra"] == 0
    studio.expect("state")
    studio.send_binary({"type": "upload", "filename": "junk.msh"}, b"$MeshFormat\nnot a mesh\n")
    assert "cannot parse junk.msh as a gmsh file" in studio.error("bad_mesh")["message"]
    studio.send_binary({"type": "upload", "filename": "bar.node"}, b"4 3 0 0\n")
    assert "unsupported" in studio.error("bad_mesh")["message"]
