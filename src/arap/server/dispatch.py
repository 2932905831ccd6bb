"""The studio protocol's answers for one session, whatever carries them (a WebSocket, a Jupyter comm).

A :class:`Dispatcher` turns validated client messages into the server messages that answer them, as
:class:`Reply` values; the transport only sends them, in order. :mod:`arap.server.connection` runs it on an event
loop (each step on a thread), :class:`arap.server.channel.ChannelWorker` on a thread of its own for synchronous
channels such as a notebook widget's comm (:mod:`arap.jupyter_widget`). Both coalesce drags the same way, settle
the shape when no request waits and stop settling as soon as one arrives.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from typing import Any, Final

import numpy as np

import arap
from arap.server.animation_export import AnimationCancelled, export_animation, keyframes_document
from arap.server.constraints import matrices_to_json
from arap.server.heatmap import distortion_frame
from arap.server.liveframes import VertexPayload, VertexStream, still_frame_header
from arap.server.meshdata import MeshData, builtin_names, load_builtin, load_upload, mesh_frame
from arap.server.protocol import (
    MAX_HANDLE_GROUPS,
    PROTOCOL_VERSION,
    ClientMessage,
    RequestError,
    check_against_mesh,
    error_message,
    server_message,
    validate,
)
from arap.server.records import readable_energy
from arap.server.render_mesh import Look, look_from_upload
from arap.server.session import DragOutcome, Session, SettleOutcome

__all__ = ["SETTLE", "Dispatcher", "Reply", "StudioConfig", "decode_message"]

logger = logging.getLogger("arap.server.connection")

Reply = dict[str, Any] | bytes | tuple[dict[str, Any], list[bytes]]
"""A server message: a text message, an encoded binary frame, or a binary message's header and payload parts."""


class _Settle:
    def __repr__(self) -> str:
        return "SETTLE"


SETTLE: Final = _Settle()
"""Yielded by :meth:`Dispatcher.handle` where the shape must be settled before it goes on (an export)."""


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


def _timed(fn: Callable[..., Any], *args: Any) -> tuple[Any, float]:
    """``fn(*args)`` and the CPU time this thread spent in it (seconds)."""
    t0 = time.thread_time()
    return fn(*args), time.thread_time() - t0


def decode_message(config: StudioConfig, content: Any, buffers: list[Any] | None) -> ClientMessage | RequestError:
    """Decode and validate a message that came as a JSON object (a binary message's header) and its buffers (its
    payload, concatenated); never raises."""
    try:
        payload = memoryview(b"".join(bytes(b) for b in buffers)) if buffers else None
        if payload is not None and len(payload) > config.max_frame_bytes:
            raise RequestError("too_large", f"message of {len(payload):,} bytes exceeds the limit of "
                               f"{config.max_frame_bytes:,}")
        return _check_upload(config, validate(content, binary=payload is not None, payload=payload))
    except RequestError as exc:
        return exc
    except Exception:
        logger.exception("unexpected error while decoding a message")
        return RequestError("internal", "unexpected server error while reading a message; see the server log")


def _check_upload(config: StudioConfig, item: ClientMessage) -> ClientMessage:
    if item.payload is not None and len(item.payload) > config.max_upload_bytes:
        raise RequestError("too_large", f"upload of {len(item.payload):,} bytes exceeds the "
                           f"limit of {config.max_upload_bytes:,}", item.type)
    return item


