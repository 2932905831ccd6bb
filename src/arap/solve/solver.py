"""The ARAP solver: precompute (factorise) once per constraint set, then alternate local and global steps."""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from arap.meshes.mesh import MeshLike
from arap.method.points import PointConstraints
from arap.options import (
    DEFAULT_ALPHA,
    DEFAULT_LBFGS_MEMORY,
    DEFAULT_LOOSE_PARTS,
    DEFAULT_TOLERANCE,
    DEFAULT_WEIGHTS,
    DEFAULT_WINDOW,
    Acceleration,
    EnergyType,
    LoosePartsMode,
    StartName,
    WeightType,
    check_solve_options,
)
from arap.solve import steps
from arap.solve.addons import LocalState
from arap.solve.anderson import AndersonAccelerator
from arap.solve.iteration import SolveState, lbfgs_applies, make_iterate
from arap.solve.kernel_cache import announce_first_compile
from arap.solve.lbfgs import LbfgsHistory
from arap.solve.loops import PLAIN_START, lbfgs_iterations, plain_iterations
from arap.solve.prepared import Points, Prepared, prepare
from arap.solve.result import ArapResult, IterationCallback, rounding_floor
from arap.solve.start import start_positions
from arap.sparse.linsolve import Factor


class ArapSolver:
    """As-Rigid-As-Possible deformation (Sorkine & Alexa 2007) of a surface, a planar mesh or a tetrahedral solid.

    Construction validates the mesh and the constraint set, builds the cells and factorises the reduced global-step
    matrix once (Cholesky); every :meth:`solve` then only back-substitutes.

    Parameters
    ----------
    V : (n, 3) or (n, 2) float array, or a mesh object
        Rest positions, or a mesh object (a ``trimesh.Trimesh``, a ``meshio.Mesh`` with ``triangle`` or ``tetra``
        cells, a ``pyvista.PolyData`` or ``UnstructuredGrid`` of tetrahedra, anything with ``vertices`` and
        ``faces``; then leave out ``F``: ``ArapSolver(mesh, constrained)``). Two columns make a planar mesh: its
        results have two columns too, and its rotations turn in the plane (:mod:`arap.meshes.domain`).
    F : (m, 3) or (m, 4) int array
        Triangles, or tetrahedra (then ``energy="elements"``). Degenerate faces are rejected (see
        :func:`arap.repair_mesh`); so are elements of zero area or volume and elements oriented against the others.
    constrained : (k,) int array
        Constrained vertices (anchors and handles, any order, unique). :meth:`solve` takes their targets in this order.
    energy : {"spokes_and_rims", "spokes", "smooth_rotations", "elements"} or None
        None: ``elements`` for planar meshes given with two coordinates and for tetrahedra, ``spokes_and_rims`` for
        surfaces. ``elements``: one rotation per triangle or tetrahedron (libigl's ``ARAP_ENERGY_TYPE_ELEMENTS``;
        see :mod:`arap.method.elements`); a triangle mesh in space with one constant coordinate then deforms in its
        plane. ``spokes_and_rims``: cells over all edges of the triangles around a vertex (Chao et al. 2010); a
        sum of non-negative per-triangle terms even with obtuse triangles, so it does not fold scans.
        ``spokes``: the paper's one-ring cells (Sorkine & Alexa 2007); with negative cotangent weights its energy can
        be negative and its minima fold scans (see "Energy and weights" in docs/solver.md).
        ``smooth_rotations``: SR-ARAP (Levi & Gotsman 2015), the spokes energy plus ``α A Σ_i Σ_j w⁺_ij ‖R_i −
        R_j‖²`` that makes neighbouring rotations agree (see :mod:`arap.method.smooth`).
    weights : {"cotangent", "clamped", "uniform"}
        ``cotangent``: ``w_ij = ½(cot α_ij + cot β_ij)``, one term on boundary edges (Pinkall & Polthier 1993).
        ``clamped``: the cotangent weights with negative values set to 0. ``uniform``: ½ per incident triangle.
    roi : (r,) int array or None
        Region of interest. Only ROI vertices move; every other vertex is held at its rest position and the linear
        system has the size of the free ROI vertices. None means the whole mesh.
    alpha : float
        Weight of the rotation term of ``energy="smooth_rotations"`` (SR-ARAP, Levi & Gotsman 2015), relative to
        the surface area so that it does not depend on the mesh's size; 0.02 by default (CGAL's default; at the same
        value this term couples rotations about 7 times as strongly as CGAL's, see :mod:`arap.method.smooth`). Ignored
        by the other energies.
    points : PointConstraints, (faces, barycentric) or (faces, barycentric, weights), or None
        Handles anywhere on the mesh (see :mod:`arap.method.points`): point ``k`` lies in element ``faces[k]`` at
        ``barycentric[k]`` (3 coordinates in a triangle, 4 in a tetrahedron, ≥ 0 summing to 1, corners in the
        order of ``F``); its weight is ``inf``
        (default) for a hard constraint, met exactly, or a positive weight for a soft one that pulls with that
        strength. :meth:`solve` then takes their targets as ``point_targets``. The factorisation stays once per
        constraint set.
    stiffness : (n,) array of float or None
        Per-vertex cell weights ``w_i`` (element cells weigh the mean of their vertices' weights, and are rigid
        when all their vertices are) of the paper's energy ``Σ_i w_i Σ_j w_ij ‖…‖²`` (Sorkine & Alexa 2007):
        1 is the plain energy (None: all 1), larger values make a vertex's cell stiffer, so a region painted stiff
        moves almost rigidly while softer parts bend; ``np.inf`` keeps a region rigid (to about 1e-8 of its size;
        see :data:`arap.method.stiffness.RIGID_STIFFNESS`). The energies reported include the weights. With the spoke
        energies (``spokes``, ``smooth_rotations``) on a mesh with obtuse triangles (negative cotangent weights),
        unequal weights can leave the energy without a minimum: that raises OptionError (``spokes_and_rims`` or
        ``weights="clamped"`` work).
    loose : {"error", "hold", "follow"}
        A connected part of the mesh that no constraint reaches (a wheel beside a car body): ``error`` (default)
        raises UnconstrainedRegionError naming it; ``hold`` keeps it at rest; ``follow`` moves it with the rigid
        motion of the constrained surface nearest to it (see :mod:`arap.solve.loose`).
    backend : str or None
        Sparse Cholesky backend (see :mod:`arap.sparse.linsolve`); None chooses by system size and whether the mesh
        is a solid (:func:`arap.sparse.linsolve.default_backend`).

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
        A connected part of the free vertices touches no constrained or held vertex (its system is singular), with
        ``loose="error"``.
    OptionError
        An unknown energy, weights or backend name.

    Examples
    --------
    Hold the bottom of the bar and move its top sideways; the solver factorises once and may solve again for other
    targets:

    >>> import numpy as np, arap
    >>> V, F = arap.builtin_mesh("bar")
    >>> bottom, top = np.flatnonzero(V[:, 1] == V[:, 1].min()), np.flatnonzero(V[:, 1] == V[:, 1].max())
    >>> solver = arap.ArapSolver(V, F, np.concatenate([bottom, top]))
    >>> result = solver.solve(np.concatenate([V[bottom], V[top] + [1.0, 0.0, 0.0]]))
    >>> bool(result.converged), round(float(result.vertices[top, 0].mean() - V[top, 0].mean()), 6)
    (True, 1.0)
    """

    def __init__(
        self,
        V: NDArray[np.floating] | MeshLike,
        F: NDArray[np.integer] | None = None,
        constrained: NDArray[np.integer] | list[int] | None = None,
        energy: EnergyType | None = None,
        weights: WeightType = DEFAULT_WEIGHTS,
        roi: NDArray[np.integer] | list[int] | None = None,
        backend: str | None = None,
        stiffness: ArrayLike | None = None,
        alpha: float = DEFAULT_ALPHA,
        points: Points | None = None,
        loose: LoosePartsMode = DEFAULT_LOOSE_PARTS,
    ) -> None:
        t0 = time.perf_counter()
        announce_first_compile()
        #: The set-up record (:class:`arap.solve.prepared.Prepared`): everything a solve reads, built once.
        self.prepared: Prepared = prepare(V, F, constrained, energy, weights, roi, backend, stiffness, alpha, points,
                                          loose)
        self._state = SolveState(LocalState.empty(self.prepared.cells.n_cells))
        self.factor_seconds = time.perf_counter() - t0

    @classmethod
    def from_prepared(cls, prepared: Prepared) -> ArapSolver:
        """A solver on a set-up record built before: another solver's, or one derived from it with
        ``dataclasses.replace`` (another local step, e.g. :class:`arap.puppet.blend.ScaledFit`). Nothing is
        factorised again (the factor is shared); the new solver has its own solve state."""
        solver = cls.__new__(cls)
        solver.prepared = prepared
        solver._state = SolveState(LocalState.empty(prepared.cells.n_cells))
        solver.factor_seconds = 0.0
        return solver

    # ------------------------------------------------------------------ the set-up, as given and checked
    @property
    def V(self) -> NDArray[np.float64]:
        """Rest positions (n, 3), as checked."""
        return self.prepared.V

    @property
    def F(self) -> NDArray[np.int64]:
        """Triangles (m, 3), as checked."""
        return self.prepared.F

    @property
    def energy_type(self) -> EnergyType:
        return self.prepared.energy_type

    @property
    def weight_type(self) -> WeightType:
        return self.prepared.weight_type

    @property
    def alpha(self) -> float:
        return self.prepared.alpha

    @property
    def constrained(self) -> NDArray[np.int64]:
        """Constrained vertices, in the order :meth:`solve` takes their targets."""
        return self.prepared.constrained

    @property
    def roi(self) -> NDArray[np.int64] | None:
        return self.prepared.roi

    @property
    def stiffness(self) -> NDArray[np.float64] | None:
        return self.prepared.stiffness

    @property
    def points(self) -> PointConstraints | None:
        return self.prepared.points

    @property
    def free(self) -> NDArray[np.int64]:
        """Vertices the solve moves (caller's numbering)."""
        return self.prepared.free

    @property
    def held(self) -> NDArray[np.int64]:
        """Vertices outside the region of interest, held at rest."""
        return self.prepared.held

    @property
    def nonfree(self) -> NDArray[np.int64]:
        return self.prepared.nonfree

    @property
    def factor(self) -> Factor | None:
        """The Cholesky factor of the reduced system (None when no vertex is free)."""
        return self.prepared.factor

    @property
    def backend(self) -> str | None:
        """The sparse Cholesky backend in use."""
        return None if self.prepared.factor is None else self.prepared.factor.backend

    @property
    def n_vertices(self) -> int:
        return self.prepared.n

    @property
    def n_free(self) -> int:
        return self.prepared.nf

    @property
    def system_size(self) -> int:
        """Number of unknown vertices in the linear system (free ROI vertices)."""
        return self.prepared.nf

    # ------------------------------------------------------------------ solving
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
            0 runs all ``max_iterations``. With rigid regions, at least :data:`arap.method.rigid.RIGID_TOLERANCE`
            (1e-9). Always at least the rounding of the targets' coordinates (:func:`arap.solve.result.rounding_floor`),
            which matters only for targets thousands of diagonals away.
        callback : callable or None
            ``callback(iteration, energy)`` after each iteration (1-based); returning False stops early.
            :meth:`current_vertices` gives the iterate meanwhile.
        acceleration : {"lbfgs", "anderson", "none"}
            ``lbfgs``: L-BFGS preconditioned by the global step (Liu, Bouaziz & Kavan 2017; see
            :mod:`arap.solve.lbfgs`) with a backtracking line search on the energy; its first direction is the plain
            step (from a cold start, its first ``arap.solve.loops.PLAIN_START`` (10) steps are plain: L-BFGS's early
            long steps could cross into a higher minimum of the spokes energy), and a search that finds no lower energy
            takes the plain step, so the energy never rises. Where a part of the shape drifts slowly, Anderson's
            extrapolations are rejected for thousands of iterations while L-BFGS keeps converging. For
            ``smooth_rotations`` (whose coupled rotations are only moved towards their optimum), hard point handles (met
            by a projection) and rigid regions, ``lbfgs`` runs ``anderson``. ``anderson``: Anderson acceleration of the
            local/global fixed point (Peng et al. 2018) with an energy safeguard: an extrapolated iterate is kept only
            if its energy is not higher than the current one, otherwise the plain step is taken. ``none``: the plain
            iteration of Sorkine & Alexa 2007.
        window : int or None
            Curvature pairs kept by L-BFGS, or Anderson's window ``m`` (previous iterates used). None:
            ``DEFAULT_LBFGS_MEMORY`` (8) for L-BFGS, ``DEFAULT_WINDOW`` (5) for Anderson.

        Returns
        -------
        ArapResult
            Its ``energies`` never rise from one iteration to the next, but once where an element solve opens the
            elements it turned over (:mod:`arap.method.unfold`), to end lower than where it opened them.
        """
        t_start = time.perf_counter()
        p, state = self.prepared, self._state
        T = p.check_targets(targets)
        cap = check_solve_options(max_iterations, tolerance, acceleration, window)
        if tolerance > 0:
            for addon in p.addons:
                tolerance = max(float(tolerance), addon.min_tolerance)
        fixed = p.fixed_positions(T)
        P = p.check_point_targets(point_targets)
        if tolerance > 0:
            tolerance = max(float(tolerance), rounding_floor(p.diagonal, T, P))
        state.local.points = None if P is None else (P, fixed)
        timings = {"local": 0.0, "rhs": 0.0, "solve": 0.0, "acceleration": 0.0}
        if initial is not None and not isinstance(initial, str):
            initial = p.to_internal(p.check_positions(initial, "initial"))
        U, E_cur, start = start_positions(p, state, T, fixed, initial, timings)
        const_E = p.inactive.energy(U, T)
        if E_cur is not None:
            E_cur += const_E
        state.live = U
        it = make_iterate(p, state.local, U, fixed, P, const_E, int(cap), tolerance, callback, timings)
        if acceleration == "lbfgs" and lbfgs_applies(p, P):
            size = DEFAULT_LBFGS_MEMORY if window is None else int(window)
            if state.history is None or state.history.window != size:
                state.history = LbfgsHistory(size)
            outcome = lbfgs_iterations(it, E_cur, state.history, 0 if start == "warm" else PLAIN_START)
        else:
            accel = None
            if acceleration != "none" and p.nf:
                size = DEFAULT_WINDOW if window is None else int(window)
                if state.accelerator is None or state.accelerator.window != size:
                    state.accelerator = AndersonAccelerator(size, it.U[:p.nf].size)
                accel = state.accelerator
            outcome = plain_iterations(it, E_cur, accel)
        if it.sync is not None:
            it.sync()
        state.last = U
        state.live = None
        # The rotations fit the stored solution only if an iteration ended with a local step on it.
        state.rotations_fresh = bool(outcome.energies) or start != "warm"
        timings["total"] = time.perf_counter() - t_start
        return ArapResult(vertices=p.to_caller(U), energies=outcome.energies,
                          iterations=len(outcome.energies), converged=outcome.converged, timings=timings,
                          residual=outcome.residual, start=start, rejected=outcome.rejected)

    def current_vertices(self) -> NDArray[np.float64]:
        """Positions of the current iterate during :meth:`solve` (from its callback), else of the last solution.

        Returns
        -------
        (n, 3) float64 array
            A copy, in the caller's vertex order; the rest pose before any solve.
        """
        U = self._state.live if self._state.live is not None else self._state.last
        if U is None:
            return self.V.copy()
        return self.prepared.to_caller(U)

    def reset(self) -> None:
        """Forget the previous solution: the next :meth:`solve` without ``initial`` starts from the rest pose."""
        self._state.last = None
        self._state.rotations_fresh = False

    # ------------------------------------------------------------------ single steps (:mod:`arap.solve.steps`)
    def fit_rotations(self, U: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
        """Local step alone: the optimal rotation of every cell for positions ``U``, shape (n, 3, 3).

        For ``smooth_rotations`` the rotations are coupled: this is one block-coordinate sweep from ``start``
        (n, 3, 3) (None: the solver's current rotations), which never raises the energy.
        """
        R = self._state.local.R if start is None else self.prepared.cells_to_internal(np.asarray(start,
                                                                                                 dtype=np.float64))
        return steps.fit_rotations(self.prepared, U, R)

    def energy(self, U: np.ndarray, R: np.ndarray | None = None) -> float:
        """Energy of positions ``U`` with rotations ``R`` (None: the optimal ones; for ``smooth_rotations``, those
        of :meth:`fit_rotations`), summed over all cells."""
        return steps.energy_of(self.prepared, U, R, self._state.local.R)

    def global_step(self, R: np.ndarray, targets: np.ndarray | list,
                    point_targets: np.ndarray | list | None = None) -> np.ndarray:
        """Global step alone: positions minimising the energy for fixed rotations ``R`` (n, 3, 3), shape (n, 3)."""
        return steps.global_step(self.prepared, R, targets, point_targets)

    def reduced_matrix(self) -> sp.csr_matrix:
        """The reduced global-step matrix ``L_ff`` (for inspection; rows in the solver's internal vertex order)."""
        return steps.reduced_matrix(self.prepared)
