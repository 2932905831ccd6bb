"""A solver's set-up as one frozen record, built in named steps: check the input, number the vertices, assemble
the cells and the reduced system, attach the add-ons, factorise.

:func:`prepare` is what :class:`arap.ArapSolver` does on construction (libigl's ``arap_precomputation``,
gpytoolbox's ``min_quad_with_fixed_precompute``); everything a solve reads comes from the record, and nothing in it
changes when a solve runs (the factor, the cells and the numbering are shared; the few caches inside its objects,
such as the inactive cells' energies, do not change what they return).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from arap.errors import ArapError, ConstraintError
from arap.meshes._geometry import barycentric_areas
from arap.meshes.domain import Domain, check_domain
from arap.meshes.mesh import MeshLike, bounding_box
from arap.meshes.topology import locality_order, vertex_adjacency
from arap.method.assembly import assemble, check_energy_for
from arap.method.cells import Cells, RhsGather, build_rhs_gather, system_matrix
from arap.method.colouring import colour_order
from arap.method.elements import vertex_measures
from arap.method.inactive import InactiveCells
from arap.method.points import PointConstraints, PointSystem, check_points
from arap.method.rigid import RigidRegions
from arap.method.smooth import SmoothRotations
from arap.method.stiffness import check_stiffness, singular_system_error
from arap.options import (
    DEFAULT_ALPHA,
    DEFAULT_ELEMENT_ENERGY,
    DEFAULT_ENERGY,
    DEFAULT_LOOSE_PARTS,
    DEFAULT_WEIGHTS,
    EnergyType,
    LoosePartsMode,
    WeightType,
    check_alpha,
    check_energy_and_weights,
    check_loose_parts,
)
from arap.solve.addons import AddOn, PlainFit, PointHandles, RigidAddOn, RotationFit, SmoothAddOn, SmoothFit
from arap.solve.indexing import check_index_array, internal_origin, rows_of, with_rows
from arap.solve.loose import FollowingParts
from arap.solve.partition import check_point_targets, check_positions, check_reach, check_targets, partition_vertices
from arap.sparse._csr import SparseRowsProduct, leading_blocks
from arap.sparse.linsolve import Factor, NotPositiveDefiniteError, background_ordering, default_backend, factorize

__all__ = ["Numbering", "Prepared", "prepare"]

Points = PointConstraints | tuple[ArrayLike, ArrayLike] | tuple[ArrayLike, ArrayLike, ArrayLike]


@dataclass(frozen=True, eq=False)
class Numbering:
    """The solver's internal vertex numbering: free vertices first, each block in an order that keeps neighbours
    close in memory (reverse Cuthill-McKee), so the gathers of the local step and the right-hand side stay in cache.

    Attributes
    ----------
    perm : (n,) int array
        Internal index → caller's index.
    inv : (n,) int array
        Caller's index → internal index.
    nf : int
        Free vertices: internal ``0 .. nf-1``; the others (constrained or held) follow.
    constrained : (k,) int array
        Internal indices of the constrained vertices, in the caller's order of ``constrained``.
    constrained_slot : (k,) int array
        Row of each constrained vertex among the non-free ones.
    colour : (n,) int array or None
        Smooth rotations' cell colouring, in the caller's numbering (None for the other energies).
    """

    perm: NDArray[np.int64]
    inv: NDArray[np.int64]
    nf: int
    constrained: NDArray[np.int64]
    constrained_slot: NDArray[np.int64]
    colour: NDArray[np.int64] | None

    @property
    def free(self) -> NDArray[np.int64]:
        return np.arange(self.nf)


@dataclass(frozen=True, eq=False)
class Prepared:
    """Everything a solve reads, built once per mesh and constraint set by :func:`prepare`.

    Attributes
    ----------
    V, F : arrays
        The checked rest positions (n, 3), or (n, 2) for a planar mesh given so, and the triangles (m, 3) or
        tetrahedra (m, 4), caller's numbering.
    domain : Domain
        The kind of mesh and its positions in the solver's coordinates (:mod:`arap.meshes.domain`).
    energy_type, weight_type : str
        The energy and the edge weights (see :mod:`arap.options`).
    alpha : float
        Smooth rotations' weight.
    constrained, roi : int arrays
        As given (``roi`` None for the whole mesh).
    stiffness : (n,) float array or None
        Per-vertex cell weights.
    points : PointConstraints or None
        Point handles.
    free, held, nonfree : int arrays
        The caller's vertices by role (:func:`arap.solve.partition.partition_vertices`).
    loose : str
        What the loose parts do (:data:`arap.options.LOOSE_PARTS`).
    loose_parts : list of int arrays
        The caller's vertices of each part no constraint reaches (held, and placed by ``following``).
    following : FollowingParts or None
        Where the loose parts go (``loose="follow"``).
    numbering : Numbering
    elements : (m, 3) or (m, 4) int array
        ``F`` in the internal numbering (what the iterations that open turned-over elements read).
    bounds : (2, 3) float array
        Bounding box of ``V``; ``diagonal`` its diagonal (1 for a single point).
    origin : (3,) float array
        Subtracted from every position inside the solver (0 unless the mesh lies far from the origin).
    rest : (n, 3) float array
        Rest positions, internal numbering, relative to ``origin``.
    areas : (n,) float array
        Vertex areas (the rigid start's weights).
    cells : Cells
        The energy's terms (scaled by ``stiffness``): one cell per vertex, or per element for ``elements``.
    cell_order : (c,) int array or None
        Element cells: the element (caller's index) behind each cell; None for vertex cells (cell ``c`` is internal
        vertex ``c``).
    non_negative : bool
        Every cell's energy is a sum of non-negative terms.
    matrix : csr_matrix
        The factored matrix ``L_ff`` (plus the point handles' terms): the energy's Hessian in x for fixed rotations.
    coupling : SparseRowsProduct
        ``L_fn @ fixed``: the right-hand side's constant; ``L_fn`` the matrix it multiplies by.
    gather : RhsGather
        How the right-hand side gathers the rotated edge vectors.
    active : (a,) int array
        Cells the iterations fit (every cell with a term on a free vertex; all cells for smooth rotations).
    rotation_fit : RotationFit
        How the local step fits the rotations.
    addons : tuple of AddOn
        Smooth rotations, rigid regions, point handles (those present, in this order).
    point_system : PointSystem or None
        The point handles' terms of the global step.
    inactive : InactiveCells
        Energies of the cells outside ``active``.
    factor : Factor or None
        The Cholesky factor of ``matrix`` (None when no vertex is free).

    Examples
    --------
    >>> import arap
    >>> from arap.solve.prepared import prepare
    >>> p = prepare(*arap.sphere(1), [0, 1])
    >>> p.n, p.energy_type, len(p.free) + len(p.nonfree) == p.n
    (42, 'spokes_and_rims', True)
    """

    V: NDArray[np.float64]
    F: NDArray[np.int64]
    domain: Domain
    energy_type: EnergyType
    weight_type: WeightType
    alpha: float
    constrained: NDArray[np.int64]
    roi: NDArray[np.int64] | None
    stiffness: NDArray[np.float64] | None
    points: PointConstraints | None
    free: NDArray[np.int64]
    held: NDArray[np.int64]
    nonfree: NDArray[np.int64]
    loose: LoosePartsMode
    loose_parts: list[NDArray[np.int64]]
    following: FollowingParts | None
    numbering: Numbering
    elements: NDArray[np.int64]
    bounds: NDArray[np.float64]
    diagonal: float
    origin: NDArray[np.float64]
    rest: NDArray[np.float64]
    areas: NDArray[np.float64]
    cells: Cells
    cell_order: NDArray[np.int64] | None
    non_negative: bool
    matrix: sp.csr_matrix
    L_fn: sp.csr_matrix
    coupling: SparseRowsProduct
    gather: RhsGather
    active: NDArray[np.int64]
    rotation_fit: RotationFit
    addons: tuple[AddOn, ...]
    point_system: PointSystem | None
    inactive: InactiveCells
    factor: Factor | None

    @property
    def n(self) -> int:
        """Number of vertices."""
        return len(self.rest)

    @property
    def nf(self) -> int:
        """Number of free vertices (the linear system's size)."""
        return self.numbering.nf

    # ------------------------------------------------------------------ the caller's arrays and the solver's
    def fixed_positions(self, targets: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions of the non-free vertices (constrained at targets, held at rest), in ``nonfree`` order."""
        return with_rows(self.rest[self.nf:], self.numbering.constrained_slot, targets)

    def to_internal(self, X: np.ndarray) -> np.ndarray:
        """Rows of a per-vertex array in the solver's internal vertex order."""
        return np.ascontiguousarray(X[self.numbering.perm])

    def relative(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions relative to the solver's origin (``X`` itself when the origin is 0, as for most meshes)."""
        return X - self.origin if self.origin.any() else X

    def to_caller(self, U: NDArray[np.float64]) -> NDArray[np.float64]:
        """Internal positions (internal order, relative to the origin) as the caller's (caller's order and
        coordinates): a new array."""
        if self.following is not None:
            U = self.following.place(U)
        return self.domain.drop(rows_of(U, self.numbering.inv, self.origin))

    def cells_to_caller(self, R: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per-cell rows (rotations, energies) in the caller's order: of vertices, or of elements."""
        if self.cell_order is None:
            return R[self.numbering.inv]
        out = np.empty_like(R)
        out[self.cell_order] = R
        return out

    def cells_to_internal(self, R: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per-cell rows given in the caller's order, in the cells' order."""
        if self.cell_order is None:
            return self.to_internal(R)
        return np.ascontiguousarray(R[self.cell_order])

    @property
    def iteration_columns(self) -> int:
        """Coordinates per vertex that a solve's iterations carry: 2 for a planar mesh whose rotation fit and add-ons
        all work in the plane (``z`` stays 0 and no work is spent on it), else 3."""
        planar = self.domain.planar and self.rotation_fit.planar_columns
        return 2 if planar and all(addon.planar_columns for addon in self.addons) else 3

    @property
    def columns(self) -> int:
        """Coordinates per vertex in the caller's arrays (2 for a planar mesh given with two)."""
        return self.domain.columns

    def check_positions(self, U: object, name: str) -> NDArray[np.float64]:
        """Checked positions (n, 3), relative to the solver's origin."""
        X = self.domain.lift(check_positions(U, self.n, name, self.columns), name, ArapError)
        return self.relative(X)

    def check_targets(self, targets: object) -> NDArray[np.float64]:
        """Checked targets, relative to the solver's origin."""
        T = self.domain.lift(check_targets(targets, len(self.constrained), self.columns), "targets",
                             ConstraintError)
        check_reach(self.bounds, T)
        return self.relative(T)

    def check_point_targets(self, point_targets: object) -> NDArray[np.float64] | None:
        """Checked point-handle targets (or None), relative to the solver's origin."""
        P = check_point_targets(point_targets, 0 if self.points is None else len(self.points), self.columns)
        if P is None:
            return None
        P = self.domain.lift(P, "point targets", ConstraintError)
        check_reach(self.bounds, P, "point targets")
        return self.relative(P)


@dataclass(frozen=True, eq=False)
class _Input:
    V: NDArray[np.float64]
    domain: Domain
    energy: EnergyType
    constrained: NDArray[np.int64]
    roi: NDArray[np.int64] | None
    stiffness: NDArray[np.float64] | None
    rigid: NDArray[np.bool_] | None
    points: PointConstraints | None
    alpha: float


def _check_input(V: NDArray[np.floating] | MeshLike, F: NDArray[np.integer] | None,
                 constrained: NDArray[np.integer] | list[int] | None, energy: EnergyType | None, weights: WeightType,
                 roi: NDArray[np.integer] | list[int] | None, stiffness: ArrayLike | None, alpha: float,
                 points: Points | None) -> _Input:
    """Step 1: check the mesh, the constraint set and the options."""
    check_energy_and_weights(DEFAULT_ENERGY if energy is None else energy, weights)
    alpha = check_alpha(alpha)
    if constrained is None and not isinstance(V, np.ndarray | list | tuple) and F is not None:
        F, constrained = None, F  # ArapSolver(mesh, constrained)
    if constrained is None:
        raise ConstraintError("constrained (the anchor and handle vertices) is missing")
    domain = check_domain(V, F, elements=energy == "elements")
    if energy is None:
        energy = DEFAULT_ELEMENT_ENERGY if domain.kind in ("planar", "solid") else DEFAULT_ENERGY
    check_energy_for(energy, domain.kind)
    F = domain.elements
    n = len(domain.V)
    checked = check_index_array(constrained, n, "constrained")
    checked_roi = None if roi is None else check_index_array(roi, n, "roi", allow_empty=False)
    weights_w: NDArray[np.float64] | None = None
    rigid: NDArray[np.bool_] | None = None
    if stiffness is not None:
        weights_w, rigid = check_stiffness(stiffness, n)
    checked_points = None
    if points is not None:
        p = (points.faces, points.barycentric, points.weights) if isinstance(points, PointConstraints) \
            else tuple(points)
        checked_points = check_points(p[0], p[1], p[2] if len(p) > 2 else None, len(F), F.shape[1])
    caller_V = domain.drop(domain.V) if domain.kind == "planar" else domain.V
    return _Input(caller_V, domain, energy, checked, checked_roi, weights_w, rigid, checked_points, float(alpha))


def _number_vertices(F: NDArray[np.int64], n: int, adjacency: sp.csr_matrix, free: NDArray[np.int64],
                     constrained: NDArray[np.int64], smooth: bool) -> Numbering:
    """Step 2: the internal numbering (free vertices first; smooth rotations' cells by colour, window by window)."""
    order = locality_order(F, n, adjacency)
    colour = None
    if smooth:  # each colour's cells consecutive, window by window, for the sweep
        order, colour = colour_order(order, adjacency)
    is_free = np.zeros(n, dtype=bool)
    is_free[free] = True
    perm = np.concatenate([order[is_free[order]], order[~is_free[order]]])
    inv = np.empty_like(perm)
    inv[perm] = np.arange(n)
    nf = len(free)
    internal = inv[constrained]
    slot = np.searchsorted(np.arange(nf, n), internal)
    return Numbering(perm=perm, inv=inv, nf=nf, constrained=internal, constrained_slot=slot, colour=colour)


def _attach_addons(cells: Cells, numbering: Numbering, energy: EnergyType, alpha: float, area: float,
                   pair_weights: NDArray[np.float64], region: NDArray[np.int64] | None,
                   point_system: PointSystem | None, active: NDArray[np.int64]
                   ) -> tuple[RotationFit, tuple[AddOn, ...], NDArray[np.int64]]:
    """Step 4: the rotation fit and the add-ons, and the cells the iterations fit."""
    n = len(numbering.perm)
    addons: list[AddOn] = []
    fit: RotationFit
    smooth_fit: SmoothFit | None = None
    if energy == "smooth_rotations":
        colour = None if numbering.colour is None else numbering.colour[numbering.perm]
        smooth_fit = SmoothFit(SmoothRotations(cells, area, alpha, pair_weights, colour))
        active = np.arange(n)  # every rotation is coupled to its neighbours': all cells take part
        fit = smooth_fit
        addons.append(SmoothAddOn(smooth_fit))
    else:
        fit = PlainFit(cells, active)
    if region is not None:
        addons.append(RigidAddOn(RigidRegions(cells, region, active),
                                 RigidRegions(cells, region, np.arange(cells.n_cells)), smooth_fit))
    if point_system is not None:
        addons.append(PointHandles(point_system, numbering.nf))
    return fit, tuple(addons), active


def prepare(V: NDArray[np.floating] | MeshLike, F: NDArray[np.integer] | None = None,
            constrained: NDArray[np.integer] | list[int] | None = None, energy: EnergyType | None = None,
            weights: WeightType = DEFAULT_WEIGHTS, roi: NDArray[np.integer] | list[int] | None = None,
            backend: str | None = None, stiffness: ArrayLike | None = None, alpha: float = DEFAULT_ALPHA,
            points: Points | None = None, loose: LoosePartsMode = DEFAULT_LOOSE_PARTS) -> Prepared:
    """Build a solver's set-up record (the parameters are :class:`arap.ArapSolver`'s; it passes its defaults).

    Returns
    -------
    Prepared

    Example
    -------
    >>> import arap
    >>> V, F = arap.builtin_mesh("sphere:200")
    >>> p = prepare(V, F, [0, 1, 2])
    >>> (p.n, p.nf + len(p.nonfree) == p.n, p.factor is not None)
    (162, True, True)
    """
    given = _check_input(V, F, constrained, energy, weights, roi, stiffness, alpha, points)
    check_loose_parts(loose)
    domain, energy = given.domain, given.energy
    F = domain.elements
    graph = domain.graph_faces
    n = len(domain.V)
    adjacency = vertex_adjacency(graph, n)
    free, held, nonfree, parts = partition_vertices(
        F, n, given.constrained, given.roi, None if given.points is None else given.points.faces, adjacency,
        loose=loose != "error")
    numbering = _number_vertices(graph, n, adjacency, free, given.constrained, energy == "smooth_rotations")
    perm, inv, nf = numbering.perm, numbering.inv, numbering.nf
    backend = backend or default_backend(nf, solid=domain.kind == "solid")
    # The reduced system's fill-reducing ordering needs only its pattern: it runs beside the set-up below.
    ordering = background_ordering(adjacency, perm, nf, backend)

    # Step 3: cells and the reduced system
    bounds = bounding_box(domain.V)
    diagonal = float(np.linalg.norm(bounds[1] - bounds[0])) or 1.0
    origin = internal_origin(domain.V, diagonal)
    rest = np.ascontiguousarray(domain.V[perm] - origin)
    F_int = inv[F]
    areas = barycentric_areas(rest, F_int) if domain.kind == "surface" else vertex_measures(rest, F_int)
    # Element cells in the order of their first internal vertex, so that neighbouring cells stay close in memory.
    cell_order = np.argsort(F_int.min(axis=1), kind="stable") if energy == "elements" else None
    assembly = assemble(rest, F_int, inv[graph] if domain.kind == "solid" else F_int, energy, weights,
                        domain.planar, None if given.stiffness is None else given.stiffness[perm],
                        None if given.rigid is None else given.rigid[perm], cell_order)
    cells = assembly.cells
    pair_weights = np.maximum(assembly.rest.w, 0.0)  # the rotation term of smooth_rotations: not scaled by stiffness
    # every cell's energy a sum of non-negative terms (per triangle for spokes and rims, per element for elements)
    non_negative = energy in ("spokes_and_rims", "elements") or not bool((assembly.rest.w < 0).any())
    L = system_matrix(cells, n)
    L_ff, L_fn = leading_blocks(L, nf)  # free rows first: L[free][:, free], L[free][:, nonfree]
    point_system: PointSystem | None = None
    if given.points is not None and len(given.points) and nf:
        mu = float(L_ff.diagonal().mean())
        point_system = PointSystem(given.points, F_int[given.points.faces], nf, n, mu)
        L_ff = (L_ff + point_system.matrix()).tocsr()
    gather = build_rhs_gather(cells, numbering.free, n)
    active = np.flatnonzero(np.bincount(gather.cell, minlength=cells.n_cells))

    fit, addons, active = _attach_addons(cells, numbering, energy, given.alpha, float(areas.sum()), pair_weights,
                                         assembly.region, point_system, active)
    inactive = InactiveCells(cells, active, numbering.constrained, rest)
    following = None
    if loose == "follow" and parts:
        placed = np.zeros(n, dtype=bool)
        placed[F_int.ravel()] = True
        placed[inv[np.concatenate(parts)]] = False
        following = FollowingParts(rest, [inv[p] for p in parts], np.flatnonzero(placed))

    # Step 5: the factorisation, once per constraint set
    factor = None
    if nf:
        try:
            factor = factorize(L_ff, backend, permutation=ordering)
            if point_system is not None:
                point_system.prepare(factor.solve)
        except NotPositiveDefiniteError as exc:
            raise singular_system_error(cells, energy, given.stiffness, str(exc)) from exc
    return Prepared(V=given.V, F=F, domain=domain, energy_type=energy, weight_type=weights, alpha=given.alpha,
                    constrained=given.constrained, roi=given.roi, stiffness=given.stiffness, points=given.points,
                    free=free, held=held, nonfree=nonfree, loose=loose, loose_parts=parts, following=following,
                    numbering=numbering, elements=F_int, bounds=bounds, diagonal=diagonal,
                    origin=origin, rest=rest, areas=areas, cells=cells, cell_order=cell_order,
                    non_negative=non_negative, matrix=L_ff.tocsr(), L_fn=L_fn, coupling=SparseRowsProduct(L_fn),
                    gather=gather, active=active, rotation_fit=fit, addons=addons, point_system=point_system,
                    inactive=inactive, factor=factor)
