"""Batched local step and right-hand side: equal to the cell-by-cell kernels, and independent of the thread count."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import pytest
from benchmarks.reference_kernels import assemble_rhs_reference, local_step_reference

from arap.kernels import parallel as _parallel
from arap.kernels.parallel import ThreadPolicy
from arap.method import local_step as covariance
from arap.method.cells import Cells, RhsGather
from arap.method.energy import arap_energy
from arap.solve.solver import ArapSolver

from .scenarios import bend_constraints


@dataclass
class State:
    """A deformed mesh part-way through a bend, with everything the kernels read."""

    cells: Cells
    gather: RhsGather
    active: np.ndarray
    U: np.ndarray
    R: np.ndarray
    const: np.ndarray


def _state(V: np.ndarray, F: np.ndarray, energy: str) -> State:
    _, _, constrained, targets = bend_constraints(V)
    solver = ArapSolver(V, F, constrained, energy=energy)
    solver.solve(targets, max_iterations=3)
    assert solver._state.last is not None
    # Rotations of the previous iteration (the lower bounds a real iteration starts from), positions moved on.
    p = solver.prepared
    return State(cells=p.cells, gather=p.gather, active=p.active, U=solver._state.last.copy(),
                 R=solver._state.local.R.copy(), const=p.L_fn @ p.fixed_positions(targets))


@pytest.fixture(scope="module", params=["knight", "camelhead", "armadillo"])
def mesh(request: pytest.FixtureRequest) -> tuple[np.ndarray, np.ndarray]:
    return request.getfixturevalue(request.param)


def _reference(s: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    R, E, out = s.R.copy(), np.zeros(len(s.U)), np.empty_like(s.const)
    local_step_reference(s.cells, s.active, s.U, R, E)
    assemble_rhs_reference(s.gather, R, s.const, out)
    return R, E, out


def _close(a: np.ndarray, b: np.ndarray, tol: float = 1e-12) -> bool:
    return bool(np.abs(a - b).max() <= tol * max(np.abs(b).max(), 1.0))


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_batched_kernels_agree_with_the_cell_by_cell_ones(mesh: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    s = _state(*mesh, energy)
    R_ref, E_ref, out_ref = _reference(s)
    a = s.active
    R, E, out = s.R.copy(), np.zeros(len(s.U)), np.empty_like(s.const)
    total = covariance.local_step(s.cells, a, s.U, R, E)
    covariance.assemble_rhs(s.gather, R, s.const, out)
    assert _close(R[a], R_ref[a]) and _close(E[a], E_ref[a]) and _close(out, out_ref)
    assert total == pytest.approx(E_ref[a].sum(), rel=1e-12, abs=1e-12 * np.abs(E_ref[a]).sum())


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_rhs_and_gradient_in_one_pass(armadillo: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    """The fused kernel gives the right-hand side of assemble_rhs and A x − b, serially and on threads alike."""
    _, _, constrained, targets = bend_constraints(armadillo[0])
    solver = ArapSolver(*armadillo, constrained, energy=energy)
    solver.solve(targets, max_iterations=3)
    assert solver._state.last is not None
    s = _state(*armadillo, energy)
    A, x = solver.prepared.matrix, np.ascontiguousarray(solver._state.last[:solver.n_free])
    rhs = np.empty_like(s.const)
    covariance.assemble_rhs(solver.prepared.gather, solver._state.local.R, s.const, rhs)
    expected = A @ x - rhs
    gather = solver.prepared.gather
    args = (gather.ptr, gather.cell, gather.g, solver._state.local.R, s.const, A.indptr, A.indices,
            A.data, x)
    runs = []
    saved = numba.get_num_threads()
    try:
        for kernel, threads in ((covariance._rhs_gradient_serial, 1),
                                (covariance._rhs_gradient_parallel, min(2, numba.config.NUMBA_NUM_THREADS))):
            numba.set_num_threads(threads)
            out, grad = np.empty_like(rhs), np.empty_like(rhs)
            kernel(*args, out, grad)
            runs.append((out, grad))
    finally:
        numba.set_num_threads(saved)
    for out, grad in runs:
        assert np.array_equal(out, rhs)
        assert np.abs(grad - expected).max() <= 1e-12 * np.abs(rhs).max()
    assert np.array_equal(runs[0][1], runs[1][1])


def test_rotations_do_not_depend_on_the_starting_guess(knight: tuple[np.ndarray, np.ndarray]) -> None:
    """The previous rotation only bounds the Newton start; identity, the optimum or garbage give the same fit."""
    s = _state(*knight, "spokes")
    a = s.active
    results = []
    for start in (s.R, np.tile(np.eye(3), (len(s.U), 1, 1)), np.full_like(s.R, np.nan), -s.R):
        R, E = start.copy(), np.zeros(len(s.U))
        covariance.local_step(s.cells, a, s.U, R, E)
        results.append((R[a], E[a]))
    for R, E in results[1:]:
        assert _close(R, results[0][0]) and _close(E, results[0][1])


@pytest.mark.parametrize("energy", ["spokes", "spokes_and_rims"])
def test_thread_count_does_not_change_results(armadillo: tuple[np.ndarray, np.ndarray], energy: str) -> None:
    s = _state(*armadillo, energy)
    args = (s.active, s.cells.ptr, s.cells.a, s.cells.b, s.cells.w, s.cells.we, s.cells.rest_sq, s.U)
    rhs = (s.gather.ptr, s.gather.cell, s.gather.g)
    runs = []
    saved = numba.get_num_threads()
    try:
        serial = (covariance._local_serial, covariance._rhs_serial)
        parallel = (covariance._local_parallel, covariance._rhs_parallel)
        for (local, assemble), threads in ((serial, 1), (parallel, 1),
                                           (parallel, min(2, numba.config.NUMBA_NUM_THREADS))):
            numba.set_num_threads(threads)
            R, E, out = s.R.copy(), np.zeros(len(s.U)), np.empty_like(s.const)
            total = local(*args, R, E)
            assemble(*rhs, R, s.const, out)
            runs.append((R, E, out, total))
    finally:
        numba.set_num_threads(saved)
    for R, E, out, total in runs[1:]:
        assert np.array_equal(R, runs[0][0]) and np.array_equal(E, runs[0][1]) and np.array_equal(out, runs[0][2])
        assert total == runs[0][3]


def test_solver_gives_the_same_shape_serial_and_parallel(camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = camelhead
    _, _, constrained, targets = bend_constraints(V)
    shapes = []
    saved = _parallel.policy
    try:
        for min_work in (2**62, 0):
            _parallel.policy = covariance.policy = ThreadPolicy(min_work=min_work)
            result = ArapSolver(V, F, constrained).solve(targets, max_iterations=20)
            shapes.append((result.vertices, result.energies))
    finally:
        _parallel.policy = covariance.policy = saved
    assert np.abs(shapes[0][0] - shapes[1][0]).max() <= 1e-12 * np.abs(V).max()
    assert np.allclose(shapes[0][1], shapes[1][1], rtol=1e-12, atol=0)


class _Clock:
    """Stands in for the kernels: records which version ran and lets the test set how long each takes."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, serial_s: float, parallel_s: float) -> None:
        self.now = 0.0
        self.cost = {"serial": serial_s, "parallel": parallel_s}
        self.calls: list[str] = []
        monkeypatch.setattr(_parallel.time, "perf_counter", lambda: self.now)
        monkeypatch.setattr(_parallel.numba, "set_num_threads", lambda n: None)
        monkeypatch.setattr(_parallel.numba.config, "NUMBA_NUM_THREADS", 2)

    def kernel(self, kind: str) -> str:
        self.calls.append(kind)
        self.now += self.cost[kind]
        return kind


