"""``arap info MESH --png OUT.png`` (with ``-c`` marking a constraints file), run in-process like tests/test_cli.py."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from arap.cli import main
from arap.meshes.shapes import builtin_mesh
from arap.render.png import SIGNATURE
from tests.png_files import decode_png
from tests.render.pixels import colour_share

V, F = builtin_mesh("bar")
BOTTOM = np.flatnonzero(V[:, 1] < 0.5)
TOP = np.flatnonzero(V[:, 1] > 4.5)


def test_info_png_writes_a_readable_picture(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bar.png"
    assert main(["info", "bar", "--png", str(out), "--width", "120", "--height", "90"]) == 0
    captured = capsys.readouterr()
    assert "ready for ARAP: yes" in captured.out  # the description is printed as without --png
    assert f"wrote {out} (120x90)" in captured.err
    data = out.read_bytes()
    assert data.startswith(SIGNATURE)
    pixels = decode_png(data)
    assert pixels.shape == (90, 120, 3)
    assert (pixels != pixels[0, 0]).any(axis=2).mean() > 0.05  # the bar is in it
    assert colour_share(pixels, "#e64c45") == 0


def test_info_png_marks_a_constraints_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfile = tmp_path / "c.json"
    cfile.write_text(json.dumps({"fixed": BOTTOM.tolist(), "handles": TOP.tolist(),
                                 "targets": (V[TOP] + [1.0, 0, 0]).tolist()}))
    out = tmp_path / "marked.png"
    assert main(["info", "bar", "--png", str(out), "-c", str(cfile), "--json", "--azimuth", "0",
                 "--elevation", "0"]) == 0
    assert json.loads(capsys.readouterr().out)["mesh"] == "built-in bar"  # --json output stays one JSON object
    pixels = decode_png(out.read_bytes())
    assert colour_share(pixels, "#e64c45") > 0.005 and colour_share(pixels, "#ff9e1a") > 0.005
    rows = np.flatnonzero(((pixels[:, :, 0] > 150) & (pixels[:, :, 1] < 120)).any(axis=1))
    assert rows.min() > 0.6 * len(pixels)  # the anchors at the bottom of the upright bar


@pytest.mark.parametrize(("argv", "message"), [
    (["--png", "{tmp}"], "cannot write {tmp}: it is a folder, not a file"),
    (["--png", "{tmp}/missing/a.png"], "cannot write {tmp}/missing/a.png: the folder {tmp}/missing does not exist"),
    (["--png", "{tmp}/fifo.png"], "cannot write {tmp}/fifo.png: it is a named pipe (FIFO), not a regular file"),
    (["-c", "{tmp}/c.json"], "-c/--constraints marks the constraints in the picture: give --png OUT.png too"),
    (["--png", "{tmp}/a.png", "-c", "{tmp}/c.json"],
     "fixed has 1 indices out of range [0, 4314) (first: item 0 = 4314)"),
    (["--png", "{tmp}/a.png", "--width", "5000"], "width must be from 1 to 4096 pixels, got 5000"),
    (["--png", "{tmp}/a.png", "--azimuth", "nan"], "azimuth must be a finite number of degrees, got nan"),
])
def test_info_png_refuses_bad_paths_and_values_in_one_line(argv: list[str], message: str, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "fifo.png")
    (tmp_path / "c.json").write_text(json.dumps({"fixed": [len(V)]}))
    args = [a.format(tmp=tmp_path) for a in argv]
    if "fifo" in message and not hasattr(os, "mkfifo"):
        pytest.skip("needs FIFOs (POSIX)")
    assert main(["info", "bar", *args]) == 1
    err = capsys.readouterr().err
    assert err == f"arap: error: {message.format(tmp=tmp_path)}\n"
    assert not (tmp_path / "a.png").exists()


def test_info_png_size_options_are_checked_by_argparse(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "bar", "--png", str(tmp_path / "a.png"), "--width", "0"]) == 2
    assert "argument --width: must be at least 1, got 0" in capsys.readouterr().err
