"""Starting poses for a cold solve: the rest pose, or the rest pose moved by the best-fit rigid motion of the targets.

The local/global iteration only descends to the nearest minimum, and from the rest pose it cannot undo a large
common rotation of all constraints: rotated 170°, the constrained vertices pull the surface through itself and the
iteration stalls far from the rigid motion (0.39 of the bounding-box diagonal off after 2,000 iterations, for us and
for libigl). Starting from the rest pose moved by the rigid motion that best maps the constrained vertices' rest
positions to their targets (weighted Procrustes, Kabsch 1976 with the reflection fix) is exact for such motions; the
solver takes it only when its energy is lower than the rest pose's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.meshes._geometry import barycentric_areas

__all__ = ["best_rigid_transform", "rigid_start", "vertex_areas"]


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


def rigid_start(V: NDArray[np.float64], constrained: NDArray[np.integer], targets: NDArray[np.float64],
                areas: NDArray[np.float64], fixed: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rest pose ``V`` moved by the best-fit rigid motion of the constrained vertices to their ``targets``
    (weighted by ``areas``), with the last ``len(fixed)`` rows (the non-free vertices) set to ``fixed``.

    Example
    -------
    One free vertex (row 0) follows the three constrained ones, turned 90° about z and shifted by 5 along x:

    >>> V = np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0], [0, 0, 0]])
    >>> T = np.array([[5.0, 1, 0], [4, 0, 0], [5, 0, 0]])
    >>> (rigid_start(V, np.array([1, 2, 3]), T, np.ones(4), T).round(9) + 0.0).tolist()
    [[5.0, 0.0, 1.0], [5.0, 1.0, 0.0], [4.0, 0.0, 0.0], [5.0, 0.0, 0.0]]
    """
    nf = len(V) - len(fixed)
    U = V.copy()
    if len(constrained):
        R, t = best_rigid_transform(V[constrained], targets, areas[constrained])
        U[:nf] = V[:nf] @ R.T + t
    U[nf:] = fixed
    return U


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


def vertex_areas(V: NDArray[np.float64], F: NDArray[np.integer]) -> NDArray[np.float64]:
    """Barycentric vertex areas: a third of the area of every incident triangle, shape (n,).

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); F = np.array([[0, 1, 2]])
    >>> vertex_areas(V, F).round(4).tolist()
    [0.1667, 0.1667, 0.1667]
    """
    return barycentric_areas(V, F)
