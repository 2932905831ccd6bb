"""Geometry of meshes and point sets: per-face and per-vertex areas, vertex normals, and the rigid motion that best maps
one point set onto another.

The areas are compiled for the set-up of large meshes: the same arithmetic as the NumPy expressions they replace
(cross products, norms, sums in face order), so the results are the same bit for bit, without the temporary (m, 3)
arrays."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)

__all__ = ["barycentric_areas", "best_rigid_transform", "double_areas", "vertex_normals"]


def double_areas(V: NDArray[np.floating], F: NDArray[np.integer]) -> NDArray[np.float64]:
    """Twice the area of every face, ``‖(V[b] − V[a]) × (V[c] − V[a])‖``.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Indices in range (not checked).

    Returns
    -------
    (m,) float64 array
    """
    return _double_areas(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F))


def barycentric_areas(V: NDArray[np.floating], F: NDArray[np.integer]) -> NDArray[np.float64]:
    """Barycentric vertex areas: a third of the area of every face added to each of its corners, face after face.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Indices in range (not checked).

    Returns
    -------
    (n,) float64 array

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); F = np.array([[0, 1, 2]])
    >>> barycentric_areas(V, F).round(4).tolist()
    [0.1667, 0.1667, 0.1667]
    """
    return _barycentric_areas(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F))


def vertex_normals(V: NDArray[np.float64], F: NDArray[np.int64]) -> NDArray[np.float64]:
    """Area-weighted unit vertex normals, shape (n, 3); zero for vertices of no (non-degenerate) face.

    Example
    -------
    >>> vertex_normals(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])).tolist()
    [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    """
    P = V[F]
    face = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])  # twice the area times the unit normal
    N = np.zeros_like(V)
    for k in range(3):
        for j in range(3):
            N[:, j] += np.bincount(F[:, k], weights=face[:, j], minlength=len(V))
    length = np.sqrt(np.einsum("ij,ij->i", N, N))
    return N / np.where(length > 0, length, 1.0)[:, None]


def best_rigid_transform(
    P: NDArray[np.float64], Q: NDArray[np.float64], weights: NDArray[np.float64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation ``R`` and translation ``t`` minimising ``Σ_k w_k ‖R p_k + t − q_k‖²`` (weighted Procrustes).

    Parameters
    ----------
    P, Q : (k, 3) float arrays
        Source and target points (k ≥ 1).
    weights : (k,) float array or None
        Non-negative weights (None: all 1). A zero total weight falls back to equal weights.

    Returns
    -------
    R : (3, 3) float64 array
        A proper rotation (det +1), also when the best orthogonal map would be a reflection. With fewer than three
        non-collinear points the rotation about their line is not determined; the one closest to the identity
        among the optima is returned.
    t : (3,) float64 array

    Examples
    --------
    >>> import numpy as np
    >>> P = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> Rz = np.array([[-1., 0, 0], [0, -1, 0], [0, 0, 1]])     # 180° about z
    >>> R, t = best_rigid_transform(P, P @ Rz.T + [1, 2, 3])
    >>> bool(np.allclose(R, Rz)), bool(np.allclose(t, [1, 2, 3]))
    (True, True)
    """
    P = np.asarray(P, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)
    w = np.ones(len(P)) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.sum() <= 0:
        w = np.ones(len(P))
    w = w / w.sum()
    cp = w @ P
    cq = w @ Q
    H = (P - cp).T @ ((Q - cq) * w[:, None])  # Σ w p qᵀ; the best R maximises tr(R H)
    U, s, Vt = np.linalg.svd(H)
    D = np.eye(3)
    # Singular values that vanish leave directions free: keep those as the identity would (rank-deficient fits).
    scale = max(float(s[0]), 1e-300)
    if s[0] <= 1e-300:
        return np.eye(3), cq - cp
    if s[1] <= 1e-12 * scale:
        R = _smallest_rotation(U[:, 0], Vt[0])
        return R, cq - R @ cp
    D[2, 2] = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ D @ U.T
    return R, cq - R @ cp


def _smallest_rotation(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation of least angle taking the unit vector ``a`` to the unit vector ``b`` (Rodrigues)."""
    axis = np.cross(a, b)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(a, b))
    if s <= 1e-12:
        if c > 0:
            return np.eye(3)
        # Opposite directions: half a turn about any axis perpendicular to a.
        p = np.eye(3)[int(np.argmin(np.abs(a)))]
        k = np.cross(a, p)
        k /= np.linalg.norm(k)
        return 2.0 * np.outer(k, k) - np.eye(3)
    k = axis / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


@nb.njit(cache=True, nogil=True, inline="always")
def _face_double_area(V, F, f):  # pragma: no cover - compiled
    a = F[f, 0]
    b = F[f, 1]
    c = F[f, 2]
    b0 = V[b, 0] - V[a, 0]
    b1 = V[b, 1] - V[a, 1]
    b2 = V[b, 2] - V[a, 2]
    c0 = V[c, 0] - V[a, 0]
    c1 = V[c, 1] - V[a, 1]
    c2 = V[c, 2] - V[a, 2]
    x = b1 * c2 - b2 * c1
    y = b2 * c0 - b0 * c2
    z = b0 * c1 - b1 * c0
    return np.sqrt(x * x + y * y + z * z)


@nb.njit(cache=True, nogil=True)
def _double_areas(V, F):  # pragma: no cover - compiled
    out = np.empty(F.shape[0])
    for f in range(F.shape[0]):
        out[f] = _face_double_area(V, F, f)
    return out


@nb.njit(cache=True, nogil=True)
def _barycentric_areas(V, F):  # pragma: no cover - compiled
    out = np.zeros(V.shape[0])
    for f in range(F.shape[0]):
        third = 0.5 * _face_double_area(V, F, f) / 3.0
        out[F[f, 0]] += third
        out[F[f, 1]] += third
        out[F[f, 2]] += third
    return out
