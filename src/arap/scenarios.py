"""Constraint scenarios used by the tests, the benchmarks and ``arap bench``: bend, twist and pull.

Each scenario works on any mesh along its longest bounding-box axis (or a given one): the lowest ``share`` of the
vertices along that axis are anchors held at rest, and handles move to their targets.

- ``bend``: the highest ``share`` are rotated by ``angle`` about their centroid, in the plane of the axis and the
  next one (``side``), then shifted along ``side`` by ``shift`` times the bounding-box diagonal.
- ``twist``: the highest ``share`` are rotated by ``angle`` about the axis through their centroid.
- ``pull``: both ends are anchors; the ``share`` of the vertices nearest to the outermost point along ``side`` at
  mid-height are shifted outwards along ``side`` by ``shift`` times the diagonal.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = ["SCENARIOS", "Scenario", "ScenarioName", "bend", "make_scenario", "pull", "twist"]

ScenarioName = Literal["bend", "twist", "pull"]
SCENARIOS: tuple[str, ...] = ("bend", "twist", "pull")


@dataclass(frozen=True)
class Scenario:
    """Anchors, handles and handle targets.

    Attributes
    ----------
    fixed : (f,) int64 array
        Anchors, held at their rest positions.
    handles : (h,) int64 array
    targets : (h, 3) float64 array
        Target of each handle.
    """

    fixed: NDArray[np.int64]
    handles: NDArray[np.int64]
    targets: NDArray[np.float64]

    @property
    def constrained(self) -> NDArray[np.int64]:
        """(f + h,) anchors then handles: the ``constrained`` argument of :class:`arap.ArapSolver`."""
        return np.concatenate([self.fixed, self.handles])

    def all_targets(self, V: NDArray[np.float64]) -> NDArray[np.float64]:
        """(f + h, 3) targets of :attr:`constrained`: anchors at their rest positions ``V``, then the handles'."""
        return np.concatenate([V[self.fixed], self.targets])


def _frame(V: NDArray[np.float64], axis: int | None, side: int | None) -> tuple[int, int, float]:
    extent = V.max(axis=0) - V.min(axis=0)
    axis = int(np.argmax(extent)) if axis is None else int(axis)
    side = (axis + 1) % 3 if side is None else int(side)
    if axis == side or not (0 <= axis < 3 and 0 <= side < 3):
        raise ValueError(f"axis and side must be two different coordinates 0..2, got {axis} and {side}")
    return axis, side, float(np.linalg.norm(extent))


def _rotation(angle: float, i: int, j: int) -> NDArray[np.float64]:
    """Rotation by ``angle`` in the plane of coordinates ``i`` and ``j`` (from ``i`` towards ``j``)."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _ends(V: NDArray[np.float64], axis: int, share: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    if not 0 < share < 0.5:
        raise ValueError(f"share must be in (0, 0.5), got {share}")
    t = V[:, axis]
    lo, hi = np.quantile(t, [share, 1.0 - share])
    return np.flatnonzero(t <= lo), np.flatnonzero(t >= hi)


def bend(V: NDArray[np.float64], *, axis: int | None = None, side: int | None = None, share: float = 0.1,
         angle: float = np.pi / 4, shift: float = 0.1) -> Scenario:
    """Fix the lowest ``share`` along ``axis``; rotate the highest ``share`` towards ``side`` and shift them.

    Parameters
    ----------
    V : (n, 3) float array
        Rest positions.
    axis : int or None
        Coordinate along which the ends are taken; None: the longest bounding-box extent.
    side : int or None
        The bending direction; None: ``(axis + 1) % 3``.
    share : float
        Share of the vertices in each end (0 < share < 0.5).
    angle : float
        Rotation of the handles in radians, in the plane (``axis``, ``side``) about their centroid.
    shift : float
        Shift of the handles along ``side``, times the bounding-box diagonal.

    Returns
    -------
    Scenario
    """
    axis, side, diag = _frame(V, axis, side)
    fixed, handles = _ends(V, axis, share)
    R = _rotation(angle, axis, side)
    centre = V[handles].mean(axis=0)
    offset = np.zeros(3)
    offset[side] = shift * diag
    return Scenario(fixed, handles, (V[handles] - centre) @ R.T + centre + offset)


def twist(V: NDArray[np.float64], *, axis: int | None = None, share: float = 0.1,
          angle: float = np.pi / 2) -> Scenario:
    """Fix the lowest ``share`` along ``axis``; turn the highest ``share`` by ``angle`` about the axis.

    Parameters
    ----------
    V : (n, 3) float array
    axis : int or None
        None: the longest bounding-box extent.
    share : float
    angle : float
        Radians, about the line along ``axis`` through the handles' centroid.

    Returns
    -------
    Scenario
    """
    axis, _, _ = _frame(V, axis, None)
    fixed, handles = _ends(V, axis, share)
    i, j = [k for k in range(3) if k != axis]
    R = _rotation(angle, i, j)
    centre = V[handles].mean(axis=0)
    return Scenario(fixed, handles, (V[handles] - centre) @ R.T + centre)


def pull(V: NDArray[np.float64], *, axis: int | None = None, side: int | None = None, share: float = 0.1,
         patch: float = 0.03, shift: float = 0.15) -> Scenario:
    """Fix both ends; pull a patch at mid-height outwards along ``side``.

    Parameters
    ----------
    V : (n, 3) float array
    axis : int or None
        None: the longest bounding-box extent.
    side : int or None
        None: ``(axis + 1) % 3``.
    share : float
        Share of the vertices in each fixed end.
    patch : float
        Share of the vertices in the pulled patch: those nearest to the vertex of largest ``side`` coordinate among
        the vertices in the middle tenth along ``axis``.
    shift : float
        Times the bounding-box diagonal.

    Returns
    -------
    Scenario
    """
    axis, side, diag = _frame(V, axis, side)
    low, high = _ends(V, axis, share)
    t = V[:, axis]
    middle = np.flatnonzero(np.abs(t - np.median(t)) <= 0.05 * (t.max() - t.min()))
    if not len(middle):
        middle = np.arange(len(V))
    apex = middle[np.argmax(V[middle, side])]
    k = max(1, round(patch * len(V)))
    handles = np.sort(np.argsort(np.linalg.norm(V - V[apex], axis=1), kind="stable")[:k])
    fixed = np.setdiff1d(np.concatenate([low, high]), handles)
    offset = np.zeros(3)
    offset[side] = shift * diag
    return Scenario(fixed, handles, V[handles] + offset)


def make_scenario(name: str, V: NDArray[np.float64]) -> Scenario:
    """The scenario ``name`` (one of :data:`SCENARIOS`) with its default parameters.

    Raises
    ------
    ValueError
        Unknown name.
    """
    if name == "bend":
        return bend(V)
    if name == "twist":
        return twist(V)
    if name == "pull":
        return pull(V)
    raise ValueError(f"unknown scenario {name!r}; expected one of {SCENARIOS}")
