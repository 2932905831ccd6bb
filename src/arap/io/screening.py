"""Screening of mesh file bytes before the format parsers see them.

Text (OBJ, OFF, ASCII STL, the PLY header) is decoded as UTF-8 or, failing that, as Latin-1: every byte is a Latin-1
character and the numbers are ASCII either way, so a comment or a solid name in a legacy encoding costs nothing.
Binary junk is refused with a clear message, as are OBJ faces naming vertex 0 (OBJ counts from 1), which the parser
would silently wrap to the last vertex. The vertex count is read from the header (OFF, PLY, binary STL) or counted
(OBJ lines, ASCII STL vertices) in a fraction of the parse time.
"""

from __future__ import annotations

import codecs
import logging
import re

import numpy as np

import arap.io.formats as formats
from arap.errors import MeshFormatError, MeshTooLargeError

__all__ = ["announced_faces", "check_obj_short_faces", "check_obj_zero_index", "check_size", "obj_vertex_count",
           "off_face_count", "off_vertex_count", "plain_obj_lines", "ply_face_count", "ply_vertex_count", "screen",
           "screen_obj", "screen_off", "screen_ply", "screen_stl", "stl_vertex_count", "vertex_count"]

logger = logging.getLogger(__name__)

#: Bytes that do not occur in text files (ASCII control characters other than tab, line breaks and form feed).
_CONTROL_BYTES = bytes(sorted(set(range(32)) - {9, 10, 11, 12, 13})) + b"\x7f"
#: Largest share of control bytes tolerated in a text file (a stray one is not worth refusing a mesh for).
_CONTROL_SHARE = 0.01
_PLY_ELEMENT = re.compile(rb"^[ \t]*element[ \t]+(\w+)[ \t]+(\d+)", re.M)
_STL_HEADER = 84
_STL_RECORD = 50


def _binary_stl_triangles(data: bytes) -> int | None:
    """Triangle count of a binary STL (its size matches the count in its header), else None."""
    if len(data) < _STL_HEADER:
        return None
    count = int.from_bytes(data[80:84], "little")
    return count if len(data) == _STL_HEADER + _STL_RECORD * count else None


def _obj_zero_index_line(data: bytes) -> int | None:
    """The first line (from 1) of an OBJ face naming vertex 0, which OBJ does not have (it counts from 1, or back
    from -1), or None. Vectorised: a token ``0`` (alone or before ``/``) on a line that starts with ``f``."""
    a = np.frombuffer(b"\n" + data + b"\n", dtype=np.uint8)

    def blank(x: np.ndarray) -> np.ndarray:
        return (x == 32) | (x == 9)  # space, tab

    zero = np.flatnonzero(a == ord("0"))
    after = a[zero + 1]
    zero = zero[blank(a[zero - 1]) & (blank(after) | (after == ord("/")) | (after == 10) | (after == 13)
                                      | (after == ord("#")))]
    if not len(zero):
        return None
    newlines = np.flatnonzero(a == 10)
    line = np.searchsorted(newlines, zero)
    start = newlines[line - 1] + 1
    while True:  # leading blanks before the keyword
        indented = blank(a[start]) & (start < zero)
        if not indented.any():
            break
        start = start + indented
    face = (a[start] == ord("f")) & blank(a[start + 1])
    hashes = np.flatnonzero(a == ord("#"))
    if len(hashes):
        before = np.searchsorted(hashes, zero) - 1
        face &= ~((before >= 0) & (hashes[np.maximum(before, 0)] >= start))  # inside a comment
    return int(line[face][0]) if face.any() else None


def _as_text(data: bytes, what: str, label: str) -> bytes:
    """UTF-8 bytes of a text file: decoded as UTF-8, or as Latin-1 when it is not UTF-8 (a byte sequence such as
    a Latin-1 comment); refuses binary data."""
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    control = len(data) - len(data.translate(None, _CONTROL_BYTES))
    if b"\x00" in data or control > _CONTROL_SHARE * len(data):
        raise MeshFormatError(f"{label} is not {what} file: it holds binary data "
                              f"({control:,} of its {len(data):,} bytes are control characters)")
    if data.isascii():  # the common case, checked without decoding
        return data
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        logger.debug("%s is not UTF-8 (%s); reading it as Latin-1", label, exc.reason)
        return data.decode("latin-1").encode("utf-8")
    return data


