"""The studio's web application: the built browser client, the WebSocket endpoint and a health check."""

from __future__ import annotations

import asyncio
import contextlib
import gc
import html
import logging
import os
import time
import weakref
from collections.abc import AsyncIterator, Callable, Iterable
from pathlib import Path

import anyio.to_thread
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketDisconnect

from arap import __version__
from arap.errors import ArapError
from arap.server.appearance import Look, look_from_path
from arap.server.client_files import STATIC_DIR, client_dir, client_missing_advice
from arap.server.connection import Connection
from arap.server.decoder import FrameDecoder
from arap.server.errors import RequestError
from arap.server.guard import RequestGuard, normalize_origin, presented_token, token_matches
from arap.server.memory import release_memory
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_default
from arap.server.pictures import is_picture, load_picture
from arap.server.protocol import error_message
from arap.server.session import Session
from arap.server.studio_config import StudioConfig

__all__ = ["DEFAULT_MAX_EXPORT_BYTES", "DEFAULT_MAX_SESSIONS", "DEFAULT_MAX_UPLOAD_BYTES", "DEFAULT_MAX_VERTICES",
           "STATIC_DIR", "client_missing_advice", "create_app", "frame_limit"]

logger = logging.getLogger(__name__)

DEFAULT_MAX_UPLOAD_BYTES = 50 * 2**20
DEFAULT_MAX_VERTICES = 2_000_000
DEFAULT_MAX_SESSIONS = 32
DEFAULT_MAX_EXPORT_BYTES = 2**31
"""Estimated memory the animation exports of all sessions may take at once (one 600-frame export of a 43k-vertex
scan is estimated at 1.2 GB: its solved frames, and the GLB's positions and normals)."""

RELEASE_WAIT_SECONDS = 5.0
"""How long a finished session's memory is waited for (a settling iteration in progress) before trimming."""

SESSION_LIMIT_CLOSE_CODE = 1013
"""WebSocket close code ("try again later") of a connection refused because the server is full."""

_NOT_BUILT = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>ARAP Studio: client not built</title></head>
<body style="font-family: sans-serif; max-width: 40em; margin: 4em auto">
<h1>ARAP Studio: the browser client is not built</h1>
<p>{advice}</p>
</body></html>
"""


def frame_limit(max_upload_bytes: int) -> int:
    """Largest WebSocket frame accepted for a given upload cap (room for the header and large selections)."""
    return max(max_upload_bytes, 64 * 2**20) + 2**20


class _Studio:
    """Shared state of the application: configuration, default mesh, live sessions."""

    def __init__(self, config: StudioConfig, default_mesh: MeshData, static_dir: Path, max_sessions: int,
                 token: str | None = None, default_look: Look | None = None) -> None:
        self.config = config
        self.default_mesh = default_mesh
        self.default_look = default_look
        """The default mesh file's colours and texture (None: drawn plain)."""
        self.static_dir = static_dir
        self.max_sessions = max_sessions
        self.sessions = 0
        self.connections: weakref.WeakSet[Connection] = weakref.WeakSet()
        self.decoder = FrameDecoder()
        self.token = token
        """Secret every client must present (None: none); see :mod:`arap.server.guard`."""
        self.keep_latest = False
        """Keep the most recently opened session of the token's holders, even after it closed (for a notebook; see
        :meth:`latest_session`)."""
        self._latest: Session | None = None
        self.prepare_session: Callable[[Session], object] | None = None
        """Called with each new session once it holds the default mesh (initial constraints, for a notebook)."""

    def opened(self, session: Session, token: str | None) -> None:
        """Note a new session and the token its client presented."""
        if self.keep_latest and self.token is not None and token_matches(token, self.token):
            self._latest = session

    def latest_kept(self) -> Session | None:
        """The session kept for a notebook (see :attr:`keep_latest`), if any."""
        return self._latest

    def latest_session(self, token: str) -> Session | None:
        """The most recently opened session whose client presented ``token``: None before one, or when ``token`` is
        not this server's (a server without a token keeps none)."""
        if self.token is None or not token_matches(token, self.token):
            return None
        return self._latest


