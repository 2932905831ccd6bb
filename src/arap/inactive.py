"""Energy of the cells that no free vertex touches: constant during a solve, recomputed only where handles moved.

A cell whose edge terms all join non-free vertices (constrained or held) takes no part in the iterations: its
positions are fixed by the targets. Its energy still counts in the reported total. At rest it is computed once; for
new targets only the cells touching a constrained vertex that left its rest position are recomputed, and the value
is cached for the targets it was computed for (a settle or a capped drag calls :meth:`InactiveCells.energy` with
the same targets again).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.cells import Cells
from arap.covariance import local_step

__all__ = ["InactiveCells"]


class InactiveCells:
    """The cells outside a solver's active set and their rest energies.

    Parameters
    ----------
    cells : Cells
    active : (k,) int array
        The cells the iterations fit (every cell with a term on a free vertex).
    constrained : (c,) int array
        Constrained vertices, in the order of the targets.
    V : (n, 3) float64 array
        Rest positions.
    """

    def __init__(self, cells: Cells, active: NDArray[np.integer], constrained: NDArray[np.integer],
                 V: NDArray[np.float64]) -> None:
        n = len(V)
        self._cells = cells
        self._constrained = constrained
        is_active = np.zeros(n, dtype=bool)
        is_active[active] = True
        tcell = cells.cell_of_term()
        terms = np.flatnonzero(~is_active[tcell])
        self._any = len(terms) > 0
        self._term_cell = tcell[terms]
        self._a = cells.a[terms]
        self._b = cells.b[terms]
        self._R = np.empty((n, 3, 3))
        self._E = np.zeros(n)
        rest_E = np.zeros(n)
        inactive = np.flatnonzero(~is_active)
        if len(inactive):
            local_step(cells, inactive, V, np.empty((n, 3, 3)), rest_E)
        self._rest_E = rest_E
        self._rest_sum = float(rest_E[inactive].sum())
        is_constrained = np.zeros(n, dtype=bool)
        is_constrained[constrained] = True
        # Inactive cells that some constrained vertex touches: those whose energy changes when all handles move.
        touched_by_any = np.unique(self._term_cell[is_constrained[self._a] | is_constrained[self._b]])
        self._touched_by_any = (touched_by_any, float(rest_E[touched_by_any].sum()))
        self._rest_targets = V[constrained]
        self._n = n
        self._cache: tuple[NDArray[np.float64], float] | None = None
        self._touched_cache: tuple[NDArray[np.bool_], tuple[NDArray[np.int64], float]] | None = None

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
            Only cells touching a constrained vertex away from its rest position differ from their rest energy.
        """
        if not self._any:
            return 0.0
        cache = self._cache
        if cache is not None and np.array_equal(cache[0], targets):
            return cache[1]
        moved_slots = np.any(targets != self._rest_targets, axis=1)
        if moved_slots.all():
            touched = self._touched_by_any
        elif self._touched_cache is not None and np.array_equal(self._touched_cache[0], moved_slots):
            touched = self._touched_cache[1]  # the same handles moved again (a drag)
        else:
            moved = np.zeros(self._n, dtype=bool)
            moved[self._constrained[moved_slots]] = True
            is_touched = np.zeros(self._n, dtype=bool)
            is_touched[self._term_cell[moved[self._a] | moved[self._b]]] = True
            cells = np.flatnonzero(is_touched)
            touched = (cells, float(self._rest_E[cells].sum()))
            self._touched_cache = (moved_slots, touched)
        value = self._rest_sum
        if len(touched[0]):  # their energy now, instead of at rest
            value += local_step(self._cells, touched[0], U, self._R, self._E) - touched[1]
        self._cache = (targets.copy(), value)
        return value
