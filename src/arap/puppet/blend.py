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
(the same prefactored matrix) with the similarities in place of the rotations, hard pins included. Each iteration
lowers ``E``.

In the cells of :mod:`arap.method.elements` (``Σ w ‖e' − L e‖² = |t| ‖J − L‖²`` for any ``L``), with ``S`` the
cell's covariance: ``c = |(S₀₀ + S₁₁, S₀₁ − S₁₀)| / Σ w ‖e‖²``. So the hybrid's local step is the planar ARAP local step
(:mod:`arap.method.planar`) with the rotation multiplied by ``r``, and :class:`BlendSolver` runs it as the local step
of ARAP's own solve (:class:`ScaledFit`): the same compiled steps, starts, acceleration and stopping rule. The energy
is the ARAP energy of the similarities plus a term that does not depend on the positions, so its gradient in the
positions is ARAP's ``2 (A x − b)`` with the similarities, and L-BFGS applies where it applies to ARAP.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)
from arap.errors import OptionError
from arap.kernels.parallel import policy
from arap.method.cells import Cells
from arap.method.inactive import InactiveCells
from arap.method.planar import planar_covariance, put_planar_rotation
from arap.options import DEFAULT_TOLERANCE, START_NAMES, Acceleration
from arap.puppet.similar import SimilarSystem
from arap.solve.addons import LocalState, RigidAddOn, RotationFit
from arap.solve.iteration import local_energy
from arap.solve.result import ArapResult
from arap.solve.solver import ArapSolver

__all__ = ["NORMAL_LAMBDA", "BlendSolver", "ScaledFit", "cell_scales", "similarity_step"]

_CHUNK = 512
"""Cells per unit of parallel work (as :mod:`arap.method.planar`)."""

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


@nb.njit(cache=True, nogil=True, inline="always")
def _scale(c, lam):  # pragma: no cover - compiled
    """One cell's :func:`cell_scales` (``c ≥ 0``)."""
    if lam == 0.0:
        return c
    if lam == 1.0:
        return np.cbrt(c)
    r = max(c, 1.0)
    for _ in range(100):
        slope = 3.0 * lam * r * r + 1.0 - lam
        step = (lam * r * r * r + (1.0 - lam) * r - c) / (slope if slope > 0.0 else 1.0)
        r = max(r - step, 0.0)
        if abs(step) <= 1e-15 * max(r, 1.0):
            break
    return r


@nb.njit(cache=True, nogil=True)
def _similarity_chunk(ch, lam, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    # arap.method.planar's kernel with the similarity r R in place of the rotation R, and the scale term.
    total = 0.0
    for t in range(ch * _CHUNK, min(cell_ids.shape[0], (ch + 1) * _CHUNK)):
        c = cell_ids[t]
        p, q, cur = planar_covariance(c, ptr, a, b, w, we, U)
        length = math.sqrt(p * p + q * q)  # tr(R S) of the best rotation: 2|t| c
        double = rest_sq[c]  # Σ w ‖e‖² = 2|t| (cotangent weights)
        r = _scale(length / double if double > 0.0 else 0.0, lam)
        cs = r  # no preferred angle for a collapsed cell: none
        sn = 0.0
        if length > 0.0:
            cs = r * p / length
            sn = r * q / length
        put_planar_rotation(R, c, cs, sn)
        grow = r * r - 1.0
        e = cur - 2.0 * r * length + r * r * double + 0.5 * lam * double * grow * grow
        E[c] = e
        total += e
    return total


@nb.njit(cache=True, nogil=True)
def _similarity_serial(lam, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    total = 0.0
    for ch in range((cell_ids.shape[0] + _CHUNK - 1) // _CHUNK):
        total += _similarity_chunk(ch, lam, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E)
    return total


@nb.njit(cache=True, nogil=True, parallel=True)
def _similarity_parallel(lam, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E):  # pragma: no cover - compiled
    n_chunks = (cell_ids.shape[0] + _CHUNK - 1) // _CHUNK
    part = np.empty(n_chunks)
    for ch in nb.prange(n_chunks):
        part[ch] = _similarity_chunk(ch, lam, cell_ids, ptr, a, b, w, we, rest_sq, U, R, E)
    total = 0.0
    for ch in range(n_chunks):  # summed in order: the thread count does not change the sum
        total += part[ch]
    return total


def similarity_step(cells: Cells, cell_ids: NDArray[np.int64], U: NDArray[np.float64], R: NDArray[np.float64],
                    E: NDArray[np.float64], lam: float) -> float:
    """The local step of the hybrid energy on planar element cells, in place: each listed cell's best similarity
    ``r R`` into ``R`` (3×3, the ``z`` row and column of the identity) and its energy
    ``Σ w ‖e' − r R e‖² + λ ½ Σ w ‖e‖² (r² − 1)²`` into ``E``; their sum.

    With the cotangent weights ``½ Σ w ‖e‖²`` is the triangle's area ``|t|`` and the energy is the module's
    ``|t| (‖J − r R‖² + λ (r² − 1)²)``; with other weights or painted stiffness the scale term is weighted as the
    cell's other terms are. ``U`` is (n, 2), or (n, 3) with ``z = 0`` (only the first two columns are read).
    """
    args = (float(lam), cell_ids, cells.ptr, cells.a, cells.b, cells.w, cells.we, cells.rest_sq, U, R, E)
    work = len(cell_ids) * len(cells.a) // max(cells.n_cells, 1)
    return float(policy.run("similarity", work, lambda: _similarity_serial(*args),
                            lambda: _similarity_parallel(*args)))


class ScaledFit(RotationFit):
    """Each planar cell's best similarity of the hybrid energy (:func:`similarity_step`), as the local step of a
    prepared solver."""

    planar_columns = True  # the similarities are fitted from the first two coordinates

    def __init__(self, cells: Cells, active: NDArray[np.int64], lam: float) -> None:
        self.cells = cells
        self.active = active
        self.lam = float(lam)

    def fit(self, U: NDArray[np.float64], state: LocalState) -> float:
        return similarity_step(self.cells, self.active, U, state.R, state.E, self.lam)

    def fit_all(self, U: NDArray[np.float64], R: NDArray[np.float64], E: NDArray[np.float64]) -> None:
        similarity_step(self.cells, np.arange(self.cells.n_cells), U, R, E, self.lam)


class BlendSolver:
    """A planar element mesh deformed with the hybrid energy (see :mod:`arap.puppet.blend`), on the set-up and the
    factorisation of an :class:`arap.ArapSolver` (the global step's matrix is ARAP's).

    The solve is the ARAP solver's own (its starts, warm starts, Anderson's acceleration or L-BFGS, stopping rule
    and compiled steps) with the local step fitting similarities instead of rotations (:class:`ScaledFit`).

    Parameters
    ----------
    solver : ArapSolver
        Built with ``energy="elements"`` on a planar mesh (``(n, 2)`` positions, or ``(n, 3)`` in ``z = 0``) and
        the constraints (anchored vertices, point handles) to meet. Its factorisation is shared, not copied.
    lam : float
        λ ≥ 0: 0 the as-similar-as-possible energy, larger values nearer the rigid one.
    direct : bool
        With λ = 0 the energy is quadratic: every solve is then one linear solve of its minimum
        (:class:`arap.puppet.similar.SimilarSystem`, factorised here), converged at once, instead of iterations
        (without rigid regions; False: iterate).

    Raises
    ------
    OptionError
        λ negative or not finite, or a solver of another energy or of a mesh not in a plane.

    Notes
    -----
    :meth:`solve` takes what :meth:`arap.ArapSolver.solve` takes and gives an :class:`arap.ArapResult`.
    """

    def __init__(self, solver: ArapSolver, lam: float, direct: bool = True) -> None:
        if not (lam >= 0.0 and np.isfinite(lam)):
            raise OptionError(f"the scale weight must be a finite number ≥ 0, got {lam!r}")
        p = solver.prepared
        if p.energy_type != "elements" or not p.cells.planar or p.F.shape[1] != 3:
            raise OptionError("the hybrid energy needs a solver of a planar triangle mesh with energy='elements'")
        self.inner = solver
        self.lam = float(lam)
        fit = ScaledFit(p.cells, p.active, self.lam)
        inactive = InactiveCells(p.cells, p.active, p.numbering.constrained, p.rest,
                                 fit=partial(similarity_step, lam=self.lam))
        #: The ARAP solver with the similarities' local step, sharing ``inner``'s factorisation.
        self.solver = ArapSolver.from_prepared(replace(p, rotation_fit=fit, inactive=inactive))
        t0 = time.perf_counter()
        rigid = any(isinstance(addon, RigidAddOn) for addon in p.addons)
        #: The as-similar-as-possible minimum as one solve (λ = 0), or None.
        self.similar = SimilarSystem(self.solver.prepared) if direct and self.lam == 0.0 and p.nf and not rigid \
            else None
        self.factor_seconds = float(solver.factor_seconds) + time.perf_counter() - t0

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
        return np.asarray(self.inner.F)

    def energy(self, U: ArrayLike) -> float:
        """The hybrid energy of positions ``U`` with their best similarities, summed over all cells."""
        return self.solver.energy(np.asarray(U, dtype=np.float64))

    def solve(self, targets: Any, initial: Any = None, max_iterations: int | None = None,
              tolerance: float = DEFAULT_TOLERANCE, callback: Callable[[int, float], Any] | None = None,
              acceleration: Acceleration = "lbfgs", window: int | None = None,
              point_targets: Any = None) -> ArapResult:
        """Deform the mesh so the constraints reach their targets: :meth:`arap.ArapSolver.solve`, with its meaning
        of every parameter (``initial`` None continues from the previous solution; a tolerance of 0 runs all
        ``max_iterations``; L-BFGS where that solver runs it, else Anderson's acceleration with its energy
        safeguard). The energies never rise.
        """
        if self.similar is None or max_iterations == 0:
            return self.solver.solve(targets, initial=initial, max_iterations=max_iterations, tolerance=tolerance,
                                     callback=callback, acceleration=acceleration, window=window,
                                     point_targets=point_targets)
        return self._solve_similar(targets, initial, callback, point_targets)

    def _solve_similar(self, targets: Any, initial: Any, callback: Callable[[int, float], Any] | None,
                       point_targets: Any) -> ArapResult:
        """The as-similar-as-possible minimum in one solve (the start does not matter, but is checked), kept as the
        solver's last solution; one iteration, converged."""
        t0 = time.perf_counter()
        solver = self.solver
        p, state = solver.prepared, solver._state
        T = p.check_targets(targets)
        fixed = p.fixed_positions(T)
        P = p.check_point_targets(point_targets)
        if initial is not None and not isinstance(initial, str):
            p.check_positions(initial, "initial")
        elif isinstance(initial, str) and initial not in START_NAMES:
            raise OptionError(f"unknown initial {initial!r}; expected one of {START_NAMES}, an array or None")
        timings = {"local": 0.0, "rhs": 0.0, "solve": 0.0, "acceleration": 0.0}
        assert self.similar is not None
        U = p.rest.copy()
        U[p.nf:] = fixed
        U[:p.nf] = self.similar.solve(fixed, P)
        timings["solve"] = time.perf_counter() - t0
        state.local.points = None if P is None else (P, fixed)
        energy = local_energy(p, state.local, U, p.inactive.energy(U, T), timings)
        state.last, state.live, state.rotations_fresh = U, None, True
        if callback is not None:
            callback(1, energy)
        timings["total"] = time.perf_counter() - t0
        return ArapResult(vertices=p.to_caller(U), energies=[energy], iterations=1, converged=True, timings=timings,
                          residual=0.0, start="given" if initial is not None and not isinstance(initial, str)
                          else "rest")

    def current_vertices(self) -> NDArray[np.float64]:
        """Positions of the current iterate during :meth:`solve` (from its callback), else of the last solution
        (the rest pose before any)."""
        return self.solver.current_vertices()

    def reset(self) -> None:
        """Forget the previous solution."""
        self.solver.reset()
