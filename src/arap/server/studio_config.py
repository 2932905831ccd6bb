"""The limits and settings shared by all sessions of a studio server (:class:`StudioConfig`), and the check of an
upload against them that every transport makes before queueing it.

Kept apart from the dispatcher so that what a server accepts reads in one place, whichever transport carries the
messages (a WebSocket, :mod:`arap.server.connection`; a notebook widget's comm, :mod:`arap.server.channel`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from arap.server.budget import MemoryBudget
from arap.server.client_messages import Upload
from arap.server.errors import RequestError
from arap.server.messages import ClientMessage

__all__ = ["StudioConfig", "check_upload_size"]


@dataclass(frozen=True)
class StudioConfig:
    """Limits and settings shared by all sessions of a server.

    Attributes
    ----------
    max_upload_bytes : int
        Largest accepted upload payload.
    max_vertices : int
        Largest accepted uploaded mesh.
    max_frame_bytes : int
        Largest accepted WebSocket frame of any kind (also given to the WebSocket server).
    max_pending : int
        Most requests waiting in one session's queue; more are answered ``busy``.
    max_history_steps, max_history_bytes : int
        Undo history limits per session.
    max_queued_bytes : int
        Estimated memory of the requests waiting in one session's queue past which its frames are no longer
        read (see :func:`arap.server.budget.request_cost`).
    max_unsent_bytes : int
        Bytes of one session's answers waiting to be handed to the socket past which its frames are no longer
        read.
    subset_frames : bool
        Send only the movable vertices' positions while a constraint set with a region of interest is dragged
        (see :mod:`arap.server.liveframes`); False sends every ``vertices`` frame in full.
    max_export_bytes : int
        Estimated memory that the animation exports of all sessions may take at once (see
        :func:`arap.server.animation_export.export_bytes`): an export larger than this is refused, one that does not
        fit beside those running waits for them.
    exports : MemoryBudget
        That budget, shared by every session given this configuration.
    """

    max_upload_bytes: int = 50 * 2**20
    max_vertices: int = 2_000_000
    max_frame_bytes: int = 65 * 2**20
    max_pending: int = 256
    max_history_steps: int = 100
    max_history_bytes: int = 512 * 2**20
    max_queued_bytes: int = 64 * 2**20
    max_unsent_bytes: int = 64 * 2**20
    subset_frames: bool = True
    max_export_bytes: int = 2**31
    exports: MemoryBudget = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "exports", MemoryBudget(self.max_export_bytes))


def check_upload_size(config: StudioConfig, msg: ClientMessage) -> ClientMessage:
    """``msg``, unless it is an upload larger than ``config`` accepts (:class:`RequestError` ``too_large``)."""
    if isinstance(msg, Upload) and len(msg.payload) > config.max_upload_bytes:
        raise RequestError("too_large", f"upload of {len(msg.payload):,} bytes exceeds the "
                           f"limit of {config.max_upload_bytes:,}", msg.type)
    return msg
