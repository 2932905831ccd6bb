"""Handles anywhere on the surface: points given as a face and barycentric coordinates, hard or soft.

A point constraint ``k`` asks that ``p_k = Σ_j b_kj u_{f_kj}`` (the point at barycentric coordinates ``b_k`` of face
``f_k`` in the deformed mesh) reach a target ``t_k``. In matrix form ``C U = T`` with ``C`` (p, n) holding the
barycentric coordinates; split over the free and the non-free vertices, ``C_f X = T − C_n U_n =: D``.

* **Soft** constraints (finite weight ``w_k``) add the penalty ``Σ_k w_k ‖C_k U − t_k‖²`` to the energy: the global
  step's matrix gains ``C_fᵀ W C_f`` and its right-hand side ``C_fᵀ W D``. The reported energies include this
  penalty, since it is part of the objective the iteration minimises (and the safeguard of the Anderson
  acceleration compares that objective).
* **Hard** constraints (weight ``inf``) are met exactly through the KKT system
  ``[A C_hᵀ; C_h 0] [X; μ] = [B; D_h]``, solved by a precomputed Schur complement: at precompute
  ``Z = A⁻¹ C_hᵀ`` (one back-substitution per hard point) and the Cholesky factor of ``S = C_h Z`` (h × h);
  every global step is then one back-substitution ``Y = A⁻¹ B`` (as without points), ``μ = S⁻¹ (C_h Y − D_h)`` and
  ``X = Y − Z μ`` (O(n h) more). Null-space elimination would need a sparse basis of ``ker C_h`` and a new
  factorisation of the projected matrix, whose fill grows with every point; the Schur form keeps the one sparse
  factor and costs a dense (n × h) product per step, a few percent of the back-substitution for tens of handles.

``A`` is the ARAP matrix of the free vertices plus ``ρ C_hᵀ C_h`` (and the soft terms); on the constraint set this
adds ``ρ ‖C_h X − D_h‖² = 0``, so the solution is unchanged, but it makes ``A`` positive definite where a part of the
mesh is held by points only (with no vertex constraint, the ARAP matrix alone is singular there). ``ρ`` is the mean
diagonal of the ARAP matrix, so that the added terms are of the size of the others. A part of the mesh that touches
no vertex constraint and no point is rejected (:class:`arap.errors.UnconstrainedRegionError`), with soft points as
with hard ones: a soft point alone makes the matrix positive definite (it pins the part's translation by its
weight).

A hard point whose face has only constrained or held vertices is already decided by those (it is refused, as it
would contradict them or repeat them); hard points that depend on each other (two in one place, four in one face)
make ``S`` singular and are refused as well.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from arap.errors import ConstraintError
from arap.indexing import check_point_constraints
from arap.linsolve import Factor

__all__ = ["PointHandles", "PointSystem"]


@dataclass(frozen=True)
class PointHandles:
    """Validated point constraints (face, barycentric coordinates, weight) for :class:`arap.ArapSolver`.

    Attributes
    ----------
    faces : (p,) int64 array
        Face of each point.
    barycentric : (p, 3) float64 array
        Barycentric coordinates in the face (non-negative, summing to 1).
    weights : (p,) float64 array
        ``inf``: hard (met exactly); finite and positive: soft (penalty ``w ‖p − t‖²``).
    """

    faces: NDArray[np.int64]
    barycentric: NDArray[np.float64]
    weights: NDArray[np.float64]

    @classmethod
    def create(cls, faces: ArrayLike, barycentric: ArrayLike, weights: ArrayLike | None = None, *,
               n_faces: int) -> PointHandles:
        """Validate and build (see :func:`arap.indexing.check_point_constraints`; ``weights=None``: all hard)."""
        return cls(*check_point_constraints(faces, barycentric, weights, n_faces))

    def __len__(self) -> int:
        return len(self.faces)

    @property
    def hard(self) -> NDArray[np.bool_]:
        """(p,) bool: which points are hard."""
        return np.isinf(self.weights)

    def positions(self, V: NDArray[np.float64], F: NDArray[np.integer]) -> NDArray[np.float64]:
        """Where the points lie on the mesh ``(V, F)``, shape (p, 3)."""
        return np.einsum("pj,pjk->pk", self.barycentric, V[F[self.faces]])

    def vertices(self, F: NDArray[np.integer]) -> NDArray[np.int64]:
        """Vertices that carry weight in some point (barycentric coordinate > 0), sorted and unique."""
        corners = F[self.faces]
        return np.unique(corners[self.barycentric > 0]).astype(np.int64)


class PointSystem:
    """The global step with point constraints, in the solver's internal vertex order (free vertices first).

    Parameters
    ----------
    points : PointHandles
    F : (m, 3) int array
        Faces in internal vertex numbers.
    n, nf : int
        Number of vertices and of free vertices (rows ``0..nf``).
    L_ff : (nf, nf) sparse matrix
        The ARAP matrix of the free vertices.
    """

    def __init__(self, points: PointHandles, F: NDArray[np.integer], n: int, nf: int, L_ff: sp.spmatrix) -> None:
        p = len(points)
        corners = np.asarray(F)[points.faces]
        C = sp.csr_matrix((points.barycentric.ravel(), (np.repeat(np.arange(p), 3), corners.ravel())),
                          shape=(p, n))
        self.C = C
        self.nf = nf
        self.weights = points.weights
        hard = points.hard
        self.hard = np.flatnonzero(hard)
        self.soft = np.flatnonzero(~hard)
        C_f = C[:, :nf].tocsr()
        self._C_n = C[:, nf:].tocsr()
        self._C_hf = C_f[self.hard]
        self._C_sf = C_f[self.soft]
        self._w_soft = points.weights[self.soft]
        self._C_s = C[self.soft].tocsr()
        empty = np.flatnonzero(np.asarray(abs(self._C_hf).sum(axis=1)).ravel() == 0)
        if len(empty):
            k = int(self.hard[empty[0]])
            raise ConstraintError(f"point {k} is hard but every vertex of its face {int(points.faces[k])} is fixed "
                                  "or outside the region of interest: it cannot move; make it soft or free a vertex")
        diag = L_ff.diagonal()
        self.rho = float(diag.mean()) if len(diag) and diag.mean() > 0 else 1.0
        A = L_ff + (self._C_sf.T @ sp.diags(self._w_soft) @ self._C_sf) + self.rho * (self._C_hf.T @ self._C_hf)
        self.matrix = sp.csr_matrix(A)
        self._Z: NDArray[np.float64] | None = None
        self._S: tuple[NDArray[np.float64], bool] | None = None

    def finish(self, factor: Factor) -> None:
        """After ``matrix`` is factorised: ``Z = A⁻¹ C_hᵀ`` and the Cholesky factor of ``S = C_h Z``."""
        if not len(self.hard):
            return
        Z = factor.solve(np.asarray(self._C_hf.T.todense()))
        S = np.asarray(self._C_hf @ Z)
        S = 0.5 * (S + S.T)
        eig = np.linalg.eigvalsh(S)
        if not eig[0] > 1e-10 * eig[-1]:
            raise ConstraintError("the hard point constraints depend on each other (e.g. two points at one place, "
                                  "or more than three in one face): make some of them soft or remove them")
        self._Z = Z
        self._S = sla.cho_factor(S)

    def rhs_constant(self, T: NDArray[np.float64], fixed: NDArray[np.float64]) -> NDArray[np.float64]:
        """What the point targets add to the right-hand side, shape (nf, 3); also stores ``D_h``."""
        D = T - self._C_n @ fixed
        self._D_h = D[self.hard]
        out = self._C_sf.T @ (self._w_soft[:, None] * D[self.soft])
        if len(self.hard):
            out = out + self.rho * (self._C_hf.T @ self._D_h)
        return np.asarray(out)

    def solve(self, factor: Factor, rhs: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions of the free vertices: minimiser of the global step subject to the hard points, shape (nf, 3)."""
        Y = factor.solve(rhs)
        if self._S is None or self._Z is None:
            return Y
        mu = sla.cho_solve(self._S, self._C_hf @ Y - self._D_h)
        return Y - self._Z @ mu

    def penalty(self, U: NDArray[np.float64], T: NDArray[np.float64]) -> float:
        """The soft points' penalty ``Σ_k w_k ‖C_k U − t_k‖²`` at positions ``U`` (internal order, all vertices)."""
        if not len(self.soft):
            return 0.0
        r = self._C_s @ U - T[self.soft]
        return float(np.dot(self._w_soft, np.einsum("ij,ij->i", r, r)))