_INDENT = re.compile(rb"^[ \t]+", re.MULTILINE)
_COMMENT = re.compile(rb"#[^\n]*")


def plain_obj_lines(data: bytes) -> bytes:
    """The OBJ text without blanks at the start of its lines and without comments (line numbers unchanged).

    trimesh's OBJ parser drops indented face lines without a word once the file has a polygon (``  f 2 5 6``
    before ``f 5 6 4 2`` loads one triangle fewer, and an indented quad is lost), and fails on a comment after a
    face (``f 1 2 3 # cap``).

    Example
    -------
    >>> plain_obj_lines(b"v 0 0 0\\n  f 1 2 3  # cap\\n\\tf 1 2 3 4\\n")
    b'v 0 0 0\\nf 1 2 3  \\nf 1 2 3 4\\n'
    """
    if _COMMENT.search(data):
        data = _COMMENT.sub(b"", data)
    return _INDENT.sub(b"", data) if _INDENT.search(data) else data


_SHORT_FACE = re.compile(rb"^[ \t]*f(?:[ \t]+[^ \t\r\n#]+){0,2}[ \t]*(?:#[^\n]*)?\r?$", re.MULTILINE)
"""An OBJ face line naming fewer than three vertices (a comment may follow)."""


def check_obj_short_faces(data: bytes, label: str) -> None:
    """Refuse an OBJ file with a face of fewer than three vertices, which the parser would drop without a word: a
    file cut inside its last face line leaves one.

    Raises
    ------
    MeshFormatError

    Example
    -------
    >>> check_obj_short_faces(b"v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf 1 2 3\\nf 1 2", "cut.obj")
    Traceback (most recent call last):
    ...
    arap.errors.MeshFormatError: cut.obj, line 5: a face with fewer than 3 vertices ('f 1 2'; the file may be cut short)
    """
    found = _SHORT_FACE.search(data)
    if found is not None:
        line = data.count(b"\n", 0, found.start()) + 1
        text = found.group().strip().decode("utf-8", "replace")
        raise MeshFormatError(f"{label}, line {line}: a face with fewer than 3 vertices ({text!r}; the file may be "
                              "cut short)")


def check_obj_zero_index(data: bytes, label: str) -> None:
    """Refuse an OBJ file with a face naming vertex 0 (OBJ counts from 1, or back from -1).

    Raises
    ------
    MeshFormatError
    """
    line = _obj_zero_index_line(data)
    if line is not None:
        raise MeshFormatError(f"{label}, line {line}: a face names vertex 0, but OBJ vertex indices start "
                              "at 1 (or count back from -1 for the last vertex)")


def screen_obj(data: bytes, label: str, obj_zero_index: bool = True) -> bytes:
    """An OBJ file's bytes as UTF-8 text, binary junk refused, and faces naming vertex 0 refused unless
    ``obj_zero_index`` is False (:func:`check_obj_zero_index`)."""
    data = _as_text(data, "an OBJ", label)
    if obj_zero_index:
        check_obj_zero_index(data, label)
    return data


def screen_off(data: bytes, label: str) -> bytes:
    """An OFF file's bytes as UTF-8 text, binary junk refused."""
    return _as_text(data, "an OFF", label)


def screen_stl(data: bytes, label: str) -> bytes:
    """An STL file's bytes: a binary STL as it is, an ASCII one as UTF-8 text; anything else refused."""
    if _binary_stl_triangles(data) is None:
        if not data.lstrip()[:5].lower() == b"solid":
            raise MeshFormatError(
                f"{label} is not an STL file: neither binary (its {len(data):,} bytes do not match the triangle "
                "count in its header) nor ASCII (which starts with 'solid')")
        data = _as_text(data, "an ASCII STL", label)
    return data


def screen_ply(data: bytes, label: str) -> bytes:
    """A PLY file's bytes with its header as UTF-8 text; a file without a ``ply`` ... ``end_header`` header
    refused."""
    end = data.find(b"end_header", 0, 1 << 20)
    if not data.startswith(b"ply") or end < 0:
        raise MeshFormatError(f"{label} is not a PLY file: it does not start with a 'ply' header ending in "
                              "'end_header'")
    return _as_text(data[:end], "a PLY", label) + data[end:]


