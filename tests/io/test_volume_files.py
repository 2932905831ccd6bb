"""Volume meshes in files (Medit, gmsh, VTK, TetGen), boundary surfaces, filling a closed surface with tetrahedra, and
``arap deform`` / ``arap info`` on solids and planar meshes."""

from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest

import arap
from arap.cli import main
from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io.volume import boundary_faces, boundary_surface, load_volume_mesh, save_volume_mesh
from arap.meshes.domain import signed_measures
from arap.meshes.grids import box_tetrahedra

MESHIO_FORMATS = ["mesh", "msh", "vtu", "vtk"]


def _needs_meshio(ext: str) -> None:
    if ext in MESHIO_FORMATS:
        pytest.importorskip("meshio")


def _has(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def _needs_pytetwild() -> None:
    """pytetwild's package imports PyVista, which arap does not need: look for it without importing it."""
    if not _has("pytetwild"):
        pytest.skip("pytetwild is not installed (pip install 'arap[solid]')")


# ---------------------------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("ext", [*MESHIO_FORMATS, "node", "ele"])
def test_a_tetrahedral_mesh_round_trips_exactly(tmp_path: Path, ext: str) -> None:
    _needs_meshio(ext)
    V, T = box_tetrahedra(2, 3, 2, size=(1.0, 5.0, 1.0))
    V = V + np.random.default_rng(1).normal(scale=1e-3, size=V.shape)  # digits that a short format would lose
    save_volume_mesh(tmp_path / f"bar.{ext}", V, T)
    W, S = load_volume_mesh(tmp_path / f"bar.{ext}")
    assert W.dtype == np.float64 and S.dtype == np.int64
    np.testing.assert_array_equal(W, V)
    np.testing.assert_array_equal(S, T)
    if ext in ("node", "ele"):
        assert sorted(os.listdir(tmp_path)) == ["bar.ele", "bar.node"]
    else:
        assert os.listdir(tmp_path) == [f"bar.{ext}"]


@pytest.mark.parametrize(("ext", "columns"), [("mesh", 2), ("node", 2), ("msh", 3), ("vtu", 3), ("vtk", 3)])
def test_a_planar_triangle_mesh_round_trips_with_its_columns_or_z_zero(tmp_path: Path, ext: str,
                                                                       columns: int) -> None:
    _needs_meshio(ext)
    V = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    save_volume_mesh(tmp_path / f"square.{ext}", V, F)
    W, G = load_volume_mesh(tmp_path / f"square.{ext}")
    assert W.shape == (4, columns)
    np.testing.assert_array_equal(W[:, :2], V)
    if columns == 3:
        assert not W[:, 2].any()
    np.testing.assert_array_equal(G, F)
    # Read as stored, the planar mesh is deformed in its plane with the element energy.
    U = arap.ArapSolver(W, G, [0, 1, 3], energy="elements").solve(W[[0, 1, 3]]).vertices
    assert U.shape == W.shape


# ---------------------------------------------------------------------------------------------- TetGen
def test_tetgen_files_numbered_from_one_with_attributes_markers_and_comments(tmp_path: Path) -> None:
    (tmp_path / "t.node").write_text(
        "# a tetrahedron and a point above it\n"
        "5 3 2 1  # points, dimension, attributes, boundary markers\n"
        "1  0 0 0   0.5 7  1\n"
        "2  1 0 0   0.5 7  1\n"
        "\n"
        "3  0 1 0   0.5 7  1   # comment after data\n"
        "4  0 0 1   0.5 7  1\n"
        "5  1 1 1   0.5 7  0\n")
    (tmp_path / "t.ele").write_text("2 4 1\n1  1 2 3 4  10\n2  2 5 3 4  -1.5\n")
    for name in ("t.node", "t.ele"):  # either file names the pair
        V, T = load_volume_mesh(tmp_path / name)
        np.testing.assert_array_equal(V, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
        assert T.tolist() == [[0, 1, 2, 3], [1, 4, 2, 3]]


def test_tetgen_files_numbered_from_zero_and_triangle_files(tmp_path: Path) -> None:
    (tmp_path / "z.node").write_text("4 3\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n")
    (tmp_path / "z.ele").write_text("1 4\n0 0 1 2 3\n")
    V, T = load_volume_mesh(tmp_path / "z.ele")
    assert V.shape == (4, 3) and T.tolist() == [[0, 1, 2, 3]]
    (tmp_path / "p.node").write_text("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n")  # Triangle's 2-d files
    (tmp_path / "p.ele").write_text("1 3 0\n1 1 2 3\n")
    V, T = load_volume_mesh(tmp_path / "p.node")
    assert V.shape == (3, 2) and T.tolist() == [[0, 1, 2]]


GOOD_NODE = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
GOOD_ELE = "1 4 0\n1 1 2 3 4\n"


@pytest.mark.parametrize(("node", "ele", "message"), [
    ("5 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", GOOD_ELE, "ends early: its header announces 5 points"),
    (GOOD_NODE + "5 1 1 1\n", GOOD_ELE, "line 6: more lines than the 4 points"),
    ("4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 x1\n", GOOD_ELE, "line 5: coordinates must be a number, got 'x1'"),
    ("4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 nan\n", GOOD_ELE, "line 5: coordinates must be finite"),
    ("4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1\n4 0 0 1\n", GOOD_ELE, "line 4: 3 numbers where the header asks for 4"),
    ("4 3 0 0\n1 0 0 0\n2 1 0 0\n4 0 1 0\n5 0 0 1\n", GOOD_ELE, "line 4: point 4 where 3 is expected"),
    ("4 3 0 0\n2 0 0 0\n3 1 0 0\n4 0 1 0\n5 0 0 1\n", GOOD_ELE, "numbers from 0 or 1"),
    ("4 5 0 0\n", GOOD_ELE, "dimension 5"),
    ("four 3 0 0\n", GOOD_ELE, "point count must be an integer, got 'four'"),
    ("1000000000000 3 0 0\n1 0 0 0\n", GOOD_ELE, "announces 1,000,000,000,000 points, but only 1 lines"),
    ("# only a comment\n", GOOD_ELE, "holds no data"),
    (GOOD_NODE, "1 4 0\n1 1 2 3 5\n", "element 1 names point 5, but"),
    (GOOD_NODE, "1 4 0\n1 0 1 2 3\n", "names point 0, but"),
    (GOOD_NODE, "1 4 0\n1 1 2 3 4.5\n", "point numbers must be an integer, got '4.5'"),
    (GOOD_NODE, "2 4 0\n1 1 2 3 4\n", "ends early: its header announces 2 elements"),
    (GOOD_NODE, "1 10 0\n1 1 2 3 4 1 2 3 4 1 2\n", "quadratic elements"),
    (GOOD_NODE, "1 3 0\n1 1 2 3\n", "3 nodes per element with 3-d points"),
    (GOOD_NODE, b"1 4 0\n1 1 2\x00 3 4\n", "binary data"),
])
def test_a_malformed_tetgen_file_gives_one_clear_error(tmp_path: Path, node: str, ele: str | bytes,
                                                       message: str) -> None:
    (tmp_path / "m.node").write_text(node)
    if isinstance(ele, bytes):
        (tmp_path / "m.ele").write_bytes(ele)
    else:
        (tmp_path / "m.ele").write_text(ele)
    with pytest.raises(MeshFormatError, match=message.replace("(", r"\(").replace(".", r"\.")):
        load_volume_mesh(tmp_path / "m.ele")


def test_a_tetgen_file_without_its_pair_or_too_large_is_refused(tmp_path: Path) -> None:
    (tmp_path / "lone.node").write_text(GOOD_NODE)
    with pytest.raises(MeshFormatError, match=r"its pair .*lone\.ele does not exist"):
        load_volume_mesh(tmp_path / "lone.node")
    (tmp_path / "lone.ele").write_text(GOOD_ELE)
    with pytest.raises(MeshTooLargeError, match="holds 4 points; at most 3"):
        load_volume_mesh(tmp_path / "lone.node", max_vertices=3)


def test_a_volume_file_that_is_a_fifo_or_a_folder_is_refused_before_it_is_opened(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.msh"
    os.mkfifo(fifo)
    with pytest.raises(MeshFormatError, match="named pipe"):
        load_volume_mesh(fifo)  # would block forever if it were opened
    (tmp_path / "folder.node").mkdir()
    (tmp_path / "folder.ele").write_text(GOOD_ELE)
    with pytest.raises(MeshFormatError, match="folder"):
        load_volume_mesh(tmp_path / "folder.ele")


# ---------------------------------------------------------------------------------------------- meshio formats
def test_gmsh_boundary_triangles_are_left_aside_and_other_cells_refused(tmp_path: Path) -> None:
    meshio = pytest.importorskip("meshio")
    V, T = box_tetrahedra(1, 2, 1)
    F = boundary_faces(T)
    meshio.write(tmp_path / "with_faces.msh", meshio.Mesh(V, [("triangle", F), ("tetra", T), ("line", F[:, :2])]),
                 file_format="gmsh22", binary=False)
    W, S = load_volume_mesh(tmp_path / "with_faces.msh")
    np.testing.assert_array_equal(W, V)
    np.testing.assert_array_equal(S, T)
    hexahedron = np.arange(8)[None, [0, 1, 3, 2, 4, 5, 7, 6]]
    meshio.write(tmp_path / "hex.vtu", meshio.Mesh(box_tetrahedra(1, 1, 1)[0], [("hexahedron", hexahedron)]))
    with pytest.raises(MeshFormatError, match=r"holds hexahedron cells; ARAP takes linear tetrahedra"):
        load_volume_mesh(tmp_path / "hex.vtu")
    (tmp_path / "junk.msh").write_text("$MeshFormat\nnot a mesh\n")
    with pytest.raises(MeshFormatError, match=r"cannot parse .*junk\.msh as a gmsh file"):
        load_volume_mesh(tmp_path / "junk.msh")


def test_a_planar_gmsh_mesh_is_read_as_stored(tmp_path: Path) -> None:
    meshio = pytest.importorskip("meshio")
    V = np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]])
    meshio.write(tmp_path / "tri.msh", meshio.Mesh(V, [("triangle", np.array([[0, 1, 2]]))]), file_format="gmsh",
                 binary=False)
    W, F = load_volume_mesh(tmp_path / "tri.msh")
    np.testing.assert_array_equal(W, V)
    assert F.tolist() == [[0, 1, 2]]


