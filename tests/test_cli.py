"""The arap command, run in-process on files under tmp_path."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import arap
from arap.cli import common as cli_common
from arap.cli import deform as cli_deform
from arap.cli import main
from arap.cli.bench import bench_constraints
from arap.io import load_mesh, save_mesh
from arap.meshes.shapes import builtin_mesh


def bar_constraints(path: Path, shift: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fix the bottom of the built-in bar and push its top sideways; writes the JSON file."""
    V, _ = builtin_mesh("bar")
    fixed = np.flatnonzero(V[:, 1] < 0.3)
    handles = np.flatnonzero(V[:, 1] > 4.7)
    targets = V[handles] + [shift, 0.0, 0.0]
    path.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": targets.tolist()}))
    return V, fixed, handles, targets


def bend_constraints_file(path: Path, V: np.ndarray) -> Path:
    """Writes the bend scenario of ``V`` (:func:`arap.constraints.scenarios.bend`) as a constraints file at ``path``."""
    from arap.constraints.scenarios import bend

    s = bend(V)
    path.write_text(json.dumps({"fixed": s.fixed.tolist(), "handles": s.handles.tolist(),
                                "targets": s.targets[len(s.fixed):].tolist()}))
    return path


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
    assert "iteration 1/15" in err and "energy" in err
    assert "ms/iteration" in err and "wrote" in err and "iteration limit reached" in err


def test_deform_runs_until_converged_by_default(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    out = tmp_path / "out.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "converged" in err and "iteration limit" not in err


def test_deform_says_when_the_cap_stopped_it(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    monkeypatch.setattr("arap.options.MAX_ITERATIONS", 3)
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(tmp_path / "o.obj"),
                 "--energy", "spokes"]) == 0
    err = capsys.readouterr().err
    assert "iteration limit reached, not converged (residual" in err and "tolerance 1e-10)" in err
    assert "the shape written is the last iterate; raise --iterations" in err and "spokes_and_rims" in err


