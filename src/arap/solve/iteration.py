"""One solve's iteration, from a solver's prepared record (:mod:`arap.solve.prepared`) and its state between solves: the
local step with the add-ons, the right-hand side, the back-substitution, and the :class:`arap.solve.loops.Iterate` that
the loops run."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from arap.method.local_step import assemble_rhs, assemble_rhs_and_gradient
from arap.method.planar import planar_rhs, planar_rhs_and_gradient
from arap.method.unfold import Unfolder
from arap.solve.addons import LocalState
from arap.solve.anderson import AndersonAccelerator
from arap.solve.lbfgs import LbfgsHistory
from arap.solve.loops import Iterate
from arap.solve.prepared import Prepared
from arap.solve.result import IterationCallback

__all__ = ["SolveState", "lbfgs_applies", "local_energy", "make_iterate", "rhs_constant"]

Array = NDArray[np.float64]

_PLANAR_COLUMNS = True
"""Planar solves iterate on two columns (False: on three, as surfaces do; for tests that compare the two)."""


@dataclass
class SolveState:
    """What a solver keeps from one solve to the next.

    Attributes
    ----------
    local : LocalState
        Rotations and cell energies of the last local step.
    last : (n, 3) float array or None
        The last solution (internal numbering), where a warm start goes on from.
    live : (n, 3) float array or None
        The iterate while a solve runs.
    rotations_fresh : bool
        The rotations fit ``last`` (an iteration ended with a local step on it).
    accelerator, history
        Anderson's window and L-BFGS's curvature pairs, kept for warm starts.
    """

    local: LocalState
    last: Array | None = None
    live: Array | None = None
    rotations_fresh: bool = False
    accelerator: AndersonAccelerator | None = None
    history: LbfgsHistory | None = field(default=None)


def local_energy(p: Prepared, state: LocalState, U: Array, const_E: float, timings: dict[str, float]) -> float:
    """Local step on the active cells at ``U`` (the rotation fit, then each add-on); the total energy."""
    t = time.perf_counter()
    e = p.rotation_fit.fit(U, state)
    for addon in p.addons:
        e = addon.after_fit(U, state, e)
    timings["local"] += time.perf_counter() - t
    return e + const_E


def rhs_constant(p: Prepared, fixed: Array, P: Array | None) -> Array:
    """The right-hand side's constant: ``L_fn @ fixed`` and the add-ons' parts."""
    const = p.coupling(fixed)
    for addon in p.addons:
        const = addon.rhs_constant(const, P, fixed)
    return const


def lbfgs_applies(p: Prepared, P: Array | None) -> bool:
    """True when the energy's gradient in x is ``2 (A x − b(R))`` with the factored ``A``, evaluated to full
    precision: rotations fitted exactly, and no add-on that breaks it (smooth rotations, rigid regions, hard point
    handles)."""
    return p.factor is not None and p.nf > 0 and all(addon.lbfgs_applies(P) for addon in p.addons)


def make_iterate(p: Prepared, state: LocalState, U: Array, fixed: Array, P: Array | None, const_E: float, cap: int,
                 tolerance: float, callback: IterationCallback | None, timings: dict[str, float]) -> Iterate:
    """The steps of one solve for :mod:`arap.solve.loops`.

    A planar solve (:attr:`Prepared.iteration_columns` 2) iterates on its own (n, 2) copy of ``U``'s first two
    columns: the local step, the right-hand side, the back-substitution, the point handles and L-BFGS's vectors
    then spend nothing on ``z``, which stays 0. The iterate's ``sync`` writes it back into ``U``: before every
    callback, and by the caller after the loop.
    """
    nf = p.nf
    A, factor, R = p.matrix, p.factor, state.R
    gather = p.gather
    d = p.iteration_columns if _PLANAR_COLUMNS else 3
    X = U if d == 3 else np.ascontiguousarray(U[:, :d])
    rhs_const = rhs_constant(p, fixed, P)
    if d == 3:
        def rhs(out: Array) -> None:
            assemble_rhs(gather, R, rhs_const, out)

        def rhs_gradient(x: Array, out: Array, grad: Array) -> None:
            assemble_rhs_and_gradient(gather, R, rhs_const, A, x, out, grad)
    else:
        const_d = np.ascontiguousarray(rhs_const[:, :d])

        def rhs(out: Array) -> None:
            planar_rhs(gather, R, const_d, out)

        def rhs_gradient(x: Array, out: Array, grad: Array) -> None:
            planar_rhs_and_gradient(gather, R, const_d, A.indptr, A.indices, A.data, x, out, grad)

    def solve(B: Array) -> Array:
        return B.copy() if factor is None else factor.solve(B)

    correct = None
    for addon in p.addons:
        correct = addon.corrector(None if P is None else P[:, :d], fixed[:, :d]) or correct

    sync = None
    if X is not U:
        def sync() -> None:
            U[:, :d] = X

        if callback is not None:  # the callback may read the iterate (ArapSolver.current_vertices)
            user = callback

            def callback(k: int, e: float) -> bool | None:
                sync()
                return user(k, e)

    # Element energies have no barrier against inversion: elements a solve turns over are opened and the solve resumes.
    unfold = None
    if p.energy_type == "elements" and p.domain.kind in ("planar", "solid") and nf:
        unfold = Unfolder(p.elements, p.rest, U, nf)
    scale = p.diagonal * np.sqrt(max(nf, 1))
    return Iterate(U=X, nf=nf, rotations=R, local=lambda X: local_energy(p, state, X, const_E, timings), rhs=rhs,
                   rhs_gradient=rhs_gradient, solve=solve, correct=correct, coupled=p.rotation_fit.coupled,
                   step_limit=tolerance * scale, scale=scale, cap=cap, callback=callback, timings=timings,
                   scale_initial=p.non_negative, unfold=unfold, sync=sync)