# ---------------------------------------------------------------------------------------------- writing errors
def test_nothing_is_written_for_unusable_arrays_or_destinations(tmp_path: Path) -> None:
    V, T = box_tetrahedra(1, 1, 1)
    bad = V.copy()
    bad[3, 1] = np.nan
    with pytest.raises(MeshError, match="NaN"):
        save_volume_mesh(tmp_path / "bad.node", bad, T)
    with pytest.raises(MeshError, match="out of range"):
        save_volume_mesh(tmp_path / "bad.vtu", V, T + 100)
    with pytest.raises(MeshError, match="tetrahedra need 3-d vertices"):
        save_volume_mesh(tmp_path / "bad.mesh", V[:, :2], T)
    with pytest.raises(MeshFormatError, match="unsupported volume mesh format 'obj'"):
        save_volume_mesh(tmp_path / "bad.obj", V, T)
    (tmp_path / "pair.ele").mkdir()  # the .ele destination is a folder: the .node file is not written either
    with pytest.raises(MeshFormatError, match=r"cannot write .*pair\.ele"):
        save_volume_mesh(tmp_path / "pair.node", V, T)
    with pytest.raises(MeshFormatError, match="does not exist"):
        save_volume_mesh(tmp_path / "missing" / "x.node", V, T)
    assert sorted(os.listdir(tmp_path)) == ["pair.ele"]


