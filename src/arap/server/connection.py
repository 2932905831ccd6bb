"""One WebSocket connection of the studio: reads requests, coalesces drags, runs them in order on one worker.

The reader task validates every frame and puts it in the session's queue; a ``drag`` replaces a ``drag`` already
waiting at the end of the queue instead of queueing behind it, so the worker always solves the newest target and
never works through a backlog. The worker handles one request at a time, running solves, factorisations and
file parsing on a thread so that the event loop (and the other sessions) keep going. Large frames are decoded
and validated on a thread too; the reader stops reading while the session's byte budgets
(:mod:`arap.server.budget`) are exhausted, and no frame, however malformed, ends the session: every failure
becomes an ``error`` answer.

A ``vertices`` frame is sent only once the client has taken what was sent before it (at most :data:`TAKEN_BYTES`
still queued for it: :meth:`Connection._until_taken`), and while settling only the newest shape waits to be sent: a
newer one replaces it. A page that reads slowly gets fewer frames, never a backlog: the socket never holds more than
about one frame in front of the keepalive pings, however large the mesh.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import anyio.to_thread
import numpy as np
from starlette.websockets import WebSocket, WebSocketDisconnect

from arap.server.appearance import Look
from arap.server.budget import ByteBudget, RequestQueue, request_cost
from arap.server.client_messages import Drag, ExportAnimation, Upload
from arap.server.decoder import PROCESS_BYTES, FrameDecoder
from arap.server.dispatch import Dispatcher
from arap.server.errors import RequestError
from arap.server.frames import encode_binary
from arap.server.mesh_model import MeshData
from arap.server.messages import ClientMessage
from arap.server.protocol import parse_binary, parse_text
from arap.server.records import DragOutcome
from arap.server.replies import SETTLE, Reply
from arap.server.server_messages import Preparing
from arap.server.session import Session
from arap.server.studio_config import StudioConfig, check_upload_size
from arap.warmup import KERNELS_READY

__all__ = ["SEND_QUEUE_EXTENSION", "TAKEN_BYTES", "Connection"]

logger = logging.getLogger(__name__)

T = TypeVar("T")

OFF_LOOP_BYTES = 256 * 1024
"""Frames at least this large are decoded and validated on a thread, not on the event loop."""
KERNEL_WAIT_SECONDS = 600.0
"""Longest a new connection waits for a background warm-up of the kernels before it is greeted anyway."""
PREPARING_SECONDS = 1.0
"""Time between two ``preparing`` messages while a new connection waits for the kernels."""
SEND_QUEUE_EXTENSION = "arap.send_queue"
"""ASGI scope extension of the studio's WebSocket protocol (:func:`arap.server.runner.websocket_protocol`):
``{"bytes": callable}``, the bytes written to the connection that its client has not taken yet. Without it (another
server) a frame counts as taken once the server's WebSocket has accepted it."""
TAKEN_BYTES = 16 * 1024
"""The client has taken what was sent to it when at most this much of it is still queued for it (asyncio's
low-water mark): then the next ``vertices`` frame is sent."""
TAKEN_POLL_SECONDS = 0.01
"""Pause between two looks at the bytes queued for a client while a frame waits for it."""


def _dumps(message: dict[str, Any]) -> str:
    return json.dumps(message, separators=(",", ":"), allow_nan=False)