def _press_ctrl_c_at_iteration_3(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make ``arap deform`` send itself SIGINT (as Ctrl-C does) after its third iteration."""
    progress = cli_common.Progress.__call__

    def press(self: cli_common.Progress, iteration: int, energy: float) -> None:
        progress(self, iteration, energy)
        if iteration == 3:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(cli_common.Progress, "__call__", press)


def test_ctrl_c_during_deform_writes_the_last_iterate(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The first Ctrl-C stops the solve at the end of its iteration: the iterate reached is written (exit 130) and
    said to be unconverged; the same three iterations run without interruption give the same shape."""
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    _press_ctrl_c_at_iteration_3(monkeypatch)
    out = tmp_path / "stopped.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(out)]) == 130
    err = capsys.readouterr().err
    assert "interrupted after 3 iterations: wrote the last iterate" in err and "not converged" in err
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # Ctrl-C works as before afterwards
    monkeypatch.undo()
    capped = tmp_path / "capped.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(capped), "-n", "3"]) == 0
    np.testing.assert_array_equal(load_mesh(out)[0], load_mesh(capped)[0])


def _press_ctrl_c_at(monkeypatch: pytest.MonkeyPatch, iteration: int) -> None:
    progress = cli_common.Progress.__call__

    def press(self: cli_common.Progress, k: int, energy: float) -> None:
        progress(self, k, energy)
        if k == iteration:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(cli_common.Progress, "__call__", press)


def test_ctrl_c_in_the_last_iteration_leaves_a_complete_output(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C during the iteration that ends the solve anyway (the cap, or convergence) stops nothing: the output
    is the complete result, exit status 0, and it is not called unconverged."""
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    capped = tmp_path / "capped.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(capped), "-n", "3"]) == 0
    converged = tmp_path / "converged.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(converged)]) == 0
    err = capsys.readouterr().err
    assert "converged" in err
    n = int(re.findall(r"arap: (\d+) iterations in", err)[-1])

    _press_ctrl_c_at(monkeypatch, 3)
    out = tmp_path / "out.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(out), "-n", "3"]) == 0
    err = capsys.readouterr().err
    assert "interrupted at the end of the solve: " in err and "was written in full" in err
    assert "interrupted after" not in err and "iteration limit reached, not converged (residual" in err
    np.testing.assert_array_equal(load_mesh(out)[0], load_mesh(capped)[0])
    monkeypatch.undo()

    _press_ctrl_c_at(monkeypatch, n)
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"{n} iterations in" in err and ", converged" in err and "not converged" not in err
    assert "was written in full" in err
    np.testing.assert_array_equal(load_mesh(out)[0], load_mesh(converged)[0])
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_while_the_output_is_written_lets_it_finish(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C that comes once the solve has ended, while or after the output is written: the output is written in
    full and the exit status (0) says so, not 130."""
    import arap.io

    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    save = arap.io.save_mesh

    def save_then_press(*args: object) -> None:
        save(*args)  # type: ignore[arg-type]
        signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(arap.io, "save_mesh", save_then_press)
    out = tmp_path / "out.obj"
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(out), "-n", "3"]) == 0
    err = capsys.readouterr().err
    assert "was written in full" in err and "arap: wrote" in err
    assert load_mesh(out)[0].shape == builtin_mesh("bar")[0].shape
    monkeypatch.undo()

    err_line = cli_deform.err

    def press_after_wrote(text: str) -> None:  # Ctrl-C as the closing lines are printed
        err_line(text)
        if text.startswith("arap: wrote"):
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(cli_deform, "err", press_after_wrote)
    out.unlink()
    assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(out), "-n", "3"]) == 0
    assert "was written in full" in capsys.readouterr().err
    assert load_mesh(out)[0].shape == builtin_mesh("bar")[0].shape
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_ignored_ctrl_c_stays_ignored(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A job started with SIGINT ignored (as a shell starts background jobs) runs to the end; the setting is kept."""
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    _press_ctrl_c_at_iteration_3(monkeypatch)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        assert main(["deform", "bar", "--constraints", str(cfile), "-o", str(tmp_path / "o.obj"), "-n", "6"]) == 0
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


def test_alpha_out_of_range_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    for value in ("-1", "inf", "1e300"):
        assert main(["deform", "bar", "-c", str(cfile), "-o", str(tmp_path / "o.obj"), "--energy",
                     "smooth_rotations", "--alpha", value]) == 2
        assert "alpha must be a number from 0 to 1000" in capsys.readouterr().err
    assert not (tmp_path / "o.obj").exists()


def test_start_from_a_shape_ends_in_its_minimum(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """With a rigid band the energy has several minima and the shape reached depends on the start (here the default
    start ends 0.015 diagonals away, at energy 1.657 against 1.512). ``--start SHAPE`` (e.g. the studio's export)
    continues from that shape and ends where it ends; a shape of another mesh is refused."""
    V, F = builtin_mesh("cactus")
    y = V[:, 1]
    fixed, top = np.flatnonzero(y < np.quantile(y, 0.1)), np.flatnonzero(y > np.quantile(y, 0.9))
    band = np.flatnonzero((y > np.quantile(y, 0.45)) & (y < np.quantile(y, 0.65)))
    c, s = np.cos(1.0), np.sin(1.0)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    centre = V[top].mean(axis=0)
    targets = (V[top] - centre) @ R.T + centre + [0.3, 0.0, 0.0]
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"version": 2, "fixed": fixed.tolist(), "handles": top.tolist(),
                                 "targets": targets.tolist(),
                                 "stiffness": [{"vertices": band.tolist(), "value": "rigid"}]}))
    stiffness = np.ones(len(V))
    stiffness[band] = np.inf
    shape = arap.ArapSolver(V, F, np.r_[fixed, top], stiffness=stiffness).solve(
        np.r_[V[fixed], targets], initial="rest").vertices
    start = tmp_path / "studio-shape.obj"
    save_mesh(start, shape, F)
    out = tmp_path / "out.obj"
    assert main(["deform", "cactus", "-c", str(cfile), "-o", str(out), "--start", str(start)]) == 0
    diagonal = np.linalg.norm(np.ptp(V, axis=0))
    assert np.abs(load_mesh(out)[0] - shape).max() < 1e-6 * diagonal
    save_mesh(tmp_path / "other.obj", *builtin_mesh("bar"))
    assert main(["deform", "cactus", "-c", str(cfile), "-o", str(out), "--start", str(tmp_path / "other.obj")]) == 1
    assert "has 4,314 vertices, but built-in cactus has 5,250: the start must be a shape of the same mesh" in \
        capsys.readouterr().err
    assert main(["deform", "cactus", "-c", str(cfile), "-o", str(out), "--start", "middle"]) == 1
    assert "--start must be one of auto, rest, rigid or a mesh file; middle does not exist" in capsys.readouterr().err


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


@pytest.mark.parametrize("fmt", ["obj", "ply", "off"])
def test_deform_writes_the_files_vertex_order(tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str) -> None:
    """Repair drops an unused vertex and welds a duplicate; the output still has the file's vertices in its order
    (a morph target of the input): the unused one where it was, the duplicate with its twin, the rest deformed as
    the repaired mesh is, and the file's triangles."""
    V, F = builtin_mesh("bar")
    V2 = np.vstack([[[7.0, 7.0, 7.0]], V, V[:1]])  # vertex 0 unused; the last one duplicates vertex 1
    F2 = F + 1
    face = np.flatnonzero(np.any(F2 == 1, axis=1))[0]
    F2[face][F2[face] == 1] = len(V2) - 1  # one face uses the duplicate
    mesh = tmp_path / f"messy.{fmt}"
    save_mesh(mesh, V2, F2)
    fixed = np.flatnonzero(V2[1:-1, 1] < 0.3) + 1
    handles = np.flatnonzero(V2[1:-1, 1] > 4.7) + 1
    targets = V2[handles] + [0.3, 0, 0]
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(), "targets": targets.tolist()}))
    out = tmp_path / f"out.{fmt}"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "3"]) == 0
    assert f"in the vertex order of {mesh} (4,316 vertices)" in capsys.readouterr().err
    U, G = load_mesh(out, repair=False)
    assert len(U) == len(V2)
    np.testing.assert_array_equal(G, F2)
    np.testing.assert_array_equal(U[0], V2[0])
    np.testing.assert_array_equal(U[-1], U[1])
    np.testing.assert_allclose(U[handles], targets, atol=1e-12)
    solved = arap.ArapSolver(V, F, np.r_[fixed, handles] - 1).solve(np.r_[V2[fixed], targets], max_iterations=3)
    np.testing.assert_allclose(U[1:-1], solved.vertices, atol=1e-12)


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
    assert "duplicate vertices" in out and f"components: {len(F):,} (3, 3," in out
    # What loading leaves is one component, not a constrained vertex per triangle.
    assert (f"ready for ARAP: yes ({len(F):,} components as stored; 1 after the repair below, which arap deform "
            "and the studio apply on loading)") in out
    assert f"after repair: {len(V):,} vertices, {len(F):,} faces, 1 component (vertex indices change)" in out
    assert "welded" in out
    assert main(["info", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["n_components"] == len(F) and report["repair"]["n_components"] == 1


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


def test_bench_holds_floating_islands(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A scan with a small island beside the main part: the island holds no constraint of the bend scenario, so it
    is held at rest instead of stopping the bench as a part that nothing pins down."""
    V, F = builtin_mesh("bar")
    tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]) * 0.01 + V.mean(axis=0) + [0, 0, 2 * np.ptp(V[:, 2])]
    path = tmp_path / "islands.obj"
    save_mesh(path, np.vstack([V, tet]), np.vstack([F, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
                                                    + len(V)]))
    assert main(["bench", str(path), "--iterations", "2", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "4 vertices of parts without one held at rest" in out


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


DEEP = "[" * 100_000 + "]" * 100_000
BAD_FILES: dict[str, str | bytes] = {
    "huge_target.json": '{"fixed": [0], "handles": [5], "targets": [[' + "9" * 401 + ", 0, 0]]}",
    "huge_target_300.json": '{"fixed": [0], "handles": [5], "targets": [[' + "9" * 320 + ", 0, 0]]}",
    "far_target.json": '{"fixed": [0], "handles": [5], "targets": [[1e300, 0, 0]]}',
    "giant_int.json": '{"fixed": [' + "1" * 5000 + "]}",
    "huge_index.json": '{"fixed": [' + "9" * 300 + "]}",
    "deep.json": '{"fixed": ' + DEEP + "}",
    "deep_top.json": DEEP,
    "float_index.json": '{"fixed": [1.0]}',
    "bool_index.json": '{"fixed": [true]}',
    "string_list.json": '{"fixed": "0 1 2"}',
    "nested_index.json": '{"fixed": [[0, 1]]}',
    "object_targets.json": '{"handles": [1], "targets": {"x": 1}}',
    "short_target.json": '{"handles": [1], "targets": [[1, 2]]}',
    "string_target.json": '{"handles": [1], "targets": [["1", 2, 3]]}',
    "nan.json": '{"handles": [1], "targets": [[NaN, 2, 3]]}',
    "list.json": "[1, 2, 3]",
    "null.json": "null",
    "empty.json": "",
    "truncated.json": '{"fixed": [1, 2',
    "binary.json": bytes(range(256)) * 4,
    "unknown_key.json": '{"fixd": [1]}',
    "nothing.json": '{"fixed": [], "handles": []}',
    "empty_roi.json": '{"fixed": [0], "roi": []}',
    "negative.json": '{"fixed": [-1]}',
    "repeated.json": '{"fixed": [3, 3]}',
    "both.json": '{"fixed": [3], "handles": [3], "targets": [[0, 0, 0]]}',
    "bad.off": "OFF\nnot numbers\n",
    "junk.obj": bytes(np.random.default_rng(0).integers(0, 256, 3000, dtype=np.uint8)),
    "zero.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
    "huge.obj": "v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nf 1 2 3\n",
    "tiny.obj": "v 0 0 0\nv 1e-300 0 0\nv 0 1e-300 0\nf 1 2 3\n",
    "points.obj": "v 0 0 0\nv 1 0 0\n",
}


@pytest.fixture
def bad_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    bar_constraints(tmp_path / "c.json")
    (tmp_path / "fixed0.json").write_text(json.dumps({"fixed": [0]}))
    (tmp_path / "folder.json").mkdir()
    (tmp_path / "folder.obj").mkdir()
    (tmp_path / "out.obj").write_text("earlier output\n")
    for name, content in BAD_FILES.items():
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
    return tmp_path


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["deform", "missing.obj", "-c", "c.json", "-o", "o.obj"], "missing.obj: no such file"),
        (["deform", "bar", "-c", "missing.json", "-o", "o.obj"], "cannot read constraints file missing.json"),
        (["deform", "bar", "-c", "folder.json", "-o", "o.obj"], "cannot read constraints file folder.json"),
        (["deform", "folder.obj", "-c", "c.json", "-o", "o.obj"], "folder.obj is a folder, not a mesh file"),
        (["deform", "bar", "-c", "c.json", "-o", "folder.obj"], "cannot write folder.obj: it is a folder"),
        (["deform", "bar", "-c", "c.json", "-o", "nowhere/o.obj"], "the folder nowhere does not exist"),
        (["deform", "bar", "-c", "c.json", "-o", "o.xyz"], "unsupported mesh format 'xyz'"),
        (["deform", "bar", "-c", "huge_target.json", "-o", "o.obj"], "integer of 401 digits"),
        (["deform", "bar", "-c", "huge_target_300.json", "-o", "o.obj"], "too large for a coordinate"),
        (["deform", "bar", "-c", "far_target.json", "-o", "o.obj"], "targets lie too far from the mesh"),
        (["deform", "bar", "-c", "giant_int.json", "-o", "o.obj"], "integer of 5,000 digits"),
        (["deform", "bar", "-c", "huge_index.json", "-o", "o.obj"], "out of range [0, 4314) (first: item 0 = 999"),
        (["deform", "bar", "-c", "deep.json", "-o", "o.obj"], "nests lists or objects too deeply"),
        (["deform", "bar", "-c", "deep_top.json", "-o", "o.obj"], "nests lists or objects too deeply"),
        (["deform", "bar", "-c", "float_index.json", "-o", "o.obj"], "integer vertex indices; item 0 is 1.0"),
        (["deform", "bar", "-c", "bool_index.json", "-o", "o.obj"], "integer vertex indices; item 0 is True"),
        (["deform", "bar", "-c", "string_list.json", "-o", "o.obj"], "must be a list of vertex indices, got str"),
        (["deform", "bar", "-c", "nested_index.json", "-o", "o.obj"], "item 0 is [0, 1]"),
        (["deform", "bar", "-c", "object_targets.json", "-o", "o.obj"], "list of [x, y, z] points, got dict"),
        (["deform", "bar", "-c", "short_target.json", "-o", "o.obj"], "item 0 must be [x, y, z] numbers"),
        (["deform", "bar", "-c", "string_target.json", "-o", "o.obj"], "item 0 must be [x, y, z] numbers"),
        (["deform", "bar", "-c", "nan.json", "-o", "o.obj"], "contains NaN, which is not valid JSON"),
        (["deform", "bar", "-c", "list.json", "-o", "o.obj"], "must be a JSON object, got list"),
        (["deform", "bar", "-c", "null.json", "-o", "o.obj"], "must be a JSON object, got NoneType"),
        (["deform", "bar", "-c", "empty.json", "-o", "o.obj"], "is not valid JSON"),
        (["deform", "bar", "-c", "truncated.json", "-o", "o.obj"], "is not valid JSON"),
        (["deform", "bar", "-c", "binary.json", "-o", "o.obj"], "is not UTF-8 text"),
        (["deform", "bar", "-c", "unknown_key.json", "-o", "o.obj"], "unknown constraint keys ['fixd']"),
        (["deform", "bar", "-c", "nothing.json", "-o", "o.obj"], "no vertex is constrained"),
        (["deform", "bar", "-c", "empty_roi.json", "-o", "o.obj"], "roi is empty"),
        (["deform", "bar", "-c", "negative.json", "-o", "o.obj"], "out of range"),
        (["deform", "bar", "-c", "repeated.json", "-o", "o.obj"], "more than once"),
        (["deform", "bar", "-c", "both.json", "-o", "o.obj"], "vertex 3 is in both fixed and handles"),
        (["deform", "bad.off", "-c", "fixed0.json", "-o", "o.obj"], "cannot parse"),
        (["deform", "junk.obj", "-c", "fixed0.json", "-o", "o.obj"], "not an OBJ file: it holds binary data"),
        (["deform", "zero.obj", "-c", "fixed0.json", "-o", "o.obj"], "OBJ vertex indices start at 1"),
        (["deform", "huge.obj", "-c", "fixed0.json", "-o", "o.obj"], "coordinates are too large"),
        (["deform", "tiny.obj", "-c", "fixed0.json", "-o", "o.obj"], "coordinates are too small"),
        (["deform", "points.obj", "-c", "fixed0.json", "-o", "o.obj"], "no faces"),
        (["deform", "bar", "-c", "c.json", "-o", "o.obj", "-n", "-1"], "--iterations must be >= 0"),
        (["deform", "bar", "-c", "c.json", "-o", "o.obj", "-t", "nan"], "--tolerance must be >= 0"),
        (["info", "bad.off"], "cannot parse"),
        (["info", "junk.obj"], "binary data"),
        (["info", "folder.obj"], "folder.obj is a folder, not a mesh file"),
        (["bench", "sphere:lots"], "bad sphere size"),
        (["info", "sphere:-5"], "fewer vertices than the smallest sphere"),
        (["bench", "bar", "-n", "0"], "must be >= 1"),
        (["bench", "huge.obj"], "coordinates are too large"),
    ],
)
def test_bad_input_exits_1_with_one_line(bad_files: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                                         message: str) -> None:
    assert main(argv) == 1
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("arap: error: ") and message in err[0]
    assert "Traceback" not in captured.err + captured.out
    assert not (bad_files / "o.obj").exists()
    assert (bad_files / "out.obj").read_text() == "earlier output\n"
    assert sorted(p.name for p in bad_files.iterdir() if p.name.startswith(".")) == []


def test_real_process_prints_no_traceback(bad_files: Path) -> None:
    """In a separate interpreter (default recursion limit, real stderr): the 401-digit target and the 100,000-deep
    nesting end with one line and status 1."""
    for name in ("huge_target.json", "deep.json", "giant_int.json"):
        proc = subprocess.run([sys.executable, "-m", "arap.cli", "deform", "bar", "-c", name, "-o", "o.obj"],
                              capture_output=True, text=True, timeout=120, cwd=bad_files)
        assert proc.returncode == 1, proc.stderr
        assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    proc = subprocess.run([sys.executable, "-m", "arap.cli", "deform", "bar"], capture_output=True, text=True,
                          timeout=120, cwd=bad_files)
    assert proc.returncode == 2 and "usage:" in proc.stderr and "Traceback" not in proc.stderr


def test_unconstrained_part_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, F = builtin_mesh("bar")
    two = tmp_path / "two.obj"
    save_mesh(two, np.vstack([V, V + np.array([3.0, 0, 0])]), np.vstack([F, F + len(V)]))
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": [0]}))
    assert main(["deform", str(two), "-c", str(cfile), "-o", str(tmp_path / "o.obj")]) == 1
    assert "touches no constrained vertex" in capsys.readouterr().err


def test_unconstrained_part_is_named_in_the_file_numbering(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Repair drops the file's first five vertices (used by no face): the vertices of the part that touches no
    constraint are named as the constraints file names them, not by their index in the repaired mesh."""
    V, F = builtin_mesh("bar")
    two = tmp_path / "two.obj"
    stray = np.full((5, 3), 7.0)
    save_mesh(two, np.vstack([stray, V, V + np.array([3.0, 0, 0])]), np.vstack([F, F + len(V)]) + len(stray))
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": [len(stray)]}))  # the first bar's first vertex
    assert main(["deform", str(two), "-c", str(cfile), "-o", str(tmp_path / "o.obj")]) == 1
    err = capsys.readouterr().err
    second = list(range(len(stray) + len(V), len(stray) + len(V) + 5))  # the second bar's first vertices
    assert f"(e.g. vertices {second} of the file)" in err, err


def test_info_reports_inconsistent_orientation(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    V, F = builtin_mesh("cylinder")
    F = F.copy()
    F[:7] = F[:7, ::-1]
    path = tmp_path / "flipped.ply"
    save_mesh(path, V, F)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "defects: 7 faces oriented against their neighbours" in out
    assert "ready for ARAP: yes" in out


def test_usage_errors_and_help(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert main(["deform", "bar"]) == 2
    assert main(["deform", "bar", "-c", "c.json", "-o", "o.obj", "-n", "many"]) == 2
    assert main(["info"]) == 2
    assert "--output" in capsys.readouterr().err  # the constraints may come as a file or by position
    assert main(["deform", "bar", "-o", "o.obj"]) == 1
    assert "-c FILE.json" in capsys.readouterr().err
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in ("deform", "info", "bench", "studio"):
        assert command in out


@pytest.mark.parametrize("command", ["deform", "info", "bench", "studio"])
def test_help_shows_percent_signs_once(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    """A description is printed as written (argparse expands ``%%`` only in argument help)."""
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert "%%" not in out
    if command == "bench":
        assert "lowest 10% along the longest axis" in " ".join(out.split())


def test_studio_calls_the_server(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import arap.server

    calls: list[tuple[object, dict[str, object]]] = []

    def fake_serve(mesh: object = None, host: str = "127.0.0.1", port: int = 8000, open_browser: bool = False,
                   *, max_sessions: int = 0, allow_origins: object = None, on_ready: object = None,
                   token: object = None, max_export_bytes: int = 0) -> None:
        calls.append((mesh, {"host": host, "port": port, "open_browser": open_browser,
                             "max_sessions": max_sessions, "allow_origins": allow_origins,
                             "max_export_bytes": max_export_bytes}))
        assert callable(on_ready)
        on_ready(f"http://{host}:{port}/")

    monkeypatch.setattr(arap.server, "serve", fake_serve, raising=False)
    assert main(["studio", "cactus", "--port", "8765", "--max-sessions", "4",
                 "--allow-origin", "http://localhost:5173"]) == 0
    assert calls == [("cactus", {"host": "127.0.0.1", "port": 8765, "open_browser": False, "max_sessions": 4,
                                 "allow_origins": ["http://localhost:5173"], "max_export_bytes": 2**31})]
    assert "http://127.0.0.1:8765/" in capsys.readouterr().out


def test_deform_explains_a_negative_energy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from arap.meshes.shapes import scan_blob

    V, F = scan_blob(n=400)
    mesh = tmp_path / "blob.off"
    save_mesh(mesh, V, F)
    cfile = bend_constraints_file(tmp_path / "c.json", V)
    out = tmp_path / "out.off"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "3", "--energy", "spokes"]) == 0
    err = capsys.readouterr().err
    assert "energy -" in err and "below 0" in err and "docs/solver.md" in err
    # The default energy is never negative and needs no note.
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "3"]) == 0
    err = capsys.readouterr().err
    assert "energy -" not in err and "below 0" not in err


def test_deform_warns_of_nearly_flat_faces_with_the_spokes_energies(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:

    V, F = builtin_mesh("bar")
    a, b, c = F[0]
    cap = 0.5 * (V[a] + V[b]) + 1e-4 * (V[c] - 0.5 * (V[a] + V[b]))  # a point just off the middle of edge ab
    V2 = np.vstack([V, cap])
    m = len(V)
    F2 = np.vstack([F[1:], [[a, b, m], [b, c, m], [c, a, m]]])
    mesh = tmp_path / "capped.obj"
    save_mesh(mesh, V2, F2)
    cfile = bend_constraints_file(tmp_path / "c.json", V2)
    out = tmp_path / "out.obj"
    for energy in ("spokes", "smooth_rotations"):
        assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "2", "--energy", energy]) == 0
        assert "1 faces are nearly flat (an angle above 179°)" in capsys.readouterr().err
    for options in ([], ["--energy", "spokes", "--weights", "clamped"]):
        assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "2", *options]) == 0
        assert "nearly flat" not in capsys.readouterr().err


