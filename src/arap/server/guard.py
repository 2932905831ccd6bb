"""Who may talk to the studio: the ``Host`` and ``Origin`` checks in front of every request.

A web page on another site must not drive the studio (cross-site WebSocket hijacking): a request whose
``Origin`` header is not the studio's own origin (``http://`` + the ``Host`` it was sent to) or a deliberately
allowed one is refused, ``Origin: null`` included. Requests without an ``Origin`` (command-line and Python
clients; browsers always send one with a WebSocket upgrade) are let through. A request whose ``Host`` names
neither a loopback name, the bound address nor an allowed name is refused too: that is what a page on a
domain re-pointed at 127.0.0.1 (DNS rebinding) sends.

A studio given a token (always when it serves a network, see ``arap studio --host``; always for a notebook's
:func:`arap.studio`) also refuses every request that does not present it: as ``?token=...`` in the URL (the page
passes it on to its WebSocket) or an ``Authorization: token ...`` header. Only the built client's static files
(``/assets/...``: the same code as in the package) are served without it.
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import time
from collections import deque
from collections.abc import Iterable
from contextvars import ContextVar
from urllib.parse import parse_qsl, urlsplit

from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Receive, Scope, Send

__all__ = ["LOOPBACK_NAMES", "TOKEN_PARAM", "RequestGuard", "is_loopback_host", "normalize_origin", "presented_token",
           "split_host", "token_matches"]

LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
"""Host names that always reach this machine only."""

WILDCARD_ADDRESSES = frozenset({"", "0.0.0.0", "::"})

_DEFAULT_PORTS = {"http": 80, "https": 443, "ws": 80, "wss": 443}

WRONG_TOKENS = 10
"""Wrong tokens from one address within :data:`WRONG_TOKEN_WINDOW` seconds after which its requests are refused
until the window has passed (guessing a token then takes forever)."""
WRONG_TOKEN_WINDOW = 60.0
MAX_TRACKED_ADDRESSES = 10_000
"""Addresses whose wrong tokens are remembered at most."""
TOKEN_PARAM = "token"
"""Query parameter carrying the studio's token (``http://host:port/?token=...``)."""

PUBLIC_PREFIX = "/assets/"
"""Path of the built client's static files, served without a token (a page cannot add it to its script URLs)."""


def is_loopback_host(host: str) -> bool:
    """Whether a bind address reaches this machine only (``localhost``, ``127.0.0.0/8``, ``::1``).

    Examples
    --------
    >>> is_loopback_host("127.0.0.1"), is_loopback_host("[::1]"), is_loopback_host("0.0.0.0")
    (True, True, False)
    """
    name = host.strip().strip("[]").lower().rstrip(".")
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def presented_token(scope: Scope) -> str | None:
    """The token a request presents: the first ``token`` query parameter, else an ``Authorization: token ...`` (or
    ``Bearer``) header; None when it has none."""
    query: str = scope.get("query_string", b"").decode("latin-1")
    for key, value in parse_qsl(query, keep_blank_values=True):
        if key == TOKEN_PARAM:
            return value
    for key, value in scope.get("headers", []):
        if key.lower() == b"authorization":
            header: str = value.decode("latin-1")
            scheme, _, credential = header.strip().partition(" ")
            if scheme.lower() in ("token", "bearer"):
                return credential.strip()
    return None


def token_matches(presented: str | None, expected: str) -> bool:
    """Whether a presented token is the expected one (compared in constant time)."""
    if presented is None:
        return False
    return hmac.compare_digest(presented.encode("utf-8", "surrogateescape"), expected.encode("utf-8"))


def split_host(value: str) -> tuple[str, int | None]:
    """Host name (lower case, IPv6 unbracketed) and port of a ``Host`` header value.

    Examples
    --------
    >>> split_host("LocalHost:8000")
    ('localhost', 8000)
    >>> split_host("[::1]:9000")
    ('::1', 9000)
    >>> split_host("example.org.")
    ('example.org', None)
    """
    value = value.strip().lower()
    port: int | None = None
    if value.startswith("["):
        name, _, rest = value[1:].partition("]")
        if rest.startswith(":") and rest[1:].isdigit():
            port = int(rest[1:])
    elif value.count(":") == 1:
        name, _, p = value.partition(":")
        port = int(p) if p.isdigit() else -1
    else:
        name = value
    return name.rstrip("."), port


