"""Unfolding the elements a solve turned over.

The element energy ``|τ| ‖J − R‖²_F`` has no barrier at zero area or volume: a long L-BFGS step can push a thin
element through it, and the solve can then settle in a nearby minimum with that element folded, of higher energy
than a minimum without it. Bounding every step so that no element turns over would keep the solve out of such
minima, but L-BFGS's steps turn healthy elements over and back on the way to fold-free results, and cutting those
steps costs many iterations.

So the solve goes on unbounded, and the iterate is looked at once the energy has settled: an element positively
oriented (in its rest orientation) at the start of the solve and not there was folded by the solve, not by the
targets. Its free vertices and their neighbours are moved to the mean of their neighbours a few times (Jacobi sweeps
of the uniform Laplacian), which opens the fold in place at a small rise of the energy, and the solve resumes from
there (see :func:`arap.solve.loops.lbfgs_iterations`). Opening as soon as the energy settles, rather than after
convergence, saves the iterations that would only refine the folded minimum; the opened run is kept only if it ends
lower with no more elements turned over, and is given up as soon as it settles otherwise (the energy alone would
sometimes keep a lower minimum with more folds). The figures are in ``benchmarks/bench_elements.py``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.meshes.domain import signed_measures

__all__ = ["SETTLED", "SMOOTHING_SWEEPS", "Unfolder"]

SMOOTHING_SWEEPS = 20
"""Jacobi sweeps of neighbour averaging over the vertices around the folded elements."""

SETTLED = 1e-6
"""The energy has settled when an iteration lowers it by at most this much of it. Folds are opened then; a looser
threshold opens folds that later iterations would have opened themselves (the 60×30 rectangle at 1e-5 ends in its
folded minimum), a tighter one spends iterations refining the folded minimum."""


class Unfolder:
    """The elements a solve turned over, and the smoothing that opens them (see the module's description).

    Parameters
    ----------
    T : (m, 3) or (m, 4) int64 array
        Elements in the solver's vertex numbering (triangles in ``z = 0`` or tetrahedra).
    rest : (n, 3) float64 array
        Rest positions (their orientation is each element's positive one).
    start : (n, 3) float64 array
        The solve's start (the constrained vertices at their targets).
    nf : int
        The first ``nf`` vertices are free; only they move.

    Example
    -------
    A square fan of four triangles about its free centre, pushed out across the bottom edge:

    >>> rest = np.array([[0.5, 0.5, 0], [0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])   # the free centre first
    >>> T = np.array([[1, 2, 0], [2, 3, 0], [3, 4, 0], [4, 1, 0]])
    >>> unfold = Unfolder(T, rest, rest, nf=1)
    >>> U = rest.copy(); U[0, :2] = [0.5, -0.3]
    >>> unfold.turned_over(U).tolist(), unfold(U), unfold.turned_over(U).tolist(), U[0].round(12).tolist()
    ([0], True, [], [0.5, 0.5, 0.0])
    """

    def __init__(self, T: NDArray[np.int64], rest: NDArray[np.float64], start: NDArray[np.float64], nf: int) -> None:
        self.T = np.ascontiguousarray(T, dtype=np.int64)
        self.nf = nf
        self.n = len(rest)
        # The orientations are measured when first asked for (most solves never are: a drag's capped run, a solve
        # with hard point handles), of copies: the solve moves ``start`` in place.
        self._rest: NDArray[np.float64] | None = rest
        self._start: NDArray[np.float64] | None = np.array(start, dtype=np.float64)
        self._orient: NDArray[np.float64] | None = None
        self._positive: NDArray[np.bool_] | None = None
        self._neighbours: sp.csr_matrix | None = None

    @property
    def orient(self) -> NDArray[np.float64]:
        """Each element's sign of measure at rest (its positive orientation)."""
        if self._orient is None:
            assert self._rest is not None
            self._orient = np.sign(signed_measures(self._rest, self.T))
            self._rest = None
        return self._orient

    @property
    def positive(self) -> NDArray[np.bool_]:
        """The elements positively oriented at the start of the solve."""
        if self._positive is None:
            assert self._start is not None
            self._positive = signed_measures(self._start, self.T) * self.orient > 0
            self._start = None
        return self._positive

    def turned_over(self, U: NDArray[np.float64]) -> NDArray[np.int64]:
        """The elements positively oriented at the start and not at ``U`` (n, 3)."""
        return np.flatnonzero(self.positive & (signed_measures(U, self.T) * self.orient <= 0))

    def neighbours(self) -> sp.csr_matrix:
        """The vertex adjacency of the elements (n, n), ones off the diagonal (built on first use)."""
        if self._neighbours is None:
            k = self.T.shape[1]
            rows = np.repeat(self.T, k, axis=1).ravel()
            cols = np.tile(self.T, (1, k)).ravel()
            keep = rows != cols
            A = sp.csr_matrix((np.ones(int(keep.sum())), (rows[keep], cols[keep])), shape=(self.n, self.n))
            A.data[:] = 1.0
            self._neighbours = A
        return self._neighbours

    def __call__(self, U: NDArray[np.float64]) -> bool:
        """Open the elements turned over at ``U`` in place (see the module's description); False if there are none
        (``U`` unchanged)."""
        folded = self.turned_over(U)
        if not len(folded):
            return False
        A = self.neighbours()
        moved = np.zeros(len(U), dtype=bool)
        moved[self.T[folded].ravel()] = True
        moved |= (A @ moved.astype(np.float64)) > 0
        moved[self.nf:] = False
        rows = np.flatnonzero(moved)
        if not len(rows):
            return False
        A_rows = A[rows]
        degree = np.asarray(A_rows.sum(axis=1)).ravel()[:, None]
        for _ in range(SMOOTHING_SWEEPS):
            U[rows] = (A_rows @ U) / degree
        return True

    def settled(self, U: NDArray[np.float64], before: float, energy: float, most: int) -> bool:
        """True when an iteration that ended at ``U`` lowered the energy from ``before`` to ``energy`` by at most
        :data:`SETTLED` of it, with more than ``most`` elements turned over at ``U``."""
        return before - energy <= SETTLED * abs(energy) and len(self.turned_over(U)) > most
