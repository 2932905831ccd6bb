"""Paths that name no regular file: FIFOs, devices, sockets and folders, directly or through symbolic links.

Reading one must fail at once with a clear message (a FIFO would block the reader forever, ``/dev/zero`` fill its
memory), and writing must leave it as it is (an atomic write renames a regular file over whatever is there). A link
to a regular file is kept and its target replaced; a file where a folder is needed is named as such.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import stat
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import arap
from arap.cli import main
from arap.constraints import Constraints, load_constraints, save_constraints
from arap.errors import ConstraintError, MeshFormatError
from arap.io import load_mesh, load_mesh_with_report, save_mesh
from arap.io.atomic import write_atomic
from arap.io.paths import SpecialFileError, read_regular_file, write_destination
from arap.meshes.shapes import builtin_mesh

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs and symbolic links (POSIX)")

EARLIER = b"# an earlier good output\n"


class Blocked(BaseException):
    """Raised by the alarm in :func:`within`; a BaseException, so that no error handler reports it as bad input."""


@contextlib.contextmanager
def within(seconds: int = 20) -> Iterator[None]:
    """Fail (instead of hanging the test run) when the block blocks, e.g. reading a FIFO nobody writes to."""

    def fire(signum: int, frame: object) -> None:
        raise Blocked(f"blocked for {seconds} s")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _bound_socket(path: Path) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(path))
    return sock


@pytest.fixture
def specials(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """In a temporary working folder: a FIFO, a socket, a folder and links to them, a link to /dev/zero, a link
    chain to a regular file, dangling links, a file where a folder is needed and a constraints file."""
    monkeypatch.chdir(tmp_path)
    os.mkfifo("fifo.obj")
    os.mkfifo("fifo.json")
    (tmp_path / "folder.obj").mkdir()
    (tmp_path / "real.obj").write_bytes(EARLIER)
    (tmp_path / "file.obj").write_bytes(EARLIER)
    for name, target in {"fifo_link.obj": "fifo.obj", "zero.obj": "/dev/zero", "zero.json": "/dev/zero",
                         "folder_link.obj": "folder.obj", "socket_link.obj": "socket.obj", "link.obj": "real.obj",
                         "chain.obj": "link.obj", "dangling.obj": "new.obj", "lost.obj": "nowhere/new.obj",
                         "loop_a.obj": "loop_b.obj", "loop_b.obj": "loop_a.obj"}.items():
        (tmp_path / name).symlink_to(target)
    V, _ = builtin_mesh("bar")
    fixed, handles = np.flatnonzero(V[:, 1] < 0.3), np.flatnonzero(V[:, 1] > 4.7)
    (tmp_path / "c.json").write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(),
                                                 "targets": (V[handles] + [1.0, 0, 0]).tolist()}))
    sock = _bound_socket(tmp_path / "socket.obj")
    try:
        yield tmp_path
    finally:
        sock.close()


def _untouched(folder: Path) -> None:
    """The special files are still there, as they were, and no temporary file was left."""
    assert stat.S_ISFIFO(os.lstat(folder / "fifo.obj").st_mode)
    assert stat.S_ISSOCK(os.lstat(folder / "socket.obj").st_mode)
    assert (folder / "folder.obj").is_dir() and not any((folder / "folder.obj").iterdir())
    for name in ("fifo_link.obj", "zero.obj", "folder_link.obj", "socket_link.obj", "link.obj"):
        assert (folder / name).is_symlink()
    assert (folder / "real.obj").read_bytes() == EARLIER and (folder / "file.obj").read_bytes() == EARLIER
    assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []


# ---------------------------------------------------------------------------------------------- reading
@pytest.mark.parametrize(("name", "message"), [
    ("fifo.obj", "cannot read fifo.obj: it is a named pipe (FIFO), not a regular file"),
    ("fifo_link.obj", "it is a symbolic link to {}/fifo.obj, which is a named pipe (FIFO), not a regular file"),
    ("zero.obj", "cannot read zero.obj: it is a symbolic link to /dev/zero, which is a character device"),
    ("socket.obj", "cannot read socket.obj: it is a socket, not a regular file"),
    ("socket_link.obj", "which is a socket, not a regular file"),
    ("folder_link.obj", "folder_link.obj is a folder, not a mesh file"),
    ("file.obj/mesh.obj", "cannot read file.obj/mesh.obj: file.obj is a file, not a folder"),
])
def test_load_mesh_refuses_what_is_no_regular_file(specials: Path, name: str, message: str) -> None:
    with within(), pytest.raises(MeshFormatError) as info:
        arap.load_mesh(name)
    assert message.format(specials.resolve()) in str(info.value)
    with within(), pytest.raises(MeshFormatError, match=r"not a regular file|folder"):
        load_mesh_with_report(name, max_vertices=10)
    _untouched(specials)


def test_a_link_to_a_regular_file_is_read(specials: Path) -> None:
    V, F = builtin_mesh("bar")
    save_mesh("real.obj", V, F)
    np.testing.assert_array_equal(load_mesh("chain.obj")[0], V)


@pytest.mark.parametrize("name", ["fifo.json", "zero.json"])
def test_load_constraints_refuses_what_is_no_regular_file(specials: Path, name: str) -> None:
    with within(), pytest.raises(ConstraintError, match=f"cannot read constraints file {name}: it is .*not a regular"):
        load_constraints(name, 10)


def test_read_regular_file_checks_again_once_open(specials: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A FIFO put in place of the checked file before it is opened is opened without blocking, then refused."""
    monkeypatch.setattr("arap.io.paths.check_regular_file", lambda path: os.stat("real.obj"))
    with within(), pytest.raises(SpecialFileError, match="named pipe"):
        read_regular_file("fifo.obj")
    assert read_regular_file("link.obj") == EARLIER


