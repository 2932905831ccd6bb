"""Batches: outputs equal arap deform's on every backend, factorisations are shared, finished outputs are skipped,
a broken job fails alone with its manifest line, and an interrupted batch leaves no partial output."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import arap
from arap.batching import batch, read_manifest
from arap.batching.jobs import chunks_for
from arap.cli import main
from tests.waiting import poll_until, scaled, wait_until

pytestmark = pytest.mark.timeout(300)


def _family(folder: Path, count: int, mesh: str = "cactus", shift: float = 0.15) -> Path:
    """``count`` poses of one constraint set (top moved sideways) and a manifest writing ``out/pose_K.ply``."""
    V, _ = arap.builtin_mesh(mesh)
    y = V[:, 1]
    fixed, top = np.flatnonzero(y < 0.3).tolist(), np.flatnonzero(y > y.max() - 0.4)
    lines = []
    for k in range(count):
        pose = {"fixed": fixed, "handles": top.tolist(), "targets": (V[top] + [shift * k, 0.0, 0.0]).tolist()}
        (folder / f"pose_{k}.json").write_text(json.dumps(pose))
        lines.append(json.dumps({"mesh": mesh, "constraints": f"pose_{k}.json", "output": f"out/pose_{k}.ply"}))
    (folder / "out").mkdir(exist_ok=True)
    manifest = folder / "jobs.jsonl"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest


def _deform(folder: Path, k: int, mesh: str = "cactus") -> np.ndarray:
    out = folder / f"deform_{k}.ply"
    assert main(["deform", mesh, "-c", str(folder / f"pose_{k}.json"), "-o", str(out), "-q"]) == 0
    return arap.load_mesh(out)[0]


@pytest.mark.parametrize("backend", ["serial", "process", "dask", "ray"])
def test_outputs_equal_arap_deforms_on_every_backend(backend: str, tmp_path: Path) -> None:
    manifest = _family(tmp_path, 4)
    report = batch(manifest, backend=backend, workers=2, progress=False)
    assert report.counts() == {"done": 4, "skipped": 0, "failed": 0}, report.failed
    for k in range(4):
        np.testing.assert_array_equal(arap.load_mesh(tmp_path / f"out/pose_{k}.ply")[0], _deform(tmp_path, k))
    # one constraint set: one factorisation per chunk (two workers: two chunks)
    assert report.factorisations == (1 if backend == "serial" else 2)


def test_jobs_sharing_a_constraint_set_share_a_factorisation(tmp_path: Path) -> None:
    manifest = _family(tmp_path, 6)
    jobs, failed = read_manifest(manifest)
    assert not failed and len(jobs) == 6
    assert [len(c) for c in chunks_for(jobs, 1)] == [6]
    assert sorted(len(c) for c in chunks_for(jobs, 2)) == [3, 3]
    report = batch(manifest, backend="serial", progress=False)
    assert report.factorisations == 1 and report.counts()["done"] == 6


def test_a_second_run_skips_finished_outputs(tmp_path: Path) -> None:
    manifest = _family(tmp_path, 3)
    assert batch(manifest, backend="serial", progress=False).counts()["done"] == 3
    (tmp_path / "out/pose_1.ply").unlink()
    second = batch(manifest, backend="serial", progress=False)
    assert second.counts() == {"done": 1, "skipped": 2, "failed": 0}
    assert [o.status for o in second.outcomes] == ["skipped", "done", "skipped"]
    assert batch(manifest, backend="serial", progress=False, skip_existing=False).counts()["done"] == 3


def test_a_broken_job_fails_alone_with_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _family(tmp_path, 2)
    V, _ = arap.builtin_mesh("cactus")
    (tmp_path / "floating.json").write_text(json.dumps({"handles": [0], "targets": [V[0].tolist()], "roi": [0, 1]}))
    lines = manifest.read_text().splitlines()
    lines.insert(1, '{"mesh": "cactus", "constraints": "missing.json", "output": "out/m.ply"}')
    lines.insert(2, "{not json")
    lines.insert(3, '{"mesh": "cactus", "constraints": "pose_0.json", "output": "out/x.ply", "energy": "rubber"}')
    lines.append('{"mesh": "cactus", "constraints": "pose_1.json", "output": "out/pose_0.ply"}')
    manifest.write_text("\n".join(lines) + "\n\n")
    status = main(["batch", str(manifest), "--backend", "serial", "-q"])
    assert status == 1
    err = capsys.readouterr().err
    assert "line 2: cannot read constraints file" in err and "missing.json" in err
    assert "line 3: not valid JSON" in err
    assert "line 4:" in err and "rubber" in err
    assert "line 6: line 1 writes the same output" in err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["pose_0.ply", "pose_1.ply"]


def _interruptible() -> None:  # pragma: no cover - runs in the child before exec
    import signal

    # Ctrl-C as at a terminal: a test run from a background job of a script (or a CI runner started so) inherits an
    # ignored SIGINT, and the batch would then ignore the test's Ctrl-C and finish every job.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_batch(manifest: Path) -> subprocess.Popen[bytes]:
    """``arap batch MANIFEST --workers 2 -q`` in a process group of its own, as a terminal starts it."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "arap.cli", "batch", str(manifest), "--workers", "2", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, start_new_session=True,
                            preexec_fn=_interruptible)


