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

import numba as nb
import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["MAX_SCALE", "LbfgsHistory", "difference_norm", "step_dot", "step_norm", "subtract_norm"]

MAX_SCALE = 4.0
"""Largest factor on the initial inverse Hessian (see :meth:`LbfgsHistory.update`)."""


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:  # pragma: no cover - compiled
    # The sum may be reordered into SIMD lanes (a fixed order for a given build): several times faster than one
    # running sum, which waits on the latency of every addition (benchmarks/bench_armadillo.py times an L-BFGS
    # iteration against a plain one).
    total = 0.0
    for i in range(a.size):
        total += a[i] * b[i]
    return total


@nb.njit(cache=True, nogil=True)
def _axpy(alpha: float, x: NDArray[np.float64], y: NDArray[np.float64]) -> None:  # pragma: no cover - compiled
    for i in range(x.size):
        y[i] += alpha * x[i]


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _axpy_dot(alpha: float, x: NDArray[np.float64], y: NDArray[np.float64],
              z: NDArray[np.float64]) -> float:  # pragma: no cover - compiled
    # y += alpha x, and the dot product of z with the new y, in one pass over y (the two loops of the recursion
    # each follow an update with the next pair's dot product: fused, they read the long vectors once less).
    total = 0.0
    for i in range(x.size):
        v = y[i] + alpha * x[i]
        y[i] = v
        total += z[i] * v
    return total


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _diff_dot(a, b, c):  # pragma: no cover - compiled
    # (a − b)ᵀc in one pass
    total = 0.0
    for i in range(a.size):
        total += (a[i] - b[i]) * c[i]
    return total


def step_dot(x_new: NDArray[np.float64], x: NDArray[np.float64], c: NDArray[np.float64]) -> float:
    """``(x_new − x)ᵀc`` over all entries of three C-contiguous float64 arrays of one size, in one pass.

    Example
    -------
    >>> step_dot(np.array([[3.0, 1.0]]), np.array([[1.0, 1.0]]), np.array([[0.5, 7.0]]))
    1.0
    """
    return float(_diff_dot(x_new.reshape(-1), x.reshape(-1), c.reshape(-1)))


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _pair(x_new, x, g_new, g, s, y):  # pragma: no cover - compiled
    # s = x_new − x, y = g_new − g and the products sᵀy, sᵀs, yᵀy, in one pass
    sy = 0.0
    ss = 0.0
    yy = 0.0
    for i in range(x.size):
        a = x_new[i] - x[i]
        b = g_new[i] - g[i]
        s[i] = a
        y[i] = b
        sy += a * b
        ss += a * a
        yy += b * b
    return sy, ss, yy


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _subtract_sq(d: NDArray[np.float64], x: NDArray[np.float64]) -> float:  # pragma: no cover - compiled
    total = 0.0
    for i in range(d.shape[0]):
        for j in range(d.shape[1]):
            v = d[i, j] - x[i, j]
            d[i, j] = v
            total += v * v
    return total


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _difference_sq(a, b):  # pragma: no cover - compiled
    total = 0.0
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            v = a[i, j] - b[i, j]
            total += v * v
    return total


