"""Machine-readable output of ``arap info`` / ``arap bench``, and what the CLI needs installed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from arap.cli import main
from arap.io import save_mesh
from arap.meshes.shapes import builtin_mesh

SERVER_STACK = ("starlette", "uvicorn", "websockets")


def test_info_json_matches_the_mesh(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "cylinder", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["n_vertices"] == 6490 and report["closed"] is True and report["n_components"] == 1
    assert report["ready"] is True and report["not_ready_reason"] is None
    assert report["repair"] == {"possible": True, "changes": [], "n_vertices": 6490, "n_faces": report["n_faces"],
                                "renumbers_vertices": False, "n_components": 1}
    assert len(report["bbox_min"]) == 3 and report["diagonal"] > 0

    # A triangle soup: every face its own component, and repair welds it back to the bar.
    V, F = builtin_mesh("bar")
    path = tmp_path / "bar.stl"
    save_mesh(path, V, F)
    assert main(["info", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["mesh"] == str(path)
    assert report["n_vertices"] == 3 * len(F) and report["n_components"] == len(F)
    assert report["duplicate_vertices"] == 3 * len(F) - len(V)
    assert report["repair"]["n_vertices"] == len(V) and report["repair"]["changes"]


def test_info_json_reports_defects(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")
    assert main(["info", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["degenerate_faces"] == 1 and report["ready"] is False
    assert "zero area" in report["not_ready_reason"]
    assert report["problems"][0] == "1 zero-area faces"
    assert report["repair"]["changes"] == ["dropped 1 zero-area faces", "dropped 1 vertices used by no face"]
    assert report["repair"]["n_faces"] == 1


def test_bench_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sphere:3000", "--iterations", "2", "--repeats", "2", "--json"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)  # nothing but the JSON object on stdout
    assert captured.err == ""
    assert report["n_vertices"] == 2892 and report["iterations"] == 2 and report["repeats"] == 2
    assert len(report["iteration_ms_runs"]) == 2 and report["iteration_ms"] > 0
    assert set(report["split_ms"]) == {"local", "rhs", "solve"}
    assert sum(report["split_ms"].values()) <= max(report["iteration_ms_runs"]) * 1.0001
    assert report["energy_last"] <= report["energy_first"]
    assert isinstance(report["kernels"]["compiled"], bool) and report["kernels"]["seconds"] >= 0


def test_studio_without_its_extra_names_it(monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "uvicorn", None)  # import uvicorn now raises ImportError
    assert main(["studio", "--port", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("arap: error: ") and "uvicorn" in err and "pip install 'arap[studio]'" in err


def test_library_and_cli_do_not_import_the_server_stack(tmp_path: Path) -> None:
    code = (
        "import sys, arap, arap.cli\n"
        "V, F = arap.builtin_mesh('bar')\n"
        "arap.ArapSolver(V, F, [0, 1, 2]).solve(V[[0, 1, 2]], max_iterations=1)\n"
        "assert arap.cli.main(['info', 'bar', '--json']) == 0\n"
        f"print(sorted(m for m in sys.modules if m.split('.')[0] in {SERVER_STACK!r} or m.startswith('arap.server')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True,
                         cwd=tmp_path).stdout
    assert out.strip().splitlines()[-1] == "[]"
