"""Pictures for the puppet warp: arrays checked as they are, files read with Pillow (imported only then).

A file's size is read from its header before anything is decoded, so a picture over :data:`MAX_PIXELS` is refused
without the memory its pixels would take.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["MAX_PIXELS", "PictureError", "as_picture", "decode_picture", "read_picture"]

MAX_PIXELS = 64_000_000
"""Largest picture (width × height) the puppet warp takes: 64 megapixels."""


class PictureError(ArapError):
    """A picture that cannot be used: missing, unreadable, corrupt, too large, of the wrong shape or type."""


def _pillow() -> Any:
    try:
        from PIL import Image
    except ImportError:
        raise PictureError("reading picture files needs Pillow: pip install 'arap[image]'") from None
    return Image


def read_picture(path: str | os.PathLike[str]) -> NDArray[np.uint8]:
    """The pixels of a picture file: (h, w, 4) uint8 when it has alpha (or a transparent colour), else (h, w, 3).

    Raises
    ------
    PictureError
        No such file, not a picture Pillow can read, corrupt or truncated, or over :data:`MAX_PIXELS`.
    """
    name = str(path)
    if not Path(path).is_file():
        raise PictureError(f"{name}: no such file" if not Path(path).exists() else f"{name}: not a file")
    return _decode(path, name)


def decode_picture(data: bytes, name: str) -> NDArray[np.uint8]:
    """The pixels of a picture file's bytes (see :func:`read_picture`; ``name`` is for the messages)."""
    import io

    return _decode(io.BytesIO(data), name)


def _decode(source: Any, name: str) -> NDArray[np.uint8]:
    Image = _pillow()
    try:
        with warnings.catch_warnings():  # Pillow warns of pictures over 89 megapixels on opening; refused below
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(source)
        with im:
            w, h = im.size
            if w * h > MAX_PIXELS:
                raise PictureError(f"{name}: the picture is {w}x{h} = {w * h / 1e6:.1f} megapixels; the puppet warp "
                                   f"takes at most {MAX_PIXELS // 1_000_000} megapixels")
            alpha = im.mode in ("RGBA", "LA", "PA", "RGBa", "La") or "transparency" in im.info
            pixels = np.asarray(im.convert("RGBA" if alpha else "RGB"), dtype=np.uint8)
    except PictureError:
        raise
    except Image.DecompressionBombError:
        raise PictureError(f"{name}: the picture is larger than {MAX_PIXELS // 1_000_000} megapixels, the most the "
                           "puppet warp takes") from None
    except Image.UnidentifiedImageError:
        raise PictureError(f"{name}: not a picture file (Pillow cannot identify it)") from None
    except (OSError, SyntaxError, ValueError) as exc:  # truncated or corrupt data
        raise PictureError(f"{name}: corrupt or truncated picture ({' '.join(str(exc).split())})") from None
    return np.ascontiguousarray(pixels)


def as_picture(image: object) -> NDArray[np.uint8]:
    """A picture given as an array or a path, as an (h, w, 3) or (h, w, 4) uint8 array.

    Parameters
    ----------
    image : (h, w, 3|4) or (h, w) uint8 array, or a path
        A grey (h, w) array becomes RGB.

    Raises
    ------
    PictureError
        A path that :func:`read_picture` refuses; an array of another shape or type, empty or over
        :data:`MAX_PIXELS`.

    Example
    -------
    >>> as_picture(np.zeros((2, 3), dtype=np.uint8)).shape
    (2, 3, 3)
    """
    if isinstance(image, (str, os.PathLike)):
        return read_picture(image)
    a = np.asarray(image)
    if a.dtype != np.uint8:
        raise PictureError(f"a picture must be a uint8 array (values 0 to 255), got dtype {a.dtype}")
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise PictureError(f"a picture must have shape (h, w, 3) or (h, w, 4), got {a.shape}")
    if a.shape[0] * a.shape[1] == 0:
        raise PictureError(f"the picture is empty ({a.shape[1]}x{a.shape[0]})")
    if a.shape[0] * a.shape[1] > MAX_PIXELS:
        raise PictureError(f"the picture is {a.shape[1]}x{a.shape[0]}; the puppet warp takes at most "
                           f"{MAX_PIXELS // 1_000_000} megapixels")
    return np.ascontiguousarray(a)
