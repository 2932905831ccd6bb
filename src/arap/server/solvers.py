"""The factorised solvers of a studio session, kept for the constraint sets used last (so that undo across a
selection change does not factorise again)."""

from __future__ import annotations

import logging
from collections import OrderedDict
from typing import Any

import numpy as np

import arap
from arap.errors import ArapError
from arap.server.constraints import ConstraintSet
from arap.server.records import Params
from arap.server.session_errors import ConstraintsRejected

__all__ = ["SOLVER_CACHE_VERTICES", "SolverCache"]

logger = logging.getLogger(__name__)

SOLVER_CACHE_VERTICES = 200_000
"""Meshes up to this size keep two factorised solvers (undo across a selection change is instant)."""


class SolverCache:
    """Solvers by (rest pose, energy, weights, alpha, loose parts, constraint set), the least recently used dropped
    first."""

    def __init__(self) -> None:
        self._solvers: OrderedDict[tuple[Any, ...], arap.ArapSolver] = OrderedDict()

    def clear(self) -> None:
        """Drop every solver (a new mesh)."""
        self._solvers.clear()

    def get(self, rest_id: int, V: np.ndarray, F: np.ndarray, cs: ConstraintSet,
            params: Params) -> arap.ArapSolver | None:
        """A factorised solver for the constraint set on the rest pose ``V`` (numbered ``rest_id``), or None when
        nothing is constrained.

        Raises
        ------
        ConstraintsRejected
            When the solver rejects the constraints.
        """
        if cs.is_empty:
            return None
        alpha = params.alpha if params.energy == "smooth_rotations" else None  # other energies ignore it
        key = (rest_id, params.energy, params.weights, alpha, params.loose, cs.solver_digest())
        solver = self._solvers.get(key)
        if solver is not None:
            self._solvers.move_to_end(key)
            return solver
        try:
            solver = arap.ArapSolver(V, F, cs.constrained, energy=params.energy, weights=params.weights,
                                     roi=cs.roi, alpha=params.alpha, stiffness=cs.stiffness, points=cs.points,
                                     loose=params.loose)
        except ArapError as exc:
            raise ConstraintsRejected(str(exc)) from exc
        logger.debug("factorised %d free vertices in %.1f ms", solver.n_free, 1000 * solver.factor_seconds)
        self._solvers[key] = solver
        keep = 2 if len(V) <= SOLVER_CACHE_VERTICES else 1
        while len(self._solvers) > keep:
            self._solvers.popitem(last=False)
        return solver
