"""What a path names, checked before a file is read or written: only regular files are read or replaced.

A named pipe (FIFO) would block a reader forever, ``/dev/zero`` would fill its memory, and an atomic write renames
its temporary file over whatever the destination is, a device node included. So readers :func:`os.stat` the path
first (without opening it) and refuse anything but a regular file, and writers refuse a destination that exists and
is not one, whether it is named directly or through symbolic links. The errors are :class:`SpecialFileError`, an
:class:`OSError` whose ``strerror`` says what is wrong in words, so that callers reporting
``exc.strerror`` show it.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

__all__ = [
    "SpecialFileError",
    "check_regular_file",
    "folder_problem",
    "kind_of",
    "not_regular",
    "read_reference",
    "read_regular_file",
    "write_destination",
]

#: Largest file a mesh file may name (a glTF buffer, an MTL file, a texture image) that is read with it.
MAX_REFERENCED_BYTES = 1 << 30


class SpecialFileError(OSError):
    """A path names something other than a regular file (a folder, a FIFO, a device, a socket) where a file is read
    or written, or a folder that is missing or is a file. ``strerror`` is the message, ``filename`` the path."""

    def __init__(self, code: int, message: str, filename: str | os.PathLike[str]) -> None:
        super().__init__(code, message, os.fspath(filename))

    def __str__(self) -> str:
        return str(self.strerror)


def kind_of(mode: int) -> str:
    """What a file mode (``st_mode``) describes, in words: "a file", "a folder", "a named pipe (FIFO)", ..."""
    if stat.S_ISREG(mode):
        return "a file"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a named pipe (FIFO)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a special file"


def _code(mode: int) -> int:
    return errno.EISDIR if stat.S_ISDIR(mode) else errno.EINVAL


def not_regular(path: Path, mode: int) -> SpecialFileError:
    """The error for a path (maybe a symbolic link) whose file, of ``mode``, is not a regular one."""
    what = kind_of(mode)
    if path.is_symlink():
        message = f"it is a symbolic link to {os.path.realpath(path)}, which is {what}, not a regular file"
    elif stat.S_ISDIR(mode):
        message = "it is a folder, not a file"
    else:
        message = f"it is {what}, not a regular file"
    return SpecialFileError(_code(mode), message, path)


def check_regular_file(path: str | os.PathLike[str]) -> os.stat_result:
    """The status of the regular file ``path`` names (links followed), found without opening it.

    Raises
    ------
    SpecialFileError
        ``path`` names a folder, a FIFO, a device or a socket (directly or through symbolic links).
    OSError
        ``path`` does not exist or cannot be examined (e.g. ``FileNotFoundError``).
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except NotADirectoryError as exc:  # a file where the path needs a folder: say which
        problem = folder_problem(path.parent)
        if problem is None:
            raise
        raise SpecialFileError(errno.ENOTDIR, problem, path) from exc
    if not stat.S_ISREG(st.st_mode):
        raise not_regular(path, st.st_mode)
    return st


def _too_large(path: Path, size: int, max_bytes: int) -> SpecialFileError:
    return SpecialFileError(errno.EFBIG, f"it is {size:,} bytes long, more than the {max_bytes:,} accepted", path)


def read_regular_file(path: str | os.PathLike[str], max_bytes: int | None = None) -> bytes:
    """The content of the regular file ``path``; anything else is refused before it is opened.

    The file is opened without blocking (a FIFO put in its place after the check cannot hang the reader) and
    examined again once open, so that what is read is the regular file that was checked.

    Parameters
    ----------
    max_bytes : int or None
        Largest accepted size; a longer file is refused before it is read (and never read past it).

    Raises
    ------
    SpecialFileError
        ``path`` is not a regular file (see :func:`check_regular_file`), or is longer than ``max_bytes``.
    OSError
        It cannot be read.
    """
    path = Path(path)
    st = check_regular_file(path)
    if max_bytes is not None and st.st_size > max_bytes:
        raise _too_large(path, st.st_size, max_bytes)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0)
    fd = os.open(path, flags)
    with os.fdopen(fd, "rb") as stream:
        mode = os.fstat(stream.fileno()).st_mode
        if not stat.S_ISREG(mode):
            raise not_regular(path, mode)
        if max_bytes is None:
            return stream.read()
        data = stream.read(max_bytes + 1)  # a file that grew since it was examined
        if len(data) > max_bytes:
            raise _too_large(path, len(data), max_bytes)
        return data


