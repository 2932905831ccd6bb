"""``arap warp``: the puppet warp of a picture file with a pins file, written as a PNG with alpha.

The pins file is JSON: ``{"pins": [[x, y], ...], "targets": [[x, y], ...]}`` in pixels (x to the right, y down);
``targets`` may be shorter than ``pins`` or hold ``null`` for pins that stay where they are; ``"angles"`` (optional,
one per pin: degrees or ``null``) makes pins hold their surroundings turned by that angle (``PuppetWarp``'s
``angles``). The studio's constraints documents name triangles of its own mesh of the picture instead of pixels:
``arap warp`` says so rather than reading one.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import os
from pathlib import Path
from typing import Any

from arap.cli.common import err, writable_destination
from arap.errors import ArapError, ConstraintError

__all__ = ["OUTPUTS", "add_parser", "read_pin_angles", "read_pins", "run_warp"]

OUTPUTS = (".png", ".glb", ".obj")
"""The outputs by extension: the warped picture, or the warped mesh textured with the picture."""


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap warp`` and its options to the subcommands of ``arap``."""
    p = commands.add_parser("warp", help="puppet-warp a picture with pins",
                            description="Move pins on a picture's shape (its opaque pixels, or the whole frame "
                                        "without alpha) and bend the rest as rigidly as it can (Igarashi et al. "
                                        "2005); write the warped picture as a PNG with alpha.")
    p.add_argument("image", metavar="IMAGE", help="picture file (PNG, JPEG, WebP, ...; at most 64 megapixels)")
    p.add_argument("--pins", required=True, metavar="PINS.json",
                   help='JSON {"pins": [[x, y], ...], "targets": [[x, y] or null, ...]} in pixels (x right, y '
                        'down); pins without a target hold; optional "angles": [degrees or null, ...], the angle '
                        "each pin holds its surroundings turned by (counter-clockwise as seen)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png",
                   help="the warped picture (PNG with alpha); or OUT.glb, the warped mesh textured with the picture; "
                        "or OUT.obj, the same with OUT.mtl and the picture as OUT.texture.png beside it")
    p.add_argument("--spacing", type=float, default=None, metavar="PX",
                   help="mesh edge length in pixels (default: about 5,000 vertices over the whole picture)")
    p.add_argument("--density", type=int, default=None, metavar="N",
                   help="without --spacing: about N mesh vertices when the shape fills the picture (default: 5000)")
    p.add_argument("--mode", choices=("rigid", "normal", "distort"), default="rigid",
                   help="rigid: as rigid as possible (default); normal: parts may grow and shrink a little (a "
                        "stretch by c keeps about its cube root); distort: as similar as possible, parts grow and "
                        "shrink freely")
    p.add_argument("--fit", action="store_true", help="enlarge the canvas to hold the warped shape")
    p.add_argument("--alpha-threshold", type=int, default=0, metavar="A",
                   help="the shape is the pixels whose alpha is above A, 0 to 254 (default: 0)")
    p.set_defaults(func=run_warp)


def read_pins(path: str | os.PathLike[str]) -> tuple[list[Any], list[Any] | None]:
    """The pins and targets of a pins file (checked in shape by :func:`arap.puppet.warp.pin_targets`).

    Raises
    ------
    ConstraintError
        Unreadable, not JSON, or not an object with a ``pins`` list (and a ``targets`` list or nothing); a
        constraints document (the studio's, whose pins are triangles of its mesh) is named as such.
    """
    doc = _read_pins_file(path)
    return doc["pins"], doc.get("targets")


def read_pin_angles(path: str | os.PathLike[str]) -> list[Any] | None:
    """The ``"angles"`` of a pins file (one per pin, degrees or None; checked by :class:`arap.puppet.PuppetWarp`),
    or None.

    Raises
    ------
    ConstraintError
        What :func:`read_pins` refuses, or ``angles`` that is not a list.
    """
    angles = _read_pins_file(path).get("angles")
    if angles is not None and not isinstance(angles, list):
        raise ConstraintError(f'{path}: "angles" must be a list of one angle (degrees) or null per pin')
    return angles