def _interrupt(proc: subprocess.Popen[bytes], ready: Any, what: str, group: bool = True) -> tuple[str, str]:
    """Once ``ready()``, a SIGINT to the batch's process group (a Ctrl-C at the terminal: the workers get it too) or
    to the batch alone; the batch's stdout and stderr once it has ended."""
    try:
        def waiting() -> bool:
            assert proc.poll() is None, proc.communicate()
            return bool(ready())

        wait_until(waiting, 120, what, interval=0.05)
        if group:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            os.kill(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=scaled(60))
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    # One line, whoever got the signal: no worker's traceback (a worker that a Ctrl-C ended between two chunks)
    assert err.decode() == "arap: interrupted\n"
    return out.decode(), err.decode()


def _no_partial_output(folder: Path, mesh: str) -> list[Path]:
    """The files in ``folder``: whole meshes, and no temporary or lock file left."""
    written = sorted(folder.iterdir())
    V, F = arap.builtin_mesh(mesh)
    for path in written:
        assert path.suffix == ".ply" and not path.name.startswith("."), f"left behind: {path.name}"
        U, G = arap.load_mesh(path)
        assert U.shape == V.shape and np.array_equal(G, F)
    return written


def test_interrupted_batch_leaves_no_partial_output(tmp_path: Path) -> None:
    manifest = _family(tmp_path, 24, mesh="sphere:20000", shift=0.02)
    out = tmp_path / "out"
    _interrupt(_start_batch(manifest), lambda: any(out.glob("pose_*.ply")), "a first output")
    written = _no_partial_output(out, "sphere:20000")
    assert 0 < len(written) < 24
    report = batch(manifest, workers=2, progress=False)  # and the next run finishes the rest
    assert report.counts() == {"done": 24 - len(written), "skipped": len(written), "failed": 0}


def test_an_interrupt_of_the_batch_alone_stops_its_workers(tmp_path: Path) -> None:
    # A SIGINT to the batch's process only (kill -INT, a supervisor): its workers do not get it, the batch stops them.
    manifest = _family(tmp_path, 12, mesh="sphere:20000", shift=0.02)
    out = tmp_path / "out"
    _interrupt(_start_batch(manifest), lambda: any(out.glob("pose_*.ply")), "a first output", group=False)
    assert 0 < len(_no_partial_output(out, "sphere:20000")) < 12  # each worker stopped in its chunk of six


def test_a_ctrl_c_while_a_worker_waits_for_work_ends_the_batch_cleanly(tmp_path: Path) -> None:
    # Two chunks: six jobs on the bar, done long before the six on the sphere. A Ctrl-C once the bar's worker waits
    # for work must not end that worker (the pool would then be broken and kill the other in the middle of a job).
    manifest = _family(tmp_path, 6, mesh="sphere:20000", shift=0.02)
    bars = tmp_path / "bars"
    bars.mkdir()
    lines = [line.replace('"out/', '"bars/').replace('"pose_', '"bars/pose_')
             for line in _family(bars, 6, mesh="bar").read_text().splitlines()]
    with manifest.open("a") as file:
        file.write("\n".join(lines) + "\n")
    out = tmp_path / "out"

    def bars_done_and_a_sphere_written() -> bool:
        return len(list((tmp_path / "bars").glob("pose_*.ply"))) == 6 and any(out.glob("pose_*.ply"))

    _interrupt(_start_batch(manifest), bars_done_and_a_sphere_written, "the bars and a first sphere written")
    # The sphere's worker may write its last poses before the signal reaches it: what must hold is whole files and
    # no lock left, whatever it had written (and, in _interrupt, the one line and the exit status).
    assert 0 < len(_no_partial_output(out, "sphere:20000")) <= 6


