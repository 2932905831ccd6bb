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
        inv = np.linalg.inv(E)  # J = [u1 − u0, u2 − u0] @ inv
        self._F = F
        self._corners = (np.ascontiguousarray(F[:, 0]), np.ascontiguousarray(F[:, 1]), np.ascontiguousarray(F[:, 2]))
        self._grad = tuple(np.ascontiguousarray(inv[:, i, j]) for i in (0, 1) for j in (0, 1))
        self._area = 0.5 * np.abs(np.linalg.det(E))
        self._similarities = np.zeros((len(F), 3, 3))
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

    def _gradients(self, U: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """The deformation gradients' entries ``(J00, J01, J10, J11)`` at positions ``U``, each (m,)."""
        x, y = U[:, 0], U[:, 1]
        f0, f1, f2 = self._corners
        g00, g01, g10, g11 = self._grad
        x0, y0 = x[f0], y[f0]
        dx1, dx2, dy1, dy2 = x[f1] - x0, x[f2] - x0, y[f1] - y0, y[f2] - y0
        return dx1 * g00 + dx2 * g10, dx1 * g01 + dx2 * g11, dy1 * g00 + dy2 * g10, dy1 * g01 + dy2 * g11

    def jacobians(self, U: NDArray[np.float64]) -> NDArray[np.float64]:
        """The deformation gradient of every triangle at positions ``U``, shape (m, 2, 2)."""
        J = self._gradients(np.asarray(U, dtype=np.float64))
        return np.stack(J, axis=1).reshape(-1, 2, 2)

    def _local(self, J: tuple[NDArray[np.float64], ...]) -> tuple[NDArray[np.float64], ...]:
        """The cells' similarities ``r R`` for gradients ``J``: their entries ``(L00, L01, L10, L11)`` and scales ``r``.

        The rotation is the nearest to ``J`` (in the plane, of angle ``atan2(J10 − J01, J00 + J11)``; the local step of
        planar ARAP) and ``c = ½ tr(Rᵀ J) = ½ |(J00 + J11, J10 − J01)|``.
        """
        p = 0.5 * (J[0] + J[3])
        q = 0.5 * (J[2] - J[1])
        c = np.hypot(p, q)
        r = cell_scales(c, self.lam)
        turned = c > 0.0
        scale = np.divide(r, c, out=np.zeros_like(r), where=turned)
        cos = np.where(turned, p * scale, r)  # no preferred angle for a collapsed triangle: none
        sin = q * scale
        return cos, -sin, sin, cos, r

    def _energy(self, J: tuple[NDArray[np.float64], ...], L: tuple[NDArray[np.float64], ...]) -> float:
        a, b, c, d = J[0] - L[0], J[1] - L[1], J[2] - L[2], J[3] - L[3]
        r = L[4]
        # Not np.dot: the threaded BLAS's start-up costs more than this short product on busy cores.
        return float(np.einsum("m,m->", self._area, a * a + b * b + c * c + d * d + self.lam * (r * r - 1.0) ** 2))

    def _as_matrices(self, L: tuple[NDArray[np.float64], ...]) -> NDArray[np.float64]:
        """The similarities as the global step takes rotations: (m, 3, 3)."""
        M = self._similarities
        M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1], M[:, 2, 2] = L
        return M

    def energy(self, U: NDArray[np.float64]) -> float:
        """The hybrid energy of positions ``U`` with their best similarities."""
        J = self._gradients(np.asarray(U, dtype=np.float64))
        return self._energy(J, self._local(J))

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
        J = self._gradients(U)
        L = self._local(J)
        best = float("inf")
        for iteration in range(1, cap + 1):
            plain = self.inner.global_step(self._as_matrices(L), targets, point_targets)
            moved = plain - U
            step = float(np.sqrt(np.einsum("ij,ij->", moved, moved) / len(U)))
            guess = None if accelerator is None else accelerator.step(U.ravel(), plain.ravel())
            if guess is not None:  # Anderson's extrapolation, kept only if it lowers the energy (Peng et al. 2018)
                U_try = guess.reshape(U.shape)
                J_try = self._gradients(U_try)
                L_try = self._local(J_try)
                energy = self._energy(J_try, L_try)
                if energy <= best:
                    U, J, L = U_try, J_try, L_try
                else:
                    guess = None
                    assert accelerator is not None
                    accelerator.reset()
            if guess is None:
                U = plain
                J = self._gradients(U)
                L = self._local(J)
                energy = self._energy(J, L)
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
