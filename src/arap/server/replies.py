"""The server messages that describe a session (its ``welcome``, ``state``, ``vertices`` and ``settle`` messages, the
``appearance`` frame of its mesh's look),
built from the session by their classes (:mod:`arap.server.server_messages`), and :data:`Reply`, what a
dispatcher hands its transport to send.

These are shared by every answer of :class:`arap.server.dispatch.Dispatcher` (and by tests that read a session's
state as the client sees it); they are kept apart from the request handlers, which decide what to send, not how a
session is described.
"""

from __future__ import annotations

import threading
from dataclasses import asdict
from typing import Any, Final
from weakref import WeakKeyDictionary

import numpy as np

from arap import __version__
from arap.server.appearance import Look
from arap.server.constraints import matrices_to_json
from arap.server.frames import encode_binary
from arap.server.meshdata import builtin_names
from arap.server.messages import MAX_HANDLE_GROUPS, PROTOCOL_VERSION
from arap.server.pictures import page_drawing
from arap.server.records import DragOutcome, readable_energy
from arap.server.server_messages import Appearance, Settle, State, Vertices, Welcome
from arap.server.session import Session
from arap.server.studio_config import StudioConfig

__all__ = ["SETTLE", "Reply", "appearance_frame", "settle_message", "state_message", "vertices_header",
           "welcome_message"]

Reply = dict[str, Any] | bytes | tuple[dict[str, Any], list[bytes]]
"""A server message: a text message, an encoded binary frame, or a binary message's header and payload parts."""


class _Settle:
    def __repr__(self) -> str:
        return "SETTLE"


SETTLE: Final = _Settle()
"""Yielded by :meth:`arap.server.dispatch.Dispatcher.handle` where the shape must be settled before it goes on (an
export)."""


def welcome_message(session: Session, config: StudioConfig) -> dict[str, Any]:
    """The ``welcome`` message: versions, built-in models, the server's limits and the session's parameters."""
    return Welcome(
        version=__version__,
        protocol=PROTOCOL_VERSION,
        builtin_meshes=builtin_names(),
        limits={"max_upload_bytes": config.max_upload_bytes,
                "max_vertices": config.max_vertices,
                "max_frame_bytes": config.max_frame_bytes,
                "max_handle_groups": MAX_HANDLE_GROUPS},
        params=asdict(session.params),
    ).to_wire()


def state_message(session: Session) -> dict[str, Any]:
    """The ``state`` message of ``session``: history, parameters, constraints, transforms and statistics."""
    n = session.n_vertices
    cs = session.constraints
    solver = session.solver
    constraints = cs.to_json()
    drawing = page_drawing(session)
    for point, angle in zip(constraints["points"], session.pin_angles(), strict=True):
        if angle is not None:
            point["angle"] = angle  # the angle a picture's pin holds (its hidden ring is the solver's alone)
    return State(
        can_undo=session.can_undo,
        can_redo=session.can_redo,
        params=asdict(session.params),
        constraints=constraints,
        transforms=matrices_to_json(session.transforms),
        rest_id=session.rest_id,
        draw_order=None if drawing is None else drawing[0],
        draw_layers=None if drawing is None else drawing[1],
        stats={
            "n_vertices": n,
            "n_faces": 0 if session.mesh is None else session.mesh.n_faces,
            "roi_size": n if cs.roi is None else len(cs.roi),
            "n_free": 0 if solver is None else int(solver.n_free),
            "factor_ms": 0.0 if solver is None else 1000.0 * float(solver.factor_seconds),
        },
    ).to_wire()


def vertices_header(session: Session, seq: int, skipped: int, outcome: DragOutcome, subset: int,
                    movable: int) -> dict[str, Any]:
    """The header of the ``vertices`` frame that answers drag ``seq`` with the solve ``outcome``."""
    return Vertices(seq=seq, skipped=skipped, iterations=outcome.iterations,
                    energies=[readable_energy(e, session.diagonal) for e in outcome.energies],
                    solve_ms=round(outcome.solve_ms, 3), ms_per_iteration=round(outcome.ms_per_iteration, 3),
                    subset=subset, movable=movable).to_wire()


def settle_message(session: Session, status: str, iterations: int, energy: float | None,
                   seconds: float | None) -> dict[str, Any]:
    """A ``settle`` message: the status, iterations, energy (as the studio shows it) and time of a settling run."""
    return Settle(status=status, iterations=iterations, energy=readable_energy(energy, session.diagonal),
                  seconds=None if seconds is None else round(seconds, 4)).to_wire()


_APPEARANCE: WeakKeyDictionary[Look, bytes] = WeakKeyDictionary()
_APPEARANCE_LOCK = threading.Lock()


def appearance_frame(look: Look) -> bytes:
    """The ``appearance`` frame of ``look``: how its mesh is drawn (built once per look: the default mesh's look is
    shared by every session)."""
    with _APPEARANCE_LOCK:
        frame = _APPEARANCE.get(look)
    if frame is not None:
        return frame
    r = 0 if look.render_map is None else len(look.render_map)
    t = 0 if look.render_faces is None else len(look.render_faces)
    header = Appearance(colors=look.colors is not None, render_vertices=r, render_faces=t,
                        texture_bytes=len(look.texture), texture_mime=look.texture_mime,
                        file_format=look.asset.format, notes=look.notes).to_wire()
    parts: list[bytes] = []
    if r:
        assert look.render_map is not None and look.render_uv is not None and look.render_faces is not None
        parts += [np.ascontiguousarray(look.render_map, dtype="<u4").tobytes(),
                  np.ascontiguousarray(look.render_uv, dtype="<f4").tobytes(),
                  np.ascontiguousarray(look.render_faces, dtype="<u4").tobytes()]
    if look.colors is not None:
        parts.append(np.ascontiguousarray(look.colors, dtype=np.uint8).tobytes())
    parts.append(look.texture)
    frame = encode_binary(header, *parts)
    with _APPEARANCE_LOCK:
        _APPEARANCE[look] = frame
    return frame
