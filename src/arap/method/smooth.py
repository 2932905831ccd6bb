"""Smooth-rotation ARAP (SR-ARAP; Levi & Gotsman 2015, "Smooth Rotation Enhanced As-Rigid-As-Possible Mesh
Animation").

The energy adds to the spokes energy a term that makes neighbouring rotations agree::

    E = Σ_i Σ_j w_ij ‖e'_ij − R_i e_ij‖²  +  α A Σ_i Σ_j w⁺_ij ‖R_i − R_j‖²_F

with ``A`` the surface area (so that ``α`` is scale-free: both terms scale with the square of the mesh size) and
``w⁺_ij = max(w_ij, 0)``: with a negative cotangent weight the rotation term would reward neighbours for
disagreeing, so it uses the clamped weights. ``α = 0`` is the spokes energy. A painted stiffness (per-cell weights)
scales the spokes term only; the rotation term keeps the symmetric weights ``w⁺_ij``.

Scaling of α. CGAL's ``SRE_ARAP`` (default α = 0.02) adds ``α A R_jᵀ / deg_i`` to cell ``i``'s covariance for every
neighbour ``j`` (``A`` the total surface area, ``deg_i`` the valence, no cotangent weight, no factor 2). Here the
term is the paper's, with cotangent weights, and its exact minimiser adds ``2αA w⁺_ij R_jᵀ``: at the same α it
couples neighbours about ``2 w⁺_ij deg_i`` ≈ 7 times as strongly as CGAL does (``w⁺ ≈ 0.58`` on equilateral
triangles, valence 6). In both, the rotation term grows against the spokes term with the number of vertices (the
spokes term of a cell scales with its own area, ``A`` with the whole surface's), so on dense scans the default
couples rotations strongly and the sweeps settle slowly.

Local step. With the positions and the other rotations fixed, the terms that hold ``R_i`` are
``−2 tr(R_i S_i) − 4αA Σ_j w⁺_ij ⟨R_i, R_j⟩`` (plus constants; each pair appears in both cells' sums), so the best
``R_i`` is the rotation fit of ``M_i = S_i + 2αA Σ_j w⁺_ij R_jᵀ``. Neighbouring rotations depend on each other, so
the vertices are coloured (no two neighbours share a colour) and the colours are updated one after the other, each
from the current rotations of the others: block-coordinate descent, exact per block, so the energy never rises.
The sweep goes window by window (:data:`arap.method.colouring.WINDOW` consecutive cells; the solver numbers the vertices
so that each colour's cells in a window are consecutive) so that it stays in cache; windows that share no edge run
in parallel, and the result does not depend on the thread count. The global step is the spokes one (the rotation
term does not involve positions).

Sweeps alone converge slowly: a sweep moves each rotation towards its neighbours' only, so a change spreads across
the mesh like a diffusion. The solver's local step therefore takes a preconditioned step on all rotations at once
(:mod:`arap.method.rotation_step`, a Laplacian of the rotation term factorised once) that never raises the energy
either: see :data:`STEPS`.

Cost. ``S_i`` depends on the positions only: :meth:`SmoothRotations.relax` computes the covariances (and the
constants of the data energy) once per local step, in a parallel pass, and stores them by sweep position; each
sweep then reads them back, adds ``2αA Σ_j w⁺_ij R_jᵀ`` (the coupled neighbours listed in sweep order) and refits
the rotations in SIMD blocks (:func:`arap.method.rotations.rotations_block`). The data energy of a cell follows from
``tr(R_i S_i)``; the rotation term needs the final rotations of both ends of a pair, so only the last sweep sums
it, counting a pair when its later endpoint is updated. On the armadillo one sweep costs about a spokes local step
(before, when every sweep recomputed the covariances and summed the rotation term, about four).

Start. A cold start does not sweep from each cell's own best rotation (:meth:`SmoothRotations.start`).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.kernels.parallel import policy
from arap.meshes._geometry import best_rigid_transform
from arap.method.cells import Cells
from arap.method.colouring import WINDOW, colour_vertices
from arap.method.local_step import CHUNK, cell_covariance
from arap.method.rotation_step import ZERO9, RotationStep, add_transposed, plus_scaled, rotation_gap, trace_with
from arap.method.rotations import BLOCK, SCRATCH_ROWS, put_covariance, rotations_block, take_rotation

__all__ = ["STEPS", "SWEEPS", "SmoothRotations"]

STEPS = 1
"""Preconditioned rotation steps (:class:`arap.method.rotation_step.RotationStep`) in one local step of the solver. A
step moves all rotations at once towards the minimum of the coupled rotation energy, where a sweep moves each towards
its neighbours' only; at the default ``alpha`` the rotation term outweighs the spokes term by far on dense meshes, so
with sweeps alone the coupled rotations were the slow part of a solve (it did not converge on the denser scans). One
step per local step converges everywhere; a second halves the iterations but not the time
(``benchmarks/bench_energies.py`` measures the three energies to convergence)."""

SWEEPS = 0
"""Block-coordinate sweeps in one local step of the solver, after its :data:`STEPS` (measured: one more sweep made an
iteration dearer without reducing the iterations). Without a step (``alpha = 0``, nothing coupled) a local step
sweeps once, which is then the spokes local step."""


@nb.njit(cache=True, nogil=True)
def _covariance_rows(lo, hi, order, ptr, a, b, w, we, rest_sq, U, S, d):  # pragma: no cover - compiled
    """Covariance ``S_c`` (row-major) and the constant of the data energy ``Σ w ‖e'‖² + Σ w ‖e‖²`` of the cells at
    sweep positions ``lo:hi``, stored by position."""
    for p in range(lo, hi):
        c = np.uint64(order[p])  # unsigned indices spare numba's negative-index fix-ups
        cov, cur = cell_covariance(c, ptr, a, b, w, we, U)
        for i in range(9):
            S[p, i] = cov[i]
        d[p] = cur + rest_sq[c]


@nb.njit(cache=True, nogil=True)
def _covariances_serial(order, ptr, a, b, w, we, rest_sq, U, S, d):  # pragma: no cover - compiled
    _covariance_rows(0, order.shape[0], order, ptr, a, b, w, we, rest_sq, U, S, d)


@nb.njit(cache=True, nogil=True, parallel=True)
def _covariances_parallel(order, ptr, a, b, w, we, rest_sq, U, S, d):  # pragma: no cover - compiled
    n = order.shape[0]
    step = CHUNK * BLOCK
    for ch in nb.prange((n + step - 1) // step):
        _covariance_rows(ch * step, min(n, (ch + 1) * step), order, ptr, a, b, w, we, rest_sq, U, S, d)


@nb.njit(cache=True, nogil=True)
def _sweep_block(lo, hi, order, nptr, nmid, nidx, nq, S, d, k2, R, E, term, sc, flag,
                 energy):  # pragma: no cover - compiled
    """The cells at sweep positions ``lo:hi`` (at most BLOCK, one colour): ``R_c`` fitted to
    ``M_c = S_c + k2 Σ_j q R_jᵀ``, ``E[c]`` its data energy; with ``energy``, ``term[c]`` the rotation term of its
    pairs with the neighbours updated earlier in the sweep (``nidx[nptr[p]:nmid[p]]``). Returns the sum of both."""
    m = hi - lo
    coupled = k2 != 0.0
    for t in range(m):
        p = lo + t
        c = np.uint64(order[p])
        near = ZERO9
        if coupled:
            for k in range(np.uint64(nptr[p]), np.uint64(nptr[p + 1])):
                near = add_transposed(near, nq[k], R, np.uint64(nidx[k]))
        put_covariance(sc, t, plus_scaled(S, p, k2, near), R, c)
    rotations_block(sc, m, flag)
    total = 0.0
    for t in range(m):
        p = lo + t
        c = np.uint64(order[p])
        take_rotation(sc, t, R, c)
        # tr(R S), plain covariance: the data energy is Σ w ‖e'‖² + Σ w ‖e‖² − 2 tr(R S)
        e = d[p] - 2.0 * trace_with(R, c, S, p)
        E[c] = e
        total += e
        if energy:
            pairs = 0.0
            if coupled:
                for k in range(np.uint64(nptr[p]), np.uint64(nmid[p])):  # final neighbours: the pair's both ends
                    pairs += nq[k] * rotation_gap(R, c, np.uint64(nidx[k]))
            term[c] = k2 * pairs
            total += k2 * pairs
    return total


@nb.njit(cache=True, nogil=True)
def _sweep_window(wi, win_ptr, run_ptr, order, nptr, nmid, nidx, nq, S, d, k2, R, E, term,
                  energy):  # pragma: no cover - compiled
    """The runs of one window, one after the other, each in blocks of BLOCK cells."""
    sc = np.empty(SCRATCH_ROWS * BLOCK)
    flag = np.empty(BLOCK, np.int64)
    total = 0.0
    for r in range(win_ptr[wi], win_ptr[wi + 1]):
        for lo in range(run_ptr[r], run_ptr[r + 1], BLOCK):
            total += _sweep_block(lo, min(run_ptr[r + 1], lo + BLOCK), order, nptr, nmid, nidx, nq, S, d, k2, R,
                                  E, term, sc, flag, energy)
    return total


@nb.njit(cache=True, nogil=True)
def _sweep_serial(group_ptr, win_ptr, run_ptr, order, nptr, nmid, nidx, nq, S, d, k2, R, E, term,
                  energy):  # pragma: no cover - compiled
    """One sweep: the windows group by group (see :class:`SmoothRotations`)."""
    total = 0.0
    for wi in range(group_ptr[group_ptr.shape[0] - 1]):
        total += _sweep_window(wi, win_ptr, run_ptr, order, nptr, nmid, nidx, nq, S, d, k2, R, E, term, energy)
    return total


@nb.njit(cache=True, nogil=True, parallel=True)
def _sweep_parallel(group_ptr, win_ptr, run_ptr, order, nptr, nmid, nidx, nq, S, d, k2, R, E, term,
                    energy):  # pragma: no cover - compiled
    total = 0.0
    for g in range(group_ptr.shape[0] - 1):  # windows of one group share no edge: they run at once
        lo = group_ptr[g]
        part = np.empty(group_ptr[g + 1] - lo)
        for i in nb.prange(group_ptr[g + 1] - lo):
            part[i] = _sweep_window(lo + i, win_ptr, run_ptr, order, nptr, nmid, nidx, nq, S, d, k2, R, E, term,
                                    energy)
        for i in range(part.shape[0]):
            total += part[i]
    return total


@nb.njit(cache=True, nogil=True)
def _rotation_term_rows(lo, hi, ptr, b, q, coef, R, out):  # pragma: no cover - compiled
    total = 0.0
    for c in range(lo, hi):
        e = 0.0
        for k in range(ptr[c], ptr[c + 1]):
            if q[k] != 0.0:
                e += q[k] * rotation_gap(R, c, b[k])
        out[c] = coef * e
        total += coef * e
    return total


@nb.njit(cache=True, nogil=True)
def _rotation_term_serial(ptr, b, q, coef, R, out):  # pragma: no cover - compiled
    """``out[c] = coef Σ_j q ‖R_c − R_j‖²`` for every cell; returns the sum (chunk by chunk, as the parallel kernel
    sums it, so that the thread count does not change it)."""
    n = ptr.shape[0] - 1
    step = CHUNK * BLOCK
    total = 0.0
    for ch in range((n + step - 1) // step):
        total += _rotation_term_rows(ch * step, min(n, (ch + 1) * step), ptr, b, q, coef, R, out)
    return total


@nb.njit(cache=True, nogil=True, parallel=True)
def _rotation_term_parallel(ptr, b, q, coef, R, out):  # pragma: no cover - compiled
    n = ptr.shape[0] - 1
    step = CHUNK * BLOCK
    n_chunks = (n + step - 1) // step
    part = np.empty(n_chunks)
    for ch in nb.prange(n_chunks):
        part[ch] = _rotation_term_rows(ch * step, min(n, (ch + 1) * step), ptr, b, q, coef, R, out)
    total = 0.0
    for ch in range(n_chunks):
        total += part[ch]
    return total



class SmoothRotations:
    """The SR-ARAP local step over spoke cells.

    Parameters
    ----------
    cells : Cells
        Spoke cells (cell ``i`` holds the terms ``(i, j, w_ij)``).
    area : float
        Surface area ``A``.
    alpha : float
        Weight of the rotation term, ``≥ 0``.
    weights : (t,) float array, optional
        Weight of each term's pair in the rotation term, aligned with ``cells.w``; must be symmetric (the weight of
        ``(i, j)`` equals that of ``(j, i)``). Default ``max(cells.w, 0)`` (cells whose terms were scaled by a
        per-cell stiffness would not be symmetric: pass the unscaled clamped weights).
    colour : (n,) int array, optional
        A colouring of the cells' graph (see :func:`colour_order`); default a greedy one.
    """

    def __init__(self, cells: Cells, area: float, alpha: float, weights: NDArray[np.float64] | None = None,
                 colour: NDArray[np.int64] | None = None) -> None:
        self.cells = cells
        self.coef = float(alpha) * float(area)
        q = np.maximum(cells.w, 0.0) if weights is None else np.asarray(weights, dtype=np.float64)
        self.q = np.ascontiguousarray(q)
        n = len(cells.ptr) - 1
        if colour is None:
            colour = colour_vertices(cells.ptr, cells.b)
        rows = cells.cell_of_term()
        # Windows of WINDOW consecutive cells (the solver numbers vertices for locality), coloured so that two
        # windows of one group share no edge; within a window, one run per vertex colour.
        window = np.arange(n, dtype=np.int64) // WINDOW
        n_win = int(window[-1]) + 1 if n else 0
        cross = window[rows] != window[cells.b]
        wgraph = sp.coo_matrix((np.ones(int(cross.sum())), (window[rows[cross]], window[cells.b[cross]])),
                               shape=(n_win, n_win)).tocsr()
        group = colour_vertices(wgraph.indptr.astype(np.int64), wgraph.indices)
        order = np.lexsort((colour, window, group[window])).astype(np.int64)
        key = (group[window] * (n_win + 1) + window) * (int(colour.max(initial=0)) + 1) + colour
        starts = np.flatnonzero(np.r_[True, key[order][1:] != key[order][:-1]]) if n else np.zeros(0, np.int64)
        self._run_ptr = np.r_[starts, n].astype(np.int64)
        run_window = window[order[starts]]
        wstarts = np.flatnonzero(np.r_[True, run_window[1:] != run_window[:-1]]) if n else np.zeros(0, np.int64)
        self._win_ptr = np.r_[wstarts, len(starts)].astype(np.int64)
        win_group = group[run_window[wstarts]]
        self._group_ptr = np.searchsorted(win_group, np.arange(int(win_group.max(initial=-1)) + 2)).astype(np.int64)
        self._order = order
        # rank: when a cell is updated in a sweep (its run's place); neighbours never share a run
        self.rank = np.empty(n, np.int64)
        self.rank[order] = np.repeat(np.arange(len(starts)), np.diff(self._run_ptr))
        self._b = cells.b.astype(np.int64)
        # Each position's coupled neighbours (q != 0), those updated earlier in the sweep first, laid out in sweep
        # order: a sweep reads them front to back.
        pos = np.empty(n, np.int64)
        pos[order] = np.arange(n)
        coupled = np.flatnonzero(self.q != 0.0)
        owner = pos[rows[coupled]]
        early = self.rank[cells.b[coupled]] < self.rank[rows[coupled]]
        by = np.lexsort((~early, owner))
        self._nidx = np.ascontiguousarray(cells.b[coupled][by], dtype=np.int64)
        self._nq = np.ascontiguousarray(self.q[coupled][by])
        self._nptr = np.r_[0, np.cumsum(np.bincount(owner, minlength=n))].astype(np.int64)
        self._nmid = self._nptr[:-1] + np.bincount(owner[early], minlength=n).astype(np.int64)
        # covariances and data-energy constants of the current positions, by sweep position
        self._S = np.empty((n, 9))
        self._d = np.empty(n)
        self._step = (RotationStep(cells, self.q, self.coef, order, self._nptr, self._nidx, self._nq)
                      if self.coef > 0 and n else None)

    def start(self, V: NDArray[np.float64], U: NDArray[np.float64], weights: NDArray[np.float64],
              R: NDArray[np.float64]) -> None:
        """Rotations to start the sweeps from at new positions ``U`` (a cold start): every cell gets the rotation
        that best maps the rest shape onto ``U`` as a whole (weighted Procrustes), a field without defects.

        Each cell's own best rotation would be the obvious start, but near a moved handle those disagree wildly, and
        the strongly coupled sweeps then settle into a state of far higher energy: from the rest pose with one
        vertex pulled, 4.3 against 0.067 on the camel head and 29 against 0.49 on a 20k-vertex scan
        (:func:`arap.meshes.shapes.scan_blob`) after 400 iterations; from this start a rigid motion of all constraints
        is exact after one iteration.

        Parameters
        ----------
        V : (n, 3) float array
            Rest positions.
        U : (n, 3) float array
            Start positions.
        weights : (n,) float array
            Weight of each vertex (e.g. its area).
        R : (n, 3, 3) float array
            Out: the start rotations.
        """
        R[:] = best_rigid_transform(V, U, weights)[0]

    def local_step(self, U: NDArray[np.float64], R: NDArray[np.float64], E: NDArray[np.float64],
                   term: NDArray[np.float64]) -> float:
        """One sweep over the colours, in place (:meth:`relax` with ``sweeps=1``).

        Parameters
        ----------
        U : (n, 3) float array
        R : (n, 3, 3) float array
            In: current rotations. Out: each block's best rotations given the others.
        E : (n,) float array
            Out: each cell's data energy ``Σ_j w_ij ‖e'_ij − R_i e_ij‖²``.
        term : (n,) float array
            Out: the rotation term ``αA (w⁺_ij + w⁺_ji) ‖R_i − R_j‖²`` of each pair, counted at the endpoint
            updated later in the sweep (so ``term.sum()`` is the rotation term; :meth:`rotation_term` gives each
            cell its own sum ``αA Σ_j w⁺_ij ‖R_i − R_j‖²``).

        Returns
        -------
        float
            The energy: data plus rotation terms, over all cells.
        """
        return self.relax(U, R, E, term, 1)

    def relax(self, U: NDArray[np.float64], R: NDArray[np.float64], E: NDArray[np.float64],
              term: NDArray[np.float64], sweeps: int, gain: float | None = None, steps: int = 0) -> float:
        """``steps`` preconditioned steps, then up to ``sweeps`` sweeps over the colours at positions ``U``, in place;
        the covariances are computed once.

        Parameters
        ----------
        U, R, E, term
            As in :meth:`local_step`; ``E`` and ``term`` describe the rotations after the last sweep.
        sweeps : int
            Most sweeps after the steps (at least 1 when no step is taken).
        gain : float or None
            None: exactly ``sweeps`` sweeps, and only the last evaluates the rotation term. Else sweep again while
            the last sweep lowered the energy by more than this fraction of it (every sweep evaluates it).
        steps : int
            Preconditioned steps on the rotations (:class:`arap.method.rotation_step.RotationStep`) before the sweeps;
            none when nothing is coupled (``alpha = 0``). After a step without a sweep, ``term[c]`` is each cell's own
            rotation term ``αA Σ_j w⁺_ij ‖R_c − R_j‖²`` (the sum is the same).

        Returns
        -------
        float
            The energy after the last sweep: data plus rotation terms, over all cells.
        """
        c = self.cells
        cov = (self._order, c.ptr, c.a, c.b, c.w, c.we, c.rest_sq, U, self._S, self._d)
        policy.run("smooth_covariance", len(c.a), lambda: _covariances_serial(*cov),
                   lambda: _covariances_parallel(*cov))
        e = 0.0
        stepped = self._step is not None and steps > 0
        sweeps = int(sweeps) if stepped else max(int(sweeps), 1)
        if self._step is not None:
            for _ in range(int(steps)):
                e = self._step.step(self._S, self._d, R, E, term)
                if not self._step.moved:
                    # Far from the minimum (a handle pulled many times the mesh's size) every length of the step
                    # can raise the energy: a sweep, exact for each colour, still lowers it. Without it the
                    # rotations, and so the positions, would stop short of a stationary point.
                    sweeps = max(sweeps, 1)
                    break
        for i in range(sweeps):
            previous, e = e, self._sweep(R, E, term, gain is not None or i == sweeps - 1)
            if gain is not None and i > 0 and previous - e <= gain * abs(e):
                break
        return e

    def _sweep(self, R: NDArray[np.float64], E: NDArray[np.float64], term: NDArray[np.float64], final: bool) -> float:
        """One sweep from the stored covariances; ``final``: also evaluate the rotation term (else the returned energy
        is the data energy only)."""
        args = (self._group_ptr, self._win_ptr, self._run_ptr, self._order, self._nptr, self._nmid, self._nidx,
                self._nq, self._S, self._d, 2.0 * self.coef, R, E, term, final)
        return float(policy.run("smooth", len(self.cells.a), lambda: _sweep_serial(*args),
                                lambda: _sweep_parallel(*args)))

    def rotation_term(self, R: NDArray[np.float64], term: NDArray[np.float64]) -> float:
        """``αA Σ_i Σ_j w⁺_ij ‖R_i − R_j‖²`` per cell into ``term``; returns the total."""
        args = (self.cells.ptr, self._b, self.q, self.coef, R, term)
        return float(policy.run("rotation_term", len(self.q), lambda: _rotation_term_serial(*args),
                                lambda: _rotation_term_parallel(*args)))