class Connection:
    """Serves one WebSocket: its own :class:`~arap.server.session.Session`.

    Parameters
    ----------
    ws : WebSocket
    config : StudioConfig
    default_mesh : MeshData
        Mesh the session starts with.
    decoder : FrameDecoder or None
        Decodes text frames of :data:`~arap.server.decoder.PROCESS_BYTES` or more in a worker process; None decodes
        them on a thread.
    prepare : callable or None
        Called with the session once it holds the default mesh, before the page receives it (e.g. to set initial
        constraints); the page then adopts the session's constraints and shape.
    default_look : Look or None
        The default mesh file's colours and texture (:mod:`arap.server.appearance`), None for a plain mesh.
    """

    def __init__(self, ws: WebSocket, config: StudioConfig, default_mesh: MeshData,
                 decoder: FrameDecoder | None = None, prepare: Callable[[Session], object] | None = None,
                 default_look: Look | None = None) -> None:
        self.ws = ws
        self.config = config
        self.default_mesh = default_mesh
        self.default_look = default_look
        self.decoder = decoder
        self.prepare = prepare
        self.session = Session(config.max_history_steps, config.max_history_bytes)
        self.dispatch = Dispatcher(self.session, config)
        self.budget = ByteBudget(config.max_queued_bytes, config.max_unsent_bytes)
        self._queue: RequestQueue[ClientMessage | RequestError] = RequestQueue(self.budget)
        self._wakeup = asyncio.Event()
        self._send_lock = asyncio.Lock()
        self._frame_tasks: set[asyncio.Task[None]] = set()
        self._closed = False
        queue = ws.scope.get("extensions", {}).get(SEND_QUEUE_EXTENSION)
        self._queued: Callable[[], int] | None = queue.get("bytes") if isinstance(queue, dict) else None
        self._shape: np.ndarray | None = None
        """The newest settling shape not yet sent (a newer one replaces it)."""
        self._statuses: list[Reply] = []
        """Settling progress messages not yet sent, in order (every one is sent)."""
        self._pump: asyncio.Task[None] | None = None
        self.superseded = 0
        """Settling shapes replaced by a newer one before the client had taken the frame before them."""

    # ------------------------------------------------------------------ sending
    async def _send_frame(self, frame: str | bytes) -> None:
        """Send one frame; its bytes count against the unsent budget until the socket has taken them."""
        size = len(frame)
        self.budget.add_unsent(size)
        try:
            async with self._send_lock:
                if isinstance(frame, str):
                    await self.ws.send_text(frame)
                else:
                    await self.ws.send_bytes(frame)
        finally:
            self.budget.add_unsent(-size)

    async def _send_json(self, message: dict[str, Any]) -> None:
        await self._send_frame(_dumps(message))

    async def _send_binary(self, header: dict[str, Any], *payload: bytes) -> None:
        await self._send_frame(encode_binary(header, *payload))

    async def _until_taken(self) -> None:
        """Wait until the client has taken what was sent to it (at most :data:`TAKEN_BYTES` still queued for it), or
        has gone. The keepalive pings go out meanwhile: what is queued in front of them stays bounded."""
        queued = self._queued
        if queued is None:
            return
        while not self._closed and queued() > TAKEN_BYTES:
            await asyncio.sleep(TAKEN_POLL_SECONDS)

    async def _send_reply(self, reply: Reply) -> None:
        if isinstance(reply, tuple) and reply[0].get("type") == "vertices":
            await self._until_taken()  # a frame never queues behind another one
        if isinstance(reply, dict):
            await self._send_json(reply)
        elif isinstance(reply, bytes):
            await self._send_frame(reply)
        else:
            await self._send_binary(reply[0], *reply[1])

    async def _send_vertices(self, seq: int, outcome: DragOutcome | None) -> None:
        await self._send_reply(self.dispatch.vertices(seq, outcome))

    async def _send_error(self, exc: RequestError) -> None:
        await self._send_json(self.dispatch.error(exc))  # type: ignore[arg-type]

    async def _answer(self, replies: Iterator[Reply | object]) -> None:
        """Send what a dispatcher's generator yields; each of its steps runs on a thread (solves, file parsing,
        encoding), the sending on the event loop; :data:`~arap.server.replies.SETTLE` settles the shape."""
        done = object()
        while True:
            reply = await self._off_loop(next, replies, done)
            if reply is done:
                return
            if reply is SETTLE:
                await self._settle()
            else:
                await self._send_reply(reply)

    @staticmethod
    async def _off_loop(fn: Callable[..., T], *args: Any) -> T:
        return await anyio.to_thread.run_sync(fn, *args)

    # ------------------------------------------------------------------ main loop
    async def run(self) -> None:
        """Accept the connection and serve it until the client goes away."""
        await self.ws.accept()
        try:
            if not KERNELS_READY.is_set():  # first run: the page shows how far the compilation is meanwhile
                await self._wait_for_kernels()
            await self._answer(self.dispatch.greeting(self.default_mesh, self.default_look, self.prepare))
        except (WebSocketDisconnect, RuntimeError, OSError) as exc:
            logger.debug("connection closed during the greeting: %r", exc)
            return
        reader = asyncio.create_task(self._read_all())
        worker = asyncio.create_task(self._worker())
        try:
            # the worker ends early only when the client is gone (a failed send): then stop reading too
            await asyncio.wait({reader, worker}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            self._closed = True  # a settling run stops at its next iteration: its thread must not outlive us
            for task in (reader, worker):
                task.cancel()
            for task in (reader, worker):
                with contextlib.suppress(asyncio.CancelledError):
                    await task
            self._queue.clear()

    async def _wait_for_kernels(self) -> None:
        """Send ``preparing`` about every :data:`PREPARING_SECONDS` until the kernels a session needs are ready (at
        most :data:`KERNEL_WAIT_SECONDS`)."""
        from arap.warmup import compile_progress

        deadline = time.monotonic() + KERNEL_WAIT_SECONDS
        while time.monotonic() < deadline:
            p = compile_progress()
            await self._send_json(Preparing(done=p.done, total=p.total, kernel=p.kernel, compiling=p.compiling,
                                            seconds=round(p.seconds, 1)).to_wire())
            if await self._off_loop(KERNELS_READY.wait, PREPARING_SECONDS):
                return

    async def _read_all(self) -> None:
        try:
            await self._reader()
        except (WebSocketDisconnect, RuntimeError, OSError) as exc:
            logger.debug("connection closed: %r", exc)

    async def _reader(self) -> None:
        while True:
            await self.budget.wait_for_room()
            message = await self.ws.receive()
            arrived = time.time()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            data = message.get("bytes")
            size = len(text) if text is not None else len(data or b"")
            if (text is not None and self.decoder is not None
                    and PROCESS_BYTES <= size <= self.config.max_frame_bytes):
                item = await self._decode_in_process(self.decoder, text, self.config.max_vertices)
            elif size >= OFF_LOOP_BYTES:
                item = await self._off_loop(self._decode, text, data, True)
            else:
                item = self._decode(text, data, False)
            del message, text, data
            if isinstance(item, Upload):
                self.dispatch.arrived[id(item)] = (arrived, time.time())
            cost = request_cost(size, not isinstance(item, Upload)) if isinstance(item, ClientMessage) else 0
            await self._enqueue(item, cost)

    @staticmethod
    async def _decode_in_process(decoder: FrameDecoder, text: str,
                                 max_indices: int) -> ClientMessage | RequestError:
        """Decode a large text frame in the decoder process; never raises (a failure becomes the ``error``)."""
        try:
            return await decoder.decode(text, max_indices)
        except RequestError as exc:
            return exc
        except MemoryError:
            return RequestError("too_large", f"not enough memory to decode a frame of {len(text):,} characters")
        except Exception:
            logger.exception("unexpected error while decoding a frame of %d characters", len(text))
            return RequestError("internal", "unexpected server error while reading a message; see the server log")

    def _decode(self, text: str | None, data: bytes | None, large: bool) -> ClientMessage | RequestError:
        """Decode and validate one frame; never raises (a failure becomes the ``error`` to answer)."""
        size = len(text) if text is not None else len(data or b"")
        try:
            if size > self.config.max_frame_bytes:
                raise RequestError("too_large", f"frame of {size:,} bytes exceeds the limit of "
                                   f"{self.config.max_frame_bytes:,}")
            if text is not None:
                return parse_text(text, cooperative=large, max_indices=self.config.max_vertices)
            if data is None:
                raise RequestError("bad_message", "empty frame")
            return check_upload_size(self.config, parse_binary(data))
        except RequestError as exc:
            return exc
        except MemoryError:
            return RequestError("too_large", f"not enough memory to decode a frame of {size:,} bytes")
        except Exception:
            logger.exception("unexpected error while decoding a frame of %d bytes", size)
            return RequestError("internal", "unexpected server error while reading a message; see the server log")

    async def _enqueue(self, item: ClientMessage | RequestError, cost: int = 0) -> None:
        if isinstance(item, Drag):
            last = self._queue[-1] if self._queue else None
            if isinstance(last, Drag):
                # the replaced drag is never answered; the answer to this one reports it in ``skipped``
                self._queue.replace_last(item, cost)
                self.dispatch.count_skipped()
                return
        if len(self._queue) >= self.config.max_pending:
            self.dispatch.arrived.pop(id(item), None)
            request = item.type if isinstance(item, ClientMessage) else item.request
            await self._send_error(RequestError("busy", f"{len(self._queue)} requests are already waiting",
                                                request))
            return
        self._queue.append(item, cost)
        self._wakeup.set()

    async def _worker(self) -> None:
        try:
            await self._work()
        except (WebSocketDisconnect, RuntimeError, OSError) as exc:
            logger.debug("connection closed while answering: %r", exc)

    async def _work(self) -> None:
        while True:
            await self._wakeup.wait()
            self._wakeup.clear()
            while self._queue:
                item = self._queue.popleft()
                if isinstance(item, RequestError):
                    await self._send_error(item)
                    continue
                try:
                    await self._handle(item)
                except RequestError as exc:
                    exc.__traceback__ = None  # its frames hold the request and the future holding exc: no cycle
                    exc.request = exc.request or item.type
                    await self._send_error(exc)
                except WebSocketDisconnect:
                    raise
                except Exception:
                    logger.exception("unexpected error while handling %s", item.type)
                    await self._send_error(RequestError("internal", f"unexpected server error in {item.type}; "
                                                        "see the server log", item.type))
            if not self._queue:
                await self._settle()

    async def _settle(self) -> None:
        """Iterate the session's shape until converged, off the event loop; a queued request stops it at once.

        Progress is streamed as ``settle`` status messages, at most 30 per second, each after a ``vertices`` frame
        (seq -1) of the intermediate shape when it moved visibly since the last one sent; the settled (or
        interrupted) shape is sent last.
        """
        s = self.session
        if not s.needs_settle:
            return
        loop = asyncio.get_running_loop()
        streamed = 0

        def on_frame(U: np.ndarray | None, iteration: int, energy: float) -> None:
            nonlocal streamed
            streamed += U is not None
            status = self.dispatch.settle_status("settling", iteration, energy, None)
            with contextlib.suppress(RuntimeError):  # the loop has closed: the connection is gone
                loop.call_soon_threadsafe(self._offer_settle_frame, U, status)

        outcome = None
        try:
            await self._send_reply(self.dispatch.settle_status("settling", 0, None, 0.0))
            outcome = await self._off_loop(self.dispatch.settle_session, lambda: bool(self._queue) or self._closed,
                                           on_frame)
        except RequestError as exc:
            await self._send_error(exc)
            return
        finally:
            if outcome is not None:
                self._shape = None  # superseded by the shape settle_done sends (it was streamed, so it is sent)
            # Frames of this run go out before anything that answers the next request: a frame of the old
            # constraint set or mesh arriving after the new one would be applied to the wrong shape.
            if self._frame_tasks:
                await asyncio.gather(*self._frame_tasks, return_exceptions=True)
        if outcome is None:
            return
        for reply in await self._off_loop(self.dispatch.settle_done, outcome, streamed):
            await self._send_reply(reply)

    def _offer_settle_frame(self, U: np.ndarray | None, status: Reply) -> None:
        """A settling run's report (on the event loop): ``U`` (None: no visible change) replaces the shape waiting to
        be sent, ``status`` is queued; both go out as soon as the client has taken the frame before."""
        if U is not None:
            self.superseded += self._shape is not None
            self._shape = U
        self._statuses.append(status)
        if self._pump is None:
            self._pump = asyncio.ensure_future(self._send_settle_frames())
            self._frame_tasks.add(self._pump)
            self._pump.add_done_callback(self._frame_tasks.discard)

    async def _send_settle_frames(self) -> None:
        """Send the newest settling shape once the client has taken the frame before it, then the progress
        messages queued meanwhile; until none waits."""
        try:
            with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
                while self._shape is not None or self._statuses:
                    if self._shape is not None:
                        await self._until_taken()
                    U, self._shape = self._shape, None
                    if U is not None:
                        frame = await self._off_loop(self._encode_shape, U)
                        await self._send_reply(frame)
                    statuses, self._statuses = self._statuses, []
                    for status in statuses:
                        await self._send_reply(status)
        finally:
            self._pump = None
            self._shape = None
            self._statuses = []

    def _encode_shape(self, U: np.ndarray) -> Reply:
        """The ``vertices`` frame (seq -1) of a settling shape (on a thread)."""
        return self.dispatch.vertices(-1, None, self.dispatch.stream.encode(U, self.session.constraints))

    async def _export_animation(self, msg: ExportAnimation) -> None:
        """Solve and send the animated GLB of export_animation off the event loop
        (:meth:`~arap.server.dispatch.Dispatcher.export_animation`); a queued request cancels it (``cancelled`` is
        sent, then that request runs)."""
        loop = asyncio.get_running_loop()

        def send(message: Reply) -> None:
            assert isinstance(message, dict)  # progress messages are JSON
            with contextlib.suppress(RuntimeError):  # the loop has closed: the connection is gone
                loop.call_soon_threadsafe(self._spawn_json, message)

        try:
            reply = await self._off_loop(self.dispatch.export_animation, msg,
                                         lambda: bool(self._queue) or self._closed, send)
        finally:
            if self._frame_tasks:
                await asyncio.gather(*self._frame_tasks, return_exceptions=True)
        await self._send_reply(reply)

    def _spawn_json(self, message: dict[str, Any]) -> None:
        task = asyncio.ensure_future(self._send_json_quietly(message))
        self._frame_tasks.add(task)
        task.add_done_callback(self._frame_tasks.discard)

    async def _send_json_quietly(self, message: dict[str, Any]) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            await self._send_json(message)

    # ------------------------------------------------------------------ requests
    async def _handle(self, msg: ClientMessage) -> None:
        if isinstance(msg, ExportAnimation):
            await self._export_animation(msg)
        else:
            await self._answer(self.dispatch.handle(msg))
