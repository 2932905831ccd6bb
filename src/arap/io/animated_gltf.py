"""An animation as one binary glTF (GLB): the first frame as the mesh, every frame a morph target, and a weights
animation that shows each frame at its time.

Morph targets are the glTF way to store per-vertex animation (glTF 2.0, "Morph Targets"; three.js, Blender and every
other glTF viewer play them): the mesh's positions are the first frame, target ``k`` holds frame ``k`` minus the
first, and the animation's sampler sets weight ``k`` to 1 at the time of frame ``k`` and 0 at the other frames'
times. With linear interpolation, a viewer shows between two frames the linear blend of the two, which is what a
frame rate between the solved frames can show. The mesh has the first frame's vertex normals (area-weighted, unit
length) and every target the change of the normals from the first frame to its own (glTF's ``NORMAL`` morph target),
so viewers shade each frame smoothly with its own normals (between frames, with the blend of the two, which they
renormalise).

Positions and normals are stored as float32 (glTF has no float64 vertex attribute); indices as uint32.
"""

from __future__ import annotations

import json
import os
import struct

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError
from arap.io.atomic import write_atomic

__all__ = ["animation_glb", "save_animation_glb"]

_FLOAT, _UINT = 5126, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def _pad(data: bytes, fill: bytes = b"\0") -> bytes:
    return data + fill * (-len(data) % 4)


def _unit_normals(X: NDArray[np.floating], F: NDArray[np.int64]) -> NDArray[np.float32]:
    """Area-weighted unit vertex normals as float32; +z for a vertex of no (non-degenerate) triangle (glTF's normals
    are unit vectors)."""
    from arap.meshes._geometry import vertex_normals

    N = vertex_normals(np.asarray(X, dtype=np.float64), F)
    N[~(np.abs(N).sum(axis=1) > 0)] = (0.0, 0.0, 1.0)
    return N.astype(np.float32)


def animation_glb(F: NDArray[np.integer], times: NDArray[np.floating], frames: NDArray[np.floating],
                  name: str = "arap animation") -> bytes:
    """The GLB file's bytes for ``frames`` (N, n, 3) at ``times`` (N,) on triangles ``F`` (m, 3).

    Raises
    ------
    MeshError
        Shapes that do not fit together, times not increasing, non-finite positions.
    """
    frames = np.asarray(frames)
    times = np.asarray(times, dtype=np.float64)
    F = np.asarray(F)
    if frames.ndim != 3 or frames.shape[2] != 3 or len(frames) == 0:
        raise MeshError(f"frames must be an (N, n, 3) array with N >= 1, got shape {list(frames.shape)}")
    if times.shape != (len(frames),):
        raise MeshError(f"{len(frames)} frames need {len(frames)} times, got shape {list(times.shape)}")
    if len(times) > 1 and not (np.diff(times) > 0).all():
        raise MeshError("frame times must increase")
    if F.ndim != 2 or F.shape[1] != 3 or (F.size and (F.min() < 0 or F.max() >= frames.shape[1])):
        raise MeshError("faces must be an (m, 3) array of vertex indices of the frames")
    if not np.isfinite(frames).all():
        raise MeshError("frames hold non-finite positions")
    base = frames[0].astype(np.float32)
    chunks: list[bytes] = []
    views: list[dict] = []
    accessors: list[dict] = []
    offset = 0

    def add(data: bytes, target: int | None, accessor: dict) -> int:
        nonlocal offset
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        views.append(view)
        chunks.append(_pad(data))
        offset += len(chunks[-1])
        accessors.append({"bufferView": len(views) - 1, **accessor})
        return len(accessors) - 1

    def vec3(values: NDArray[np.float32], bounds: bool = True) -> int:
        extent = {"min": values.min(axis=0).tolist(), "max": values.max(axis=0).tolist()} if bounds else {}
        return add(np.ascontiguousarray(values, dtype="<f4").tobytes(), _ARRAY_BUFFER,
                   {"componentType": _FLOAT, "count": len(values), "type": "VEC3", **extent})

    indices = add(np.ascontiguousarray(F, dtype="<u4").tobytes(), _ELEMENT_ARRAY_BUFFER,
                  {"componentType": _UINT, "count": int(F.size), "type": "SCALAR"})
    position = vec3(base)
    F64 = F.astype(np.int64)
    base_normals = _unit_normals(frames[0], F64)
    normal = vec3(base_normals, bounds=False)
    targets = [{"POSITION": vec3(frame.astype(np.float32) - base),
                "NORMAL": vec3(_unit_normals(frame, F64) - base_normals, bounds=False)} for frame in frames]
    t32 = (times - times[0]).astype(np.float32)
    key_times = add(t32.astype("<f4").tobytes(), None, {"componentType": _FLOAT, "count": len(t32),
                                                        "type": "SCALAR", "min": [float(t32[0])],
                                                        "max": [float(t32[-1])]})
    weights = add(np.eye(len(frames), dtype="<f4").tobytes(), None,
                  {"componentType": _FLOAT, "count": len(frames) ** 2, "type": "SCALAR"})
    doc = {
        "asset": {"version": "2.0", "generator": "arap"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "weights": [0.0] * len(frames),
                    "primitives": [{"attributes": {"POSITION": position, "NORMAL": normal}, "indices": indices,
                                    "mode": 4, "targets": targets}],
                    "extras": {"targetNames": [f"frame_{k:04d}" for k in range(len(frames))]}}],
        "animations": [{"name": name, "samplers": [{"input": key_times, "output": weights,
                                                    "interpolation": "LINEAR"}],
                        "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}],
        "buffers": [{"byteLength": offset}],
        "bufferViews": views,
        "accessors": accessors,
    }
    body = _pad(json.dumps(doc, separators=(",", ":")).encode(), b" ")
    binary = b"".join(chunks)
    total = 12 + 8 + len(body) + 8 + len(binary)
    return b"".join([struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(body), b"JSON"), body,
                     struct.pack("<I4s", len(binary), b"BIN\0"), binary])


def save_animation_glb(path: str | os.PathLike[str], F: NDArray[np.integer], times: NDArray[np.floating],
                       frames: NDArray[np.floating]) -> None:
    """Write :func:`animation_glb` to ``path`` atomically (see :mod:`arap.io.atomic`)."""
    write_atomic(path, animation_glb(F, times, frames))
