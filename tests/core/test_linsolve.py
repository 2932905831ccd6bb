"""Sparse Cholesky backends: the same solution from each, valid factors for each ordering, clear failures."""

from __future__ import annotations

import importlib.util
import logging
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from arap.errors import OptionError
from arap.meshes.grids import box_tetrahedra
from arap.meshes.shapes import sphere, sphere_frequency_for
from arap.solve.solver import ArapSolver
from arap.sparse.linsolve import (
    BACKEND_ENV,
    BACKENDS,
    LARGE_SOLID_SYSTEM,
    LARGE_SYSTEM,
    ORDERINGS,
    NotPositiveDefiniteError,
    available_backends,
    default_backend,
    factorize,
)

HAVE_SKSPARSE = importlib.util.find_spec("sksparse") is not None


def _caps(V: np.ndarray, share: float = 0.05) -> np.ndarray:
    y = V[:, 1]
    return np.flatnonzero((y <= np.quantile(y, share)) | (y >= np.quantile(y, 1.0 - share)))


@pytest.fixture(scope="module")
def reduced() -> sp.csr_matrix:
    """Reduced global-step matrix of a 20k-vertex sphere with both caps fixed (large enough for supernodes)."""
    V, F = sphere(frequency=sphere_frequency_for(20_000))
    return ArapSolver(V, F, _caps(V), backend="scipy").reduced_matrix()


@pytest.fixture(scope="module")
def rhs(reduced: sp.csr_matrix) -> np.ndarray:
    return np.random.default_rng(1).normal(size=(reduced.shape[0], 3))


def _relative_residual(A: sp.spmatrix, X: np.ndarray, B: np.ndarray) -> float:
    return float(np.linalg.norm(A @ X - B) / np.linalg.norm(B))


def test_fallback_chain_order() -> None:
    found = available_backends()
    assert found[-1] == "scipy"
    assert found == [name for name in BACKENDS if name in found]
    assert ("sksparse" in found) == HAVE_SKSPARSE


@pytest.mark.parametrize("backend", BACKENDS)
def test_backends_give_the_same_solution(backend: str, reduced: sp.csr_matrix, rhs: np.ndarray) -> None:
    if backend not in available_backends():
        pytest.skip(f"{backend} is not installed")
    reference = spla.spsolve(reduced.tocsc(), rhs)
    factor = factorize(reduced, backend)
    assert factor.backend == backend
    assert "factor" in factor.timings
    X = factor.solve(rhs)
    assert X.shape == rhs.shape
    assert np.abs(X - reference).max() <= 1e-10 * np.abs(reference).max()
    # A second solve with the same factor (the solver reuses it every iteration) gives the same answer.
    np.testing.assert_array_equal(factor.solve(rhs), X)


@pytest.mark.skipif(not HAVE_SKSPARSE, reason="scikit-sparse is not installed")
@pytest.mark.parametrize("ordering", ORDERINGS)
def test_each_ordering_gives_a_valid_factor(ordering: str, reduced: sp.csr_matrix, rhs: np.ndarray) -> None:
    factor = factorize(reduced, "sksparse", ordering=ordering)
    assert set(factor.timings) == {"analyse", "factor", "convert"}
    assert _relative_residual(reduced, factor.solve(rhs), rhs) < 1e-12
    # One right-hand side column and a C-ordered block give the same as the Fortran-ordered block.
    X1 = factor.solve(np.ascontiguousarray(rhs[:, :1]))
    assert np.abs(X1[:, 0] - factor.solve(rhs)[:, 0]).max() < 1e-13 * np.abs(X1).max()


