"""Undo/redo history of a studio session: snapshots of rest pose, deformed pose, constraints and transforms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arap.server.constraints import ConstraintSet

__all__ = ["History", "Snapshot"]


@dataclass(frozen=True, eq=False)
class Snapshot:
    """One state of a session's edit (arrays are shared, never modified).

    Attributes
    ----------
    rest_id : int
        Identifies the rest pose ``V`` (solvers are cached per rest pose).
    V : (n, 3) array
        Rest pose.
    U : (n, 3) array
        Deformed positions.
    constraints : ConstraintSet
    transforms : (g, 4, 4) array
        Handle group transforms.
    settled : bool
        ``U`` is the converged shape of the constraints (no settling needed after restoring it).
    energy : float or None
        The energy of ``U`` when known (reported again when the step is restored).
    """

    rest_id: int
    V: np.ndarray
    U: np.ndarray
    constraints: ConstraintSet
    transforms: np.ndarray
    settled: bool = False
    energy: float | None = None


class History:
    """Linear undo/redo history with a cap on steps and on the memory the snapshots hold.

    Parameters
    ----------
    max_steps : int
        Most snapshots kept (at least 2).
    max_bytes : int
        Memory budget of the distinct arrays the snapshots hold; the oldest snapshots are dropped beyond it
        (two are always kept).
    """

    def __init__(self, max_steps: int = 100, max_bytes: int = 512 * 2**20) -> None:
        self.max_steps = max(2, int(max_steps))
        self.max_bytes = int(max_bytes)
        self._items: list[Snapshot] = []
        self._pos = -1

    def clear(self, snapshot: Snapshot) -> None:
        """Start over with ``snapshot`` as the only state."""
        self._items = [snapshot]
        self._pos = 0

    @property
    def current(self) -> Snapshot:
        """The snapshot of the current position."""
        return self._items[self._pos]

    @property
    def can_undo(self) -> bool:
        """True if there is an older state."""
        return self._pos > 0

    @property
    def can_redo(self) -> bool:
        """True if there is a newer state."""
        return self._pos < len(self._items) - 1

    def __len__(self) -> int:
        return len(self._items)

    def push(self, snapshot: Snapshot) -> None:
        """Record a new state after the current one (dropping the redo states)."""
        del self._items[self._pos + 1 :]
        self._items.append(snapshot)
        self._pos = len(self._items) - 1
        while len(self._items) > 2 and (len(self._items) > self.max_steps or self.nbytes() > self.max_bytes):
            del self._items[0]
            self._pos -= 1

    def replace_current(self, snapshot: Snapshot) -> None:
        """Replace the snapshot of the current position (a step refined in place, e.g. settled)."""
        self._items[self._pos] = snapshot

    def undo(self) -> Snapshot | None:
        """Step back; the snapshot to restore, or None at the oldest state."""
        if not self.can_undo:
            return None
        self._pos -= 1
        return self._items[self._pos]

    def redo(self) -> Snapshot | None:
        """Step forward; the snapshot to restore, or None at the newest state."""
        if not self.can_redo:
            return None
        self._pos += 1
        return self._items[self._pos]

    def nbytes(self) -> int:
        """Memory held by the distinct position arrays of all snapshots."""
        seen: dict[int, int] = {}
        for s in self._items:
            for a in (s.V, s.U, s.constraints.pose):
                seen[id(a)] = a.nbytes
        return sum(seen.values())
