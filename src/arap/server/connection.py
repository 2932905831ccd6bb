"""One WebSocket connection of the studio: reads requests, coalesces drags, runs them in order on one worker.

The reader task validates every frame and puts it in the session's queue; a ``drag`` replaces a ``drag`` already
waiting at the end of the queue instead of queueing behind it, so the worker always solves the newest target and
never works through a backlog. The worker handles one request at a time, running solves, factorisations and
file parsing on a thread so that the event loop (and the other sessions) keep going. Large frames are decoded
and validated on a thread too; the reader stops reading while the session's byte budgets
(:mod:`arap.server.budget`) are exhausted, and no frame, however malformed, ends the session: every failure
becomes an ``error`` answer.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, TypeVar

import anyio.to_thread
import numpy as np
from starlette.websockets import WebSocket, WebSocketDisconnect

import arap
from arap.kernel_cache import KERNELS_READY
from arap.server.animation_export import AnimationCancelled
from arap.server.budget import ByteBudget, RequestQueue, request_cost
from arap.server.decoder import PROCESS_BYTES, FrameDecoder
from arap.server.heatmap import distortion_frame
from arap.server.liveframes import VertexPayload, VertexStream, still_frame_header
from arap.server.meshdata import MeshData, builtin_names, load_builtin, load_upload, mesh_frame
from arap.server.protocol import (
    MAX_HANDLE_GROUPS,
    PROTOCOL_VERSION,
    ClientMessage,
    RequestError,
    check_against_mesh,
    encode_binary,
    error_message,
    parse_binary,
    parse_text,
    server_message,
)
from arap.server.records import readable_energy
from arap.server.render_mesh import Look, look_from_upload
from arap.server.session import DragOutcome, Session

__all__ = ["Connection", "StudioConfig"]

logger = logging.getLogger(__name__)

T = TypeVar("T")

OFF_LOOP_BYTES = 256 * 1024
KERNEL_WAIT_SECONDS = 600.0
"""Longest a new connection waits for a background warm-up of the kernels before it is greeted anyway."""
"""Frames at least this large are decoded and validated on a thread, not on the event loop."""


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


def _dumps(message: dict[str, Any]) -> str:
    return json.dumps(message, separators=(",", ":"), allow_nan=False)


def _timed(fn: Callable[..., T], *args: Any) -> tuple[T, float]:
    """``fn(*args)`` and the CPU time this thread spent in it (seconds)."""
    t0 = time.thread_time()
    return fn(*args), time.thread_time() - t0


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
        The default mesh file's colours and texture (:mod:`arap.server.render_mesh`), None for a plain mesh.
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
        self.budget = ByteBudget(config.max_queued_bytes, config.max_unsent_bytes)
        self._queue: RequestQueue[ClientMessage | RequestError] = RequestQueue(self.budget)
        self._wakeup = asyncio.Event()
        self._send_lock = asyncio.Lock()
        self._skipped = 0
        self._frame_tasks: set[asyncio.Task[None]] = set()
        self._stream = VertexStream(config.subset_frames)
        self._arrived: dict[int, tuple[float, float]] = {}
        self._closed = False

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

    async def _send_mesh(self, mesh: MeshData) -> None:
        self._stream.reset(mesh.V)
        await self._send_frame(await self._off_loop(mesh_frame, mesh))
        await self._send_appearance()

    async def _send_appearance(self) -> None:
        """The ``appearance`` of the session's mesh, right after its mesh frame; nothing for a plain mesh."""
        look = self.session.look
        if look is not None:
            await self._send_frame(await self._off_loop(lambda: look.frame))

    async def _upload(self, msg: ClientMessage) -> None:
        """Load an upload and send its mesh and state; the times of each step are logged (INFO, one JSON line)."""
        arrived, decoded = self._arrived.pop(id(msg), (float("nan"), float("nan")))
        started = time.time()
        assert msg.payload is not None
        mesh, cpu = await self._off_loop(_timed, load_upload, msg.payload, msg.fields["filename"],
                                         self.config.max_vertices)
        look = await self._off_loop(look_from_upload, msg.payload, msg.fields["filename"], mesh,
                                    self.config.max_vertices)
        parsed = time.time()
        self.session.load(mesh, look)
        self._skipped = 0
        self._stream.reset(mesh.V)
        frame = await self._off_loop(mesh_frame, mesh)
        encoded = time.time()
        await self._send_frame(frame)
        del frame
        await self._send_appearance()
        mesh_sent = time.time()
        await self._send_state()
        if logger.isEnabledFor(logging.INFO):
            ms = {"decode_ms": decoded - arrived, "queued_ms": started - decoded, "parse_repair_ms": parsed - started,
                  "encode_ms": encoded - parsed, "send_mesh_ms": mesh_sent - encoded,
                  "send_state_ms": time.time() - mesh_sent}
            logger.info("upload timings %s", json.dumps({"name": mesh.name, "n_vertices": mesh.n_vertices,
                                                         "arrived": arrived, "mesh_sent": mesh_sent,
                                                         "parse_repair_cpu_ms": round(1000 * cpu, 2),
                                                         **{k: round(1000 * v, 2) for k, v in ms.items()}}))

    async def _send_vertices(self, seq: int, outcome: DragOutcome | None) -> None:
        subset, movable, parts = self._stream.encode(self.session.U, self.session.constraints)
        if outcome is None:
            header = still_frame_header(seq, subset, movable)
        else:
            header = server_message("vertices", seq=seq, skipped=self._skipped, iterations=outcome.iterations,
                                    energies=[readable_energy(e, self.session.diagonal) for e in outcome.energies],
                                    solve_ms=round(outcome.solve_ms, 3),
                                    ms_per_iteration=round(outcome.ms_per_iteration, 3),
                                    subset=subset, movable=movable)
            self._skipped = 0
        await self._send_binary(header, *parts)

    async def _send_state(self) -> None:
        # the state echoes the constraints, which can hold millions of indices: encoded off the event loop
        await self._send_frame(await self._off_loop(lambda: _dumps(self.session.state())))

    async def _send_error(self, exc: RequestError) -> None:
        await self._send_json(error_message(exc))

    @staticmethod
    async def _off_loop(fn: Callable[..., T], *args: Any) -> T:
        return await anyio.to_thread.run_sync(fn, *args)

    # ------------------------------------------------------------------ main loop
    async def run(self) -> None:
        """Accept the connection and serve it until the client goes away."""
        await self.ws.accept()
        try:
            if not KERNELS_READY.is_set():  # first run: the page says that the solver is being prepared meanwhile
                await self._off_loop(KERNELS_READY.wait, KERNEL_WAIT_SECONDS)
            await self._off_loop(self.session.load, self.default_mesh, self.default_look)
            if self.prepare is not None:
                await self._off_loop(self.prepare, self.session)
            await self._send_json(server_message(
                "welcome",
                version=arap.__version__,
                protocol=PROTOCOL_VERSION,
                builtin_meshes=builtin_names(),
                limits={"max_upload_bytes": self.config.max_upload_bytes,
                        "max_vertices": self.config.max_vertices,
                        "max_frame_bytes": self.config.max_frame_bytes,
                        "max_handle_groups": MAX_HANDLE_GROUPS},
                params=asdict(self.session.params),
            ))
            await self._send_mesh(self.default_mesh)
            await self._send_state()
            if self.prepare is not None:
                await self._send_vertices(-1, None)
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
                item = await self._decode_in_process(self.decoder, text)
            elif size >= OFF_LOOP_BYTES:
                item = await self._off_loop(self._decode, text, data, True)
            else:
                item = self._decode(text, data, False)
            del message, text, data
            if isinstance(item, ClientMessage) and item.type == "upload":
                self._arrived[id(item)] = (arrived, time.time())
            cost = request_cost(size, item.payload is None) if isinstance(item, ClientMessage) else 0
            await self._enqueue(item, cost)

    @staticmethod
    async def _decode_in_process(decoder: FrameDecoder, text: str) -> ClientMessage | RequestError:
        """Decode a large text frame in the decoder process; never raises (a failure becomes the ``error``)."""
        try:
            return await decoder.decode(text)
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
                return parse_text(text, cooperative=large)
            if data is None:
                raise RequestError("bad_message", "empty frame")
            item = parse_binary(data)
            if item.payload is not None and len(item.payload) > self.config.max_upload_bytes:
                raise RequestError("too_large", f"upload of {len(item.payload):,} bytes exceeds the "
                                   f"limit of {self.config.max_upload_bytes:,}", item.type)
            return item
        except RequestError as exc:
            return exc
        except MemoryError:
            return RequestError("too_large", f"not enough memory to decode a frame of {size:,} bytes")
        except Exception:
            logger.exception("unexpected error while decoding a frame of %d bytes", size)
            return RequestError("internal", "unexpected server error while reading a message; see the server log")

    async def _enqueue(self, item: ClientMessage | RequestError, cost: int = 0) -> None:
        if isinstance(item, ClientMessage) and item.type == "drag":
            last = self._queue[-1] if self._queue else None
            if isinstance(last, ClientMessage) and last.type == "drag":
                # the replaced drag is never answered; the answer to this one reports it in ``skipped``
                self._queue.replace_last(item, cost)
                self._skipped += 1
                return
        if len(self._queue) >= self.config.max_pending:
            self._arrived.pop(id(item), None)
            request = item.type if isinstance(item, ClientMessage) else item.request
            await self._send_error(RequestError("busy", f"{len(self._queue)} requests are already waiting",
                                                request))
            return
        self._queue.append(item, cost)
        self._wakeup.set()

    async def _check(self, msg: ClientMessage) -> None:
        """:func:`check_against_mesh`; off the event loop for constraint sets (they can list millions of indices)."""
        args = (msg, self.session.n_vertices, self.session.n_groups)
        if msg.type == "set_constraints":
            await self._off_loop(check_against_mesh, *args)
        else:
            check_against_mesh(*args)

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
                    await self._check(item)
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
            frame = None
            if U is not None:
                streamed += 1
                frame = self._stream.encode(U, s.constraints)
            with contextlib.suppress(RuntimeError):  # the loop has closed: the connection is gone
                loop.call_soon_threadsafe(self._spawn_settle_frame, frame, iteration, energy)

        try:
            await self._send_settle_status("settling", 0, None, 0.0)
            outcome = await self._off_loop(s.settle, lambda: bool(self._queue) or self._closed, on_frame)
        except RequestError as exc:
            await self._send_error(exc)
            return
        finally:
            # Frames of this run go out before anything that answers the next request: a frame of the old
            # constraint set or mesh arriving after the new one would be applied to the wrong shape.
            if self._frame_tasks:
                await asyncio.gather(*self._frame_tasks, return_exceptions=True)
        if outcome is None:
            return
        if streamed or outcome.moved > 0:  # the client has not seen this shape yet
            await self._send_vertices(-1, None)
        await self._send_settle_status(outcome.status, outcome.iterations, outcome.energy, outcome.seconds)

    def _spawn_settle_frame(self, frame: VertexPayload | None, iteration: int, energy: float) -> None:
        task = asyncio.ensure_future(self._send_settle_frame(frame, iteration, energy))
        self._frame_tasks.add(task)
        task.add_done_callback(self._frame_tasks.discard)

    async def _send_settle_frame(self, frame: VertexPayload | None, iteration: int, energy: float) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            if frame is not None:
                subset, movable, parts = frame
                await self._send_binary(still_frame_header(-1, subset, movable), *parts)
            await self._send_settle_status("settling", iteration, energy, None)

    async def _send_shape_status(self) -> None:
        """``settle`` for a shape that needs no settling (after undo, redo, apply or loading), so that the client's
        status and energy describe the shape it now shows; a shape that needs it is settled next."""
        if not self.session.needs_settle:
            await self._send_settle_status("settled", 0, self.session.energy, 0.0)

    async def _send_settle_status(self, status: str, iterations: int, energy: float | None,
                                  seconds: float | None) -> None:
        await self._send_json(server_message("settle", status=status, iterations=iterations,
                                             energy=readable_energy(energy, self.session.diagonal),
                                             seconds=None if seconds is None else round(seconds, 4)))

    async def _export_animation(self, f: dict[str, Any]) -> None:
        """Solve and send the animated GLB of export_animation off the event loop, with ``animation_progress`` at
        most 10 times per second; a queued request cancels it (``cancelled`` is sent, then that request runs)."""
        loop = asyncio.get_running_loop()
        last = [0.0]
        t0 = time.perf_counter()

        def progress(done: int, frames: int) -> None:
            now = time.perf_counter()
            if done and done < frames and now - last[0] < 0.1:
                return
            last[0] = now
            message = server_message("animation_progress", status="solving", frame=done, frames=frames,
                                     seconds=round(now - t0, 3))
            with contextlib.suppress(RuntimeError):  # the loop has closed: the connection is gone
                loop.call_soon_threadsafe(self._spawn_json, message)

        try:
            filename, mime, data, frames, seconds = await self._off_loop(
                self.session.export_animation, f["times_ms"], f["transforms"], f["fps"],
                lambda: bool(self._queue) or self._closed, progress)
        except AnimationCancelled:
            await self._send_json(server_message("animation_progress", status="cancelled", frame=0, frames=0,
                                                 seconds=round(time.perf_counter() - t0, 3)))
            return
        finally:
            if self._frame_tasks:
                await asyncio.gather(*self._frame_tasks, return_exceptions=True)
        await self._send_binary(server_message("animation", filename=filename, mime=mime, frames=frames,
                                               seconds=round(seconds, 3)), data)

    def _spawn_json(self, message: dict[str, Any]) -> None:
        task = asyncio.ensure_future(self._send_json_quietly(message))
        self._frame_tasks.add(task)
        task.add_done_callback(self._frame_tasks.discard)

    async def _send_json_quietly(self, message: dict[str, Any]) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            await self._send_json(message)

    # ------------------------------------------------------------------ requests
    async def _handle(self, msg: ClientMessage) -> None:
        s = self.session
        f = msg.fields
        t = msg.type
        if t == "drag":
            outcome = await self._off_loop(s.drag, f["transforms"])
            await self._send_vertices(f["seq"], outcome)
        elif t == "end_drag":
            s.end_drag()
            await self._send_state()
        elif t == "load_builtin":
            mesh = await self._off_loop(load_builtin, f["name"])
            await self._off_loop(s.load, mesh)
            self._skipped = 0
            await self._send_mesh(mesh)
            await self._send_state()
            await self._send_shape_status()
        elif t == "upload":
            await self._upload(msg)
            await self._send_shape_status()
        elif t == "set_constraints":
            solved = await self._off_loop(s.set_constraints, f["roi"], f["fixed"], f["handle_groups"],
                                          f.get("targets"), f.get("stiffness"), f.get("points"))
            if solved is not None:
                await self._send_vertices(-1, solved)
            await self._send_state()
        elif t == "set_params":
            await self._off_loop(lambda: s.set_params(**f))
            await self._send_state()
        elif t in ("undo", "redo", "reset", "apply"):
            before = s.U
            await self._off_loop(getattr(s, t))
            self._stream.reset(None)  # everything may have changed: the next frame is full
            if s.U is not before and not np.array_equal(s.U, before):
                await self._send_vertices(-1, None)
            await self._send_state()
            await self._send_shape_status()
        elif t == "export":
            # The exported shape must not depend on timing: an unsettled shape settles first (a new request
            # stops it, and the shape reached is exported).
            await self._settle()
            filename, mime, data = await self._off_loop(s.export, f["format"])
            await self._send_binary(server_message("export", filename=filename, mime=mime), data)
        elif t == "get_distortion":
            header, data = await self._off_loop(distortion_frame, s)
            await self._send_binary(header, data)
        elif t == "get_constraints":
            document = await self._off_loop(s.constraints_document, f.get("times_ms"), f.get("transforms"))
            await self._send_json(server_message("constraints", document=document))
        elif t == "export_animation":
            await self._export_animation(f)
        else:
            raise RequestError("bad_message", f"unhandled message type {t!r}")
