"""PNG files of RGB pictures, with the standard library only (zlib and struct): an encoder for 8-bit RGB images. Each
scanline is stored with the Sub filter (the difference to the pixel on its left), which suits rendered pictures'
smooth gradients and large flat areas.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["SIGNATURE", "encode_png"]

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
    >>> data[:8] == SIGNATURE
    True
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
