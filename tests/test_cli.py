"""The arap command, run in-process on files under tmp_path."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.cli import bench_constraints, main
from arap.io import load_mesh, save_mesh
from arap.shapes import builtin_mesh


def bar_constraints(path: Path, shift: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fix the bottom of the built-in bar and push its top sideways; writes the JSON file."""
    V, _ = builtin_mesh("bar")
    fixed = np.flatnonzero(V[:, 1] < 0.3)
    handles = np.flatnonzero(V[:, 1] > 4.7)
    targets = V[handles] + [shift, 0.0, 0.0]
    path.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": targets.tolist()}))
    return V, fixed, handles, targets


@pytest.mark.parametrize("fmt", ["obj", "ply"])
def test_deform_builtin_bar(tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str) -> None:
    cfile = tmp_path / "c.json"
    V, fixed, handles, targets = bar_constraints(cfile)
    out = tmp_path / f"out.{fmt}"
    code = main(["deform", "bar", "--constraints", str(cfile), "-o", str(out), "--iterations", "15"])
    assert code == 0
    U, F = load_mesh(out)
    assert U.shape == V.shape and F.shape == builtin_mesh("bar")[1].shape
    np.testing.assert_allclose(U[fixed], V[fixed], atol=1e-12)
    np.testing.assert_allclose(U[handles], targets, atol=1e-12)
    # The middle of the bar moved sideways but less than the top, and lengths are roughly kept.
    middle = np.abs(V[:, 1] - 2.5) < 0.05
    assert 0.05 < (U[middle, 0] - V[middle, 0]).mean() < 0.95
    assert np.ptp(U[:, 1]) == pytest.approx(5.0, rel=0.1)
    err = capsys.readouterr().err
    assert "iteration 1/15" in err and "energy" in err and "change" in err
    assert "ms/iteration" in err and "wrote" in err


def test_deform_file_mesh_quiet_with_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, F = builtin_mesh("bar")
    mesh = tmp_path / "bar.off"
    save_mesh(mesh, V, F)
    cfile = tmp_path / "c.json"
    V, fixed, handles, targets = bar_constraints(cfile, shift=0.5)
    out = tmp_path / "out.off"
    code = main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "5", "--energy", "spokes_and_rims",
                 "--weights", "uniform", "--quiet"])
    assert code == 0
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
    U, _ = load_mesh(out)
    np.testing.assert_allclose(U[handles], targets, atol=1e-12)
    np.testing.assert_allclose(U[fixed], V[fixed], atol=1e-12)


def test_deform_renumbers_constraints_after_repair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # An OBJ with one duplicated vertex: repair welds it and shifts the later indices down by one.
    V, F = builtin_mesh("bar")
    V2 = np.vstack([V[:1], V])
    F2 = F + 1
    F2[0, np.flatnonzero(F[0] == 0)[:1]] = 0  # one face uses the duplicate
    mesh = tmp_path / "dup.obj"
    save_mesh(mesh, V2, F2)
    fixed = np.flatnonzero(V2[:, 1] < 0.3)[1:]  # skip the duplicate itself
    handles = np.flatnonzero(V2[:, 1] > 4.7)
    targets = V2[handles] + [0.3, 0, 0]
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": targets.tolist()}))
    out = tmp_path / "out.obj"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "3"]) == 0
    U, _ = load_mesh(out)
    assert len(U) == len(V)
    np.testing.assert_allclose(U[handles - 1], targets, atol=1e-12)
    assert "renumbered" in capsys.readouterr().err


def test_info_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "cylinder"]) == 0
    out = capsys.readouterr().out
    assert "vertices: 6,490" in out and "closed" in out and "components: 1" in out
    assert "ready for ARAP: yes" in out and "repair: nothing to do" in out
    V, F = builtin_mesh("bar")
    path = tmp_path / "bar.stl"
    save_mesh(path, V, F)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"vertices: {3 * len(F):,}" in out  # the raw soup
    assert "duplicate vertices" in out
    assert f"ready for ARAP: yes (each of the {len(F):,} components needs a constrained vertex" in out
    assert f"after repair: {len(V):,} vertices" in out and "welded" in out