def _limited_memory() -> None:  # pragma: no cover - runs in the child before exec
    import resource

    # A reader of /dev/zero fails with MemoryError instead of taking the machine's memory.
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


@pytest.mark.parametrize("special", ["device", "fifo"])
def test_a_device_or_a_fifo_as_constraints_fails_that_job_only(special: str, tmp_path: Path) -> None:
    manifest = _family(tmp_path, 3, mesh="bar")
    if special == "fifo":
        os.mkfifo(tmp_path / "pipe.json")
        named, words = "pipe.json", "named pipe (FIFO)"
    else:
        named, words = "/dev/zero", "character device"
    lines = manifest.read_text().splitlines()
    lines[1] = json.dumps({"mesh": "bar", "constraints": named, "output": "out/pose_1.ply"})
    manifest.write_text("\n".join(lines) + "\n")
    # In a child with a memory limit and a deadline: reading /dev/zero or the FIFO must neither exhaust nor hang it.
    proc = subprocess.run([sys.executable, "-m", "arap.cli", "batch", str(manifest), "--workers", "2", "-q"],
                          capture_output=True, text=True, timeout=240, preexec_fn=_limited_memory)
    assert proc.returncode == 1, proc.stderr
    assert f"line 2: cannot read constraints file {tmp_path / named if special == 'fifo' else named}" in proc.stderr
    assert words in proc.stderr and "2 done" in proc.stdout, proc.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["pose_0.ply", "pose_2.ply"]


def test_a_batch_makes_the_output_folders_it_needs(tmp_path: Path) -> None:
    manifest = _family(tmp_path, 3, mesh="bar")
    (tmp_path / "out").rmdir()
    (tmp_path / "file").write_text("a file where a folder is needed")
    lines = manifest.read_text().splitlines()
    lines[1] = lines[1].replace("out/pose_1.ply", "deeper/still/pose_1.ply")
    lines.append(lines[0].replace("out/pose_0.ply", "file/pose_3.ply"))
    manifest.write_text("\n".join(lines) + "\n")
    report = batch(manifest, backend="serial", progress=False)
    assert report.counts() == {"done": 3, "skipped": 0, "failed": 1}, report.failed
    assert (tmp_path / "out/pose_0.ply").is_file() and (tmp_path / "out/pose_2.ply").is_file()
    assert (tmp_path / "deeper/still/pose_1.ply").is_file()
    (failed,) = report.failed
    assert failed.line == 4 and "cannot make the folder" in failed.reason and "not a folder" in failed.reason
    assert failed.extra.get("preflight")


def test_jobs_that_all_fail_alike_fail_before_any_worker_starts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    import arap.batching.backends as backends

    manifest = _family(tmp_path, 3, mesh="bar")
    manifest.write_text(manifest.read_text().replace('"mesh": "bar"', '"mesh": "missing.obj"'))

    def no_pool(*args: object, **kwargs: object) -> None:
        raise AssertionError("a worker pool was started")

    monkeypatch.setattr(backends, "ProcessPoolExecutor", no_pool)
    assert main(["batch", str(manifest), "--workers", "2", "-q"]) == 1
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert "every job fails the pre-flight check, no worker started" in lines[0]
    assert f"cannot read mesh {tmp_path / 'missing.obj'}" in lines[0]
    assert not list((tmp_path / "out").iterdir())
    report = batch(manifest, progress=False)
    assert report.counts()["failed"] == 3 and len(report.preflight_failed) == 3 and not report.started
    assert "no worker started" in report.summary()


