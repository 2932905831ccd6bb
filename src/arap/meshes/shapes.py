"""Built-in triangle meshes generated in code: editing demos and benchmark spheres.

Every built-in is a single closed, manifold, genus-0 surface without degenerate faces, standing on the plane
``y = 0`` (y is up) and centred on the y axis. They are deterministic: the same call always returns the same
arrays.

- ``bar``: a 1 × 5 × 1 box, each side a uniform grid of right triangles.
- ``cylinder``: radius 0.5, height 4, flat caps; near-equilateral triangles (staggered rings).
- ``cactus``: a trunk with two arms, a smooth Catmull–Clark surface built from a block cage, about 5 tall.

Two generators make meshes like real scans, with many obtuse triangles and so many negative cotangent weights
(seeded, deterministic, not built-ins): :func:`obtuse_cylinder` and :func:`scan_blob`.

Examples
--------
>>> import arap
>>> arap.BUILTIN_MESHES
('cactus', 'bar', 'cylinder')
>>> [arap.builtin_mesh(name)[0].shape[1] for name in arap.BUILTIN_MESHES]
[3, 3, 3]
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError
from arap.meshes.repair import repair_mesh
from arap.meshes.spheres import MAX_SPHERE_VERTICES, sphere, sphere_frequency_for

__all__ = ["BUILTIN_MESHES", "DEFAULT_SPHERE_SUBDIVISIONS", "builtin_mesh", "obtuse_cylinder", "scan_blob", "sphere",
           "sphere_frequency_for"]

BUILTIN_MESHES = ("cactus", "bar", "cylinder")
"""The named demo shapes. :func:`builtin_mesh` also takes ``"sphere"`` and ``"sphere:N"`` (about N vertices)."""

DEFAULT_SPHERE_SUBDIVISIONS = 6
"""Subdivisions of the built-in ``"sphere"``: 40,962 vertices."""



# ---------------------------------------------------------------------------------------------- helpers
def _orient_outward(V: np.ndarray, F: np.ndarray, center: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Flip faces whose normal points towards ``center(centroids)`` (valid for locally convex parts)."""
    P = V[F]
    normal = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    centroid = P.mean(axis=1)
    inward = np.einsum("ij,ij->i", normal, centroid - center(centroid)) < 0
    F = F.copy()
    F[inward] = F[inward][:, ::-1]
    return F


def _split_quads(V: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Triangles from quads (a, b, c, d), each cut along its shorter diagonal."""
    d_ac = np.linalg.norm(V[Q[:, 0]] - V[Q[:, 2]], axis=1)
    d_bd = np.linalg.norm(V[Q[:, 1]] - V[Q[:, 3]], axis=1)
    use_ac = d_ac <= d_bd
    t_ac = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    t_bd = np.concatenate([Q[:, [0, 1, 3]], Q[:, [1, 2, 3]]])
    mask = np.concatenate([use_ac, use_ac])
    return np.where(mask[:, None], t_ac, t_bd)


# ---------------------------------------------------------------------------------------------- bar
def _bar(divisions: int = 14, length: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Box [-0.5, 0.5] × [0, length] × [-0.5, 0.5] with ``divisions`` grid cells per unit."""
    n = divisions
    size = np.array([n, length * n, n])
    points: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    offset = 0
    for axis in range(3):
        u_ax, v_ax = [a for a in range(3) if a != axis]
        nu, nv = size[u_ax], size[v_ax]
        iu, iv = np.meshgrid(np.arange(nu + 1), np.arange(nv + 1), indexing="ij")
        grid = (iu * (nv + 1) + iv).astype(np.int64)
        a, b, c, d = grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]
        flip = ((iu[:-1, :-1] + iv[:-1, :-1]) % 2).astype(bool)
        t1 = np.where(flip[..., None], np.stack([a, b, d], -1), np.stack([a, b, c], -1)).reshape(-1, 3)
        t2 = np.where(flip[..., None], np.stack([b, c, d], -1), np.stack([a, c, d], -1)).reshape(-1, 3)
        for side in (0, size[axis]):
            P = np.zeros(((nu + 1) * (nv + 1), 3), dtype=np.int64)
            P[:, u_ax] = iu.ravel()
            P[:, v_ax] = iv.ravel()
            P[:, axis] = side
            points.append(P)
            tris.append(np.concatenate([t1, t2]) + offset)
            offset += len(P)
    lattice = np.concatenate(points)
    F = np.concatenate(tris)
    repaired = repair_mesh(lattice.astype(np.float64), F, weld_tolerance=0.0)  # weld shared box edges
    V = repaired.V / n - np.array([0.5, 0.0, 0.5])
    F = _orient_outward(V, repaired.F, lambda c: np.array([0.0, length / 2, 0.0]))
    return V, F


