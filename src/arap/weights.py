"""Edge weights: cotangent (Pinkall & Polthier 1993; Meyer et al. 2003) and uniform, and the cotangent Laplacian."""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp

from arap._csr import csr_from_triplets

WeightType = Literal["cotangent", "uniform"]
WEIGHT_TYPES: tuple[str, ...] = ("cotangent", "uniform")


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
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    P0, P1, P2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    cots = np.empty((len(F), 3))
    for k, (a, b, c) in enumerate(((P0, P1, P2), (P1, P2, P0), (P2, P0, P1))):
        u = b - a
        v = c - a
        dot = np.einsum("ij,ij->i", u, v)
        cross = np.linalg.norm(np.cross(u, v), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            cots[:, k] = dot / cross
    return cots


def corner_weights(V: np.ndarray, F: np.ndarray, weights: str = "cotangent") -> np.ndarray:
    """Per-face contribution to the weight of the edge opposite each corner.

    ``cotangent``: ``½ cot`` of the corner angle, so an interior edge gets ``½(cot α + cot β)`` and a boundary edge
    the single term ``½ cot α``. ``uniform``: ``½`` per face, so interior edges get 1 and boundary edges ½.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    weights : {"cotangent", "uniform"}

    Returns
    -------
    (m, 3) float64 array
    """
    if weights == "cotangent":
        return 0.5 * face_cotangents(V, F)
    if weights == "uniform":
        return np.full((len(F), 3), 0.5)
    raise ValueError(f"unknown weights {weights!r}; expected one of {WEIGHT_TYPES}")


def edge_weight_matrix(V: np.ndarray, F: np.ndarray, weights: str = "cotangent") -> sp.csr_matrix:
    """Symmetric matrix of edge weights ``W[i, j] = w_ij`` (zero diagonal), shape (n, n)."""
    n = len(V)
    F = np.asarray(F, dtype=np.int64)
    cw = corner_weights(V, F, weights)
    i = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    j = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    w = np.concatenate([cw[:, 0], cw[:, 1], cw[:, 2]])
    return csr_from_triplets(np.concatenate([i, j]), np.concatenate([j, i]), np.concatenate([w, w]), n)


def cotangent_laplacian(V: np.ndarray, F: np.ndarray, weights: str = "cotangent") -> sp.csr_matrix:
    """The (positive semi-definite) Laplacian ``L = D − W``: ``L_ij = −w_ij``, ``L_ii = Σ_j w_ij``.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    weights : {"cotangent", "uniform"}

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix
        Symmetric, zero row sums.
    """
    W = edge_weight_matrix(V, F, weights)
    d = np.asarray(W.sum(axis=1)).ravel()
    return (sp.diags(d) - W).tocsr()
