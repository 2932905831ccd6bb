"""The bend scenario of ``arap bench``, and what every constraint scenario is made of.

A scenario picks constrained vertices of a mesh from its shape alone (quantiles along its longest axis) and gives
their targets, so the same scenario applies to any mesh. The tests and the benchmarks add more of them (twist, pull,
rigid: ``benchmarks/scenarios.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from arap.meshes.mesh import bounding_box

__all__ = ["Scenario", "axis_ends", "bend", "build_scenario", "diagonal", "rotation"]


@dataclass(frozen=True)
class Scenario:
    """Constraints of a scenario.

    Attributes
    ----------
    name : str
    fixed : (f,) int64 array
        Vertices held at their rest positions.
    handles : (h,) int64 array
        Vertices moved to ``targets[len(fixed):]``.
    constrained : (f + h,) int64 array
        ``fixed`` then ``handles``: the order of ``targets``.
    targets : (f + h, 3) float64 array
    """

    name: str
    fixed: NDArray[np.int64]
    handles: NDArray[np.int64]
    constrained: NDArray[np.int64]
    targets: NDArray[np.float64]


def diagonal(V: NDArray[np.float64]) -> float:
    """Length of the bounding-box diagonal of ``V``."""
    box = bounding_box(V)
    return float(np.linalg.norm(box[1] - box[0]))


def axis_ends(V: NDArray[np.float64], axis: int | None,
              share: float) -> tuple[int, NDArray[np.int64], NDArray[np.int64]]:
    """Longest axis (unless given) and the vertices in its lowest and highest ``share``."""
    if axis is None:
        box = bounding_box(V)
        axis = int(np.argmax(box[1] - box[0]))
    x = V[:, axis]
    lo, hi = np.quantile(x, [share, 1.0 - share])
    return axis, np.flatnonzero(x <= lo), np.flatnonzero(x >= hi)


def rotation(axis: NDArray[np.float64] | list[float], angle: float) -> NDArray[np.float64]:
    """Rotation by ``angle`` radians about ``axis`` (Rodrigues), shape (3, 3)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def build_scenario(name: str, V: NDArray[np.float64], fixed: NDArray[np.int64], handles: NDArray[np.int64],
                   moved: NDArray[np.float64]) -> Scenario:
    """The scenario ``name`` holding ``fixed`` at rest and moving ``handles`` to ``moved``."""
    return Scenario(name=name, fixed=fixed, handles=handles, constrained=np.concatenate([fixed, handles]),
                    targets=np.concatenate([V[fixed], moved]))


def bend(V: NDArray[np.float64], axis: int | None = None, share: float = 0.1, angle: float = 0.6,
         shift: float = 0.15) -> Scenario:
    """Fix the lowest ``share`` of the vertices along ``axis`` (default: the longest), rotate the highest ``share``
    by ``angle`` radians about their centroid in the plane of ``axis`` and the next axis, and shift them along that
    next axis by ``shift`` bounding-box diagonals.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.random.default_rng(0).random((100, 3)) * [1, 4, 1]
    >>> s = bend(V)
    >>> s.targets.shape == (len(s.constrained), 3), bool(np.all(s.targets[:len(s.fixed)] == V[s.fixed]))
    (True, True)
    """
    axis, fixed, handles = axis_ends(V, axis, share)
    other = (axis + 1) % 3
    R = rotation(np.eye(3)[3 - axis - other], angle)
    centre = V[handles].mean(axis=0)
    offset = np.zeros(3)
    offset[other] = shift * diagonal(V)
    return build_scenario("bend", V, fixed, handles, (V[handles] - centre) @ R.T + centre + offset)
