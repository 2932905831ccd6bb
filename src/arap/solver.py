"""The ARAP solver: precompute (factorise) once per constraint set, then alternate local and global steps."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from arap.cells import ENERGY_TYPES, build_cells, build_rhs_gather, system_matrix
from arap.covariance import assemble_rhs, covariances, local_step
from arap.errors import ConstraintError, UnconstrainedRegionError
from arap.indexing import check_index_array, find_unconstrained_part
from arap.linsolve import NotPositiveDefiniteError, factorize
from arap.mesh import check_mesh
from arap.topology import locality_order, vertex_adjacency
from arap.weights import WEIGHT_TYPES

IterationCallback = Callable[[int, float], "bool | None"]


@dataclass
class ArapResult:
    """Outcome of :meth:`ArapSolver.solve`.

    Attributes
    ----------
    vertices : (n, 3) float64 array
        Deformed positions; constrained vertices are exactly at their targets.
    energies : list of float
        ARAP energy (with optimal rotations) after each iteration.
    iterations : int
        Iterations run.
    converged : bool
        True if the relative energy change fell to ``tolerance`` before ``max_iterations``.
    timings : dict of str to float
        Seconds spent, summed over iterations: ``local`` (covariances, rotations, energy), ``rhs``, ``solve``, and
        ``total`` for the whole call.
    """

    vertices: np.ndarray
    energies: list[float]
    iterations: int
    converged: bool
    timings: dict[str, float] = field(default_factory=dict)


class ArapSolver:
    """As-Rigid-As-Possible surface deformation (Sorkine & Alexa 2007).

    Construction validates the mesh and the constraint set, builds the cells and factorises the reduced global-step
    matrix once (Cholesky); every :meth:`solve` then only back-substitutes.

    Parameters
    ----------
    V : (n, 3) float array
        Rest positions.
    F : (m, 3) int array
        Triangles. Degenerate faces are rejected (see :func:`arap.repair_mesh`).
    constrained : (k,) int array
        Constrained vertices (anchors and handles, any order, unique). :meth:`solve` takes their targets in this order.
    energy : {"spokes", "spokes_and_rims"}
        ``spokes``: the paper's one-ring cells (Sorkine & Alexa 2007). ``spokes_and_rims``: cells over all edges of
        the triangles around a vertex (Chao et al. 2010).
    weights : {"cotangent", "uniform"}
        ``cotangent``: ``w_ij = ½(cot α_ij + cot β_ij)``, one term on boundary edges (Pinkall & Polthier 1993).
        ``uniform``: ½ per incident triangle (1 on interior edges).
    roi : (r,) int array or None
        Region of interest. Only ROI vertices move; every other vertex is held at its rest position and the linear
        system has the size of the free ROI vertices. None means the whole mesh.
    backend : str or None
        Sparse Cholesky backend (see :mod:`arap.linsolve`); None chooses by system size
        (:func:`arap.linsolve.default_backend`).

    Notes
    -----
    Vertices used by no face carry no energy; they are held at their rest position.

    Raises
    ------
    MeshError
        Malformed mesh (shapes, non-finite coordinates, bad or degenerate faces).
    ConstraintError
        Out-of-range or duplicate indices.
    UnconstrainedRegionError
        A connected part of the free vertices touches no constrained or held vertex (its system is singular).
    """

    def __init__(
        self,
        V: np.ndarray,
        F: np.ndarray,
        constrained: np.ndarray | list[int],
        energy: str = "spokes",
        weights: str = "cotangent",
        roi: np.ndarray | list[int] | None = None,
        backend: str | None = None,
    ) -> None:
        t0 = time.perf_counter()
        if energy not in ENERGY_TYPES:
            raise ValueError(f"unknown energy {energy!r}; expected one of {ENERGY_TYPES}")
        if weights not in WEIGHT_TYPES:
            raise ValueError(f"unknown weights {weights!r}; expected one of {WEIGHT_TYPES}")
        V, F = check_mesh(V, F)
        n = len(V)
        self.V = V
        self.F = F
        self.energy_type = energy
        self.weight_type = weights
        self.constrained = check_index_array(constrained, n, "constrained")
        self.roi = None if roi is None else check_index_array(roi, n, "roi")

        fixed_mask = np.zeros(n, dtype=bool)
        fixed_mask[self.constrained] = True
        referenced = np.zeros(n, dtype=bool)
        referenced[F.ravel()] = True
        held_mask = ~referenced & ~fixed_mask
        if self.roi is not None:
            in_roi = np.zeros(n, dtype=bool)
            in_roi[self.roi] = True
            held_mask |= ~in_roi & ~fixed_mask
        self.held = np.flatnonzero(held_mask)
        self.free = np.flatnonzero(~fixed_mask & ~held_mask)
        self.nonfree = np.flatnonzero(fixed_mask | held_mask)
        adjacency = vertex_adjacency(F, n)
        part = find_unconstrained_part(F, n, self.free, adjacency)
        if part is not None:
            sample, size = part
            where = "" if self.roi is None else " (region of interest)"
            raise UnconstrainedRegionError(
                f"a connected part of {size} free vertices{where} touches no constrained vertex, so its position is "
                f"undetermined (e.g. vertices {sample}); add an anchor or handle there"
                + ("" if self.roi is None else " or shrink the region of interest"),
                vertices=sample, size=size,
            )

        # Internally vertices are renumbered for memory locality (reverse Cuthill-McKee): neighbours get nearby
        # indices, so the gathers of the local step and the right-hand side stay in cache.
        self._perm = locality_order(F, n, adjacency)
        self._inv = np.empty_like(self._perm)
        self._inv[self._perm] = np.arange(n)
        self._V = np.ascontiguousarray(V[self._perm])
        self._constrained = self._inv[self.constrained]
        self._free = np.sort(self._inv[self.free])
        self._nonfree = np.sort(self._inv[self.nonfree])
        self._constrained_slot = np.searchsorted(self._nonfree, self._constrained)
        self._cells = build_cells(self._V, self._inv[F], energy, weights)
        L = system_matrix(self._cells, n)
        L_f = L[self._free]
        self._L_fn = L_f[:, self._nonfree].tocsr()
        L_ff = L_f[:, self._free]
        self._gather = build_rhs_gather(self._cells, self._free, n)
        self._active = np.flatnonzero(np.bincount(self._gather.cell, minlength=n))
        self._prepare_constant_energy(n)
        self.factor = None
        if len(self.free):
            try:
                self.factor = factorize(L_ff, backend)
            except NotPositiveDefiniteError as exc:
                raise ConstraintError(
                    "the reduced ARAP system is singular: some free vertices are connected to the constraints only "
                    f"through zero-weight edges ({exc})"
                ) from exc
        self.backend = None if self.factor is None else self.factor.backend
        self._R = np.tile(np.eye(3), (n, 1, 1))
        self._E = np.zeros(n)
        self._last: np.ndarray | None = None
        self._rotations_fresh = False
        self.factor_seconds = time.perf_counter() - t0

    # ------------------------------------------------------------------ set-up helpers
    def _prepare_constant_energy(self, n: int) -> None:
        """Cells outside the active set only see non-free vertices: their energy is constant during a solve."""
        is_active = np.zeros(n, dtype=bool)
        is_active[self._active] = True
        tcell = self._cells.cell_of_term()
        self._inactive_terms = np.flatnonzero(~is_active[tcell])
        self._inactive_term_cell = tcell[self._inactive_terms]
        self._inactive_a = self._cells.a[self._inactive_terms]
        self._inactive_b = self._cells.b[self._inactive_terms]
        self._R_scratch = np.empty((n, 3, 3))
        self._E_scratch = np.zeros(n)
        rest_E = np.zeros(n)
        inactive = np.flatnonzero(~is_active)
        if len(inactive):
            local_step(self._cells, inactive, self._V, np.empty((n, 3, 3)), rest_E)
        self._rest_E = rest_E
        self._rest_inactive_sum = float(rest_E[inactive].sum())

    def _constant_energy(self, U: np.ndarray, targets: np.ndarray) -> float:
        """Energy of the inactive cells, whose terms see only non-free vertices (``U`` holds them in place).

        Only cells touching a constrained vertex away from its rest position differ from their rest energy.
        """
        if not len(self._inactive_terms):
            return 0.0
        n = len(self._V)
        moved = np.zeros(n, dtype=bool)
        moved[self._constrained] = np.any(targets != self._V[self._constrained], axis=1)
        touched = np.unique(self._inactive_term_cell[moved[self._inactive_a] | moved[self._inactive_b]])
        if not len(touched):
            return self._rest_inactive_sum
        E = self._E_scratch
        local_step(self._cells, touched, U, self._R_scratch, E)
        return self._rest_inactive_sum - float(self._rest_E[touched].sum()) + float(E[touched].sum())

    def _fixed_positions(self, targets: np.ndarray) -> np.ndarray:
        """Positions of the non-free vertices (constrained at targets, held at rest), in ``nonfree`` order."""
        fixed = self._V[self._nonfree]
        fixed[self._constrained_slot] = targets
        return fixed

    def _to_internal(self, X: np.ndarray) -> np.ndarray:
        """Rows of a per-vertex array in the solver's internal vertex order."""
        return np.ascontiguousarray(X[self._perm])

    def _check_positions(self, U: np.ndarray, name: str) -> np.ndarray:
        U = np.asarray(U, dtype=np.float64)
        n = self.n_vertices
        if U.shape != (n, 3):
            raise ValueError(f"{name} must have shape ({n}, 3), got {U.shape}")
        if not np.all(np.isfinite(U)):
            raise ValueError(f"{name} has non-finite coordinates")
        return U

    def _check_targets(self, targets: np.ndarray | list) -> np.ndarray:
        T = np.asarray(targets, dtype=np.float64)
        k = len(self._constrained)
        if T.shape != (k, 3):
            raise ConstraintError(f"targets must have shape ({k}, 3), one row per constrained vertex; got {T.shape}")
        if not np.all(np.isfinite(T)):
            bad = int(np.flatnonzero(~np.all(np.isfinite(T), axis=1))[0])
            raise ConstraintError(f"targets must be finite; row {bad} is {T[bad].tolist()}")
        return T

    # ------------------------------------------------------------------ solving
    @property
    def n_vertices(self) -> int:
        return len(self._V)

    @property
    def n_free(self) -> int:
        return len(self._free)

    def solve(
        self,
        targets: np.ndarray | list,
        initial: np.ndarray | None = None,
        max_iterations: int = 10,
        tolerance: float = 0.0,
        callback: IterationCallback | None = None,
    ) -> ArapResult:
        """Deform the mesh so the constrained vertices reach their targets.

        Parameters
        ----------
        targets : (k, 3) float array
            Target of each constrained vertex, in the order of ``constrained``.
        initial : (n, 3) float array or None
            Initial guess. None: the previous solution of this solver, or the rest pose the first time.
        max_iterations : int
            Cap on local/global iterations (≥ 0).
        tolerance : float
            Stop when ``|E_{k-1} − E_k| ≤ tolerance · |E_{k-1}|``. 0 runs all iterations.
        callback : callable or None
            ``callback(iteration, energy)`` after each iteration (1-based); returning False stops early.

        Returns
        -------
        ArapResult
        """
        t_start = time.perf_counter()
        T = self._check_targets(targets)
        if int(max_iterations) != max_iterations or max_iterations < 0:
            raise ValueError(f"max_iterations must be a non-negative integer, got {max_iterations!r}")
        if not tolerance >= 0:
            raise ValueError(f"tolerance must be >= 0, got {tolerance!r}")
        use_cache = initial is None and self._last is not None and self._rotations_fresh
        if initial is None:
            U = self._V.copy() if self._last is None else self._last.copy()
        else:
            U = self._to_internal(self._check_positions(initial, "initial"))
        fixed = self._fixed_positions(T)
        timings = {"local": 0.0, "rhs": 0.0, "solve": 0.0}
        active = self._active
        prev: float | None = None
        if not use_cache:
            t = time.perf_counter()
            local_step(self._cells, active, U, self._R, self._E)
            timings["local"] += time.perf_counter() - t
        at_targets = np.array_equal(U[self._nonfree], fixed)
        U[self._nonfree] = fixed
        const_E = self._constant_energy(U, T)
        if at_targets:
            prev = float(self._E[active].sum()) + const_E
        rhs_const = self._L_fn @ fixed
        rhs = np.empty((len(self._free), 3))
        energies: list[float] = []
        converged = False
        for it in range(int(max_iterations)):
            if self.factor is not None:
                t = time.perf_counter()
                assemble_rhs(self._gather, self._R, rhs_const, rhs)
                t2 = time.perf_counter()
                U[self._free] = self.factor.solve(rhs)
                t3 = time.perf_counter()
                timings["rhs"] += t2 - t
                timings["solve"] += t3 - t2
            t = time.perf_counter()
            local_step(self._cells, active, U, self._R, self._E)
            timings["local"] += time.perf_counter() - t
            e = float(self._E[active].sum()) + const_E
            energies.append(e)
            stop = callback is not None and callback(it + 1, e) is False
            if prev is not None and abs(prev - e) <= tolerance * max(abs(prev), 1e-300):
                converged = True
            prev = e
            if converged or stop:
                break
        self._last = U
        # The rotations fit the stored solution only if an iteration ended with a local step on it.
        self._rotations_fresh = bool(energies)
        timings["total"] = time.perf_counter() - t_start
        return ArapResult(vertices=U[self._inv], energies=energies, iterations=len(energies), converged=converged,
                          timings=timings)

    def reset(self) -> None:
        """Forget the previous solution: the next :meth:`solve` without ``initial`` starts from the rest pose."""
        self._last = None
        self._rotations_fresh = False

    # ------------------------------------------------------------------ single steps (for analysis and tests)
    def fit_rotations(self, U: np.ndarray) -> np.ndarray:
        """Local step alone: the optimal rotation of every cell for positions ``U``, shape (n, 3, 3)."""
        U = self._to_internal(self._check_positions(U, "U"))
        R = np.empty((self.n_vertices, 3, 3))
        local_step(self._cells, np.arange(self.n_vertices), U, R, np.empty(self.n_vertices))
        return R[self._inv]

    def energy(self, U: np.ndarray, R: np.ndarray | None = None) -> float:
        """Energy of positions ``U`` with rotations ``R`` (None: the optimal ones), summed over all cells."""
        U = self._to_internal(self._check_positions(U, "U"))
        if R is None:
            E = np.empty(self.n_vertices)
            local_step(self._cells, np.arange(self.n_vertices), U, np.empty((self.n_vertices, 3, 3)), E)
            return float(E.sum())
        d = U[self._cells.a] - U[self._cells.b]
        cur = float(np.dot(self._cells.w, np.einsum("ij,ij->i", d, d)))
        S = covariances(self._cells, U)
        R = self._to_internal(np.asarray(R, dtype=np.float64))
        return cur + float(self._cells.rest_sq.sum()) - 2.0 * float(np.einsum("cij,cji->", R, S))

    def global_step(self, R: np.ndarray, targets: np.ndarray | list) -> np.ndarray:
        """Global step alone: positions minimising the energy for fixed rotations ``R`` (n, 3, 3), shape (n, 3)."""
        T = self._check_targets(targets)
        fixed = self._fixed_positions(T)
        U = self._V.copy()
        U[self._nonfree] = fixed
        if self.factor is not None:
            rhs = np.empty((len(self._free), 3))
            assemble_rhs(self._gather, self._to_internal(np.asarray(R, dtype=np.float64)), self._L_fn @ fixed, rhs)
            U[self._free] = self.factor.solve(rhs)
        return U[self._inv]

    @property
    def system_size(self) -> int:
        """Number of unknown vertices in the linear system (free ROI vertices)."""
        return len(self._free)

    def reduced_matrix(self) -> sp.csr_matrix:
        """The reduced global-step matrix ``L_ff`` (for inspection; rows in the solver's internal vertex order)."""
        L = system_matrix(self._cells, self.n_vertices)
        return L[self._free][:, self._free].tocsr()
