"""Running the studio: bind a socket, report the URL, serve with uvicorn until interrupted."""

from __future__ import annotations

import asyncio
import logging
import os
import secrets
import socket
import struct
import threading
import webbrowser
from collections.abc import Callable, Iterable
from typing import Any
from urllib.parse import quote

import uvicorn

from arap.server.app import (
    DEFAULT_MAX_EXPORT_BYTES,
    DEFAULT_MAX_SESSIONS,
    DEFAULT_MAX_UPLOAD_BYTES,
    DEFAULT_MAX_VERTICES,
    create_app,
    frame_limit,
)
from arap.server.connection import SEND_QUEUE_EXTENSION
from arap.server.guard import TOKEN_PARAM, is_loopback_host
from arap.server.headtimeout import DEFAULT_HEAD_TIMEOUT, head_timeout_protocol
from arap.server.mesh_model import MeshData

__all__ = ["bind_socket", "kernel_unsent_bytes", "make_server", "new_token", "serve", "studio_url",
           "websocket_protocol"]

logger = logging.getLogger(__name__)

try:
    import fcntl
    import termios

    _OUTQ: int | None = termios.TIOCOUTQ  # Linux: SIOCOUTQ, bytes the peer has not acknowledged
except (ImportError, AttributeError):  # no such query here: the transport's own buffer is all that is measured
    _OUTQ = None


def kernel_unsent_bytes(sock: Any) -> int:
    """Bytes of a TCP socket's send queue that its peer has not acknowledged (0 where the system cannot tell).

    Parameters
    ----------
    sock : socket-like
        Anything with ``fileno()`` (an asyncio transport's ``get_extra_info("socket")``).
    """
    if _OUTQ is None or sock is None:
        return 0
    try:
        return int(struct.unpack("i", fcntl.ioctl(sock.fileno(), _OUTQ, b"\0\0\0\0"))[0])
    except (OSError, ValueError):  # closed meanwhile
        return 0


def websocket_protocol() -> type[asyncio.Protocol]:
    """uvicorn's WebSocket protocol (``websockets``' sans-I/O one, what ``ws="auto"`` picks) telling the studio how
    much its client has not taken yet: the scope's :data:`~arap.server.connection.SEND_QUEUE_EXTENSION` holds
    ``{"bytes": callable}``, the bytes in the transport's buffer plus those of the socket's send queue not yet
    acknowledged (:func:`kernel_unsent_bytes`). A connection sends its next ``vertices`` frame only once the client
    took the last one, so frames never pile up in the socket in front of the keepalive pings."""
    from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

    class SendQueueProtocol(WebSocketsSansIOProtocol):
        def handle_connect(self, event: Any) -> None:
            super().handle_connect(event)
            scope = getattr(self, "scope", None)
            if scope is not None:
                scope.setdefault("extensions", {})[SEND_QUEUE_EXTENSION] = {"bytes": self.unsent_bytes}

        def unsent_bytes(self) -> int:
            transport = self.transport
            if transport is None or transport.is_closing():
                return 0
            return transport.get_write_buffer_size() + kernel_unsent_bytes(transport.get_extra_info("socket"))

    return SendQueueProtocol


def studio_url(host: str = "127.0.0.1", port: int = 8000, token: str | None = None) -> str:
    """URL a browser on this machine opens for a server bound to ``host:port`` (with ``?token=`` when it has one).

    A wildcard address (``0.0.0.0``, ``::``) is shown as the loopback address; IPv6 addresses are bracketed.

    Examples
    --------
    >>> studio_url("127.0.0.1", 8000)
    'http://127.0.0.1:8000/'
    >>> studio_url("::", 9000)
    'http://[::1]:9000/'
    >>> studio_url("0.0.0.0", 8000, token="s3cret")
    'http://127.0.0.1:8000/?token=s3cret'
    """
    h = host.strip("[]")
    if h in ("", "0.0.0.0"):
        h = "127.0.0.1"
    elif h == "::":
        h = "::1"
    if ":" in h:
        h = f"[{h}]"
    url = f"http://{h}:{int(port)}/"
    return url if token is None else f"{url}?{TOKEN_PARAM}={quote(token, safe='')}"


def new_token() -> str:
    """A fresh random token (256 bits, URL-safe)."""
    return secrets.token_urlsafe(32)


