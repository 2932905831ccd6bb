"""Atomic writes: a killed or failing writer leaves the earlier file intact and no partial file at its path."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arap.constraints import Constraints, load_constraints, save_constraints
from arap.errors import ConstraintError, MeshFormatError
from arap.io import load_mesh, save_mesh
from arap.io.atomic import atomic_output, write_atomic
from arap.meshes.shapes import builtin_mesh
from tests.waiting import wait_until

EARLIER = b"# an earlier good output\n"
TIMEOUT = 120.0


def _others(folder: Path, keep: set[str]) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (512 * 1024, 512 * 1024))


# Python ignores SIGXFSZ (a write past the limit then fails with EFBIG); "kill" restores the default action, under
# which the kernel kills the process in the middle of its write.
SAVE_BIG_MESH = """
import signal, sys
if sys.argv[2] == "kill":
    signal.signal(signal.SIGXFSZ, signal.SIG_DFL)
from arap.io import save_mesh
from arap.meshes.shapes import sphere
V, F = sphere(6)
save_mesh(sys.argv[1], V, F)
"""


def test_writer_killed_mid_write_leaves_the_earlier_file(tmp_path: Path) -> None:
    """The kernel kills the writer (SIGXFSZ) when its file passes 512 KiB, in the middle of writing a 2.5 MB mesh."""
    out = tmp_path / "out.obj"
    out.write_bytes(EARLIER)
    proc = subprocess.run([sys.executable, "-c", SAVE_BIG_MESH, str(out), "kill"], capture_output=True,
                          timeout=TIMEOUT, preexec_fn=_limit_file_size)
    assert proc.returncode == -signal.SIGXFSZ, proc.stderr
    assert out.read_bytes() == EARLIER
    leftovers = _others(tmp_path, {"out.obj"})
    assert len(leftovers) == 1 and leftovers[0].startswith(".out.obj.") and leftovers[0].endswith(".tmp")
    assert (tmp_path / leftovers[0]).stat().st_size == 512 * 1024  # the partial write went there


def test_failed_write_removes_its_temporary_file(tmp_path: Path) -> None:
    """With SIGXFSZ ignored the write fails with EFBIG instead: an error, the earlier file kept, nothing left."""
    out = tmp_path / "out.obj"
    out.write_bytes(EARLIER)
    proc = subprocess.run([sys.executable, "-c", SAVE_BIG_MESH, str(out), "fail"], capture_output=True, text=True,
                          timeout=TIMEOUT, preexec_fn=_limit_file_size)
    assert proc.returncode == 1 and "MeshFormatError: cannot write" in proc.stderr
    assert out.read_bytes() == EARLIER
    assert _others(tmp_path, {"out.obj"}) == []


DEFORM_KILLED_BEFORE_RENAME = """
import os, sys, time
from pathlib import Path
marker = Path(sys.argv[1])
def stall(fd):
    marker.write_text("written")
    time.sleep(600)  # the scenario: stalled before the rename until the test kills it
os.fsync = stall
from arap.cli import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("fmt", ["obj", "ply"])
def test_killed_arap_deform_leaves_the_earlier_output(tmp_path: Path, fmt: str) -> None:
    """``arap deform`` is killed (SIGKILL) once its output is written but before it is in place."""
    V, F = builtin_mesh("bar")
    out = tmp_path / f"out.{fmt}"
    save_mesh(out, V, F)
    earlier = out.read_bytes()
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": np.flatnonzero(V[:, 1] < 0.3).tolist(),
                                 "handles": np.flatnonzero(V[:, 1] > 4.7).tolist(),
                                 "targets": (V[V[:, 1] > 4.7] + [1.0, 0, 0]).tolist()}))
    marker = tmp_path / "marker"
    child = subprocess.Popen([sys.executable, "-c", DEFORM_KILLED_BEFORE_RENAME, str(marker), "deform", "bar",
                              "-c", str(cfile), "-o", str(out), "-n", "2", "-q"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        def flushing() -> bool:
            assert child.poll() is None, child.stderr.read() if child.stderr else ""
            return marker.exists()

        wait_until(flushing, TIMEOUT, "the writer to reach its flush")
        assert out.read_bytes() == earlier  # not touched while the new content is being written
    finally:
        child.kill()
        child.wait(timeout=TIMEOUT)
        if child.stderr:
            child.stderr.close()
    assert out.read_bytes() == earlier
    U, _ = load_mesh(out)
    np.testing.assert_array_equal(U, V)
    temporary = _others(tmp_path, {out.name, "c.json", "marker"})
    assert len(temporary) == 1 and temporary[0].endswith(".tmp")
    assert (tmp_path / temporary[0]).stat().st_size > 0


def test_successful_write_replaces_and_keeps_permissions(tmp_path: Path) -> None:
    path = tmp_path / "a.txt"
    write_atomic(path, "first")
    os.chmod(path, 0o640)
    write_atomic(path, b"second")
    assert path.read_bytes() == b"second"
    assert path.stat().st_mode & 0o777 == 0o640
    assert _others(tmp_path, {"a.txt"}) == []


def test_exception_inside_the_block_keeps_the_earlier_file(tmp_path: Path) -> None:
    path = tmp_path / "a.bin"
    path.write_bytes(EARLIER)
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_output(path) as stream:
            stream.write(b"partial")
            raise RuntimeError("boom")
    assert path.read_bytes() == EARLIER
    assert _others(tmp_path, {"a.bin"}) == []


def test_symlink_target_is_replaced(tmp_path: Path) -> None:
    target = tmp_path / "real.obj"
    target.write_bytes(EARLIER)
    link = tmp_path / "link.obj"
    link.symlink_to(target)
    V, F = builtin_mesh("bar")
    save_mesh(link, V, F)
    assert link.is_symlink()
    np.testing.assert_array_equal(load_mesh(target)[0], V)


def test_unwritable_destinations_are_clear_errors(tmp_path: Path) -> None:
    V, F = builtin_mesh("bar")
    (tmp_path / "folder.obj").mkdir()
    with pytest.raises(MeshFormatError, match="cannot write"):
        save_mesh(tmp_path / "folder.obj", V, F)
    with pytest.raises(MeshFormatError, match="cannot write"):
        save_mesh(tmp_path / "missing" / "a.obj", V, F)
    c = Constraints(fixed=np.array([0]), handles=np.zeros(0, dtype=np.int64), targets=np.zeros((0, 3)))
    with pytest.raises(ConstraintError, match="cannot write"):
        save_constraints(tmp_path / "folder.obj", c)
    assert _others(tmp_path, {"folder.obj"}) == []


def test_save_constraints_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "c.json"
    first = Constraints(fixed=np.array([0, 1]), handles=np.array([2]), targets=np.array([[1.0, 2, 3]]))
    save_constraints(path, first)
    earlier = path.read_bytes()

    def fail(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(ConstraintError, match="No space left on device"):
        save_constraints(path, Constraints(fixed=np.array([5]), handles=np.zeros(0, dtype=np.int64),
                                           targets=np.zeros((0, 3))))
    assert path.read_bytes() == earlier
    assert _others(tmp_path, {"c.json"}) == []
    np.testing.assert_array_equal(load_constraints(path, 10).fixed, [0, 1])