def test_small_problems_always_run_serially(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = _Clock(monkeypatch, serial_s=1.0, parallel_s=1e-6)
    policy = ThreadPolicy(min_work=50_000, work_per_thread=25_000)
    for _ in range(100):
        policy.run("k", 49_999, lambda: clock.kernel("serial"), lambda: clock.kernel("parallel"))
    assert clock.calls == ["serial"] * 100
    assert policy.threads(49_999) == 1 and policy.threads(50_000) == 2 and policy.threads(10**7) == 2


@pytest.mark.parametrize(("serial_s", "parallel_s", "winner"), [(1.0, 0.6, "parallel"), (1.0, 20.0, "serial")])
def test_large_problems_run_the_way_measured_faster(monkeypatch: pytest.MonkeyPatch, serial_s: float,
                                                    parallel_s: float, winner: str) -> None:
    clock = _Clock(monkeypatch, serial_s, parallel_s)
    policy = ThreadPolicy(min_work=50_000, probe_every=8)
    for _ in range(400):
        policy.run("k", 100_000, lambda: clock.kernel("serial"), lambda: clock.kernel("parallel"))
    loser = "serial" if winner == "parallel" else "parallel"
    # The loser is tried once at first, then probed ever more rarely (8, 16, 32, ... calls apart).
    assert clock.calls.count(loser) <= 2 + 6
    assert clock.calls[-50:].count(winner) >= 49


def test_a_load_that_goes_away_brings_the_threads_back(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = _Clock(monkeypatch, serial_s=1.0, parallel_s=30.0)
    policy = ThreadPolicy(min_work=50_000, probe_every=4)
    for _ in range(50):
        policy.run("k", 100_000, lambda: clock.kernel("serial"), lambda: clock.kernel("parallel"))
    assert clock.calls[-10:] == ["serial"] * 10
    clock.cost["parallel"] = 0.5
    for _ in range(300):
        policy.run("k", 100_000, lambda: clock.kernel("serial"), lambda: clock.kernel("parallel"))
    assert clock.calls[-20:].count("parallel") >= 19


def test_an_occasional_stall_does_not_flip_the_choice(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = _Clock(monkeypatch, serial_s=1.0, parallel_s=3.0)
    policy = ThreadPolicy(min_work=50_000, probe_every=1000)  # no probe within the test
    for i in range(200):
        clock.cost["serial"] = 50.0 if i % 10 == 5 else 1.0  # one call in ten loses a time slice
        policy.run("k", 100_000, lambda: clock.kernel("serial"), lambda: clock.kernel("parallel"))
    assert clock.calls.count("parallel") == 1  # the first call, to measure it


def test_results_do_not_depend_on_uninitialised_memory(monkeypatch: pytest.MonkeyPatch,
                                                        camelhead: tuple[np.ndarray, np.ndarray]) -> None:
    """A rotation fit starts its root search from the cell's previous rotation, and the start sets the last bits of
    the result: a start read from uninitialised memory made energies differ from run to run in the last digit.
    Whatever new uninitialised arrays hold, every figure must come out the same, bit for bit."""
    V, F = camelhead
    _, _, constrained, targets = bend_constraints(V)
    real_empty = np.empty
    runs = []
    for seed in (1.3, 2.7):

        def garbage(*args: object, seed: float = seed, **kwargs: object) -> np.ndarray:
            a = real_empty(*args, **kwargs)  # type: ignore[call-overload]
            if a.dtype.kind == "f":  # finite values in [-2, 2] that differ between the two runs
                a.reshape(-1)[:] = 2.0 * np.sin(seed * np.arange(a.size, dtype=np.float64))
            return a

        with monkeypatch.context() as m:
            m.setattr(np, "empty", garbage)
            solver = ArapSolver(V, F, constrained, energy="spokes_and_rims")
            result = solver.solve(targets, max_iterations=5)
            runs.append((result.energies, solver.energy(result.vertices),
                         arap_energy(V, F, result.vertices, energy="spokes_and_rims")))
    assert runs[0] == runs[1]
