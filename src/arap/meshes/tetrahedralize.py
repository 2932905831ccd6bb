"""Filling a closed surface with tetrahedra, and embedding points in a tetrahedral mesh.

:func:`tetrahedralize` calls fTetWild (Hu et al. 2020, "Fast Tetrahedral Meshing in the Wild") through its Python
bindings, `pytetwild <https://github.com/pyvista/pytetwild>`_ (``pip install 'arap[solid]'``), imported only when it
is called. fTetWild remeshes: the solid's boundary follows the surface within ``epsilon`` but does not keep its
vertices. fTetWild runs in a process of its own, in a temporary folder: it writes a file of its own in its working
folder (``__tracked_surface.stl``), and a crash in it cannot take the caller down.

:func:`embed_points` places any points (the surface's vertices) in the solid's tetrahedra by their barycentric
coordinates, and :func:`interpolate_points` carries them along with a deformation of the solid, a linear
interpolation that gives the points back exactly at rest.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arap.errors import ArapError, MeshError
from arap.meshes.domain import signed_measures
from arap.meshes.mesh import DEGENERATE_TOLERANCE, check_mesh

__all__ = ["embed_points", "interpolate_points", "tetrahedralize"]

logger = logging.getLogger(__name__)

_HINT = "pip install 'arap[solid]'"


def _check_tetwild() -> None:
    """Refuse at once when pytetwild is not installed (before a process is started for it)."""
    if importlib.util.find_spec("pytetwild") is None:
        raise ArapError(f"tetrahedralize needs fTetWild's Python bindings, pytetwild: {_HINT}")


def _tetwild() -> Any:
    """fTetWild's compiled module from pytetwild.

    The compiled module is loaded on its own: pytetwild's package imports PyVista on import (an optional
    dependency of pytetwild that its numpy interface does not use).
    """
    spec = importlib.util.find_spec("pytetwild")
    if spec is None or not spec.submodule_search_locations:
        raise ArapError(f"tetrahedralize needs fTetWild's Python bindings, pytetwild: {_HINT}")
    name = "pytetwild.PyfTetWildWrapper"
    for folder in spec.submodule_search_locations:
        for candidate in sorted(Path(folder).glob("PyfTetWildWrapper*")):
            if not any(str(candidate).endswith(suffix) for suffix in importlib.machinery.EXTENSION_SUFFIXES):
                continue
            loader = importlib.machinery.ExtensionFileLoader(name, str(candidate))
            module_spec = importlib.util.spec_from_file_location(name, candidate, loader=loader)
            if module_spec is None:
                continue
            module = importlib.util.module_from_spec(module_spec)
            loader.exec_module(module)
            return module
    raise ArapError(f"pytetwild is installed without its compiled fTetWild module; reinstall it: {_HINT}")


def _closed(F: NDArray[np.int64]) -> tuple[int, int]:
    """Boundary edges and non-manifold edges of a triangle mesh."""
    from arap.meshes.topology import edge_face_counts

    _, counts = edge_face_counts(F)
    return int((counts == 1).sum()), int((counts > 2).sum())


def tetrahedralize(V: ArrayLike, F: ArrayLike, *, edge_length: float = 0.05, epsilon: float = 1e-3,
                   optimize: bool = True, threads: int = 0) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Fill a closed triangle surface with tetrahedra (fTetWild), every one positively oriented.

    fTetWild remeshes the surface: the solid's boundary lies within ``epsilon`` of it, with vertices of its own. To
    deform the surface with the solid, embed its vertices (:func:`embed_points`) and interpolate
    (:func:`interpolate_points`).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        A closed (watertight) surface.
    edge_length : float
        Target edge length of the tetrahedra, relative to the bounding-box diagonal (0.05: a twentieth).
    epsilon : float
        Largest distance of the solid's boundary from the surface, relative to the bounding-box diagonal.
    optimize : bool
        Improve the tetrahedra's shape (fTetWild's optimisation; False is faster, with flatter tetrahedra).
    threads : int
        Threads fTetWild uses (0: all cores).

    Returns
    -------
    V_tet : (k, 3) float64 array
    T : (t, 4) int64 array
        Tetrahedra with positive signed volume, every vertex used.

    Raises
    ------
    MeshError
        An unusable surface (:func:`arap.check_mesh`), one that is not closed, or an fTetWild result with inverted,
        flat or no tetrahedra.
    OptionError
        ``edge_length`` or ``epsilon`` out of range.
    ArapError
        pytetwild is not installed.

    Example
    -------
    >>> import arap
    >>> V, F = arap.sphere(subdivisions=1)
    >>> V_tet, T = tetrahedralize(V, F, edge_length=0.2)   # doctest: +SKIP
    """
    from arap.errors import OptionError

    V, F = check_mesh(np.asarray(V), np.asarray(F))
    for name, value in (("edge_length", edge_length), ("epsilon", epsilon)):
        if not (isinstance(value, int | float) and 1e-6 <= value <= 1.0):
            raise OptionError(f"{name} must be a number from 1e-6 to 1 (a share of the bounding-box diagonal), got "
                              f"{value!r}")
    if not isinstance(threads, int) or threads < 0:
        raise OptionError(f"threads must be an integer >= 0, got {threads!r}")
    open_edges, non_manifold = _closed(F)
    if open_edges or non_manifold:
        raise MeshError(f"tetrahedralize fills a closed surface; this one has {open_edges:,} boundary edges and "
                        f"{non_manifold:,} non-manifold edges (close its holes first)")
    _check_tetwild()
    t0 = time.perf_counter()
    V_tet, T = _run_tetwild(V, F, np.array([edge_length, epsilon, float(bool(optimize)), threads], dtype=np.float64))
    logger.info("tetrahedralize: %d vertices, %d tetrahedra in %.2f s", len(V_tet), len(T),
                time.perf_counter() - t0)
    if T.ndim != 2 or T.shape[1] != 4 or not len(T):
        raise MeshError(f"fTetWild returned no tetrahedra for this surface ({len(V):,} vertices, {len(F):,} faces)")
    used = np.unique(T)
    if len(used) < len(V_tet):  # keep only the vertices of the tetrahedra, in their order
        index = np.full(len(V_tet), -1, dtype=np.int64)
        index[used] = np.arange(len(used))
        V_tet, T = V_tet[used], index[T]
    signed = signed_measures(V_tet, T)
    if (signed < 0).sum() * 2 > len(signed):  # fTetWild's own orientation is the opposite of the solver's
        T = T[:, [0, 2, 1, 3]]
        signed = -signed
    diag = float(np.linalg.norm(np.ptp(V_tet, axis=0)))
    bad = signed <= DEGENERATE_TOLERANCE * diag ** 3
    if bad.any():
        raise MeshError(f"fTetWild returned {int(bad.sum()):,} inverted or flat tetrahedra of {len(T):,} (first: "
                        f"{int(np.argmax(bad))}); try another edge_length or optimize=True")
    return V_tet, np.ascontiguousarray(T)