def screen(data: bytes, ft: str, label: str, obj_zero_index: bool = True) -> bytes:
    """Bytes the parsers can take: text as UTF-8, binary junk and OBJ faces naming vertex 0 refused (the screening
    function of the format's record in :mod:`arap.io.formats`).

    Parameters
    ----------
    obj_zero_index : bool
        Look for OBJ faces naming vertex 0 (:func:`check_obj_zero_index`); False leaves that to the caller, e.g.
        for a file the plain OBJ reader accepts, which takes only indices from 1 up.

    Raises
    ------
    MeshFormatError
        An empty file, binary data where text is expected, an STL that is neither binary nor ASCII, a PLY without
        its header, an OBJ face naming vertex 0.
    """
    if not data or data.isspace():
        raise MeshFormatError(f"{label} contains no vertices (the file is empty)")
    if ft == "obj":  # the one screening with an option
        return screen_obj(data, label, obj_zero_index)
    check = formats.get(ft).function("screen")
    return data if check is None else bytes(check(data, label))


def _off_count(data: bytes, position: int) -> int | None:
    """Count number ``position`` of an OFF header (1: vertices, 2: faces), or None when it cannot be read."""
    tokens: list[bytes] = []
    for line in data[:1 << 16].splitlines():
        tokens += line.split(b"#", 1)[0].split()
        if len(tokens) >= 3:
            break
    if len(tokens) < 3 or not tokens[0].upper().endswith(b"OFF"):
        return None
    try:
        return int(tokens[position])
    except ValueError:
        return None


def obj_vertex_count(data: bytes) -> tuple[int, str]:
    """The ``v`` lines of an OBJ file."""
    count = data.count(b"\nv ") + data.count(b"\nv\t") + int(data.startswith((b"v ", b"v\t")))
    return count, f"{count:,} vertices"


def off_vertex_count(data: bytes) -> tuple[int, str] | None:
    """The vertex count of an OFF header."""
    vertices = _off_count(data, 1)
    return None if vertices is None else (vertices, f"{vertices:,} vertices")


def _ply_counts(data: bytes) -> dict[bytes, int]:
    header = data[:data.find(b"end_header", 0, 1 << 20)]
    return {name: int(n) for name, n in _PLY_ELEMENT.findall(header)}


def ply_vertex_count(data: bytes) -> tuple[int, str] | None:
    """The vertex count of a PLY header."""
    vertices = _ply_counts(data).get(b"vertex")
    return None if vertices is None else (vertices, f"{vertices:,} vertices")


def stl_vertex_count(data: bytes) -> tuple[int, str]:
    """Half the triangles of an STL (a closed surface has about that many vertices once welded)."""
    triangles = _binary_stl_triangles(data)
    if triangles is None:
        triangles = (data.count(b"vertex") + data.count(b"VERTEX") + data.count(b"Vertex")) // 3
    return triangles // 2, f"{triangles:,} triangles (about {triangles // 2:,} vertices once welded)"


def off_face_count(data: bytes) -> int | None:
    """The face count of an OFF header."""
    return _off_count(data, 2)


def ply_face_count(data: bytes) -> int | None:
    """The face count of a PLY header."""
    return _ply_counts(data).get(b"face")


def vertex_count(data: bytes, ft: str) -> tuple[int, str] | None:
    """The vertices a file holds, read cheaply from its header or its lines before parsing, with what was counted.

    For STL (a triangle soup welded after loading) the count is half the triangles: a closed surface has about
    that many vertices. None when the header cannot be read (the parser then reports what is wrong) or the format
    has no such count.
    """
    count = formats.get(ft).function("vertex_count")
    return None if count is None else count(data)


def announced_faces(data: bytes, ft: str) -> int | None:
    """The face count an OFF or PLY header announces, or None (other formats, or a header that cannot be read).

    Example
    -------
    >>> announced_faces(b"OFF\\n# a comment\\n4 2 0\\n", "off")
    2
    """
    count = formats.get(ft).function("face_count")
    return None if count is None else count(data)


def check_size(data: bytes, ft: str, label: str, max_vertices: int | None) -> None:
    """Refuse a file holding more than ``max_vertices`` vertices, from a cheap count (:func:`vertex_count`).

    Raises
    ------
    MeshTooLargeError
    """
    if max_vertices is None:
        return
    found = vertex_count(data, ft)
    if found is not None and found[0] > max_vertices:
        raise MeshTooLargeError(f"{label} holds {found[1]}; at most {max_vertices:,} vertices are accepted",
                                found[0], max_vertices)
