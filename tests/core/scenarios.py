"""Constraint scenarios shared by the solver tests."""

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
