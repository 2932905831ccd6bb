"""Measures of rendered pictures shared by the render tests."""

from __future__ import annotations

import numpy as np

from arap.render.show import as_rgb


def colour_share(pixels: np.ndarray, hex_color: str, tolerance: float = 0.12) -> float:
    """Share of pixels of the hue of ``hex_color`` (its direction in RGB, whatever the brightness)."""
    target = as_rgb(hex_color)
    p = pixels.reshape(-1, 3).astype(float)
    norm = np.linalg.norm(p, axis=1)
    lit = norm > 60
    cos = p[lit] @ target / (norm[lit] * np.linalg.norm(target))
    return float(np.mean(cos > 1 - tolerance ** 2 / 2)) * lit.mean()
