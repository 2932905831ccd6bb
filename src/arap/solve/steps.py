"""Single steps of a prepared solver (:mod:`arap.solve.prepared`), for analysis and tests: the local step alone, the
energy of given positions (and rotations), the global step alone and the reduced matrix, in the caller's vertex
order. None changes the state of a solve."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.method.cells import system_matrix
from arap.method.local_step import assemble_rhs, covariances
from arap.method.rotations import identity_rotations
from arap.solve.iteration import rhs_constant
from arap.solve.prepared import Prepared

__all__ = ["energy_of", "fit_rotations", "global_step", "reduced_matrix"]


def fit_rotations(p: Prepared, U: object, start: NDArray[np.float64]) -> NDArray[np.float64]:
    """Local step alone: the optimal rotation of every cell for positions ``U`` (caller's order), shape (n, 3, 3).

    Coupled rotations (``smooth_rotations``) are one block-coordinate sweep from ``start`` (internal order), which
    never raises the energy; the other fits ignore it.
    """
    X = p.to_internal(p.check_positions(U, "U"))
    nc = p.cells.n_cells
    R = identity_rotations(nc)
    if p.rotation_fit.coupled:
        R[:] = start
    E = np.empty(nc)
    p.rotation_fit.fit_all(X, R, E)
    for addon in p.addons:
        addon.after_fit_all(X, R, E)
    return p.cells_to_caller(R)


def energy_of(p: Prepared, U: object, R: object | None, current: NDArray[np.float64]) -> float:
    """Energy of positions ``U`` with rotations ``R`` (None: the optimal ones; for coupled rotations those of
    :func:`fit_rotations` from ``current``), summed over all cells."""
    if R is None and p.rotation_fit.coupled:
        R = fit_rotations(p, U, current)
    X = p.to_internal(p.check_positions(U, "U"))
    if R is None:
        E = np.empty(p.cells.n_cells)
        R_opt = identity_rotations(p.cells.n_cells)
        p.rotation_fit.fit_all(X, R_opt, E)
        for addon in p.addons:
            addon.after_fit_all(X, R_opt, E)
        return float(E.sum())
    cells = p.cells
    d = X[cells.a] - X[cells.b]
    cur = float(np.dot(cells.w, np.einsum("ij,ij->i", d, d)))
    S = covariances(cells, X)
    R_int = p.cells_to_internal(np.asarray(R, dtype=np.float64))
    value = cur + float(cells.rest_sq.sum()) - 2.0 * float(np.einsum("cij,cji->", R_int, S))
    return value + p.rotation_fit.rotation_energy(R_int)


def global_step(p: Prepared, R: object, targets: object, point_targets: object = None) -> NDArray[np.float64]:
    """Global step alone: positions minimising the energy for fixed rotations ``R`` (n, 3, 3), shape (n, 3)."""
    T = p.check_targets(targets)
    fixed = p.fixed_positions(T)
    P = p.check_point_targets(point_targets)
    U = p.rest.copy()
    U[p.nf:] = fixed
    if p.factor is not None:
        rhs = np.empty((p.nf, 3))
        assemble_rhs(p.gather, p.cells_to_internal(np.asarray(R, dtype=np.float64)), rhs_constant(p, fixed, P), rhs)
        g = p.factor.solve(rhs)
        for addon in p.addons:
            correct = addon.corrector(P, fixed)
            if correct is not None:
                g = correct(g)
        U[:p.nf] = g
    return p.to_caller(U)


def reduced_matrix(p: Prepared) -> sp.csr_matrix:
    """The reduced global-step matrix ``L_ff`` (for inspection; rows in the solver's internal vertex order)."""
    L = system_matrix(p.cells, p.n)
    free = p.numbering.free
    return L[free][:, free].tocsr()
