"""Batches: outputs equal arap deform's on every backend, factorisations are shared, finished outputs are skipped,
a broken job fails alone with its manifest line, and an interrupted batch leaves no partial output."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import arap
from arap.batching import batch, read_manifest
from arap.batching.jobs import chunks_for
from arap.cli import main
from tests.waiting import poll_until

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


def test_interrupted_batch_leaves_no_partial_output(tmp_path: Path) -> None:
    manifest = _family(tmp_path, 24, mesh="sphere:20000", shift=0.02)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "arap.cli", "batch", str(manifest), "--workers", "2", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, start_new_session=True)
    try:
        def first_written() -> bool:
            assert proc.poll() is None, proc.communicate()
            return any((tmp_path / "out").glob("pose_*.ply"))

        poll_until(first_written, 120, interval=0.05)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C reaches the whole process group, workers included
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    written = sorted((tmp_path / "out").iterdir())
    assert 0 < len(written) < 24
    V, F = arap.builtin_mesh("sphere:20000")
    for path in written:
        assert path.suffix == ".ply", f"left behind: {path.name}"
        U, G = arap.load_mesh(path)
        assert U.shape == V.shape and np.array_equal(G, F)
    report = batch(manifest, workers=2, progress=False)  # and the next run finishes the rest
    assert report.counts() == {"done": 24 - len(written), "skipped": len(written), "failed": 0}
