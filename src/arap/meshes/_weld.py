"""Welding of coincident and nearly coincident vertices and detection of duplicate faces (for repair and
diagnosis of meshes)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _cc
from scipy.spatial import cKDTree

__all__: list[str] = []


def _first_equal_row(A: np.ndarray) -> np.ndarray:
    """For every row of ``A`` (k, c), the index of the first row equal to it (itself if unique)."""
    k = len(A)
    if k == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.lexsort(A.T[::-1])  # stable: equal rows keep their original order
    S = A[order]
    starts = np.ones(k, dtype=bool)
    starts[1:] = np.any(S[1:] != S[:-1], axis=1)
    group = np.cumsum(starts) - 1
    rep = np.empty(k, dtype=np.int64)
    rep[order] = order[np.flatnonzero(starts)][group]
    return rep


_WELD_DIRECTION = np.array([0.6012, 0.5321, 0.5963]) / np.linalg.norm([0.6012, 0.5321, 0.5963])
_WELD_MAX_RUN = 32


def _weld_groups(V: np.ndarray, tol: float) -> np.ndarray:
    """Representative (smallest index) of every vertex after welding points closer than ``tol``.

    Points closer than ``tol`` are closer than ``tol`` along any direction: sorted along one (not an axis, which
    grid-like meshes share), such pairs lie in runs of neighbours less than ``tol`` apart, and only pairs within a
    run are measured. Long runs (many points on a plane across that direction) go to a k-d tree.
    """
    n = len(V)
    if n < 2:
        return np.arange(n, dtype=np.int64)
    P = V + 0.0  # turns -0.0 into 0.0
    s = P @ _WELD_DIRECTION
    order = np.argsort(s, kind="stable")
    ss = s[order]
    slack = tol + 8 * np.finfo(np.float64).eps * float(np.abs(ss).max())
    run = np.concatenate(([0], np.cumsum(np.diff(ss) > slack)))
    longest = int(np.bincount(run).max())
    if longest > _WELD_MAX_RUN:
        return _weld_groups_tree(V, tol)
    pairs = []
    for k in range(1, longest):
        i = np.flatnonzero(run[:-k] == run[k:])
        a, b = order[i], order[i + k]
        d = P[a] - P[b]
        close = np.einsum("ij,ij->i", d, d) <= tol * tol
        pairs.append(np.stack([a[close], b[close]], axis=1))
    return _component_minimum(np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64), n)


def _component_minimum(pairs: np.ndarray, n: int) -> np.ndarray:
    """Smallest index of every vertex's connected component in the graph of edges ``pairs``."""
    if not len(pairs):
        return np.arange(n, dtype=np.int64)
    G = sp.coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = _cc(G, directed=False)
    first = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, labels, np.arange(n, dtype=np.int64))
    return first[labels]


def _weld_groups_tree(V: np.ndarray, tol: float) -> np.ndarray:
    """:func:`_weld_groups` with exact duplicates found by sorting and close points by a k-d tree."""
    n = len(V)
    rep = _first_equal_row(V + 0.0)  # + 0.0 turns -0.0 into 0.0
    first = np.flatnonzero(rep == np.arange(n))
    inverse = np.searchsorted(first, rep)
    if tol > 0 and len(first) > 1:
        U = V[first]
        pairs = cKDTree(U).query_pairs(tol, output_type="ndarray")
        if len(pairs):
            k = len(U)
            G = sp.coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
            _, labels = _cc(G, directed=False)
            group_first = np.full(labels.max() + 1, n, dtype=np.int64)
            np.minimum.at(group_first, labels, first)
            rep = group_first[labels][inverse]
    return rep


def _unique_face_mask(F: np.ndarray) -> np.ndarray:
    """True for the first occurrence of every face (same vertex set, either orientation)."""
    S = np.sort(F, axis=1)
    n = int(S.max()) + 1 if len(S) else 1
    if n >= 2**21:  # the three indices do not fit one int64 key
        return _first_equal_row(S) == np.arange(len(F))
    key = (S[:, 0] * n + S[:, 1]) * n + S[:, 2]
    order = np.argsort(key, kind="stable")  # equal keys keep their order: the first comes first
    k = key[order]
    keep = np.ones(len(F), dtype=bool)
    keep[order[1:][k[1:] == k[:-1]]] = False
    return keep
