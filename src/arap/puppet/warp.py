"""The puppet warp of a picture (Igarashi, Moscovich & Hughes 2005; Photoshop's Puppet Warp).

Pins are points of the picture's shape; moving some of them bends the picture around the others, as rigidly as it
can. The shape is meshed (:func:`arap.puppet.imagemesh.image_mesh`), every pin becomes a hard point handle at its
place in its triangle (barycentric coordinates; :mod:`arap.method.points`), the planar mesh is deformed until
converged, and the picture is drawn on the deformed mesh (:mod:`arap.puppet.raster`).

Modes:

- ``"rigid"``: the element ARAP energy (one rotation per triangle, :mod:`arap.method.elements`): every triangle stays
  as close to a rotated copy of itself as the pins allow.
- ``"distort"``: the as-similar-as-possible energy, each triangle as close to a rotated *and scaled* copy of itself
  (the first, linear step of Igarashi et al.; the conformal energy of least-squares conformal maps): parts may grow
  and shrink, so a pin pulled away stretches the picture instead of dragging it along. It is one sparse linear
  solve.
- ``"normal"``: between the two, the ARAP/ASAP hybrid of Liu et al. 2008 (:mod:`arap.puppet.blend`) with λ = 1:
  every triangle is fitted a rotation and a scale, and a scale costs as much as its squared change of area, so a
  part the pins stretch by a factor ``c`` keeps about ``∛c`` of it: parts give a little where pins pull, and bend
  as in ``"rigid"`` elsewhere.

A part of the shape (an island of the picture) without any pin stays where it is.

A pin may hold an angle (Photoshop's fixed pin rotation, set there by Alt-dragging around a pin): its neighbourhood
then turns by that angle about the pin instead of turning freely with the bend. Such a pin carries a hidden ring of
:data:`~arap.puppet.rings.RING_POINTS` hard point handles at :data:`~arap.puppet.rings.RING_SPACINGS` mean edge
lengths around it, which move with the pin turned by its angle (:mod:`arap.puppet.rings`, as in the studio).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from arap.errors import ArapError, ConstraintError, OptionError
from arap.puppet.imagemesh import DEFAULT_DENSITY, ImageMesh, image_mesh
from arap.puppet.picture import as_picture
from arap.puppet.raster import draw_textured
from arap.puppet.rings import pin_rings

if TYPE_CHECKING:
    from arap.puppet.blend import BlendSolver
    from arap.solve.solver import ArapSolver

__all__ = ["MODES", "PuppetWarp", "WarpMode", "pin_targets", "warp"]

WarpMode = Literal["rigid", "normal", "distort"]
MODES: tuple[str, ...] = ("rigid", "normal", "distort")
"""The warp's modes, from the stiffest: Photoshop's Puppet Warp offers the same three."""


def _points(value: object, what: str) -> NDArray[np.float64]:
    try:
        A = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConstraintError(f"{what} must be (x, y) pairs of numbers") from None
    if A.size == 0:
        return np.zeros((0, 2))
    if A.ndim != 2 or A.shape[1] != 2:
        raise ConstraintError(f"{what} must have shape (k, 2), got {A.shape}")
    if not np.isfinite(A).all():
        raise ConstraintError(f"{what} must be finite numbers")
    return A


def pin_targets(pins: ArrayLike, targets: object = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pins and where they go, a pin without a new place holding where it is.

    Parameters
    ----------
    pins : (k, 2) array-like
        Pixel positions (x, y) on the picture's shape.
    targets : (k, 2) array-like, a shorter sequence, a sequence with None entries, or None
        Target of each pin in order; a pin past the end, or whose entry is None, holds (None: all hold).

    Returns
    -------
    pins, targets : (k, 2) float64 arrays

    Raises
    ------
    ConstraintError
        No pin, malformed or non-finite pins or targets, more targets than pins, two pins at one place.

    Example
    -------
    >>> p, t = pin_targets([[1, 2], [3, 4], [5, 6]], [None, [0, 0]])
    >>> t.tolist()
    [[1.0, 2.0], [0.0, 0.0], [5.0, 6.0]]
    """
    P = _points(pins, "pins")
    if len(P) == 0:
        raise ConstraintError("give at least one pin")
    T = P.copy()
    if targets is not None:
        if isinstance(targets, np.ndarray):
            entries: list[object] = list(targets.reshape(len(targets), -1))
        elif isinstance(targets, (list, tuple)):
            entries = list(targets)
        else:
            raise ConstraintError("targets must be a list of (x, y) pairs or None")
        if len(entries) > len(P):
            raise ConstraintError(f"{len(entries)} targets for {len(P)} pins; give at most one target per pin")
        for k, entry in enumerate(entries):
            if entry is None:
                continue
            if np.asarray(entry, dtype=object).shape != (2,):
                raise ConstraintError(f"the target of pin {k} must be an (x, y) pair or None, got {entry!r}")
            T[k] = _points([entry], f"the target of pin {k}")[0]
    order = np.lexsort((P[:, 1], P[:, 0]))
    same = np.flatnonzero(np.all(P[order[1:]] == P[order[:-1]], axis=1))
    if len(same):
        a, b = sorted((int(order[same[0]]), int(order[same[0] + 1])))
        raise ConstraintError(f"pins {a} and {b} are at the same place ({P[a, 0]:g}, {P[a, 1]:g})")
    return P, T


