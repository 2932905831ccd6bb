"""Handles anywhere on the surface: points given by a triangle and barycentric coordinates, hard or soft.

A point constraint ``k`` asks that ``Σ_c β_kc p'_{v_kc} = t_k`` for the corners ``v_k`` of its triangle. In the
global step (``A x = b`` over the free vertices ``x``):

- a **soft** constraint with weight ``w_k`` adds ``w_k ‖C_k x − t_k‖²`` to the energy, that is ``w_k C_kᵀC_k`` to
  ``A`` and ``w_k C_kᵀ t_k`` to ``b`` (weights are relative to the cotangent weights of the energy, which are of
  order 1);
- **hard** constraints (``w_k = inf``) are met exactly through their Lagrange multipliers: with ``Z = A⁻¹ C_hᵀ``
  and the small dense ``S = C_h Z``, each global step solves ``y = A⁻¹ b`` as before and corrects it,
  ``x = y − W (C_h y − d)`` with ``W = Z S⁻¹`` (``n_free × h``), computed once per constraint set. ``A`` also holds
  ``μ C_hᵀC_h`` (an augmented Lagrangian term, ``μ`` the mean diagonal of the system matrix): it does not move the
  constrained minimiser, but keeps ``A`` positive definite when a part of the mesh is held only by point handles.

The factorisation stays once per constraint set; a hard point costs one more back-substitution at set-up. Per
iteration the correction reads the few rows of ``y`` at the hard points' corners and updates ``y`` in place with the
product of ``W`` by the (h, d) miss: one compiled pass over ``W`` and ``y``, no temporary ``n_free``-long array and
no BLAS call (a threaded BLAS would share the cores with the solver's own threaded kernels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernel below is defined)
from arap.errors import ConstraintError

__all__ = ["BARYCENTRIC_TOLERANCE", "PointConstraints", "PointSystem", "check_points"]

BARYCENTRIC_TOLERANCE = 1e-9
"""How far below 0, or how far from summing to 1, barycentric coordinates may be."""


@dataclass(frozen=True)
class PointConstraints:
    """Validated point constraints (see :func:`check_points`).

    Attributes
    ----------
    faces : (p,) int64 array
        Triangle of each point.
    barycentric : (p, 3) float64 array
        Coordinates of each point in its triangle (corners in the order of ``F[face]``), summing to 1.
    weights : (p,) float64 array
        ``inf`` for a hard constraint (met exactly), else the positive weight of a soft one.
    """

    faces: NDArray[np.int64]
    barycentric: NDArray[np.float64]
    weights: NDArray[np.float64]

    @property
    def hard(self) -> NDArray[np.bool_]:
        """(p,) bool: which constraints are hard."""
        return np.isinf(self.weights)

    def __len__(self) -> int:
        return len(self.faces)

    def positions(self, V: NDArray[np.float64], F: NDArray[np.int64]) -> NDArray[np.float64]:
        """(p, 3) positions of the points on the surface ``V``."""
        return np.einsum("pc,pcx->px", self.barycentric, V[F[self.faces]])


def check_points(faces: object, barycentric: object, weights: object, n_faces: int,
                 corners: int = 3) -> PointConstraints:
    """Validate point constraints.

    Parameters
    ----------
    faces : (p,) sequence of int
        Triangle indices.
    barycentric : (p, corners) array-like of float
        Barycentric coordinates, each ``≥ 0`` and summing to 1 (within :data:`BARYCENTRIC_TOLERANCE`).
    weights : (p,) array-like of float, or None
        ``inf`` (hard) or a positive weight per point; None: all hard.
    n_faces : int
        Number of triangles (or tetrahedra).
    corners : int
        3 for points in triangles, 4 for points in tetrahedra.

    Returns
    -------
    PointConstraints

    Raises
    ------
    ConstraintError
        Wrong shapes, face indices out of range or not integers, coordinates negative, not finite or not summing
        to 1, weights zero, negative or NaN.

    Example
    -------
    >>> p = check_points([0], [[0.2, 0.3, 0.5]], None, n_faces=4)
    >>> p.hard.tolist()
    [True]
    """
    f = np.asarray(faces)
    if f.ndim != 1 or (f.size and f.dtype.kind not in "iu"):
        raise ConstraintError("point faces must be a flat list of integer triangle indices")
    out = (f < 0) | (f >= n_faces)  # in the array's own dtype: uint64 beyond int64 must not wrap
    if out.any():
        raise ConstraintError(f"point face {int(f[out][0])} out of range 0..{n_faces - 1}")
    f = f.astype(np.int64)
    try:
        b = np.array(barycentric, dtype=np.float64).reshape(-1, corners) if len(f) else np.zeros((0, corners))
    except (TypeError, ValueError) as exc:
        raise ConstraintError(f"barycentric coordinates must be {len(f)} {'triples' if corners == 3 else 'quadruples'}"
                              f" of numbers ({exc})") from exc
    if b.shape != (len(f), corners):
        raise ConstraintError(f"barycentric coordinates must have shape ({len(f)}, {corners}), got {b.shape}")
    if not np.isfinite(b).all():
        raise ConstraintError("barycentric coordinates must be finite")
    if (b < -BARYCENTRIC_TOLERANCE).any() or (np.abs(b.sum(axis=1) - 1.0) > BARYCENTRIC_TOLERANCE).any():
        k = int(np.flatnonzero((b < -BARYCENTRIC_TOLERANCE).any(axis=1)
                               | (np.abs(b.sum(axis=1) - 1.0) > BARYCENTRIC_TOLERANCE))[0])
        raise ConstraintError(f"barycentric coordinates of point {k} must be >= 0 and sum to 1, got "
                              f"{b[k].tolist()}")
    if weights is None:
        w = np.full(len(f), np.inf)
    else:
        try:
            w = np.array(weights, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ConstraintError(f"point weights must be numbers ({exc})") from exc
        if w.shape != (len(f),):
            raise ConstraintError(f"point weights must have shape ({len(f)},), got {w.shape}")
        if np.isnan(w).any() or (w <= 0).any():
            raise ConstraintError("point weights must be positive (inf: a hard constraint)")
    return PointConstraints(f, np.clip(b, 0.0, None), w)



@nb.njit("void(float64[:, :], float64[:, :], int64[:], int64[:], float64[:], float64[:, :])", cache=True, nogil=True)
def _project(y, W, indptr, indices, data, goal):  # pragma: no cover - compiled
    """``y −= W (C_h y − goal)`` in place, ``C_h`` given by its CSR arrays (a few entries per row). One signature of
    any memory layout: a back-substitution returns C or Fortran order depending on the backend, and ``y`` is run
    through in its own order."""
    h, d = goal.shape
    miss = np.empty((h, d))
    for k in range(h):
        for j in range(d):
            acc = -goal[k, j]
            for q in range(indptr[k], indptr[k + 1]):
                acc += data[q] * y[indices[q], j]
            miss[k, j] = acc
    if y.strides[0] >= y.strides[1]:  # rows contiguous
        for i in range(y.shape[0]):
            for j in range(d):
                acc = 0.0
                for k in range(h):
                    acc += W[i, k] * miss[k, j]
                y[i, j] -= acc
    else:  # columns contiguous (Fortran order)
        for j in range(d):
            for i in range(y.shape[0]):
                acc = 0.0
                for k in range(h):
                    acc += W[i, k] * miss[k, j]
                y[i, j] -= acc


class PointSystem:
    """Point constraints in the reduced global step of a solver.

    Parameters
    ----------
    points : PointConstraints
    corners : (p, 3) or (p, 4) int array
        The corner vertices of each point's triangle (or tetrahedron), in the solver's internal numbering.
    n_free : int
        Free vertices: internal indices ``0..n_free-1``; the others are non-free (fixed values).
    mu : float
        Weight of the augmented Lagrangian term of the hard constraints.
    """

    def __init__(self, points: PointConstraints, corners: NDArray[np.int64], n_free: int, n: int, mu: float) -> None:
        p = len(points)
        rows = np.repeat(np.arange(p), corners.shape[1] if corners.ndim == 2 else 3)
        C = sp.csr_matrix((points.barycentric.ravel(), (rows, corners.ravel())), shape=(p, n))
        self.C_free = C[:, :n_free].tocsr()
        self.C_known = C[:, n_free:].tocsr()
        self.hard = points.hard
        self.soft_w = np.where(self.hard, 0.0, points.weights)
        self.mu = float(mu)
        self.C_free.eliminate_zeros()
        touches_free = np.diff(self.C_free.indptr) > 0
        if p and not touches_free.all():
            k = int(np.flatnonzero(~touches_free)[0])
            raise ConstraintError(f"point {k} lies on a triangle whose corners are all constrained or held; move it "
                                  "or free one of them")
        self._w_all = np.where(self.hard, self.mu, self.soft_w)
        self._entry_point = np.repeat(np.arange(p), np.diff(self.C_free.indptr))  # the point of each entry of C_free
        self.W: NDArray[np.float64] | None = None
        self._hard_rows: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]] | None = None

    def matrix(self) -> sp.csr_matrix:
        """``Σ_soft w CᵀC + μ Σ_hard CᵀC`` over the free vertices, added to the system matrix."""
        W = sp.diags(self._w_all)
        return (self.C_free.T @ W @ self.C_free).tocsr()

    def prepare(self, solve: object) -> None:
        """Precompute ``W = Z S⁻¹`` (``Z = A⁻¹ C_hᵀ``, ``S = C_h Z``) with the factorised ``A`` (``solve(B)``), and
        the hard rows of ``C``: all that the per-iteration correction reads besides ``y``.

        Raises
        ------
        ConstraintError
            The hard points do not pin independent positions (``S`` numerically singular).
        """
        if not self.hard.any():
            return
        Ch = self.C_free[self.hard].tocsr()
        Z = np.asarray(solve(np.ascontiguousarray(Ch.T.toarray())))  # type: ignore[operator]
        S = np.asarray(Ch @ Z)
        S = 0.5 * (S + S.T)
        message = ("the hard point constraints are not independent (two points at the same place, or more points "
                   "than a triangle's corners can satisfy)")
        try:
            factor = sla.cho_factor(S)
        except sla.LinAlgError as exc:
            raise ConstraintError(message) from exc
        pivots = np.abs(np.diag(factor[0]))
        if pivots.min() <= 1e-6 * pivots.max():  # numerically singular: rounding let the factorisation through
            raise ConstraintError(message)
        # W = Z S⁻¹ = (S⁻¹ Zᵀ)ᵀ, S symmetric; row-major, as the correction runs over the free vertices.
        self.W = np.ascontiguousarray(sla.cho_solve(factor, Z.T, check_finite=False).T)
        self._hard_rows = (Ch.indptr.astype(np.int64), Ch.indices.astype(np.int64),
                           np.ascontiguousarray(Ch.data, dtype=np.float64))

    def known(self, fixed: NDArray[np.float64]) -> NDArray[np.float64]:
        """(p, 3) contribution of the non-free vertices to each point."""
        return np.asarray(self.C_known @ fixed)

    def rhs(self, targets: NDArray[np.float64], fixed: NDArray[np.float64]) -> NDArray[np.float64]:
        """(n_free, 3) addition to the right-hand side for the point ``targets``."""
        r = (targets - self.known(fixed)) * self._w_all[:, None]
        return np.asarray(self.C_free.T @ r)

    def subtract_rhs(self, const: NDArray[np.float64], targets: NDArray[np.float64], fixed: NDArray[np.float64]
                     ) -> NDArray[np.float64]:
        """``const − rhs(targets, fixed)`` as a new array, written into a copy of ``const`` at the few rows the points'
        corners touch (no other ``n_free``-long array)."""
        r = (targets - self.known(fixed)) * self._w_all[:, None]
        out = np.array(const, dtype=np.float64)
        np.subtract.at(out, self.C_free.indices, self.C_free.data[:, None] * r[self._entry_point])
        return out

    def correct(self, y: NDArray[np.float64], targets: NDArray[np.float64], fixed: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """The solution of the global step with the hard constraints met, from the unconstrained one ``y`` (corrected
        in place)."""
        return self.project(y, self.goal(targets, fixed))

    def goal(self, targets: NDArray[np.float64], fixed: NDArray[np.float64]) -> NDArray[np.float64]:
        """What the free vertices must give the hard points, ``C_h x``, for ``targets``: (h, 3), once per solve."""
        h = self.hard
        return targets[h] - self.known(fixed)[h]

    def project(self, y: NDArray[np.float64], goal: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`correct` with the hard points' :meth:`goal` computed before (once per solve: a drag corrects every
        iteration). ``y`` (float64, ``(n_free, d)``, any memory layout) is corrected in place and returned.

        Example
        -------
        Two triangles, a hard point at the middle of their shared edge, ``A`` the identity:

        >>> pts = check_points([0], [[0.0, 0.5, 0.5]], None, n_faces=2)
        >>> system = PointSystem(pts, np.array([[0, 1, 2]]), n_free=4, n=4, mu=1.0)
        >>> system.prepare(lambda B: B)
        >>> y = np.zeros((4, 2))
        >>> system.project(y, np.array([[1.0, 2.0]])).round(12).tolist()
        [[0.0, 0.0], [1.0, 2.0], [1.0, 2.0], [0.0, 0.0]]
        """
        if self.W is None or self._hard_rows is None:
            return y
        _project(y, self.W, *self._hard_rows, np.asarray(goal, dtype=np.float64))
        return y

    def penalty(self, free: NDArray[np.float64], targets: NDArray[np.float64], fixed: NDArray[np.float64]) -> float:
        """``Σ_soft w ‖C x − t‖²``: the soft constraints' part of the energy."""
        if not self.soft_w.any():
            return 0.0
        r = np.asarray(self.C_free @ free) + self.known(fixed) - targets
        return float(np.dot(self.soft_w, np.einsum("ij,ij->i", r, r)))
