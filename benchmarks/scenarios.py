"""Named constraint scenarios of the tests and the benchmarks (bend, twist, pull, rigid): each picks constrained
vertices of a mesh from its shape alone and gives their targets, so the same scenario applies to any mesh. The bend
is the package's own (:func:`arap.constraints.scenarios.bend`, what ``arap bench`` times).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from arap.constraints.scenarios import Scenario, axis_ends, bend, build_scenario, diagonal, rotation
from arap.errors import ArapError

__all__ = ["SCENARIO_NAMES", "Scenario", "bend", "make_scenario", "pull", "rigid", "rotation", "twist"]

ScenarioName = Literal["bend", "twist", "pull", "rigid"]
SCENARIO_NAMES: tuple[str, ...] = ("bend", "twist", "pull", "rigid")


def twist(V: NDArray[np.float64], axis: int | None = None, share: float = 0.1, angle: float = np.pi / 2) -> Scenario:
    """Fix the lowest ``share`` along ``axis`` and turn the highest ``share`` by ``angle`` about that axis
    through their centroid."""
    axis, fixed, handles = axis_ends(V, axis, share)
    centre = V[handles].mean(axis=0)
    R = rotation(np.eye(3)[axis], angle)
    return build_scenario("twist", V, fixed, handles, (V[handles] - centre) @ R.T + centre)


def pull(V: NDArray[np.float64], axis: int | None = None, share: float = 0.1, distance: float = 0.2) -> Scenario:
    """Fix the lowest ``share`` along ``axis`` and pull the single vertex farthest along it by ``distance``
    bounding-box diagonals along the axis."""
    axis, fixed, _ = axis_ends(V, axis, share)
    tip = np.array([int(np.argmax(V[:, axis]))], dtype=np.int64)
    offset = np.zeros(3)
    offset[axis] = distance * diagonal(V)
    return build_scenario("pull", V, fixed, tip, V[tip] + offset)


def rigid(V: NDArray[np.float64], angle: float = np.radians(170.0), count: int = 40, seed: int = 0) -> Scenario:
    """Move ``count`` scattered vertices (no fixed ones) by one rigid motion rotating ``angle`` radians."""
    rng = np.random.default_rng(seed)
    handles = np.sort(rng.choice(len(V), size=min(count, len(V)), replace=False)).astype(np.int64)
    R = rotation([0.3, -1.0, 0.5], angle)
    t = np.array([0.5, -0.25, 0.1]) * diagonal(V)
    return build_scenario("rigid", V, np.zeros(0, dtype=np.int64), handles, V[handles] @ R.T + t)


def make_scenario(name: ScenarioName | str, V: NDArray[np.float64]) -> Scenario:
    """The scenario ``name`` (one of :data:`SCENARIO_NAMES`) with its default parameters."""
    makers = {"bend": bend, "twist": twist, "pull": pull, "rigid": rigid}
    if name not in makers:
        raise ArapError(f"unknown scenario {name!r}; expected one of {SCENARIO_NAMES}")
    return makers[name](V)
