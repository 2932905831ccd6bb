"""A step-by-step implementation of the puppet warp's hybrid energy (Liu et al. 2008; :mod:`arap.puppet.blend`), written
from its formulas with NumPy: deformation gradients per triangle, the similarity fit in closed form, the energy
weighted by the triangles' areas, and ARAP's global step."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import OptionError
from arap.options import DEFAULT_TOLERANCE, DEFAULT_WINDOW, MAX_ITERATIONS
from arap.puppet.blend import cell_scales
from arap.solve.anderson import AndersonAccelerator
from arap.solve.result import ArapResult


class StepwiseBlend:
    """The hybrid energy's local/global iteration step by step from Python (NumPy local steps, one
    :meth:`arap.ArapSolver.global_step` per iteration, Anderson's acceleration with an energy safeguard): the
    reference that :class:`arap.puppet.blend.BlendSolver`'s compiled solve is checked against."""

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
