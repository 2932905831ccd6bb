"""Make the pictures of the examples gallery (``docs/examples/``) from the examples' own code.

Each example page holds one complete Python program (its first ```` ```python ```` block). This runs that program
as written, in an empty temporary folder, and pictures the shape it started from and the shape it made with
:func:`arap.show`, both from one camera framed on the two shapes together, so that the pictures compare. What to
picture is read from the names the program leaves (``V``, ``F``, ``result``, the constraints): :data:`EXAMPLES`
says which, per example. A page's text, code and pictures therefore cannot disagree: change the code, run this, and
the pictures follow.

Written per example NAME: ``NAME-before.png`` and ``NAME-after.png`` (``--width`` x ``--height`` each), and
``NAME.png``, the two side by side (the gallery's thumbnail; the README shows the bend's). The animation adds
``animation-frames.png``, five frames in a row.

Run: ``python tools/gallery.py [NAME ...] [--out docs/images/gallery] [--width 320] [--height 300]`` (no names: all).
"""

from __future__ import annotations

import argparse
import io
import os
import re
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PAGES = ROOT / "docs" / "examples"
OUT = ROOT / "docs" / "images" / "gallery"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
RIGID_COLOUR = "#5b8fd9"
BASE_COLOUR = "#c7c9cf"


@dataclass
class Scene:
    """What one example's pictures show: the mesh at rest and deformed, and the keyword arguments of
    :func:`arap.show` for both (marks, colours; a picture may override them in ``before`` or ``after``)."""

    V: np.ndarray
    F: np.ndarray
    deformed: np.ndarray
    marks: dict[str, Any] = field(default_factory=dict)
    before: dict[str, Any] = field(default_factory=dict)
    after: dict[str, Any] = field(default_factory=dict)
    frames: list[np.ndarray] = field(default_factory=list)


def _bend(ns: dict[str, Any]) -> Scene:
    return Scene(ns["V"], ns["F"], ns["result"].vertices, {"constraints": ns["c"]})


def _rigid(ns: dict[str, Any]) -> Scene:
    colors = np.tile(np.array([int(BASE_COLOUR[k:k + 2], 16) for k in (1, 3, 5)]), (len(ns["V"]), 1))
    colors[ns["rigid"]] = [int(RIGID_COLOUR[k:k + 2], 16) for k in (1, 3, 5)]
    return Scene(ns["V"], ns["F"], ns["result"].vertices,
                 {"fixed": ns["fixed"], "handles": ns["top"], "colors": colors.astype(np.uint8)})


def _points(ns: dict[str, Any]) -> Scene:
    F = ns["F"]
    return Scene(ns["V"], F, ns["result"].vertices, {"fixed": ns["ends"], "handles": np.unique(F[ns["faces"]])})


def _textured(ns: dict[str, Any]) -> Scene:
    """Each triangle in its own corners (no shared vertices), coloured from the texture at its UV centroid."""
    from PIL import Image

    asset, twisted = ns["asset"], ns["twisted"]
    image = np.asarray(Image.open(io.BytesIO(next(iter(twisted.textures.values())))).convert("RGB"))
    h, w = image.shape[:2]
    uv = twisted.uvs.mean(axis=1)
    rows = np.clip((uv[:, 1] % 1.0 * h).astype(int), 0, h - 1)
    cols = np.clip((uv[:, 0] % 1.0 * w).astype(int), 0, w - 1)
    colors = np.repeat(image[rows, cols], 3, axis=0)
    F = asset.faces
    split = np.arange(3 * len(F)).reshape(-1, 3)
    corner = F.reshape(-1)
    return Scene(asset.vertices[corner], split, twisted.vertices[corner], {"colors": colors})


def _ends(ns: dict[str, Any]) -> Scene:
    return Scene(ns["V"], ns["F"] if "F" in ns else ns["T"], ns["result"].vertices,
                 {"fixed": ns["left"], "handles": ns["right"]})