def test_info_says_vertex_indices_change_only_when_repair_renumbers(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    V, F = builtin_mesh("bar")
    path = tmp_path / "dup.obj"
    save_mesh(path, V, np.concatenate([F, F[:5]]))  # duplicate faces: dropping them keeps every vertex number
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "repair would: dropped 5 duplicate faces" in out
    assert f"after repair: {len(V):,} vertices, {len(F):,} faces, 1 component (vertex indices stay)" in out
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["repair"]["renumbers_vertices"] is False
    path = tmp_path / "unused.obj"
    save_mesh(path, np.concatenate([[[9.0, 9.0, 9.0]], V]), F + 1)  # an unused first vertex: all shift by one
    assert main(["info", str(path)]) == 0
    assert "faces, 1 component (vertex indices change)" in capsys.readouterr().out
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["repair"]["renumbers_vertices"] is True


def test_start_shapes_that_are_not_of_the_mesh_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--start``: a shape with NaN coordinates is refused naming the option and the vertex (also when a welded copy
    of that vertex is finite), a file of the same vertex count with other triangles is refused, an unreadable one
    is named as the start; an STL written by ``arap deform`` (triangles only) is a start like the OBJ it came from."""
    V, F = builtin_mesh("bar")
    V2 = np.vstack([V, V[:1]])  # the last vertex duplicates vertex 0; a face uses it
    F2 = F.copy()
    face = np.flatnonzero(np.any(F2 == 0, axis=1))[0]
    F2[face][F2[face] == 0] = len(V)
    mesh = tmp_path / "mesh.obj"
    save_mesh(mesh, V2, F2)
    cfile = tmp_path / "c.json"
    bar_constraints(cfile)
    out = tmp_path / "out.obj"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "5", "-q"]) == 0
    U, _ = load_mesh(out, repair=False)

    def start_error(U_start: np.ndarray, F_start: np.ndarray, name: str) -> str:
        path = tmp_path / name
        save_mesh(path, U_start, F_start) if np.isfinite(U_start).all() else path.write_text(
            "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in U_start.tolist())
            + "".join(f"f {a} {b} {c}\n" for a, b, c in (F_start + 1).tolist()))
        assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(tmp_path / "o.obj"), "--start", str(path)]) == 1
        return capsys.readouterr().err

    for vertex in (100, 0):  # vertex 0 has a finite welded copy
        bad = U.copy()
        bad[vertex] = np.nan
        assert f"--start {tmp_path / 'nan.obj'}: vertex {vertex} has NaN or infinite coordinates" in start_error(
            bad, F2, "nan.obj")
    assert "has the vertex count of" in start_error(U, np.roll(F2, 7), "other.obj")  # other triangles
    (tmp_path / "folder.obj").mkdir()
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "--start", str(tmp_path / "folder.obj")]) == 1
    assert "--start: " in capsys.readouterr().err
    stl = tmp_path / "shape.stl"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(stl), "-n", "5", "-q"]) == 0
    from_obj, from_stl = tmp_path / "from_obj.obj", tmp_path / "from_stl.obj"
    for start, result in ((out, from_obj), (stl, from_stl)):
        assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(result), "-n", "3", "-q", "--start",
                     str(start)]) == 0
    diagonal = np.linalg.norm(np.ptp(V, axis=0))
    np.testing.assert_allclose(load_mesh(from_stl)[0], load_mesh(from_obj)[0], atol=1e-6 * diagonal)


def test_deform_says_when_it_cannot_keep_the_files_vertex_order(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """An unused vertex with NaN coordinates cannot be written: the output has the repaired mesh's vertices, and
    the command says so (naming the vertex) instead of leaving the numbering change unsaid."""
    V, F = builtin_mesh("bar")
    mesh = tmp_path / "nan.obj"
    mesh.write_text("v nan nan nan\n" + "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in (F + 2).tolist()))
    cfile = tmp_path / "c.json"
    fixed, handles = np.flatnonzero(V[:, 1] < 0.3) + 1, np.flatnonzero(V[:, 1] > 4.7) + 1
    cfile.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(),
                                 "targets": (V[handles - 1] + [0.5, 0, 0]).tolist()}))
    out = tmp_path / "out.obj"
    assert main(["deform", str(mesh), "-c", str(cfile), "-o", str(out), "-n", "2"]) == 0
    err = capsys.readouterr().err
    assert f"not in the vertex order of {mesh}: its vertex 0, used by no face, has NaN" in err
    assert len(load_mesh(out, repair=False)[0]) == len(V)


def test_the_command_modules_import_only_common() -> None:
    """No import cycle in arap.cli, imports inside functions included: the package imports the command modules,
    they import arap.cli.common only, and common imports none of them."""
    import ast

    import arap.cli

    folder = Path(arap.cli.__file__).parent
    found: dict[str, set[str]] = {}
    for path in folder.glob("*.py"):
        imported: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module == "arap.cli":
                imported |= {f"arap.cli.{a.name}" if (folder / f"{a.name}.py").exists() else "arap.cli"
                             for a in node.names}
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("arap.cli."):
                imported.add(str(node.module))
            elif isinstance(node, ast.Import):
                imported |= {a.name for a in node.names if a.name == "arap.cli" or a.name.startswith("arap.cli.")}
        found[path.stem] = imported
    commands = set(found) - {"__init__", "__main__", "common"}
    assert {"deform", "animate", "batch", "info", "bench", "studio", "warmup"} <= commands
    assert found["__init__"] == {f"arap.cli.{name}" for name in commands | {"common"}}
    assert found["common"] == set()
    for name in commands:
        assert found[name] == {"arap.cli.common"}, name
    assert found["__main__"] == {"arap.cli"}


def test_deform_warns_when_no_vertex_is_free(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A region of interest made only of constrained vertices (as the old reference example had it) moves the handles
    alone: the command says so even with -q, and stays silent when vertices are free."""
    V, _ = builtin_mesh("bar")
    cons = tmp_path / "c.json"
    cons.write_text(json.dumps({"fixed": [0, 1, 2], "handles": [40, 41],
                                "targets": (V[[40, 41]] + 0.1).tolist(), "roi": [0, 1, 2, 40, 41]}))
    assert main(["deform", "bar", "-c", str(cons), "-o", str(tmp_path / "o.obj"), "-q"]) == 0
    assert "no vertex of the region of interest is free to move" in capsys.readouterr().err
    cons.write_text(json.dumps({"fixed": [0, 1, 2], "handles": [40, 41], "targets": (V[[40, 41]] + 0.1).tolist()}))
    assert main(["deform", "bar", "-c", str(cons), "-o", str(tmp_path / "o.obj"), "-q"]) == 0
    assert "free to move" not in capsys.readouterr().err


@pytest.mark.parametrize("model", ["obj", "glb"])
def test_deform_keeps_a_textured_models_attributes(model: str, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A textured OBJ or GLB deformed into its own format keeps texture coordinates, materials and groups bit for
    bit, with the positions of the geometry-only result; into another format it gets the geometry and a note."""
    from arap.io.assets import load_asset
    from tests.io.asset_models import cube_glb, cube_obj

    mesh = (cube_obj if model == "obj" else cube_glb)(tmp_path)
    src = load_asset(mesh)
    V = src.vertices
    fixed = np.flatnonzero(V[:, 1] <= V[:, 1].min() + 1e-9)
    corner = V[np.argmax(V @ [1.0, 1.0, 0.5])]
    handles = np.flatnonzero(np.abs(V - corner).max(axis=1) <= 1e-9)
    cons = tmp_path / "c.json"
    cons.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(),
                                "targets": (V[handles] + [0.3, 0.2, 0.0]).tolist()}))
    out = tmp_path / f"out.{model}"
    assert main(["deform", str(mesh), "-c", str(cons), "-o", str(out), "-q"]) == 0
    plain = tmp_path / "out.ply"
    assert main(["deform", str(mesh), "-c", str(cons), "-o", str(plain)]) == 0
    assert "gets the geometry only" in capsys.readouterr().err
    got = load_asset(out)
    np.testing.assert_array_equal(got.faces, src.faces)
    assert got.materials == src.materials and got.groups == src.groups
    if src.uvs is not None:
        assert got.uvs is not None and np.array_equal(got.uvs, src.uvs)
    assert got.textures == src.textures
    sm = src.solve_mesh()  # the library's way: weld the seams, solve, split again
    indices, targets = sm.constraints(np.concatenate([fixed, handles]),
                                      np.concatenate([V[fixed], V[handles] + [0.3, 0.2, 0.0]]))
    expected = sm.file_vertices(arap.ArapSolver(sm.V, sm.F, indices).solve(targets).vertices)
    np.testing.assert_allclose(got.vertices, expected, atol=1e-6)
    assert np.abs(got.vertices[handles] - (V[handles] + [0.3, 0.2, 0.0])).max() <= 1e-6
    assert len(load_mesh(plain)[0]) > 0


def test_deform_reads_a_glb_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``arap deform`` parses a textured GLB input once: the mesh it solves and the asset it writes come from the
    same reading."""
    import arap.io.gltf_asset
    from arap.io.assets import load_asset
    from tests.io.asset_models import cube_glb

    mesh = cube_glb(tmp_path)
    V = load_asset(mesh).vertices
    fixed = np.flatnonzero(V[:, 1] <= V[:, 1].min() + 1e-9)
    handles = np.flatnonzero(V[:, 1] >= V[:, 1].max() - 1e-9)
    cons = tmp_path / "c.json"
    cons.write_text(json.dumps({"fixed": fixed.tolist(), "handles": handles.tolist(),
                                "targets": (V[handles] + [0.2, 0.0, 0.0]).tolist()}))
    reads: list[str] = []
    real = arap.io.gltf_asset.read_gltf_asset

    def counting(data: bytes, name: str, *args: Any, **kwargs: Any) -> Any:
        reads.append(name)
        return real(data, name, *args, **kwargs)

    monkeypatch.setattr(arap.io.gltf_asset, "read_gltf_asset", counting)
    assert main(["deform", str(mesh), "-c", str(cons), "-o", str(tmp_path / "out.glb"), "-q"]) == 0
    assert reads == [str(mesh)]


@pytest.mark.parametrize("suffix", ["", "/"])
def test_an_output_folder_is_named_as_one(tmp_path: Path, capsys: pytest.CaptureFixture[str], suffix: str) -> None:
    code = main(["deform", "bar", "--fix", "y<0.1", "--handle", "y>4.9", "--move", "0.5,0,0",
                 "-o", str(tmp_path) + suffix])
    assert code == 1
    err = capsys.readouterr().err
    assert "is a folder; give the output file's name" in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []
