"""Reading back the animated GLB that :mod:`arap.io.animated_gltf` writes (first frame as the mesh, one morph target
per frame, a weights animation), for the tests of the animation export."""

from __future__ import annotations

import json
import struct

import numpy as np


def glb_frames(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions ``(N, n, 3)`` of an animated GLB (first frame as the mesh, a morph target per frame)."""
    assert data[:4] == b"glTF"
    json_len = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + json_len])
    binary = data[20 + json_len + 8:]

    def accessor(k: int, width: int) -> np.ndarray:
        a = doc["accessors"][k]
        view = doc["bufferViews"][a["bufferView"]]
        raw = np.frombuffer(binary, dtype="<f4", count=a["count"] * width, offset=view["byteOffset"])
        return raw.reshape(a["count"], width) if width > 1 else raw

    prim = doc["meshes"][0]["primitives"][0]
    base = accessor(prim["attributes"]["POSITION"], 3).astype(np.float64)
    frames = np.stack([base + accessor(t["POSITION"], 3) for t in prim["targets"]])
    times = accessor(doc["animations"][0]["samplers"][0]["input"], 1).astype(np.float64)
    return times, frames
