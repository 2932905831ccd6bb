"""Mesh files: OBJ, OFF, PLY and STL from paths or bytes, in file vertex order."""

from arap.io.meshfile import (
    MESH_FORMATS,
    format_of,
    load_mesh,
    load_mesh_bytes,
    load_mesh_bytes_with_report,
    load_mesh_with_report,
    save_mesh,
    save_mesh_bytes,
)

__all__ = [
    "MESH_FORMATS",
    "format_of",
    "load_mesh",
    "load_mesh_bytes",
    "load_mesh_bytes_with_report",
    "load_mesh_with_report",
    "save_mesh",
    "save_mesh_bytes",
]