def _run_tetwild(V: NDArray[np.float64], F: NDArray[np.int64], options: NDArray[np.float64]) -> tuple[
        NDArray[np.float64], NDArray[np.int64]]:
    """fTetWild's tetrahedra, computed in a child process working in a temporary folder."""
    package_root = str(Path(__file__).resolve().parents[2])  # the folder holding the arap package
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([package_root, *filter(None, [env.get("PYTHONPATH")])])
    with tempfile.TemporaryDirectory(prefix="arap-tetwild-") as folder:
        np.savez(Path(folder) / "surface.npz", V=V, F=F, options=options)
        run = subprocess.run([sys.executable, "-c", "from arap.meshes.tetrahedralize import _child; _child()"],
                             cwd=folder, env=env, capture_output=True, text=True, check=False)
        result = Path(folder) / "solid.npz"
        if run.returncode != 0 or not result.exists():
            said = [line for line in (run.stderr or "").splitlines() if line.strip()]
            raise MeshError(f"fTetWild failed on this surface (exit status {run.returncode}"
                            f"{': ' + said[-1].strip() if said else ''})")
        with np.load(result) as data:
            return np.ascontiguousarray(data["V"], dtype=np.float64), np.ascontiguousarray(data["T"], dtype=np.int64)


def _child() -> None:
    """The child process of :func:`_run_tetwild`: reads ``surface.npz`` in its working folder, writes ``solid.npz``."""
    with np.load("surface.npz") as data:
        V, F, options = data["V"], data["F"], data["options"]
    edge_length, epsilon, optimize, threads = options.tolist()
    V_tet, T = _tetwild().tetrahedralize_mesh(
        np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.uint32),
        bool(optimize), False, float(edge_length), 0.0, float(epsilon), 10.0, False, int(threads), 80, 6, True,
        False, False, np.empty((0, 3)), np.empty((0, 4), dtype=np.int32), np.empty(0))
    np.savez("solid.npz", V=np.asarray(V_tet, dtype=np.float64), T=np.asarray(T, dtype=np.int64))