def bind_socket(host: str = "127.0.0.1", port: int = 8000) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0 picks a free one).

    Raises
    ------
    OSError
        The address is in use or cannot be bound.
    """
    infos = socket.getaddrinfo(host.strip("[]") or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)
    except OSError:
        sock.close()
        raise
    sock.set_inheritable(True)
    return sock


def make_server(
    mesh: str | os.PathLike[str] | MeshData | None = None,
    host: str = "127.0.0.1",
    port: int = 8000,
    *,
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
    max_vertices: int = DEFAULT_MAX_VERTICES,
    max_sessions: int = DEFAULT_MAX_SESSIONS,
    allow_origins: Iterable[str] = (),
    log_level: str = "warning",
    token: str | None = None,
    head_timeout: float = DEFAULT_HEAD_TIMEOUT,
    max_export_bytes: int = DEFAULT_MAX_EXPORT_BYTES,
) -> tuple[uvicorn.Server, socket.socket, str]:
    """Build the studio's uvicorn server and bind its socket, without serving yet.

    Run it with ``server.run(sockets=[sock])``; set ``server.should_exit = True`` to stop it. Parameters are
    those of :func:`serve`.

    Returns
    -------
    server : uvicorn.Server
    sock : socket.socket
        The bound, listening socket.
    url : str
        The studio's URL (with the actual port when ``port`` is 0, and the token when there is one).
    """
    if token is None and not is_loopback_host(host):
        token = new_token()
    app = create_app(mesh, max_upload_bytes=max_upload_bytes, max_vertices=max_vertices, max_sessions=max_sessions,
                     allow_origins=allow_origins, bind_host=host, token=token, max_export_bytes=max_export_bytes)
    config = uvicorn.Config(
        app,
        http=head_timeout_protocol(head_timeout),
        ws=websocket_protocol(),
        log_level=log_level,
        ws_per_message_deflate=False,
        ws_max_size=frame_limit(max_upload_bytes),
        lifespan="on",
    )
    sock = bind_socket(host, port)
    return uvicorn.Server(config), sock, studio_url(host, sock.getsockname()[1], token)


def serve(
    mesh: str | os.PathLike[str] | None = None,
    host: str = "127.0.0.1",
    port: int = 8000,
    open_browser: bool = False,
    *,
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
    max_vertices: int = DEFAULT_MAX_VERTICES,
    max_sessions: int = DEFAULT_MAX_SESSIONS,
    allow_origins: Iterable[str] = (),
    log_level: str = "warning",
    on_ready: Callable[[str], None] | None = None,
    token: str | None = None,
    head_timeout: float = DEFAULT_HEAD_TIMEOUT,
    max_export_bytes: int = DEFAULT_MAX_EXPORT_BYTES,
) -> None:
    """Run the studio until interrupted (Ctrl-C).

    The mesh is loaded and the socket bound before serving starts, so a bad mesh or a busy port raises here.

    Parameters
    ----------
    mesh : str, path-like or None
        Default mesh of new sessions (see :func:`arap.server.create_app`).
    host : str
        Address to bind; the default only accepts connections from this machine. Any other address (a network
        interface, ``0.0.0.0``) gets a token when none is given.
    port : int
        TCP port; 0 picks a free one (the URL passed to ``on_ready`` has it).
    open_browser : bool
        Open the studio in the default web browser once the server listens.
    max_upload_bytes, max_vertices : int
        Upload limits.
    max_sessions : int
        Most sessions (browser tabs) at once; more are refused with a reason.
    allow_origins : iterable of str
        Web origins (``http(s)://host[:port]``) allowed to use the studio besides its own pages; requests from any
        other origin, and requests whose ``Host`` is not this server, are refused (see :mod:`arap.server.guard`).
    log_level : str
        uvicorn's log level.
    on_ready : callable or None
        Called with the studio's URL once the socket is bound, before serving (e.g. to print it); it carries the
        token (``?token=...``) when there is one.
    token : str or None
        Secret every request must present (see :mod:`arap.server.guard`). None: a random one when ``host`` is not
        a loopback address, none on loopback.
    head_timeout : float
        Seconds a client has to send a request's line and headers before its connection is closed
        (see :mod:`arap.server.headtimeout`).
    max_export_bytes : int
        Estimated memory the animation exports of all sessions may take at once (see
        :func:`arap.server.create_app`).

    Raises
    ------
    arap.errors.ArapError
        The mesh cannot be loaded.
    OSError
        The address cannot be bound.

    Examples
    --------
    The mesh is read before the server starts, so a mistake shows at once:

    >>> from arap.server.runner import serve
    >>> try:
    ...     serve("no-such-mesh.obj")
    ... except Exception as error:
    ...     print(type(error).__name__)
    MeshFormatError
    """
    server, sock, url = make_server(mesh, host, port, max_upload_bytes=max_upload_bytes,
                                    max_vertices=max_vertices, max_sessions=max_sessions,
                                    allow_origins=allow_origins, log_level=log_level, token=token,
                                    head_timeout=head_timeout, max_export_bytes=max_export_bytes)
    logger.info("ARAP Studio listening on %s", url.split("?")[0])
    if on_ready is not None:
        on_ready(url)
    if open_browser:
        threading.Timer(0.5, webbrowser.open, args=(url,)).start()
    try:
        server.run(sockets=[sock])
    finally:
        sock.close()
