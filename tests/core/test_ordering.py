"""The fill-reducing ordering computed beside the set-up: the same permutation, factor and solutions as CHOLMOD's
own nested dissection, a fallback where METIS is missing, and the solver's use of it."""

from __future__ import annotations

import ctypes
import importlib.util

import numpy as np
import pytest
import scipy.sparse as sp

import arap.sparse.ordering as ordering
from arap.meshes.shapes import sphere, sphere_frequency_for
from arap.meshes.topology import vertex_adjacency
from arap.solve.solver import ArapSolver
from arap.sparse._csr_permute import permuted_pattern, permuted_symmetric, with_diagonal
from arap.sparse.linsolve import background_ordering, factorize
from arap.sparse.ordering import (
    BackgroundOrdering,
    leading_subgraph,
    metis_available,
    nested_dissection,
    permute_rows,
    unpermute_rows,
)

HAVE_SKSPARSE = importlib.util.find_spec("sksparse") is not None
needs_cholmod = pytest.mark.skipif(not (HAVE_SKSPARSE and metis_available()),
                                   reason="scikit-sparse or the METIS library is not installed")


def _caps(V: np.ndarray, share: float = 0.05) -> np.ndarray:
    y = V[:, 1]
    return np.flatnonzero((y <= np.quantile(y, share)) | (y >= np.quantile(y, 1.0 - share)))


@pytest.fixture(scope="module")
def solver() -> ArapSolver:
    V, F = sphere(frequency=sphere_frequency_for(20_000))
    return ArapSolver(V, F, _caps(V), backend="scipy")


