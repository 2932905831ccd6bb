"""A small decoder of the PNG files the package writes (:func:`arap.render.png.encode_png`), to read pictures back
in the tests: non-interlaced 8-bit RGB or RGBA with the scanline filters None, Sub and Up."""

from __future__ import annotations

import struct
import zlib

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError
from arap.render.png import SIGNATURE

__all__ = ["decode_png"]


def decode_png(data: bytes) -> NDArray[np.uint8]:
    """The pixels of a PNG file of the kind :func:`encode_png` writes (8-bit RGB or RGBA, not interlaced, scanline
    filters None, Sub or Up).

    Returns
    -------
    (h, w, 3) or (h, w, 4) uint8 array

    Raises
    ------
    ArapError
        Not a PNG file, a damaged one (a chunk's CRC, truncated data), or one of another kind.

    Example
    -------
    >>> img = np.arange(24, dtype=np.uint8).reshape(2, 4, 3)
    >>> bool((decode_png(encode_png(img, filter="up")) == img).all())
    True
    """
    if not data.startswith(SIGNATURE):
        raise ArapError("not a PNG file (no PNG signature)")
    pos, header, idat = len(SIGNATURE), b"", []
    while pos + 12 <= len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length].rjust(4, b"\0"))
        if len(body) != length or zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ArapError(f"damaged PNG file: chunk {kind!r} is truncated or fails its CRC")
        if kind == b"IHDR":
            header = body
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + length
    if len(header) != 13:
        raise ArapError("damaged PNG file: no image header")
    w, h, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", header)
    channels = {2: 3, 6: 4}.get(color)
    if depth != 8 or channels is None or interlace:
        raise ArapError(f"unsupported PNG: bit depth {depth}, colour type {color}, interlace {interlace}")
    try:
        raw = np.frombuffer(zlib.decompress(b"".join(idat)), dtype=np.uint8)
    except zlib.error as exc:
        raise ArapError(f"damaged PNG file: {exc}") from None
    stride = channels * w
    if raw.size != h * (stride + 1):
        raise ArapError(f"damaged PNG file: {raw.size} bytes of image data for {w}x{h} pixels")
    raw = raw.reshape(h, stride + 1)
    out = np.empty((h, stride), dtype=np.uint8)
    for i in range(h):
        code, row = int(raw[i, 0]), raw[i, 1:]
        if code == 0:
            out[i] = row
        elif code == 1:  # Sub: running sums per channel, modulo 256
            sums = np.cumsum(row.reshape(w, channels).astype(np.uint64), axis=0) % 256
            out[i] = sums.astype(np.uint8).reshape(stride)
        elif code == 2:
            out[i] = row + (out[i - 1] if i else np.uint8(0))
        else:
            raise ArapError(f"unsupported PNG scanline filter {code} (row {i})")
    return out.reshape(h, w, channels)
