"""One job's output at a time: a lock per output, so that two batches writing into one folder never run the same job,
and workers that end with the batch that started them.

A job holds an exclusive :func:`fcntl.flock` lock on a hidden file beside its output (``.NAME.lock``) while it runs,
and removes that file when it is done. The system releases such a lock when its holder ends, however it ended, so a
lock file left by a killed batch is stale: the next batch takes it over at once. A batch that finds a job's lock held
runs its other jobs first, then waits for the lock and skips the job when the other batch wrote its output.

Where the file system has no such locks (or the folder cannot hold the lock file), jobs run unlocked.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # not on POSIX: no locks
    fcntl = None  # type: ignore[assignment]

__all__ = ["LOCK_SUFFIX", "exit_with_parent", "lock_path", "output_lock"]

LOCK_SUFFIX = ".lock"
"""The lock file of output ``folder/NAME`` is ``folder/.NAME.lock``."""

_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def lock_path(output: str | os.PathLike[str]) -> Path:
    """The lock file of an output: ``.NAME.lock`` beside it."""
    path = Path(output)
    return path.with_name(f".{path.name}{LOCK_SUFFIX}")


_BUSY = -1


def _take(path: Path, wait: bool) -> int | None:
    """The descriptor of the locked lock file; ``_BUSY`` when another process holds it (and ``wait`` is false); None
    when no lock can be had here (the job then runs unlocked)."""
    assert fcntl is not None
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError:
            return None
        except BaseException:  # interrupted as the file was made: removed, unless another process holds it
            _give_up(None, path)
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            os.close(fd)
            return _BUSY
        except OSError:  # e.g. ENOLCK: a file system without locks
            os.close(fd)
            return None
        except BaseException:  # interrupted (a Ctrl-C) while waiting, or as the lock was taken: no lock file left
            _give_up(fd, path)
            raise
        # The previous holder removes the file as it lets go: the lock is ours only if the file is still the one there.
        try:
            if _is_there(fd, path):
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, 0)
                    os.write(fd, f"{os.getpid()}\n".encode())
                return fd
        except BaseException:
            _give_up(fd, path)
            raise
        os.close(fd)


def _is_there(fd: int, path: Path) -> bool:
    """Whether the file open as ``fd`` is the one at ``path``."""
    try:
        here = os.stat(path)
    except FileNotFoundError:
        return False
    mine = os.fstat(fd)
    return (here.st_dev, here.st_ino) == (mine.st_dev, mine.st_ino)


def _give_up(fd: int | None, path: Path) -> None:
    """Close ``fd``, the lock file at ``path`` being taken when an interrupt came (None: opened again here), and
    remove the file first when the lock is ours, or free: another batch's held lock file stays."""
    assert fcntl is not None
    with contextlib.suppress(OSError):
        if fd is None:
            fd = os.open(path, os.O_RDWR | getattr(os, "O_CLOEXEC", 0))
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # ours already, or taken now: no other process holds it
        if _is_there(fd, path):
            os.unlink(path)
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)


@contextlib.contextmanager
def output_lock(output: str | os.PathLike[str], wait: bool = True) -> Iterator[bool]:
    """Hold the lock of ``output`` for the block.

    Parameters
    ----------
    output : path-like
        The job's output; its folder must exist.
    wait : bool
        Wait while another process holds the lock; otherwise the block gets False at once and holds nothing.

    Yields
    ------
    bool
        True when the lock is held (or cannot be had on this file system: the job runs unlocked), False when another
        process holds it and ``wait`` is false.
    """
    if fcntl is None:
        yield True
        return
    path = lock_path(output)
    fd = _take(path, wait)
    if fd == _BUSY:
        yield False
        return
    try:
        yield True
    finally:
        if fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(path)  # before letting go: a waiting process then finds the file gone and takes a new one
            os.close(fd)


def exit_with_parent(parent: int) -> None:
    """End this process when the process ``parent`` is gone, however it ended (a worker initializer).

    On Linux the kernel kills it when its parent ends (``PR_SET_PDEATHSIG``); elsewhere, and as a fallback, a thread
    watches :func:`os.getppid` and exits when it changes.
    """
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent:  # the parent ended before the kernel was told
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="arap-batch-watchdog", daemon=True).start()
