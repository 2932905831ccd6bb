"""Constraint scenarios and measures of results shared by the solver tests."""

from __future__ import annotations

import numpy as np

from arap.constraints.scenarios import bend


def bend_constraints(V: np.ndarray, axis: int | None = None, share: float = 0.1, angle: float = 0.6,
                     shift: float = 0.15) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ``bend`` scenario of :mod:`arap.constraints.scenarios` as ``fixed, handle, constrained, targets``."""
    s = bend(V, axis=axis, share=share, angle=angle, shift=shift)
    return s.fixed, s.handles, s.constrained, s.targets


def random_rigid(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    return Q, rng.normal(size=3)


def rigid_misfit(V: np.ndarray, U: np.ndarray, idx: np.ndarray) -> float:
    """Largest distance of ``U[idx]`` from the best rigid motion of ``V[idx]``, in bounding-box diagonals."""
    P, Q = U[idx], V[idx]
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    u, _, vt = np.linalg.svd((Q - qc).T @ (P - pc))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return float(np.abs((Q - qc) @ R.T + pc - P).max() / np.linalg.norm(np.ptp(V, axis=0)))


ROUNDING = 1e-12
"""Relative slack of comparisons that round-off decides: another CPU's vector width or summation order, or another
Cholesky backend (``ARAP_BACKEND``, see :mod:`arap.sparse.linsolve`), moves results by about 1e-15 of their size per
operation; a comparison across code paths or of an energy "never rising" allows this much of the values' size."""


def rises(energies: np.ndarray | list[float], rel: float = ROUNDING, tiny: float = 1e-300) -> np.ndarray:
    """Steps ``k`` where ``energies[k + 1]`` rises above ``energies[k]`` by more than round-off: more than ``rel``
    times the largest energy's size (plus ``tiny``, for energies that are all zero). An empty array: it never rose."""
    E = np.asarray(energies, dtype=np.float64)
    if len(E) < 2:
        return np.zeros(0, dtype=np.int64)
    slack = rel * float(np.abs(E).max()) + tiny
    return np.flatnonzero(np.diff(E) > slack)
