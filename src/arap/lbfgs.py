"""L-BFGS directions preconditioned by the global step (Liu, Bouaziz & Kavan 2017).

With the rotations fitted to the positions ``x`` (the local step), the ARAP energy is ``E(x) = xᵀAx − 2 b(R(x))ᵀx +
c`` and, the rotations being optimal, its gradient is ``2 (A x − b(R(x)))`` (the rotations' own change does not
count at an optimum). The plain local/global step ``A⁻¹ b − x`` is therefore a gradient step preconditioned by the
system matrix. Liu et al. 2017 ("Quasi-Newton Methods for Real-time Simulation of Hyperelastic Materials") use that
matrix as the initial inverse Hessian of L-BFGS: the first direction is the plain step, and the curvature pairs
``(s, y)`` of the last ``m`` steps correct it where the energy is flatter or steeper than the matrix says, which the
plain iteration and Anderson's extrapolation handle poorly when a part of the shape drifts slowly for hundreds of
iterations. The line search that keeps the energy from rising lives in the solver; this module only forms
directions.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["LbfgsHistory"]


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    # einsum, not the threaded BLAS: with busy cores its thread start-up costs more than these products.
    return float(np.einsum("ij,ij->", a, b))


class LbfgsHistory:
    """The last ``window`` curvature pairs and the two-loop recursion (Nocedal & Wright, Algorithm 7.4).

    Parameters
    ----------
    window : int
        Number ``m`` of curvature pairs kept (≥ 1).

    Examples
    --------
    Minimise ``½ xᵀQx − cᵀx`` from a poor preconditioner (the diagonal of ``Q``); exact line searches make
    L-BFGS reach the minimum of this 3-dimensional quadratic in 3 steps.

    >>> import numpy as np
    >>> Q = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]); c = np.array([[1.0], [2.0], [3.0]])
    >>> h = LbfgsHistory(window=5)
    >>> x = np.zeros((3, 1)); g = Q @ x - c
    >>> for _ in range(3):
    ...     d = h.direction(g, lambda q: q / np.diag(Q)[:, None])
    ...     step = -float((g * d).sum()) / float((d * (Q @ d)).sum())
    ...     x_new = x + step * d; g_new = Q @ x_new - c
    ...     _ = h.update(x_new - x, g_new - g)
    ...     x, g = x_new, g_new
    >>> bool(np.allclose(x, np.linalg.solve(Q, c)))
    True
    """

    def __init__(self, window: int) -> None:
        if int(window) != window or window < 1:
            raise ArapError(f"window must be a positive integer, got {window!r}")
        self.window = int(window)
        self._s: list[NDArray[np.float64]] = []
        self._y: list[NDArray[np.float64]] = []
        self._rho: list[float] = []

    def __len__(self) -> int:
        return len(self._s)

    def reset(self) -> None:
        """Forget every pair: the next direction is the preconditioned gradient step."""
        self._s.clear()
        self._y.clear()
        self._rho.clear()

    def update(self, s: NDArray[np.float64], y: NDArray[np.float64]) -> bool:
        """Record the step ``s`` and the change ``y`` of the gradient along it; False (nothing recorded) when
        ``sᵀy`` is not positive, where the energy is not convex along the step."""
        sy = _dot(s, y)
        if not sy > 1e-14 * np.sqrt(_dot(s, s) * _dot(y, y)):
            return False
        if len(self._s) == self.window:
            self._s.pop(0)
            self._y.pop(0)
            self._rho.pop(0)
        self._s.append(s)
        self._y.append(y)
        self._rho.append(1.0 / sy)
        return True

    def direction(self, gradient: NDArray[np.float64],
                  precondition: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> NDArray[np.float64]:
        """The descent direction ``−H ∇E``, with ``precondition`` applying the initial inverse Hessian.

        Parameters
        ----------
        gradient : (k, d) float64 array
            The gradient (any positive multiple of it; ``update`` must be given the same multiple).
        precondition : callable
            ``q ↦ H₀ q`` on (k, d) arrays, e.g. a back-substitution with the factored system matrix.

        Returns
        -------
        (k, d) float64 array
            A new array.
        """
        q = gradient.copy()
        alphas = []
        for s, y, rho in zip(reversed(self._s), reversed(self._y), reversed(self._rho), strict=True):
            a = rho * _dot(s, q)
            alphas.append(a)
            q -= a * y
        r = precondition(q)
        for (s, y, rho), a in zip(zip(self._s, self._y, self._rho, strict=True), reversed(alphas), strict=True):
            r += (a - rho * _dot(y, r)) * s
        return np.negative(r, out=r)
