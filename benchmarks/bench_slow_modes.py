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

With ``--ceiling`` the Hessian ``H / 2`` is first assembled by probing (central differences of the exact gradient on
groups of vertices more than four edges apart, about 40 colours × 3 coordinates of gradients), every product below
uses it, and per scenario it also measures:

* the ceiling: how many eigenvalues of ``T`` lie above 0.98, 0.95 and 0.90 (among the ``--ceiling-modes`` slowest,
  shift-invert Lanczos on ``H v = μ A v``, ``λ = 1 − μ``), and the iterations of conjugate gradients on the
  linearised problem ``H e = H e₀`` to reduce the ``H`` norm of the error by 1e-6, preconditioned by ``A⁻¹`` alone
  and with the ``k`` slowest exact eigenvectors added (``A⁻¹ + V (VᵀHV)⁻¹ Vᵀ``) or deflated (``Q + (I − QH) A⁻¹``,
  ``Q = V (VᵀHV)⁻¹ Vᵀ``), for ``e₀`` the rest pose's error and a random one: no coarse space of ``k`` columns can
  do better than its ``k`` exact eigenvectors;
* coarse spaces at equal size (``3 n / --space-coarsen`` columns): scalar interpolated fields (Euclidean nearest
  centres, as above, or centres of clusters that follow the surface: graph Voronoi cells of farthest-point seeds),
  a smooth partition-of-unity affine map per centre, a piecewise-constant affine map per surface cluster, the six
  rigid-body modes per surface cluster, and smoothed aggregation (pyamg, when installed) with the rigid-body modes as
  near-null space, on the same clusters and on its own aggregates: each one's median locking ratio and two-level
  factor.

Run: ``python benchmarks/bench_slow_modes.py [--modes 8] [--coarsen 20] [--quick] [--meshes NAME ...] [--ceiling
[--ceiling-modes 256] [--space-coarsen 20 5] [--no-amg]] [--json [PATH]]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from arap import ArapSolver
from arap.io import load_mesh
from arap.meshes.shapes import builtin_mesh
from arap.meshes.topology import vertex_adjacency
from arap.method.local_step import assemble_rhs
from arap.solve.iteration import local_energy, rhs_constant
from arap.sparse.linsolve import NotPositiveDefiniteError, factorize
from benchjson import add_json_option, figure, write_results
from scenarios import make_scenario

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
        #: ``H / 2`` once assembled (:func:`assemble_hessian`): products use it instead of differences.
        self.assembled: sp.csr_matrix | None = None

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
        if self.assembled is not None:
            return np.asarray(self.assembled @ v.ravel())
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


# ---------------------------------------------------------------------------------------------------------------
# The ceiling and coarse spaces at equal size (``--ceiling``): every product below uses the Hessian assembled once by
# probing (central differences of the exact gradient on groups of vertices far enough apart not to share a row).

#: Eigenvalues of ``T`` the ceiling counts above.
THRESHOLDS = (0.98, 0.95, 0.90)
#: Exact slow eigenvectors deflated from the preconditioned conjugate gradients.
DEFLATED = (8, 16, 32, 64, 128, 256)


