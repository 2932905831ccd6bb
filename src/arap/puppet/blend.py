"""The puppet warp's "normal" mode: the ARAP/ASAP hybrid of Liu, Zhang, Xu, Gotsman & Gortler 2008 ("A
Local/Global Approach to Mesh Parameterization", SGP 2008, section 3.3).

Every triangle ``t`` is fitted a rotation-scale ``L_t = r_t R_t`` (a similarity; never a reflection) and the shape
minimises

    E = Σ_t |t| ( ‖J_t − r_t R_t‖²_F + λ (r_t² − 1)² )

over the positions and the cells' similarities, ``J_t`` the triangle's deformation gradient. ``λ = 0`` is the
as-similar-as-possible energy (parts grow and shrink freely: Photoshop's *Distort*), ``λ → ∞`` the as-rigid-as-possible
one (``r_t = 1``: *Rigid*); in between, scale costs ``λ`` times its squared change of area. The term is weighted by
the triangle's area (Liu et al. weigh it per triangle), so that the blend does not depend on the mesh's density.

The local step keeps the rotation of ARAP (the nearest rotation to ``J_t``; in the plane it is also the direction of
the nearest similarity) and finds the scale in closed form: with ``c = ½ tr(R_tᵀ J_t)`` the scale of the nearest
similarity, ``E_t(r) = |t| (2r² − 4rc + λ(r² − 1)² + const)`` is least at the one positive root of

    λ r³ + (1 − λ) r − c = 0,

so ``λ = 1`` (:data:`NORMAL_LAMBDA`) gives ``r = ∛c``: a part the pins stretch by a similarity of scale ``c`` keeps
the scale ``∛c`` (stretched 8 times, it is drawn twice as large and bends the rest). The global step is ARAP's
(the same prefactored matrix, :meth:`arap.ArapSolver.global_step`) with the similarities in place of the rotations,
hard pins included. Each iteration lowers ``E``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError
from arap.options import DEFAULT_TOLERANCE, DEFAULT_WINDOW, MAX_ITERATIONS
from arap.solve.anderson import AndersonAccelerator
from arap.solve.result import ArapResult

__all__ = ["NORMAL_LAMBDA", "BlendSolver", "cell_scales"]

NORMAL_LAMBDA = 1.0
"""The scale term's weight λ of the "normal" mode: each part keeps the cube root of the scale the pins ask of it."""


def cell_scales(c: NDArray[np.float64], lam: float) -> NDArray[np.float64]:
    """The scale ``r ≥ 0`` minimising ``2r² − 4rc + λ(r² − 1)²`` for each ``c``: the positive root of
    ``λr³ + (1 − λ)r − c = 0`` (``r = c`` for ``λ = 0``, ``∛c`` for ``λ = 1``).

    Newton's iteration from ``max(1, c)``, where the cubic is positive and convex, decreases to the root (``λ = 1``:
    the cube root itself).

    Example
    -------
    >>> cell_scales(np.array([8.0, 1.0, 0.125]), 1.0).round(12).tolist()
    [2.0, 1.0, 0.5]
    """
    c = np.maximum(np.asarray(c, dtype=np.float64), 0.0)
    if lam == 0.0:
        return c
    if lam == 1.0:
        return np.cbrt(c)
    r = np.maximum(c, 1.0)
    for _ in range(100):
        slope = 3.0 * lam * r * r + 1.0 - lam
        step = (lam * r**3 + (1.0 - lam) * r - c) / np.where(slope > 0.0, slope, 1.0)
        r = np.maximum(r - step, 0.0)
        if np.all(np.abs(step) <= 1e-15 * np.maximum(r, 1.0)):
            break
    return r