@pytest.mark.skipif(not HAVE_SKSPARSE, reason="scikit-sparse is not installed")
def test_nested_dissection_fills_less_than_minimum_degree(reduced: sp.csr_matrix) -> None:
    """The default ordering is chosen for its fill on meshes; CHOLMOD reports the factor's size."""
    from sksparse.cholmod import analyze

    C = reduced.tocsc()
    nnz = {}
    for ordering in ("metis", "amd"):
        f = analyze(C, mode="simplicial", ordering_method=ordering)
        f.cholesky_inplace(C)
        nnz[ordering] = f.L().nnz
    assert nnz["metis"] < nnz["amd"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_and_indefinite_matrices_are_rejected(backend: str) -> None:
    if backend not in available_backends():
        pytest.skip(f"{backend} is not installed")
    V, F = sphere(2)
    L = ArapSolver(V, F, [0], backend="scipy").reduced_matrix()
    n = L.shape[0]
    # Shifted down by more than its smallest eigenvalue: indefinite.
    smallest = spla.eigsh(L.tocsc(), k=1, sigma=0, which="LM", return_eigenvectors=False)[0]
    indefinite = (L - 2 * smallest * sp.identity(n)).tocsr()
    with pytest.raises(NotPositiveDefiniteError):
        factorize(indefinite, backend)
    # A free vertex tied to the rest only by zero weights: an exactly zero row and column.
    keep = np.ones(n)
    keep[n // 2] = 0.0
    singular = (sp.diags(keep) @ L @ sp.diags(keep)).tocsr()
    with pytest.raises(NotPositiveDefiniteError):
        factorize(singular, backend)


def test_unknown_names_are_rejected(reduced: sp.csr_matrix) -> None:
    with pytest.raises(ValueError, match="backend"):
        factorize(reduced, "pardiso")
    with pytest.raises(ValueError, match="ordering"):
        factorize(reduced, "scipy", ordering="rcm")


def test_default_backend_follows_the_system_size(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(BACKEND_ENV, raising=False)
    found = available_backends()
    small = default_backend(1_000)
    assert small == ("cholespy" if "cholespy" in found else found[0])
    large = default_backend(LARGE_SYSTEM)
    assert large == ("sksparse" if HAVE_SKSPARSE else small)


def test_a_solid_takes_the_large_backend_from_fewer_unknowns(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(BACKEND_ENV, raising=False)
    assert LARGE_SOLID_SYSTEM < LARGE_SYSTEM
    small = default_backend(LARGE_SOLID_SYSTEM - 1, solid=True)
    assert small == default_backend(LARGE_SOLID_SYSTEM - 1)
    assert default_backend(LARGE_SOLID_SYSTEM, solid=True) == ("sksparse" if HAVE_SKSPARSE else small)
    assert default_backend(LARGE_SOLID_SYSTEM) == small  # a surface of as many unknowns keeps the small one
    V, T = box_tetrahedra(28, 20, 20)  # 12,789 vertices, 11,760 unknowns with both ends held
    x = V[:, 0]
    ends = np.flatnonzero((x <= x.min() + 1e-9) | (x >= x.max() - 1e-9))
    solver = ArapSolver(V, T, ends)
    assert solver.system_size >= LARGE_SOLID_SYSTEM
    assert solver.backend == default_backend(solver.system_size, solid=True)


@pytest.mark.parametrize("name", available_backends())
def test_the_environment_names_the_default_backend_for_every_size(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(BACKEND_ENV, name)
    assert default_backend(1_000) == default_backend(LARGE_SYSTEM) == name
    V, F = sphere(2)
    assert ArapSolver(V, F, _caps(V)).backend == name
    assert ArapSolver(V, F, _caps(V), backend="scipy").backend == "scipy"  # a backend named in the call wins


def test_an_unknown_backend_in_the_environment_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(BACKEND_ENV, "pardiso")
    with pytest.raises(OptionError, match=BACKEND_ENV):
        default_backend(1_000)
    monkeypatch.setenv(BACKEND_ENV, "")
    assert default_backend(1_000) in BACKENDS


def test_solver_uses_the_default_backend_and_agrees_with_the_fallback() -> None:
    V, F = sphere(3)
    constrained = _caps(V, 0.1)
    targets = V[constrained] + np.where(V[constrained, 1:2] > 0, 0.2, 0.0)
    fast = ArapSolver(V, F, constrained)
    assert fast.backend == default_backend(fast.system_size)
    a = fast.solve(targets, max_iterations=3).vertices
    b = ArapSolver(V, F, constrained, backend="scipy").solve(targets, max_iterations=3).vertices
    assert np.abs(a - b).max() < 1e-10


@pytest.mark.parametrize("backend", available_backends())
def test_an_indefinite_matrix_is_refused_without_a_word_on_stdout(
        backend: str, capfd: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture) -> None:
    """CHOLMOD inside cholespy prints its warning with the C library's printf: it must reach the log, not the
    standard output that a command's JSON goes to."""
    A = sp.csr_matrix(sp.diags([2.0, -1.0, 3.0, 1.0]))
    with caplog.at_level(logging.DEBUG, logger="arap.sparse.linsolve"), pytest.raises(NotPositiveDefiniteError):
        factorize(A, backend)
    out, _ = capfd.readouterr()
    assert out == ""
    if backend == "cholespy":
        assert any("CHOLMOD" in r.getMessage() for r in caplog.records)


def test_other_output_meanwhile_still_reaches_stdout() -> None:
    """In a process of its own (pytest's capture bypasses file descriptor 1 for Python's prints)."""
    code = ("import os\n"
            "from arap._cstdout import c_stdout_to_log\n"
            "print('before')\n"
            "with c_stdout_to_log():\n"
            "    os.write(1, b'CHOLMOD warning: not positive definite\\n')\n"
            "    os.write(1, b'another thread said this\\n')\n"
            "    print('a buffered line')\n"
            "print('after')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    lines = out.splitlines()
    assert lines[0] == "before" and lines[-1] == "after"
    assert sorted(lines[1:-1]) == ["a buffered line", "another thread said this"]
