"""Keep what compiled code prints off the process's standard output.

CHOLMOD inside the ``cholespy`` wheel reports a matrix that is not positive definite with the C library's ``printf``
("CHOLMOD warning: not positive definite. file: ... line: ..."), straight to file descriptor 1. The library raises a
clear error in that case anyway; the stray line would only corrupt what a command writes on standard output (e.g.
``arap bench --json``) and puzzle a user. :func:`c_stdout_to_log` sends such lines to the log instead.
"""

from __future__ import annotations

import ctypes
import logging
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

__all__ = ["c_stdout_to_log"]

logger = logging.getLogger("arap.sparse.linsolve")
_lock = threading.Lock()


@lru_cache(maxsize=1)
def _libc() -> Any:
    """The C library (for ``fflush``), or None where it cannot be loaded."""
    try:
        libc = ctypes.CDLL(None)
        libc.fflush  # noqa: B018 - resolves the symbol, or raises AttributeError
    except (OSError, TypeError, AttributeError):
        return None
    return libc


@contextmanager
def c_stdout_to_log(prefix: bytes = b"CHOLMOD") -> Iterator[None]:
    """During the block, file descriptor 1 writes to a temporary file; afterwards the lines starting with ``prefix``
    go to the ``arap.sparse.linsolve`` logger (DEBUG) and everything else written meanwhile (another thread's output,
    the text Python had buffered) is written to standard output.

    Blocks run one at a time. Where there is no standard output (file descriptor 1 closed) the block runs as it is.

    Example
    -------
    >>> with c_stdout_to_log():
    ...     _ = os.write(1, b"CHOLMOD warning: not positive definite\\n")
    """
    with _lock:
        try:
            saved = os.dup(1)
        except OSError:  # nothing to protect
            saved = -1
        if saved < 0:
            yield
            return
        with tempfile.TemporaryFile() as tmp:
            _flush_python_stdout()
            os.dup2(tmp.fileno(), 1)
            try:
                yield
            finally:
                _flush_python_stdout()
                libc = _libc()
                if libc is not None:
                    libc.fflush(None)  # the C library buffers stdout when it is not a terminal
                os.dup2(saved, 1)
                os.close(saved)
                tmp.seek(0)
                _dispatch(tmp.read(), prefix)


def _flush_python_stdout() -> None:
    try:
        sys.stdout.flush()
    except (AttributeError, ValueError, OSError):  # replaced, closed or broken stdout: nothing buffered
        pass


def _dispatch(captured: bytes, prefix: bytes) -> None:
    """Log the captured lines that start with ``prefix``; write the rest back to standard output."""
    passed = []
    for line in captured.splitlines(keepends=True):
        if line.startswith(prefix):
            logger.debug("%s", line.decode("utf-8", "replace").rstrip())
        else:
            passed.append(line)
    rest = b"".join(passed)
    while rest:
        try:
            rest = rest[os.write(1, rest):]
        except OSError:  # standard output went away meanwhile
            return
