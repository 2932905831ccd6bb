"""A NumPy reader for plain triangle OBJ files (large scans), used before the general parser.

It accepts only files made of ``v x y z`` lines, triangle ``f`` lines with positive indices (``a``, ``a/t``,
``a//n`` or ``a/t/n``), ``vn``/``vt``/``s`` lines, comments and blank lines; anything else (polygons, negative
indices, vertex colours, groups, objects, materials) is left to the general parser, which also writes the error
messages. Lines are classified by their first bytes with NumPy and the runs of vertex and face lines are read as
whole blocks (no loop over lines in Python); a file with indented lines or many interleaved runs goes through a
line-by-line loop.
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

_SPACE, _TAB, _LF, _CR = 32, 9, 10, 13
_BLANKS = {k: bytes.maketrans(k + b"\t\r\n", b"    ") for k in (b"v", b"f")}
_MAX_RUNS = 64
_OTHER, _VERTEX, _FACE, _BAD = 0, 1, 2, 3


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
    buf = np.frombuffer(data, dtype=np.uint8)
    if len(buf) < 2:
        return None
    starts = np.concatenate(([0], np.flatnonzero(buf[:-1] == _LF) + 1))
    ends = np.append(starts[1:], len(buf))
    last = len(buf) - 1
    first, second, third = (buf[np.minimum(starts + k, last)] for k in range(3))
    if np.any((first == _SPACE) | (first == _TAB)):
        return _parse_by_lines(data)
    gap2 = ((second == _SPACE) | (second == _TAB)) & (starts + 1 < ends)
    gap3 = ((third == _SPACE) | (third == _TAB)) & (starts + 2 < ends)
    kind = np.full(len(starts), _BAD, dtype=np.uint8)
    kind[(first == _LF) | (first == _CR) | (first == ord("#"))] = _OTHER
    kind[(first == ord("s")) & gap2] = _OTHER
    kind[(first == ord("v")) & ((second == ord("n")) | (second == ord("t"))) & gap3] = _OTHER
    kind[(first == ord("v")) & gap2] = _VERTEX
    kind[(first == ord("f")) & gap2] = _FACE
    if np.any(kind == _BAD):
        return None
    vertex_text = _block(data, kind == _VERTEX, starts, ends, b"v")
    face_text = _block(data, kind == _FACE, starts, ends, b"f")
    if vertex_text is None or face_text is None:  # interleaved lines, or a stray letter for the general parser
        return _parse_by_lines(data)
    if not vertex_text or not face_text:
        return None
    if b"/" in face_text:
        face_text = _SLASHES.sub(b"", face_text)
    if vertex_text.translate(None, b"0123456789eE+-. ") or face_text.translate(None, b"0123456789 "):
        return None
    nv = int(np.count_nonzero(kind == _VERTEX))
    nf = int(np.count_nonzero(kind == _FACE))
    coords = np.fromstring(vertex_text, dtype=np.float64, sep=" ")
    indices = np.fromstring(face_text, dtype=np.int64, sep=" ")
    if len(coords) != 3 * nv or len(indices) != 3 * nf:
        return None
    if indices.min() < 1 or indices.max() > nv:
        return None
    return coords.reshape(-1, 3), (indices - 1).reshape(-1, 3)


def _block(data: bytes, mask: NDArray[np.bool_], starts: NDArray[np.intp], ends: NDArray[np.intp],
           keyword: bytes) -> bytes | None:
    """The lines ``mask`` (all starting with ``keyword``) joined, the keywords and line breaks blanked; b"" for no
    line, None for more than ``_MAX_RUNS`` separate runs of such lines or a keyword letter elsewhere in them."""
    edges = np.flatnonzero(np.diff(mask.astype(np.int8), prepend=0, append=0))
    if not len(edges):
        return b""
    if len(edges) > 2 * _MAX_RUNS:
        return None
    parts = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        chunk = data[starts[a]:ends[b - 1]]
        if chunk.count(keyword) != b - a:
            return None
        parts.append(chunk.translate(_BLANKS[keyword]))
    return b" ".join(parts)


def _parse_by_lines(data: bytes) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """:func:`parse_plain_obj` one line at a time (files with indented lines)."""
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
    coords = np.fromstring(vertex_text, dtype=np.float64, sep=" ")
    indices = np.fromstring(face_text, dtype=np.int64, sep=" ")
    if len(coords) != 3 * len(vertex_lines) or len(indices) != 3 * len(face_lines):
        return None
    if indices.min() < 1 or indices.max() > len(vertex_lines):
        return None
    return coords.reshape(-1, 3), (indices - 1).reshape(-1, 3)
