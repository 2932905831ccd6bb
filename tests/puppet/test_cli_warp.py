"""``arap warp``: the PNG it writes is the library's warp; bad input gives one line, exit status 1, and no file."""

from __future__ import annotations

import io
import json
import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import arap
from arap.cli import main
from tests.puppet.pictures import bar, ring

PINS = {"pins": [[30, 100], [100, 100], [170, 100]], "targets": [[40, 70], None, [160, 70]]}


def _png(path: Path, img: np.ndarray) -> Path:
    Image.fromarray(img).save(path)
    return path


def _pins(path: Path, doc: object) -> Path:
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_the_png_written_is_the_librarys_warp(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    img = bar()
    image = _png(tmp_path / "bar.png", img)
    out = tmp_path / "out.png"
    assert main(["warp", str(image), "--pins", str(_pins(tmp_path / "pins.json", PINS)), "-o", str(out),
                 "--spacing", "6"]) == 0
    written = np.asarray(Image.open(out))
    assert written.shape == (200, 200, 4)
    expected = arap.warp(img, PINS["pins"], PINS["targets"], spacing=6)
    assert np.abs(written.astype(float) - expected).mean() <= 1.0
    assert np.abs(written.astype(float) - img).mean() > 1.0  # it did warp
    assert (arap.warp(image, PINS["pins"], PINS["targets"], spacing=6) == expected).all()  # a path reads the same
    assert "wrote" in capsys.readouterr().err


def test_fit_makes_a_larger_picture(tmp_path: Path) -> None:
    image = _png(tmp_path / "bar.png", bar())
    pins = _pins(tmp_path / "p.json", {"pins": [[30, 100], [170, 100]], "targets": [None, [250, 100]]})
    out = tmp_path / "out.png"
    assert main(["warp", str(image), "--pins", str(pins), "-o", str(out), "--spacing", "8", "--fit"]) == 0
    assert Image.open(out).size[0] > 230


def _huge_png_header(path: Path, w: int, h: int) -> Path:
    """A PNG whose header says w × h, with a few bytes of pixels (never decoded)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    data = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))
    path.write_bytes(data)
    return path


def _truncated_png(path: Path) -> Path:
    buffer = io.BytesIO()
    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 255, (120, 120, 4), dtype=np.uint8)).save(buffer, format="PNG")
    path.write_bytes(buffer.getvalue()[: len(buffer.getvalue()) // 2])
    return path


@pytest.mark.parametrize(("make", "pins", "message"), [
    (lambda d: _huge_png_header(d / "big.png", 9000, 8000), PINS, "72.0 megapixels; the puppet warp takes at most 64"),
    (lambda d: _huge_png_header(d / "bomb.png", 20000, 20000), PINS, "larger than 64 megapixels"),
    (lambda d: _png(d / "empty.png", np.zeros((50, 50, 4), dtype=np.uint8)), PINS, "shape is empty"),
    (lambda d: _png(d / "ring.png", ring(200, 30, 80)), {"pins": [[100, 100]]},
     r"pin 0 at \(100, 100\) is outside the picture's shape"),
    (lambda d: _truncated_png(d / "cut.png"), PINS, "corrupt or truncated"),
    (lambda d: (d / "notes.png").write_text("not a picture") and d / "notes.png", PINS, "not a picture file"),
    (lambda d: d / "missing.png", PINS, "no such file"),
    (lambda d: _png(d / "bar.png", bar()), {"pin": []}, 'expected an object {"pins"'),
    (lambda d: _png(d / "bar.png", bar()), {"pins": [[30, 100]], "targets": [[1, 2], [3, 4]]},
     "2 targets for 1 pins"),
])
def test_bad_input_gives_one_line_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                      make: object, pins: object, message: str) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    image = make(folder)  # type: ignore[operator]
    pins_file = _pins(folder / "pins.json", pins)
    out = tmp_path / "out"
    out.mkdir()
    assert main(["warp", str(image), "--pins", str(pins_file), "-o", str(out / "o.png")]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("arap: error:")
    assert re.search(message, lines[0]), lines[0]
    assert list(out.iterdir()) == []


def test_an_output_that_is_not_a_png_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    image = _png(tmp_path / "bar.png", bar())
    assert main(["warp", str(image), "--pins", str(_pins(tmp_path / "p.json", PINS)), "-o",
                 str(tmp_path / "o.jpg")]) == 1
    assert "written as PNG (OUT.png), its mesh as OUT.glb or OUT.obj" in capsys.readouterr().err
    assert not (tmp_path / "o.jpg").exists()


@pytest.mark.parametrize("name", ["mesh.glb", "mesh.obj"])
def test_the_warped_mesh_is_written_with_its_texture(tmp_path: Path, name: str) -> None:
    import trimesh

    img = bar()
    image = _png(tmp_path / "bar.png", img)
    out = tmp_path / name
    assert main(["warp", str(image), "--pins", str(_pins(tmp_path / "pins.json", PINS)), "-o", str(out),
                 "--spacing", "8"]) == 0
    puppet = arap.PuppetWarp(img, PINS["pins"], spacing=8)
    U = puppet.deform(PINS["targets"])
    loaded = trimesh.load(out, force="mesh", process=False)
    assert len(loaded.vertices) == len(U)
    assert np.abs(loaded.vertices[:, :2] - np.column_stack([U[:, 0], 200 - U[:, 1]])).max() < 1e-3
    uv = np.asarray(loaded.visual.uv)
    assert np.abs(uv - np.column_stack([puppet.mesh.vertices[:, 0] / 200,
                                        1 - puppet.mesh.vertices[:, 1] / 200])).max() < 1e-5
    if name.endswith(".obj"):
        assert sorted(p.name for p in tmp_path.iterdir()) == ["bar.png", "mesh.mtl", "mesh.obj",
                                                              "mesh.texture.png", "pins.json"]
        assert (np.asarray(Image.open(tmp_path / "mesh.texture.png")) == img).all()


def test_the_modes_offered_are_the_librarys() -> None:
    from arap.cli import build_parser
    from arap.puppet.warp import MODES

    commands = next(a for a in build_parser()._actions if a.dest == "command")
    warp = commands.choices["warp"]  # type: ignore[index]
    mode = next(a for a in warp._actions if a.dest == "mode")
    assert tuple(mode.choices) == MODES  # type: ignore[arg-type]