def test_killing_a_batch_ends_its_workers(tmp_path: Path) -> None:
    psutil = pytest.importorskip("psutil")
    # Each worker's chunk takes minutes: without the parent watch, its worker would go on long after the kill.
    manifest = _family(tmp_path, 200, mesh="sphere:20000", shift=0.004)
    proc = subprocess.Popen([sys.executable, "-m", "arap.cli", "batch", str(manifest), "--workers", "2", "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    children: list[Any] = []
    try:
        def running() -> bool:
            assert proc.poll() is None, proc.communicate()
            return any((tmp_path / "out").glob("pose_*.ply"))

        wait_until(running, 180, "a first output", interval=0.05)
        children = psutil.Process(proc.pid).children(recursive=True)
        assert children
        proc.kill()  # SIGKILL: the batch cannot stop its workers itself
        proc.wait(timeout=30)

        def gone(p: Any) -> bool:
            try:
                return not p.is_running() or p.status() == psutil.STATUS_ZOMBIE
            except psutil.NoSuchProcess:
                return True

        deadline = scaled(20)
        assert poll_until(lambda: all(gone(p) for p in children), deadline, interval=0.1), \
            f"still running {deadline:g} s after the batch was killed: {[p.pid for p in children if not gone(p)]}"
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in children:
            with contextlib.suppress(psutil.Error):
                p.kill()
    written = len(list((tmp_path / "out").glob("pose_*.ply")))
    assert written < 200


def test_a_job_another_batch_is_running_is_not_run_twice(tmp_path: Path) -> None:
    import fcntl
    import threading

    from arap.batching.locks import lock_path

    manifest = _family(tmp_path, 3, mesh="bar")
    out = tmp_path / "out"
    held = lock_path(out / "pose_1.ply")
    fd = os.open(held, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)  # as a batch running that job holds it
    stale = lock_path(out / "pose_2.ply")
    stale.write_text("999999\n")  # left by a batch that was killed: no one holds it
    reports: list[Any] = []
    second = threading.Thread(target=lambda: reports.append(batch(manifest, backend="serial", progress=False)))
    second.start()
    try:
        wait_until(lambda: (out / "pose_0.ply").exists() and (out / "pose_2.ply").exists(), 120, "the free jobs done")
        assert second.is_alive() and not (out / "pose_1.ply").exists()  # it waits for the other batch
        (out / "pose_1.ply").write_bytes((out / "pose_0.ply").read_bytes())  # the other batch finishes the job
    finally:
        os.unlink(held)
        os.close(fd)
        second.join(scaled(120))
    assert not second.is_alive(), "the second batch went on after the other let its job go"
    (report,) = reports
    assert [o.status for o in report.outcomes] == ["done", "skipped", "done"]
    assert sorted(p.name for p in out.iterdir()) == ["pose_0.ply", "pose_1.ply", "pose_2.ply"]  # locks removed


@pytest.mark.parametrize("moment", ["made", "taken", "waiting"])
def test_an_interrupt_as_a_lock_is_taken_leaves_no_lock_file(moment: str, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import fcntl

    from arap.batching import locks

    # A Ctrl-C handled right after the lock file was made, right after the lock was taken, or while another batch
    # holds it: the first two leave no lock file behind, the third leaves the other batch's.
    output = tmp_path / "pose.ply"
    held = None
    if moment == "waiting":
        held = os.open(locks.lock_path(output), os.O_RDWR | os.O_CREAT)
        fcntl.flock(held, fcntl.LOCK_EX)
    calls: list[str] = []

    def interrupted_once(name: str, real: Any) -> Any:
        def call(*args: Any) -> Any:
            first = name not in calls
            calls.append(name)
            if first and moment == "waiting":
                raise KeyboardInterrupt  # the wait for the other batch's lock, interrupted
            result = real(*args)
            if first:
                raise KeyboardInterrupt
            return result
        return call

    if moment == "made":
        monkeypatch.setattr(locks.os, "open", interrupted_once("open", os.open))
    else:
        monkeypatch.setattr(locks.fcntl, "flock", interrupted_once("flock", fcntl.flock))
    with pytest.raises(KeyboardInterrupt), locks.output_lock(output):
        pytest.fail("the block ran")
    monkeypatch.undo()
    if held is None:
        assert list(tmp_path.iterdir()) == []
    else:
        assert list(tmp_path.iterdir()) == [locks.lock_path(output)]
        os.close(held)


def test_a_quiet_dask_batch_prints_only_its_summary(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    manifest = _family(tmp_path, 2, mesh="bar")
    # A process of its own: the command's logging set-up, not pytest's, decides what reaches stderr.
    proc = subprocess.run([sys.executable, "-m", "arap.cli", "batch", str(manifest), "--backend", "dask", "--workers",
                           "1", "-q"], capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    noise = [line for line in proc.stderr.splitlines() if not line.startswith("arap: compiling")]  # first run only
    assert noise == []
    assert proc.stdout.startswith("arap batch: 2 done") and len(proc.stdout.splitlines()) == 1
