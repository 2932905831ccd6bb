"""The ARAP energy of a deformed surface against its rest pose."""

from __future__ import annotations

import numpy as np

from arap.cells import DEFAULT_ENERGY, build_cells
from arap.covariance import local_step
from arap.mesh import check_mesh
from arap.weights import DEFAULT_WEIGHTS


def cell_energies(
    V: np.ndarray, F: np.ndarray, U: np.ndarray, energy: str = DEFAULT_ENERGY, weights: str = DEFAULT_WEIGHTS
) -> np.ndarray:
    """Energy of every cell with its optimal rotation.

    Parameters
    ----------
    V : (n, 3) float array
        Rest positions.
    F : (m, 3) int array
    U : (n, 3) float array
        Deformed positions.
    energy : {"spokes_and_rims", "spokes"}
        Cell definition: spokes and rims (Chao et al. 2010, the default) or the paper's one-ring spokes (Sorkine &
        Alexa 2007).
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    (n,) float64 array
        ``E_i = min_R Σ w ‖(p'_a − p'_b) − R (p_a − p_b)‖²`` over the cell's terms.
    """
    V, F = check_mesh(V, F)
    U = np.ascontiguousarray(U, dtype=np.float64)
    if U.shape != V.shape:
        raise ValueError(f"U must have the shape of V {V.shape}, got {U.shape}")
    cells = build_cells(V, F, energy, weights)
    n = len(V)
    E = np.empty(n)
    local_step(cells, np.arange(n), U, np.empty((n, 3, 3)), E)
    return E


def arap_energy(
    V: np.ndarray, F: np.ndarray, U: np.ndarray, energy: str = DEFAULT_ENERGY, weights: str = DEFAULT_WEIGHTS
) -> float:
    """The ARAP energy of ``U`` against the rest pose ``V``, with optimal rotations.

    ``E = Σ_i Σ_{(a,b)∈cell i} w_ab ‖(p'_a − p'_b) − R_i (p_a − p_b)‖²``. The default cells, spokes and rims (Chao et
    al. 2010), hold every edge of the triangles around a vertex, weighted by ``½ cot`` of the opposite angle in that
    triangle; the energy is then a sum of per-triangle Dirichlet energies, never negative, and zero at rest.
    ``energy="spokes"`` is the paper's (Sorkine & Alexa 2007): the one-ring edges with ``w_ij = ½(cot α + cot β)``.
    With obtuse triangles some of those weights are negative and that energy can be below zero, even at rest.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    U : (n, 3) float array
    energy : {"spokes_and_rims", "spokes"}
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    float
    """
    return float(cell_energies(V, F, U, energy, weights).sum())