class Dispatcher:
    """The answers to one session's requests.

    Parameters
    ----------
    session : Session
    config : StudioConfig
    """

    def __init__(self, session: Session, config: StudioConfig) -> None:
        self.session = session
        self.config = config
        self.stream = VertexStream(config.subset_frames)
        self._skipped = 0  # drags replaced by a newer one since the last answered drag
        self._skipped_lock = threading.Lock()  # counted by the transport's thread, read by the answering one
        self.arrived: dict[int, tuple[float, float]] = {}
        """Arrival and decoding times of uploads waiting, by ``id`` of their message (for the timing log)."""

    # ------------------------------------------------------------------ messages
    def welcome(self) -> Reply:
        return server_message(
            "welcome",
            version=arap.__version__,
            protocol=PROTOCOL_VERSION,
            builtin_meshes=builtin_names(),
            limits={"max_upload_bytes": self.config.max_upload_bytes,
                    "max_vertices": self.config.max_vertices,
                    "max_frame_bytes": self.config.max_frame_bytes,
                    "max_handle_groups": MAX_HANDLE_GROUPS},
            params=asdict(self.session.params),
        )

    def greeting(self, mesh: MeshData, look: Look | None,
                 prepare: Callable[[Session], object] | None) -> Iterator[Reply]:
        """Load the session's first mesh; the welcome, the mesh, the state (and the prepared shape)."""
        self.session.load(mesh, look)
        if prepare is not None:
            prepare(self.session)
        yield self.welcome()
        yield from self.mesh(mesh)
        yield self.state()
        if prepare is not None:
            yield self.vertices(-1, None)

    def rejoin(self) -> Iterator[Reply]:
        """The greeting of a client that joins the session as it is: the welcome, its mesh, the state and the
        shape (a notebook widget's view opening)."""
        mesh = self.session.mesh
        yield self.welcome()
        if mesh is None:
            return
        yield from self.mesh(mesh)
        yield self.state()
        yield self.vertices(-1, None)
        yield from self.shape_status()

    def mesh(self, mesh: MeshData) -> Iterator[Reply]:
        """The ``mesh`` frame, then the ``appearance`` of a mesh that has one."""
        self.stream.reset(mesh.V)
        yield mesh_frame(mesh)
        look = self.session.look
        if look is not None:
            yield look.frame

    def count_skipped(self) -> None:
        """A queued drag was replaced by a newer one: the answer to the newer one reports it (``skipped``)."""
        with self._skipped_lock:
            self._skipped += 1

    def export_animation(self, fields: dict[str, Any], interrupted: Callable[[], bool],
                         send: Callable[[Reply], object]) -> Reply:
        """Solve ``export_animation``'s keyframes into an animated GLB (:mod:`arap.server.animation_export`),
        sending ``animation_progress`` through ``send`` at most 10 times per second; the ``animation`` reply, or a
        ``cancelled`` progress message when ``interrupted()`` turned true (a new request waits)."""
        t0 = time.perf_counter()
        last = [0.0]

        def progress(done: int, frames: int) -> None:
            now = time.perf_counter()
            if done and done < frames and now - last[0] < 0.1:
                return
            last[0] = now
            send(server_message("animation_progress", status="solving", frame=done, frames=frames,
                                seconds=round(now - t0, 3)))

        try:
            filename, mime, data, frames, seconds = export_animation(
                self.session, fields["times_ms"], fields["transforms"], fields["fps"], interrupted, progress)
        except AnimationCancelled:
            return server_message("animation_progress", status="cancelled", frame=0, frames=0,
                                  seconds=round(time.perf_counter() - t0, 3))
        return server_message("animation", filename=filename, mime=mime, frames=frames,
                              seconds=round(seconds, 3)), [data]

    def take_skipped(self) -> int:
        """The drags replaced since the last call (the transport's thread counts while another answers)."""
        with self._skipped_lock:
            n, self._skipped = self._skipped, 0
        return n

    def state(self) -> Reply:
        return state_message(self.session)

    def vertices(self, seq: int, outcome: DragOutcome | None, frame: VertexPayload | None = None) -> Reply:
        """A ``vertices`` frame of the session's shape (or of ``frame``, already encoded); ``outcome`` is the
        solve that answered drag ``seq`` (None: no solve)."""
        subset, movable, parts = frame if frame is not None else self.stream.encode(self.session.U,
                                                                                       self.session.constraints)
        if outcome is None:
            return still_frame_header(seq, subset, movable), parts
        header = server_message("vertices", seq=seq, skipped=self.take_skipped(), iterations=outcome.iterations,
                                energies=[readable_energy(e, self.session.diagonal) for e in outcome.energies],
                                solve_ms=round(outcome.solve_ms, 3),
                                ms_per_iteration=round(outcome.ms_per_iteration, 3),
                                subset=subset, movable=movable)
        return header, parts

    def settle_status(self, status: str, iterations: int, energy: float | None, seconds: float | None) -> Reply:
        return server_message("settle", status=status, iterations=iterations,
                              energy=readable_energy(energy, self.session.diagonal),
                              seconds=None if seconds is None else round(seconds, 4))

    @staticmethod
    def error(exc: RequestError) -> Reply:
        return error_message(exc)

    def shape_status(self) -> Iterator[Reply]:
        """``settle`` for a shape that needs no settling (after undo, redo, apply or loading), so that the client's
        status and energy describe the shape it now shows; a shape that needs it is settled next."""
        if not self.session.needs_settle:
            yield self.settle_status("settled", 0, self.session.energy, 0.0)

    # ------------------------------------------------------------------ settling
    def settle_frame(self, U: np.ndarray | None, iteration: int, energy: float) -> list[Reply]:
        """What a settling run sends for one progress report (on the thread that settles)."""
        replies: list[Reply] = []
        if U is not None:
            replies.append(self.vertices(-1, None, self.stream.encode(U, self.session.constraints)))
        replies.append(self.settle_status("settling", iteration, energy, None))
        return replies

    def settle_done(self, outcome: SettleOutcome, streamed: int) -> list[Reply]:
        """What ends a settling run: the shape reached when the client has not seen it, and the status."""
        replies: list[Reply] = []
        if streamed or outcome.moved > 0:
            replies.append(self.vertices(-1, None))
        replies.append(self.settle_status(outcome.status, outcome.iterations, outcome.energy, outcome.seconds))
        return replies

    def settle(self, interrupted: Callable[[], bool], send: Callable[[Reply], object]) -> None:
        """Settle the shape on this thread, sending its progress with ``send``; ``interrupted`` stops it."""
        s = self.session
        if not s.needs_settle:
            return
        streamed = 0

        def on_frame(U: np.ndarray | None, iteration: int, energy: float) -> None:
            nonlocal streamed
            streamed += U is not None
            for reply in self.settle_frame(U, iteration, energy):
                send(reply)

        send(self.settle_status("settling", 0, None, 0.0))
        try:
            outcome = s.settle(interrupted, on_frame)
        except RequestError as exc:
            send(self.error(exc))
            return
        if outcome is not None:
            for reply in self.settle_done(outcome, streamed):
                send(reply)

    # ------------------------------------------------------------------ requests
    def handle(self, msg: ClientMessage) -> Iterator[Reply | _Settle]:
        """Check ``msg`` against the session's mesh and carry it out, yielding its answers (and :data:`SETTLE`
        where the shape must be settled first). Raises :class:`RequestError`."""
        s = self.session
        f = msg.fields
        t = msg.type
        check_against_mesh(msg, s.n_vertices, s.n_groups)
        if t == "drag":
            outcome = s.drag(f["transforms"])
            yield self.vertices(f["seq"], outcome)
        elif t == "end_drag":
            s.end_drag()
            yield self.state()
        elif t == "load_builtin":
            mesh = load_builtin(f["name"])
            s.load(mesh)
            self.take_skipped()
            yield from self.mesh(mesh)
            yield self.state()
            yield from self.shape_status()
        elif t == "upload":
            yield from self._upload(msg)
            yield from self.shape_status()
        elif t == "set_constraints":
            solved = s.set_constraints(f["roi"], f["fixed"], f["handle_groups"], f.get("targets"),
                                       f.get("stiffness"), f.get("points"))
            if solved is not None:
                yield self.vertices(-1, solved)
            yield self.state()
        elif t == "set_params":
            s.set_params(**f)
            yield self.state()
        elif t in ("undo", "redo", "reset", "apply"):
            before = s.U
            getattr(s, t)()
            self.stream.reset(None)  # everything may have changed: the next frame is full
            if s.U is not before and not np.array_equal(s.U, before):
                yield self.vertices(-1, None)
            yield self.state()
            yield from self.shape_status()
        elif t == "export":
            # The exported shape must not depend on timing: an unsettled shape settles first (a new request
            # stops it, and the shape reached is exported).
            yield SETTLE
            filename, mime, data = s.export(f["format"])
            yield server_message("export", filename=filename, mime=mime), [data]
        elif t == "get_distortion":
            header, data = distortion_frame(s)
            yield header, [data]
        elif t == "get_constraints":
            # with the timeline's keyframes when the message carries them
            times = f.get("times_ms")
            document = keyframes_document(s, times, f.get("transforms") or []) if times else s.constraints_document()
            yield server_message("constraints", document=document)
        else:
            raise RequestError("bad_message", f"unhandled message type {t!r}")

    def _upload(self, msg: ClientMessage) -> Iterator[Reply]:
        """Load an upload and send its mesh and state; the times of each step are logged (INFO, one JSON line)."""
        arrived, decoded = self.arrived.pop(id(msg), (float("nan"), float("nan")))
        started = time.time()
        assert msg.payload is not None
        mesh, cpu = _timed(load_upload, msg.payload, msg.fields["filename"], self.config.max_vertices)
        look = look_from_upload(msg.payload, msg.fields["filename"], mesh, self.config.max_vertices)
        parsed = time.time()
        self.session.load(mesh, look)
        self.take_skipped()
        frames = list(self.mesh(mesh))
        encoded = time.time()
        yield from frames
        del frames
        mesh_sent = time.time()
        yield self.state()
        if logger.isEnabledFor(logging.INFO):
            ms = {"decode_ms": decoded - arrived, "queued_ms": started - decoded, "parse_repair_ms": parsed - started,
                  "encode_ms": encoded - parsed, "send_mesh_ms": mesh_sent - encoded,
                  "send_state_ms": time.time() - mesh_sent}
            logger.info("upload timings %s", json.dumps({"name": mesh.name, "n_vertices": mesh.n_vertices,
                                                         "arrived": arrived, "mesh_sent": mesh_sent,
                                                         "parse_repair_cpu_ms": round(1000 * cpu, 2),
                                                         **{k: round(1000 * v, 2) for k, v in ms.items()}}))


def state_message(session: Session) -> dict[str, Any]:
    """The ``state`` message of ``session``: history, parameters, constraints, transforms and statistics."""
    n = session.n_vertices
    cs = session.constraints
    solver = session.solver
    return server_message(
        "state",
        can_undo=session.can_undo,
        can_redo=session.can_redo,
        params=asdict(session.params),
        constraints=cs.to_json(),
        transforms=matrices_to_json(session.transforms),
        rest_id=session.rest_id,
        stats={
            "n_vertices": n,
            "n_faces": 0 if session.mesh is None else session.mesh.n_faces,
            "roi_size": n if cs.roi is None else len(cs.roi),
            "n_free": 0 if solver is None else int(solver.n_free),
            "factor_ms": 0.0 if solver is None else 1000.0 * float(solver.factor_seconds),
        },
    )