class BlendSolver:
    """A planar element mesh deformed with the hybrid energy (see :mod:`arap.puppet.blend`), on the factorisation of
    an :class:`arap.ArapSolver` (the global step's matrix is ARAP's).

    Parameters
    ----------
    solver : ArapSolver
        Built with ``energy="elements"`` on a planar mesh (``(n, 2)`` positions, or ``(n, 3)`` in ``z = 0``) and
        the constraints (anchored vertices, point handles) to meet.
    lam : float
        λ ≥ 0: 0 the as-similar-as-possible energy, larger values nearer the rigid one.

    Notes
    -----
    :meth:`solve` takes what :meth:`arap.ArapSolver.solve` takes and gives an :class:`arap.ArapResult`.
    """

    def __init__(self, solver: Any, lam: float) -> None:
        if not (lam >= 0.0 and np.isfinite(lam)):
            raise OptionError(f"the scale weight must be a finite number ≥ 0, got {lam!r}")
        self.inner = solver
        self.lam = float(lam)
        V = np.asarray(solver.V, dtype=np.float64)[:, :2]
        F = np.asarray(solver.F, dtype=np.int64)
        E = np.stack([V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]], axis=2)  # (m, 2, 2): edges as columns
        inv = np.linalg.inv(E)
        self._F = F
        self._grad = inv  # J = [u1 − u0, u2 − u0] @ inv
        self._area = 0.5 * np.abs(np.linalg.det(E))
        lo, hi = V.min(axis=0), V.max(axis=0)
        self._diagonal = float(np.linalg.norm(hi - lo))
        self._last: NDArray[np.float64] | None = None
        self._live: NDArray[np.float64] | None = None
        self.factor_seconds = float(getattr(solver, "factor_seconds", 0.0))

    @property
    def n_free(self) -> int:
        """Free vertices of the factorised system."""
        return int(self.inner.n_free)

    @property
    def V(self) -> NDArray[np.float64]:
        """Rest positions."""
        return np.asarray(self.inner.V)

    @property
    def F(self) -> NDArray[np.int64]:
        """Triangles."""
        return self._F

    def jacobians(self, U: NDArray[np.float64]) -> NDArray[np.float64]:
        """The deformation gradient of every triangle at positions ``U``, shape (m, 2, 2)."""
        P = np.asarray(U, dtype=np.float64)[:, :2]
        F = self._F
        D = np.stack([P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]], axis=2)
        return np.matmul(D, self._grad)

    def _local(self, U: NDArray[np.float64], J: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                                           NDArray[np.float64]]:
        """The cells' similarities for positions ``U`` (whose gradients are ``J``): (m, 3, 3) as the global step takes
        them, and their scales (m,)."""
        R = self.inner.fit_rotations(U)
        c = 0.5 * np.einsum("mij,mij->m", R[:, :2, :2], J)
        r = cell_scales(c, self.lam)
        return R * r[:, None, None], r

    def _energy(self, J: NDArray[np.float64], L: NDArray[np.float64], r: NDArray[np.float64]) -> float:
        residual = J - L[:, :2, :2]
        return float(np.dot(self._area, np.einsum("mij,mij->m", residual, residual) + self.lam * (r * r - 1.0) ** 2))

    def energy(self, U: NDArray[np.float64]) -> float:
        """The hybrid energy of positions ``U`` with their best similarities."""
        U = np.asarray(U, dtype=np.float64)
        J = self.jacobians(U)
        return self._energy(J, *self._local(U, J))

    def solve(self, targets: Any, initial: Any = None, max_iterations: int | None = None,
              tolerance: float = DEFAULT_TOLERANCE, callback: Callable[[int, float], Any] | None = None,
              acceleration: Any = "anderson", window: int | None = None, point_targets: Any = None) -> ArapResult:
        """Deform the mesh so the constraints reach their targets (as :meth:`arap.ArapSolver.solve`).

        ``initial`` None continues from the previous solution (the first time: ARAP's start, the rest pose or its
        best rigid motion onto the targets); a tolerance of 0 runs all ``max_iterations``. Converged when the plain
        step's root mean square is at most ``tolerance`` times the rest pose's bounding-box diagonal.
        ``acceleration``: ``"none"`` the plain local/global iteration, anything else Anderson's acceleration with
        ``window`` iterates (default 5) and an energy safeguard (an extrapolation that raises the energy is replaced
        by the plain step), as :meth:`arap.ArapSolver.solve` does with ``"anderson"``. The energies never rise.
        """
        t0 = time.perf_counter()
        cap = MAX_ITERATIONS if max_iterations is None else int(max_iterations)
        if cap < 0:
            raise OptionError(f"max_iterations must be ≥ 0, got {max_iterations}")
        if initial is None and self._last is not None:
            U, start = self._last, "warm"
        elif initial is None or isinstance(initial, str):
            first = self.inner.solve(targets, initial="auto" if initial is None else initial, max_iterations=0,
                                     point_targets=point_targets)
            U, start = first.vertices, first.start
        else:
            U, start = np.array(initial, dtype=np.float64), "given"
            if U.shape != self.V.shape:
                raise OptionError(f"initial must have shape {self.V.shape}, got {U.shape}")
        energies: list[float] = []
        converged = False
        step = float("nan")
        accelerator = None if acceleration == "none" else AndersonAccelerator(
            DEFAULT_WINDOW if window is None else int(window), U.size)
        J = self.jacobians(U)
        L, r = self._local(U, J)
        best = float("inf")
        for iteration in range(1, cap + 1):
            plain = self.inner.global_step(L, targets, point_targets)
            step = float(np.sqrt(np.mean(np.sum((plain - U) ** 2, axis=1))))
            guess = None if accelerator is None else accelerator.step(U.ravel(), plain.ravel())
            if guess is not None:  # Anderson's extrapolation, kept only if it lowers the energy (Peng et al. 2018)
                U_try = guess.reshape(U.shape)
                J_try = self.jacobians(U_try)
                L_try, r_try = self._local(U_try, J_try)
                energy = self._energy(J_try, L_try, r_try)
                if energy <= best:
                    U, J, L, r = U_try, J_try, L_try, r_try
                else:
                    guess = None
                    assert accelerator is not None
                    accelerator.reset()
            if guess is None:
                U = plain
                J = self.jacobians(U)
                L, r = self._local(U, J)
                energy = self._energy(J, L, r)
            best = min(best, energy)
            energies.append(energy)
            self._live = U
            if callback is not None and callback(iteration, energy) is False:
                break
            if tolerance > 0 and step <= tolerance * self._diagonal:
                converged = True
                break
        self._live = None
        self._last = U
        return ArapResult(vertices=U.copy(), energies=energies, iterations=len(energies), converged=converged,
                          timings={"total": time.perf_counter() - t0}, residual=step, start=start)

    def current_vertices(self) -> NDArray[np.float64]:
        """Positions of the current iterate during :meth:`solve` (from its callback), else of the last solution
        (the rest pose before any)."""
        U = self._live if self._live is not None else self._last
        return self.V.copy() if U is None else U.copy()

    def reset(self) -> None:
        """Forget the previous solution."""
        self._last = None
