"""Decoding of large text frames in a separate process.

JSON decoding builds one Python object per number while holding the interpreter lock: a thread decoding a 50 MB
constraint set (millions of indices) would take the lock from the event loop, and from every other session, for
seconds. Text frames of :data:`PROCESS_BYTES` or more are therefore decoded and validated in one worker process
shared by all sessions, and their index and point lists come back as NumPy arrays, which cross the process
boundary as flat buffers and need no per-number work in the server. Smaller frames are decoded on the event loop
or a thread (see :mod:`arap.server.connection`).

If the worker process cannot be started or dies, the frame is decoded on a thread instead: slower for the other
sessions, never lost.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

import anyio.to_thread
import numpy as np

from arap.server.protocol import ClientMessage, parse_text

__all__ = ["PROCESS_BYTES", "FrameDecoder", "arrays_from_lists", "decode_text_frame"]

logger = logging.getLogger(__name__)

PROCESS_BYTES = 2 * 2**20
"""Text frames at least this large are decoded in the worker process."""


def _int_array(values: list[int]) -> np.ndarray | list[int]:
    try:
        return np.array(values, dtype=np.int64)
    except OverflowError:
        return values  # an index beyond int64 stays a list: checking it against the mesh reports it out of range


def arrays_from_lists(msg: ClientMessage) -> ClientMessage:
    """Replace a validated ``set_constraints``'s index and point lists by arrays; other messages unchanged.

    Parameters
    ----------
    msg : ClientMessage
        A message returned by :func:`arap.server.protocol.parse_text`.

    Returns
    -------
    ClientMessage
        ``roi``, ``fixed`` and each handle group as (k,) int64 arrays, ``targets`` as a (t, 3) float64 array.
    """
    if msg.type != "set_constraints":
        return msg
    fields: dict[str, Any] = dict(msg.fields)
    fields["fixed"] = _int_array(fields["fixed"])
    if fields["roi"] is not None:
        fields["roi"] = _int_array(fields["roi"])
    fields["handle_groups"] = [_int_array(g) for g in fields["handle_groups"]]
    if fields.get("targets") is not None:
        fields["targets"] = np.array(fields["targets"], dtype=np.float64).reshape(-1, 3)
    return ClientMessage(msg.type, fields, msg.payload)


def decode_text_frame(data: bytes) -> ClientMessage:
    """Decode and validate a UTF-8 text frame with arrays for its long lists (runs in the worker process).

    Raises
    ------
    arap.server.protocol.RequestError
        As :func:`arap.server.protocol.parse_text`.
    """
    return arrays_from_lists(parse_text(data.decode("utf-8")))


def _exit_with_parent(parent: int) -> None:
    """Worker initializer: end the worker when the server process is gone, however it ended."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="arap-decoder-watchdog", daemon=True).start()


def _decode_on_thread(data: bytes) -> ClientMessage:
    return arrays_from_lists(parse_text(data.decode("utf-8"), cooperative=True))


class FrameDecoder:
    """The worker process that decodes large text frames, started on first use and shared by all sessions."""

    def __init__(self) -> None:
        self._pool: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()
        self._closed = False

    def _executor(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._closed:
                raise RuntimeError("the frame decoder is closed")
            if self._pool is None:
                # "spawn": the server has threads, which a forked child must not inherit half-way through.
                self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                                 initializer=_exit_with_parent, initargs=(os.getpid(),))
            return self._pool

    @property
    def started(self) -> bool:
        """Whether the worker process is running (it starts with the first large frame)."""
        return self._pool is not None

    def _discard(self, pool: ProcessPoolExecutor) -> None:
        with self._lock:
            if self._pool is pool:
                self._pool = None
        pool.shutdown(wait=False, cancel_futures=True)

    async def decode(self, text: str) -> ClientMessage:
        """Decode and validate a text frame in the worker process (on a thread if the process is unusable).

        Raises
        ------
        arap.server.protocol.RequestError
            The frame is not a valid message.
        """
        data = await anyio.to_thread.run_sync(str.encode, text)
        pool: ProcessPoolExecutor | None = None
        try:
            pool = self._executor()
            return await asyncio.get_running_loop().run_in_executor(pool, decode_text_frame, data)
        except BrokenProcessPool as exc:
            # raised by submit or by the result: the worker died (killed, out of memory); start a new one next time
            logger.warning("the decoder process ended (%r); decoding on a thread", exc)
            if pool is not None:
                self._discard(pool)
        except (RuntimeError, OSError) as exc:
            logger.warning("cannot use the decoder process (%r); decoding on a thread", exc)
        return await anyio.to_thread.run_sync(_decode_on_thread, data)

    def close(self, wait: bool = True) -> None:
        """Stop the worker process; frames waiting to be decoded are dropped.

        Parameters
        ----------
        wait : bool
            Wait until the worker process has ended (at most the frame it is decoding).
        """
        with self._lock:
            self._closed = True
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=wait, cancel_futures=True)
