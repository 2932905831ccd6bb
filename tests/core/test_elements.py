"""The element energy (one rotation per triangle or tetrahedron) and planar meshes: identities, an independent
per-element reference, libigl's elements solver, and every bad input."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.errors import ConstraintError, MeshError, OptionError
from arap.meshes.domain import check_domain, signed_measures
from arap.method.elements import element_weights

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _rotation_2d(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


@pytest.fixture(scope="module")
def strip() -> tuple[np.ndarray, np.ndarray]:
    """A 2:1 planar strip with a hole, (n, 2)."""
    return arap.rectangle_triangles(24, 12, hole=(1.0, 0.5, 0.25))


@pytest.fixture(scope="module")
def bar() -> tuple[np.ndarray, np.ndarray]:
    """A 10×2×2 box of cubes, six tetrahedra each."""
    return arap.box_tetrahedra(10, 2, 2)


def _ends(V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = V[:, 0]
    return np.flatnonzero(x <= x.min() + 1e-9), np.flatnonzero(x >= x.max() - 1e-9)


def _turned_strip(V: np.ndarray, angle: float = np.pi / 2) -> tuple[np.ndarray, np.ndarray]:
    left, right = _ends(V)
    c = V[right].mean(axis=0)
    return np.concatenate([left, right]), np.concatenate([V[left], (V[right] - c) @ _rotation_2d(angle).T + c])


def _twisted_bar(V: np.ndarray, angle: float = 2 * np.pi / 3) -> tuple[np.ndarray, np.ndarray]:
    left, right = _ends(V)
    c = V[right].mean(axis=0)
    return np.concatenate([left, right]), np.concatenate([V[left], (V[right] - c) @ _rotation_x(angle).T + c])


def _reference_energies(V: np.ndarray, T: np.ndarray, U: np.ndarray) -> np.ndarray:
    """``|τ| ‖J − R‖²_F`` per element with J from the element's edge matrices and R from an SVD with the reflection
    fixed: a per-element computation that shares no code with the solver."""
    d = T.shape[1] - 1
    P = V[:, :d] if V.shape[1] >= d else V
    E = np.stack([P[T[:, i]] - P[T[:, 0]] for i in range(1, d + 1)], axis=2)  # columns: rest edges
    Q = U[:, :d]
    D = np.stack([Q[T[:, i]] - Q[T[:, 0]] for i in range(1, d + 1)], axis=2)
    J = D @ np.linalg.inv(E)
    W, _, Zt = np.linalg.svd(J)
    fix = np.ones((len(T), d))
    fix[:, -1] = np.sign(np.linalg.det(W @ Zt))
    R = (W * fix[:, None, :]) @ Zt
    measure = np.abs(np.linalg.det(E)) / (2.0 if d == 2 else 6.0)
    return measure * ((J - R) ** 2).sum(axis=(1, 2))


# ---------------------------------------------------------------------------------------------- identities
def test_planar_input_gives_planar_output_and_the_elements_energy(strip: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = strip
    b, targets = _turned_strip(V)
    solver = arap.ArapSolver(V, F, b)
    assert solver.energy_type == "elements"
    result = solver.solve(targets)
    assert result.converged
    assert result.vertices.shape == V.shape
    np.testing.assert_allclose(result.vertices[b], targets, atol=1e-12)
    energies = np.asarray(result.energies)
    # never rising, but for the one step where a solve that converged with triangles it turned over opens them
    # (arap.method.unfold; whether it turns any over depends on round-off), after which it ends lower
    rises = np.flatnonzero(np.diff(energies) > 1e-12 * abs(energies[0]))
    assert len(rises) <= 1
    assert len(rises) == 0 or energies[-1] < energies[rises[0]]
    assert arap.arap_energy(V, F, result.vertices) == pytest.approx(energies[-1], rel=1e-9)
    # a gentler turn folds no triangle over
    b, targets = _turned_strip(V, np.pi / 4)
    lifted = np.column_stack([solver.solve(targets).vertices, np.zeros(len(V))])
    assert np.all(signed_measures(lifted, F) > 0)


@pytest.mark.parametrize("kind", ["planar", "solid"])
def test_rigid_motions_cost_nothing_and_are_recovered(kind: str, strip: tuple[np.ndarray, np.ndarray],
                                                      bar: tuple[np.ndarray, np.ndarray]) -> None:
    V, T = strip if kind == "planar" else bar
    R = _rotation_2d(2.5) if kind == "planar" else _rotation_x(2.5) @ np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    Q = V @ R.T + (3.0 if kind == "planar" else np.array([1.0, -2.0, 0.5]))
    scale = np.ptp(V, axis=0).max()
    assert abs(arap.arap_energy(V, T, Q)) <= 1e-12 * scale ** 2 * len(T)
    assert np.abs(arap.cell_energies(V, T, Q)).max() <= 1e-12 * scale ** 2
    b = np.concatenate(_ends(V))
    result = arap.ArapSolver(V, T, b).solve(Q[b])
    assert np.abs(result.vertices - Q).max() <= 1e-9 * scale


@pytest.mark.parametrize("kind", ["planar", "solid"])
def test_element_energies_match_an_independent_per_element_svd(kind: str, strip: tuple[np.ndarray, np.ndarray],
                                                               bar: tuple[np.ndarray, np.ndarray]) -> None:
    V, T = strip if kind == "planar" else bar
    rng = np.random.default_rng(7)
    U = V + 0.05 * rng.standard_normal(V.shape)
    U[:, 0] *= 1.3
    ours = arap.cell_energies(V, T, U)
    assert ours.shape == (len(T),)
    np.testing.assert_allclose(ours, _reference_energies(V, T, U), rtol=1e-8, atol=1e-14)


def test_cotangent_weights_are_those_of_libigl(bar: tuple[np.ndarray, np.ndarray],
                                               strip: tuple[np.ndarray, np.ndarray]) -> None:
    igl = pytest.importorskip("igl")
    V, T = bar
    # libigl: edges [1,2],[2,0],[0,1],[3,0],[3,1],[3,2] with l·cot θ / 6 (its cotmatrix_entries' convention)
    C = np.asarray(igl.cotmatrix_entries(V, T))
    ours = element_weights(V, T)  # edges 01, 02, 03, 12, 13, 23
    np.testing.assert_allclose(ours[:, [3, 1, 0, 2, 4, 5]], C, rtol=1e-10, atol=1e-14)
    V2, F2 = strip
    lifted = np.column_stack([V2, np.zeros(len(V2))])
    np.testing.assert_allclose(element_weights(lifted, F2), np.asarray(igl.cotmatrix_entries(V2, F2)),
                               rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("kind", ["planar", "solid"])
def test_the_minimum_is_libigls_from_the_same_start(kind: str, strip: tuple[np.ndarray, np.ndarray],
                                                     bar: tuple[np.ndarray, np.ndarray]) -> None:
    igl = pytest.importorskip("igl")
    V, T = strip if kind == "planar" else bar
    b, targets = _turned_strip(V) if kind == "planar" else _twisted_bar(V, np.pi / 3)
    ours = arap.ArapSolver(V, T, b).solve(targets, initial="rest", tolerance=1e-12).vertices
    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS
    data.max_iter = 3000
    igl.arap_precomputation(V, T, V.shape[1], b.astype(np.int64), data)
    start = V.copy()
    start[b] = targets
    theirs = np.asarray(igl.arap_solve(targets, data, start))
    e_ours, e_theirs = arap.arap_energy(V, T, ours), arap.arap_energy(V, T, theirs)
    assert e_ours <= e_theirs * (1 + 1e-7)
    assert np.abs(ours - theirs).max() <= 1e-4 * np.linalg.norm(np.ptp(V, axis=0))


def test_a_flat_mesh_in_space_deforms_in_its_plane_with_elements(strip: tuple[np.ndarray, np.ndarray]) -> None:
    V2, F = strip
    V = np.column_stack([V2[:, 0], np.full(len(V2), 4.0), V2[:, 1]])  # the plane y = 4
    b, targets2 = _turned_strip(V2)
    targets = np.column_stack([targets2[:, 0], np.full(len(b), 4.0), targets2[:, 1]])
    solver = arap.ArapSolver(V, F, b, energy="elements")
    result = solver.solve(targets)
    assert result.vertices.shape == V.shape
    assert np.all(result.vertices[:, 1] == 4.0)
    planar = arap.ArapSolver(V2, F, b).solve(targets2).vertices
    np.testing.assert_allclose(result.vertices[:, [0, 2]], planar, atol=1e-7)
    off = targets.copy()
    off[0, 1] += 0.5
    with pytest.raises(ConstraintError, match="leave the plane y = 4"):
        solver.solve(off)
    # the default energy keeps treating a flat (n, 3) mesh as a surface in space
    assert arap.ArapSolver(V, F, b).energy_type == "spokes_and_rims"


def test_planar_rotations_turn_about_the_normal(strip: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = strip
    b, targets = _turned_strip(V)
    solver = arap.ArapSolver(V, F, b)
    U = solver.solve(targets).vertices
    R = solver.fit_rotations(U)
    assert R.shape == (len(F), 3, 3)
    np.testing.assert_allclose(R[:, 2, 2], 1.0)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    # a mirrored pose cannot be reached by rotations in the plane: its energy stays high
    mirrored = V * [-1.0, 1.0]
    assert arap.arap_energy(V, F, mirrored) > 0.1 * np.ptp(V[:, 0]) ** 2


def test_the_planar_spoke_energies_also_turn_in_the_plane(strip: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = strip
    b, targets = _turned_strip(V)
    result = arap.ArapSolver(V, F, b, energy="spokes_and_rims").solve(targets)
    assert result.converged and result.vertices.shape == V.shape


# ---------------------------------------------------------------------------------------------- add-ons
def test_a_rigid_part_of_a_solid_moves_as_one_body(bar: tuple[np.ndarray, np.ndarray]) -> None:
    V, T = bar
    b, targets = _twisted_bar(V)
    stiffness = np.ones(len(V))
    middle = np.abs(V[:, 0] - 5.0) <= 1.0
    stiffness[middle] = np.inf
    U = arap.ArapSolver(V, T, b, stiffness=stiffness).solve(targets).vertices
    P, Q = V[middle], U[middle]
    d_rest = np.linalg.norm(P[:, None] - P[None], axis=2)
    d_now = np.linalg.norm(Q[:, None] - Q[None], axis=2)
    assert np.abs(d_now - d_rest).max() <= 1e-6
    plain = arap.ArapSolver(V, T, b).solve(targets).vertices[middle]
    assert np.abs(np.linalg.norm(plain[:, None] - plain[None], axis=2) - d_rest).max() > 1e-3


def test_point_handles_inside_tetrahedra_land_on_their_targets(bar: tuple[np.ndarray, np.ndarray]) -> None:
    V, T = bar
    left, _ = _ends(V)
    far = int(np.argmax(V[T].mean(axis=1)[:, 0]))
    beta = np.array([[0.1, 0.2, 0.3, 0.4]])
    target = (beta @ V[T[far]]) + [0.0, 2.0, 0.0]
    solver = arap.ArapSolver(V, T, left, points=([far], beta))
    U = solver.solve(V[left], point_targets=target).vertices
    np.testing.assert_allclose(beta @ U[T[far]], target, atol=1e-9)
    with pytest.raises(ConstraintError, match="quadruples"):
        arap.ArapSolver(V, T, left, points=([far], [[0.5, 0.5, 0.0]]))


def test_only_the_region_of_interest_moves(bar: tuple[np.ndarray, np.ndarray]) -> None:
    V, T = bar
    b, targets = _twisted_bar(V, np.pi / 4)
    roi = np.flatnonzero(V[:, 0] >= 4.0)
    U = arap.ArapSolver(V, T, b[np.isin(b, roi)], roi=roi).solve(targets[np.isin(b, roi)]).vertices
    outside = np.setdiff1d(np.arange(len(V)), roi)
    np.testing.assert_array_equal(U[outside], V[outside])


def test_mesh_objects_from_meshio(bar: tuple[np.ndarray, np.ndarray]) -> None:
    meshio = pytest.importorskip("meshio")
    V, T = bar
    mesh = meshio.Mesh(V, [("triangle", np.array([[0, 1, 2]])), ("tetra", T)])  # boundary faces beside (gmsh)
    b = np.concatenate(_ends(V))
    assert arap.ArapSolver(mesh, b).energy_type == "elements"
    with pytest.raises(MeshError, match="mixes element types"):
        check_domain(meshio.Mesh(V, [("tetra", T), ("hexahedron", np.arange(8)[None])]))


# ---------------------------------------------------------------------------------------------- bad input
def test_each_bad_element_mesh_gets_its_own_error(bar: tuple[np.ndarray, np.ndarray],
                                                  strip: tuple[np.ndarray, np.ndarray]) -> None:
    V, T = bar
    b = np.concatenate(_ends(V))
    inverted = T.copy()
    inverted[5] = inverted[5][[1, 0, 2, 3]]
    with pytest.raises(MeshError, match=r"1 tetrahedra are inverted .*first: 5"):
        arap.ArapSolver(V, inverted, b)
    flat = V.copy()
    flat[T[3, 3]] = flat[T[3, 0]] + 0.5 * (flat[T[3, 1]] - flat[T[3, 0]]) + 0.5 * (flat[T[3, 2]] - flat[T[3, 0]])
    with pytest.raises(MeshError, match="zero volume"):
        check_domain(flat, T[3:4])
    with pytest.raises(MeshError, match="repeat a vertex"):
        check_domain(V, np.array([[0, 1, 1, 2]]))
    with pytest.raises(MeshError, match="out of range"):
        check_domain(V, np.array([[0, 1, 2, len(V)]]))
    with pytest.raises(MeshError, match="need 3-d vertices"):
        check_domain(V[:, :2], T)
    with pytest.raises(MeshError, match=r"\(m, 3\) or tetrahedra \(m, 4\)"):
        check_domain(V, np.zeros((2, 5), dtype=int))
    with pytest.raises(OptionError, match="tetrahedra take energy='elements'"):
        arap.ArapSolver(V, T, b, energy="spokes_and_rims")
    V2, F2 = strip
    folded = F2.copy()
    folded[0] = folded[0][[1, 0, 2]]
    with pytest.raises(MeshError, match="folded over"):
        arap.ArapSolver(V2, folded, [0])
    with pytest.raises(OptionError, match="planar mesh takes"):
        arap.ArapSolver(V2, F2, [0], energy="smooth_rotations")
    b2, targets2 = _turned_strip(V2)
    solver = arap.ArapSolver(V2, F2, b2)
    with pytest.raises(ConstraintError, match=rf"shape \({len(b2)}, 2\)"):
        solver.solve(np.column_stack([targets2, np.zeros(len(b2))]))


def test_surfaces_keep_their_default_energy_and_results() -> None:
    V, F = arap.builtin_mesh("bar")
    y = V[:, 1]
    b = np.flatnonzero((y == y.min()) | (y == y.max()))
    targets = V[b] + np.where(y[b, None] == y.max(), [1.0, 0.0, 0.0], 0.0)
    solver = arap.ArapSolver(V, F, b)
    assert solver.energy_type == "spokes_and_rims"
    default = solver.solve(targets, max_iterations=30).vertices
    explicit = arap.ArapSolver(V, F, b, energy="spokes_and_rims").solve(targets, max_iterations=30).vertices
    np.testing.assert_array_equal(default, explicit)
    # element cells on a surface in space: 3×3 rotations per triangle, one cell per triangle
    elements = arap.ArapSolver(V, F, b, energy="elements")
    assert elements.prepared.cells.n_cells == len(F)
    assert elements.solve(targets).converged
