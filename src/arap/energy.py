"""The ARAP energy of a deformed surface against its rest pose."""

from __future__ import annotations

import numpy as np

from arap.cells import build_cells
from arap.covariance import local_step
from arap.mesh import check_mesh


def cell_energies(
    V: np.ndarray, F: np.ndarray, U: np.ndarray, energy: str = "spokes", weights: str = "cotangent"
) -> np.ndarray:
    """Energy of every cell with its optimal rotation.

    Parameters
    ----------
    V : (n, 3) float array
        Rest positions.
    F : (m, 3) int array
    U : (n, 3) float array
        Deformed positions.
    energy : {"spokes", "spokes_and_rims"}
        Cell definition: the paper's one-ring spokes (Sorkine & Alexa 2007) or spokes and rims (Chao et al. 2010).
    weights : {"cotangent", "uniform"}

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
    V: np.ndarray, F: np.ndarray, U: np.ndarray, energy: str = "spokes", weights: str = "cotangent"
) -> float:
    """The ARAP energy of ``U`` against the rest pose ``V``, with optimal rotations (Sorkine & Alexa 2007).

    ``E = Σ_i Σ_{j∈N(i)} w_ij ‖(p'_i − p'_j) − R_i (p_i − p_j)‖²`` with cotangent weights by default. With obtuse
    triangles some weights are negative and the energy can be below zero, even at rest.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    U : (n, 3) float array
    energy : {"spokes", "spokes_and_rims"}
    weights : {"cotangent", "uniform"}

    Returns
    -------
    float
    """
    return float(cell_energies(V, F, U, energy, weights).sum())
