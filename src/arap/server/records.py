"""The records a studio session hands back: its solver parameters and what a drag or a settling run did."""

from __future__ import annotations

from dataclasses import dataclass

from arap.cells import EnergyType
from arap.server.protocol import PARAMS
from arap.weights import WeightType

__all__ = ["DragOutcome", "Params", "SettleOutcome"]


@dataclass
class Params:
    """Solver parameters of a session."""

    iterations: int = PARAMS["iterations"]["default"]
    energy: EnergyType = PARAMS["energy"]["default"]
    weights: WeightType = PARAMS["weights"]["default"]
    alpha: float = PARAMS["alpha"]["default"]


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
