"""Compiled per-face geometry for the set-up of large meshes: the same arithmetic as the NumPy expressions it
replaces (cross products, norms, sums in face order), so the results are the same bit for bit, without the
temporary (m, 3) arrays."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)


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
    """A third of the area of every face added to each of its corners, face after face.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Indices in range (not checked).

    Returns
    -------
    (n,) float64 array
    """
    return _barycentric_areas(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F))


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
