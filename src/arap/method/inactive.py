"""Energy of the cells that no free vertex touches: constant during a solve, recomputed only where targets moved.

A cell whose edge terms all join non-free vertices (constrained or held) takes no part in the iterations: its
positions are fixed by the targets. Its energy still counts in the reported total. It is computed at rest once; for
new targets only the cells touching a constrained vertex whose target changed since the previous call are
recomputed, and the value is cached for the targets it was computed for (a settle or a capped drag calls
:meth:`InactiveCells.energy` with the same targets again).

A drag moves a handle group by one rigid motion, and a cell's energy does not change when all its vertices move by
one rigid motion (the best rotation absorbs it). So when the changed targets are one rigid motion of the previous
ones (checked to round-off), only the cells that also hold an unchanged vertex are recomputed: usually none.
"""

from __future__ import annotations

from collections.abc import Callable

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)
from arap.meshes.mesh import bounding_box
from arap.method.cells import Cells
from arap.method.horn import best_rotation
from arap.method.local_step import local_step
from arap.method.rotations import identity_rotations

__all__ = ["RIGID_TOLERANCE", "InactiveCells"]

#: Changed targets count as one rigid motion of the previous ones when it maps every one of them to within this
#: fraction of the rest shape's bounding-box diagonal (round-off of a transform applied in float64).
RIGID_TOLERANCE = 1e-12


class InactiveCells:
    """The cells outside a solver's active set and their energies at the last targets seen.

    Parameters
    ----------
    cells : Cells
    active : (k,) int array
        The cells the iterations fit (every cell with a term on a free vertex).
    constrained : (c,) int array
        Constrained vertices, in the order of the targets.
    V : (n, 3) float64 array
        Rest positions.
    fit : callable or None
        ``fit(cells, cell_ids, U, R, E)``: the local step that gives the cells' energies (None:
        :func:`arap.method.local_step.local_step`, the best rotations; a variant's must also leave a cell's energy
        unchanged when all its vertices move by one rigid motion).

    Attributes
    ----------
    recomputed : int
        Cells whose energy the last call of :meth:`energy` computed (for tests and benchmarks).
    """

    def __init__(self, cells: Cells, active: NDArray[np.integer], constrained: NDArray[np.integer],
                 V: NDArray[np.float64], fit: Callable[..., float] | None = None) -> None:
        n = len(V)
        self._fit = local_step if fit is None else fit
        nc = cells.n_cells
        self._cells = cells
        self._constrained = constrained
        is_active = np.zeros(nc, dtype=bool)
        is_active[active] = True
        counts = np.diff(cells.ptr)
        self._inactive = np.flatnonzero(~is_active)
        terms = np.flatnonzero(np.repeat(~is_active, counts))  # (a cell per term would take 8 bytes a term)
        self._term_cell = np.repeat(self._inactive, counts[self._inactive])
        self._a = cells.a[terms]
        self._b = cells.b[terms]
        self._R = identity_rotations(nc)  # the rest pose's rotations: where later fits start
        self._E = np.zeros(nc)  # energy of every inactive cell at the cached targets
        if len(self._inactive):
            self._fit(cells, self._inactive, V, self._R, self._E)
        box = bounding_box(V) if n else np.zeros((2, 3))
        self._tolerance = RIGID_TOLERANCE * float(np.linalg.norm(box[1] - box[0]))
        self._n = n
        self._nc = nc
        self._targets = V[constrained].copy()
        self._value = float(self._E[self._inactive].sum())
        self._sets: tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int64]] | None = None
        self.recomputed = 0

    def energy(self, U: NDArray[np.float64], targets: NDArray[np.float64]) -> float:
        """Energy of the inactive cells with the constrained vertices at ``targets``.

        Parameters
        ----------
        U : (n, 3) float64 array
            Positions (the non-free rows are read: constrained vertices at ``targets``, held ones at rest).
        targets : (c, 3) float64 array

        Returns
        -------
        float
            The sum over the inactive cells of their energy at ``U``.
        """
        self.recomputed = 0
        if not len(self._inactive):
            return self._value
        changed = _changed_rows(self._targets, targets)
        if not changed.any():
            return self._value
        touched, mixed = self._cells_of(changed)
        cells = mixed if self._moved_rigidly(np.flatnonzero(changed), targets) else touched
        if len(cells):
            E = self._E
            self._fit(self._cells, cells, U, self._R, E)
            self.recomputed = len(cells)
            self._value = float(E[self._inactive].sum())
        self._targets = targets.copy()
        return self._value

    def _cells_of(self, changed: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The inactive cells holding a vertex whose target changed, and those of them also holding another
        non-free vertex (cached for the same changed targets: a drag changes the same ones on every call)."""
        sets = self._sets
        if sets is not None and np.array_equal(sets[0], changed):
            return sets[1], sets[2]
        moved = np.zeros(self._n, dtype=bool)
        moved[self._constrained[changed]] = True
        moved_a, moved_b = moved[self._a], moved[self._b]
        is_touched = np.zeros(self._nc, dtype=bool)
        is_touched[self._term_cell[moved_a | moved_b]] = True
        is_mixed = np.zeros(self._nc, dtype=bool)
        is_mixed[self._term_cell[~(moved_a & moved_b)]] = True
        touched = np.flatnonzero(is_touched)
        mixed = np.flatnonzero(is_touched & is_mixed)
        self._sets = (changed, touched, mixed)
        return touched, mixed

    def _moved_rigidly(self, rows: NDArray[np.int64], targets: NDArray[np.float64]) -> bool:
        """True when one rigid motion maps the previous targets of ``rows`` to their new ones (to round-off)."""
        return bool(_rigid_fit_miss(self._targets, targets, rows) <= self._tolerance)


@nb.njit(cache=True, nogil=True)
def _changed_rows(A, B):  # pragma: no cover - compiled
    out = np.empty(A.shape[0], np.bool_)
    for i in range(A.shape[0]):
        out[i] = A[i, 0] != B[i, 0] or A[i, 1] != B[i, 1] or A[i, 2] != B[i, 2]
    return out


@nb.njit(cache=True, nogil=True)
def _rigid_fit_miss(P, Q, rows):  # pragma: no cover - compiled
    # The rigid motion best mapping P[rows] to Q[rows] (centroids, and the rotation maximising tr(R H) for their
    # centred cross-covariance H = Σ (p − cp)(q − cq)ᵀ, by Horn's method: no LAPACK call, whose threads would
    # contend with the solver's), then the largest |R p + t − q| over the rows and coordinates.
    k = rows.shape[0]
    cp = np.zeros(3)
    cq = np.zeros(3)
    for r in range(k):
        i = rows[r]
        for a in range(3):
            cp[a] += P[i, a]
            cq[a] += Q[i, a]
    cp /= k
    cq /= k
    H = np.zeros((3, 3))
    for r in range(k):
        i = rows[r]
        for a in range(3):
            pa = P[i, a] - cp[a]
            for b in range(3):
                H[a, b] += pa * (Q[i, b] - cq[b])
    R = np.empty((3, 3))
    best_rotation(H, R)
    worst = 0.0
    for r in range(k):
        i = rows[r]
        for a in range(3):
            d = abs(R[a, 0] * (P[i, 0] - cp[0]) + R[a, 1] * (P[i, 1] - cp[1]) + R[a, 2] * (P[i, 2] - cp[2])
                    + cq[a] - Q[i, a])
            if d > worst:
                worst = d
    return worst
