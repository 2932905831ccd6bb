"""PNG files of RGB pictures, with the standard library only (zlib and struct): an encoder for 8-bit RGB images and a
small decoder of the files it writes (non-interlaced 8-bit RGB or RGBA with the scanline filters None, Sub and Up),
which the tests use to read pictures back. Each scanline is stored with the Sub filter (the difference to the pixel on
its left), which suits rendered pictures' smooth gradients and large flat areas.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["SIGNATURE", "decode_png", "encode_png"]

SIGNATURE = b"\x89PNG\r\n\x1a\n"

_FILTERS = {"none": 0, "sub": 1, "up": 2}


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(pixels: NDArray[np.uint8], *, filter: str = "sub", level: int = 6) -> bytes:
    """The PNG file of an RGB picture.

    Parameters
    ----------
    pixels : (h, w, 3) uint8 array
    filter : {"sub", "up", "none"}
        Scanline filter of every row.
    level : int
        zlib compression level, 0 to 9.

    Returns
    -------
    bytes

    Raises
    ------
    ArapError
        ``pixels`` is not an (h, w, 3) uint8 array with h, w >= 1, or ``filter`` is unknown.

    Example
    -------
    >>> data = encode_png(np.zeros((2, 3, 3), dtype=np.uint8))
    >>> data[:8] == SIGNATURE, decode_png(data).shape
    (True, (2, 3, 3))
    """
    pixels = np.asarray(pixels)
    if pixels.dtype != np.uint8 or pixels.ndim != 3 or pixels.shape[2] != 3 or not pixels.shape[0] * pixels.shape[1]:
        raise ArapError(f"a PNG picture must be an (h, w, 3) uint8 array, got {pixels.dtype} {pixels.shape}")
    if filter not in _FILTERS:
        raise ArapError(f"unknown PNG filter {filter!r}; expected one of {sorted(_FILTERS)}")
    h, w, _ = pixels.shape
    rows = pixels.reshape(h, 3 * w)
    if filter == "sub":
        rows = rows.copy()
        rows[:, 3:] -= pixels.reshape(h, 3 * w)[:, :-3]  # uint8 arithmetic wraps modulo 256, as PNG's filters do
    elif filter == "up":
        rows = rows.copy()
        rows[1:] -= pixels.reshape(h, 3 * w)[:-1]
    raw = np.empty((h, 3 * w + 1), dtype=np.uint8)
    raw[:, 0] = _FILTERS[filter]
    raw[:, 1:] = rows
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8 bits, RGB, deflate, adaptive filters, no interlace
    return (SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw.tobytes(), level))
            + _chunk(b"IEND", b""))


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