def test_info_reports_defects(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "1 zero-area faces" in out
    assert "ready for ARAP: no (1 faces have zero area" in out
    assert "repair would: dropped 1 zero-area faces; dropped 1 vertices used by no face" in out


def test_bench_prints_a_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sphere:3000", "--iterations", "2", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    for label in ("precompute", "per iteration", "right-hand side", "solve", "energy"):
        assert label in out
    assert "2,892 vertices" in out  # 10 · 17² + 2


def test_bench_constraints_scenario() -> None:
    V, _ = builtin_mesh("bar")
    fixed, handles, targets = bench_constraints(V)
    assert V[fixed, 1].max() < V[handles, 1].min()
    assert abs(len(fixed) - 0.1 * len(V)) < 0.05 * len(V)
    assert targets.shape == (len(handles), 3)
    # Rigid motion of the handle set: pairwise distances kept.
    d0 = np.linalg.norm(V[handles][:, None] - V[handles][None], axis=2)
    d1 = np.linalg.norm(targets[:, None] - targets[None], axis=2)
    np.testing.assert_allclose(d1, d0, atol=1e-12)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["deform", "missing.obj", "-c", "c.json", "-o", "o.obj"], "missing.obj: no such file"),
        (["deform", "bar", "-c", "missing.json", "-o", "o.obj"], "cannot read constraints file"),
        (["deform", "bar", "-c", "c.json", "-o", "o.xyz"], "unsupported mesh format 'xyz'"),
        (["deform", "bar", "-c", "bad.json", "-o", "o.obj"], "out of range"),
        (["deform", "bar", "-c", "c.json", "-o", "o.obj", "-n", "-1"], "--iterations must be >= 0"),
        (["info", "bad.off"], "cannot parse"),
        (["bench", "sphere:lots"], "bad sphere size"),
    ],
)
def test_errors_exit_2_with_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    monkeypatch.chdir(tmp_path)
    bar_constraints(tmp_path / "c.json")
    (tmp_path / "bad.json").write_text(json.dumps({"fixed": [10**9]}))
    (tmp_path / "bad.off").write_text("OFF\nnot numbers\n")
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("arap: error: ") and message in err[0]
    assert "Traceback" not in err[0]
    assert not (tmp_path / "o.obj").exists()


def test_unconstrained_part_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, F = builtin_mesh("bar")
    two = tmp_path / "two.obj"
    save_mesh(two, np.vstack([V, V + np.array([3.0, 0, 0])]), np.vstack([F, F + len(V)]))
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": [0]}))
    assert main(["deform", str(two), "-c", str(cfile), "-o", str(tmp_path / "o.obj")]) == 2
    assert "touches no constrained vertex" in capsys.readouterr().err


def test_usage_errors_and_help(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert main(["deform", "bar"]) == 2
    assert "--constraints" in capsys.readouterr().err
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in ("deform", "info", "bench", "studio"):
        assert command in out


def test_studio_calls_the_server(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import arap.server

    calls: list[tuple[object, dict[str, object]]] = []

    def fake_serve(mesh: object = None, host: str = "127.0.0.1", port: int = 8000, open_browser: bool = False,
                   *, on_ready: object = None) -> None:
        calls.append((mesh, {"host": host, "port": port, "open_browser": open_browser}))
        assert callable(on_ready)
        on_ready(f"http://{host}:{port}/")

    monkeypatch.setattr(arap.server, "serve", fake_serve, raising=False)
    assert main(["studio", "cactus", "--port", "8765"]) == 0
    assert calls == [("cactus", {"host": "127.0.0.1", "port": 8765, "open_browser": False})]
    assert "http://127.0.0.1:8765/" in capsys.readouterr().out


def test_deform_explains_a_negative_energy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from arap.scenarios import bend
    from arap.shapes import scan_blob

    V, F = scan_blob(n=400)
    mesh = tmp_path / "blob.off"
    save_mesh(mesh, V, F)
    s = bend(V)
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": s.fixed.tolist(), "handles": s.handles.tolist(),
                                 "targets": s.targets[len(s.fixed):].tolist()}))
    out = tmp_path / "out.off"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "3", "--energy", "spokes"]) == 0
    err = capsys.readouterr().err
    assert "energy -" in err and "below 0" in err and "README" in err
    # The default energy is never negative and needs no note.
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "3"]) == 0
    err = capsys.readouterr().err
    assert "energy -" not in err and "below 0" not in err