@pytest.mark.parametrize(("argv", "message"), [
    (["info", "fifo.obj"], "cannot read fifo.obj: it is a named pipe (FIFO), not a regular file"),
    (["info", "--json", "zero.obj"], "which is a character device, not a regular file"),
    (["info", "file.obj/mesh.obj"], "file.obj/mesh.obj: no such file (file.obj is a file, not a folder)"),
    (["bench", "fifo_link.obj"], "which is a named pipe (FIFO), not a regular file"),
    (["deform", "fifo.obj", "-c", "c.json", "-o", "o.obj"], "cannot read fifo.obj: it is a named pipe"),
    (["deform", "zero.obj", "-c", "c.json", "-o", "o.obj"], "which is a character device"),
    (["deform", "bar", "-c", "fifo.json", "-o", "o.obj"], "cannot read constraints file fifo.json: it is a named"),
    (["deform", "bar", "-c", "zero.json", "-o", "o.obj"], "which is a character device, not a regular file"),
    (["deform", "bar", "-c", "c.json", "-o", "o.obj", "--start", "fifo.obj"], "--start: cannot read fifo.obj"),
    (["deform", "bar", "-c", "c.json", "-o", "o.obj", "--start", "file.obj/s.obj"],
     "file.obj/s.obj does not exist (file.obj is a file, not a folder)"),
])
def test_commands_refuse_to_read_what_is_no_regular_file(specials: Path, capsys: pytest.CaptureFixture[str],
                                                         argv: list[str], message: str) -> None:
    with within(60):
        assert main(argv) == 1
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert err[-1].startswith("arap: error: ") and message in err[-1], err
    assert "Traceback" not in captured.err
    assert not (specials / "o.obj").exists()
    _untouched(specials)


def test_the_studio_refuses_a_fifo_as_its_mesh(specials: Path) -> None:
    pytest.importorskip("starlette")
    from arap.server.meshdata import load_default

    with within(), pytest.raises(MeshFormatError, match="named pipe"):
        load_default("fifo.obj")


# ---------------------------------------------------------------------------------------------- writing
@pytest.mark.parametrize(("name", "message"), [
    ("fifo.obj", "cannot write fifo.obj: it is a named pipe (FIFO), not a regular file"),
    ("fifo_link.obj", "cannot write fifo_link.obj: it is a symbolic link to {}/fifo.obj, which is a named pipe"),
    ("socket.obj", "cannot write socket.obj: it is a socket, not a regular file"),
    ("socket_link.obj", "which is a socket, not a regular file"),
    ("folder.obj", "cannot write folder.obj: it is a folder, not a file"),
    ("folder_link.obj", "which is a folder, not a regular file"),
    ("lost.obj", "it is a symbolic link to {}/nowhere/new.obj, and the folder {}/nowhere does not exist"),
    ("file.obj/out.obj", "cannot write file.obj/out.obj: file.obj is a file, not a folder"),
    ("file.obj/more/out.obj", "file.obj is a file, not a folder"),
    ("loop_a.obj", "cannot write loop_a.obj"),
])
def test_save_mesh_leaves_what_is_no_regular_file(specials: Path, name: str, message: str) -> None:
    V, F = builtin_mesh("bar")
    with within(), pytest.raises(MeshFormatError) as info:
        save_mesh(name, V, F)
    assert message.format(specials.resolve(), specials.resolve()) in str(info.value)
    _untouched(specials)
    assert not (specials / "nowhere").exists()


