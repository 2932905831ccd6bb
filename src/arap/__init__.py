"""arap: As-Rigid-As-Possible modeling (Sorkine & Alexa 2007) of surfaces, planar meshes and tetrahedral solids.

Fix both ends of a bar and move one of them sideways:

>>> import arap
>>> import numpy as np
>>> V, F = arap.builtin_mesh("bar")                      # along y, from 0 to 5
>>> y = V[:, 1]
>>> constrained = np.flatnonzero((y == y.min()) | (y == y.max()))
>>> targets = V[constrained] + np.where(y[constrained, None] == y.max(), [1.0, 0.0, 0.0], 0.0)
>>> solver = arap.ArapSolver(V, F, constrained)           # factorises once
>>> result = solver.solve(targets)                        # back-substitutes per iteration, until converged
>>> result.converged, result.vertices.shape
(True, (4314, 3))
>>> arap.__version__
'0.1.0'

Public names are imported on first use, so ``import arap`` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from arap.errors import (
    ArapError,
    ConstraintError,
    MeshError,
    MeshFormatError,
    MeshTooLargeError,
    OptionError,
    UnconstrainedRegionError,
)

__version__ = "0.1.0"

_LAZY: dict[str, str] = {
    "ArapSolver": "arap.solve.solver",
    "ArapResult": "arap.solve.solver",
    "arap_energy": "arap.method.energy",
    "cell_energies": "arap.method.energy",
    "cell_distortion": "arap.method.energy",
    "rotations_from_covariances": "arap.method.rotations",
    "cotangent_laplacian": "arap.method.weights",
    "check_mesh": "arap.meshes.mesh",
    "check_domain": "arap.meshes.domain",
    "rectangle_triangles": "arap.meshes.grids",
    "box_tetrahedra": "arap.meshes.grids",
    "mesh_arrays": "arap.meshes.mesh",
    "MeshLike": "arap.meshes.mesh",
    "repair_mesh": "arap.meshes.repair",
    "inspect_mesh": "arap.diagnose",
    "load_mesh": "arap.io",
    "load_mesh_with_report": "arap.io",
    "load_mesh_bytes": "arap.io",
    "save_mesh": "arap.io",
    "save_mesh_bytes": "arap.io",
    "MESH_FORMATS": "arap.io",
    "VOLUME_FORMATS": "arap.io",
    "load_volume_mesh": "arap.io",
    "save_volume_mesh": "arap.io",
    "boundary_faces": "arap.meshes.domain",
    "boundary_surface": "arap.io",
    "tetrahedralize": "arap.meshes.tetrahedralize",
    "embed_points": "arap.meshes.tetrahedralize",
    "interpolate_points": "arap.meshes.tetrahedralize",
    "MeshAsset": "arap.io",
    "load_asset": "arap.io",
    "save_asset": "arap.io",
    "sphere": "arap.meshes.shapes",
    "Constraints": "arap.constraints",
    "save_constraints": "arap.constraints",
    "RepairResult": "arap.meshes.repair",
    "MeshInfo": "arap.diagnose",
    "builtin_mesh": "arap.meshes.shapes",
    "BUILTIN_MESHES": "arap.meshes.shapes",
    "load_constraints": "arap.constraints",
    "studio": "arap.notebook",
    "Studio": "arap.notebook",
    "widget": "arap.jupyter_widget",
    "StudioWidget": "arap.jupyter_widget",
    "animate": "arap.animation",
    "load_keyframes": "arap.animation",
    "Animation": "arap.animation",
    "batch": "arap.batching",
    "show": "arap.render.show",
    "Picture": "arap.render.picture",
    "image_mesh": "arap.puppet.imagemesh",
    "ImageMesh": "arap.puppet.imagemesh",
    "warp": "arap.puppet.warp",
    "PuppetWarp": "arap.puppet.warp",
}

__all__ = [
    "BUILTIN_MESHES",
    "MESH_FORMATS",
    "VOLUME_FORMATS",
    "Animation",
    "ArapError",
    "ArapResult",
    "ArapSolver",
    "ConstraintError",
    "Constraints",
    "ImageMesh",
    "MeshAsset",
    "MeshError",
    "MeshFormatError",
    "MeshInfo",
    "MeshLike",
    "MeshTooLargeError",
    "OptionError",
    "Picture",
    "PuppetWarp",
    "RepairResult",
    "Studio",
    "StudioWidget",
    "UnconstrainedRegionError",
    "__version__",
    "animate",
    "arap_energy",
    "batch",
    "boundary_faces",
    "boundary_surface",
    "box_tetrahedra",
    "builtin_mesh",
    "cell_distortion",
    "cell_energies",
    "check_domain",
    "check_mesh",
    "cotangent_laplacian",
    "embed_points",
    "image_mesh",
    "inspect_mesh",
    "interpolate_points",
    "load_asset",
    "load_constraints",
    "load_keyframes",
    "load_mesh",
    "load_mesh_bytes",
    "load_mesh_with_report",
    "load_volume_mesh",
    "mesh_arrays",
    "rectangle_triangles",
    "repair_mesh",
    "rotations_from_covariances",
    "save_asset",
    "save_constraints",
    "save_mesh",
    "save_mesh_bytes",
    "save_volume_mesh",
    "show",
    "sphere",
    "studio",
    "tetrahedralize",
    "warp",
    "widget",
]

if TYPE_CHECKING:
    from arap.animation import Animation, animate, load_keyframes
    from arap.batching import batch
    from arap.constraints import Constraints, load_constraints, save_constraints
    from arap.diagnose import MeshInfo, inspect_mesh
    from arap.io import (
        MESH_FORMATS,
        VOLUME_FORMATS,
        MeshAsset,
        boundary_surface,
        load_asset,
        load_mesh,
        load_mesh_bytes,
        load_mesh_with_report,
        load_volume_mesh,
        save_asset,
        save_mesh,
        save_mesh_bytes,
        save_volume_mesh,
    )
    from arap.jupyter_widget import StudioWidget, widget
    from arap.meshes.domain import boundary_faces, check_domain
    from arap.meshes.grids import box_tetrahedra, rectangle_triangles
    from arap.meshes.mesh import MeshLike, check_mesh, mesh_arrays
    from arap.meshes.repair import RepairResult, repair_mesh
    from arap.meshes.shapes import BUILTIN_MESHES, builtin_mesh, sphere
    from arap.meshes.tetrahedralize import embed_points, interpolate_points, tetrahedralize
    from arap.method.energy import arap_energy, cell_energies
    from arap.method.rotations import rotations_from_covariances
    from arap.method.weights import cotangent_laplacian
    from arap.notebook import Studio, studio
    from arap.puppet.imagemesh import ImageMesh, image_mesh
    from arap.puppet.warp import PuppetWarp, warp
    from arap.render.picture import Picture
    from arap.render.show import show
    from arap.solve.solver import ArapResult, ArapSolver


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'arap' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
