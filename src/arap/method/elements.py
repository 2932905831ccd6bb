"""Element cells: one rotation per triangle or tetrahedron (libigl's ``ARAP_ENERGY_TYPE_ELEMENTS``).

A cell is a single element; its terms are the element's edges, and its energy is
``Σ_(i,j) w_ij ‖(p'_i − p'_j) − R (p_i − p_j)‖²`` over them. With the cotangent weights (``w_ij = −|τ| ∇λ_i · ∇λ_j``,
``λ`` the element's barycentric coordinates and ``|τ|`` its area or volume: ``½ cot`` of the opposite angle in a
triangle, ``l_kl cot θ_kl / 6`` in a tetrahedron, ``θ_kl`` the dihedral angle at the opposite edge ``kl``) this is
exactly ``|τ| ‖J − R‖²_F`` for the element's deformation gradient ``J``: never negative, zero only for a rigid
motion of the element, obtuse angles or not. The system matrix they give is the cotangent Laplacian (times one).

``weights="clamped"`` sets negative weights to 0; ``"uniform"`` gives every edge ``½`` in a triangle and a sixth of the
mean edge length in a tetrahedron (the cotangent weights' scale).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.method.cells import Cells, finish_cells
from arap.options import check_weights

__all__ = ["element_cells", "element_weights", "vertex_measures"]

_TRIANGLE_EDGES = np.array([[1, 2], [2, 0], [0, 1]])
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def _gradients(V: NDArray[np.float64], T: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gradients of the barycentric coordinates of every element (m, k, d) and the elements' measures (m,)."""
    d = T.shape[1] - 1
    P = V[:, :d]
    E = np.stack([P[T[:, i]] - P[T[:, 0]] for i in range(1, d + 1)], axis=1)  # (m, d, d): rows are edge vectors
    det = np.linalg.det(E)
    inv = np.linalg.inv(E)  # columns of inv are ∇λ_1..∇λ_d (E inv = I)
    G = np.empty((len(T), d + 1, d))
    G[:, 1:, :] = np.transpose(inv, (0, 2, 1))
    G[:, 0, :] = -G[:, 1:, :].sum(axis=1)
    measure = np.abs(det) / (2.0 if d == 2 else 6.0)
    return G, measure


def _triangle_gradients(V: NDArray[np.float64], T: NDArray[np.int64]) -> tuple[NDArray[np.float64],
                                                                              NDArray[np.float64]]:
    """The same for triangles in space: gradients within each triangle's plane."""
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    n = np.cross(b - a, c - a)
    double = np.linalg.norm(n, axis=1)
    G = np.empty((len(T), 3, 3))
    # ∇λ_i = n × (opposite edge) / |n|², the opposite edge taken counter-clockwise about n.
    for i, (p, q) in enumerate(((b, c), (c, a), (a, b))):
        G[:, i, :] = np.cross(n, q - p) / (double * double)[:, None]
    return G, 0.5 * double


def element_weights(V: NDArray[np.float64], T: NDArray[np.int64], weights: str = "cotangent",
                    planar: bool = True) -> NDArray[np.float64]:
    """The weight of every edge of every element, shape (m, 3) for triangles (edges opposite corners 0, 1, 2) or
    (m, 6) for tetrahedra (edges 01, 02, 03, 12, 13, 23).

    Parameters
    ----------
    V : (n, 3) float64 array
        Positions (planar triangles in ``z = 0``).
    T : (m, 3) or (m, 4) int64 array
    weights : {"cotangent", "clamped", "uniform"}
    planar : bool
        Triangles lie in ``z = 0`` (else: triangles in space).

    Example
    -------
    A right isosceles triangle: ``½ cot 45° = ½`` at the legs, ``½ cot 90° = 0`` at the hypotenuse.

    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> (element_weights(V, np.array([[0, 1, 2]])).round(12) + 0.0).tolist()
    [[0.0, 0.5, 0.5]]
    """
    check_weights(weights)
    T = np.asarray(T, dtype=np.int64)
    edges = _TRIANGLE_EDGES if T.shape[1] == 3 else _TET_EDGES
    if weights == "uniform":
        if T.shape[1] == 3:
            return np.full((len(T), 3), 0.5)
        lengths = np.linalg.norm(V[T[:, edges[:, 0]]] - V[T[:, edges[:, 1]]], axis=2)
        return np.repeat(lengths.mean(axis=1, keepdims=True) / 6.0, 6, axis=1)
    G, measure = _gradients(V, T) if (T.shape[1] == 4 or planar) else _triangle_gradients(V, T)
    w = -measure[:, None] * np.einsum("mkd,mkd->mk", G[:, edges[:, 0]], G[:, edges[:, 1]])
    return np.maximum(w, 0.0) if weights == "clamped" else w


def element_cells(V: NDArray[np.float64], T: NDArray[np.int64], weights: str = "cotangent",
                  planar: bool = False, order: NDArray[np.int64] | None = None) -> Cells:
    """One cell per element, its terms the element's edges (see the module's description).

    Parameters
    ----------
    V : (n, 3) float64 array
    T : (m, 3) or (m, 4) int64 array
        Vertex indices into ``V``.
    weights : {"cotangent", "clamped", "uniform"}
    planar : bool
        The mesh lies in ``z = 0`` and its rotations are about ``z`` (2×2).
    order : (m,) int array or None
        The element behind each cell (None: cell ``c`` is element ``c``).

    Returns
    -------
    Cells
        ``n_cells = m``; terms ``(T[e, i], T[e, j], w)``.

    Example
    -------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> cells = element_cells(V, np.array([[0, 1, 2, 3]]))
    >>> cells.n_cells, len(cells.a), bool(cells.w.sum() > 0)
    (1, 6, True)
    """
    T = np.asarray(T, dtype=np.int64)
    if order is not None:
        T = T[order]
    edges = _TRIANGLE_EDGES if T.shape[1] == 3 else _TET_EDGES
    w = element_weights(V, T, weights, planar)
    k = len(edges)
    ptr = np.arange(0, k * len(T) + 1, k, dtype=np.int64)
    a = T[:, edges[:, 0]].ravel()
    b = T[:, edges[:, 1]].ravel()
    return finish_cells(V, ptr, a, b, w.ravel(), planar=planar)


def vertex_measures(V: NDArray[np.float64], T: NDArray[np.int64]) -> NDArray[np.float64]:
    """A third of every triangle's area or a quarter of every tetrahedron's volume at each of its corners, (n,).

    Example
    -------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> (vertex_measures(V, np.array([[0, 1, 2, 3]])) * 24).round(12).tolist()
    [1.0, 1.0, 1.0, 1.0]
    """
    T = np.asarray(T, dtype=np.int64)
    if T.shape[1] == 3:
        e1, e2 = V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]
        measure = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    else:
        e1, e2, e3 = (V[T[:, i]] - V[T[:, 0]] for i in (1, 2, 3))
        measure = np.abs(np.einsum("ij,ij->i", np.cross(e1, e2), e3)) / 6.0
    k = T.shape[1]
    return np.bincount(T.ravel(), weights=np.repeat(measure / k, k), minlength=len(V)).astype(np.float64)