class _ClientFiles:
    """Static files of the built client; 404 for everything while the client is not built."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self._files: StaticFiles | None = None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if not self.directory.is_dir():
            response: Response = PlainTextResponse("not found (the studio client is not built)", status_code=404)
            await response(scope, receive, send)
            return
        if self._files is None:
            self._files = StaticFiles(directory=self.directory, html=True)
        await self._files(scope, receive, send)


def _default_mesh(spec: str | os.PathLike[str] | MeshData | None, max_vertices: int) -> tuple[MeshData, Look | None]:
    """The mesh every session starts with and its look: a picture file (PNG, JPEG, WebP) opened as the page opens
    one (:func:`arap.server.pictures.load_picture`), anything else as :func:`arap.server.meshdata.load_default` and
    :func:`arap.server.appearance.look_from_path` read it.

    Raises
    ------
    arap.errors.ArapError
        The file cannot be read, is not a usable mesh, or is a picture without an opaque part or with too many
        vertices once meshed.
    """
    if isinstance(spec, (str, os.PathLike)) and is_picture(os.fspath(spec)) and Path(spec).is_file():
        path = Path(spec)
        try:
            return load_picture(path.read_bytes(), path.name, max_vertices)
        except OSError as exc:
            raise ArapError(f"{path}: cannot be read: {exc.strerror or exc}") from exc
        except RequestError as exc:
            raise ArapError(f"{path}: {exc.message.removeprefix(f'{path.name}: ')}") from exc
    mesh = load_default(spec)
    return mesh, look_from_path(spec, mesh)


def create_app(
    default_mesh: str | os.PathLike[str] | MeshData | None = None,
    *,
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
    max_vertices: int = DEFAULT_MAX_VERTICES,
    max_history_steps: int = 100,
    max_history_bytes: int = 512 * 2**20,
    max_pending: int = 256,
    max_sessions: int = DEFAULT_MAX_SESSIONS,
    max_queued_bytes: int = 64 * 2**20,
    max_unsent_bytes: int = 64 * 2**20,
    max_export_bytes: int = DEFAULT_MAX_EXPORT_BYTES,
    subset_frames: bool = True,
    allow_origins: Iterable[str] = (),
    bind_host: str | None = None,
    allowed_hosts: Iterable[str] = (),
    static_dir: str | os.PathLike[str] | None = None,
    token: str | None = None,
) -> Starlette:
    """Build the studio application.

    Parameters
    ----------
    default_mesh : str, path-like, MeshData or None
        Mesh every new session starts with: a built-in model name (``arap.BUILTIN_MESHES``), a mesh file chosen
        by whoever runs the server, a picture file (PNG, JPEG, WebP: opened as the page opens one, for the puppet
        warp), arrays wrapped in a :class:`~arap.server.mesh_model.MeshData`, or None for the first built-in model.
        Loaded once, here.
    max_upload_bytes : int
        Largest mesh file a client may upload.
    max_vertices : int
        Largest uploaded mesh, in vertices.
    max_history_steps, max_history_bytes : int
        Undo history limits per session.
    max_pending : int
        Requests that may wait in one session's queue before more are answered ``busy``.
    max_sessions : int
        Most sessions at once; one more is accepted, sent a ``busy`` error and closed with code 1013 and a reason.
    max_queued_bytes, max_unsent_bytes : int
        Byte budgets of one session (requests waiting, answers not yet sent): past them its frames are not read
        until the worker catches up (see :class:`arap.server.studio_config.StudioConfig`).
    max_export_bytes : int
        Estimated memory the animation exports of all sessions may take at once: a larger export is refused, one
        that does not fit beside those running waits (see :func:`arap.server.animation_export.export_bytes`).
    subset_frames : bool
        While a constraint set with a region of interest is dragged, send only the movable vertices' positions
        (see :mod:`arap.server.liveframes`); False sends every frame in full.
    allow_origins : iterable of str
        Web origins (``http(s)://host[:port]``) allowed to use the studio besides its own pages. Requests from
        any other origin, ``null`` included, are refused with 403 (see :mod:`arap.server.guard`).
    bind_host : str or None
        Address the server is bound to; requests must name it, a loopback name or an allowed host in ``Host``
        (a wildcard address accepts any IP address). None: loopback names only.
    allowed_hosts : iterable of str
        More host names accepted in ``Host``.
    static_dir : path-like or None
        Built client (default: the package's ``static`` folder, or the folder ``ARAP_STUDIO_CLIENT`` names).
    token : str or None
        Secret every request must present, as ``?token=...`` in its URL or an ``Authorization: token ...``
        header (the client's static files excepted); 403 without it. None: no token (loopback servers).

    Returns
    -------
    starlette.applications.Starlette
        Routes: ``/`` (the client, or a 503 page when it is not built), ``/ws`` (the WebSocket protocol of
        ``docs/protocol.md``), ``/healthz`` and the client's static files.

    Raises
    ------
    arap.errors.ArapError
        The default mesh cannot be loaded (or a picture has no opaque part, or too many vertices once meshed).
    ValueError
        A limit is not positive, an allowed origin is not an http(s) origin, or the token is empty.
    """
    for name, value in (("max_upload_bytes", max_upload_bytes), ("max_vertices", max_vertices),
                        ("max_history_steps", max_history_steps), ("max_pending", max_pending),
                        ("max_sessions", max_sessions), ("max_queued_bytes", max_queued_bytes),
                        ("max_unsent_bytes", max_unsent_bytes), ("max_export_bytes", max_export_bytes)):
        if int(value) < 1:
            raise ValueError(f"{name} must be positive, got {value}")
    config = StudioConfig(
        max_upload_bytes=int(max_upload_bytes),
        max_vertices=int(max_vertices),
        max_frame_bytes=frame_limit(int(max_upload_bytes)),
        max_pending=int(max_pending),
        max_history_steps=int(max_history_steps),
        max_history_bytes=int(max_history_bytes),
        max_queued_bytes=int(max_queued_bytes),
        max_unsent_bytes=int(max_unsent_bytes),
        max_export_bytes=int(max_export_bytes),
        subset_frames=bool(subset_frames),
    )
    origins = tuple(allow_origins)
    for origin in origins:
        normalize_origin(origin)  # a mistyped origin fails here, not on the first request
    if token is not None and not token:
        raise ValueError("the token must not be empty")
    guard = Middleware(RequestGuard, bind_host=bind_host, allowed_hosts=tuple(allowed_hosts), allow_origins=origins,
                       token=token)
    mesh, look = _default_mesh(default_mesh, int(max_vertices))
    logger.info("default mesh %s: %d vertices, %d faces", mesh.name, mesh.n_vertices, mesh.n_faces)
    static = Path(static_dir) if static_dir is not None else client_dir()
    advice = client_missing_advice(static)
    if advice is not None:
        logger.warning("%s The server answers its pages with 503 until then.", advice)
    studio = _Studio(config, mesh, static, int(max_sessions), token, look)

    async def index(request: Request) -> Response:
        page = static / "index.html"
        advice = client_missing_advice(static)
        if advice is not None:
            return HTMLResponse(_NOT_BUILT.format(advice=html.escape(advice)), status_code=503)
        return FileResponse(page, headers={"Cache-Control": "no-cache"})

    async def healthz(request: Request) -> Response:
        return JSONResponse({"status": "ok", "version": __version__, "sessions": studio.sessions,
                             "client_built": (static / "index.html").is_file()})

    async def websocket(ws: WebSocket) -> None:
        if studio.sessions >= studio.max_sessions:
            await _refuse_full(ws, studio.max_sessions)
            return
        studio.sessions += 1
        try:
            connection = Connection(ws, studio.config, studio.default_mesh, studio.decoder, studio.prepare_session,
                                    studio.default_look)
            studio.connections.add(connection)
            studio.opened(connection.session, presented_token(ws.scope))
            await connection.run()
        finally:
            studio.sessions -= 1
        # The session's arrays are garbage once a settling run's thread has let go of them (it stops at its next
        # iteration); then hand the freed heap back to the system, off the event loop.
        session = weakref.ref(connection.session)
        del connection
        await _until_freed(session, studio, RELEASE_WAIT_SECONDS)
        await anyio.to_thread.run_sync(release_memory)

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        try:
            yield
        finally:
            await anyio.to_thread.run_sync(studio.decoder.close)

    app = Starlette(lifespan=lifespan, routes=[
        Route("/", index),
        Route("/healthz", healthz),
        WebSocketRoute("/ws", websocket),
        Mount("/", app=_ClientFiles(static)),
    ], middleware=[guard])
    app.state.studio = studio
    return app


async def _until_freed(ref: weakref.ref[Session], studio: _Studio, seconds: float) -> None:
    """Wait until the session ``ref`` refers to is freed (at most ``seconds``; not at all for the session a
    notebook keeps)."""
    start = time.monotonic()
    collected = False
    while time.monotonic() < start + seconds:
        session = ref()
        if session is None or session is studio.latest_kept():
            return
        del session
        if not collected and time.monotonic() > start + 0.2:
            gc.collect()  # the session may be held only by reference cycles (an exception's frames)
            collected = True
        await asyncio.sleep(0.05)


async def _refuse_full(ws: WebSocket, limit: int) -> None:
    """Tell a client the server is full (an ``error`` it can show, then a close with the reason)."""
    reason = f"the studio already serves {limit} session{'' if limit == 1 else 's'}; close one and reconnect"
    await ws.accept()
    try:
        await ws.send_json(error_message(RequestError("busy", reason)))
        await ws.close(SESSION_LIMIT_CLOSE_CODE, reason)
    except (WebSocketDisconnect, RuntimeError, OSError) as exc:
        logger.debug("refused client left first: %r", exc)
