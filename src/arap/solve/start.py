"""Where a solve starts: the previous solution (warm), the rest pose, the rest pose moved by the targets' best-fit
rigid motion, whichever of these two has the lower energy, or positions given by the caller; and the rotations its
first global step uses.

The local/global iteration only descends to the nearest minimum, and from the rest pose it cannot undo a large
common rotation of all constraints: rotated 170°, the constrained vertices pull the surface through itself and the
iteration stalls far from the rigid motion (0.39 of the bounding-box diagonal off after 2,000 iterations, for us and
for libigl). Starting from the rest pose moved by the rigid motion that best maps the constrained vertices' rest
positions to their targets (weighted Procrustes, Kabsch 1976 with the reflection fix) is exact for such motions; the
solver takes it only when its energy is lower than the rest pose's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError
from arap.meshes._geometry import best_rigid_transform
from arap.options import START_NAMES
from arap.solve.indexing import assign_rows
from arap.solve.iteration import SolveState, local_energy
from arap.solve.prepared import Prepared

__all__ = ["cold_rotations", "rigid_start", "start_positions"]


def start_positions(
    p: Prepared, state: SolveState, T: NDArray[np.float64], fixed: NDArray[np.float64],
    initial: NDArray[np.float64] | str | None, timings: dict[str, float]
) -> tuple[NDArray[np.float64], float | None, str]:
    """Starting positions (internal order, non-free vertices at their fixed positions), their active-cell energy
    (None when the rotations in ``state.local.R`` were not fitted to them) and the name of the start.

    ``initial`` is already checked (an array in the internal numbering, relative to the origin), a start name or
    None. Leaves in ``state.local.R`` the rotations the first global step uses.
    """
    local = state.local
    if initial is None:
        if state.last is None:
            initial = "auto"
        else:
            U = state.last  # continued in place: the solver owns it, and the result is a copy
            if not state.rotations_fresh:
                local_energy(p, local, U, 0.0, timings)
            at_targets = assign_rows(U[p.nf:], fixed)
            E = p.rotation_fit.stored_energy(local, p.active) if at_targets else None
            return U, E, "warm"
    if isinstance(initial, str):
        if initial not in START_NAMES:
            raise OptionError(f"unknown initial {initial!r}; expected one of {START_NAMES}, an array or None")
        candidates = []
        if initial in ("auto", "rest"):
            U = p.rest.copy()
            U[p.nf:] = fixed
            candidates.append(("rest", U))
        if initial in ("auto", "rigid"):
            candidates.append(("rigid", rigid_start(p.rest, p.numbering.constrained, T, p.areas, fixed)))
        best: tuple[float, str, NDArray[np.float64], NDArray[np.float64]] | None = None
        for name, U in candidates:
            cold_rotations(p, state, U)
            E = local_energy(p, local, U, 0.0, timings)
            if best is None or E < best[0]:
                best = (E, name, U, local.R.copy() if len(candidates) > 1 else local.R)
        assert best is not None
        E, name, U, R = best
        if R is not local.R:
            local.R[:] = R
        return U, E, name
    U = np.asarray(initial)
    U[p.nf:] = fixed
    cold_rotations(p, state, U)
    return U, local_energy(p, local, U, 0.0, timings), "given"


def cold_rotations(p: Prepared, state: SolveState, U: NDArray[np.float64]) -> None:
    """Before a cold start: the rotations the first local step goes on from. Identities (the rotation fits start
    their search there, so that a cold start does not depend on earlier solves, to the last bit), or for
    ``smooth_rotations`` the start of the coupled local steps (:meth:`arap.method.smooth.SmoothRotations.start`)."""
    p.rotation_fit.cold(p.rest, U, p.areas, state.local.R)


def rigid_start(V: NDArray[np.float64], constrained: NDArray[np.integer], targets: NDArray[np.float64],
                areas: NDArray[np.float64], fixed: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rest pose ``V`` moved by the best-fit rigid motion of the constrained vertices to their ``targets``
    (weighted by ``areas``), with the last ``len(fixed)`` rows (the non-free vertices) set to ``fixed``.

    Example
    -------
    One free vertex (row 0) follows the three constrained ones, turned 90° about z and shifted by 5 along x:

    >>> V = np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0], [0, 0, 0]])
    >>> T = np.array([[5.0, 1, 0], [4, 0, 0], [5, 0, 0]])
    >>> (rigid_start(V, np.array([1, 2, 3]), T, np.ones(4), T).round(9) + 0.0).tolist()
    [[5.0, 0.0, 1.0], [5.0, 1.0, 0.0], [4.0, 0.0, 0.0], [5.0, 0.0, 0.0]]
    """
    nf = len(V) - len(fixed)
    U = V.copy()
    if len(constrained):
        R, t = best_rigid_transform(V[constrained], targets, areas[constrained])
        U[:nf] = V[:nf] @ R.T + t
    U[nf:] = fixed
    return U
