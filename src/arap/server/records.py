"""The records a studio session hands back: its solver parameters and what a drag or a settling run did."""

from __future__ import annotations

import math
from dataclasses import dataclass

from arap.method.weights import WeightType
from arap.options import EnergyType, LoosePartsMode
from arap.server.messages import PARAMS

__all__ = ["ENERGY_ZERO", "DragOutcome", "Params", "SettleOutcome", "readable_energy"]

ENERGY_ZERO = 1e-12
"""Energies within this many squared bounding-box diagonals of 0 are reported as 0."""


def readable_energy(value: float | None, diagonal: float) -> float | None:
    """An energy as the studio shows it: None when unknown or not finite, 0 when within :data:`ENERGY_ZERO` squared
    diagonals of 0. A shape's energy is a sum over its cells of differences of terms of the order of the squared
    edge lengths, so a rigid pose gives about ±1e-16 of their sum instead of 0: a user would read ``-2.4e-15`` under
    an energy that cannot be negative as a sign of trouble.

    Example
    -------
    >>> readable_energy(-2.4e-15, 1.0), readable_energy(3e-4, 1.0), readable_energy(float("nan"), 1.0)
    (0.0, 0.0003, None)
    """
    if value is None or not math.isfinite(value):
        return None
    return 0.0 if abs(value) <= ENERGY_ZERO * diagonal * diagonal else float(value)


@dataclass
class Params:
    """Solver parameters of a session."""

    iterations: int = PARAMS["iterations"]["default"]
    energy: EnergyType = PARAMS["energy"]["default"]
    weights: WeightType = PARAMS["weights"]["default"]
    alpha: float = PARAMS["alpha"]["default"]
    loose: LoosePartsMode = PARAMS["loose"]["default"]
    warp: str = PARAMS["warp"]["default"]
    """The puppet warp's mode for pictures (:data:`arap.puppet.warp.MODES`); surfaces and solids ignore it."""


@dataclass
class DragOutcome:
    """What one solve did (for the ``vertices`` header)."""

    iterations: int
    energies: list[float]
    solve_ms: float

    @property
    def ms_per_iteration(self) -> float:
        """Solve time per iteration."""
        return self.solve_ms / max(self.iterations, 1)


@dataclass
class SettleOutcome:
    """What one settling run did (for the ``settle`` message)."""

    iterations: int
    energy: float | None
    converged: bool
    seconds: float
    moved: float
    """Largest coordinate change of the shape (0: the shape was kept as it was)."""
    interrupted: bool = False
    """A new request stopped it (it resumes later); else it converged or used up its iterations."""

    @property
    def status(self) -> str:
        """The ``settle`` message's status for this run's end."""
        return "settled" if self.converged else "stopped" if self.interrupted else "unconverged"
