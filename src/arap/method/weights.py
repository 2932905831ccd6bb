"""Edge weights and the cotangent Laplacian.

- ``cotangent``: ``w_ij = ½(cot α_ij + cot β_ij)`` (Pinkall & Polthier 1993; Meyer et al. 2003), the weights of
  Sorkine & Alexa 2007. Obtuse triangles make some of them negative.
- ``clamped``: the cotangent weights with negative values replaced by 0, as Open3D's
  ``TriangleMesh::DeformAsRigidAsPossible`` does (``ComputeEdgeWeightsCot`` with ``min_weight = 0``).
- ``uniform``: 1 on interior edges, ½ on boundary edges.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp

from arap.options import WeightType as WeightType  # the name the server modules import from here
from arap.options import check_weights
from arap.sparse._csr import csr_from_face_edges


def face_cotangents(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Cotangent of every corner angle.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array

    Returns
    -------
    (m, 3) float64 array
        ``C[f, k]`` is the cotangent of the angle of face ``f`` at its corner ``k``, i.e. the angle opposite the edge
        ``(F[f, k+1], F[f, k+2])``. Degenerate (zero-area) faces give ``inf``/``nan``; validate meshes first.
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    return _cotangent_kernel(V, F)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _cotangent_kernel(V, F):  # pragma: no cover - compiled
    cots = np.empty((F.shape[0], 3))
    for f in range(F.shape[0]):
        for k in range(3):
            a = F[f, k]
            b = F[f, (k + 1) % 3]
            c = F[f, (k + 2) % 3]
            u0 = V[b, 0] - V[a, 0]
            u1 = V[b, 1] - V[a, 1]
            u2 = V[b, 2] - V[a, 2]
            v0 = V[c, 0] - V[a, 0]
            v1 = V[c, 1] - V[a, 1]
            v2 = V[c, 2] - V[a, 2]
            x0 = u1 * v2 - u2 * v1
            x1 = u2 * v0 - u0 * v2
            x2 = u0 * v1 - u1 * v0
            cots[f, k] = (u0 * v0 + u1 * v1 + u2 * v2) / np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    return cots


def corner_weights(V: np.ndarray, F: np.ndarray, weights: str = "cotangent") -> np.ndarray:
    """Per-face contribution to the weight of the edge opposite each corner.

    ``cotangent``: ``½ cot`` of the corner angle, so an interior edge gets ``½(cot α + cot β)`` and a boundary edge
    the single term ``½ cot α``. ``clamped``: ``max(½ cot, 0)``, zero at obtuse corners (the per-triangle form of
    clamping, used by the spokes-and-rims cells, whose terms are per triangle). ``uniform``: ``½`` per face, so
    interior edges get 1 and boundary edges ½.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    (m, 3) float64 array
    """
    check_weights(weights)
    if weights == "cotangent":
        return 0.5 * face_cotangents(V, F)
    if weights == "clamped":
        return np.maximum(0.5 * face_cotangents(V, F), 0.0)
    return np.full((len(F), 3), 0.5)  # uniform


def edge_weight_matrix(V: np.ndarray, F: np.ndarray, weights: str = "cotangent") -> sp.csr_matrix:
    """Symmetric matrix of edge weights ``W[i, j] = w_ij`` (zero diagonal), shape (n, n).

    ``clamped`` clamps the summed edge weight, ``max(½(cot α + cot β), 0)``, as Open3D does.
    """
    if weights == "clamped":
        W = edge_weight_matrix(V, F, "cotangent")
        W.sum_duplicates()
        np.maximum(W.data, 0.0, out=W.data)
        return W
    F = np.asarray(F, dtype=np.int64)
    return csr_from_face_edges(F, len(V), corner_weights(V, F, weights))


def cotangent_laplacian(V: np.ndarray, F: np.ndarray, weights: str = "cotangent") -> sp.csr_matrix:
    """The (positive semi-definite) Laplacian ``L = D − W``: ``L_ij = −w_ij``, ``L_ii = Σ_j w_ij``.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    weights : {"cotangent", "clamped", "uniform"}

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        Symmetric, zero row sums.

    Examples
    --------
    >>> import numpy as np, arap
    >>> V, F = arap.sphere(1)
    >>> L = arap.cotangent_laplacian(V, F)
    >>> L.shape, bool(abs(L @ np.ones(len(V))).max() < 1e-12)     # constants are in its null space
    ((42, 42), True)
    """
    W = edge_weight_matrix(V, F, weights)
    d = np.asarray(W.sum(axis=1)).ravel()
    return (sp.diags(d) - W).tocsr()
