"""The ARAP solver: precompute (factorise) once per constraint set, then alternate local and global steps."""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arap._csr import SparseRowsProduct, leading_blocks
from arap.anderson import AndersonAccelerator
from arap.cells import (
    build_cells,
    build_rhs_gather,
    check_stiffness,
    scale_cells,
    singular_system_error,
    system_matrix,
)
from arap.colouring import colour_order
from arap.covariance import assemble_rhs, assemble_rhs_and_gradient, local_step
from arap.errors import ConstraintError
from arap.inactive import InactiveCells
from arap.indexing import check_index_array, internal_origin, rows_of, with_rows
from arap.kernel_cache import announce_first_compile
from arap.lbfgs import LbfgsHistory
from arap.linsolve import NotPositiveDefiniteError, background_ordering, factorize
from arap.loops import PLAIN_START, Iterate, lbfgs_iterations, plain_iterations
from arap.mesh import MeshLike, bounding_box, check_mesh, is_mesh_like, mesh_arrays
from arap.options import (
    DEFAULT_ALPHA,
    DEFAULT_ENERGY,
    DEFAULT_LBFGS_MEMORY,
    DEFAULT_TOLERANCE,
    DEFAULT_WEIGHTS,
    DEFAULT_WINDOW,
    Acceleration,
    EnergyType,
    StartName,
    WeightType,
    check_alpha,
    check_energy_and_weights,
    check_solve_options,
)
from arap.partition import check_point_targets, check_positions, check_reach, check_targets, partition_vertices
from arap.points import PointConstraints, PointSystem, check_points
from arap.result import ArapResult, IterationCallback, rounding_floor
from arap.rigid import RIGID_TOLERANCE, RigidRegions, rigid_regions
from arap.rotations import identity_rotations
from arap.smooth import STEPS, SWEEPS, SmoothRotations
from arap.solve_start import SolveStart
from arap.start import vertex_areas
from arap.steps import SingleSteps
from arap.topology import locality_order, vertex_adjacency