def _graph(A: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    G = A.tolil()
    G.setdiag(0)
    G = G.tocsr()
    G.eliminate_zeros()
    G.sort_indices()
    return G.indptr, G.indices


def test_leading_subgraph_is_the_pattern_of_the_reduced_matrix(solver: ArapSolver) -> None:
    adjacency = vertex_adjacency(solver.F, solver.n_vertices)
    indptr, indices = leading_subgraph(adjacency, solver.prepared.numbering.perm, solver.n_free)
    A = solver.reduced_matrix()
    ref_ptr, ref_idx = _graph(A)
    np.testing.assert_array_equal(indptr, ref_ptr)
    np.testing.assert_array_equal(indices, ref_idx)
    pattern_ptr, pattern_idx = with_diagonal(indptr, indices)
    np.testing.assert_array_equal(pattern_ptr, A.indptr)
    np.testing.assert_array_equal(pattern_idx, A.indices)


def test_permuted_symmetric_takes_the_upper_triangle() -> None:
    # Symmetric pattern, values that differ in the last bits between the triangles.
    A = sp.csr_matrix(np.array([[4.0, -1.0, 0.0, -2.0], [-1.0 - 1e-16 * 4, 5.0, -1.5, 0.0],
                                [0.0, -1.5, 3.0, -0.5], [-2.0 + 4e-16, 0.0, -0.5, 6.0]]))
    perm = np.array([2, 0, 3, 1])
    C = permuted_symmetric(A, perm)
    upper = np.triu(A.toarray())
    symmetric = upper + np.triu(upper, 1).T
    np.testing.assert_array_equal(C.toarray(), symmetric[perm][:, perm])
    assert C.has_sorted_indices
    ptr, idx, source = permuted_pattern(A.indptr, A.indices, perm)
    np.testing.assert_array_equal(ptr, C.indptr)
    np.testing.assert_array_equal(idx, C.indices)
    np.testing.assert_array_equal(A.data[source], C.data)


def test_row_permutations_round_trip() -> None:
    rng = np.random.default_rng(0)
    perm = rng.permutation(7)
    B = rng.normal(size=(7, 3))
    P = permute_rows(B, perm)
    assert P.flags.f_contiguous
    np.testing.assert_array_equal(P, B[perm])
    np.testing.assert_array_equal(unpermute_rows(P, perm, 2), B)
    np.testing.assert_array_equal(permute_rows(B[:, 0], perm), B[perm, 0])
    np.testing.assert_array_equal(unpermute_rows(B[perm, 0], perm, 1), B[:, 0])


@needs_cholmod
def test_nested_dissection_is_cholmods_own_ordering(solver: ArapSolver) -> None:
    from sksparse.cholmod import analyze

    A = solver.reduced_matrix()
    perm = nested_dissection(*_graph(A))
    assert np.array_equal(np.sort(perm), np.arange(A.shape[0]))
    own = analyze(A.tocsc(), mode="supernodal", ordering_method="metis").P()
    np.testing.assert_array_equal(perm, own)


@needs_cholmod
@pytest.mark.parametrize("given", ["array", "background"])
def test_a_given_ordering_solves_as_cholmods_own(solver: ArapSolver, given: str) -> None:
    from arap.sparse.linsolve import _plan_symbolic

    A = solver.reduced_matrix()
    B = np.random.default_rng(1).normal(size=(A.shape[0], 3))
    own = factorize(A, "sksparse")
    assert "ordering" not in own.timings
    indptr, indices = _graph(A)
    permutation: np.ndarray | BackgroundOrdering = (
        nested_dissection(indptr, indices) if given == "array" else BackgroundOrdering(indptr, indices, _plan_symbolic))
    factor = factorize(A, "sksparse", permutation=permutation)
    assert {"ordering", "analyse", "factor", "convert"} <= set(factor.timings)
    np.testing.assert_array_equal(factor.permutation, own.permutation)
    reference = own.solve(B)
    X = factor.solve(B)
    assert np.abs(X - reference).max() <= 1e-10 * np.abs(reference).max()
    np.testing.assert_array_equal(X, reference)  # the same factor, bit for bit
    np.testing.assert_array_equal(factor.solve(B[:, 1]), reference[:, 1])
    if isinstance(permutation, BackgroundOrdering):
        assert permutation.seconds > 0 and permutation.prepared is not None
        assert factor.timings["ordering_thread"] == permutation.seconds


@needs_cholmod
def test_a_matrix_off_the_analysed_pattern_is_analysed_again(solver: ArapSolver) -> None:
    from arap.sparse.linsolve import _plan_symbolic

    A = solver.reduced_matrix()
    ordering_thread = BackgroundOrdering(*_graph(A), _plan_symbolic)
    # Couple two vertices that are not neighbours, weakly: still positive definite, one more pair of entries.
    i, j = 0, A.shape[0] - 1
    assert A[i, j] == 0
    coupling = sp.csr_matrix(([1e-3, 1e-3], ([i, j], [j, i])), shape=A.shape)
    A2 = (A + coupling).tocsr()
    A2.sort_indices()
    factor = factorize(A2, "sksparse", permutation=ordering_thread)
    assert not ordering_thread.prepared.fits(A2)
    B = np.random.default_rng(2).normal(size=(A.shape[0], 3))
    X = factor.solve(B)
    assert np.linalg.norm(A2 @ X - B) / np.linalg.norm(B) < 1e-12


@needs_cholmod
def test_solver_orders_beside_the_set_up_and_agrees_with_cholmod() -> None:
    V, F = sphere(4)
    constrained = _caps(V, 0.1)
    targets = V[constrained] + np.where(V[constrained, 1:2] > 0, 0.2, 0.0)
    fast = ArapSolver(V, F, constrained, backend="sksparse")
    assert "ordering_thread" in fast.factor.timings
    reference = ArapSolver(V, F, constrained, backend="scipy")
    a = fast.solve(targets, max_iterations=5).vertices
    b = reference.solve(targets, max_iterations=5).vertices
    assert np.abs(a - b).max() < 1e-10


def test_without_metis_the_factorisation_orders_by_itself(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ordering, "_metis", lambda: None)
    assert not metis_available()
    V, F = sphere(3)
    constrained = _caps(V, 0.1)
    adjacency = vertex_adjacency(F, len(V))
    assert background_ordering(adjacency, np.arange(len(V)), len(V) - len(constrained), "sksparse") is None
    with pytest.raises(RuntimeError, match="METIS"):
        nested_dissection(np.array([0, 1, 2]), np.array([1, 0]))
    if HAVE_SKSPARSE:
        solver = ArapSolver(V, F, constrained, backend="sksparse")
        assert "ordering" not in solver.factor.timings
        rest = solver.solve(V[constrained], max_iterations=2)
        np.testing.assert_allclose(rest.vertices, V, atol=1e-12)


def test_no_ordering_thread_for_the_other_backends() -> None:
    V, F = sphere(2)
    adjacency = vertex_adjacency(F, len(V))
    for backend in ("cholespy", "scipy"):
        assert background_ordering(adjacency, np.arange(len(V)), 10, backend) is None
    assert background_ordering(adjacency, np.arange(len(V)), 0, "sksparse") is None


def test_graphs_without_edges_and_errors_reach_the_caller(monkeypatch: pytest.MonkeyPatch) -> None:
    if metis_available():
        np.testing.assert_array_equal(nested_dissection(np.zeros(4, dtype=np.int64), np.zeros(0, dtype=np.int64)),
                                      np.arange(3))

    def failing(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
        raise RuntimeError("METIS_NodeND failed (status -2)")

    monkeypatch.setattr(ordering, "nested_dissection", failing)
    background = BackgroundOrdering(np.array([0, 1, 2]), np.array([1, 0]))
    with pytest.raises(RuntimeError, match="status -2"):
        background.result()


@needs_cholmod
def test_fewer_refinement_passes_still_give_a_comparable_ordering(solver: ArapSolver) -> None:
    from sksparse.cholmod import analyze

    A = solver.reduced_matrix()
    fills = {}
    for passes in (None, 1):
        perm = nested_dissection(*_graph(A), refinement_passes=passes)
        assert np.array_equal(np.sort(perm), np.arange(A.shape[0]))
        C = permuted_symmetric(A, perm)
        f = analyze(C, mode="simplicial", ordering_method="natural")
        f.cholesky_inplace(C)
        fills[passes] = f.L().nnz
    assert fills[1] < 1.1 * fills[None]


needs_second_metis = pytest.mark.skipif(not (HAVE_SKSPARSE and ordering._second_metis() is not None),
                                        reason="scikit-sparse is not installed or METIS cannot be loaded twice")


def _factor_nonzeros(A: sp.csr_matrix, perm: np.ndarray) -> int:
    from sksparse.cholmod import analyze

    C = permuted_symmetric(A, perm)
    f = analyze(C, mode="simplicial", ordering_method="natural")
    f.cholesky_inplace(C)
    return int(f.L().nnz)


@needs_second_metis
def test_halves_ordered_at_once_are_reproducible_and_fill_no_more(solver: ArapSolver) -> None:
    A = solver.reduced_matrix()
    graph = _graph(A)
    whole = nested_dissection(*graph, halves=False)
    split = nested_dissection(*graph, halves=True)
    assert np.array_equal(np.sort(split), np.arange(A.shape[0]))
    assert not np.array_equal(split, whole)  # the halves were ordered apart
    for _ in range(3):  # the two copies of METIS draw from their own generators: no dependence on timing
        np.testing.assert_array_equal(nested_dissection(*graph, halves=True), split)
    assert _factor_nonzeros(A, split) < 1.05 * _factor_nonzeros(A, whole)
    B = np.random.default_rng(3).normal(size=(A.shape[0], 3))
    X = factorize(A, "sksparse", permutation=split).solve(B)
    assert np.linalg.norm(A @ X - B) / np.linalg.norm(B) < 1e-12


def _raw_handlers() -> list[tuple[bytes, bytes, int]]:
    # GNU C's struct sigaction: the handler, the signal mask (of which the kernel keeps the first 64 bits; the C
    # library leaves the rest undefined), the flags (less SA_RESTORER, which it adds to every handler it installs).
    return [(buffer.raw[:8], buffer.raw[8:16], int.from_bytes(buffer.raw[136:140], "little") & ~0x04000000)
            for _, buffer in ordering._signal_handlers()]


@needs_second_metis
def test_halves_leave_the_c_signal_handlers_as_they_were(solver: ArapSolver) -> None:
    import signal

    previous = signal.signal(signal.SIGTERM, lambda *args: None)
    try:
        before = _raw_handlers()
        assert len(before) == 2
        for _ in range(3):
            nested_dissection(*_graph(solver.reduced_matrix()), halves=True)
            assert _raw_handlers() == before
        # The restore itself: a handler changed behind Python's back is put back.
        saved = ordering._signal_handlers()
        ordering._libc().signal(signal.SIGTERM, ctypes.c_void_p(1))  # SIG_IGN
        assert _raw_handlers() != before
        ordering._restore_signal_handlers(saved)
        assert _raw_handlers() == before
    finally:
        signal.signal(signal.SIGTERM, previous)


@needs_second_metis
def test_an_error_in_either_half_reaches_the_caller(monkeypatch: pytest.MonkeyPatch, solver: ArapSolver) -> None:
    def failing(*args: object) -> int:
        return -4

    monkeypatch.setattr(ordering, "_second_metis", lambda: failing)
    before = _raw_handlers()
    with pytest.raises(RuntimeError, match="status -4"):
        nested_dissection(*_graph(solver.reduced_matrix()), halves=True)
    assert _raw_handlers() == before


@needs_cholmod
def test_without_a_second_metis_the_whole_graph_is_ordered_in_one_call(monkeypatch: pytest.MonkeyPatch,
                                                                        solver: ArapSolver) -> None:
    graph = _graph(solver.reduced_matrix())
    whole = nested_dissection(*graph, halves=False)
    monkeypatch.setattr(ordering, "_second_metis", lambda: None)
    np.testing.assert_array_equal(nested_dissection(*graph, halves=True), whole)
    monkeypatch.undo()
    monkeypatch.setattr(ordering, "_glibc_has_private_namespaces", lambda: False)
    ordering._second_metis.cache_clear()
    try:
        assert ordering._second_metis() is None
    finally:
        ordering._second_metis.cache_clear()


@needs_second_metis
def test_the_solver_over_halves_agrees_with_scipy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ordering, "SPLIT_VERTICES", 100)
    monkeypatch.setattr(ordering, "_cpus", lambda: 2)
    V, F = sphere(4)
    constrained = _caps(V, 0.1)
    targets = V[constrained] + np.where(V[constrained, 1:2] > 0, 0.2, 0.0)
    fast = ArapSolver(V, F, constrained, backend="sksparse")
    graph = leading_subgraph(vertex_adjacency(F, len(V)), fast.prepared.numbering.perm, fast.n_free)
    assert not np.array_equal(fast.factor.permutation, nested_dissection(*graph, halves=False))
    reference = ArapSolver(V, F, constrained, backend="scipy")
    a = fast.solve(targets, max_iterations=5).vertices
    b = reference.solve(targets, max_iterations=5).vertices
    assert np.abs(a - b).max() < 1e-10
