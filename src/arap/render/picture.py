"""A rendered picture: its pixels, its PNG file, and how it is saved and shown. :class:`Picture` is what
:func:`arap.show` returns; Jupyter shows it inline (``_repr_png_``), and :meth:`Picture.save` writes the PNG file
atomically through the io layer's safe writer, which refuses to replace a folder, a named pipe, a device or a
symbolic link to one, as every writer of arap does.
"""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError
from arap.render.camera import Camera
from arap.render.png import encode_png

__all__ = ["Picture"]


class Picture:
    """A picture of a mesh.

    Parameters
    ----------
    pixels : (h, w, 3) uint8 array
        Rows from the top, columns from the left, RGB (sRGB).
    camera : Camera or None
        The camera that took it: pass it as ``camera=`` to :func:`arap.show` to picture another shape (a
        deformation of the mesh) at the same place and scale.

    Example
    -------
    >>> pic = Picture(np.zeros((2, 3, 3), dtype=np.uint8))
    >>> pic, pic.width, pic.height, pic.png()[:4]
    (Picture(3x2), 3, 2, b'\\x89PNG')
    """

    def __init__(self, pixels: NDArray[np.uint8], camera: Camera | None = None) -> None:
        pixels = np.asarray(pixels)
        if pixels.dtype != np.uint8 or pixels.ndim != 3 or pixels.shape[2] != 3 or 0 in pixels.shape:
            raise ArapError(f"a picture's pixels must be an (h, w, 3) uint8 array, got {pixels.dtype} {pixels.shape}")
        self._pixels = np.array(pixels)  # a copy of its own, read-only
        self._pixels.flags.writeable = False
        self.camera = camera

    @property
    def pixels(self) -> NDArray[np.uint8]:
        """(h, w, 3) uint8 array, read-only."""
        return self._pixels

    @property
    def width(self) -> int:
        """Width in pixels."""
        return int(self._pixels.shape[1])

    @property
    def height(self) -> int:
        """Height in pixels."""
        return int(self._pixels.shape[0])

    def png(self) -> bytes:
        """The picture as a PNG file (8-bit RGB)."""
        return encode_png(self._pixels)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the picture as a PNG file, atomically (the file is either its earlier content or the whole picture).

        Parameters
        ----------
        path : path-like
            The file to write; the PNG format is written whatever its extension.

        Raises
        ------
        arap.io.paths.SpecialFileError
            ``path`` is a folder, a named pipe, a device or a socket (or a symbolic link to one), or its folder is
            missing; nothing is written.
        OSError
            The file cannot be written; it is left as it was.
        """
        from arap.io.atomic import write_atomic

        write_atomic(path, self.png())

    def _repr_png_(self) -> bytes:
        """What Jupyter shows: the PNG file."""
        return self.png()

    def __repr__(self) -> str:
        return f"Picture({self.width}x{self.height})"
