"""A deadline for each request's head: uvicorn's HTTP protocols with connections that never finish a request closed.

uvicorn (0.54 and earlier) times out only an idle keep-alive connection after a response; a client that connects
and sends nothing, or half a request line, or headers without their blank line, keeps its connection (and a file
descriptor, a protocol object and a parser) for ever, and the bytes it sends later restart nothing. A few hundred
such clients (slowloris) exhaust the server. The protocols here close a connection whose request line and headers
are not complete within ``timeout`` seconds of its opening, or of the first byte of a next request on a kept-alive
connection; a request whose head arrived in time is not limited (its response may take as long as it needs), nor
is a WebSocket once upgraded.
"""

from __future__ import annotations

import asyncio
import importlib.util
import logging
from typing import TYPE_CHECKING

__all__ = ["DEFAULT_HEAD_TIMEOUT", "head_timeout_protocol"]

DEFAULT_HEAD_TIMEOUT = 10.0
"""Seconds a client has to send a request's line and headers."""

logger = logging.getLogger(__name__)


def _base_protocol() -> type[asyncio.Protocol]:
    """The HTTP protocol uvicorn picks with ``http="auto"``: httptools' when installed, else h11's."""
    if importlib.util.find_spec("httptools") is not None:
        from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

        return HttpToolsProtocol
    from uvicorn.protocols.http.h11_impl import H11Protocol

    return H11Protocol


def head_timeout_protocol(timeout: float = DEFAULT_HEAD_TIMEOUT,
                          base: type[asyncio.Protocol] | None = None) -> type[asyncio.Protocol]:
    """uvicorn's HTTP protocol class (``base``, default as ``http="auto"``) with a deadline on request heads.

    Pass it as ``uvicorn.Config(app, http=head_timeout_protocol(10.0))``.

    Raises
    ------
    ValueError
        ``timeout`` is not positive.
    """
    if not timeout > 0:
        raise ValueError(f"the request head timeout must be positive, got {timeout}")
    if TYPE_CHECKING:
        # The base is chosen at run time, which mypy cannot take as a class's base; it checks the subclass against
        # h11's protocol, whose attributes used here (cycle, transport, loop, client) httptools' protocol has too.
        from uvicorn.protocols.http.h11_impl import H11Protocol as parent
    else:
        parent = base if base is not None else _base_protocol()

    class HeadTimeoutProtocol(parent):
        head_timeout = float(timeout)

        # (a stream transport, as uvicorn's own protocols take)
        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            self._head_timer: asyncio.TimerHandle | None = None
            super().connection_made(transport)
            self._arm_head_timer()

        def data_received(self, data: bytes) -> None:
            cycle = self.cycle
            super().data_received(data)
            if self.transport.is_closing() or self.transport.get_protocol() is not self:
                self._disarm_head_timer()  # closed, or upgraded to a WebSocket
            elif self.cycle is not cycle and self.cycle is not None:
                self._disarm_head_timer()  # a request's head is complete
            elif self.cycle is None or self.cycle.response_complete:
                self._arm_head_timer()  # (part of) a next request: keeps the deadline of its first byte

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm_head_timer()
            super().connection_lost(exc)

        def _arm_head_timer(self) -> None:
            if self._head_timer is None:
                self._head_timer = self.loop.call_later(self.head_timeout, self._head_timed_out)

        def _disarm_head_timer(self) -> None:
            if self._head_timer is not None:
                self._head_timer.cancel()
                self._head_timer = None

        def _head_timed_out(self) -> None:
            self._head_timer = None
            if self.transport.is_closing() or self.transport.get_protocol() is not self:
                return
            if self.cycle is not None and not self.cycle.response_complete:
                return  # a request is being answered
            client = self.client
            logger.info("closed a connection from %s: no complete request within %g s",
                        client[0] if client else "an unknown address", self.head_timeout)
            self.transport.close()

    HeadTimeoutProtocol.__name__ = HeadTimeoutProtocol.__qualname__ = f"HeadTimeout{parent.__name__}"
    return HeadTimeoutProtocol
