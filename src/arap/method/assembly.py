"""The energy's cells on a mesh, weighted by the painted stiffness, with their rigid regions: the one assembly that
the solver (:func:`arap.solve.prepared.prepare`) and the energy functions (:mod:`arap.method.energy`) share.

Vertex cells (``spokes``, ``spokes_and_rims``, ``smooth_rotations``; :mod:`arap.method.cells`) are one per vertex,
so per-vertex stiffness weighs them directly; element cells (``elements``; :mod:`arap.method.elements`) are one per
triangle or tetrahedron, weighed by :func:`arap.method.stiffness.element_stiffness`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError
from arap.method.cells import Cells, build_cells
from arap.method.elements import element_cells
from arap.method.rigid import rigid_regions
from arap.method.stiffness import element_stiffness, scale_cells

__all__ = ["Assembly", "assemble", "check_energy_for"]


@dataclass(frozen=True, eq=False)
class Assembly:
    """An energy's cells on one mesh.

    Attributes
    ----------
    rest : Cells
        The cells without stiffness.
    cells : Cells
        The cells scaled by their stiffness (``rest`` itself without stiffness).
    region : (c,) int64 array or None
        Rigid region of each cell (``-1``: none), None without rigid parts.
    weights : (c,) float64 array or None
        Each cell's stiffness.
    """

    rest: Cells
    cells: Cells
    region: NDArray[np.int64] | None
    weights: NDArray[np.float64] | None


def check_energy_for(energy: str, kind: str) -> None:
    """Refuse an energy that the kind of mesh (``"surface"``, ``"planar"``, ``"solid"``) has no cells for.

    Raises
    ------
    OptionError

    Example
    -------
    >>> check_energy_for("spokes", "solid")
    Traceback (most recent call last):
    ...
    arap.errors.OptionError: the spokes energy has cells on triangles; tetrahedra take energy='elements'
    """
    if kind == "solid" and energy != "elements":
        raise OptionError(f"the {energy} energy has cells on triangles; tetrahedra take energy='elements'")
    if kind == "planar" and energy == "smooth_rotations":
        raise OptionError("smooth_rotations turns rotations in space; a planar mesh takes 'elements' (the default), "
                          "'spokes_and_rims' or 'spokes'")


def assemble(V: NDArray[np.float64], F: NDArray[np.int64], graph_faces: NDArray[np.int64], energy: str,
             weights: str, planar: bool = False, stiffness: NDArray[np.float64] | None = None,
             rigid: NDArray[np.bool_] | None = None, order: NDArray[np.int64] | None = None) -> Assembly:
    """Build an energy's cells, weighted by per-vertex stiffness.

    Parameters
    ----------
    V : (n, 3) float64 array
        Rest positions (a planar mesh in ``z = 0``).
    F : (m, 3) or (m, 4) int64 array
        Triangles or tetrahedra, indices into ``V``.
    graph_faces : (k, 3) int64 array
        Triangles spanning the mesh's edges (``F`` for triangles; see :attr:`arap.meshes.domain.Domain.graph_faces`).
    energy, weights : str
        See :mod:`arap.options`.
    planar : bool
        Rotations about ``z``.
    stiffness : (n,) float64 array or None
        Checked per-vertex weights (:func:`arap.method.stiffness.check_stiffness`).
    rigid : (n,) bool array or None
        Vertices of rigid parts.
    order : (m,) int array or None
        Element cells only: the element behind each cell (for memory locality).

    Returns
    -------
    Assembly
    """
    region: NDArray[np.int64] | None = None
    if energy == "elements":
        rest = element_cells(V, F, weights, planar, order)
        cell_weights = None
        if stiffness is not None:
            T = F if order is None else F[order]
            cell_weights, cell_rigid = element_stiffness(T, stiffness, rigid if rigid is not None
                                                         else np.zeros(len(V), dtype=bool))
            if cell_rigid.any():
                labels = rigid_regions(graph_faces, rigid if rigid is not None else np.zeros(len(V), dtype=bool))
                region = np.where(cell_rigid, labels[T[:, 0]], -1)
        cells = rest if cell_weights is None else scale_cells(rest, cell_weights)
        return Assembly(rest=rest, cells=cells, region=region, weights=cell_weights)
    rest = build_cells(V, F, energy, weights, planar)
    cells = rest if stiffness is None else scale_cells(rest, stiffness)
    if rigid is not None and rigid.any():
        region = rigid_regions(F, rigid)
    return Assembly(rest=rest, cells=cells, region=region, weights=stiffness)
