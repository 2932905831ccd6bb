"""The ARAP energy of a deformed surface against its rest pose."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arap.errors import ArapError
from arap.meshes._geometry import barycentric_areas
from arap.meshes.domain import Domain, check_domain
from arap.meshes.mesh import MeshLike
from arap.method.assembly import assemble, check_energy_for
from arap.method.cells import Cells
from arap.method.local_step import local_step
from arap.method.rigid import RigidRegions
from arap.method.rotations import identity_rotations
from arap.method.smooth import SmoothRotations
from arap.method.stiffness import check_stiffness
from arap.options import (
    DEFAULT_ALPHA,
    DEFAULT_ELEMENT_ENERGY,
    DEFAULT_ENERGY,
    DEFAULT_WEIGHTS,
    EnergyType,
    WeightType,
    check_alpha,
    check_energy_and_weights,
)

__all__ = ["arap_energy", "cell_distortion", "cell_energies", "distortion_from_cells"]


def _inputs(V: Any, F: Any, U: Any, energy: EnergyType | None) -> tuple[Domain, NDArray[np.float64], EnergyType]:
    """Rest mesh, deformed positions (in the solver's coordinates) and the energy (None: the mesh's default) from
    arrays or mesh objects (``f(mesh, U)`` leaves out ``F``)."""
    if U is None and not isinstance(V, np.ndarray | list | tuple) and F is not None:
        F, U = None, F
    if U is None:
        raise ArapError("U (the deformed positions) is missing")
    domain = check_domain(V, F, elements=energy == "elements")
    if energy is None:
        energy = DEFAULT_ELEMENT_ENERGY if domain.kind in ("planar", "solid") else DEFAULT_ENERGY
    check_energy_for(energy, domain.kind)
    raw = getattr(U, "vertices", None)
    if raw is None:
        raw = getattr(U, "points", U)  # a mesh object: trimesh's vertices, meshio's and pyvista's points
    X = np.ascontiguousarray(raw, dtype=np.float64)
    shape = (len(domain.V), domain.columns)
    if X.shape != shape:
        raise ArapError(f"U must have the shape of V {shape}, got {X.shape}")
    if not np.isfinite(X).all():
        raise ArapError("U has non-finite coordinates")
    return domain, domain.lift(X, "U", ArapError), energy


ROUNDS = 1000
"""Most rounds (a preconditioned rotation step and a block-coordinate sweep) :func:`cell_energies` runs for the
rotations of ``smooth_rotations``; they stop once the energy no longer falls, in a few dozen rounds on the shared
scans."""


def _settle_rotations(cells: Cells, V: NDArray[np.float64], F: NDArray[np.int64], U: NDArray[np.float64],
                      R: NDArray[np.float64], E: NDArray[np.float64], alpha: float,
                      pair_weights: NDArray[np.float64]) -> None:
    """Relax the SR-ARAP rotations (preconditioned steps and sweeps) until the energy stops falling, from the
    per-cell rotations in ``R`` and from the one rotation that best maps ``V`` onto ``U`` (the solver's cold start),
    and keep the lower; ``R`` and ``E`` (each cell's data energy plus its rotation term) get the result.

    With negative cotangent weights a cell's own best rotation can be far from its neighbours' even at rest (on the
    camel head the per-cell start settled at 20.8 where the identity gives 0): the coupled rotations then stay in a
    much higher state than the solver's."""
    areas = barycentric_areas(V, F)
    smooth = SmoothRotations(cells, float(areas.sum()), check_alpha(alpha), pair_weights)
    best = np.inf
    found = (R.copy(), E.copy())
    for start in ("cells", "rigid"):
        Rs, Es, term = R.copy(), E.copy(), np.zeros(len(V))
        if start == "rigid":
            smooth.start(V, U, areas, Rs)
        previous = value = np.inf
        for _ in range(ROUNDS):
            value = smooth.relax(U, Rs, Es, term, 1, steps=1)
            if previous - value <= 1e-14 * abs(value):
                break
            previous = value
        if value < best:
            best = value
            smooth.rotation_term(Rs, term)  # each cell's own sum
            found = (Rs, Es + term)
    R[:], E[:] = found


def cell_energies(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    U: NDArray[np.floating] | MeshLike | None = None,
    energy: EnergyType | None = None,
    weights: WeightType = DEFAULT_WEIGHTS,
    stiffness: ArrayLike | None = None,
    alpha: float = DEFAULT_ALPHA,
) -> NDArray[np.float64]:
    """Energy of every cell with its optimal rotation.

    Parameters
    ----------
    V : (n, 3) float array or MeshLike
        Rest positions, or the rest mesh as an object with ``vertices`` and ``faces`` (then leave out ``F``:
        ``cell_energies(mesh, U)``).
    F : (m, 3) int array
    U : (n, 3) float array or MeshLike
        Deformed positions (or a mesh object holding them).
    energy : {"spokes_and_rims", "spokes", "smooth_rotations", "elements"} or None
        Cell definition: spokes and rims (Chao et al. 2010, the default for surfaces), the paper's one-ring spokes
        (Sorkine & Alexa 2007), or one cell per triangle or tetrahedron (``elements``, the default for planar meshes
        given with two coordinates and for tetrahedra; see :mod:`arap.method.elements`). None: the mesh's default.
    weights : {"cotangent", "clamped", "uniform"}
    stiffness : (n,) array of float or None
        Cell weights ``w_i`` (see :class:`arap.ArapSolver`): each cell's energy is multiplied by its weight, and
        the cells of a rigid region (``inf``) share one rotation.
    alpha : float
        Weight of the rotation term of ``smooth_rotations`` (see :mod:`arap.method.smooth`); each cell then also carries
        ``αA Σ_j w⁺_ij ‖R_i − R_j‖²``, with rotations found by block-coordinate sweeps until the energy settles.

    Returns
    -------
    (n,) float64 array, or (m,) for ``elements``
        ``E_i = w_i min_R Σ w ‖(p'_a − p'_b) − R (p_a − p_b)‖²`` over the cell's terms: one per vertex, or one per
        element in the order of ``F``.

    Raises
    ------
    MeshError
        The rest mesh is unusable.
    ArapError
        ``U`` is missing, of another shape than ``V`` or not finite.
    OptionError
        Unknown energy or weights.

    Example
    -------
    >>> import arap
    >>> V, F = arap.builtin_mesh("bar")
    >>> bool(abs(cell_energies(V, F, V)).max() < 1e-9)
    True
    """
    return _cells_and_energies(V, F, U, energy, weights, stiffness, alpha)[1]


def _cells_and_energies(V: Any, F: Any, U: Any, energy: EnergyType | None, weights: WeightType,
                        stiffness: ArrayLike | None, alpha: float) -> tuple[Cells, NDArray[np.float64]]:
    """The (unscaled) cells of the rest mesh and :func:`cell_energies` of ``U``."""
    check_energy_and_weights(DEFAULT_ENERGY if energy is None else energy, weights)
    domain, Uc, energy = _inputs(V, F, U, energy)
    Vc, Fc = domain.V, domain.elements
    scale, rigid = (None, None) if stiffness is None else check_stiffness(stiffness, len(Vc))
    assembly = assemble(Vc, Fc, domain.graph_faces, energy, weights, domain.planar, scale, rigid)
    rest, cells = assembly.rest, assembly.cells
    nc = cells.n_cells
    E = np.empty(nc)
    R = identity_rotations(nc)
    local_step(cells, np.arange(nc), Uc, R, E)
    if energy == "smooth_rotations":
        _settle_rotations(cells, Vc, Fc, Uc, R, E, alpha, np.maximum(rest.w, 0.0))
    if assembly.region is not None:
        RigidRegions(cells, assembly.region, np.arange(nc)).share(Uc, R, E)
    return rest, E


def cell_distortion(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    U: NDArray[np.floating] | MeshLike | None = None,
    energy: EnergyType | None = None,
    weights: WeightType = DEFAULT_WEIGHTS,
    stiffness: ArrayLike | None = None,
    alpha: float = DEFAULT_ALPHA,
) -> NDArray[np.float64]:
    """How far every cell is from rigid: its energy over its weighted rest size.

    ``D_i = E_i / Σ w ‖p_a − p_b‖²`` over the terms of cell ``i``, with ``E_i`` from :func:`cell_energies`. The
    ratio does not depend on the mesh's scale or resolution: 0 for a rigid motion of the cell, about ``s²`` for a
    cell whose edges all stretched or shrank by a relative ``s``. Cells whose rest sum is not positive (possible
    with ``energy="spokes"`` on obtuse triangles) get 0.

    Parameters
    ----------
    V : (n, 3) float array or MeshLike
        Rest positions, or the rest mesh object (then leave out ``F``: ``cell_distortion(mesh, U)``).
    F : (m, 3) int array
    U : (n, 3) float array or MeshLike
        Deformed positions.
    energy : {"spokes_and_rims", "spokes", "smooth_rotations", "elements"} or None
        See :func:`cell_energies`.
    weights : {"cotangent", "clamped", "uniform"}
    stiffness : (n,) array of float or None
        Cell weights (see :func:`cell_energies`); they scale the energy, not the rest size.
    alpha : float
        Weight of the rotation term of ``smooth_rotations`` (see :func:`cell_energies`).

    Returns
    -------
    (n,) float64 array, or (m,) for ``elements``

    Raises
    ------
    MeshError, ArapError, OptionError
        As :func:`cell_energies`.

    Example
    -------
    >>> import arap
    >>> V, F = arap.builtin_mesh("bar")
    >>> bool(cell_distortion(V, F, 2.0 * V).max() > 0.5)
    True
    """
    rest, E = _cells_and_energies(V, F, U, energy, weights, stiffness, alpha)
    out = np.zeros_like(E)
    ok = rest.rest_sq > 0
    out[ok] = E[ok] / rest.rest_sq[ok]
    return out


def distortion_from_cells(cells: Cells, V: NDArray[np.float64], F: NDArray[np.int64], U: NDArray[np.float64],
                          energy: EnergyType = DEFAULT_ENERGY, alpha: float = DEFAULT_ALPHA) -> NDArray[np.float64]:
    """:func:`cell_distortion` (without stiffness) from cells built beforehand, for repeated evaluation on one rest
    mesh (building the cells costs far more than the rotations).

    Parameters
    ----------
    cells : Cells
        ``build_cells(V, F, energy, weights)`` of the checked rest mesh (or its element cells,
        :func:`arap.method.elements.element_cells`).
    V : (n, 3) float64 array
        Rest positions, as checked by :func:`arap.check_mesh`.
    F : (m, 3) or (m, 4) int64 array
    U : (n, 3) float64 array
        Deformed positions (finite, of the shape of ``V``).
    energy : {"spokes_and_rims", "spokes", "smooth_rotations", "elements"}
        The energy ``cells`` were built for.
    alpha : float
        Weight of the rotation term of ``smooth_rotations``.

    Returns
    -------
    (n,) float64 array
    """
    nc = cells.n_cells
    E = np.empty(nc)
    R = identity_rotations(nc)
    local_step(cells, np.arange(nc), U, R, E)
    if energy == "smooth_rotations":
        _settle_rotations(cells, V, F, U, R, E, alpha, np.maximum(cells.w, 0.0))
    out = np.zeros_like(E)
    ok = cells.rest_sq > 0
    out[ok] = E[ok] / cells.rest_sq[ok]
    return out


def arap_energy(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    U: NDArray[np.floating] | MeshLike | None = None,
    energy: EnergyType | None = None,
    weights: WeightType = DEFAULT_WEIGHTS,
    stiffness: ArrayLike | None = None,
    alpha: float = DEFAULT_ALPHA,
) -> float:
    """The ARAP energy of ``U`` against the rest pose ``V``, with optimal rotations.

    ``E = Σ_i Σ_{(a,b)∈cell i} w_ab ‖(p'_a − p'_b) − R_i (p_a − p_b)‖²``. The default cells, spokes and rims (Chao et
    al. 2010), hold every edge of the triangles around a vertex, weighted by ``½ cot`` of the opposite angle in that
    triangle; the energy is then a sum of per-triangle Dirichlet energies, never negative, and zero at rest.
    ``energy="spokes"`` is the paper's (Sorkine & Alexa 2007): the one-ring edges with ``w_ij = ½(cot α + cot β)``.
    With obtuse triangles some of those weights are negative and that energy can be below zero, even at rest.

    Parameters
    ----------
    V : (n, 3) float array or MeshLike
        Rest positions, or the rest mesh object (then leave out ``F``: ``arap_energy(mesh, U)``).
    F : (m, 3) int array
    U : (n, 3) float array or MeshLike
        Deformed positions.
    energy : {"spokes_and_rims", "spokes", "smooth_rotations", "elements"} or None
        See :func:`cell_energies`.
    weights : {"cotangent", "clamped", "uniform"}
    stiffness : (n,) array of float or None
        Cell weights (see :func:`cell_energies`).
    alpha : float
        Weight of the rotation term of ``smooth_rotations`` (see :func:`cell_energies`).

    Returns
    -------
    float

    Raises
    ------
    MeshError, ArapError, OptionError
        As :func:`cell_energies`.

    Examples
    --------
    A rigid motion costs nothing; a stretch does:

    >>> import numpy as np, arap
    >>> V, F = arap.sphere(1)
    >>> turned = V @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) + 2.0
    >>> bool(abs(arap.arap_energy(V, F, turned)) < 1e-9), bool(arap.arap_energy(V, F, V * [1.0, 1.0, 1.5]) > 0)
    (True, True)
    """
    return float(cell_energies(V, F, U, energy, weights, stiffness, alpha).sum())