def normalize_origin(origin: str) -> str:
    """``scheme://host:port`` with the default port spelled out and the host in lower case.

    Raises
    ------
    ValueError
        ``origin`` is not an ``http``/``https`` origin.

    Examples
    --------
    >>> normalize_origin("HTTP://Example.org")
    'http://example.org:80'
    """
    parts = urlsplit(origin.strip())
    scheme = parts.scheme.lower()
    if scheme not in ("http", "https") or not parts.hostname:
        raise ValueError(f"not an http(s) origin: {origin!r}")
    host = parts.hostname.lower().rstrip(".")
    if ":" in host:
        host = f"[{host}]"
    return f"{scheme}://{host}:{parts.port or _DEFAULT_PORTS[scheme]}"


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


logger = logging.getLogger(__name__)

_refused: ContextVar[bool] = ContextVar("arap_refused_handshake", default=False)
"""Set in the task that answered a WebSocket handshake with a 403 (see :class:`_RefusalLogFilter`)."""


class _RefusalLogFilter(logging.Filter):
    """Drops uvicorn's "ASGI callable returned without completing handshake." after a deliberate 403.

    uvicorn's WebSocket protocol (websockets' sans-I/O implementation) sends the 403 response the guard gives but
    never counts the handshake as done, so every refused origin or host was logged at ERROR level without context.
    The guard logs its own line (INFO, with the reason); the same message in any other case still gets through.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        return not (_refused.get() and record.getMessage().startswith("ASGI callable returned without completing"))


def _install_refusal_filter() -> None:
    uvicorn_log = logging.getLogger("uvicorn.error")
    if not any(isinstance(f, _RefusalLogFilter) for f in uvicorn_log.filters):
        uvicorn_log.addFilter(_RefusalLogFilter())


class RequestGuard:
    """ASGI middleware refusing requests with a foreign ``Host`` or ``Origin`` (403; before any WebSocket accept).

    Parameters
    ----------
    app : ASGI application
    bind_host : str or None
        Address the server is bound to. A wildcard (``0.0.0.0``, ``::``) accepts any IP address as host (an IP
        address cannot be re-pointed); None or a loopback address accepts loopback names only.
    allowed_hosts : iterable of str
        More host names to accept (e.g. the machine's name when it serves a network).
    allow_origins : iterable of str
        Origins allowed besides the studio's own (``http(s)://host[:port]``); their host names are accepted as
        hosts too (a reverse proxy in front of the studio).
    token : str or None
        Secret every request must present (see :func:`presented_token`), but for the client's static files
        (``/assets/...``); None: no token.

    Raises
    ------
    ValueError
        An entry of ``allow_origins`` is not an http(s) origin.
    """

    def __init__(self, app: ASGIApp, *, bind_host: str | None = None, allowed_hosts: Iterable[str] = (),
                 allow_origins: Iterable[str] = (), token: str | None = None) -> None:
        self.app = app
        if token is not None and not token:
            raise ValueError("the token must not be empty")
        self.token = token
        self._failures: dict[str, deque[float]] = {}
        self.origins = frozenset(normalize_origin(o) for o in allow_origins)
        _install_refusal_filter()
        names = set(LOOPBACK_NAMES) | {split_host(h)[0] for h in allowed_hosts}
        names |= {urlsplit(o).hostname or "" for o in self.origins} - {""}
        self.any_ip = False
        if bind_host is not None:
            bound = bind_host.strip("[]").lower()
            if bound in WILDCARD_ADDRESSES:
                self.any_ip = True
            else:
                names.add(bound)
        self.hosts = frozenset(names)

    def host_allowed(self, host: str | None) -> bool:
        """Whether a ``Host`` header value names this server."""
        if not host:
            return False
        name, port = split_host(host)
        if port == -1:
            return False
        return name in self.hosts or (self.any_ip and _is_ip(name))

    def origin_allowed(self, origin: str | None, host: str, scheme: str) -> bool:
        """Whether an ``Origin`` header value is the studio's own origin or an allowed one (absent: allowed)."""
        if origin is None:
            return True
        try:
            got = normalize_origin(origin)
        except ValueError:
            return False  # "null" (sandboxed pages, file: URLs) and anything that is not an http(s) origin
        if got in self.origins:
            return True
        own_scheme = "https" if scheme in ("https", "wss") else "http"
        try:
            own = normalize_origin(f"{own_scheme}://{host}")
        except ValueError:
            return False
        return got == own

    def refusal(self, scope: Scope) -> str | None:
        """Why a request is refused, or None when it may go on."""
        headers: dict[str, str] = {}
        for key, value in scope.get("headers", []):
            name = key.decode("latin-1").lower()
            if name in ("host", "origin"):
                if name in headers:
                    return f"more than one {name} header"
                headers[name] = value.decode("latin-1")
        host = headers.get("host")
        if not self.host_allowed(host):
            return f"host {(host or '')[:100]!r} is not this server (start the studio with --host to serve a network)"
        assert host is not None
        if not self.origin_allowed(headers.get("origin"), host, scope.get("scheme", "http")):
            return (f"origin {headers['origin'][:100]!r} may not use the studio (start it with --allow-origin to "
                    "allow it)")
        if self.token is None or self._public(scope):
            return None
        token = presented_token(scope)
        if token is None:
            return "this studio needs its token: open the URL it printed when it started (with its ?token=...)"
        client = scope.get("client")
        address = str(client[0]) if client else ""
        if self._locked_out(address):
            return (f"too many wrong tokens from this address: wait {WRONG_TOKEN_WINDOW:.0f} seconds, then open the "
                    "URL the studio printed when it started")
        if not token_matches(token, self.token):
            self._wrong_token(address)
            return "wrong token: open the URL the studio printed when it started"
        return None

    def _locked_out(self, address: str) -> bool:
        """Whether ``address`` presented :data:`WRONG_TOKENS` wrong tokens within the last window."""
        times = self._failures.get(address)
        if not times:
            return False
        now = time.monotonic()
        while times and now - times[0] > WRONG_TOKEN_WINDOW:
            times.popleft()
        if not times:
            del self._failures[address]
        return len(times) >= WRONG_TOKENS

    def _wrong_token(self, address: str) -> None:
        if len(self._failures) >= MAX_TRACKED_ADDRESSES and address not in self._failures:
            self._failures.clear()  # a flood of addresses: start afresh rather than grow without bound
        self._failures.setdefault(address, deque()).append(time.monotonic())

    @staticmethod
    def _public(scope: Scope) -> bool:
        """A GET or HEAD of the built client's static files (no token needed)."""
        path = scope.get("path", "")
        return (scope["type"] == "http" and scope.get("method") in ("GET", "HEAD") and path.startswith(PUBLIC_PREFIX)
                and ".." not in path and "\\" not in path)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        reason = self.refusal(scope)
        if reason is None:
            await self.app(scope, receive, send)
            return
        if scope["type"] == "http":
            await PlainTextResponse(f"forbidden: {reason}", status_code=403)(scope, receive, send)
            return
        await receive()  # websocket.connect
        client = scope.get("client")
        logger.info("refused a WebSocket connection from %s: %s", client[0] if client else "an unknown address", reason)
        _refused.set(True)
        if "websocket.http.response" in scope.get("extensions", {}):
            body = f"forbidden: {reason}".encode()
            await send({"type": "websocket.http.response.start", "status": 403,
                        "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                                    (b"content-length", str(len(body)).encode())]})
            await send({"type": "websocket.http.response.body", "body": body})
        else:
            await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