class ArapSolver(SolveStart, SingleSteps):
    """As-Rigid-As-Possible surface deformation (Sorkine & Alexa 2007).

    Construction validates the mesh and the constraint set, builds the cells and factorises the reduced global-step
    matrix once (Cholesky); every :meth:`solve` then only back-substitutes.

    Parameters
    ----------
    V : (n, 3) float array or MeshLike
        Rest positions, or a mesh object with ``vertices`` and ``faces`` (e.g. ``trimesh.Trimesh``; then leave out
        ``F``: ``ArapSolver(mesh, constrained)``).
    F : (m, 3) int array
        Triangles. Degenerate faces are rejected (see :func:`arap.repair_mesh`).
    constrained : (k,) int array
        Constrained vertices (anchors and handles, any order, unique). :meth:`solve` takes their targets in this order.
    energy : {"spokes_and_rims", "spokes", "smooth_rotations"}
        ``spokes_and_rims`` (default): cells over all edges of the triangles around a vertex (Chao et al. 2010); a
        sum of non-negative per-triangle terms even with obtuse triangles, so it does not fold scans.
        ``spokes``: the paper's one-ring cells (Sorkine & Alexa 2007); with negative cotangent weights its energy can
        be negative and its minima fold scans (see "Energy and weights" in docs/solver.md).
        ``smooth_rotations``: SR-ARAP (Levi & Gotsman 2015), the spokes energy plus ``α A Σ_i Σ_j w⁺_ij ‖R_i −
        R_j‖²`` that makes neighbouring rotations agree (see :mod:`arap.smooth`).
    weights : {"cotangent", "clamped", "uniform"}
        ``cotangent``: ``w_ij = ½(cot α_ij + cot β_ij)``, one term on boundary edges (Pinkall & Polthier 1993).
        ``clamped``: the cotangent weights with negative values set to 0. ``uniform``: ½ per incident triangle.
    roi : (r,) int array or None
        Region of interest. Only ROI vertices move; every other vertex is held at its rest position and the linear
        system has the size of the free ROI vertices. None means the whole mesh.
    alpha : float
        Weight of the rotation term of ``energy="smooth_rotations"`` (SR-ARAP, Levi & Gotsman 2015), relative to
        the surface area so that it does not depend on the mesh's size; 0.02 by default (CGAL's default; at the same
        value this term couples rotations about 7 times as strongly as CGAL's, see :mod:`arap.smooth`). Ignored by
        the other energies.
    points : PointConstraints, (faces, barycentric) or (faces, barycentric, weights), or None
        Handles anywhere on the surface (see :mod:`arap.points`): point ``k`` lies in triangle ``faces[k]`` at
        ``barycentric[k]`` (3 coordinates ≥ 0 summing to 1, corners in the order of ``F``); its weight is ``inf``
        (default) for a hard constraint, met exactly, or a positive weight for a soft one that pulls with that
        strength. :meth:`solve` then takes their targets as ``point_targets``. The factorisation stays once per
        constraint set.
    stiffness : (n,) array of float or None
        Per-vertex cell weights ``w_i`` of the paper's energy ``Σ_i w_i Σ_j w_ij ‖…‖²`` (Sorkine & Alexa 2007):
        1 is the plain energy (None: all 1), larger values make a vertex's cell stiffer, so a region painted stiff
        moves almost rigidly while softer parts bend; ``np.inf`` keeps a region rigid (to about 1e-8 of its size;
        see :data:`arap.cells.RIGID_STIFFNESS`). The energies reported include the weights. With the spoke energies
        (``spokes``, ``smooth_rotations``) on a mesh with obtuse triangles (negative cotangent weights), unequal
        weights can leave the energy without a minimum: that raises OptionError (``spokes_and_rims`` or
        ``weights="clamped"`` work).
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
    OptionError
        An unknown energy, weights or backend name.
    """

    def __init__(
        self,
        V: NDArray[np.floating] | MeshLike,
        F: NDArray[np.integer] | None = None,
        constrained: NDArray[np.integer] | list[int] | None = None,
        energy: EnergyType = DEFAULT_ENERGY,
        weights: WeightType = DEFAULT_WEIGHTS,
        roi: NDArray[np.integer] | list[int] | None = None,
        backend: str | None = None,
        stiffness: ArrayLike | None = None,
        alpha: float = DEFAULT_ALPHA,
        points: PointConstraints | tuple[ArrayLike, ArrayLike] | tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    ) -> None:
        t0 = time.perf_counter()
        announce_first_compile()
        check_energy_and_weights(energy, weights)
        alpha = check_alpha(alpha)
        if constrained is None and is_mesh_like(V) and F is not None:
            F, constrained = None, F  # ArapSolver(mesh, constrained)
        if constrained is None:
            raise ConstraintError("constrained (the anchor and handle vertices) is missing")
        V, F = check_mesh(*mesh_arrays(V, F))
        n = len(V)
        self.V = V
        self.F = F
        self.energy_type = energy
        self.weight_type = weights
        self.constrained = check_index_array(constrained, n, "constrained")
        self.roi = None if roi is None else check_index_array(roi, n, "roi", allow_empty=False)
        rigid: NDArray[np.bool_] | None = None
        self.stiffness: NDArray[np.float64] | None = None
        if stiffness is not None:
            self.stiffness, rigid = check_stiffness(stiffness, n)

        adjacency = vertex_adjacency(F, n)
        self.points: PointConstraints | None = None
        if points is not None:
            p = (points.faces, points.barycentric, points.weights) if isinstance(points, PointConstraints) \
                else tuple(points)
            self.points = check_points(p[0], p[1], p[2] if len(p) > 2 else None, len(F))
        self.free, self.held, self.nonfree = partition_vertices(
            F, n, self.constrained, self.roi, None if self.points is None else self.points.faces, adjacency)

        # Internally vertices are renumbered for memory locality (reverse Cuthill-McKee): neighbours get nearby
        # indices, so the gathers of the local step and the right-hand side stay in cache.
        # Free vertices come first, so that the free and the non-free rows are two contiguous blocks.
        order = locality_order(F, n, adjacency)
        colour = None
        if energy == "smooth_rotations":  # each colour's cells consecutive, window by window, for the sweep
            order, colour = colour_order(order, adjacency)
        is_free = np.zeros(n, dtype=bool)
        is_free[self.free] = True
        self._perm = np.concatenate([order[is_free[order]], order[~is_free[order]]])
        self._inv = np.empty_like(self._perm)
        self._inv[self._perm] = np.arange(n)
        # The reduced system's fill-reducing ordering needs only its pattern: it runs beside the set-up below.
        ordering = background_ordering(adjacency, self._perm, len(self.free), backend)
        self._bounds = bounding_box(V)
        self._diagonal = float(np.linalg.norm(self._bounds[1] - self._bounds[0])) or 1.0
        self._origin = internal_origin(V, self._diagonal)
        self._V = np.ascontiguousarray(V[self._perm] - self._origin)
        self._areas = vertex_areas(self._V, self._inv[F])
        self._constrained = self._inv[self.constrained]
        self._nf = len(self.free)
        self._free = np.arange(self._nf)
        self._nonfree = np.arange(self._nf, n)
        self._constrained_slot = np.searchsorted(self._nonfree, self._constrained)
        self._cells = build_cells(self._V, self._inv[F], energy, weights)
        pair_weights = np.maximum(self._cells.w, 0.0)  # the rotation term of smooth_rotations: not scaled by stiffness
        # every cell's energy a sum of non-negative terms (per triangle for spokes and rims)
        self._non_negative = energy == "spokes_and_rims" or not bool((self._cells.w < 0).any())
        if self.stiffness is not None:
            self._cells = scale_cells(self._cells, self.stiffness[self._perm])
        L = system_matrix(self._cells, n)
        L_ff, self._L_fn = leading_blocks(L, self._nf)  # free rows first: L[free][:, free], L[free][:, nonfree]
        self._coupling = SparseRowsProduct(self._L_fn)  # L_fn @ fixed, the right-hand side's constant
        self._points: PointSystem | None = None
        if self.points is not None and len(self.points) and len(self.free):
            mu = float(L_ff.diagonal().mean())
            self._points = PointSystem(self.points, self._inv[F[self.points.faces]], self._nf, n, mu)
            L_ff = (L_ff + self._points.matrix()).tocsr()
        self._A = L_ff.tocsr()  # the factored matrix: the energy's Hessian in x for fixed rotations (L-BFGS)
        self._point_state: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._gather = build_rhs_gather(self._cells, self._free, n)
        self._active = np.flatnonzero(np.bincount(self._gather.cell, minlength=n))
        self.alpha = float(alpha)
        self._smooth: SmoothRotations | None = None
        if energy == "smooth_rotations":
            # every rotation is coupled to its neighbours': all cells take part in the local step
            self._smooth = SmoothRotations(self._cells, float(self._areas.sum()), self.alpha, pair_weights,
                                           None if colour is None else colour[self._perm])
            self._active = np.arange(n)
            self._term = np.zeros(n)
        self._rigid: RigidRegions | None = None
        self._rigid_all: RigidRegions | None = None
        if rigid is not None and rigid.any():
            region = rigid_regions(self._inv[F], rigid[self._perm])
            self._rigid = RigidRegions(self._cells, region, self._active)
            self._rigid_all = RigidRegions(self._cells, region, np.arange(n))
        self._inactive = InactiveCells(self._cells, self._active, self._constrained, self._V)
        self.factor = None
        if len(self.free):
            try:
                self.factor = factorize(L_ff, backend, permutation=ordering)
                if self._points is not None:
                    self._points.prepare(self.factor.solve)
            except NotPositiveDefiniteError as exc:
                raise singular_system_error(self._cells, energy, self.stiffness, str(exc)) from exc
        self.backend = None if self.factor is None else self.factor.backend
        self._R = identity_rotations(n)
        self._E = np.zeros(n)
        self._last: NDArray[np.float64] | None = None
        self._live: NDArray[np.float64] | None = None
        self._accelerator: AndersonAccelerator | None = None
        self._history: LbfgsHistory | None = None
        self._rotations_fresh = False
        self.factor_seconds = time.perf_counter() - t0

    # ------------------------------------------------------------------ set-up helpers
    def _fixed_positions(self, targets: np.ndarray) -> np.ndarray:
        """Positions of the non-free vertices (constrained at targets, held at rest), in ``nonfree`` order."""
        return with_rows(self._V[self._nf:], self._constrained_slot, targets)

    def _to_internal(self, X: np.ndarray) -> np.ndarray:
        """Rows of a per-vertex array in the solver's internal vertex order."""
        return np.ascontiguousarray(X[self._perm])

    def _relative(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions relative to the solver's origin (``X`` itself when the origin is 0, as for most meshes)."""
        return X - self._origin if self._origin.any() else X

    def _check_positions(self, U: object, name: str) -> NDArray[np.float64]:
        """Checked positions (n, 3), relative to the solver's origin."""
        return self._relative(check_positions(U, self.n_vertices, name))

    def _check_targets(self, targets: object) -> NDArray[np.float64]:
        """Checked targets, relative to the solver's origin."""
        T = check_targets(targets, len(self._constrained))
        check_reach(self._bounds, T)
        return self._relative(T)

    def _check_point_targets(self, point_targets: object) -> NDArray[np.float64] | None:
        """Checked point-handle targets (or None), relative to the solver's origin."""
        P = check_point_targets(point_targets, 0 if self.points is None else len(self.points))
        if P is not None:
            check_reach(self._bounds, P, "point targets")
        return None if P is None else self._relative(P)

    def _to_caller(self, U: NDArray[np.float64]) -> NDArray[np.float64]:
        """Internal positions (internal order, relative to the origin) as the caller's: a new array."""
        return rows_of(U, self._inv, self._origin)

    # ------------------------------------------------------------------ solving
    @property
    def n_vertices(self) -> int:
        return len(self._V)

    @property
    def n_free(self) -> int:
        return len(self._free)

    def solve(
        self,
        targets: NDArray[np.float64] | list,
        initial: NDArray[np.float64] | StartName | None = None,
        max_iterations: int | None = None,
        tolerance: float = DEFAULT_TOLERANCE,
        callback: IterationCallback | None = None,
        acceleration: Acceleration = "lbfgs",
        window: int | None = None,
        point_targets: NDArray[np.float64] | list | None = None,
    ) -> ArapResult:
        """Deform the mesh so the constrained vertices reach their targets; by default, iterate until converged.

        Parameters
        ----------
        targets : (k, 3) float array
            Target of each constrained vertex, in the order of ``constrained``.
        initial : (n, 3) float array, {"auto", "rest", "rigid"} or None
            Where the iteration starts. None: the previous solution of this solver (a warm start, reusing its
            rotations), or ``"auto"`` the first time (and after :meth:`reset`). ``"rest"``: the rest pose with the
            constrained vertices at their targets. ``"rigid"``: the rest pose moved by the rigid motion that best
            maps the constrained vertices to their targets (weighted Procrustes). ``"auto"``: whichever of the two
            has the lower energy, so that constraints moved together by one rigid motion, however large its angle,
            give that motion at once. An array: these positions (constrained vertices are moved to their targets).
        max_iterations : int or None
            Cap on local/global iterations (≥ 0). None: until converged, at most ``MAX_ITERATIONS``.
        tolerance : float
            Converged when the step of the plain local/global iteration from the current iterate, root mean square
            over the free vertices, is at most ``tolerance`` times the bounding-box diagonal. That step is the
            energy gradient preconditioned by the system matrix, so it vanishes exactly at a stationary point.
            0 runs all ``max_iterations``. With rigid regions, at least :data:`arap.rigid.RIGID_TOLERANCE` (1e-9).
            Always at least the rounding of the targets' coordinates (:func:`arap.result.rounding_floor`), which
            matters only for targets thousands of diagonals away.
        callback : callable or None
            ``callback(iteration, energy)`` after each iteration (1-based); returning False stops early.
            :meth:`current_vertices` gives the iterate meanwhile.
        acceleration : {"lbfgs", "anderson", "none"}
            ``lbfgs``: L-BFGS preconditioned by the global step (Liu, Bouaziz & Kavan 2017; see
            :mod:`arap.lbfgs`) with a backtracking line search on the energy; its first direction is the plain
            step (from a cold start, its first ``arap.loops.PLAIN_START`` (10) steps are plain: L-BFGS's early long
            steps could cross into a higher minimum of the spokes energy), and a search that finds no lower energy
            takes the plain step, so the energy never rises. Where a
            part of the shape drifts slowly, Anderson's extrapolations are rejected for thousands of iterations
            while L-BFGS keeps converging. For ``smooth_rotations`` (whose coupled rotations are only moved towards
            their optimum), hard point handles (met by a projection) and rigid regions, ``lbfgs`` runs
            ``anderson``. ``anderson``: Anderson acceleration of the local/global fixed point (Peng et al. 2018)
            with an energy safeguard: an extrapolated iterate is kept only if its energy is not higher than the
            current one, otherwise the plain step is taken. ``none``: the plain iteration of Sorkine & Alexa 2007.
        window : int or None
            Curvature pairs kept by L-BFGS, or Anderson's window ``m`` (previous iterates used). None:
            ``DEFAULT_LBFGS_MEMORY`` (8) for L-BFGS, ``DEFAULT_WINDOW`` (5) for Anderson.

        Returns
        -------
        ArapResult
            Its ``energies`` never rise from one iteration to the next.
        """
        t_start = time.perf_counter()
        T = self._check_targets(targets)
        cap = check_solve_options(max_iterations, tolerance, acceleration, window)
        if self._rigid is not None and tolerance > 0:
            tolerance = max(float(tolerance), RIGID_TOLERANCE)
        fixed = self._fixed_positions(T)
        P = self._check_point_targets(point_targets)
        if tolerance > 0:
            tolerance = max(float(tolerance), rounding_floor(self._diagonal, T, P))
        self._point_state = None if P is None else (P, fixed)
        timings = {"local": 0.0, "rhs": 0.0, "solve": 0.0, "acceleration": 0.0}
        U, E_cur, start = self._start(T, fixed, initial, timings)
        const_E = self._inactive.energy(U, T)
        if E_cur is not None:
            E_cur += const_E
        self._live = U
        nf = self._nf
        rhs_const = self._coupling(fixed)
        if self._points is not None and P is not None:
            rhs_const = rhs_const - self._points.rhs(P, fixed)  # assemble_rhs subtracts its constant
        it = self._iterate(U, fixed, P, rhs_const, const_E, int(cap), tolerance, callback, timings)
        if acceleration == "lbfgs" and self._lbfgs_applies(P):
            size = DEFAULT_LBFGS_MEMORY if window is None else int(window)
            if self._history is None or self._history.window != size:
                self._history = LbfgsHistory(size)
            outcome = lbfgs_iterations(it, E_cur, self._history, 0 if start == "warm" else PLAIN_START)
        else:
            accel = None
            if acceleration != "none" and nf:
                size = DEFAULT_WINDOW if window is None else int(window)
                if self._accelerator is None or self._accelerator.window != size:
                    self._accelerator = AndersonAccelerator(size, 3 * nf)
                accel = self._accelerator
            outcome = plain_iterations(it, E_cur, accel)
        self._last = U
        self._live = None
        # The rotations fit the stored solution only if an iteration ended with a local step on it.
        self._rotations_fresh = bool(outcome.energies) or start != "warm"
        timings["total"] = time.perf_counter() - t_start
        return ArapResult(vertices=self._to_caller(U), energies=outcome.energies,
                          iterations=len(outcome.energies), converged=outcome.converged, timings=timings,
                          residual=outcome.residual, start=start, rejected=outcome.rejected)

    def _iterate(self, U: NDArray[np.float64], fixed: NDArray[np.float64], P: NDArray[np.float64] | None,
                 rhs_const: NDArray[np.float64], const_E: float, cap: int, tolerance: float,
                 callback: IterationCallback | None, timings: dict[str, float]) -> Iterate:
        """The steps of one :meth:`solve` call for :mod:`arap.loops`."""
        nf = self._nf
        A, factor, points = self._A, self.factor, self._points

        def rhs(out: NDArray[np.float64]) -> None:
            assemble_rhs(self._gather, self._R, rhs_const, out)

        def rhs_gradient(x: NDArray[np.float64], out: NDArray[np.float64], grad: NDArray[np.float64]) -> None:
            assemble_rhs_and_gradient(self._gather, self._R, rhs_const, A, x, out, grad)

        def solve(B: NDArray[np.float64]) -> NDArray[np.float64]:
            return B.copy() if factor is None else factor.solve(B)

        correct = None
        if points is not None and P is not None and points.hard.any():
            def correct(g: NDArray[np.float64]) -> NDArray[np.float64]:
                return points.correct(g, P, fixed)

        scale = self._diagonal * np.sqrt(max(nf, 1))
        return Iterate(U=U, nf=nf, rotations=self._R, local=lambda X: self._local(X, const_E, timings), rhs=rhs,
                       rhs_gradient=rhs_gradient, solve=solve, correct=correct, coupled=self._smooth is not None,
                       step_limit=tolerance * scale, scale=scale, cap=cap, callback=callback, timings=timings,
                       scale_initial=self._non_negative)

    def _lbfgs_applies(self, point_targets: NDArray[np.float64] | None) -> bool:
        """True when the energy's gradient in x is ``2 (A x − b(R))`` with the factored ``A``, evaluated to full
        precision: rotations fitted exactly (not ``smooth_rotations``), no hard point handles (their projection is
        not ``A⁻¹``) and no rigid regions (their huge cell weights cancel in ``A x − b``)."""
        hard = self._points is not None and point_targets is not None and bool(self._points.hard.any())
        return (self.factor is not None and self._smooth is None and self._rigid is None and not hard
                and self._nf > 0)

    def _local(self, U: NDArray[np.float64], const_E: float, timings: dict[str, float]) -> float:
        """Local step on the active cells at ``U``; returns the total energy."""
        t = time.perf_counter()
        e_term = 0.0
        if self._smooth is not None:
            e = self._smooth.relax(U, self._R, self._E, self._term, SWEEPS, steps=STEPS)
            e_term = float(self._term.sum())
        else:
            e = local_step(self._cells, self._active, U, self._R, self._E)
        if self._rigid is not None:
            e += self._rigid.share(U, self._R, self._E)
            if self._smooth is not None:  # the shared rotations change the rotation term
                e += self._smooth.rotation_term(self._R, self._term) - e_term
        if self._points is not None and self._point_state is not None:
            e += self._points.penalty(U[:self._nf], *self._point_state)
        timings["local"] += time.perf_counter() - t
        return e + const_E

    def current_vertices(self) -> NDArray[np.float64]:
        """Positions of the current iterate during :meth:`solve` (from its callback), else of the last solution.

        Returns
        -------
        (n, 3) float64 array
            A copy, in the caller's vertex order; the rest pose before any solve.
        """
        U = self._live if self._live is not None else self._last
        if U is None:
            return self.V.copy()
        return self._to_caller(U)

    def reset(self) -> None:
        """Forget the previous solution: the next :meth:`solve` without ``initial`` starts from the rest pose."""
        self._last = None
        self._rotations_fresh = False

    @property
    def system_size(self) -> int:
        """Number of unknown vertices in the linear system (free ROI vertices)."""
        return len(self._free)