def _animation(ns: dict[str, Any]) -> Scene:
    frames = ns["animation"].vertices
    marks = {"fixed": ns["fixed"], "handles": ns["top"]}
    picks = np.linspace(0, len(frames) - 1, 5).round().astype(int)
    return Scene(frames[0], ns["F"], frames[-1], marks, frames=[frames[k] for k in picks])


#: The examples, in the gallery's order: page name (``docs/examples/NAME.md``) and how to picture its program's
#: names.
EXAMPLES: dict[str, Callable[[dict[str, Any]], Scene]] = {
    "bend": _bend,
    "twist": _bend,
    "rigid-parts": _rigid,
    "point-handles": _points,
    "textured-asset": _textured,
    "animation": _animation,
    "planar-strip": _ends,
    "solid-bar": _ends,
}


def example_code(name: str, pages: Path = PAGES) -> str:
    """The program of an example page: its first Python block."""
    page = pages / f"{name}.md"
    blocks = BLOCK.findall(page.read_text(encoding="utf-8"))
    if not blocks:
        raise ValueError(f"{page}: no ```python block")
    return blocks[0]


def run_example(name: str, pages: Path = PAGES) -> dict[str, Any]:
    """Run an example's program as written, in an empty temporary folder; returns the names it left."""
    code = example_code(name, pages)
    namespace: dict[str, Any] = {"__name__": "__example__"}
    here = os.getcwd()
    with tempfile.TemporaryDirectory(prefix=f"arap-gallery-{name}-") as folder:
        os.chdir(folder)
        try:
            exec(compile(code, f"docs/examples/{name}.md", "exec"), namespace)
        finally:
            os.chdir(here)
    return namespace


def render(name: str, out: Path = OUT, *, width: int = 320, height: int = 300,
           pages: Path = PAGES) -> list[Path]:
    """Run example ``name`` and write its pictures into ``out``; returns the paths written."""
    import arap
    from arap.render.camera import fit_camera
    from arap.render.picture import Picture

    scene = EXAMPLES[name](run_example(name, pages))
    shapes = [X if X.shape[1] == 3 else np.column_stack([X, np.zeros(len(X))])  # planar meshes lie in z = 0
              for X in (scene.V, scene.deformed, *scene.frames)]
    view = {"azimuth": 0.0, "elevation": 0.0} if all(np.ptp(X[:, 2]) == 0 for X in shapes) else {}
    camera = fit_camera(np.vstack(shapes), width, height, **view)
    before = arap.show(scene.V, scene.F, camera=camera, **(scene.marks | scene.before))
    after = arap.show(scene.deformed, scene.F, camera=camera, **(scene.marks | scene.after))
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for suffix, picture in (("-before", before), ("-after", after),
                            ("", Picture(np.hstack([before.pixels, after.pixels])))):
        path = out / f"{name}{suffix}.png"
        picture.save(path)
        written.append(path)
    if scene.frames:
        strip_camera = fit_camera(np.vstack(shapes), 128, height, **view)
        pixels = [arap.show(U, scene.F, camera=strip_camera, **scene.marks).pixels for U in scene.frames]
        path = out / f"{name}-frames.png"
        Picture(np.hstack(pixels)).save(path)
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", metavar="NAME", help=f"examples to picture (default: all: "
                                                                 f"{', '.join(EXAMPLES)})")
    parser.add_argument("--out", type=Path, default=OUT, help="folder for the pictures (default: %(default)s)")
    parser.add_argument("--width", type=int, default=320, help="width of each picture (default: %(default)s)")
    parser.add_argument("--height", type=int, default=300, help="height of each picture (default: %(default)s)")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in EXAMPLES]
    if unknown:
        parser.error(f"unknown example {', '.join(unknown)}; choose from {', '.join(EXAMPLES)}")
    for name in args.names or list(EXAMPLES):
        for path in render(name, args.out, width=args.width, height=args.height):
            print(f"{path} ({path.stat().st_size:,} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