def difference_norm(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Euclidean norm of ``a − b`` over all entries, in one pass without a temporary (float64 arrays of one shape
    (k, m), any memory layout).

    Example
    -------
    >>> difference_norm(np.array([[4.0, 0.0, 5.0]]), np.array([[1.0, 0.0, 1.0]]))
    5.0
    """
    return float(np.sqrt(_difference_sq(a, b)))


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _subtract_sq_place(d, x, out):  # pragma: no cover - compiled
    total = 0.0
    for i in range(d.shape[0]):
        for j in range(d.shape[1]):
            v = d[i, j] - x[i, j]
            d[i, j] = v
            out[i, j] = x[i, j] + v
            total += v * v
    return total


def subtract_norm(d: NDArray[np.float64], x: NDArray[np.float64], out: NDArray[np.float64] | None = None) -> float:
    """``d −= x`` in place and the Euclidean norm of the result, in one pass (float64 arrays of one shape (k, m),
    any memory layout: a back-substitution may return Fortran order); with ``out``, also ``out = x + d`` (the step
    taken) in the same pass.

    Example
    -------
    >>> d = np.array([[4.0, 0.0, 5.0]]); subtract_norm(d, np.array([[1.0, 0.0, 1.0]])), d.tolist()
    (5.0, [[3.0, 0.0, 4.0]])
    """
    if out is None:
        return float(np.sqrt(_subtract_sq(d, x)))
    return float(np.sqrt(_subtract_sq_place(d, x, out)))


def step_norm(d: NDArray[np.float64]) -> float:
    """Euclidean norm of a C-contiguous float64 array over all its entries.

    Example
    -------
    >>> step_norm(np.array([[3.0, 0.0, 4.0]]))
    5.0
    """
    flat = d.reshape(-1)
    return float(np.sqrt(_dot(flat, flat)))


class LbfgsHistory:
    """The last ``window`` curvature pairs and the two-loop recursion (Nocedal & Wright, Algorithm 7.4).

    The pairs live in preallocated slots and the recursion works in place (compiled dot products and updates), so
    a direction allocates nothing but what ``precondition`` returns.

    Parameters
    ----------
    window : int
        Number ``m`` of curvature pairs kept (≥ 1).

    Attributes
    ----------
    scale : float
        Factor on the initial inverse Hessian (1 until :meth:`update` is given an ``excess``).

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
    ...     _ = h.update(x_new, x, g_new, g)
    ...     x, g = x_new, g_new
    >>> bool(np.allclose(x, np.linalg.solve(Q, c)))
    True
    """

    def __init__(self, window: int) -> None:
        if int(window) != window or window < 1:
            raise ArapError(f"window must be a positive integer, got {window!r}")
        self.window = int(window)
        self._S: NDArray[np.float64] | None = None  # (window, size) steps
        self._Y: NDArray[np.float64] | None = None  # (window, size) gradient changes
        self._rho = np.zeros(self.window)
        self._q = np.empty(0)
        self._alpha = np.zeros(self.window)
        self._order: list[int] = []  # slots, oldest first
        self._work: tuple[NDArray[np.float64], ...] = ()
        self.scale = 1.0

    def buffers(self, rows: int, count: int = 4, columns: int = 3) -> tuple[NDArray[np.float64], ...]:
        """``count`` work arrays of shape (rows, columns), allocated once for a given size (a drag calls the loop
        with one iteration many times; fresh arrays of a large mesh cost page faults on every call)."""
        if len(self._work) != count or self._work[0].shape != (rows, columns):
            self._work = tuple(np.empty((rows, columns)) for _ in range(count))
        return self._work

    def __len__(self) -> int:
        return len(self._order)

    def reset(self) -> None:
        """Forget every pair and the scale: the next direction is the preconditioned gradient step."""
        self._order.clear()
        self.scale = 1.0

    def _slots(self, size: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if self._S is None or self._Y is None or self._S.shape[1] != size:
            self._S = np.empty((self.window, size))
            self._Y = np.empty((self.window, size))
            self._q = np.empty(size)
            self._order.clear()
        return self._S, self._Y

    def update(self, x_new: NDArray[np.float64], x: NDArray[np.float64], g_new: NDArray[np.float64],
               g: NDArray[np.float64], excess: float | None = None) -> bool:
        """Record the step ``s = x_new − x`` and the gradient's change ``y = g_new − g`` along it; False (nothing
        recorded) when ``sᵀy`` is not positive, where the energy is not convex along the step.

        The arrays (any shape, C-contiguous, all of one size) are not kept: their differences are copied into
        the history. When the window is full, the oldest pair makes room (also when the new pair is refused).

        ``excess``, when given, is ``sᵀ(H₀⁻¹ s − y)``: how much more the initial Hessian curves along the step than
        the energy does. The initial inverse Hessian is then scaled for the next directions by
        ``γ = sᵀH₀⁻¹s / sᵀy`` (the Barzilai-Borwein step length in the metric of ``H₀⁻¹``), clipped to
        ``[1, MAX_SCALE]``: where the energy is flatter than the system matrix (the nearly free turns of a limb
        about its joint) the unscaled steps fall short, and the line search accepted twice the step in most
        iterations of a settle on the armadillo. With spokes-and-rims cells, scaled steps took markedly fewer
        iterations to the same minima on four meshes and three scenarios (at most 4: larger factors made the line
        search backtrack more; ``benchmarks/bench_convergence.py`` measures the iterations to convergence, and
        ``benchmarks/README.md`` describes the runs).
        """
        S, Y = self._slots(x.size)
        free = [k for k in range(self.window) if k not in self._order]
        slot = free[0] if free else self._order.pop(0)  # a full window gives up its oldest pair
        sy, ss, yy = _pair(x_new.reshape(-1), x.reshape(-1), g_new.reshape(-1), g.reshape(-1), S[slot], Y[slot])
        if not sy > 1e-14 * np.sqrt(ss * yy):
            return False
        self._order.append(slot)
        self._rho[slot] = 1.0 / sy
        if excess is not None:
            self.scale = min(max(1.0 + excess / sy, 1.0), MAX_SCALE)
        return True

    def direction(self, gradient: NDArray[np.float64],
                  precondition: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> NDArray[np.float64]:
        """The descent direction ``−H ∇E``, with ``precondition`` applying the initial inverse Hessian (times
        :attr:`scale`).

        Parameters
        ----------
        gradient : (k, d) float64 array
            The gradient (any positive multiple of it; ``update`` must be given the same multiple).
        precondition : callable
            ``q ↦ H₀ q`` on (k, d) arrays, e.g. a back-substitution with the factored system matrix.

        Returns
        -------
        (k, d) float64 array
            A new array (or the one ``precondition`` returned, written over).
        """
        S, Y = self._slots(gradient.size)
        q = self._q
        q[:] = gradient.reshape(-1)
        rho, alpha = self._rho, self._alpha
        newest_first = self._order[::-1]
        if newest_first:
            a = rho[newest_first[0]] * _dot(S[newest_first[0]], q)
        for k, slot in enumerate(newest_first):  # α_i = ρ_i s_iᵀq; q −= α_i y_i (and the next α's product)
            alpha[slot] = a
            if k + 1 < len(newest_first):
                after = newest_first[k + 1]
                a = rho[after] * _axpy_dot(-a, Y[slot], q, S[after])
            else:
                _axpy(-a, Y[slot], q)
        r = np.ascontiguousarray(precondition(q.reshape(gradient.shape)), dtype=np.float64)
        if np.shares_memory(r, q):
            r = r.copy()
        if self.scale != 1.0:
            r *= self.scale
        flat = r.reshape(-1)
        oldest_first = self._order
        if oldest_first:
            b = rho[oldest_first[0]] * _dot(Y[oldest_first[0]], flat)
        for k, slot in enumerate(oldest_first):  # β_i = ρ_i y_iᵀr; r += (α_i − β_i) s_i (and the next β's product)
            if k + 1 < len(oldest_first):
                after = oldest_first[k + 1]
                b = rho[after] * _axpy_dot(alpha[slot] - b, S[slot], flat, Y[after])
            else:
                _axpy(alpha[slot] - b, S[slot], flat)
        return np.negative(r, out=r)