def test_a_failed_write_leaves_the_earlier_file(tmp_path: Path) -> None:
    V, T = box_tetrahedra(1, 1, 1)
    save_volume_mesh(tmp_path / "keep.node", V, T)
    before = (tmp_path / "keep.node").read_bytes()
    with pytest.raises(MeshError):
        save_volume_mesh(tmp_path / "keep.node", np.full_like(V, np.inf), T)
    assert (tmp_path / "keep.node").read_bytes() == before


# ---------------------------------------------------------------------------------------------- boundary
def _outward(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Whether each triangle's normal points away from the centroid of ``V`` (a convex body)."""
    P = V[F]
    normal = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    return np.einsum("ij,ij->i", normal, P.mean(axis=1) - V.mean(axis=0)) > 0


def test_the_boundary_of_a_cube_of_six_tetrahedra_is_twelve_outward_triangles() -> None:
    V, T = box_tetrahedra(1, 1, 1)
    assert len(T) == 6 and (signed_measures(V, T) > 0).all()
    F = boundary_faces(T)
    assert F.shape == (12, 3)
    assert _outward(V, F).all()
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    assert area.sum() == pytest.approx(6.0)
    # A closed surface: every edge in two triangles, once each way.
    half = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    assert len({tuple(e) for e in half.tolist()}) == 36
    assert {tuple(e) for e in half.tolist()} == {tuple(e) for e in half[:, ::-1].tolist()}
    # Tetrahedra the other way round: with the positions, the faces still point outward.
    inverted = T[:, [0, 2, 1, 3]]
    assert _outward(V, boundary_faces(inverted, V)).all()
    assert not _outward(V, boundary_faces(inverted)).any()


def test_the_boundary_surface_leaves_interior_vertices_out() -> None:
    V, T = box_tetrahedra(3, 3, 3)
    surface, F, kept = boundary_surface(V, T)
    interior = np.all((V > 0) & (V < 3), axis=1)
    assert kept.tolist() == np.flatnonzero(~interior).tolist()
    np.testing.assert_array_equal(surface, V[kept])
    assert len(F) == 6 * 9 * 2 and _outward(surface, F).all()
    arap.check_mesh(surface, F)


# ---------------------------------------------------------------------------------------------- tetrahedralize
@pytest.fixture(scope="module")
def sphere_solid(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    _needs_pytetwild()
    import trimesh

    m = trimesh.creation.icosphere(1)
    V, F = np.asarray(m.vertices), np.asarray(m.faces, dtype=np.int64)
    here, folder = os.getcwd(), tmp_path_factory.mktemp("cwd")
    os.chdir(folder)
    try:
        V_tet, T = arap.tetrahedralize(V, F, edge_length=0.2)
    finally:
        os.chdir(here)
    assert os.listdir(folder) == []  # fTetWild's own file stays in its temporary folder
    return V, F, V_tet, T


def test_a_tetrahedralized_closed_surface_has_no_inverted_element(
        sphere_solid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> None:
    _, _, V_tet, T = sphere_solid
    assert T.dtype == np.int64 and T.shape[1] == 4 and len(T) > 50
    assert (signed_measures(V_tet, T) > 0).all()
    assert np.array_equal(np.unique(T), np.arange(len(V_tet)))
    # The solid fills the sphere: its boundary lies near the unit sphere, its volume near 4π/3 (the icosphere's).
    surface = boundary_surface(V_tet, T)[0]
    assert np.abs(np.linalg.norm(surface, axis=1) - 1.0).max() < 0.1
    assert np.abs(signed_measures(V_tet, T)).sum() / 6 == pytest.approx(4 * np.pi / 3, rel=0.15)
    arap.ArapSolver(V_tet, T, [0])  # the solver takes it


def test_the_surface_embedded_in_its_solid_is_reproduced_exactly_at_rest(
        sphere_solid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> None:
    V, _, V_tet, T = sphere_solid
    tets, bary = arap.embed_points(V_tet, T, V)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0, atol=1e-12)
    assert bary.min() > -0.2  # each vertex in, or just outside, the tetrahedron it follows
    diag = np.linalg.norm(np.ptp(V, axis=0))
    assert np.abs(arap.interpolate_points(V_tet, T, tets, bary) - V).max() <= 1e-9 * diag
    # A rigid motion of the solid moves the surface rigidly.
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    moved = arap.interpolate_points(V_tet @ R.T + 3.0, T, tets, bary)
    np.testing.assert_allclose(moved, V @ R.T + 3.0, atol=1e-9 * diag)


def test_embedding_points_inside_gives_containing_tetrahedra() -> None:
    V, T = box_tetrahedra(2, 2, 2)
    P = np.random.default_rng(3).uniform(0.01, 1.99, size=(200, 3))
    tets, bary = arap.embed_points(V, T, P)
    assert bary.min() >= -1e-12
    np.testing.assert_allclose(arap.interpolate_points(V, T, tets, bary), P, atol=1e-12)


def test_tetrahedralize_refuses_an_open_surface() -> None:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(MeshError, match="closed surface; this one has 3 boundary edges"):
        arap.tetrahedralize(V, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2]]))