def read_reference(folder: str | os.PathLike[str], reference: str, max_bytes: int = MAX_REFERENCED_BYTES) -> bytes:
    """The content of a file that a mesh file in ``folder`` names by ``reference`` (a glTF buffer or image, an OBJ
    ``mtllib``, an MTL texture, a PLY ``TextureFile``): the one rule every reader applies to the files it is
    pointed to.

    The reference is a path relative to ``folder`` (``/`` or ``\\`` between folder names). It is read only when the
    file it names lies inside ``folder`` once symbolic links are resolved (the real path of the file is under the
    real path of the folder), is a regular file (no folder, FIFO, device or socket) and holds at most ``max_bytes``:
    an absolute path, ``..`` leading out, or a link pointing out of the folder is refused, so that a mesh file
    cannot make the program read (and copy into what it writes) any other file of the machine.

    Raises
    ------
    SpecialFileError
        The reference leads outside ``folder``, names no regular file, or a file longer than ``max_bytes``; the
        message (``strerror``) says which.
    OSError
        The file does not exist or cannot be read.
    """
    base = os.path.realpath(folder)
    text = reference.replace("\\", "/")
    try:
        target = os.path.realpath(os.path.join(base, text))
    except ValueError as exc:  # a NUL character
        raise SpecialFileError(errno.EINVAL, "it is not a valid file name", reference) from exc
    if os.path.commonpath([base, target]) != base:
        raise SpecialFileError(errno.EPERM, f"it leads outside {base}, the folder of the mesh file", reference)
    return read_regular_file(target, max_bytes)


def folder_problem(folder: Path) -> str | None:
    """Why ``folder`` cannot hold a file, when it is missing or is not a folder (naming the file found where a folder
    is needed); None when it is a folder or cannot be examined (the caller then reports its own error)."""
    try:
        st = os.stat(folder)
    except (FileNotFoundError, NotADirectoryError):
        for above in folder.parents:  # the nearest existing folder above: a file there is what is wrong
            try:
                mode = os.stat(above).st_mode
            except (FileNotFoundError, NotADirectoryError):
                continue
            except OSError:
                break
            if not stat.S_ISDIR(mode):
                return f"{above} is {kind_of(mode)}, not a folder"
            break
        return f"the folder {folder} does not exist"
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode):
        return f"{folder} is {kind_of(st.st_mode)}, not a folder"
    return None


def write_destination(path: str | os.PathLike[str]) -> Path:
    """The file a write to ``path`` replaces: ``path`` itself, or the file its symbolic link (chain) points to, so
    that the link is kept. That file must be a regular file or not exist yet (a dangling link's target is created),
    in an existing folder.

    Raises
    ------
    SpecialFileError
        The destination is a folder, a FIFO, a device or a socket (directly or through links), or its folder is
        missing or is a file.
    OSError
        It cannot be examined (a loop of symbolic links, a folder that cannot be searched).
    """
    given = Path(path)
    linked = given.is_symlink()
    dest = Path(os.path.realpath(given)) if linked else given
    try:
        st: os.stat_result | None = os.stat(dest)
    except (FileNotFoundError, NotADirectoryError):
        st = None
    if st is not None:
        if not stat.S_ISREG(st.st_mode):
            raise not_regular(given, st.st_mode)
        return dest
    problem = folder_problem(dest.parent)
    if problem is not None:
        if linked:
            problem = f"it is a symbolic link to {dest}, and {problem}"
        raise SpecialFileError(errno.ENOENT, problem, given)
    return dest