def assemble_hessian(lin: Linearised, symmetric: bool = True) -> sp.csr_matrix:
    """``H / 2`` (the derivative of :meth:`Linearised.gradient`) as a sparse matrix, coordinates interleaved.

    The gradient at a vertex depends on the vertices within two edges (its cells' rotations depend on their 1-rings),
    so vertices more than four edges apart are perturbed together: one gradient difference per colour and coordinate.
    """
    nf = lin.p.nf
    A1 = (free_adjacency(lin.p, through_fixed=True) + sp.identity(lin.p.n, format="csr")).astype(np.int32).tocsr()
    S = (A1 @ A1).tocsr()[:nf, :nf]  # the pattern of a row: vertices within two edges, through constrained ones too
    conflict = (S @ S).tocsr()  # columns sharing a row
    colour = np.full(nf, -1, dtype=np.int64)
    ptr, idx = conflict.indptr, conflict.indices
    for i in range(nf):
        used = set(colour[idx[ptr[i]:ptr[i + 1]]].tolist())
        c = 0
        while c in used:
            c += 1
        colour[i] = c
    S = S.tocoo()
    rows, cols = S.row.astype(np.int64), S.col.astype(np.int64)
    data = np.empty((len(rows), 3, 3))
    for c in range(int(colour.max()) + 1):
        take = colour[cols] == c
        for a in range(3):
            d = np.zeros((nf, 3))
            d[colour == c, a] = lin.eps
            column = (lin.gradient(lin.x + d) - lin.gradient(lin.x - d)) / (2 * lin.eps)
            lin.products += 1
            data[take, :, a] = column[rows[take]]
    r3 = (3 * rows[:, None, None] + np.arange(3)[None, :, None]).repeat(3, axis=2)
    c3 = (3 * cols[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1)
    H = sp.csr_matrix((data.ravel(), (r3.ravel(), c3.ravel())), shape=(3 * nf, 3 * nf))
    H = (0.5 * (H + H.T)).tocsr() if symmetric else H.tocsr()
    H.eliminate_zeros()
    return H


def free_adjacency(p: Any, through_fixed: bool = False) -> sp.csr_matrix:
    """The free vertices' edge adjacency from the faces, in the solver's internal order (the global-step matrix
    lacks edges whose weight is 0, which the rotations still see); ``through_fixed``: all vertices', for paths that
    pass through the constrained ones."""
    perm = p.numbering.perm
    adjacency = (vertex_adjacency(p.F, p.n).tocsr()[perm][:, perm] != 0).astype(float).tocsr()
    free = adjacency[:p.nf, :p.nf]
    pattern = (p.matrix != 0).astype(np.int8)
    assert ((pattern - pattern.multiply(free + sp.identity(p.nf))) != 0).nnz == 0, "faces and matrix disagree"
    return adjacency if through_fixed else free


def ceiling_modes(H: sp.csr_matrix, A3: sp.csr_matrix, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` smallest ``μ`` of ``H v = μ A v`` (``λ = 1 − μ`` the eigenvalues of ``T``, the slowest first), by
    shift-invert Lanczos, and their eigenvectors (``Vᵀ A V = I``)."""
    N = H.shape[0]
    factor = factorize(H.tocsr())
    OPinv = sla.LinearOperator((N, N), matvec=lambda v: factor.solve(np.asarray(v).reshape(-1, 1)).ravel(),
                               dtype=float)
    vals, vecs = sla.eigsh(H, k=k, M=A3, sigma=0.0, which="LM", OPinv=OPinv, tol=1e-6,
                           ncv=min(N, max(2 * k + 1, k + 40)))
    order = np.argsort(vals)
    return vals[order], vecs[:, order]


def pcg_iterations(H: sp.csr_matrix, precondition: Any, e_true: np.ndarray, reduction: float = 1e-6,
                   maxiter: int = 5000) -> int:
    """Iterations of preconditioned conjugate gradients on ``H e = H e_true`` from 0 until the ``H`` norm of the
    error is ``reduction`` times its start."""
    b = H @ e_true
    x = np.zeros_like(b)
    r = b.copy()
    z = precondition(r)
    p = z.copy()
    rz = float(r @ z)
    start = float(np.sqrt(e_true @ b))
    for it in range(1, maxiter + 1):
        Hp = H @ p
        alpha = rz / float(p @ Hp)
        x += alpha * p
        r -= alpha * Hp
        e = e_true - x
        if np.sqrt(max(float(e @ (H @ e)), 0.0)) <= reduction * start:
            return it
        z = precondition(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return maxiter


def edge_graph(p: Any, X: np.ndarray) -> sp.csr_matrix:
    """The free vertices' edge graph (from the global-step matrix's pattern) weighted by edge lengths at ``X``."""
    G = sp.triu(free_adjacency(p), k=1).tocoo()
    length = np.linalg.norm(X[G.row] - X[G.col], axis=1)
    W = sp.csr_matrix((np.maximum(length, 1e-300), (G.row, G.col)), shape=p.matrix.shape)
    return (W + W.T).tocsr()


def surface_clusters(G: sp.csr_matrix, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``m`` seeds by farthest-point sampling of graph distance (from vertex 0's farthest) and the graph Voronoi
    cluster of every vertex (multi-source Dijkstra on the edge lengths)."""
    n = G.shape[0]
    d = csgraph.dijkstra(G, indices=0)
    seeds = [int(np.argmax(np.where(np.isfinite(d), d, -1)))]
    d = csgraph.dijkstra(G, indices=seeds[0])
    for _ in range(1, min(m, n)):
        s = int(np.argmax(d))
        seeds.append(s)
        d = np.minimum(d, csgraph.dijkstra(G, indices=s, limit=float(d[s])))
    _, _, source = csgraph.dijkstra(G, indices=seeds, min_only=True, return_predecessors=True)
    label = np.searchsorted(np.sort(seeds), source)
    order = np.argsort(seeds)
    return np.asarray(seeds)[order], label  # seeds sorted, label indexes them


def scalar_weights(X: np.ndarray, centres: np.ndarray, near: np.ndarray, dist: np.ndarray) -> sp.csr_matrix:
    """Each vertex's weights over its candidate centres ``near`` (n, k): they sum to 1 and reproduce its position
    (affine fields exact), the least-squares such weights scaled by inverse distance (as :func:`coarse_space`)."""
    n, k = near.shape
    D = np.maximum(dist, 1e-12 * float(dist.max()))
    C = np.concatenate([np.ones((n, 1, k)), np.transpose(centres[near] - X[:, None, :], (0, 2, 1))], axis=1)
    G = np.einsum("nik,nk,njk->nij", C, 1.0 / D, C)
    rhs = np.zeros((n, 4, 1))
    rhs[:, 0] = 1.0
    lam = np.linalg.solve(G + 1e-12 * np.eye(4), rhs)[..., 0]
    w = np.einsum("nik,ni->nk", C, lam) / D
    return sp.csr_matrix((w.ravel(), near.ravel(), np.arange(0, k * n + 1, k)), shape=(n, len(centres)))


def surface_neighbours(X: np.ndarray, G: sp.csr_matrix, seeds: np.ndarray, label: np.ndarray,
                       k: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Each vertex's ``k`` nearest centres among its own cluster's and those of clusters within two cluster
    adjacencies (so a centre across a gap, near in space but far on the surface, is never used)."""
    m = len(seeds)
    Gc = G.tocoo()
    C = sp.csr_matrix((np.ones(len(Gc.row)), (label[Gc.row], label[Gc.col])), shape=(m, m))
    C = ((C + sp.identity(m)) != 0).astype(float)
    C2 = (C @ C).tocsr()
    near = np.zeros((len(X), k), dtype=np.int64)
    dist = np.zeros((len(X), k))
    members = np.argsort(label, kind="stable")
    bounds = np.searchsorted(label[members], np.arange(m + 1))
    for c in range(m):
        vs = members[bounds[c]:bounds[c + 1]]
        cand = C2.indices[C2.indptr[c]:C2.indptr[c + 1]]
        if len(cand) < k:
            extra = np.argsort(np.linalg.norm(X[seeds] - X[seeds[c]], axis=1))[:k]
            cand = np.union1d(cand, extra)
        dd = np.linalg.norm(X[vs, None, :] - X[seeds[cand]][None, :, :], axis=2)
        pick = np.argsort(dd, axis=1)[:, :k]
        near[vs] = cand[pick]
        dist[vs] = np.take_along_axis(dd, pick, axis=1)
    return near, dist


def affine_columns(P1: sp.csr_matrix, X: np.ndarray, origin: np.ndarray) -> sp.csr_matrix:
    """Each coarse node an affine map ``M_j`` (12 columns): vertex field ``Σ_j P1_ij M_j [x_i − origin_j; 1]``.
    With ``P1`` a cluster indicator, the piecewise-constant affine space."""
    P1 = P1.tocoo()
    i, j, w = P1.row, P1.col, P1.data
    y = np.concatenate([X[i] - origin[j], np.ones((len(i), 1))], axis=1)  # (nnz, 4)
    rows = (3 * i[:, None, None] + np.arange(3)[None, :, None]).repeat(4, axis=2)
    cols = 12 * j[:, None, None] + 4 * np.arange(3)[None, :, None] + np.arange(4)[None, None, :]
    vals = (w[:, None, None] * y[:, None, :]).repeat(3, axis=1)
    return sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * P1.shape[0], 12 * P1.shape[1]))


def rigid_columns(label: np.ndarray, X: np.ndarray, m: int) -> sp.csr_matrix:
    """Rigid-body modes per cluster (6 columns): translation and infinitesimal rotation ``ω × (x − c)`` about the
    cluster's centroid."""
    n = len(X)
    count = np.bincount(label, minlength=m)
    c = np.stack([np.bincount(label, weights=X[:, a], minlength=m) for a in range(3)], axis=1) / \
        np.maximum(count, 1)[:, None]
    Y = X - c[label]
    block = np.zeros((n, 3, 6))
    block[:, :, :3] = np.eye(3)
    block[:, 0, 4], block[:, 0, 5] = Y[:, 2], -Y[:, 1]  # ω × Y
    block[:, 1, 3], block[:, 1, 5] = -Y[:, 2], Y[:, 0]
    block[:, 2, 3], block[:, 2, 4] = Y[:, 1], -Y[:, 0]
    rows = (3 * np.arange(n)[:, None, None] + np.arange(3)[None, :, None]).repeat(6, axis=2)
    cols = (6 * label[:, None, None] + np.arange(6)[None, None, :]).repeat(3, axis=1)
    return sp.csr_matrix((block.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * n, 6 * m))


def rigid_near_null(X: np.ndarray) -> np.ndarray:
    """The six rigid-body modes of the whole mesh (3n, 6), for smoothed aggregation."""
    return rigid_columns(np.zeros(len(X), dtype=np.int64), X - X.mean(axis=0), 1).toarray()


def semidefinite_solver(M: sp.spmatrix) -> Any:
    """``g ↦ M⁻¹ g`` (``g`` of shape (m,) or (m, k)) for a coarse matrix ``PᵀMP``, shifted by 1e-12 of its largest
    diagonal entry (more if that does not solve it to 1e-6): a space whose columns are dependent (a partition of
    unity of affine maps holds the constant linear maps twice) makes it singular, and the shift changes ``P y`` by
    about as little."""
    M = sp.csr_matrix(M)
    M = (0.5 * (M + M.T)).tocsr()
    probe = M @ np.random.default_rng(0).standard_normal(M.shape[0])
    for shift in (1e-12, 1e-10, 1e-8):
        try:
            factor = factorize((M + shift * float(M.diagonal().max()) * sp.identity(M.shape[0])).tocsr())
        except NotPositiveDefiniteError:
            continue
        y = factor.solve(probe.reshape(-1, 1)).ravel()
        if np.all(np.isfinite(y)) and np.linalg.norm(M @ y - probe) <= 1e-6 * np.linalg.norm(probe):
            return lambda g: (lambda x: x.ravel() if np.ndim(g) == 1 else x)(factor.solve(np.asarray(g).reshape(
                M.shape[0], -1)))
    raise NotPositiveDefiniteError("the coarse matrix is not positive semi-definite")


class Assembled:
    """The products the ceiling and the coarse-space comparison need, from the assembled ``H / 2``."""

    def __init__(self, lin: Linearised, H: sp.csr_matrix) -> None:
        assert lin.p.factor is not None
        self.lin, self.H, self.factor = lin, H, lin.p.factor
        self.A3 = sp.kron(lin.p.matrix, sp.identity(3), format="csr")

    def a_solve(self, r: np.ndarray) -> np.ndarray:
        return self.factor.solve(np.ascontiguousarray(r.reshape(-1, 3))).ravel()

    def q(self, u: np.ndarray) -> float:
        return float(u @ (self.H @ u)) / float(u @ (self.A3 @ u))

    def locking(self, vecs: np.ndarray, P: sp.csr_matrix) -> list[float]:
        """The locking ratio of each column of ``vecs`` on ``P`` (see :func:`locking_ratio`)."""
        gram = semidefinite_solver(P.T @ self.A3 @ P)
        Y = gram(np.asarray(P.T @ (self.A3 @ vecs)))
        return [self.q(np.asarray(P @ Y[:, j])) / self.q(vecs[:, j]) for j in range(vecs.shape[1])]

    def two_level_preconditioner(self, P: sp.csr_matrix) -> Any:
        """``r ↦ A⁻¹ r + P (PᵀHP)⁻¹ Pᵀ r``."""
        coarse, PT = self.coarse_solver(P), P.T.tocsr()
        return lambda r: self.a_solve(r) + P @ coarse(PT @ r)

    def coarse_solver(self, P: sp.csr_matrix) -> Any:
        """``g ↦ (Pᵀ H P)⁻¹ g``."""
        return semidefinite_solver(P.T @ self.H @ P)

    def two_level(self, e: np.ndarray, P: sp.csr_matrix, cycles: int = 4) -> float:
        """Reduction per cycle (``H`` norm) of ``e`` by exact Galerkin correction on ``P`` and one plain step."""
        coarse = self.coarse_solver(P)

        def norm(u: np.ndarray) -> float:
            return float(np.sqrt(max(float(u @ (self.H @ u)), 0.0)))

        start = norm(e)
        for _ in range(cycles):
            e = e - P @ coarse(P.T @ (self.H @ e))
            e = e - self.a_solve(self.H @ e)
        return (norm(e) / start) ** (1 / cycles)


def ceiling(asm: Assembled, count: int, e0: np.ndarray) -> dict[str, Any]:
    """Eigenvalues of ``T`` above each threshold (among the ``count`` slowest computed) and iterations of conjugate
    gradients on ``H e = H e0`` preconditioned by ``A⁻¹`` with the ``k`` slowest exact eigenvectors added
    (``A⁻¹ + V (VᵀHV)⁻¹ Vᵀ``) or deflated (A-DEF2: ``Q + (I − Q H) A⁻¹``, ``Q = V (VᵀHV)⁻¹ Vᵀ``)."""
    t = time.perf_counter()
    mu, V = ceiling_modes(asm.H, asm.A3, count)
    lam = 1.0 - mu
    out: dict[str, Any] = {"computed": count, "eigenvalues": lam, "eigen_seconds": time.perf_counter() - t,
                           "above": {f"{th}": int((lam > th).sum()) for th in THRESHOLDS},
                           "above_is_lower_bound": {f"{th}": bool(lam[-1] > th) for th in THRESHOLDS}}
    HV = asm.H @ V
    rng = np.random.default_rng(0)
    errors = {"rest": e0, "random": rng.standard_normal(len(e0))}
    rows = []
    for k in (0, *tuple(d for d in DEFLATED if d <= count)):
        Vk, HVk = V[:, :k], HV[:, :k]
        Einv = np.linalg.inv(Vk.T @ HVk) if k else np.zeros((0, 0))

        def additive(r: np.ndarray, Vk: np.ndarray = Vk, Einv: np.ndarray = Einv) -> np.ndarray:
            return asm.a_solve(r) + Vk @ (Einv @ (Vk.T @ r))

        def deflated(r: np.ndarray, Vk: np.ndarray = Vk, HVk: np.ndarray = HVk, Einv: np.ndarray = Einv) -> np.ndarray:
            z = asm.a_solve(r)
            return Vk @ (Einv @ (Vk.T @ r)) + z - Vk @ (Einv @ (HVk.T @ z))

        row: dict[str, Any] = {"k": k}
        for which, e in errors.items():
            row[f"additive_{which}"] = pcg_iterations(asm.H, additive, e)
            row[f"deflated_{which}"] = pcg_iterations(asm.H, deflated, e) if k else row[f"additive_{which}"]
        row["kappa"] = float(mu.max() if k == 0 else 1.0) / float(mu[k]) if k < count else float("nan")
        rows.append(row)
        print(f"    k={k:4d}: PCG iterations for 1e-6 (rest-pose error / random error): added "
              f"{row['additive_rest']}/{row['additive_random']}, deflated {row['deflated_rest']}/"
              f"{row['deflated_random']}", flush=True)
    out["pcg"] = rows
    print("    eigenvalues of T above " + ", ".join(f"{th}: {out['above'][f'{th}']}"
                                                 f"{'+' if out['above_is_lower_bound'][f'{th}'] else ''}"
                                                 for th in THRESHOLDS) + f" (of the {count} slowest)", flush=True)
    out["vectors"] = V
    return out


def compare_spaces(asm: Assembled, X: np.ndarray, vecs: np.ndarray, e0: np.ndarray, columns: int,
                   amg: bool) -> list[dict[str, Any]]:
    """Locking ratio (median over the slow modes ``vecs``), two-level factor, and iterations of conjugate gradients
    on ``H e = H e0`` preconditioned by ``A⁻¹ + P (PᵀHP)⁻¹ Pᵀ`` (as the ceiling's), of each coarse space with about
    ``columns`` columns."""
    n = len(X)
    G = edge_graph(asm.lin.p, X)
    e = vecs @ np.random.default_rng(0).standard_normal(vecs.shape[1])
    spaces: list[tuple[str, Any]] = []
    m3, m6, m12 = max(4, columns // 3), max(1, columns // 6), max(4, columns // 12)
    centres_idx = np.linspace(0, n - 1, m3).astype(int)
    dist, near = cKDTree(X[centres_idx]).query(X, k=8)
    spaces.append(("scalar, Euclidean nearest centres", lambda: sp.kron(
        scalar_weights(X, X[centres_idx], near, dist), sp.identity(3), format="csr")))

    def scalar_graph() -> sp.csr_matrix:
        seeds, label = surface_clusters(G, m3)
        nb, dd = surface_neighbours(X, G, seeds, label)
        return sp.kron(scalar_weights(X, X[seeds], nb, dd), sp.identity(3), format="csr")
    spaces.append(("scalar, surface clusters", scalar_graph))

    def affine_pu(graph: bool) -> sp.csr_matrix:
        if graph:
            seeds, label = surface_clusters(G, m12)
            nb, dd = surface_neighbours(X, G, seeds, label)
            return affine_columns(scalar_weights(X, X[seeds], nb, dd), X, X[seeds])
        idx = np.linspace(0, n - 1, m12).astype(int)
        dd, nb = cKDTree(X[idx]).query(X, k=8)
        return affine_columns(scalar_weights(X, X[idx], nb, dd), X, X[idx])
    spaces.append(("smooth affine (partition of unity), Euclidean", lambda: affine_pu(False)))
    spaces.append(("smooth affine (partition of unity), surface clusters", lambda: affine_pu(True)))

    def piecewise(kind: str) -> sp.csr_matrix:
        m = m12 if kind == "affine" else m6
        seeds, label = surface_clusters(G, m)
        if kind == "rigid":
            return rigid_columns(label, X, len(seeds))
        ind = sp.csr_matrix((np.ones(n), (np.arange(n), label)), shape=(n, len(seeds)))
        return affine_columns(ind, X, X[seeds])
    spaces.append(("piecewise-constant affine per surface cluster", lambda: piecewise("affine")))
    spaces.append(("rigid-body modes per surface cluster", lambda: piecewise("rigid")))
    if amg:
        try:
            import pyamg
        except ImportError:
            print("    pyamg is not installed: smoothed aggregation skipped")
        else:
            H3 = asm.H.tobsr(blocksize=(3, 3))
            B = rigid_near_null(X)

            def sa(predefined: bool) -> sp.csr_matrix:
                options: dict[str, Any] = {"max_levels": 2, "max_coarse": 1, "keep": True}
                if predefined:  # the rigid-per-cluster space's clusters as aggregates: its prolongator smoothed
                    seeds, label = surface_clusters(G, m6)
                    agg = sp.csr_matrix((np.ones(n), (np.arange(n), label)), shape=(n, len(seeds)))
                    options["aggregate"] = ("predefined", {"AggOp": agg})
                ml = pyamg.smoothed_aggregation_solver(H3, B=B, **options)
                return ml.levels[0].P.tocsr()
            spaces.append(("smoothed aggregation (pyamg), rigid near-null space, surface clusters", lambda: sa(True)))
            spaces.append(("smoothed aggregation (pyamg), rigid near-null space, its own aggregates",
                           lambda: sa(False)))
    out = []
    for name, build in spaces:
        t = time.perf_counter()
        P = build()
        lock = float(np.median(asm.locking(vecs, P)))
        factor = asm.two_level(e, P)
        pcg = pcg_iterations(asm.H, asm.two_level_preconditioner(P), e0)
        out.append({"space": name, "columns": int(P.shape[1]),
                    "equal_size": bool(abs(P.shape[1] - columns) <= 0.05 * columns), "median_locking_ratio": lock,
                    "two_level_factor": factor, "pcg_iterations_rest": pcg, "seconds": time.perf_counter() - t})
        print(f"    {name}: {P.shape[1]} columns, median locking {lock:.2f}, two-level factor {factor:.3f}, PCG "
              f"with it added to A⁻¹: {pcg} iterations", flush=True)
    return out


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


def run(name: str, scenario: str, k: int, coarsen: int, options: argparse.Namespace | None = None) -> dict[str, Any]:
    V, F = load(name)
    s = make_scenario(scenario, V)
    solver = ArapSolver(V, F, s.constrained)
    reference = solver.solve(s.targets, initial="rest", tolerance=1e-12).vertices
    iterations, rate = lbfgs_run(solver, s.targets, reference)
    solver.solve(s.targets, initial=reference, tolerance=1e-12)
    lin = Linearised(solver, s.targets)
    extra: dict[str, Any] = {}
    asm = None
    if options is not None and options.ceiling:
        t = time.perf_counter()
        lin.assembled = assemble_hessian(lin)
        asm = Assembled(lin, lin.assembled)
        check = np.random.default_rng(1).standard_normal(3 * lin.p.nf)
        saved, lin.assembled = lin.assembled, None
        exact = lin.hessian_times(check)
        lin.assembled = saved
        extra["assembly"] = {"seconds": time.perf_counter() - t, "gradients": lin.products,
                             "nonzeros": int(saved.nnz), "relative_error": float(
                                 np.linalg.norm(saved @ check - exact) / np.linalg.norm(exact))}
        print(f"  {name}: H/2 assembled from {lin.products} gradients ({saved.nnz:,} nonzeros), product error "
              f"{extra['assembly']['relative_error']:.1e}", flush=True)
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
    if asm is not None and options is not None:
        X = lin.U[:lin.p.nf]
        e0 = (lin.p.rest[:lin.p.nf] - X).ravel()
        c = ceiling(asm, options.ceiling_modes, e0)
        del c["vectors"]
        extra["ceiling"] = c
        extra["spaces"] = []
        for coarsen_by in options.space_coarsen:
            columns = 3 * lin.p.nf // coarsen_by
            print(f"  coarse spaces of about {columns} columns (3 n / {coarsen_by}):", flush=True)
            for row in compare_spaces(asm, X, vecs, e0, columns, not options.no_amg):
                extra["spaces"].append({"coarsen": coarsen_by, **row})
    return {"mesh": name, "scenario": scenario, "n": len(V), "lbfgs_iterations": iterations, "lbfgs_rate": rate,
            "kappa": kappa, "cg_iterations_1e-8": 0.5 * np.sqrt(kappa) * np.log(2 / 1e-8), "modes": modes,
            "two_level_factor": two_level, "eigen_seconds": seconds, "hessian_products": lin.products, **extra}


def figures_of(r: dict[str, Any]) -> list[dict[str, Any]]:
    """The headline figures of one scenario's results ``r`` (a row of the JSON's data)."""
    name, scenario = r["mesh"], r["scenario"]
    figures = [figure(f"{name} {scenario}: L-BFGS iterations", r["lbfgs_iterations"], "iterations",
                      "CG bound, same preconditioner", r["cg_iterations_1e-8"]),
               figure(f"{name} {scenario}: two-level factor per cycle (1 plain step)", r["two_level_factor"], "×",
                      "L-BFGS per iteration", r["lbfgs_rate"]),
               figure(f"{name} {scenario}: median locking ratio of the slow modes",
                      float(np.median([m["locking_ratio"] for m in r["modes"]])), "×")]
    if "ceiling" not in r:
        return figures
    c = r["ceiling"]
    for th in THRESHOLDS:
        bound = f" (at least: all {c['computed']} computed)" if c["above_is_lower_bound"][f"{th}"] else ""
        figures.append(figure(f"{name} {scenario}: eigenvalues of T above {th}{bound}", c["above"][f"{th}"],
                              "eigenvalues"))
    base = c["pcg"][0]
    for row in c["pcg"][1:]:
        if row["k"] in (8, 64, 256):
            figures.append(figure(f"{name} {scenario}: PCG iterations for 1e-6, {row['k']} slowest exact eigenvectors "
                                  "deflated (rest-pose error)", row["deflated_rest"], "iterations", "A⁻¹ alone",
                                  base["deflated_rest"]))
    for coarsen_by in sorted({s["coarsen"] for s in r["spaces"]}, reverse=True):
        same = [s for s in r["spaces"] if s["coarsen"] == coarsen_by and s.get("equal_size", True)]
        best = min(same, key=lambda s: s["two_level_factor"])
        figures.append(figure(f"{name} {scenario}: best two-level factor, {best['columns']} columns (3n/{coarsen_by}): "
                              f"{best['space']}", best["two_level_factor"], "×", "L-BFGS per iteration",
                              r["lbfgs_rate"]))
        fewest = min(same, key=lambda s: s["pcg_iterations_rest"])
        figures.append(figure(f"{name} {scenario}: PCG iterations for 1e-6, A⁻¹ + best coarse space of "
                              f"{fewest['columns']} columns (3n/{coarsen_by}): {fewest['space']}",
                              fewest["pcg_iterations_rest"], "iterations", "A⁻¹ alone", base["deflated_rest"]))
    return figures


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", type=int, default=8, help="slow modes per scenario (default: 8)")
    parser.add_argument("--coarsen", type=int, default=20, help="fine vertices per coarse centre (default: 20)")
    parser.add_argument("--quick", action="store_true", help="the built-in cactus only")
    parser.add_argument("--meshes", nargs="+", default=None, metavar="NAME",
                        help="only these meshes (cactus, camelhead.off, armadillo.obj)")
    parser.add_argument("--ceiling", action="store_true",
                        help="assemble H, count the eigenvalues of T above 0.98/0.95/0.90, run conjugate gradients "
                        "with the slowest exact eigenvectors deflated, and compare coarse spaces at equal size")
    parser.add_argument("--ceiling-modes", type=int, default=256,
                        help="slowest eigenvalues computed for the ceiling (default: 256)")
    parser.add_argument("--space-coarsen", type=int, nargs="+", default=[20, 5],
                        help="coarse spaces compared with 3 n / this many columns, one comparison per value "
                        "(default: 20 5)")
    parser.add_argument("--no-amg", action="store_true", help="skip smoothed aggregation (pyamg)")
    add_json_option(parser, "bench_slow_modes")
    args = parser.parse_args(argv)
    scenarios = [s for s in SCENARIOS if "." not in s[0]] if args.quick else \
        [s for s in SCENARIOS if "." not in s[0] or (MESHES / s[0]).exists()]
    if args.meshes:
        scenarios = [s for s in scenarios if s[0] in args.meshes]
    rows, figures = [], []
    for name, scenario in scenarios:
        r = run(name, scenario, args.modes, args.coarsen, args)
        rows.append(r)
        print(f"\n{name} {scenario} ({r['n']:,} vertices): L-BFGS {r['lbfgs_iterations']} iterations, rate "
              f"{r['lbfgs_rate']:.3f}/iteration; kappa {r['kappa']:.0f}, CG bound {r['cg_iterations_1e-8']:.0f} "
              f"iterations for 1e-8; two-level factor per cycle {r['two_level_factor']:.2f} "
              f"({r['hessian_products']} Hessian products, {r['eigen_seconds']:.0f} s)")
        print("  eigenvalue  share  rigid-res  locking")
        for m in r["modes"]:
            print(f"  {m['eigenvalue']:.4f}    {m['share']:.3f}  {m['rigid_residual']:.3f}      "
                  f"{m['locking_ratio']:.0f}")
        figures += figures_of(r)
    if args.json:
        write_results(args.json, "bench_slow_modes", figures, rows)


if __name__ == "__main__":
    main()