# ---------------------------------------------------------------------------------------------- revolution
def _band(lower: np.ndarray, a_lower: np.ndarray, upper: np.ndarray, a_upper: np.ndarray) -> list[list[int]]:
    """Triangles between two rings of vertex ids with increasing angles in [0, 2π)."""
    n, m = len(lower), len(upper)
    a = np.append(a_lower, a_lower[0] + 2 * np.pi)
    b = np.append(a_upper, a_upper[0] + 2 * np.pi)
    i = j = 0
    out: list[list[int]] = []
    while i < n or j < m:
        step_lower = j == m or (i < n and a[i + 1] < b[j + 1])
        if step_lower:
            if n > 1:
                out.append([int(lower[i % n]), int(lower[(i + 1) % n]), int(upper[j % m])])
            i += 1
        else:
            if m > 1:
                out.append([int(lower[i % n]), int(upper[(j + 1) % m]), int(upper[j % m])])
            j += 1
    return out


def _revolve(profile: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed surface of revolution about the y axis from a profile of (radius, height) points.

    The profile starts and ends on the axis (radius 0); each ring gets about ``2π r / spacing`` vertices, and
    rings of equal count are staggered by half a step so the triangles are close to equilateral.
    """
    verts: list[np.ndarray] = []
    rings: list[tuple[np.ndarray, np.ndarray]] = []
    count = 0
    previous_n = 0
    for k, (r, y) in enumerate(profile):
        n = 1 if r <= 0 else max(6, round(2 * np.pi * r / spacing))
        stagger = 0.5 if (n == previous_n and k % 2) else 0.0
        angles = (np.arange(n) + stagger) * (2 * np.pi / n)
        verts.append(np.stack([r * np.sin(angles), np.full(n, y), r * np.cos(angles)], axis=1))
        rings.append((np.arange(count, count + n), angles))
        count += n
        previous_n = n
    F: list[list[int]] = []
    for (lo, a_lo), (hi, a_hi) in itertools.pairwise(rings):
        F.extend(_band(lo, a_lo, hi, a_hi))
    V = np.concatenate(verts)
    F_arr = np.asarray(F, dtype=np.int64)
    return V, F_arr


def _cylinder(radius: float = 0.5, height: float = 4.0, spacing: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    row = spacing * np.sqrt(3) / 2
    n_cap = int(np.ceil(radius / spacing))
    n_side = int(np.ceil(height / row))
    cap = np.linspace(0.0, radius, n_cap + 1)
    side = np.linspace(0.0, height, n_side + 1)
    profile = np.concatenate([
        np.stack([cap, np.zeros_like(cap)], axis=1),
        np.stack([np.full(n_side - 1, radius), side[1:-1]], axis=1),
        np.stack([cap[::-1], np.full_like(cap, height)], axis=1),
    ])
    V, F = _revolve(profile, spacing)
    F = _orient_outward(V, F, lambda c: np.stack([np.zeros(len(c)), np.full(len(c), height / 2), np.zeros(len(c))],
                                                 axis=1))
    return V, F


# ---------------------------------------------------------------------------------------------- cactus
# Blocks (x, y, z) of the control cage: a trunk with a low left arm and a higher right arm.
_CACTUS_BLOCKS = (
    [(0, y, 0) for y in range(10)]
    + [(-1, 3, 0), (-2, 3, 0), (-2, 4, 0), (-2, 5, 0), (-2, 6, 0)]
    + [(1, 5, 0), (2, 5, 0), (2, 6, 0), (2, 7, 0), (2, 8, 0)]
)

# Corners of the unit cube's faces, counter-clockwise seen from outside, by outward direction.
_CUBE_FACES = {
    (1, 0, 0): [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)],
    (-1, 0, 0): [(0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)],
    (0, 1, 0): [(0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)],
    (0, -1, 0): [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],
    (0, 0, 1): [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
    (0, 0, -1): [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)],
}


def _block_cage(blocks: list[tuple[int, int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """Quad surface of a union of unit cubes (faces between two cubes removed), vertices shared."""
    occupied = set(blocks)
    corners: dict[tuple[int, int, int], int] = {}
    quads: list[list[int]] = []
    for bx, by, bz in blocks:
        for (dx, dy, dz), face in _CUBE_FACES.items():
            if (bx + dx, by + dy, bz + dz) in occupied:
                continue
            quad = []
            for cx, cy, cz in face:
                key = (bx + cx, by + cy, bz + cz)
                quad.append(corners.setdefault(key, len(corners)))
            quads.append(quad)
    V = np.zeros((len(corners), 3))
    for key, idx in corners.items():
        V[idx] = key
    return V, np.asarray(quads, dtype=np.int64)


def _catmull_clark(V: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One Catmull–Clark step on a closed quad mesh; returns (vertices, quads)."""
    n, q = len(V), len(Q)
    face_pts = V[Q].mean(axis=1)
    a = Q.ravel()
    b = np.roll(Q, -1, axis=1).ravel()
    key = np.minimum(a, b) * n + np.maximum(a, b)
    uniq, edge_of = np.unique(key, return_inverse=True)
    edge_of = edge_of.reshape(q, 4)  # edge_of[f, k] is the edge (Q[f, k], Q[f, k+1])
    e0, e1 = uniq // n, uniq % n
    e_faces = np.zeros((len(uniq), 3))
    np.add.at(e_faces, edge_of.ravel(), np.repeat(face_pts, 4, axis=0))
    edge_pts = (V[e0] + V[e1] + e_faces) / 4.0  # closed mesh: two faces per edge

    valence = np.bincount(np.concatenate([e0, e1]), minlength=n).astype(np.float64)
    face_sum = np.zeros((n, 3))
    np.add.at(face_sum, Q.ravel(), np.repeat(face_pts, 4, axis=0))
    mid = (V[e0] + V[e1]) / 2.0
    mid_sum = np.zeros((n, 3))
    np.add.at(mid_sum, e0, mid)
    np.add.at(mid_sum, e1, mid)
    k = valence[:, None]
    new_v = (face_sum / k + 2.0 * mid_sum / k + (k - 3.0) * V) / k

    V_out = np.concatenate([new_v, edge_pts, face_pts])
    e_id = n + edge_of
    f_id = n + len(uniq) + np.arange(q)
    quads = [np.stack([Q[:, c], e_id[:, c], f_id, e_id[:, (c - 1) % 4]], axis=1) for c in range(4)]
    return V_out, np.concatenate(quads)


def _cactus(levels: int = 3, scale: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    V, Q = _block_cage(_CACTUS_BLOCKS)
    for _ in range(levels):
        V, Q = _catmull_clark(V, Q)
    F = _split_quads(V, Q)
    V = V - np.array([0.5, 0.0, 0.5])
    V[:, 1] -= V[:, 1].min()
    return V * scale, F


# ---------------------------------------------------------------------------------------------- obtuse meshes
def obtuse_cylinder(seed: int = 0, *, spacing: float = 0.05, squash: float = 0.5, jitter: float = 0.3
                    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The ``cylinder`` built-in with rows squashed together and jittered: most triangles are obtuse.

    Rings of about ``π / spacing`` vertices, ``squash`` times the near-equilateral row spacing apart, so every
    side triangle's corner opposite a ring edge is obtuse; each side vertex is then moved by a uniform random
    amount of up to ``jitter`` times the ring and row steps. Radius 0.5, height 4, flat caps, y up.

    With the defaults (12,286 vertices) 17.7% of the edges have a negative cotangent weight; with
    ``spacing=0.1`` (3,042 vertices) 18.5%.

    Parameters
    ----------
    seed : int
        Seed of the jitter (``numpy.random.default_rng``).
    spacing : float
        Vertex spacing along the rings.
    squash : float
        Row spacing relative to that of equilateral triangles (below 0.577, the untouched rows are obtuse).
    jitter : float
        Largest random move, in steps.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
        Closed, counter-clockwise seen from outside.
    """
    if not 0 < squash <= 1 or not 0 <= jitter < 0.5 or not spacing > 0:
        raise OptionError(f"need 0 < squash <= 1, 0 <= jitter < 0.5, spacing > 0; got {squash}, {jitter}, {spacing}")
    rng = np.random.default_rng(seed)
    height = 4.0
    V, F = _cylinder(0.5, height / squash, spacing)
    V[:, 1] *= squash
    side = np.flatnonzero((V[:, 1] > 1e-9) & (V[:, 1] < height - 1e-9))
    row = spacing * np.sqrt(3) / 2 * squash
    angle = np.arctan2(V[side, 0], V[side, 2]) + rng.uniform(-jitter, jitter, len(side)) * spacing / 0.5
    V[side, 0] = 0.5 * np.sin(angle)
    V[side, 2] = 0.5 * np.cos(angle)
    V[side, 1] += rng.uniform(-jitter, jitter, len(side)) * row
    return V, F


def scan_blob(seed: int = 0, *, n: int = 4000, stretch: float = 3.0, jitter: float = 0.5, noise: float = 0.003
              ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """An elongated, noisy, irregularly sampled ellipsoid, like a scan: many obtuse triangles.

    ``n`` points on the unit sphere (a Fibonacci lattice moved by Gaussian noise of ``jitter`` times the mean
    spacing) are triangulated by their convex hull, stretched ``stretch`` times along y, scaled by ½ and moved
    radially by Gaussian noise of ``noise`` (absolute). With the defaults (4,000 vertices, 3 × 1 × 1 units)
    19.9% of the edges have a negative cotangent weight; with ``n=1500``, 20.7%.

    Parameters
    ----------
    seed : int
        Seed of the noise (``numpy.random.default_rng``).
    n : int
        Number of vertices (≥ 20).
    stretch : float
        Length over width.
    jitter : float
        Tangential sampling noise, in mean point spacings.
    noise : float
        Radial noise (standard deviation), in model units.

    Returns
    -------
    V : (n, 3) float64 array
        Centred on the origin.
    F : (2n − 4, 3) int64 array
        Closed, counter-clockwise seen from outside.
    """
    from scipy.spatial import ConvexHull

    if n < 20 or not stretch > 0:
        raise OptionError(f"need n >= 20 and stretch > 0; got {n}, {stretch}")
    rng = np.random.default_rng(seed)
    k = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * k / n)
    azimuth = np.pi * (1.0 + 5.0 ** 0.5) * k
    P = np.stack([np.sin(polar) * np.cos(azimuth), np.cos(polar), np.sin(polar) * np.sin(azimuth)], axis=1)
    P += rng.normal(size=P.shape) * jitter * np.sqrt(4.0 * np.pi / n)
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    F = _orient_outward(P, ConvexHull(P).simplices.astype(np.int64), np.zeros_like)
    V = 0.5 * P * np.array([1.0, stretch, 1.0]) + P * (noise * rng.normal(size=(n, 1)))
    return V, F


# ---------------------------------------------------------------------------------------------- registry
_BUILDERS: dict[str, Callable[[], tuple[np.ndarray, np.ndarray]]] = {
    "cactus": _cactus,
    "bar": _bar,
    "cylinder": _cylinder,
}


def builtin_mesh(name: str) -> tuple[np.ndarray, np.ndarray]:
    """One of the built-in meshes (see the module description), or a geodesic sphere.

    Parameters
    ----------
    name : {"cactus", "bar", "cylinder", "sphere"} or "sphere:N"
        ``"sphere"`` is a geodesic sphere of 40,962 vertices (:data:`DEFAULT_SPHERE_SUBDIVISIONS`), ``"sphere:N"``
        one of about ``N`` vertices (at least 12, at most :data:`MAX_SPHERE_VERTICES`): the names ``arap`` takes on
        the command line.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array

    Raises
    ------
    OptionError
        Unknown name, or a sphere size that is not a whole number in range.

    Example
    -------
    >>> V, F = builtin_mesh("sphere:1000")
    >>> V.shape
    (1002, 3)
    """
    if name == "sphere" or name.startswith("sphere:"):
        return _named_sphere(name)
    try:
        build = _BUILDERS[name]
    except KeyError:
        raise OptionError(f"unknown built-in mesh {name!r}; choose one of {', '.join(BUILTIN_MESHES)}, sphere or "
                          "sphere:N (about N vertices)") from None
    V, F = build()
    return np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64)


def _named_sphere(name: str) -> tuple[np.ndarray, np.ndarray]:
    """``"sphere"`` or ``"sphere:N"`` (see :func:`builtin_mesh`)."""
    if name == "sphere":
        return sphere(DEFAULT_SPHERE_SUBDIVISIONS)
    text = name.partition(":")[2].replace("_", "").replace(",", "")
    try:
        wanted = int(text)
    except ValueError:
        raise OptionError(f"bad sphere size in {name!r}; use e.g. sphere:100000") from None
    if wanted < 12:
        raise OptionError(f"{name} asks for fewer vertices than the smallest sphere (12); use e.g. sphere:100000")
    if wanted > MAX_SPHERE_VERTICES:
        raise OptionError(f"{name} asks for more than {MAX_SPHERE_VERTICES:,} vertices, the largest sphere built")
    return sphere(frequency=sphere_frequency_for(wanted))