def _locate(mesh: ImageMesh, pins: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The triangle of every pin and its barycentric coordinates there.

    A pin on a shape pixel that the mesh misses by a little (where the outline cuts a corner) goes to the nearest
    point of the mesh.
    """
    V, F = mesh.vertices, mesh.triangles
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = B - A, C - A
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    w, h = mesh.size
    faces = np.empty(len(pins), dtype=np.int64)
    bary = np.empty((len(pins), 3))
    for k, (x, y) in enumerate(pins):
        d = np.array([x, y]) - A
        l1 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
        l2 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
        L = np.column_stack([1.0 - l1 - l2, l1, l2])
        low = L.min(axis=1)
        t = int(np.argmax(low))
        if low[t] < -1e-12:
            on_shape = 0 <= x < w and 0 <= y < h and bool(mesh.mask[int(y), int(x)])
            if not on_shape:
                raise ConstraintError(f"pin {k} at ({x:g}, {y:g}) is outside the picture's shape (on a transparent "
                                      "or background pixel, or off the picture)")
            clipped = np.clip(L, 0.0, None)
            clipped /= clipped.sum(axis=1, keepdims=True)
            near = np.einsum("mc,mcx->mx", clipped, V[F])
            t = int(np.argmin(np.hypot(near[:, 0] - x, near[:, 1] - y)))
            L[t] = clipped[t]
        b = np.clip(L[t], 0.0, None)
        faces[k], bary[k] = t, b / b.sum()
    return faces, bary


def _angles(value: object, k: int, what: str) -> list[float | None]:
    """One angle in degrees or None per pin (None: all None)."""
    if value is None:
        return [None] * k
    entries = list(value) if isinstance(value, (list, tuple, np.ndarray)) else None
    if entries is None or len(entries) != k:
        raise ConstraintError(f"{what} must be a list of one angle (degrees) or None per pin, {k} in all")
    out: list[float | None] = []
    for j, a in enumerate(entries):
        if a is None:
            out.append(None)
            continue
        try:
            angle = float(a)
        except (TypeError, ValueError):
            raise ConstraintError(f"the angle of pin {j} must be a number of degrees or None, got {a!r}") from None
        if not np.isfinite(angle):
            raise ConstraintError(f"the angle of pin {j} must be finite, got {a!r}")
        out.append(angle)
    return out


def _similarity_matrix(V: NDArray[np.float64], F: NDArray[np.int64]) -> sp.csr_matrix:
    """The rows whose squares sum to the as-similar-as-possible energy ``Σ_t |t| ‖J_t − S_t‖²`` (``S_t`` the
    similarity nearest the deformation gradient ``J_t``), over the unknowns ``[x; y]``."""
    n, m = len(V), len(F)
    P = V[F][:, :, :2]
    E = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=1)
    inv = np.linalg.inv(E)
    G = np.empty((m, 3, 2))
    G[:, 1:, :] = np.transpose(inv, (0, 2, 1))
    G[:, 0, :] = -G[:, 1:, :].sum(axis=1)
    area = 0.5 * np.abs(np.linalg.det(E))
    s = np.sqrt(area / 2.0)[:, None]
    # J = [[a, b], [c, d]] with a = Σ x_i gx_i, b = Σ x_i gy_i, c = Σ y_i gx_i, d = Σ y_i gy_i; its distance to the
    # nearest similarity is ((a − d)² + (b + c)²) / 2.
    cols = np.concatenate([F, F + n, F, F + n], axis=1)
    vals = np.concatenate([G[:, :, 0] * s, -G[:, :, 1] * s, G[:, :, 1] * s, G[:, :, 0] * s], axis=1)
    order = np.concatenate([np.zeros((m, 6), dtype=np.int64), np.ones((m, 6), dtype=np.int64)], axis=1)
    row_index = 2 * np.arange(m)[:, None] + order
    return sp.csr_matrix((vals.ravel(), (row_index.ravel(), cols.ravel())), shape=(2 * m, 2 * n))


class PuppetWarp:
    """A picture meshed and pinned, ready to warp: the mesh and the solver are built once, each new set of targets
    is one solve.

    Parameters
    ----------
    image : (h, w, 3|4) uint8 array or a path
        The picture (with alpha, its shape is its opaque pixels; see :func:`arap.image_mesh`).
    pins : (k, 2) array-like
        Pixel positions (x right, y down) on the shape.
    spacing, density, alpha_threshold, background, tolerance
        The mesh's, as :func:`arap.image_mesh` takes them (ignored when ``mesh`` is given).
    rigid : (h, w) bool array or None
        Parts of the picture kept rigid (``mode="rigid"`` only): the triangles whose corners all lie on these
        pixels move as one piece.
    mode : {"rigid", "normal", "distort"}
        The energy (see :mod:`arap.puppet.warp`).
    mesh : ImageMesh or None
        A mesh of this picture made earlier (None: made here).
    angles : list of float or None, or None
        Per pin, None for a pin whose neighbourhood turns freely with the bend (Photoshop's "auto"), or the angle in
        degrees (counter-clockwise as seen, y down: a positive angle turns x towards −y) by which it holds its
        neighbourhood turned about it; :meth:`deform` may give such a pin another angle.

    Raises
    ------
    ArapError
        An unusable picture, a pin outside the shape (named), two pins at one place, an unknown mode, a pin that
        holds an angle but has none of its ring on the shape.

    Examples
    --------
    Mesh a bar once, then bend it twice (each a single solve):

    >>> import numpy as np, arap
    >>> img = np.zeros((40, 100, 4), dtype=np.uint8); img[15:25, 10:90] = (200, 80, 20, 255)
    >>> puppet = arap.PuppetWarp(img, [[12, 20], [88, 20]], spacing=5)
    >>> for target in ([80, 30], [80, 10]):
    ...     moved = puppet.deform([None, target])
    ...     print(moved.shape[1], bool(np.allclose(moved.max(axis=0)[1] >= 25, target[1] >= 25)))
    2 True
    2 True
    """

    def __init__(self, image: object, pins: ArrayLike, *, spacing: float | None = None,
                 density: int = DEFAULT_DENSITY, rigid: ArrayLike | None = None, mode: WarpMode = "rigid",
                 alpha_threshold: int = 0, background: tuple[int, int, int] | None = None, tolerance: float = 0.0,
                 mesh: ImageMesh | None = None, angles: object = None) -> None:
        if mode not in MODES:
            raise OptionError(f"unknown warp mode {mode!r}; expected one of {', '.join(MODES)}")
        self.picture = as_picture(image)
        self.mesh = mesh if mesh is not None else image_mesh(self.picture, spacing, density=density,
                                                             alpha_threshold=alpha_threshold,
                                                             background=background, tolerance=tolerance)
        if self.mesh.size != (self.picture.shape[1], self.picture.shape[0]):
            raise ArapError(f"the mesh is of a {self.mesh.size[0]}x{self.mesh.size[1]} picture, not of this "
                            f"{self.picture.shape[1]}x{self.picture.shape[0]} one")
        self.mode = mode
        self.pins, _ = pin_targets(pins)
        #: Per pin, the angle (degrees) it holds, or None (turns freely).
        self.angles = _angles(angles, len(self.pins), "angles")
        faces, bary = _locate(self.mesh, self.pins)
        # The hidden rings, on the rest mesh; their angles are counter-clockwise as seen with y down, so turned the
        # other way in the rings' x-towards-y sense.
        self._rings = pin_rings(self.mesh.vertices, self.mesh.triangles, self.pins,
                                [None if a is None else -np.radians(a) for a in self.angles])
        ring = self._rings.points
        self._faces_all, self._bary_all = np.concatenate([faces, ring.faces]), np.concatenate([bary, ring.barycentric])
        self.faces, self.barycentric = faces, bary
        V, F = self.mesh.vertices, self.mesh.triangles
        n = len(V)
        adjacency = sp.coo_matrix((np.ones(3 * len(F)), (F.ravel(), np.roll(F, 1, axis=1).ravel())), shape=(n, n))
        _, label = csgraph.connected_components(adjacency, directed=False)
        pinned = np.zeros(label.max() + 1, dtype=bool)
        pinned[label[F[self.faces, 0]]] = True
        #: Vertices of the parts without a pin: they hold.
        self.held = np.flatnonzero(~pinned[label])
        stiffness = None
        if rigid is not None:
            if mode != "rigid":
                raise OptionError("rigid parts need mode='rigid'")
            R = np.asarray(rigid, dtype=bool)
            if R.shape != self.mesh.mask.shape:
                raise ArapError(f"rigid must be an (h, w) mask of the picture, shape {self.mesh.mask.shape}, got "
                                f"{R.shape}")
            w, h = self.mesh.size
            c = np.clip(V[:, 0].astype(np.int64), 0, w - 1)
            r = np.clip(V[:, 1].astype(np.int64), 0, h - 1)
            stiffness = np.where(R[r, c], np.inf, 1.0)
        self._solver: ArapSolver | BlendSolver | None = None
        if mode in ("rigid", "normal"):
            from arap.solve.solver import ArapSolver

            solver = ArapSolver(V, F, self.held, points=(self._faces_all, self._bary_all), stiffness=stiffness)
            self._solver = solver
            if mode == "normal":
                from arap.puppet.blend import NORMAL_LAMBDA, BlendSolver

                self._solver = BlendSolver(solver, NORMAL_LAMBDA)
        else:
            self._prepare_distort()

    def _prepare_distort(self) -> None:
        V, F = self.mesh.vertices, self.mesh.triangles
        n, k = len(V), len(self._faces_all)
        M = _similarity_matrix(V, F)
        Q = (M.T @ M).tocsr()
        # Among equally similar shapes (a part held by one pin may turn and scale about it freely), the one whose
        # displacement varies least: a tiny graph Laplacian of the displacement, zero for a translation.
        edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        both = np.concatenate([edges, edges[:, ::-1]])
        A = sp.csr_matrix((np.ones(len(both)), (both[:, 0], both[:, 1])), shape=(n, n))
        A.data[:] = 1.0  # an edge of two triangles counted once
        L = sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A
        self._smooth = sp.block_diag([L, L], format="csr") * (1e-6 * float(Q.diagonal().mean()))
        rows = np.concatenate([np.repeat(np.arange(k), 3), np.repeat(np.arange(k), 3) + k])
        corners = self.mesh.triangles[self._faces_all]
        cols = np.concatenate([corners.ravel(), corners.ravel() + n])
        vals = np.concatenate([self._bary_all.ravel(), self._bary_all.ravel()])
        C = sp.csr_matrix((vals, (rows, cols)), shape=(2 * k, 2 * n))
        H = self.held
        if len(H):
            Ch = sp.csr_matrix((np.ones(2 * len(H)), (np.arange(2 * len(H)), np.concatenate([H, H + n]))),
                               shape=(2 * len(H), 2 * n))
            C = sp.vstack([C, Ch]).tocsr()
        K = sp.bmat([[Q + self._smooth, C.T], [C, None]], format="csc")
        self._kkt = spla.splu(K)

    def deform(self, targets: object = None, angles: object = None) -> NDArray[np.float64]:
        """Where the mesh's vertices go when the pins move to ``targets``.

        Parameters
        ----------
        targets : see :func:`pin_targets`
            A pin without a target holds.
        angles : list of float or None, or None
            New angles (degrees) of pins that hold one (None entries, or None: the angles they were made with).

        Returns
        -------
        (n, 2) float64 array
            In pixel coordinates; every pin's point (its barycentric coordinates in its triangle) is on its target.

        Raises
        ------
        ConstraintError
            Malformed targets, or an angle for a pin made without one.
        """
        _, T = pin_targets(self.pins, targets)
        given = _angles(angles, len(self.pins), "angles")
        for j, a in enumerate(given):
            if a is not None and self.angles[j] is None:
                raise ConstraintError(f"pin {j} was made without an angle: give it one (angles=) when making the "
                                      "PuppetWarp")
        if len(self._rings.pin):
            T = np.concatenate([T, self._rings.targets(T, [None if a is None else -np.radians(a) for a in given])])
        V = self.mesh.vertices
        if self._solver is not None:
            result = self._solver.solve(V[self.held], point_targets=T)
            return np.asarray(result.vertices, dtype=np.float64)
        n = len(V)
        z0 = np.concatenate([V[:, 0], V[:, 1]])
        rhs = np.concatenate([self._smooth @ z0, T[:, 0], T[:, 1], V[self.held, 0], V[self.held, 1]])
        z = self._kkt.solve(rhs)
        return np.column_stack([z[:n], z[n:2 * n]])

    def canvas(self, vertices: NDArray[np.float64], fit: bool = False) -> tuple[tuple[int, int], tuple[int, int]]:
        """The result's top-left corner in the picture's coordinates and its (width, height): the picture's frame,
        or with ``fit`` the frame enlarged to hold the deformed shape."""
        w, h = self.mesh.size
        if not fit:
            return (0, 0), (w, h)
        lo = np.floor(np.minimum(vertices.min(axis=0), 0.0)).astype(np.int64)
        hi = np.ceil(np.maximum(vertices.max(axis=0), [w, h])).astype(np.int64)
        size = hi - lo
        if int(size[0]) * int(size[1]) > 4 * 64_000_000:
            raise ArapError(f"the warped picture would be {int(size[0])}x{int(size[1])} pixels; move the pins less "
                            "far or leave out fit")
        return (int(lo[0]), int(lo[1])), (int(size[0]), int(size[1]))

    def pin_parts(self) -> NDArray[np.int64]:
        """The pin each triangle belongs to: the nearest pin to its rest centroid, within its part of the shape
        (an island without a pin: -1).

        Photoshop's pin depth brings a pin's part forward or back; here ``depth=np.asarray(pin_depth)[parts]`` (a
        depth per pin) draws the parts in that order where they overlap (see :meth:`draw_order`), e.g.
        ``puppet(targets, depth=np.array([0, 1, 0])[puppet.pin_parts()])`` draws pin 1's part over the others.
        """
        V, F = self.mesh.vertices, self.mesh.triangles
        centroid = V[F].mean(axis=1)
        n = len(V)
        adjacency = sp.coo_matrix((np.ones(3 * len(F)), (F.ravel(), np.roll(F, 1, axis=1).ravel())), shape=(n, n))
        _, label = csgraph.connected_components(adjacency, directed=False)
        island = label[F[:, 0]]
        pin_island = label[F[self.faces, 0]]
        d = np.hypot(centroid[:, None, 0] - self.pins[None, :, 0], centroid[:, None, 1] - self.pins[None, :, 1])
        d[island[:, None] != pin_island[None, :]] = np.inf
        parts = np.argmin(d, axis=1)
        parts[~np.isfinite(d.min(axis=1))] = -1
        return parts.astype(np.int64)

    def draw_order(self, depth: ArrayLike | None) -> NDArray[np.int64] | None:
        """The triangles' drawing order for a depth (None: the mesh's own order).

        ``depth`` is an (h, w) map of the picture (read at each triangle's rest centroid), one value per triangle
        or one per vertex (a triangle takes its corners' mean); triangles of larger depth are drawn over those of
        smaller depth, equal depths in the mesh's order.
        """
        if depth is None:
            return None
        D = np.asarray(depth, dtype=np.float64)
        V, F = self.mesh.vertices, self.mesh.triangles
        if D.shape == self.mesh.mask.shape:
            centroid = V[F].mean(axis=1)
            w, h = self.mesh.size
            value = D[np.clip(centroid[:, 1].astype(np.int64), 0, h - 1),
                      np.clip(centroid[:, 0].astype(np.int64), 0, w - 1)]
        elif D.shape == (len(F),):
            value = D
        elif D.shape == (len(V),):
            value = D[F].mean(axis=1)
        else:
            raise ArapError(f"depth must be an (h, w) map {self.mesh.mask.shape}, one value per triangle "
                            f"({len(F)}) or one per vertex ({len(V)}), got shape {D.shape}")
        if not np.isfinite(value).all():
            raise ArapError("depth values must be finite")
        return np.argsort(value, kind="stable")

    def render(self, vertices: NDArray[np.float64], *, fit: bool = False,
               depth: ArrayLike | None = None) -> NDArray[np.uint8]:
        """The picture drawn on the mesh at ``vertices`` (see :meth:`canvas` and :meth:`draw_order`); (h', w', 4)
        uint8 RGBA."""
        origin, size = self.canvas(vertices, fit)
        return draw_textured(self.picture, self.mesh.vertices, vertices, self.mesh.triangles, size, origin,
                             self.draw_order(depth))

    def textured_mesh(self, vertices: NDArray[np.float64]) -> Any:
        """A ``trimesh.Trimesh`` of the mesh at ``vertices``, textured with the picture: positions ``(x, h − y, 0)``
        in pixels (y up, as mesh files have it; triangles facing +z), texture coordinates ``(x / w, 1 − y / h)`` of
        the rest positions."""
        import trimesh
        from PIL import Image

        w, h = self.mesh.size
        V = np.column_stack([vertices[:, 0], h - vertices[:, 1], np.zeros(len(vertices))])
        rest = self.mesh.vertices
        uv = np.column_stack([rest[:, 0] / w, 1.0 - rest[:, 1] / h])
        F = self.mesh.triangles
        up = np.column_stack([rest[:, 0], h - rest[:, 1]])  # the rest positions, y up: all one way round
        e1, e2 = up[F[:, 1]] - up[F[:, 0]], up[F[:, 2]] - up[F[:, 0]]
        if np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0:
            F = F[:, ::-1]
        mode = "RGBA" if self.picture.shape[2] == 4 else "RGB"
        visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(self.picture, mode))
        return trimesh.Trimesh(V, F, visual=visual, process=False)

    def __call__(self, targets: object = None, *, fit: bool = False,
                 depth: ArrayLike | None = None) -> NDArray[np.uint8]:
        """The warped picture for ``targets`` (:meth:`deform`, then :meth:`render`)."""
        return self.render(self.deform(targets), fit=fit, depth=depth)


def warp(image: object, pins: ArrayLike, targets: object = None, spacing: float | None = None,
         rigid: ArrayLike | None = None, mode: WarpMode = "rigid", *, fit: bool = False,
         depth: ArrayLike | None = None, density: int = DEFAULT_DENSITY, alpha_threshold: int = 0,
         background: tuple[int, int, int] | None = None, tolerance: float = 0.0,
         angles: object = None) -> NDArray[np.uint8]:
    """Puppet-warp a picture: move pins on it and bend the rest as rigidly as it can (see :class:`PuppetWarp`).

    Parameters
    ----------
    image : (h, w, 3|4) uint8 array or a path
    pins : (k, 2) array-like
        Pixel positions (x right, y down) on the picture's shape.
    targets : (k, 2) array-like, shorter, with None entries, or None
        Where the pins go; pins without a target hold.
    spacing : float or None
        The mesh's edge length in pixels (None: from ``density``).
    rigid : (h, w) bool array or None
        Parts kept rigid.
    mode : {"rigid", "normal", "distort"}
        The energy, from the stiffest (see :mod:`arap.puppet.warp`).
    fit : bool
        Enlarge the canvas to hold the warped shape (else: the picture's size).
    depth : array-like or None
        Which parts are drawn over which where they overlap (see :meth:`PuppetWarp.draw_order`).
    density, alpha_threshold, background, tolerance
        As :func:`arap.image_mesh` takes them.
    angles : list of float or None, or None
        Per pin, None (its surroundings turn freely) or the angle in degrees by which the pin holds them turned
        (see :class:`PuppetWarp`).

    Returns
    -------
    (h', w', 4) uint8 array
        Straight RGBA.

    Example
    -------
    >>> import numpy as np, arap
    >>> img = np.zeros((40, 100, 4), dtype=np.uint8); img[15:25, 10:90] = (200, 80, 20, 255)
    >>> out = arap.warp(img, [[12, 20], [88, 20]], [None, [80, 35]], spacing=5)
    >>> out.shape, out[20, 12].tolist()
    ((40, 100, 4), [200, 80, 20, 255])
    """
    puppet = PuppetWarp(image, pins, spacing=spacing, density=density, rigid=rigid, mode=mode,
                        alpha_threshold=alpha_threshold, background=background, tolerance=tolerance,
                        angles=angles)
    return puppet(targets, fit=fit, depth=depth)
