"""Atomic file writes: a file is either its earlier content or the complete new one, never a partial write.

The data goes to a temporary file in the destination's folder (same file system), is flushed to disk, and then
renamed over the destination with :func:`os.replace`, which is atomic on POSIX and Windows. A writer killed before
the rename leaves the destination untouched (and at most a hidden ``.NAME.XXXXXXXX.tmp`` file beside it); a write
that fails removes its temporary file.

Only regular files are replaced (:func:`arap.io.paths.write_destination`): a destination that is a folder, a FIFO, a
device or a socket, named directly or through symbolic links, is refused before anything is written. A symbolic link
is kept and the regular file it points to is replaced, its temporary file written beside that file; a dangling link
gets the file it names, when that file's folder exists.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from arap.io.paths import not_regular, write_destination

__all__ = ["atomic_output", "temporary_name", "write_atomic"]


def temporary_name(path: Path) -> Path:
    """A fresh hidden name beside ``path`` for its temporary file (``.NAME.XXXXXXXX.tmp``)."""
    return path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")


def _sync_folder(folder: Path) -> None:
    """Flush a folder's entry list (so the rename itself survives a crash); not possible on every system."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
    try:
        fd = os.open(folder, flags)
    except OSError:
        return
    try:
        with contextlib.suppress(OSError):
            os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[BinaryIO]:
    """Open a binary stream whose content replaces ``path`` atomically when the block ends without an error.

    Parameters
    ----------
    path : path-like
        Destination. A symbolic link is kept and followed: the regular file it points to is replaced (or, for a
        dangling link, created). An existing file keeps its permission bits.

    Yields
    ------
    BinaryIO
        The temporary file, open for writing.

    Raises
    ------
    arap.io.paths.SpecialFileError
        The destination is not a regular file (a folder, a FIFO, a device, a socket, or a link to one), or its
        folder is missing or is a file; nothing is written.
    OSError
        The folder is not writable, or the write fails. The temporary file is removed and the destination is left
        as it was.
    """
    dest = write_destination(path)
    tmp = temporary_name(dest)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        try:
            mode = dest.stat().st_mode
        except FileNotFoundError:
            pass
        else:
            if not stat.S_ISREG(mode):  # put there while the data was written
                raise not_regular(Path(path), mode)
            os.chmod(tmp, stat.S_IMODE(mode))
        os.replace(tmp, dest)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _sync_folder(dest.parent)


def write_atomic(path: str | os.PathLike[str], data: bytes | str, *, encoding: str = "utf-8") -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`).

    Parameters
    ----------
    path : path-like
    data : bytes or str
        Text is encoded with ``encoding``.
    encoding : str

    Raises
    ------
    OSError
        The file cannot be written; ``path`` is unchanged.
    """
    payload = data.encode(encoding) if isinstance(data, str) else bytes(data)
    with atomic_output(path) as stream:
        stream.write(payload)
