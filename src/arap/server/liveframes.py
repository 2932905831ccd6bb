"""Payloads of ``vertices`` frames: all positions, or only those of the vertices that can move.

While a constraint set with a region of interest is being dragged, only the free vertices of the region and the
handle vertices can move. The first frame of such a constraint set is a full frame that also carries the list of
these *movable* vertices; later frames carry only their positions (float32, in the list's order). The stream
keeps a copy of what the client holds and falls back to a full frame whenever anything outside the list changed,
so a client that applies the frames in order always holds exactly the float32 positions a full frame would give.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.server.constraints import ConstraintSet
from arap.server.server_messages import Vertices

__all__ = ["VertexPayload", "VertexStream", "movable_vertices", "still_frame_header"]

VertexPayload = tuple[int, int, list[bytes]]
"""``(subset, movable, parts)`` of one ``vertices`` frame (see :meth:`VertexStream.encode`)."""


def movable_vertices(cs: ConstraintSet, n_vertices: int) -> NDArray[np.int64] | None:
    """Vertices a drag of ``cs`` can move: region of interest and handles, less the fixed ones.

    Parameters
    ----------
    cs : ConstraintSet
    n_vertices : int

    Returns
    -------
    (k,) int64 array or None
        Sorted indices, or None when every vertex may move (no region of interest, or one covering the mesh) or
        none can (every vertex of the region is fixed): a full frame lists no movable vertices (``movable`` 0), so a
        client could not apply subset frames of zero positions after it.
    """
    if cs.roi is None or cs.is_empty or len(cs.roi) >= n_vertices:
        return None
    mask = np.zeros(n_vertices, dtype=bool)
    mask[cs.roi] = True
    for group in cs.groups:
        mask[group] = True
    mask[cs.fixed] = False
    idx = np.flatnonzero(mask)
    if len(idx) == 0 or len(idx) >= n_vertices:
        return None
    return idx.astype(np.int64)


class VertexStream:
    """What the client holds, and the payload of the next ``vertices`` frame.

    Parameters
    ----------
    subsets : bool
        Send subset frames when possible; False sends every frame in full.
    """

    def __init__(self, subsets: bool = True) -> None:
        self.subsets = subsets
        self._held: NDArray[np.float32] | None = None
        self._key: Any = None
        self._movable: NDArray[np.int64] | None = None
        self._still: NDArray[np.int64] | None = None

    def reset(self, positions: NDArray[np.floating] | None = None) -> None:
        """The client now holds ``positions`` (a mesh frame) or something unknown (None); the next frame is full."""
        self._held = None if positions is None else np.array(positions, dtype="<f4")
        self._key = None
        self._movable = self._still = None

    def encode(self, U: NDArray[np.floating], cs: ConstraintSet) -> VertexPayload:
        """Payload of a frame showing ``U`` ``(n, 3)`` under the constraint set ``cs``.

        Parameters
        ----------
        U : (n, 3) float array
        cs : ConstraintSet
            The session's current constraint set (compared by identity).

        Returns
        -------
        subset : int
            -1 for a full frame, else the number of positions the payload holds.
        movable : int
            Length of the uint32 list of movable vertices appended to a full frame (0: none).
        parts : list of bytes
            The payload.
        """
        U32 = np.ascontiguousarray(U, dtype="<f4")
        held = self._held
        if (self.subsets and self._key is cs and self._movable is not None and self._still is not None
                and held is not None and held.shape == U32.shape
                and np.array_equal(U32[self._still].view("<u4"), held[self._still].view("<u4"))):
            part = U32[self._movable]
            held[self._movable] = part
            return len(self._movable), 0, [part.tobytes()]
        self._held = U32.copy()
        movable = movable_vertices(cs, len(U32)) if self.subsets else None
        self._key = cs
        self._movable = movable
        if movable is None:
            self._still = None
            return -1, 0, [U32.tobytes()]
        self._still = np.setdiff1d(np.arange(len(U32)), movable, assume_unique=True)
        return -1, len(movable), [U32.tobytes(), movable.astype("<u4").tobytes()]


def still_frame_header(seq: int, subset: int, movable: int) -> dict[str, Any]:
    """Header of a ``vertices`` frame that ran no solve (a settling frame, or the pose after a change)."""
    return Vertices(seq=seq, skipped=0, iterations=0, energies=[], solve_ms=0.0, ms_per_iteration=0.0,
                    subset=subset, movable=movable).to_wire()
