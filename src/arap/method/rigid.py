"""Rigid regions: every cell of a connected rigid region shares one rotation.

A vertex painted with an infinite stiffness belongs to a rigid region (a connected component of such vertices).
Large cell weights alone do not make a region rigid in practice: each cell's rotation is fitted on its own, and the
alternating local/global iteration needs many steps to turn a stiff region as one piece. Here the cells of a region
share one rotation, the best fit to the sum of their covariances (the local step's optimum under that constraint),
and their weights are :data:`arap.method.stiffness.RIGID_STIFFNESS`, so the global step keeps the region's edges at that
rotation of their rest vectors: the region moves as a rigid body, and the energy still never rises.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from arap.method.cells import Cells
from arap.method.planar import planar_rotations
from arap.method.rotations import rotations_from_covariances

__all__ = ["RIGID_TOLERANCE", "RigidRegions", "rigid_regions"]

RIGID_TOLERANCE = 1e-9
"""Tightest convergence tolerance of a solve with rigid regions (a smaller ``tolerance`` is raised to it). Their cell
weights (:data:`arap.method.stiffness.RIGID_STIFFNESS`) leave the plain step a rounding floor of a few 1e-10 of the
diagonal: a rigid band of the cactus bent by 1 rad reached 1e-9 in 207 iterations but never 3e-10 (3,000 iterations,
the step back at 2.6e-9)."""


@nb.njit(cache=True, nogil=True)
def _region_covariances(a, b, we, region, U, S):  # pragma: no cover - compiled
    """``S[r] += w e (p'_a − p'_b)ᵀ`` over the terms, ``r`` the region of each term's cell."""
    for t in range(a.shape[0]):
        r = region[t]
        for i in range(3):
            d = U[a[t], i] - U[b[t], i]
            for k in range(3):
                S[r, k, i] += we[t, k] * d


@nb.njit(cache=True, nogil=True)
def _term_energies(a, b, w, e, cell, region, U, R, E):  # pragma: no cover - compiled
    """``E[c] = Σ w ‖(p'_a − p'_b) − R_r e‖²`` over each cell's terms, term by term (``E`` zeroed for those cells)."""
    for t in range(a.shape[0]):
        E[cell[t]] = 0.0
    for t in range(a.shape[0]):
        r = region[t]
        total = 0.0
        for i in range(3):
            x = U[a[t], i] - U[b[t], i] - (R[r, i, 0] * e[t, 0] + R[r, i, 1] * e[t, 1] + R[r, i, 2] * e[t, 2])
            total += x * x
        E[cell[t]] += w[t] * total


def rigid_regions(F: NDArray[np.int64], rigid: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Label the connected regions of rigid vertices.

    Parameters
    ----------
    F : (m, 3) int array
    rigid : (n,) bool array

    Returns
    -------
    (n,) int64 array
        Region of each vertex, ``0..k-1``; ``-1`` for vertices that are not rigid.

    Example
    -------
    >>> F = np.array([[0, 1, 2], [2, 3, 4]])
    >>> rigid_regions(F, np.array([True, True, False, True, True])).tolist()
    [0, 0, -1, 1, 1]
    """
    n = len(rigid)
    a = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    b = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    keep = rigid[a] & rigid[b]
    graph = sp.coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    out = np.full(n, -1, dtype=np.int64)
    ids = np.flatnonzero(rigid)
    _, out[ids] = np.unique(labels[ids], return_inverse=True)
    return out


class RigidRegions:
    """The cells of each rigid region and the terms that build their shared rotation.

    Parameters
    ----------
    cells : Cells
    region : (n,) int array
        Region of each cell's vertex (``-1``: none), from :func:`rigid_regions`.
    cell_ids : (k,) int array
        Cells the local step updates; the others keep their own rotations.
    """

    def __init__(self, cells: Cells, region: NDArray[np.int64], cell_ids: NDArray[np.int64]) -> None:
        in_step = np.zeros(cells.n_cells, dtype=bool)
        in_step[cell_ids] = True
        term_cell = cells.cell_of_term()
        terms = np.flatnonzero((region[term_cell] >= 0) & in_step[term_cell])
        self.n_regions = int(region.max(initial=-1)) + 1
        self.cells = np.flatnonzero((region >= 0) & in_step)
        self.cell_region = region[self.cells]
        self._terms = terms
        self._term_cell = term_cell[terms]
        self._term_region = region[self._term_cell]
        self._a = cells.a[terms]
        self._b = cells.b[terms]
        self._we = cells.we[terms]
        self._w = cells.w[terms]
        nonzero = self._w != 0.0
        self._e = np.zeros_like(self._we)  # rest edge vectors, for energies without cancellation
        self._e[nonzero] = self._we[nonzero] / self._w[nonzero, None]
        self._n = cells.n_cells
        self._planar = cells.planar

    def share(self, U: NDArray[np.float64], R: NDArray[np.float64], E: NDArray[np.float64]) -> float:
        """Give every cell of a region the region's best rotation, after a local step fitted each on its own.

        Parameters
        ----------
        U : (n, 3) float array
            Current positions.
        R : (n, 3, 3) float array
            Rotations of the local step; the regions' cells are overwritten.
        E : (n,) float array
            Cell energies of the local step; the regions' cells are updated.

        Returns
        -------
        float
            Change of the total energy of the regions' cells (≥ 0 up to rounding: a shared rotation fits no cell
            better than its own; their energies are recomputed term by term, exactly).
        """
        if not len(self._terms):
            return 0.0
        S = np.zeros((self.n_regions, 3, 3))
        _region_covariances(self._a, self._b, self._we, self._term_region, U, S)
        shared = planar_rotations(S) if self._planar else rotations_from_covariances(S)
        # Σ w ‖e' − R e‖² term by term: the expanded form the local step uses would lose the small residuals of
        # rigid cells to cancellation between their large weighted terms.
        before = float(E[self.cells].sum())
        _term_energies(self._a, self._b, self._w, self._e, self._term_cell, self._term_region, U, shared, E)
        change = float(E[self.cells].sum()) - before
        R[self.cells] = shared[self.cell_region]
        return change
