"""What :meth:`arap.ArapSolver.solve` returns: the result record, and the least tolerance a solve can reach.

The options it takes (their names, defaults and checks) are in :mod:`arap.options`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError

if TYPE_CHECKING:
    import trimesh

__all__ = ["ROUNDING_FLOOR", "ArapResult", "IterationCallback", "rounding_floor"]

IterationCallback = Callable[[int, float], "bool | None"]

#: The least tolerance of :meth:`ArapSolver.solve`, in units of the rounding of the largest coordinate the solve
#: handles (relative to the diagonal): targets placed ``k`` diagonals beyond the mesh leave the plain step a rounding
#: floor of about 6-11 ``ε k`` (measured at ``k`` = 1e6 and 1e9), which a tolerance of 1e-10 would never reach from
#: ``k`` ≈ 1e5 on. Within ordinary reach (``k`` below about 7,000) the floor is below the default tolerance.
ROUNDING_FLOOR = 64.0

@dataclass
class ArapResult:
    """Outcome of :meth:`ArapSolver.solve`.

    Attributes
    ----------
    vertices : (n, 3) float64 array
        Deformed positions; constrained vertices are exactly at their targets.
    energies : list of float
        ARAP energy (with optimal rotations) after each iteration.
    iterations : int
        Iterations run: every one passed to the callback, one per entry of ``energies`` (with those of a run an
        element solve gave up after opening the elements it turned over, see :func:`arap.solve.loops.lbfgs_iterations`).
    converged : bool
        True if the last iteration's plain step was within ``tolerance`` (see :meth:`ArapSolver.solve`); False when
        the iteration cap or the callback stopped it first.
    timings : dict of str to float
        Seconds spent, summed over iterations: ``local`` (covariances, rotations, energy), ``rhs``, ``solve``,
        ``acceleration``, and ``total`` for the whole call.
    residual : float
        Root-mean-square step of the plain iteration at the last iterate, relative to the bounding-box diagonal
        (NaN if no iteration ran).
    start : {"warm", "rest", "rigid", "given"}
        Where the iteration started (see ``initial``).
    rejected : int
        Accelerated steps rejected by the energy safeguard: Anderson extrapolations, or L-BFGS line searches that
        found no lower energy (the plain step was taken instead).

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> result = arap.ArapSolver(V, F, [0, 1]).solve(V[[0, 1]] + [0.0, 0.0, 0.5])   # a translation
    >>> bool(result.converged), result.vertices.shape, bool(abs(result.vertices[:, 2] - V[:, 2] - 0.5).max() < 1e-6)
    (True, (42, 3), True)
    """

    vertices: NDArray[np.float64]
    energies: list[float]
    iterations: int
    converged: bool
    timings: dict[str, float] = field(default_factory=dict)
    residual: float = float("nan")
    start: str = "rest"
    rejected: int = 0

    def to_trimesh(self, mesh: Any) -> trimesh.Trimesh:
        """The deformed mesh as a ``trimesh.Trimesh``.

        Parameters
        ----------
        mesh : (m, 3) int array or arap.io.MeshAsset
            The faces the solve used, or the asset the solve came from (its ``solve_mesh()`` or its file vertices):
            then its texture (first UV set and image) or vertex colours are kept.
        """
        if hasattr(mesh, "to_trimesh"):  # an asset converts positions on itself (arap.io.MeshAsset.to_trimesh)
            return mesh.to_trimesh(self.vertices)
        F = np.asarray(mesh)
        if F.ndim != 2 or F.shape[1] != 3 or not np.issubdtype(F.dtype, np.integer):
            raise MeshError("to_trimesh needs the faces (m, 3) or the MeshAsset the solve came from")
        import trimesh

        return trimesh.Trimesh(vertices=np.asarray(self.vertices, dtype=np.float64), faces=F, process=False)


def rounding_floor(diagonal: float, *targets: NDArray[np.float64] | None) -> float:
    """The least meaningful tolerance of a solve: :data:`ROUNDING_FLOOR` times the rounding of the largest
    coordinate, relative to the diagonal (the plain step cannot fall below it).

    Parameters
    ----------
    diagonal : float
        The mesh's bounding-box diagonal; the rest shape lies within it of the solver's origin.
    *targets : (k, 3) float arrays or None
        Target positions, relative to the solver's origin.

    Returns
    -------
    float

    Example
    -------
    >>> from arap.options import DEFAULT_TOLERANCE
    >>> rounding_floor(1.0, np.zeros((2, 3))) < DEFAULT_TOLERANCE < rounding_floor(1.0, np.full((2, 3), 1e6))
    True
    """
    reach = diagonal
    for X in targets:
        if X is not None and X.size:
            reach = max(reach, -float(X.min()), float(X.max()))  # whole-array reductions: fast on (k, 3) arrays
    return ROUNDING_FLOOR * float(np.finfo(np.float64).eps) * reach / diagonal
