"""One WebSocket connection of the studio: reads requests, coalesces drags, runs them in order on one worker.

The reader task validates every frame and puts it in the session's queue; a ``drag`` replaces a ``drag`` already
waiting at the end of the queue instead of queueing behind it, so the worker always solves the newest target and
never works through a backlog. The worker handles one request at a time, running solves, factorisations and
file parsing on a thread so that the event loop (and the other sessions) keep going.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, TypeVar

import anyio.to_thread
import numpy as np
from starlette.websockets import WebSocket, WebSocketDisconnect

import arap
from arap.server.meshdata import MeshData, builtin_names, load_builtin, load_upload
from arap.server.protocol import (
    MAX_HANDLE_GROUPS,
    PROTOCOL_VERSION,
    ClientMessage,
    RequestError,
    check_against_mesh,
    encode_binary,
    parse_binary,
    parse_text,
)
from arap.server.session import DragOutcome, Session

__all__ = ["Connection", "StudioConfig"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


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
    """

    max_upload_bytes: int = 50 * 2**20
    max_vertices: int = 2_000_000
    max_frame_bytes: int = 65 * 2**20
    max_pending: int = 256
    max_history_steps: int = 100
    max_history_bytes: int = 512 * 2**20


class Connection:
    """Serves one WebSocket: its own :class:`~arap.server.session.Session`.

    Parameters
    ----------
    ws : WebSocket
    config : StudioConfig
    default_mesh : MeshData
        Mesh the session starts with.
    """

    def __init__(self, ws: WebSocket, config: StudioConfig, default_mesh: MeshData) -> None:
        self.ws = ws
        self.config = config
        self.default_mesh = default_mesh
        self.session = Session(config.max_history_steps, config.max_history_bytes)
        self._queue: deque[ClientMessage | RequestError] = deque()
        self._wakeup = asyncio.Event()
        self._send_lock = asyncio.Lock()
        self._skipped = 0

    # ------------------------------------------------------------------ sending
    async def _send_json(self, message: dict[str, Any]) -> None:
        async with self._send_lock:
            await self.ws.send_text(json.dumps(message, separators=(",", ":"), allow_nan=False))

    async def _send_binary(self, header: dict[str, Any], *payload: bytes) -> None:
        frame = encode_binary(header, *payload)
        async with self._send_lock:
            await self.ws.send_bytes(frame)

    async def _send_mesh(self, mesh: MeshData) -> None:
        header = {"type": "mesh", "name": mesh.name, "n_vertices": mesh.n_vertices, "n_faces": mesh.n_faces,
                  "report": mesh.report}
        await self._send_binary(header, np.ascontiguousarray(mesh.V, dtype="<f4").tobytes(),
                                np.ascontiguousarray(mesh.F, dtype="<u4").tobytes())

    async def _send_vertices(self, seq: int, outcome: DragOutcome | None) -> None:
        header: dict[str, Any] = {"type": "vertices", "seq": seq, "skipped": 0, "iterations": 0,
                                  "energies": [], "solve_ms": 0.0, "ms_per_iteration": 0.0}
        if outcome is not None:
            header.update(skipped=self._skipped, iterations=outcome.iterations,
                          energies=[e if np.isfinite(e) else None for e in outcome.energies],
                          solve_ms=round(outcome.solve_ms, 3), ms_per_iteration=round(outcome.ms_per_iteration, 3))
            self._skipped = 0
        await self._send_binary(header, self.session.vertices_f32())

    async def _send_state(self) -> None:
        await self._send_json(self.session.state())

    async def _send_error(self, exc: RequestError) -> None:
        await self._send_json(exc.to_message())

    @staticmethod
    async def _off_loop(fn: Callable[..., T], *args: Any) -> T:
        return await anyio.to_thread.run_sync(fn, *args)

    # ------------------------------------------------------------------ main loop
    async def run(self) -> None:
        """Accept the connection and serve it until the client goes away."""
        await self.ws.accept()
        try:
            await self._off_loop(self.session.load, self.default_mesh)
            await self._send_json({
                "type": "welcome",
                "version": arap.__version__,
                "protocol": PROTOCOL_VERSION,
                "builtin_meshes": builtin_names(),
                "limits": {"max_upload_bytes": self.config.max_upload_bytes,
                           "max_vertices": self.config.max_vertices,
                           "max_frame_bytes": self.config.max_frame_bytes,
                           "max_handle_groups": MAX_HANDLE_GROUPS},
                "params": asdict(self.session.params),
            })
            await self._send_mesh(self.default_mesh)
            await self._send_state()
        except (WebSocketDisconnect, RuntimeError) as exc:
            logger.debug("connection closed during the greeting: %r", exc)
            return
        worker = asyncio.create_task(self._worker())
        try:
            await self._reader()
        except (WebSocketDisconnect, RuntimeError) as exc:
            logger.debug("connection closed: %r", exc)
        finally:
            worker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await worker

    async def _reader(self) -> None:
        while True:
            message = await self.ws.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            data = message.get("bytes")
            item: ClientMessage | RequestError
            size = len(text) if text is not None else len(data or b"")
            try:
                if size > self.config.max_frame_bytes:
                    raise RequestError("too_large", f"frame of {size:,} bytes exceeds the limit of "
                                       f"{self.config.max_frame_bytes:,}")
                if text is not None:
                    item = parse_text(text)
                elif data is not None:
                    item = parse_binary(data)
                    if item.payload is not None and len(item.payload) > self.config.max_upload_bytes:
                        raise RequestError("too_large", f"upload of {len(item.payload):,} bytes exceeds the "
                                           f"limit of {self.config.max_upload_bytes:,}", item.type)
                else:
                    raise RequestError("bad_message", "empty frame")
            except RequestError as exc:
                item = exc
            await self._enqueue(item)

    async def _enqueue(self, item: ClientMessage | RequestError) -> None:
        if isinstance(item, ClientMessage) and item.type == "drag":
            last = self._queue[-1] if self._queue else None
            if isinstance(last, ClientMessage) and last.type == "drag":
                self._queue[-1] = item
                self._skipped += 1
                return
        if len(self._queue) >= self.config.max_pending:
            request = item.type if isinstance(item, ClientMessage) else item.request
            await self._send_error(RequestError("busy", f"{len(self._queue)} requests are already waiting",
                                                request))
            return
        self._queue.append(item)
        self._wakeup.set()

    async def _worker(self) -> None:
        try:
            await self._work()
        except (WebSocketDisconnect, RuntimeError) as exc:
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
                    check_against_mesh(item, self.session.n_vertices, self.session.n_groups)
                    await self._handle(item)
                except RequestError as exc:
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

        Intermediate shapes are streamed as ``vertices`` frames (seq -1) with a ``settle`` status, at most 30 per
        second; the settled (or interrupted) shape is sent last.
        """
        s = self.session
        if not s.needs_settle:
            return
        loop = asyncio.get_running_loop()
        streamed = 0

        def on_frame(U: np.ndarray, iteration: int, energy: float) -> None:
            nonlocal streamed
            streamed += 1
            frame = np.ascontiguousarray(U, dtype="<f4").tobytes()
            asyncio.run_coroutine_threadsafe(self._send_settle_frame(frame, iteration, energy), loop)

        try:
            await self._send_settle_status("settling", 0, None, 0.0)
            outcome = await self._off_loop(s.settle, lambda: bool(self._queue), on_frame)
        except RequestError as exc:
            await self._send_error(exc)
            return
        if outcome is None:
            return
        if streamed or outcome.moved > 0:  # the client has not seen this shape yet
            await self._send_vertices(-1, None)
        await self._send_settle_status("settled" if outcome.converged else "stopped", outcome.iterations,
                                       outcome.energy, outcome.seconds)

    async def _send_settle_frame(self, frame: bytes, iteration: int, energy: float) -> None:
        header = {"type": "vertices", "seq": -1, "skipped": 0, "iterations": 0, "energies": [], "solve_ms": 0.0,
                  "ms_per_iteration": 0.0}
        async with self._send_lock:
            await self.ws.send_bytes(encode_binary(header, frame))
        await self._send_settle_status("settling", iteration, energy, None)

    async def _send_settle_status(self, status: str, iterations: int, energy: float | None,
                                  seconds: float | None) -> None:
        await self._send_json({"type": "settle", "status": status, "iterations": iterations,
                               "energy": energy if energy is None or np.isfinite(energy) else None,
                               "seconds": None if seconds is None else round(seconds, 4)})

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
        elif t in ("load_builtin", "upload"):
            if t == "load_builtin":
                mesh = await self._off_loop(load_builtin, f["name"])
            else:
                assert msg.payload is not None
                mesh = await self._off_loop(load_upload, msg.payload, f["filename"], self.config.max_vertices)
            await self._off_loop(s.load, mesh)
            self._skipped = 0
            await self._send_mesh(mesh)
            await self._send_state()
        elif t == "set_constraints":
            outcome = await self._off_loop(s.set_constraints, f["roi"], f["fixed"], f["handle_groups"],
                                           f.get("targets"))
            if outcome is not None:
                await self._send_vertices(-1, outcome)
            await self._send_state()
        elif t == "set_params":
            await self._off_loop(lambda: s.set_params(**f))
            await self._send_state()
        elif t in ("undo", "redo", "reset", "apply"):
            before = s.U
            await self._off_loop(getattr(s, t))
            if s.U is not before and not np.array_equal(s.U, before):
                await self._send_vertices(-1, None)
            await self._send_state()
        elif t == "export":
            filename, mime, data = await self._off_loop(s.export, f["format"])
            await self._send_binary({"type": "export", "filename": filename, "mime": mime}, data)
        elif t == "get_constraints":
            await self._send_json({"type": "constraints", "document": s.constraints_document()})
        else:
            raise RequestError("bad_message", f"unhandled message type {t!r}")
