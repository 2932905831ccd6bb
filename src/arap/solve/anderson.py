"""Anderson acceleration of a fixed-point iteration ``x ← G(x)`` (Peng et al. 2018).

The local/global iteration of ARAP is a fixed-point map ``G`` on the free vertex positions: fit the rotations to
``x``, then solve the global step. Anderson acceleration (type II, Walker & Ni 2011) extrapolates from the last
``m`` iterates: with residuals ``f_k = G(x_k) − x_k`` it finds ``θ = argmin ‖f_k − ΔF θ‖`` over the differences of
consecutive residuals and proposes ``x_{k+1} = G(x_k) − ΔG θ``. Peng et al. 2018 ("Anderson Acceleration for
Geometry Optimization and Physics Simulation") pair it with an energy safeguard: the proposal is kept only if its
energy is no higher than the current one, otherwise the plain step ``G(x_k)`` is taken, which never raises the
energy of a local/global solver. The safeguard lives in the solver; this module only extrapolates.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["AndersonAccelerator"]


class AndersonAccelerator:
    """Type-II Anderson extrapolation over a window of the last ``window`` iterates.

    Parameters
    ----------
    window : int
        Number ``m`` of previous iterate differences used (≥ 1).
    size : int
        Length of the (flattened) iterate vectors.

    Notes
    -----
    The least-squares problem is solved through its ``m × m`` normal equations, whose Gram matrix is updated by one
    matrix-vector product per step, so the cost per step is three passes over ``m`` vectors of length ``size``. The
    products avoid the threaded BLAS, whose thread start-up costs more than these short products on busy cores.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.diag([0.9, 0.5, 0.1]); c = np.ones(3)
    >>> G = lambda x: A @ x + c                      # fixed point: (I − A)⁻¹ c
    >>> aa = AndersonAccelerator(window=3, size=3)
    >>> x = np.zeros(3)
    >>> for _ in range(6):
    ...     g = G(x)
    ...     x_aa = aa.step(x, g)
    ...     x = g if x_aa is None else x_aa
    >>> bool(np.allclose(x, np.linalg.solve(np.eye(3) - A, c)))
    True
    """

    def __init__(self, window: int, size: int) -> None:
        if int(window) != window or window < 1:
            raise ArapError(f"window must be a positive integer, got {window!r}")
        self.window = int(window)
        self._dF = np.zeros((self.window, size))
        self._dG = np.zeros((self.window, size))
        self._gram = np.zeros((self.window, self.window))
        self._f_prev = np.empty(size)
        self._g_prev = np.empty(size)
        self._count = 0  # differences stored (≤ window)
        self._next = 0  # slot of the next difference
        self._has_prev = False

    def reset(self) -> None:
        """Forget the history (the next :meth:`step` only records its iterate)."""
        self._count = 0
        self._next = 0
        self._has_prev = False

    def step(self, x: NDArray[np.float64], g: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Record the iterate ``x`` and its image ``g = G(x)``; return the extrapolated next iterate.

        Parameters
        ----------
        x, g : (size,) float64 arrays
            Current iterate and the fixed-point map applied to it (not modified).

        Returns
        -------
        (size,) float64 array or None
            ``g − ΔG θ``; None while the history is empty (the plain step ``g`` is then the next iterate).
        """
        f = g - x
        if self._has_prev:
            j = self._next
            np.subtract(f, self._f_prev, out=self._dF[j])
            np.subtract(g, self._g_prev, out=self._dG[j])
            self._count = min(self._count + 1, self.window)
            self._next = (j + 1) % self.window
            col = np.einsum("kn,n->k", self._dF[: self._count], self._dF[j])
            self._gram[j, : self._count] = col
            self._gram[: self._count, j] = col
        self._f_prev[:] = f
        self._g_prev[:] = g
        self._has_prev = True
        if self._count == 0:
            return None
        k = self._count
        gram = self._gram[:k, :k]
        rhs = np.einsum("kn,n->k", self._dF[:k], f)
        # Scale-aware Tikhonov term: keeps the normal equations solvable when differences are nearly dependent.
        reg = 1e-12 * max(float(np.trace(gram)), 1e-300)
        try:
            theta = np.linalg.solve(gram + reg * np.eye(k), rhs)
        except np.linalg.LinAlgError:
            theta = np.linalg.lstsq(gram, rhs, rcond=None)[0]
        if not np.all(np.isfinite(theta)):
            self.reset()
            return None
        return g - np.einsum("k,kn->n", theta, self._dG[:k])
