"""Synthetic pictures for the puppet warp's tests, drawn with NumPy."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def centres(h: int, w: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The pixel centres' x and y, each (h, w)."""
    y, x = np.mgrid[0:h, 0:w] + 0.5
    return x, y


def ring(size: int = 200, inner: float = 30.0, outer: float = 80.0) -> NDArray[np.uint8]:
    """An RGBA disc with a hole, opaque on a transparent background, coloured by position."""
    x, y = centres(size, size)
    d = np.hypot(x - size / 2, y - size / 2)
    img = textured(size, size)
    img[:, :, 3] = np.where((d < outer) & (d > inner), 255, 0)
    return img


def textured(h: int, w: int) -> NDArray[np.uint8]:
    """An opaque RGBA picture with smooth colour gradients (bilinear resampling changes it little)."""
    x, y = centres(h, w)
    img = np.empty((h, w, 4), dtype=np.uint8)
    img[:, :, 0] = np.rint(127.5 + 100 * np.sin(x / 17.0)).astype(np.uint8)
    img[:, :, 1] = np.rint(127.5 + 100 * np.cos(y / 13.0)).astype(np.uint8)
    img[:, :, 2] = np.rint(127.5 + 100 * np.sin((x + y) / 23.0)).astype(np.uint8)
    img[:, :, 3] = 255
    return img


def bar(h: int = 200, w: int = 200) -> NDArray[np.uint8]:
    """A horizontal grey bar, 160 × 40 pixels, on a transparent background."""
    img = np.zeros((h, w, 4), dtype=np.uint8)
    img[80:120, 20:180] = (128, 128, 128, 255)
    return img


def dot(img: NDArray[np.uint8], x: float, y: float, colour: tuple[int, int, int], radius: float = 3.0) -> None:
    """Paint an opaque dot of ``colour`` centred on (x, y)."""
    cx, cy = centres(img.shape[0], img.shape[1])
    inside = np.hypot(cx - x, cy - y) <= radius
    img[inside, :3] = colour
    img[inside, 3] = 255


def find(img: NDArray[np.uint8], colour: tuple[int, int, int], within: int = 30) -> NDArray[np.float64]:
    """Centre (x, y) of the opaque pixels of about ``colour``."""
    cx, cy = centres(img.shape[0], img.shape[1])
    near = (np.abs(img[:, :, :3].astype(int) - colour).max(axis=2) <= within) & (img[:, :, 3] > 200)
    assert near.any(), f"no pixel of colour {colour}"
    return np.array([cx[near].mean(), cy[near].mean()])
