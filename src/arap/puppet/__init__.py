"""The puppet warp of pictures (Igarashi, Moscovich & Hughes 2005): a picture's shape meshed
(:mod:`~arap.puppet.outline`, :mod:`~arap.puppet.imagemesh`), pinned and deformed as rigidly as it can
(:mod:`~arap.puppet.warp`), and drawn on the deformed mesh (:mod:`~arap.puppet.raster`); pictures are read by
:mod:`~arap.puppet.picture`."""

from __future__ import annotations

from arap.puppet.imagemesh import ImageMesh, image_mesh
from arap.puppet.warp import PuppetWarp, pin_targets, warp

__all__ = ["ImageMesh", "PuppetWarp", "image_mesh", "pin_targets", "warp"]