def test_a_device_is_left_as_it_is(specials: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A character device node (as root, the writer used to rename its file over it), directly and by a link."""
    try:
        os.mknod("null.obj", 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except (PermissionError, OSError) as exc:
        pytest.skip(f"cannot make a device node here: {exc}")
    os.symlink("null.obj", "null_link.obj")
    V, F = builtin_mesh("bar")
    for name in ("null.obj", "null_link.obj"):
        with pytest.raises(MeshFormatError, match="character device, not a regular file"):
            save_mesh(name, V, F)
        assert main(["deform", "bar", "-c", "c.json", "-o", name]) == 1
        assert "character device, not a regular file" in capsys.readouterr().err
        assert stat.S_ISCHR(os.lstat("null.obj").st_mode)
    _untouched(specials)


def test_save_constraints_and_write_atomic_leave_a_fifo(specials: Path) -> None:
    c = Constraints(fixed=np.array([0]), handles=np.zeros(0, dtype=np.int64), targets=np.zeros((0, 3)))
    with pytest.raises(ConstraintError, match=r"cannot write constraints file fifo\.json: it is a named pipe"):
        save_constraints("fifo.json", c)
    with pytest.raises(SpecialFileError, match="which is a named pipe"):
        write_atomic("fifo_link.obj", b"data")
    assert stat.S_ISFIFO(os.lstat("fifo.json").st_mode)
    _untouched(specials)


def test_a_fifo_put_in_place_during_the_write_is_left(specials: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The destination is examined again just before the rename."""
    real_fsync = os.fsync
    out = specials / "out.obj"

    def swap(fd: int) -> None:
        real_fsync(fd)
        out.unlink()
        os.mkfifo(out)

    out.write_bytes(EARLIER)
    monkeypatch.setattr(os, "fsync", swap)
    with pytest.raises(SpecialFileError, match="named pipe"):
        write_atomic(out, b"data")
    monkeypatch.setattr(os, "fsync", real_fsync)
    assert stat.S_ISFIFO(os.lstat(out).st_mode)
    out.unlink()
    _untouched(specials)


def test_a_link_to_a_regular_file_is_kept_and_its_target_replaced(specials: Path) -> None:
    """Through a chain of two links, into another folder: the target is replaced atomically (its temporary file
    beside it), keeps its permission bits, and both links stay links."""
    (specials / "elsewhere").mkdir()
    target = specials / "elsewhere" / "target.obj"
    target.write_bytes(EARLIER)
    os.chmod(target, 0o640)
    os.symlink(target, "far.obj")
    os.symlink("far.obj", "far_chain.obj")
    V, F = builtin_mesh("bar")
    save_mesh("far_chain.obj", V, F)
    assert Path("far_chain.obj").is_symlink() and Path("far.obj").is_symlink()
    np.testing.assert_array_equal(load_mesh(target)[0], V)
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert write_destination("far_chain.obj") == target.resolve()
    assert sorted(p.name for p in target.parent.iterdir()) == ["target.obj"]
    _untouched(specials)


def test_a_dangling_link_gets_the_file_it_names(specials: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """When the folder of the file it names exists; the link is kept (otherwise see ``lost.obj`` above)."""
    assert main(["deform", "bar", "-c", "c.json", "-o", "dangling.obj", "-q"]) == 0
    assert Path("dangling.obj").is_symlink() and Path("new.obj").is_file()
    assert load_mesh("new.obj")[0].shape == builtin_mesh("bar")[0].shape
    _untouched(specials)


@pytest.mark.parametrize(("output", "message"), [
    ("fifo.obj", "cannot write fifo.obj: it is a named pipe (FIFO), not a regular file"),
    ("fifo_link.obj", "which is a named pipe (FIFO), not a regular file"),
    ("socket_link.obj", "which is a socket, not a regular file"),
    ("folder_link.obj", "which is a folder, not a regular file"),
    ("lost.obj", "nowhere does not exist"),
    ("file.obj/out.obj", "cannot write file.obj/out.obj: file.obj is a file, not a folder"),
])
def test_deform_refuses_an_output_that_is_no_regular_file(specials: Path, capsys: pytest.CaptureFixture[str],
                                                          output: str, message: str) -> None:
    """Before any work: one line, exit status 1, nothing written."""
    with within(60):
        assert main(["deform", "bar", "-c", "c.json", "-o", output]) == 1
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("arap: error: ") and message in err[0], err
    _untouched(specials)


def test_deform_through_a_link_replaces_its_target(specials: Path) -> None:
    assert main(["deform", "bar", "-c", "c.json", "-o", "chain.obj", "-q"]) == 0
    assert Path("chain.obj").is_symlink() and Path("link.obj").is_symlink()
    assert load_mesh("real.obj")[0].shape == builtin_mesh("bar")[0].shape
    assert [p.name for p in specials.iterdir() if p.name.startswith(".")] == []
