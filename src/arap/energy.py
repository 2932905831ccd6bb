"""The ARAP energy of a deformed surface against its rest pose."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.cells import DEFAULT_ENERGY, ENERGY_TYPES, EnergyType, build_cells
from arap.covariance import local_step
from arap.errors import ArapError, OptionError
from arap.mesh import MeshLike, check_mesh, is_mesh_like, mesh_arrays
from arap.weights import DEFAULT_WEIGHTS, WEIGHT_TYPES, WeightType

__all__ = ["arap_energy", "cell_energies"]


def _inputs(V: Any, F: Any, U: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest mesh and deformed positions from arrays or mesh objects (``f(mesh, U)`` leaves out ``F``)."""
    if U is None and is_mesh_like(V) and F is not None:
        F, U = None, F
    if U is None:
        raise ArapError("U (the deformed positions) is missing")
    V, F = check_mesh(*mesh_arrays(V, F))
    U = np.ascontiguousarray(U.vertices if is_mesh_like(U) else U, dtype=np.float64)
    if U.shape != V.shape:
        raise ArapError(f"U must have the shape of V {V.shape}, got {U.shape}")
    if not np.isfinite(U).all():
        raise ArapError("U has non-finite coordinates")
    return V, F, U


def cell_energies(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    U: NDArray[np.floating] | MeshLike | None = None,
    energy: EnergyType = DEFAULT_ENERGY,
    weights: WeightType = DEFAULT_WEIGHTS,
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
    energy : {"spokes_and_rims", "spokes"}
        Cell definition: spokes and rims (Chao et al. 2010, the default) or the paper's one-ring spokes (Sorkine &
        Alexa 2007).
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    (n,) float64 array
        ``E_i = min_R Σ w ‖(p'_a − p'_b) − R (p_a − p_b)‖²`` over the cell's terms.

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
    if energy not in ENERGY_TYPES:
        raise OptionError(f"unknown energy {energy!r}; expected one of {ENERGY_TYPES}")
    if weights not in WEIGHT_TYPES:
        raise OptionError(f"unknown weights {weights!r}; expected one of {WEIGHT_TYPES}")
    V, F, U = _inputs(V, F, U)
    cells = build_cells(V, F, energy, weights)
    n = len(V)
    E = np.empty(n)
    local_step(cells, np.arange(n), U, np.empty((n, 3, 3)), E)
    return E


def arap_energy(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    U: NDArray[np.floating] | MeshLike | None = None,
    energy: EnergyType = DEFAULT_ENERGY,
    weights: WeightType = DEFAULT_WEIGHTS,
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
    energy : {"spokes_and_rims", "spokes"}
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    float

    Raises
    ------
    MeshError, ArapError, OptionError
        As :func:`cell_energies`.
    """
    return float(cell_energies(V, F, U, energy, weights).sum())
