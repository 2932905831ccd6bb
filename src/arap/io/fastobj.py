"""A NumPy reader for plain triangle OBJ files (large scans), used before the general parser.

It accepts only files made of ``v x y z`` lines, triangle ``f`` lines with positive indices (``a``, ``a/t``,
``a//n`` or ``a/t/n``), ``vn``/``vt``/``s`` lines, comments and blank lines; anything else (polygons, negative
indices, vertex colours, groups, objects, materials) is left to the general parser, which also writes the error
messages.
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import NDArray

__all__ = ["parse_plain_obj"]

_ALLOWED = (b"#", b"vn ", b"vt ", b"s ", b"vn\t", b"vt\t", b"s\t")
_SLASHES = re.compile(rb"/\S*")
_NUMBERS = re.compile(rb"[0-9eE+\-. \t]*")
_INTEGERS = re.compile(rb"[0-9 \t]*")


def parse_plain_obj(data: bytes) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """Vertices and faces of a plain triangle OBJ file, or None when it is not one.

    Parameters
    ----------
    data : bytes
        The file's content.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
        Zero-based, in file order.
        Or None: the file holds something this reader does not handle.
    """
    vertex_lines: list[bytes] = []
    face_lines: list[bytes] = []
    for raw in data.splitlines():
        line = raw.strip()
        if line.startswith((b"v ", b"v\t")):
            vertex_lines.append(line[2:])
        elif line.startswith((b"f ", b"f\t")):
            face_lines.append(line[2:])
        elif line and not line.startswith(_ALLOWED):
            return None
    if not vertex_lines or not face_lines:
        return None
    vertex_text = b" ".join(vertex_lines)
    face_text = _SLASHES.sub(b"", b" ".join(face_lines))
    if not (_NUMBERS.fullmatch(vertex_text) and _INTEGERS.fullmatch(face_text)):
        return None
    coords = np.fromstring(vertex_text.decode("ascii"), dtype=np.float64, sep=" ")
    indices = np.fromstring(face_text.decode("ascii"), dtype=np.int64, sep=" ")
    if len(coords) != 3 * len(vertex_lines) or len(indices) != 3 * len(face_lines):
        return None
    if indices.min() < 1 or indices.max() > len(vertex_lines):
        return None
    return coords.reshape(-1, 3), (indices - 1).reshape(-1, 3)
