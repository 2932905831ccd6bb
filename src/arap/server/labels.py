"""How the studio names the solver's options in its menus (the names themselves are :mod:`arap.options`')."""

from __future__ import annotations

__all__ = ["ENERGY_LABELS", "LOOSE_LABELS", "WARP_LABELS", "WEIGHT_LABELS"]

ENERGY_LABELS: dict[str, str] = {"spokes": "spokes (2007 paper)", "spokes_and_rims": "spokes and rims",
                                 "smooth_rotations": "smooth rotations (SR-ARAP)"}
"""How the studio names each energy."""
WEIGHT_LABELS: dict[str, str] = {"cotangent": "cotangent", "clamped": "cotangent, clamped at 0", "uniform": "uniform"}
"""How the studio names each weighting."""
LOOSE_LABELS: dict[str, str] = {"follow": "follow nearest part", "hold": "stay put", "error": "refuse selection"}
"""How the studio names what loose parts (parts no constraint reaches) do."""
WARP_LABELS: dict[str, str] = {"rigid": "rigid", "normal": "normal", "distort": "distort"}
"""How the studio names the puppet warp's modes (:data:`arap.puppet.warp.MODES`), as Photoshop's Puppet Warp does."""
