"""Why a result takes 100-400 iterations: the slow modes of the global-step-preconditioned iteration, and what a
coarse space interpolated from fewer vertices can do about them.

At the converged shape ``x*`` of a scenario, the plain local/global step is, to first order, ``e ← T e`` with
``T = I − A⁻¹ H / 2`` (``A`` the factored global-step matrix, ``H`` the energy's Hessian with the rotations fitted,
here by central differences of the exact gradient ``2 (A x − b(R(x)))``). Its eigenvalues near 1 are the slow modes:
``κ = 1 / (1 − λ_max)`` is the condition number a Krylov method preconditioned by ``A`` sees, and conjugate gradients
need about ``½ √κ ln(2/ε)`` iterations to reduce an error by ``ε``, the count L-BFGS (also preconditioned by ``A``)
is compared with.

Printed per scenario: the largest eigenvalues of ``T``; for each slow mode the share of vertices it moves
(participation ratio) and how far it is from a rigid motion of those vertices; the measured L-BFGS iterations and its
rate in the linear phase; and two measures of a coarse space of fields interpolated from ``n / --coarsen`` cluster
centres (weights that reproduce affine fields, so rigid motions are exact):

* the locking ratio of each slow mode, ``q(P y) / q(v)`` for its best approximation ``P y`` in the ``A`` norm, with
  the Rayleigh quotient ``q(u) = uᵀHu / uᵀAu``. Far above 1, the coarse space holds the mode only with stiff
  (stretching) components (membrane locking: the fine bending stiffness scales with the cells' size squared);
* the two-level factor: the reduction per cycle of an error made of the slow modes by the best coarse correction on
  that space (the Galerkin ``Pᵀ H P`` of the exact Hessian, solved exactly) and one plain step, against L-BFGS's
  rate per iteration.

Run: ``python benchmarks/bench_slow_modes.py [--modes 8] [--coarsen 20] [--quick] [--json [PATH]]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.spatial import cKDTree

from arap import ArapSolver
from arap.constraints.scenarios import make_scenario
from arap.io import load_mesh
from arap.meshes.shapes import builtin_mesh
from arap.method.covariance import assemble_rhs
from arap.solve.iteration import local_energy, rhs_constant
from benchjson import add_json_option, figure, write_results

MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"
SCENARIOS = [("armadillo.obj", "bend"), ("camelhead.off", "bend"), ("cactus", "bend")]
#: The two-level factor needs a Hessian product per coarse column: skipped above this many.
MAX_COARSE_COLUMNS = 8000


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    return load_mesh(MESHES / name) if "." in name else builtin_mesh(name)


class Linearised:
    """The gradient of the energy (rotations fitted) over the free vertices at ``x*``, and its derivatives."""

    def __init__(self, solver: ArapSolver, targets: np.ndarray) -> None:
        p = solver.prepared
        self.p, self.state = p, solver._state.local
        fixed = p.fixed_positions(p.check_targets(targets))
        self.const = rhs_constant(p, fixed, None)
        assert solver._state.last is not None
        self.U = solver._state.last.copy()
        self.x = self.U[:p.nf].copy()
        self.eps = 1e-6 * p.diagonal
        self.products = 0

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """Half the energy's gradient, ``A x − b(R(x))``."""
        U = self.U.copy()
        U[:self.p.nf] = x
        local_energy(self.p, self.state, U, 0.0, {"local": 0.0})
        b = np.empty((self.p.nf, 3))
        assemble_rhs(self.p.gather, self.state.R, self.const, b)
        return np.asarray(self.p.matrix @ x - b)

    def hessian_times(self, v: np.ndarray) -> np.ndarray:
        """``H v / 2`` by central differences."""
        v = v.reshape(-1, 3)
        size = float(np.linalg.norm(v))
        if size == 0:
            return np.zeros(v.size)
        d = v / size * self.eps
        self.products += 1
        return ((self.gradient(self.x + d) - self.gradient(self.x - d)) / (2 * self.eps) * size).ravel()

    def a_times(self, v: np.ndarray) -> np.ndarray:
        return np.asarray(self.p.matrix @ v.reshape(-1, 3)).ravel()


