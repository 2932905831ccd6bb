"""The compiled set-up (cells, system matrix, right-hand-side gather, blocks, geometry, components) against plain
NumPy/SciPy constructions of the same objects: equal bit for bit on manifold meshes with boundaries and obtuse
triangles, equal to rounding where terms are summed in another order (edges of more than two faces)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from arap.meshes._geometry import barycentric_areas, double_areas
from arap.meshes.shapes import sphere
from arap.meshes.topology import free_components, vertex_adjacency
from arap.method.cells import Cells, build_cells, build_rhs_gather, system_matrix
from arap.method.weights import corner_weights
from arap.sparse._csr import SparseRowsProduct, csr_from_triplets, leading_blocks

Mesh = tuple[np.ndarray, np.ndarray]


def _reference_rim_cells(V: np.ndarray, F: np.ndarray, weights: str) -> tuple[np.ndarray, ...]:
    """Spokes-and-rims terms by a lexicographic sort of all (cell, a, b) triples and a bincount merge."""
    n = len(V)
    cw = corner_weights(V, F, weights)
    ea = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    eb = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    ew = np.concatenate([cw[:, 0], cw[:, 1], cw[:, 2]])
    ex = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    cell = np.concatenate([ea, eb, ex])
    a = np.concatenate([ea, eb, np.minimum(ea, eb)])
    b = np.concatenate([eb, ea, np.maximum(ea, eb)])
    w = np.concatenate([ew, ew, ew])
    order = np.lexsort((b, a, cell))
    cell, a, b, w = cell[order], a[order], b[order], w[order]
    first = np.ones(len(cell), dtype=bool)
    first[1:] = (cell[1:] != cell[:-1]) | (a[1:] != a[:-1]) | (b[1:] != b[:-1])
    w = np.bincount(np.cumsum(first) - 1, weights=w)
    cell, a, b = cell[first], a[first], b[first]
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell, minlength=n), out=ptr[1:])
    e = V[a] - V[b]
    rest_sq = np.bincount(cell, weights=w * np.einsum("ij,ij->i", e, e), minlength=n)
    return ptr, a, b, w, w[:, None] * e, rest_sq


def _reference_matrix(cells: Cells, n: int, scipy: bool = False) -> sp.csr_matrix:
    """The triplets (a, b, −w), (b, a, −w), (i, i, Σ w) assembled by ``csr_from_triplets`` (or by SciPy)."""
    a, b, w = cells.a, cells.b, cells.w
    diagonal = np.bincount(a, weights=w, minlength=n) + np.bincount(b, weights=w, minlength=n)
    used = np.flatnonzero(np.bincount(a, minlength=n) + np.bincount(b, minlength=n))
    rows, cols = np.concatenate([a, b, used]), np.concatenate([b, a, used])
    vals = np.concatenate([-w, -w, diagonal[used]])
    if scipy:
        return sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
    return csr_from_triplets(rows, cols, vals, n)


def _reference_gather(cells: Cells, rows: np.ndarray, n: int) -> dict[tuple[int, int], np.ndarray]:
    """{(row, cell): Σ ±we} over the terms of each cell touching each row."""
    row_of = np.full(n, -1)
    row_of[rows] = np.arange(len(rows))
    out: dict[tuple[int, int], np.ndarray] = {}
    cell_of = cells.cell_of_term()
    for k in range(len(cells.a)):
        for end, sign in ((cells.a[k], 1.0), (cells.b[k], -1.0)):
            r = row_of[end]
            if r >= 0:
                key = (int(r), int(cell_of[k]))
                out[key] = out.get(key, np.zeros(3)) + sign * cells.we[k]
    return out


def _open_grid(k: int = 12) -> Mesh:
    """A bumpy open grid: boundary edges and vertices, obtuse and acute triangles."""
    x, y = np.meshgrid(np.linspace(0, 1, k), np.linspace(0, 1.7, k))
    rng = np.random.default_rng(3)
    V = np.stack([x.ravel() + 0.02 * rng.normal(size=k * k), y.ravel(), 0.1 * np.sin(5 * x.ravel())], axis=1)
    i = np.arange(k - 1)
    q = (i[:, None] * k + i[None, :]).ravel()
    F = np.concatenate([np.stack([q, q + 1, q + k + 1], 1), np.stack([q, q + k + 1, q + k], 1)])
    return V, F.astype(np.int64)


def _fan_with_a_fin() -> Mesh:
    """Non-manifold: an edge shared by three triangles, and one face listed twice."""
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0.2], [0.5, 0.1, 1], [1.5, 1, 0.3]], dtype=float)
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 5, 2], [1, 5, 2]], dtype=np.int64)
    return V, F


@pytest.fixture(params=["icosphere", "open_grid", "camelhead", "knight"])
def manifold(request: pytest.FixtureRequest) -> Mesh:
    if request.param == "open_grid":
        return _open_grid()
    return request.getfixturevalue(request.param)


@pytest.mark.parametrize("weights", ["cotangent", "clamped", "uniform"])
def test_rim_cells_equal_the_sorted_construction_bit_for_bit(manifold: Mesh, weights: str) -> None:
    V, F = manifold
    cells = build_cells(V, F, "spokes_and_rims", weights)
    ptr, a, b, w, we, rest_sq = _reference_rim_cells(V, F, weights)
    for got, want in ((cells.ptr, ptr), (cells.a, a), (cells.b, b), (cells.w, w), (cells.we, we),
                      (cells.rest_sq, rest_sq)):
        np.testing.assert_array_equal(got, want)
    assert cells.a.dtype == cells.b.dtype == np.int32


def test_rim_cells_of_non_manifold_edges_equal_to_rounding() -> None:
    # to rounding: the compiled kernels may fuse a multiply and an add where NumPy rounds twice (CPUs with FMA)
    V, F = _fan_with_a_fin()
    cells = build_cells(V, F)
    ptr, a, b, w, we, rest_sq = _reference_rim_cells(V, F, "cotangent")
    np.testing.assert_array_equal(cells.ptr, ptr)
    np.testing.assert_array_equal(cells.a, a)
    np.testing.assert_array_equal(cells.b, b)
    np.testing.assert_allclose(cells.w, w, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(cells.we, we, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(cells.rest_sq, rest_sq, rtol=1e-13, atol=1e-15)
    cw = corner_weights(V, F, "cotangent")

    def weight(cell: int, a: int, b: int) -> float:
        terms = np.arange(cells.ptr[cell], cells.ptr[cell + 1])
        (k,) = terms[(cells.a[terms] == a) & (cells.b[terms] == b)]
        return float(cells.w[k])

    # edge (0, 1) lies in three faces: one spoke of cell 0 sums the three corner weights opposite it
    assert weight(0, 0, 1) == pytest.approx(cw[0, 2] + cw[1, 2] + cw[2, 2], rel=1e-13)
    # the face listed twice gives its rim (2, 5) twice to the cell of its corner 1: summed
    assert weight(1, 2, 5) == pytest.approx(2 * cw[3, 0], rel=1e-13)


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_system_matrix_equals_the_triplet_construction(manifold: Mesh, energy: str) -> None:
    V, F = manifold
    n = len(V) + 2  # two vertices no face uses: no diagonal entry
    cells = build_cells(np.vstack([V, np.zeros((2, 3))]), F, energy)
    L = system_matrix(cells, n)
    ref = _reference_matrix(cells, n)
    np.testing.assert_array_equal(L.indptr, ref.indptr)
    np.testing.assert_array_equal(L.indices, ref.indices)
    np.testing.assert_array_equal(L.data, ref.data)
    by_scipy = _reference_matrix(cells, n, scipy=True)
    by_scipy.sort_indices()
    np.testing.assert_array_equal(L.indices, by_scipy.indices)
    np.testing.assert_allclose(L.data, by_scipy.data, rtol=1e-14, atol=1e-14 * abs(L.data).max())
    assert L[n - 1].nnz == 0
    assert abs(L.sum(axis=1)).max() < 1e-12 * abs(L.data).max()


def test_rhs_gather_sums_every_cell_once_per_row(icosphere: Mesh) -> None:
    V, F = icosphere
    n = len(V)
    cells = build_cells(V, F)
    rows = np.flatnonzero(np.arange(n) % 3 != 0)  # some vertices are not rows
    gather = build_rhs_gather(cells, rows, n)
    expected = _reference_gather(cells, rows, n)
    got: dict[tuple[int, int], np.ndarray] = {}
    for r in range(len(rows)):
        cells_of_row = gather.cell[gather.ptr[r]:gather.ptr[r + 1]]
        assert (np.diff(cells_of_row) > 0).all()  # increasing, no repeats
        for p in range(gather.ptr[r], gather.ptr[r + 1]):
            got[(r, int(gather.cell[p]))] = gather.g[p]
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        np.testing.assert_allclose(got[key], value, rtol=1e-14, atol=1e-15)


def test_csr_from_triplets_sums_duplicates_like_scipy() -> None:
    rng = np.random.default_rng(0)
    n = 50
    rows, cols = rng.integers(0, n, 2000), rng.integers(0, n, 2000)
    vals = rng.normal(size=2000)
    M = csr_from_triplets(rows, cols, vals, n)
    ref = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
    ref.sum_duplicates()
    assert M.has_sorted_indices and (np.diff(M.indices[M.indptr[3]:M.indptr[4]]) > 0).all()
    np.testing.assert_array_equal(M.indptr, ref.indptr)
    np.testing.assert_array_equal(M.indices, ref.indices)
    np.testing.assert_allclose(M.data, ref.data, rtol=1e-14, atol=1e-14)


def test_leading_blocks_equal_scipy_slicing(camelhead: Mesh) -> None:
    V, F = camelhead
    L = system_matrix(build_cells(V, F), len(V))
    k = len(V) * 2 // 3
    left, right = leading_blocks(L, k)
    for got, want in ((left, L[:k][:, :k]), (right, L[:k][:, k:])):
        assert got.shape == want.shape
        assert (got != want).nnz == 0
        assert got.has_sorted_indices
    assert left.nnz + right.nnz == L[:k].nnz  # explicit zeros kept



def test_sparse_rows_product_equals_scipy_bit_for_bit_on_every_call(camelhead: Mesh) -> None:
    """The coupling to the fixed vertices: the same values as SciPy's product, and rows without entries stay zero
    from call to call in the kept buffer."""
    V, F = camelhead
    L = system_matrix(build_cells(V, F), len(V))
    k = len(V) - 40
    _, right = leading_blocks(L, k)
    product = SparseRowsProduct(right)
    assert 0 < len(product.rows) < k
    rng = np.random.default_rng(3)
    for _ in range(3):
        X = rng.normal(size=(len(V) - k, 3))
        np.testing.assert_array_equal(product(X), right @ X)
    with pytest.raises(ValueError, match="shape"):
        product(np.zeros((len(V) - k, 2)))

def test_geometry_kernels_equal_the_numpy_expressions(knight: Mesh) -> None:
    V, F = knight
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    twice = np.sqrt(cross[:, 0] ** 2 + cross[:, 1] ** 2 + cross[:, 2] ** 2)
    np.testing.assert_array_equal(double_areas(V, F), twice)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    expected = np.bincount(F.ravel(), weights=np.repeat(area / 3.0, 3), minlength=len(V))
    np.testing.assert_array_equal(barycentric_areas(V, F), expected)


def test_free_components_match_scipy_and_find_the_pinned_ones() -> None:
    V, F = sphere(3)
    n = len(V)
    # Cut the sphere by a band of non-free vertices: two caps, one of them with a fixed vertex inside.
    y = V[:, 1]
    band = np.abs(y) < 0.15
    fixed_in_cap = int(np.argmax(y))
    free = np.flatnonzero(~band & (np.arange(n) != fixed_in_cap))
    A = vertex_adjacency(F, n)
    count, labels, pinned = free_components(A, free)
    ref_count, ref_labels = connected_components(A[free][:, free], directed=False)
    assert count == ref_count == 2
    np.testing.assert_array_equal(labels, ref_labels)
    assert pinned.all()  # both caps touch the band
    # Without the band, only the fixed vertex pins the (single) component.
    everything_else = np.flatnonzero(np.arange(n) != fixed_in_cap)
    count, labels, pinned = free_components(A, everything_else)
    assert count == 1 and pinned.tolist() == [True]
    count, labels, pinned = free_components(A, np.arange(n))
    assert count == 1 and pinned.tolist() == [False]


def test_solver_set_up_equals_the_reference_constructions(armadillo: Mesh) -> None:
    """The solver's cells and factored matrix, as built before the compiled set-up (trimesh's armadillo)."""
    from arap.solve.solver import ArapSolver

    V, F = armadillo
    y = V[:, 1]
    constrained = np.flatnonzero((y < np.quantile(y, 0.1)) | (y > np.quantile(y, 0.9)))
    solver = ArapSolver(V, F, constrained, backend="scipy")
    Fi = solver.prepared.numbering.inv[F]
    ptr, a, b, w, _, _ = _reference_rim_cells(solver.prepared.rest, Fi, "cotangent")
    np.testing.assert_array_equal(solver.prepared.cells.a, a)
    np.testing.assert_array_equal(solver.prepared.cells.ptr, ptr)
    np.testing.assert_array_equal(solver.prepared.cells.b, b)
    np.testing.assert_array_equal(solver.prepared.cells.w, w)
    L = _reference_matrix(solver.prepared.cells, len(V))
    reduced = L[solver.prepared.numbering.free][:, solver.prepared.numbering.free]
    assert (solver.reduced_matrix() != reduced).nnz == 0