def _read_pins_file(path: str | os.PathLike[str]) -> dict[str, Any]:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConstraintError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConstraintError(f"{path}: cannot read the pins file ({exc})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConstraintError(f"{path}: not JSON ({exc})") from None
    if isinstance(doc, dict) and "pins" not in doc and any(k in doc for k in ("points", "fixed", "handles")):
        raise ConstraintError(f'{path}: this is a constraints document (the studio\'s Save constraints, or arap '
                              'deform\'s): its pins are triangles of the studio\'s mesh of the picture, not pixels; '
                              'arap warp reads {"pins": [[x, y], ...], "targets": [...], "angles": [...]} in pixels')
    if not isinstance(doc, dict) or not isinstance(doc.get("pins"), list):
        raise ConstraintError(f'{path}: expected an object {{"pins": [[x, y], ...], "targets": [...]}}')
    targets = doc.get("targets")
    if targets is not None and not isinstance(targets, list):
        raise ConstraintError(f'{path}: "targets" must be a list of [x, y] or null')
    return doc


def _check_destination(path: str) -> None:
    """Refuse an output that is not a PNG or cannot be written, before any work."""
    if Path(path).suffix.lower() not in OUTPUTS:
        raise ArapError(f"{path}: the warped picture is written as PNG (OUT.png), its mesh as OUT.glb or OUT.obj")
    writable_destination(path, ArapError)


def _write_mesh(path: str, mesh: Any) -> list[str]:
    """Write the textured mesh as GLB, or as OBJ with its MTL file and texture beside it; the files written."""
    from arap.io.atomic import write_atomic

    out = Path(path)
    if out.suffix.lower() == ".glb":
        write_atomic(out, mesh.export(file_type="glb"))
        return [str(out)]
    import trimesh.exchange.obj

    mtl = f"{out.stem}.mtl"
    texture = f"{out.stem}.texture.png"
    text, extra = trimesh.exchange.obj.export_obj(mesh, include_texture=True, return_texture=True, mtl_name=mtl)
    images = [name for name in extra if name != mtl]
    material = extra[mtl]
    for name in images:
        material = material.replace(name.encode(), texture.encode())
    written = []
    for name, data in [(texture, extra[images[0]]), (mtl, material)]:
        write_atomic(out.with_name(name), data)
        written.append(str(out.with_name(name)))
    write_atomic(out, text)
    return [str(out), *written]


def run_warp(args: argparse.Namespace) -> int:
    """``arap warp``: read, warp, write; the exit status."""
    from arap.io.atomic import write_atomic
    from arap.puppet.imagemesh import DEFAULT_DENSITY
    from arap.puppet.picture import read_picture
    from arap.puppet.warp import PuppetWarp

    _check_destination(args.output)
    if args.spacing is not None and not (args.spacing > 0 and math.isfinite(args.spacing)):
        raise ArapError(f"--spacing must be a positive number of pixels, got {args.spacing}")
    pins, targets = read_pins(args.pins)
    angles = read_pin_angles(args.pins)
    picture = read_picture(args.image)
    density = DEFAULT_DENSITY if args.density is None else args.density
    puppet = PuppetWarp(picture, pins, spacing=args.spacing, density=density, mode=args.mode,
                        alpha_threshold=args.alpha_threshold, angles=angles)
    vertices = puppet.deform(targets)
    try:
        if Path(args.output).suffix.lower() != ".png":
            written = _write_mesh(args.output, puppet.textured_mesh(vertices))
            err(f"arap: wrote {', '.join(written)} ({len(vertices):,} vertices)")
            return 0
        out = puppet.render(vertices, fit=args.fit)
        from PIL import Image

        buffer = io.BytesIO()
        Image.fromarray(out, "RGBA").save(buffer, format="PNG")
        write_atomic(args.output, buffer.getvalue())
    except OSError as exc:
        raise ArapError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    err(f"arap: wrote {args.output} ({out.shape[1]}x{out.shape[0]})")
    return 0
