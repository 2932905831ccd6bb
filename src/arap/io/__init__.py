"""Mesh files: OBJ, OFF, PLY, STL, GLB and glTF from paths or bytes, in file vertex order; textured models (their
UVs, normals, colours, materials, textures and scenes kept) through :mod:`arap.io.assets`; tetrahedral and planar
meshes in Medit, gmsh, VTK and TetGen files through :mod:`arap.io.volume`.

Examples
--------
>>> import arap
>>> arap.MESH_FORMATS
('obj', 'off', 'ply', 'stl', 'glb', 'gltf')
>>> arap.VOLUME_FORMATS
('mesh', 'msh', 'vtu', 'vtk', 'node', 'ele')
"""

from arap.io.assets import (
    ASSET_FORMATS,
    MeshAsset,
    SolveMesh,
    load_asset,
    load_asset_bytes,
    save_asset,
)
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
from arap.io.volume import (
    VOLUME_FORMATS,
    boundary_faces,
    boundary_surface,
    load_volume_mesh,
    save_volume_mesh,
)

__all__ = [
    "ASSET_FORMATS",
    "MESH_FORMATS",
    "VOLUME_FORMATS",
    "MeshAsset",
    "SolveMesh",
    "boundary_faces",
    "boundary_surface",
    "format_of",
    "load_asset",
    "load_asset_bytes",
    "load_mesh",
    "load_mesh_bytes",
    "load_mesh_bytes_with_report",
    "load_mesh_with_report",
    "load_volume_mesh",
    "save_asset",
    "save_mesh",
    "save_mesh_bytes",
    "save_volume_mesh",
]
