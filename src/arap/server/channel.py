"""A studio session served over a synchronous channel (a notebook widget's comm, :mod:`arap.jupyter_widget`): requests
queue and are answered in order by a thread of the session's own, as :mod:`arap.server.connection` answers a
WebSocket's (with :class:`arap.server.dispatch.Dispatcher`): drags coalesce, and the shape settles while no request
waits, stopping as soon as one arrives.

Several views of one widget share its session. Each request is tagged with the view that sent it: what answers only
that request (the greeting of a view opening, an export, a constraints document, an animation, the distortion, an
error) goes to that view, what changes the shared session (a mesh, the state, positions, settling) to every view."""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from arap.server.client_messages import Drag, ExportAnimation
from arap.server.dispatch import Dispatcher
from arap.server.errors import RequestError
from arap.server.frames import decode_binary
from arap.server.messages import ClientMessage
from arap.server.replies import Reply, _Settle

__all__ = ["ChannelWorker"]

logger = logging.getLogger(__name__)


SHARED_REPLIES = frozenset({"mesh", "appearance", "state", "vertices", "settle"})
"""Types of the replies that show the shared session, sent to every view; the others answer their request's view."""


@dataclass(frozen=True)
class _Task:
    fn: Callable[[], Iterator[Reply]]
    view: str | None = None


@dataclass(frozen=True)
class _Request:
    item: ClientMessage | RequestError
    view: str | None = None


def reply_type(reply: Reply) -> str:
    """The message type of a reply (a text message, an encoded binary frame, or a header with its payload)."""
    if isinstance(reply, dict):
        return str(reply["type"])
    if isinstance(reply, bytes):
        return str(decode_binary(reply)[0]["type"])
    return str(reply[0]["type"])


class ChannelWorker:
    """Serves one session over a synchronous channel: requests are put in a queue and answered in order by a
    thread of its own, which settles the shape while none waits and stops settling when one arrives.

    Parameters
    ----------
    dispatcher : Dispatcher
    send : callable
        ``send(reply, view)``, called on the worker's thread; ``view`` is the view the reply is for, or None for
        every view. Its exceptions are logged, not raised.
    """

    def __init__(self, dispatcher: Dispatcher, send: Callable[[Reply, str | None], object],
                 on_idle: Callable[[], object] | None = None) -> None:
        self.dispatcher = dispatcher
        self._send = send
        self._on_idle = on_idle
        self._queue: collections.deque[_Request | _Task] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False
        self._busy = False
        self._thread = threading.Thread(target=self._run, name="arap-widget-worker", daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def call(self, task: Callable[[], Iterator[Reply]], view: str | None = None) -> None:
        """Queue ``task``: run on the worker's thread in turn with the requests, it yields the replies to send, all
        to ``view`` (None: every view), e.g. :meth:`Dispatcher.rejoin` for a view opening."""
        with self._cond:
            if not self._closed:
                self._queue.append(_Task(task, view))
                self._cond.notify()

    def put(self, item: ClientMessage | RequestError, view: str | None = None) -> None:
        """Queue a request of ``view`` (a drag replaces a drag waiting at the end of the queue) or an error to
        answer."""
        with self._cond:
            if self._closed:
                return
            if isinstance(item, Drag) and self._queue:
                last = self._queue[-1]
                if isinstance(last, _Request) and isinstance(last.item, Drag):
                    self._queue[-1] = _Request(item, view)
                    self.dispatcher.count_skipped()
                    return
            if len(self._queue) >= self.dispatcher.config.max_pending:
                request = item.type if isinstance(item, ClientMessage) else item.request
                self._emit(self.dispatcher.error(RequestError(
                    "busy", f"{len(self._queue)} requests are already waiting", request)), view)
                return
            self._queue.append(_Request(item, view))
            self._cond.notify()

    def idle(self, timeout: float = 10.0) -> bool:
        """Wait until the queue is empty and nothing is being answered or settled; False on timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._queue or self._busy:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
        return True

    def close(self, timeout: float = 10.0) -> None:
        """Stop the thread (a settling run stops at its next iteration); idempotent."""
        with self._cond:
            self._closed = True
            self._queue.clear()
            self._cond.notify_all()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _emit(self, reply: Reply, view: str | None = None, *, only: bool = False) -> None:
        """Send ``reply`` to ``view``, or to every view when it shows the shared session (unless ``only``) or no view
        asked."""
        try:
            shared = view is None or (not only and reply_type(reply) in SHARED_REPLIES)
            self._send(reply, None if shared else view)
        except Exception:
            logger.exception("could not send a reply")

    def _interrupted(self) -> bool:
        return bool(self._queue) or self._closed

    def _run(self) -> None:
        while True:
            with self._cond:
                self._busy = False
                self._cond.notify_all()
                while not self._queue and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                queued = self._queue.popleft()
                self._busy = True
            if isinstance(queued, _Task):
                self._answer(None, queued, queued.view)
            else:
                item, view = queued.item, queued.view
                if isinstance(item, RequestError):
                    self._emit(self.dispatcher.error(item), view)
                elif isinstance(item, ExportAnimation):
                    self._answer(item, self._export_animation(item, view), view)
                else:
                    self._answer(item, self.dispatcher.handle(item), view)
            if not self._queue:
                self._settle()
            if not self._queue and self._on_idle is not None:
                try:
                    self._on_idle()
                except Exception:
                    logger.exception("unexpected error after answering")

    def _export_animation(self, item: ExportAnimation, view: str | None) -> Iterator[Reply]:
        yield self.dispatcher.export_animation(item, self._interrupted, lambda reply: self._emit(reply, view))

    def _settle(self) -> None:
        try:
            self.dispatcher.settle(self._interrupted, self._emit)
        except Exception:
            logger.exception("unexpected error while settling")

    def _answer(self, item: ClientMessage | None, replies: Iterator[Reply | _Settle] | _Task,
                view: str | None) -> None:
        """Send the replies to ``item`` (None: a task's, every one to ``view``)."""
        name = item.type if item is not None else None
        only = isinstance(replies, _Task)
        try:
            for reply in replies.fn() if isinstance(replies, _Task) else replies:
                if isinstance(reply, _Settle):
                    self._settle()
                else:
                    self._emit(reply, view, only=only)
        except RequestError as exc:
            exc.__traceback__ = None
            exc.request = exc.request or name
            self._emit(self.dispatcher.error(exc), view)
        except Exception:
            logger.exception("unexpected error while handling %s", name)
            self._emit(self.dispatcher.error(RequestError(
                "internal", f"unexpected server error in {name}; see the server log", name)), view)
