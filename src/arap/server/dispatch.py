"""The studio protocol's answers for one session, whatever carries them (a WebSocket, a Jupyter comm).

A :class:`Dispatcher` turns validated client messages into the server messages that answer them, as
:class:`~arap.server.replies.Reply` values; the transport only sends them, in order. Each message class has its
handler (:meth:`Dispatcher.handle` picks it by the message's class), and the session's refusals
(:mod:`arap.server.session_errors`) become :class:`~arap.server.errors.RequestError` here, with the code of
:data:`arap.server.errors.SESSION_ERROR_CODES`. :mod:`arap.server.connection` runs it on an event loop (each step
on a thread), :class:`arap.server.channel.ChannelWorker` on a thread of its own for synchronous channels such as a
notebook widget's comm (:mod:`arap.jupyter_widget`). Both coalesce drags the same way, settle the shape when no
request waits and stop settling as soon as one arrives.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from arap.server.animation_export import AnimationCancelled, export_animation, keyframes_document
from arap.server.appearance import BUNDLE_EXPANSION, Look, is_bundle, load_bundle_upload, look_from_upload
from arap.server.client_messages import (
    Apply,
    Drag,
    EndDrag,
    Export,
    ExportAnimation,
    GetConstraints,
    GetDistortion,
    KeepShape,
    LoadBuiltin,
    Redo,
    Remesh,
    Reset,
    SetConstraints,
    SetParams,
    SetPinAngle,
    SetPinDepth,
    Undo,
    Upload,
)
from arap.server.errors import RequestError, request_error
from arap.server.heatmap import distortion_frame
from arap.server.liveframes import VertexPayload, VertexStream, still_frame_header
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_builtin, load_upload, mesh_frame
from arap.server.messages import ClientMessage
from arap.server.pictures import is_picture, load_picture
from arap.server.protocol import check_against_mesh, error_message, validate
from arap.server.records import DragOutcome, SettleOutcome
from arap.server.replies import (
    SETTLE,
    Reply,
    _Settle,
    appearance_frame,
    settle_message,
    state_message,
    vertices_header,
    welcome_message,
)
from arap.server.server_messages import Animation, AnimationProgress, Constraints
from arap.server.server_messages import Export as ExportReply
from arap.server.session import Session
from arap.server.session_errors import SessionError
from arap.server.settling import FrameCallback
from arap.server.studio_config import StudioConfig, check_upload_size

__all__ = ["Dispatcher", "decode_message"]

logger = logging.getLogger("arap.server.connection")

Answers = Iterator[Reply | _Settle]
"""What a handler yields: the replies to send, and :data:`~arap.server.replies.SETTLE` where the shape must settle."""


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
        return check_upload_size(config, validate(content, binary=payload is not None, payload=payload))
    except RequestError as exc:
        return exc
    except Exception:
        logger.exception("unexpected error while decoding a message")
        return RequestError("internal", "unexpected server error while reading a message; see the server log")


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
        self._handlers: dict[type[ClientMessage], Callable[[Any], Answers]] = {
            Drag: self._drag,
            EndDrag: self._end_drag,
            LoadBuiltin: self._load_builtin,
            Upload: self._upload,
            SetConstraints: self._set_constraints,
            SetParams: self._set_params,
            Undo: self._history_step,
            Redo: self._history_step,
            Reset: self._history_step,
            Apply: self._history_step,
            Export: self._export,
            GetDistortion: self._get_distortion,
            GetConstraints: self._get_constraints,
            KeepShape: self._keep_shape,
            SetPinDepth: self._set_pin_depth,
            SetPinAngle: self._set_pin_angle,
            Remesh: self._remesh,
        }
        """The handler of each message class (``export_animation`` is run by the transports, which stream its
        progress: :meth:`export_animation`)."""

    # ------------------------------------------------------------------ messages
    def welcome(self) -> Reply:
        return welcome_message(self.session, self.config)

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
            yield appearance_frame(look)

    def count_skipped(self) -> None:
        """A queued drag was replaced by a newer one: the answer to the newer one reports it (``skipped``)."""
        with self._skipped_lock:
            self._skipped += 1

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
        return vertices_header(self.session, seq, self.take_skipped(), outcome, subset, movable), parts

    def settle_status(self, status: str, iterations: int, energy: float | None, seconds: float | None) -> Reply:
        return settle_message(self.session, status, iterations, energy, seconds)

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

    def settle_session(self, interrupted: Callable[[], bool], on_frame: FrameCallback) -> SettleOutcome | None:
        """:meth:`Session.settle`, a refusal raised as :class:`RequestError`."""
        try:
            return self.session.settle(interrupted, on_frame)
        except SessionError as exc:
            error = request_error(exc)
        raise error

    def settle(self, interrupted: Callable[[], bool], send: Callable[[Reply], object]) -> None:
        """Settle the shape on this thread, sending its progress with ``send``; ``interrupted`` stops it."""
        if not self.session.needs_settle:
            return
        streamed = 0

        def on_frame(U: np.ndarray | None, iteration: int, energy: float) -> None:
            nonlocal streamed
            streamed += U is not None
            for reply in self.settle_frame(U, iteration, energy):
                send(reply)

        send(self.settle_status("settling", 0, None, 0.0))
        try:
            outcome = self.settle_session(interrupted, on_frame)
        except RequestError as exc:
            send(self.error(exc))
            return
        if outcome is not None:
            for reply in self.settle_done(outcome, streamed):
                send(reply)

    # ------------------------------------------------------------------ requests
    def handle(self, msg: ClientMessage) -> Answers:
        """Check ``msg`` against the session's mesh and carry it out with its class's handler, yielding its answers
        (and :data:`SETTLE` where the shape must be settled first). Raises :class:`RequestError`."""
        check_against_mesh(msg, self.session.n_vertices, self.session.n_groups)
        handler = self._handlers.get(type(msg))
        if handler is None:
            raise RequestError("bad_message", f"unhandled message type {msg.type!r}")
        try:
            yield from handler(msg)
        except SessionError as exc:
            error = request_error(exc, msg.type)
        else:
            return
        raise error  # outside the handler: the session's error and its frames are not kept with it

    def export_animation(self, msg: ExportAnimation, interrupted: Callable[[], bool],
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
            send(AnimationProgress(status="solving", frame=done, frames=frames, seconds=round(now - t0, 3)).to_wire())

        try:
            filename, mime, data, frames, seconds = export_animation(
                self.session, msg.times_ms, msg.transforms, msg.fps, interrupted, progress, msg.easings, msg.keys,
                msg.format, self.config.exports)
        except AnimationCancelled:
            return AnimationProgress(status="cancelled", frame=0, frames=0,
                                     seconds=round(time.perf_counter() - t0, 3)).to_wire()
        except SessionError as exc:
            error = request_error(exc, msg.type)
        else:
            return Animation(filename=filename, mime=mime, frames=frames, seconds=round(seconds, 3)).to_wire(), [data]
        raise error

    def _drag(self, msg: Drag) -> Answers:
        outcome = self.session.drag(msg.transforms, msg.key)
        yield self.vertices(msg.seq, outcome)

    def _keep_shape(self, msg: KeepShape) -> Answers:
        # the converged shape is kept: an unsettled one settles first (as for an export); a given one as it is
        if msg.shape is None:
            yield SETTLE
        self.session.keep_shape(msg.key, msg.shape)

    def _end_drag(self, msg: EndDrag) -> Answers:
        self.session.end_drag()
        yield self.state()

    def _load_builtin(self, msg: LoadBuiltin) -> Answers:
        mesh = load_builtin(msg.name)
        self.session.load(mesh)
        self.take_skipped()
        yield from self.mesh(mesh)
        yield self.state()
        yield from self.shape_status()

    def _set_constraints(self, msg: SetConstraints) -> Answers:
        solved = self.session.set_constraints(msg.roi, msg.fixed, msg.handle_groups, msg.targets, msg.stiffness,
                                              msg.points)
        if solved is not None:
            yield self.vertices(-1, solved)
        yield self.state()

    def _set_params(self, msg: SetParams) -> Answers:
        self.session.set_params(msg.iterations, msg.energy, msg.weights, msg.alpha, msg.loose, msg.warp)
        yield self.state()

    def _set_pin_depth(self, msg: SetPinDepth) -> Answers:
        self.session.set_pin_depth(list(msg.depth))
        yield self.state()

    def _set_pin_angle(self, msg: SetPinAngle) -> Answers:
        outcome = self.session.set_pin_angle(msg.pin, msg.angle)
        yield self.vertices(-1, outcome)
        yield self.state()

    def _remesh(self, msg: Remesh) -> Answers:
        mesh = self.session.remesh(msg.density, self.config.max_vertices)
        self.take_skipped()
        yield from self.mesh(mesh)
        yield self.vertices(-1, None)
        yield self.state()
        yield from self.shape_status()

    def _history_step(self, msg: Undo | Redo | Reset | Apply) -> Answers:
        s = self.session
        before = s.U
        if isinstance(msg, Undo):
            s.undo()
        elif isinstance(msg, Redo):
            s.redo()
        elif isinstance(msg, Reset):
            s.reset()
        else:
            s.apply()
        self.stream.reset(None)  # everything may have changed: the next frame is full
        if s.U is not before and not np.array_equal(s.U, before):
            yield self.vertices(-1, None)
        yield self.state()
        yield from self.shape_status()

    def _export(self, msg: Export) -> Answers:
        # The exported shape must not depend on timing: an unsettled shape settles first (a new request stops it,
        # and the shape reached is exported).
        yield SETTLE
        filename, mime, data = self.session.export(msg.format)
        yield ExportReply(filename=filename, mime=mime).to_wire(), [data]

    def _get_distortion(self, msg: GetDistortion) -> Answers:
        header, data = distortion_frame(self.session)
        yield header, [data]

    def _get_constraints(self, msg: GetConstraints) -> Answers:
        # with the timeline's keyframes when the message carries them
        s = self.session
        times = msg.times_ms
        document = (keyframes_document(s, times, msg.transforms or [], msg.easings, msg.keys) if times
                    else s.constraints_document())
        yield Constraints(document=document).to_wire()

    def _upload(self, msg: Upload) -> Answers:
        """Load an upload and send its mesh and state, then the shape's status; the times of each step are logged
        (INFO, one JSON line)."""
        arrived, decoded = self.arrived.pop(id(msg), (float("nan"), float("nan")))
        started = time.time()
        if is_picture(msg.filename):
            (mesh, look), cpu = _timed(load_picture, msg.payload, msg.filename, self.config.max_vertices)
        elif is_bundle(msg.filename):
            (mesh, look), cpu = _timed(load_bundle_upload, msg.payload, msg.filename, self.config.max_vertices,
                                       BUNDLE_EXPANSION * self.config.max_upload_bytes)
        else:
            mesh, cpu = _timed(load_upload, msg.payload, msg.filename, self.config.max_vertices)
            look = look_from_upload(msg.payload, msg.filename, mesh, self.config.max_vertices)
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
        yield from self.shape_status()
