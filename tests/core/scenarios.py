"""Constraint scenarios shared by the solver tests."""

from __future__ import annotations

import numpy as np


def bend_constraints(V: np.ndarray, axis: int | None = None, share: float = 0.1, angle: float = 0.6,
                     shift: float = 0.15) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fix the lowest ``share`` of vertices along the long axis, rotate and shift the highest ``share``.

    Returns
    -------
    fixed, handle, constrained, targets
    """
    if axis is None:
        axis = int(np.argmax(V.max(0) - V.min(0)))
    x = V[:, axis]
    lo, hi = np.quantile(x, [share, 1 - share])
    fixed = np.flatnonzero(x <= lo)
    handle = np.flatnonzero(x >= hi)
    other = (axis + 1) % 3
    c, s = np.cos(angle), np.sin(angle)
    R = np.eye(3)
    R[axis, axis], R[axis, other], R[other, axis], R[other, other] = c, -s, s, c
    centre = V[handle].mean(0)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    offset = np.zeros(3)
    offset[other] = shift * diag
    targets = np.concatenate([V[fixed], (V[handle] - centre) @ R.T + centre + offset])
    return fixed, handle, np.concatenate([fixed, handle]), targets


def random_rigid(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    return Q, rng.normal(size=3)