def _barycentric(V: NDArray[np.float64], T: NDArray[np.int64], tets: NDArray[np.int64],
                 P: NDArray[np.float64]) -> NDArray[np.float64]:
    """Barycentric coordinates (k, 4) of points ``P`` (k, 3) in tetrahedra ``tets`` (k,)."""
    corners = V[T[tets]]  # (k, 4, 3)
    E = corners[:, 1:, :] - corners[:, :1, :]  # (k, 3, 3): rows are edge vectors
    try:
        local = np.linalg.solve(np.transpose(E, (0, 2, 1)), (P - corners[:, 0, :])[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        raise MeshError("a tetrahedron is flat (zero volume): points cannot be embedded in it") from None
    return np.column_stack([1.0 - local.sum(axis=1), local])


def embed_points(V: ArrayLike, T: ArrayLike, P: ArrayLike, candidates: int = 16) -> tuple[
        NDArray[np.int64], NDArray[np.float64]]:
    """The tetrahedron holding each point, and the point's barycentric coordinates in it.

    A point inside the mesh gets a tetrahedron that contains it (coordinates in [0, 1]); a point outside (a surface
    vertex a little outside the solid fTetWild made) gets the nearby tetrahedron it is least outside of, and
    coordinates a little outside [0, 1]. Either way ``Σ_j b_j V[T[t, j]]`` is the point (up to round-off), so
    :func:`interpolate_points` gives it back at rest and carries it along linearly when the solid deforms.

    Parameters
    ----------
    V : (n, 3) float array
    T : (m, 4) int array
        Tetrahedra without flat ones.
    P : (k, 3) float array
    candidates : int
        Tetrahedra tried per point: those with the nearest centroids (more are tried for the points found in none).

    Returns
    -------
    tets : (k,) int64 array
    barycentric : (k, 4) float64 array
        Summing to 1.

    Example
    -------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> tets, b = embed_points(V, np.array([[0, 1, 2, 3]]), [[0.25, 0.25, 0.25]])
    >>> tets.tolist(), b.round(12).tolist()
    ([0], [[0.25, 0.25, 0.25, 0.25]])
    """
    from scipy.spatial import cKDTree

    V = np.asarray(V, dtype=np.float64)
    T = np.asarray(T, dtype=np.int64)
    P = np.asarray(P, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3 or T.ndim != 2 or T.shape[1] != 4 or not len(T):
        raise MeshError(f"embed_points needs vertices (n, 3) and tetrahedra (m, 4), got {V.shape} and {T.shape}")
    if P.ndim != 2 or P.shape[1] != 3 or not np.isfinite(P).all():
        raise MeshError(f"points must be a finite (k, 3) array, got shape {P.shape}")
    tree = cKDTree(V[T].mean(axis=1))
    best_tet = np.zeros(len(P), dtype=np.int64)
    best_bary = np.zeros((len(P), 4))
    todo = np.arange(len(P))
    k = min(max(int(candidates), 1), len(T))
    for _ in range(2):  # the nearest candidates, then four times as many for the points inside none of them
        _, near = tree.query(P[todo], k=k)
        near = np.asarray(near, dtype=np.int64).reshape(len(todo), k)
        bary = _barycentric(V, T, near.ravel(), np.repeat(P[todo], k, axis=0)).reshape(len(todo), k, 4)
        choice = bary.min(axis=2).argmax(axis=1)  # >= 0 inside; the larger, the less outside
        rows = np.arange(len(todo))
        best_tet[todo], best_bary[todo] = near[rows, choice], bary[rows, choice]
        todo = todo[best_bary[todo].min(axis=1) < -1e-12]
        if not len(todo) or k >= len(T):
            break
        k = min(4 * k, len(T))
    return best_tet, best_bary


def interpolate_points(U: ArrayLike, T: ArrayLike, tets: ArrayLike, barycentric: ArrayLike) -> NDArray[np.float64]:
    """Positions of embedded points (:func:`embed_points`) in the deformed tetrahedral mesh ``U``.

    Parameters
    ----------
    U : (n, 3) float array
        Positions of the tetrahedral mesh's vertices (deformed, or at rest).
    T : (m, 4) int array
    tets : (k,) int array
    barycentric : (k, 4) float array

    Returns
    -------
    (k, 3) float64 array
        ``Σ_j barycentric[:, j] U[T[tets, j]]``.

    Examples
    --------
    Points carried along by a tetrahedral mesh that moves as a whole:

    >>> import numpy as np, arap
    >>> V, T = arap.box_tetrahedra(2, 2, 2)
    >>> points = np.array([[0.25, 0.5, 0.5], [0.5, 0.5, 0.75]])
    >>> tets, barycentric = arap.embed_points(V, T, points)
    >>> moved = arap.interpolate_points(V + [1.0, 0.0, 0.0], T, tets, barycentric)
    >>> moved.round(6).tolist()
    [[1.25, 0.5, 0.5], [1.5, 0.5, 0.75]]
    """
    U = np.asarray(U, dtype=np.float64)
    T = np.asarray(T, dtype=np.int64)
    return np.einsum("kj,kjd->kd", np.asarray(barycentric, dtype=np.float64), U[T[np.asarray(tets, dtype=np.int64)]])