def slow_modes(lin: Linearised, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` largest eigenvalues of ``T`` and their eigenvectors (``(A − H/2) v = λ A v``)."""
    N = 3 * lin.p.nf
    assert lin.p.factor is not None
    factor = lin.p.factor
    op = sla.LinearOperator((N, N), matvec=lambda v: lin.a_times(v) - lin.hessian_times(v), dtype=float)
    M = sla.LinearOperator((N, N), matvec=lin.a_times, dtype=float)
    Minv = sla.LinearOperator((N, N), matvec=lambda v: factor.solve(np.ascontiguousarray(v.reshape(-1, 3))).ravel(),
                              dtype=float)
    vals, vecs = sla.eigsh(op, k=k, M=M, Minv=Minv, which="LA", tol=1e-4, maxiter=5000)
    order = np.argsort(-vals)
    return vals[order], vecs[:, order]


def shape_of(v: np.ndarray, X: np.ndarray) -> tuple[float, float]:
    """Participation ratio (share of vertices the mode moves) and its distance from a rigid motion of them."""
    v = v.reshape(-1, 3)
    e = np.linalg.norm(v, axis=1)
    share = float((e ** 2).sum() ** 2 / (e ** 4).sum() / len(e))
    top = np.argsort(-e)[:max(10, int(0.9 * share * len(e)))]
    Y = X[top] - X[top].mean(axis=0)
    rows = np.zeros((len(top), 3, 6))
    rows[:, 0, 1], rows[:, 0, 2] = Y[:, 2], -Y[:, 1]
    rows[:, 1, 0], rows[:, 1, 2] = -Y[:, 2], Y[:, 0]
    rows[:, 2, 0], rows[:, 2, 1] = Y[:, 1], -Y[:, 0]
    rows[:, :, 3:] = np.eye(3)
    J, b = rows.reshape(-1, 6), v[top].ravel()
    sol = np.linalg.lstsq(J, b, rcond=None)[0]
    return share, float(np.linalg.norm(J @ sol - b) / np.linalg.norm(b))


def coarse_space(X: np.ndarray, coarsen: int) -> sp.csr_matrix:
    """Fields interpolated from ``n / coarsen`` cluster centres (a regular subsample in the solver's locality order):
    each vertex's weights over its eight nearest centres sum to 1 and reproduce its position (so affine fields, rigid
    motions included, are interpolated exactly), the least-squares such weights, scaled by inverse distance."""
    n, k = len(X), 8
    centres = X[np.linspace(0, n - 1, max(k, n // coarsen)).astype(int)]
    dist, near = cKDTree(centres).query(X, k=k)
    scale = 1.0 / np.maximum(dist, 1e-12 * float(dist.max()))  # (n, k) prior: nearer centres weigh more
    C = np.concatenate([np.ones((n, 1, k)), np.transpose(centres[near] - X[:, None, :], (0, 2, 1))], axis=1)
    D = scale[:, None, :] ** -1  # minimise Σ w_j² / scale_j under C w = (1, 0, 0, 0)
    G = np.einsum("nik,nk,njk->nij", C, 1.0 / D[:, 0, :], C)
    rhs = np.zeros((n, 4))
    rhs[:, 0] = 1.0
    lam = np.linalg.solve(G + 1e-12 * np.eye(4), rhs[..., None])[..., 0]
    w = np.einsum("nik,ni->nk", C, lam) / D[:, 0, :]
    P1 = sp.csr_matrix((w.ravel(), near.ravel(), np.arange(0, k * n + 1, k)), shape=(n, len(centres)))
    return sp.kron(P1, sp.identity(3), format="csr")


def locking_ratio(lin: Linearised, v: np.ndarray, P: sp.csr_matrix) -> float:
    """``q(P y) / q(v)`` for the ``A``-orthogonal projection ``P y`` of ``v`` on the coarse space."""
    A3 = sp.kron(lin.p.matrix, sp.identity(3), format="csr")  # coordinates interleaved as v.reshape(-1, 3)

    def q(u: np.ndarray) -> float:
        return float(u @ lin.hessian_times(u)) / float(u @ (A3 @ u))

    y = sla.spsolve((P.T @ A3 @ P).tocsc(), P.T @ (A3 @ v))
    return q(P @ y) / q(v)


def two_level_factor(lin: Linearised, vecs: np.ndarray, P: sp.csr_matrix, smoothing: int = 1,
                     cycles: int = 4) -> float:
    """Mean reduction per cycle of the ``H`` norm of an error made of the slow modes, by the linear two-level method
    with the best coarse operator there is (the Galerkin ``Pᵀ H P`` of the exact Hessian, solved exactly) and
    ``smoothing`` plain steps: the most a coarse correction on this space can do."""
    assert lin.p.factor is not None
    factor = lin.p.factor
    Pc = P.tocsc()
    HP = np.column_stack([lin.hessian_times(Pc[:, j].toarray().ravel()) for j in range(P.shape[1])])
    Hc = P.T @ HP
    coarse_inverse = np.linalg.pinv(0.5 * (Hc + Hc.T))

    def norm(e: np.ndarray) -> float:
        return float(np.sqrt(max(float(e @ lin.hessian_times(e)), 0.0)))

    e = vecs @ np.random.default_rng(0).standard_normal(vecs.shape[1])
    start = norm(e)
    for _ in range(cycles):
        e = e - P @ (coarse_inverse @ (P.T @ lin.hessian_times(e)))
        for _ in range(smoothing):
            e = e - factor.solve(np.ascontiguousarray(lin.hessian_times(e).reshape(-1, 3))).ravel()
    return (norm(e) / start) ** (1 / cycles)


def lbfgs_run(solver: ArapSolver, targets: np.ndarray, reference: np.ndarray) -> tuple[int, float]:
    """Iterations of the default solve from the rest pose, and its error's rate per iteration between 1e-2 and
    1e-5 of the diagonal (the linear phase)."""
    errors: list[float] = []

    def record(k: int, energy: float) -> bool:
        errors.append(float(np.abs(solver.current_vertices() - reference).max()))
        return True

    solver.reset()
    result = solver.solve(targets, initial="rest", callback=record)
    d = solver.prepared.diagonal
    phase = [i for i, e in enumerate(errors) if 1e-5 * d < e < 1e-2 * d]
    rate = (errors[phase[-1]] / errors[phase[0]]) ** (1 / max(1, phase[-1] - phase[0])) if len(phase) > 1 \
        else float("nan")
    return result.iterations, float(rate)


def run(name: str, scenario: str, k: int, coarsen: int) -> dict[str, Any]:
    V, F = load(name)
    s = make_scenario(scenario, V)
    solver = ArapSolver(V, F, s.constrained)
    reference = solver.solve(s.targets, initial="rest", tolerance=1e-12).vertices
    iterations, rate = lbfgs_run(solver, s.targets, reference)
    solver.solve(s.targets, initial=reference, tolerance=1e-12)
    lin = Linearised(solver, s.targets)
    t = time.perf_counter()
    vals, vecs = slow_modes(lin, k)
    seconds = time.perf_counter() - t
    P = coarse_space(lin.U[:lin.p.nf], coarsen)
    modes = []
    for j in range(len(vals)):
        share, rigid = shape_of(vecs[:, j], lin.U[:lin.p.nf])
        modes.append({"eigenvalue": float(vals[j]), "share": share, "rigid_residual": rigid,
                      "locking_ratio": locking_ratio(lin, vecs[:, j], P)})
    two_level = two_level_factor(lin, vecs, P) if P.shape[1] <= MAX_COARSE_COLUMNS else float("nan")
    kappa = 1.0 / (1.0 - float(vals[0]))
    return {"mesh": name, "scenario": scenario, "n": len(V), "lbfgs_iterations": iterations, "lbfgs_rate": rate,
            "kappa": kappa, "cg_iterations_1e-8": 0.5 * np.sqrt(kappa) * np.log(2 / 1e-8), "modes": modes,
            "two_level_factor": two_level, "eigen_seconds": seconds, "hessian_products": lin.products}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", type=int, default=8, help="slow modes per scenario (default: 8)")
    parser.add_argument("--coarsen", type=int, default=20, help="fine vertices per coarse centre (default: 20)")
    parser.add_argument("--quick", action="store_true", help="the built-in cactus only")
    add_json_option(parser, "bench_slow_modes")
    args = parser.parse_args(argv)
    scenarios = [s for s in SCENARIOS if "." not in s[0]] if args.quick else \
        [s for s in SCENARIOS if "." not in s[0] or (MESHES / s[0]).exists()]
    rows, figures = [], []
    for name, scenario in scenarios:
        r = run(name, scenario, args.modes, args.coarsen)
        rows.append(r)
        print(f"\n{name} {scenario} ({r['n']:,} vertices): L-BFGS {r['lbfgs_iterations']} iterations, rate "
              f"{r['lbfgs_rate']:.3f}/iteration; kappa {r['kappa']:.0f}, CG bound {r['cg_iterations_1e-8']:.0f} "
              f"iterations for 1e-8; two-level factor per cycle {r['two_level_factor']:.2f} "
              f"({r['hessian_products']} Hessian products, {r['eigen_seconds']:.0f} s)")
        print("  eigenvalue  share  rigid-res  locking")
        for m in r["modes"]:
            print(f"  {m['eigenvalue']:.4f}    {m['share']:.3f}  {m['rigid_residual']:.3f}      "
                  f"{m['locking_ratio']:.0f}")
        figures.append(figure(f"{name} {scenario}: L-BFGS iterations", r["lbfgs_iterations"], "iterations",
                              "CG bound, same preconditioner", r["cg_iterations_1e-8"]))
        figures.append(figure(f"{name} {scenario}: two-level factor per cycle (1 plain step)", r["two_level_factor"],
                              "×", "L-BFGS per iteration", r["lbfgs_rate"]))
        figures.append(figure(f"{name} {scenario}: median locking ratio of the slow modes",
                              float(np.median([m["locking_ratio"] for m in r["modes"]])), "×"))
    if args.json:
        write_results(args.json, "bench_slow_modes", figures, rows)


if __name__ == "__main__":
    main()
