"""The measuring helpers of benchmarks/bench_slow_modes.py: the Hessian assembled by probing, the coarse spaces and
the conjugate gradients the ceiling counts with."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest
import scipy.sparse as sp
from benchmarks.scenarios import make_scenario

from arap import ArapSolver
from arap.meshes.shapes import builtin_mesh
from tests.tool_modules import load_benchmark


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return load_benchmark("bench_slow_modes")


@pytest.fixture(scope="module")
def bent(bench: ModuleType) -> object:
    """The cactus bent and converged (its clamped weights leave edges out of the global-step matrix)."""
    V, F = builtin_mesh("cactus")
    s = make_scenario("bend", V)
    solver = ArapSolver(V, F, s.constrained)
    solver.solve(s.targets, initial="rest", tolerance=1e-12)
    return bench.Linearised(solver, s.targets)


def test_assembled_hessian_is_the_gradients_derivative(bench: ModuleType, bent: object) -> None:
    H = bench.assemble_hessian(bent)
    r = np.random.default_rng(0).standard_normal((bent.p.nf, 3))
    h = 1e-6 * bent.p.diagonal
    exact = ((bent.gradient(bent.x + h * r) - bent.gradient(bent.x - h * r)) / (2 * h)).ravel()
    assert np.linalg.norm(H @ r.ravel() - exact) <= 1e-6 * np.linalg.norm(exact)
    assert sp.linalg.norm(H - H.T) <= 1e-8 * sp.linalg.norm(H)


def test_coarse_spaces_hold_what_they_promise(bench: ModuleType, bent: object) -> None:
    X = bent.U[:bent.p.nf]
    n = len(X)
    G = bench.edge_graph(bent.p, X)
    seeds, label = bench.surface_clusters(G, 40)
    assert len(seeds) == 40 and set(np.unique(label)) == set(range(40))
    assert np.array_equal(label[seeds], np.arange(40))  # each seed lies in its own cluster
    rng = np.random.default_rng(1)
    M, t, w = rng.standard_normal((3, 3)), rng.standard_normal(3), rng.standard_normal(3)
    affine = X @ M.T + t
    rigid = np.cross(w, X) + t
    near, dist = bench.surface_neighbours(X, G, seeds, label)
    P1 = bench.scalar_weights(X, X[seeds], near, dist)
    assert np.allclose(P1 @ (X[seeds] @ M.T + t), affine)  # affine fields interpolated exactly
    for P, field in [(bench.affine_columns(P1, X, X[seeds]), affine), (bench.rigid_columns(label, X, 40), rigid),
                     (bench.affine_columns(sp.csr_matrix((np.ones(n), (np.arange(n), label))), X, X[seeds]),
                      affine)]:
        y = sp.linalg.lsqr(P, field.ravel(), atol=1e-14, btol=1e-14)[0]
        assert np.linalg.norm(P @ y - field.ravel()) <= 1e-6 * np.linalg.norm(field)


def test_conjugate_gradients_count_until_the_error_is_reduced(bench: ModuleType) -> None:
    H = sp.diags(np.linspace(1.0, 100.0, 50)).tocsr()
    e = np.ones(50)
    assert bench.pcg_iterations(H, lambda r: r / H.diagonal(), e) == 1
    plain = bench.pcg_iterations(H, lambda r: r, e)
    assert 5 < plain <= 50


def test_coarse_matrices_of_dependent_columns_are_solved(bench: ModuleType) -> None:
    rng = np.random.default_rng(2)
    P = sp.csr_matrix(rng.standard_normal((40, 6)))
    P = sp.hstack([P, P[:, :2]]).tocsr()  # two columns twice: P^T P singular
    M = (P.T @ P).tocsr()
    g = M @ rng.standard_normal(8)
    y = bench.semidefinite_solver(M)(g)
    assert np.linalg.norm(M @ y - g) <= 1e-6 * np.linalg.norm(g)
    assert bench.semidefinite_solver(M)(np.column_stack([g, 2 * g])).shape == (8, 2)
