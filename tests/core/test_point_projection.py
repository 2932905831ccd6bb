"""The hard point handles' correction of the global step: the constrained minimiser of the step's quadratic for
surfaces (three columns), planar meshes (two) and solids, whatever the memory layout of the back-substitution's
result; corrected in place, without another array as long as the mesh; a vertex written as a point gives the
vertex handle's solve on every kind of mesh; and a drag's short warm solves meet the points exactly with energies
that never rise."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import arap
import arap.solve.iteration as iteration
from arap.meshes.grids import box_tetrahedra, rectangle_triangles
from arap.meshes.shapes import sphere
from arap.solve.prepared import Prepared, prepare

KINDS = ("surface", "planar", "solid")


def _mesh(kind: str, size: int = 1) -> tuple[np.ndarray, np.ndarray, str]:
    """A small mesh of each kind and the energy it is solved with."""
    if kind == "surface":
        V, F = sphere(frequency=2 * size)
        return V, F, "spokes_and_rims"
    if kind == "planar":
        V, F = rectangle_triangles(8 * size, 4 * size)
        return V, F, "elements"
    V, T = box_tetrahedra(4 * size, 2, 2)
    return V, T, "elements"


def _pinned(V: np.ndarray) -> np.ndarray:
    """The vertices at the low end along x."""
    return np.flatnonzero(V[:, 0] <= V[:, 0].min() + 1e-9)


def _points(V: np.ndarray, F: np.ndarray, soft: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Three hard points in elements far from the pinned end, spread over the mesh, and one soft point."""
    centres = V[F].mean(axis=1)
    order = np.argsort(-centres[:, 0], kind="stable")
    faces = np.array([order[0], order[len(order) // 3], order[len(order) // 2], order[len(order) // 4]])
    rng = np.random.default_rng(7)
    bary = rng.random((4, F.shape[1])) + 0.1
    bary /= bary.sum(axis=1, keepdims=True)
    weights = np.array([np.inf, np.inf, np.inf, 2.0 if soft else np.inf])
    return faces, bary, weights


def _prepared(kind: str) -> tuple[Prepared, int]:
    V, F, energy = _mesh(kind)
    p = prepare(V, F, _pinned(V), energy=energy, points=_points(V, F))  # type: ignore[arg-type]
    return p, p.iteration_columns


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", ["C", "F"])
def test_the_correction_is_the_constrained_minimiser(kind: str, order: str) -> None:
    p, d = _prepared(kind)
    system = p.point_system
    assert system is not None and p.factor is not None and system.hard.sum() == 3
    rng = np.random.default_rng(3)
    b = rng.standard_normal((p.nf, d))
    goal = rng.standard_normal((3, d))
    y = np.asarray(p.factor.solve(b), order=order)
    x = system.project(y, goal)
    assert x is y  # corrected in place
    # The minimiser of xᵀA x − 2 bᵀx subject to C_h x = goal, from the dense KKT system.
    A = p.matrix.toarray()
    C = system.C_free[system.hard].toarray()
    K = np.block([[A, C.T], [C, np.zeros((3, 3))]])
    reference = np.linalg.solve(K, np.vstack([b, goal]))[:p.nf]
    scale = np.abs(reference).max()
    np.testing.assert_allclose(x, reference, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(C @ x, goal, rtol=0, atol=1e-10 * scale)


def test_the_correction_and_the_right_hand_side_make_no_array_as_long_as_the_mesh() -> None:
    V, F = rectangle_triangles(90, 45)
    p = prepare(V, F, _pinned(V), energy="elements", points=_points(V, F))
    system = p.point_system
    assert system is not None and p.factor is not None and p.nf > 4000
    y = np.asarray(p.factor.solve(np.ones((p.nf, 2))))
    goal = np.zeros((3, 2))
    targets, fixed, const = np.ones((4, 3)), p.fixed_positions(np.zeros((len(p.constrained), 3))), np.zeros((p.nf, 3))
    expected = const - system.rhs(targets, fixed)
    system.project(y.copy(), goal)  # compiled and warm
    n_long = p.nf * 2 * 8
    tracemalloc.start()
    try:
        system.project(y, goal)
        _, peak_project = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        out = system.subtract_rhs(const, targets, fixed)
        _, peak_rhs = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak_project < n_long / 4
    assert peak_rhs < 1.25 * const.nbytes  # the result alone
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_the_elements_are_numbered_once_at_set_up(monkeypatch: pytest.MonkeyPatch) -> None:
    V, F, _ = _mesh("planar")
    faces, bary, _ = _points(V, F)
    solver = arap.ArapSolver(V, F, _pinned(V), energy="elements", points=(faces, bary))
    p = solver.prepared
    np.testing.assert_array_equal(p.elements, p.numbering.inv[p.F])
    seen: list[np.ndarray] = []

    class Recording(iteration.Unfolder):
        def __init__(self, T: np.ndarray, *args: object) -> None:
            seen.append(T)
            super().__init__(T, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(iteration, "Unfolder", Recording)
    targets = V[_pinned(V)]
    P = np.einsum("pc,pcx->px", bary, V[F[faces]]) + np.array([0.1, 0.0])
    for _ in range(2):
        solver.solve(targets, point_targets=P, max_iterations=1)
    assert len(seen) == 2 and all(T is p.elements for T in seen)


@pytest.mark.parametrize("kind", KINDS)
def test_a_vertex_as_a_point_gives_the_vertex_handle(kind: str) -> None:
    V, F, energy = _mesh(kind)
    fixed = _pinned(V)
    handle = int(np.argmax(V[:, 0] + 0.1 * V[:, 1]))
    target = V[handle] + np.array([0.1, 0.3, 0.0])[:V.shape[1]] * np.ptp(V[:, 0])
    start = V.copy()
    start[handle] = target
    vertex = arap.ArapSolver(V, F, np.append(fixed, handle), energy=energy).solve(  # type: ignore[arg-type]
        np.vstack([V[fixed], target]), max_iterations=20, tolerance=0, acceleration="none", initial=start)
    f = int(np.flatnonzero((F == handle).any(axis=1))[0])
    bary = (F[f] == handle).astype(float)
    point = arap.ArapSolver(V, F, fixed, energy=energy, points=([f], [bary])).solve(  # type: ignore[arg-type]
        V[fixed], point_targets=[target], max_iterations=20, tolerance=0, acceleration="none", initial=start)
    scale = float(np.linalg.norm(np.ptp(V, axis=0)))
    np.testing.assert_allclose(point.vertices, vertex.vertices, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(point.energies, vertex.energies, rtol=1e-8)


@pytest.mark.parametrize("kind", KINDS)
def test_a_drag_meets_its_hard_points_with_energies_never_rising(kind: str) -> None:
    V, F, energy = _mesh(kind, size=2)
    fixed = _pinned(V)
    faces, bary, weights = _points(V, F, soft=False)
    solver = arap.ArapSolver(V, F, fixed, energy=energy, points=(faces, bary, weights))  # type: ignore[arg-type]
    rest = np.einsum("pc,pcx->px", bary, V[F[faces]])
    scale = float(np.linalg.norm(np.ptp(V, axis=0)))
    lift = np.array([0.0, 1.0]) if kind == "planar" else np.array([0.0, 0.6, 0.8])  # a planar mesh given as (n, 2)
    for k in range(1, 6):
        P = rest.copy()
        P[0] += 0.04 * k * scale * lift
        result = solver.solve(V[fixed], point_targets=P, max_iterations=2, tolerance=0)
        U = result.vertices
        reached = np.einsum("pc,pcx->px", bary, U[F[faces]])
        assert np.abs(reached - P).max() <= 1e-9 * scale
        assert np.diff(result.energies).max(initial=0.0) <= 1e-10 * abs(result.energies[0])