# ---------------------------------------------------------------------------------------------- command line
def test_deform_a_tetrahedral_bar_by_position(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("meshio")
    V, T = box_tetrahedra(2, 10, 2, size=(1.0, 5.0, 1.0))
    save_volume_mesh(tmp_path / "bar.msh", V, T)
    out = tmp_path / "out.vtu"
    code = main(["deform", str(tmp_path / "bar.msh"), "--fix", "y<0.05", "--handle", "y>0.95", "--rotate", "x:90",
                 "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    assert "240 tetrahedra" in capsys.readouterr().err
    U, S = load_volume_mesh(out)
    np.testing.assert_array_equal(S, T)
    bottom, top = V[:, 1] < 0.25, V[:, 1] > 4.75
    np.testing.assert_allclose(U[bottom], V[bottom], atol=1e-9)
    # The top end turned a quarter turn about x (about its centroid): its y extent became a z extent.
    assert np.ptp(U[top, 2]) == pytest.approx(0.0, abs=1e-9) and np.ptp(U[top, 1]) == pytest.approx(1.0, abs=1e-9)
    assert (signed_measures(U, T) > 0).all()  # no element inverted
    # Written as a surface: the boundary, outward, of the deformed solid.
    code = main(["deform", str(tmp_path / "bar.msh"), "--fix", "y<0.05", "--handle", "y>0.95", "--move", "1,0,0",
                 "-o", str(tmp_path / "out.obj"), "-q"])
    assert code == 0
    surface, F = arap.load_mesh(tmp_path / "out.obj")
    assert len(surface) == len(boundary_surface(V, T)[0]) and len(F) == len(boundary_faces(T))


def test_deform_a_planar_tetgen_mesh_in_its_plane(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y = np.meshgrid(np.linspace(0, 4, 9), np.linspace(0, 1, 3), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel()])
    idx = np.arange(len(V)).reshape(9, 3)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    save_volume_mesh(tmp_path / "strip.node", V, F)
    code = main(["deform", str(tmp_path / "strip.ele"), "--fix", "x<0.1", "--handle", "x>0.9", "--move", "0,1,0",
                 "-o", str(tmp_path / "bent.node")])
    assert code == 0, capsys.readouterr().err
    U, G = load_volume_mesh(tmp_path / "bent.ele")
    assert U.shape == V.shape and np.array_equal(G, F)
    np.testing.assert_allclose(U[V[:, 0] == 4], V[V[:, 0] == 4] + [0, 1], atol=1e-9)
    assert (signed_measures(np.column_stack([U, np.zeros(len(U))]), G) > 0).all()


def test_deform_solid_fills_a_closed_surface_and_writes_it_deformed(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    _needs_pytetwild()
    import trimesh

    m = trimesh.creation.icosphere(1)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    arap.save_mesh(tmp_path / "sphere.obj", V, F)
    code = main(["deform", "--solid", str(tmp_path / "sphere.obj"), "--edge-length", "0.2", "--fix", "y<0.2",
                 "--handle", "y>0.8", "--move", "0.5,0,0", "-o", str(tmp_path / "out.obj")])
    assert code == 0, capsys.readouterr().err
    assert "tetrahedra" in capsys.readouterr().err
    U, G = arap.load_mesh(tmp_path / "out.obj", repair=False)
    assert U.shape == V.shape and np.array_equal(G, F)
    low, high = V[:, 1] < -0.85, V[:, 1] > 0.85
    assert np.abs(U[low] - V[low]).max() < 0.05  # near the fixed tetrahedra
    assert (U[high, 0] - V[high, 0]).mean() == pytest.approx(0.5, abs=0.05)  # near the moved ones
    # -c with --solid: a constraints file cannot name the solid's vertices.
    assert main(["deform", "--solid", str(tmp_path / "sphere.obj"), "-c", "x.json", "-o", str(tmp_path / "o.obj")]) == 1
    assert "by position" in capsys.readouterr().err


def test_a_bad_volume_file_is_one_line_and_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "bad.node").write_text(GOOD_NODE)
    (tmp_path / "bad.ele").write_text("1 4 0\n1 1 2 3 9\n")
    out = tmp_path / "out.vtu"
    code = main(["deform", str(tmp_path / "bad.ele"), "--fix", "x<0.1", "--handle", "x>0.9", "--move", "1,0,0",
                 "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("\n") == 1 and err.startswith("arap: error:") and "names point 9" in err
    assert not out.exists()
    assert main(["info", str(tmp_path / "bad.node")]) == 1
    assert capsys.readouterr().err.count("\n") == 1


def test_info_on_a_volume_file_prints_counts_and_volumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, T = box_tetrahedra(2, 2, 2)
    save_volume_mesh(tmp_path / "box.ele", V, T)
    assert main(["info", str(tmp_path / "box.ele")]) == 0
    text = capsys.readouterr().out
    assert "27 vertices" in text and "48 tetrahedra, 48 boundary faces" in text
    assert "min 0.166667, max 0.166667" in text and "ready for ARAP: yes (a solid" in text
    assert main(["info", "--json", str(tmp_path / "box.node")]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["n_tetrahedra"] == 48 and report["n_boundary_faces"] == 48 and report["kind"] == "solid"
    assert report["min_volume"] == pytest.approx(1 / 6) and report["total_volume"] == pytest.approx(8.0)


def test_deform_a_solid_with_a_constraints_file_and_refuse_surface_energies(tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    V, T = box_tetrahedra(1, 4, 1)
    save_volume_mesh(tmp_path / "bar.node", V, T)
    fixed, handles = np.flatnonzero(V[:, 1] == 0), np.flatnonzero(V[:, 1] == 4)
    (tmp_path / "c.json").write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(),
                                                 "targets": (V[handles] + [0.5, 0, 0]).tolist()}))
    code = main(["deform", str(tmp_path / "bar.ele"), "-c", str(tmp_path / "c.json"), "-o", str(tmp_path / "o.node"),
                 "-q"])
    assert code == 0, capsys.readouterr().err
    U, S = load_volume_mesh(tmp_path / "o.node")
    assert np.array_equal(S, T)
    np.testing.assert_allclose(U[handles], V[handles] + [0.5, 0, 0], atol=1e-9)
    np.testing.assert_allclose(U[fixed], V[fixed], atol=1e-9)
    code = main(["deform", str(tmp_path / "bar.ele"), "-c", str(tmp_path / "c.json"), "--energy", "spokes", "-o",
                 str(tmp_path / "spokes.node")])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "tetrahedra take energy='elements'" in err
    assert not (tmp_path / "spokes.node").exists()


def test_load_mesh_points_volume_files_to_load_volume_mesh(tmp_path: Path) -> None:
    with pytest.raises(MeshFormatError, match=r"a volume mesh: arap\.load_volume_mesh reads it"):
        arap.load_mesh(tmp_path / "bar.msh")


def test_missing_optional_packages_are_named_with_the_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import arap.io.volume as volume
    import arap.meshes.tetrahedralize as tetrahedralize

    real_import, real_find = importlib.import_module, importlib.util.find_spec

    def no_meshio(name: str, package: str | None = None) -> object:
        if name == "meshio":
            raise ImportError("No module named 'meshio'", name="meshio")
        return real_import(name, package)

    def no_pytetwild(name: str, package: str | None = None) -> object:
        return None if name == "pytetwild" else real_find(name, package)

    monkeypatch.setattr(volume.importlib, "import_module", no_meshio)
    V, T = box_tetrahedra(1, 1, 1)
    with pytest.raises(MeshFormatError, match=r"through meshio, which is not installed: pip install 'arap\[solid\]'"):
        save_volume_mesh(tmp_path / "box.vtu", V, T)
    assert os.listdir(tmp_path) == []
    monkeypatch.setattr(tetrahedralize.importlib.util, "find_spec", no_pytetwild)
    surface, F, _ = boundary_surface(V, T)
    with pytest.raises(arap.ArapError, match=r"pytetwild: pip install 'arap\[solid\]'"):
        arap.tetrahedralize(surface, F)


# ---------------------------------------------------------------------------------------------- other commands
def _tet_bar(tmp_path: Path, name: str = "bar.node") -> tuple[np.ndarray, np.ndarray, Path]:
    V, T = box_tetrahedra(1, 4, 1)
    save_volume_mesh(tmp_path / name, V, T)
    return V, T, tmp_path / name


def test_constraints_picks_the_vertices_of_a_volume_file_by_position(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    V, _, path = _tet_bar(tmp_path)
    out = tmp_path / "c.json"
    code = main(["constraints", str(path), "--fix", "y<0.1", "--handle", "y>0.9", "--move", "0.5,0,0", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    assert f"{len(V):,} vertices" in capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert sorted(doc["fixed"]) == np.flatnonzero(V[:, 1] == 0).tolist()
    assert sorted(doc["handles"]) == np.flatnonzero(V[:, 1] == 4).tolist()
    # The file drives arap deform on the same volume file.
    assert main(["deform", str(path), "-c", str(out), "-o", str(tmp_path / "o.ele"), "-q"]) == 0
    U, _ = load_volume_mesh(tmp_path / "o.ele")
    top = V[:, 1] == 4
    np.testing.assert_allclose(U[top], V[top] + [0.5, 0, 0], atol=1e-9)


def _keys(tmp_path: Path, V: np.ndarray) -> Path:
    fixed, top = np.flatnonzero(V[:, 1] == 0), np.flatnonzero(V[:, 1] == 4)
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "targets": V[top].tolist()},
                         {"time": 0.5, "targets": (V[top] + [0.6, 0, 0]).tolist()}]}
    (tmp_path / "keys.json").write_text(json.dumps(doc))
    return tmp_path / "keys.json"


def test_animate_a_solid_from_a_volume_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, T, path = _tet_bar(tmp_path)
    keys = _keys(tmp_path, V)
    top = V[:, 1] == 4
    # Numbered volume files: the tetrahedra, solved with the element energy.
    code = main(["animate", str(path), "-k", str(keys), "--fps", "4", "-o", str(tmp_path / "f_#.ele")])
    assert code == 0, capsys.readouterr().err
    frames = sorted(tmp_path.glob("f_*.ele"))
    assert [p.name for p in frames] == ["f_0.ele", "f_1.ele", "f_2.ele"]
    U, S = load_volume_mesh(frames[-1])
    assert np.array_equal(S, T)
    np.testing.assert_allclose(U[top], V[top] + [0.6, 0, 0], atol=1e-6)
    assert (signed_measures(U, T) > 0).all()
    # Numbered surface files and an animated GLB: the boundary surface of the solid, as arap deform writes it.
    assert main(["animate", str(path), "-k", str(keys), "--fps", "4", "-o", str(tmp_path / "s_#.obj"), "-q"]) == 0
    surface, F = arap.load_mesh(tmp_path / "s_2.obj")
    rest, faces, kept = boundary_surface(V, T)
    assert len(surface) == len(rest) and np.array_equal(F, faces)
    np.testing.assert_allclose(surface, U[kept], atol=1e-6)
    assert main(["animate", str(path), "-k", str(keys), "--fps", "4", "-o", str(tmp_path / "a.glb"), "-q"]) == 0
    assert (tmp_path / "a.glb").stat().st_size > 0


def test_batch_deforms_volume_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, T, _ = _tet_bar(tmp_path, "bar.node")
    top, fixed = np.flatnonzero(V[:, 1] == 4), np.flatnonzero(V[:, 1] == 0)
    (tmp_path / "c.json").write_text(json.dumps({"fixed": fixed.tolist(), "handles": top.tolist(),
                                                 "targets": (V[top] + [0.5, 0, 0]).tolist()}))
    lines = [{"mesh": "bar.node", "constraints": "c.json", "output": "out/bar.ele"},
             {"mesh": "bar.ele", "constraints": "c.json", "output": "out/bar.obj"}]
    (tmp_path / "jobs.jsonl").write_text("\n".join(json.dumps(line) for line in lines) + "\n")
    code = main(["batch", str(tmp_path / "jobs.jsonl"), "--workers", "1", "-q"])
    assert code == 0, capsys.readouterr().err
    U, S = load_volume_mesh(tmp_path / "out" / "bar.ele")
    assert np.array_equal(S, T)
    np.testing.assert_allclose(U[top], V[top] + [0.5, 0, 0], atol=1e-6)
    surface, F = arap.load_mesh(tmp_path / "out" / "bar.obj")
    _, faces, kept = boundary_surface(V, T)
    assert np.array_equal(F, faces)
    np.testing.assert_allclose(surface, U[kept], atol=1e-6)


def test_animate_a_planar_tetgen_mesh_keeps_its_two_columns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y = np.meshgrid(np.linspace(0, 4, 9), np.linspace(0, 1, 3), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel()])
    idx = np.arange(len(V)).reshape(9, 3)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    save_volume_mesh(tmp_path / "strip.node", V, F)
    fixed, end = np.flatnonzero(V[:, 0] == 0), np.flatnonzero(V[:, 0] == 4)
    P = np.column_stack([V, np.zeros(len(V))])
    (tmp_path / "keys.json").write_text(json.dumps({
        "fixed": fixed.tolist(), "handles": end.tolist(),
        "keyframes": [{"time": 0.0, "targets": P[end].tolist()},
                      {"time": 0.5, "targets": (P[end] + [0, 1, 0]).tolist()}]}))
    code = main(["animate", str(tmp_path / "strip.ele"), "-k", str(tmp_path / "keys.json"), "--fps", "2", "-o",
                 str(tmp_path / "bent_#.node"), "-q"])
    assert code == 0, capsys.readouterr().err
    U, G = load_volume_mesh(tmp_path / "bent_1.ele")
    assert U.shape == V.shape and np.array_equal(G, F)
    np.testing.assert_allclose(U[end], V[end] + [0, 1], atol=1e-6)
    assert (signed_measures(np.column_stack([U, np.zeros(len(U))]), G) > 0).all()  # bent in its plane, not folded
