"""Decoding of large text frames in separate processes, with bounded memory and fairly between sessions.

Decoding holds the interpreter lock: a thread decoding a 50 MB constraint set (millions of indices) would take it
from the event loop, and from every other session, for a second or more (``json.loads``, which builds a Python
object per number, for several). Text frames of :data:`PROCESS_BYTES` or more are therefore decoded and validated
in worker processes shared by all sessions, with :func:`arap.server.protocol.parse_large_text`: long lists of
numbers are counted against their limits before they are decoded and become NumPy arrays (never Python lists),
which cross the process boundary as flat buffers and need no per-number work in the server. Smaller frames are
decoded on the event loop or a thread (see :mod:`arap.server.connection`).

Fairness: frames of :data:`LARGE_BYTES` or more are decoded by a worker of their own (the large lane), the others
by another (the small lane), so a frame of a few megabytes never waits behind another session's 50 MB ones; the
large lane's worker runs at a lower CPU priority, so on a busy machine it does not slow the small lane either. Each
session decodes one frame at a time (its reader waits for it), so a lane's queue holds at most one frame per
session and serves them in turn.

If a worker process cannot be started or dies, the frame is decoded on a thread instead: slower for the other
sessions, never lost.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import anyio.to_thread
import numpy as np

from arap.server.client_messages import SetConstraints
from arap.server.memory import release_memory
from arap.server.messages import ClientMessage
from arap.server.protocol import parse_large_text

__all__ = ["LARGE_BYTES", "PROCESS_BYTES", "FrameDecoder", "arrays_from_lists", "decode_text_frame", "lane_of"]

logger = logging.getLogger(__name__)

PROCESS_BYTES = 2 * 2**20
"""Text frames at least this large are decoded in a worker process."""

LARGE_BYTES = 8 * 2**20
"""Text frames at least this large are decoded in the large lane (a worker of their own)."""

LARGE_LANE_NICENESS = 5
"""The large lane's worker runs at this lower CPU priority (Unix ``nice``): on a busy machine the event loop and the
small lane come first."""

TRIM_BYTES = 4 * 2**20
"""A worker hands its freed memory back to the system after decoding a frame at least this large."""


def lane_of(size: int) -> str:
    """The lane that decodes a text frame of ``size`` characters: ``"small"`` or ``"large"``."""
    return "large" if size >= LARGE_BYTES else "small"


def _int_array(values: list[int] | np.ndarray) -> np.ndarray | list[int]:
    if isinstance(values, np.ndarray):
        return values  # from parse_large_text: int32 or int64
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
        ``roi``, ``fixed`` and each handle group as (k,) integer arrays (int64 from lists; int32 or int64 from
        :func:`arap.server.protocol.parse_large_text`), ``targets`` as a (t, 3) float64 array.
    """
    if not isinstance(msg, SetConstraints):
        return msg
    targets = None if msg.targets is None else np.asarray(msg.targets, dtype=np.float64).reshape(-1, 3)
    return dataclasses.replace(msg, fixed=_int_array(msg.fixed),
                               roi=None if msg.roi is None else _int_array(msg.roi),
                               handle_groups=[_int_array(g) for g in msg.handle_groups], targets=targets)


def decode_text_frame(data: bytes | str, max_indices: int | None = None) -> ClientMessage:
    """Decode and validate a UTF-8 text frame with arrays for its long lists (runs in a worker process).

    A list of vertex indices longer than ``max_indices`` is refused when counted, before it is decoded (see
    :func:`arap.server.protocol.parse_large_text`): neither this process nor the server ever holds it as an array.

    Raises
    ------
    arap.server.protocol.RequestError
        As :func:`arap.server.protocol.parse_large_text`.
    """
    size = len(data)
    if isinstance(data, str):
        data = data.encode("utf-8")
    try:
        return arrays_from_lists(parse_large_text(data, max_indices))
    finally:
        if size >= TRIM_BYTES:
            del data
            release_memory()


def _start_worker(parent: int, niceness: int) -> None:
    """Worker initializer: lower the worker's CPU priority by ``niceness`` (where the system allows), and end it
    when the server process is gone, however it ended."""
    if niceness and hasattr(os, "nice"):
        try:
            os.nice(niceness)
        except OSError:
            pass
    _exit_with_parent(parent)


def _exit_with_parent(parent: int) -> None:
    """End this worker when the server process is gone, however it ended."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="arap-decoder-watchdog", daemon=True).start()


def _decode_on_thread(text: str, max_indices: int | None) -> ClientMessage:
    return arrays_from_lists(parse_large_text(text.encode("utf-8"), max_indices))


class FrameDecoder:
    """The worker processes that decode large text frames, one per lane (see :func:`lane_of`), each started on
    first use and shared by all sessions."""

    def __init__(self) -> None:
        self._pools: dict[str, ProcessPoolExecutor] = {}
        self._lock = threading.Lock()
        self._closed = False

    def _executor(self, lane: str) -> ProcessPoolExecutor:
        with self._lock:
            if self._closed:
                raise RuntimeError("the frame decoder is closed")
            pool = self._pools.get(lane)
            if pool is None:
                # "spawn": the server has threads, which a forked child must not inherit half-way through.
                pool = self._pools[lane] = ProcessPoolExecutor(
                    max_workers=1, mp_context=multiprocessing.get_context("spawn"), initializer=_start_worker,
                    initargs=(os.getpid(), LARGE_LANE_NICENESS if lane == "large" else 0))
            return pool

    @property
    def started(self) -> bool:
        """Whether a worker process is running (each starts with the first frame of its lane)."""
        return bool(self._pools)

    def _discard(self, pool: ProcessPoolExecutor) -> None:
        with self._lock:
            for lane, p in list(self._pools.items()):
                if p is pool:
                    del self._pools[lane]
        pool.shutdown(wait=False, cancel_futures=True)

    async def decode(self, text: str, max_indices: int | None = None) -> ClientMessage:
        """Decode and validate a text frame in its lane's worker process (on a thread if the process is unusable).

        ``max_indices``: see :func:`decode_text_frame`.

        Raises
        ------
        arap.server.protocol.RequestError
            The frame is not a valid message.
        """
        pool: ProcessPoolExecutor | None = None
        try:
            pool = self._executor(lane_of(len(text)))
            # the text itself goes to the worker (pickled once as UTF-8): no encoded copy waits here meanwhile
            return await asyncio.get_running_loop().run_in_executor(pool, decode_text_frame, text, max_indices)
        except BrokenProcessPool as exc:
            # raised by submit or by the result: the worker died (killed, out of memory); start a new one next time
            logger.warning("the decoder process ended (%r); decoding on a thread", exc)
            if pool is not None:
                self._discard(pool)
        except (RuntimeError, OSError) as exc:
            logger.warning("cannot use the decoder process (%r); decoding on a thread", exc)
        return await anyio.to_thread.run_sync(_decode_on_thread, text, max_indices)

    def close(self, wait: bool = True) -> None:
        """Stop the worker processes; frames waiting to be decoded are dropped.

        Parameters
        ----------
        wait : bool
            Wait until the worker processes have ended (at most the frames they are decoding).
        """
        with self._lock:
            self._closed = True
            pools = list(self._pools.values())
            self._pools.clear()
        for pool in pools:
            pool.shutdown(wait=wait, cancel_futures=True)
