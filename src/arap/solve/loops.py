"""The iteration loops of :meth:`arap.ArapSolver.solve`: the plain and Anderson-accelerated local/global iteration,
and L-BFGS preconditioned by the global step.

Both act on an :class:`Iterate`, which the solver builds for one call: the positions, the local step, the
right-hand side (and the global step's residual), the back-substitution and the point-handle correction. Energies
never rise from one iteration to the next: Anderson's extrapolations and L-BFGS's line search fall back on the
plain step, which cannot raise the energy. The one exception: an element solve that settles with elements it turned
over opens them (:mod:`arap.method.unfold`), and goes on from there.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from arap.method.unfold import Unfolder
from arap.solve.anderson import AndersonAccelerator
from arap.solve.lbfgs import LbfgsHistory, difference_norm, step_dot, step_norm, subtract_norm
from arap.solve.result import IterationCallback

__all__ = ["CHECK_EVERY", "CHECK_FACTOR", "LINE_SEARCH_HALVINGS", "PLAIN_START", "Iterate", "Outcome",
           "lbfgs_iterations", "plain_iterations"]

#: L-BFGS line search: trials from step 1, halving, before the plain step is taken instead.
LINE_SEARCH_HALVINGS = 5
#: L-BFGS measures the plain step (a back-substitution) when its own step was at most this many times the tolerance,
#: and every ``CHECK_EVERY`` iterations.
CHECK_FACTOR = 10.0
CHECK_EVERY = 10
#: Plain local/global steps before L-BFGS builds its history, from a cold start (not a warm start). Far from
#: equilibrium the rotations change fast, and L-BFGS's early long steps can cross into another basin of the spokes
#: energy, whose negative cotangent weights give it several minima: on the armadillo bend, L-BFGS from the start
#: settled at −0.022799 while the plain iteration reaches −0.022825 (libigl's basin), and with 10 plain steps first
#: at −0.022847. Over 8 spokes scenarios on scans, the first 10 steps plain gave a lower minimum in 5, the same in 2
#: and a higher one in 1; with spokes and rims (one minimum) the same shapes, at 0–8% more iterations.
PLAIN_START = 10

Array = NDArray[np.float64]


@dataclass
class Iterate:
    """One :meth:`~arap.ArapSolver.solve` call's state and steps, as the loops see them.

    Attributes
    ----------
    U : (n, d) float64 array
        Positions in the solver's internal order, written in place; the first ``nf`` rows are the free vertices.
        ``d`` is 3, or 2 for a planar solve (every array below then has two columns).
    nf : int
        Number of free vertices.
    rotations : (n, 3, 3) float64 array
        The rotations the right-hand side uses (written by ``local``).
    local : callable
        ``local(U) -> energy``: the local step at ``U``, fitting ``rotations``; the total energy.
    rhs : callable
        ``rhs(out)``: the global step's right-hand side ``b`` for ``rotations``, into ``out`` (nf, 3).
    rhs_gradient : callable
        ``rhs_gradient(x, out, grad)``: ``rhs(out)`` and ``grad = A x − b``, the residual of the global step.
    solve : callable
        ``solve(B)``: ``A⁻¹ B`` for (nf, 3) ``B`` (a new array).
    correct : callable or None
        Applied to the global step's solution (hard point handles), or None; it may correct its argument in place
        (the solution of ``solve``, a new array) and returns the corrected solution.
    coupled : bool
        The rotations are moved on from their previous values (``smooth_rotations``): the plain step after a
        rejected extrapolation restarts from the rotations before it.
    step_limit : float
        Converged when the plain step's norm (over all free coordinates) is at most this.
    scale : float
        ``diagonal · √nf``: the plain step's norm over this is the reported residual.
    cap : int
        Most iterations.
    callback : callable or None
        ``callback(iteration, energy)``; False stops.
    timings : dict of str to float
        Seconds, accumulated: ``local`` (inside ``local``), ``rhs``, ``solve``, ``acceleration``.
    scale_initial : bool
        L-BFGS scales its initial inverse Hessian ``A⁻¹`` by the curvature seen along the last step (see
        :meth:`arap.solve.lbfgs.LbfgsHistory.update`). Its longer steps can end in another minimum of an energy with
        several (the spokes energy with negative cotangent weights), so the solver asks for it only where every
        cell's energy is a sum of non-negative terms.
    unfold : Unfolder or None
        Opens the elements that the solve turned over (:class:`arap.method.unfold.Unfolder`, planar and solid element
        energies only). None: nothing is unfolded.
    sync : callable or None
        Writes ``U`` into the solver's (n, 3) positions when ``U`` is a planar solve's (n, 2) copy of them; None
        when ``U`` is the solver's array itself.
    """

    U: Array
    nf: int
    rotations: Array
    local: Callable[[Array], float]
    rhs: Callable[[Array], None]
    rhs_gradient: Callable[[Array, Array, Array], None]
    solve: Callable[[Array], Array]
    correct: Callable[[Array], Array] | None
    coupled: bool
    step_limit: float
    scale: float
    cap: int
    callback: IterationCallback | None
    timings: dict[str, float]
    scale_initial: bool = False
    unfold: Unfolder | None = None
    sync: Callable[[], None] | None = None


@dataclass
class Outcome:
    """What a loop did: the energies after each iteration, whether the last plain step was within the tolerance,
    the residual (plain step over ``scale``; NaN if never measured) and the rejected accelerated steps."""

    energies: list[float] = field(default_factory=list)
    converged: bool = False
    residual: float = float("nan")
    rejected: int = 0


def plain_iterations(it: Iterate, energy: float | None, accel: AndersonAccelerator | None) -> Outcome:
    """The local/global iteration of Sorkine & Alexa 2007, Anderson-accelerated when ``accel`` is given.

    Parameters
    ----------
    it : Iterate
    energy : float or None
        Energy at the start, when ``it.rotations`` were fitted to it (None: they were fitted to another shape, and
        the first step is not extrapolated).
    accel : AndersonAccelerator or None
        Reset before use. An extrapolated iterate is kept only if its energy is not higher than the current one.
    """
    out = Outcome()
    nf, U, timings = it.nf, it.U, it.timings
    rhs = np.empty((nf, U.shape[1]))
    # The coupled rotations of smooth_rotations go on from the current ones: kept for the fallback of a rejected
    # extrapolation, in one buffer for the call.
    saved = np.empty_like(it.rotations) if accel is not None and it.coupled else None
    if accel is not None:
        accel.reset()
    for k in range(it.cap):
        x = U[:nf]  # a view: read before the iterate is overwritten below
        t = time.perf_counter()
        it.rhs(rhs)
        t2 = time.perf_counter()
        g = it.solve(rhs)
        if it.correct is not None:
            g = it.correct(g)
        timings["rhs"] += t2 - t
        timings["solve"] += time.perf_counter() - t2
        if accel is None:  # the step, its norm and the new iterate (x is a view of U) in one pass
            step = subtract_norm(g, x, x)
        else:
            step = difference_norm(g, x)
        out.residual = step / it.scale
        last = step <= it.step_limit
        candidate = None
        if accel is not None:
            t = time.perf_counter()
            candidate = accel.step(x.ravel(), g.ravel())
            timings["acceleration"] += time.perf_counter() - t
            if last or energy is None:
                candidate = None
            U[:nf] = g if candidate is None else candidate.reshape(nf, -1)
        if candidate is not None and saved is not None:
            np.copyto(saved, it.rotations)
        e = it.local(U)
        if candidate is not None and energy is not None and e > energy:
            # Safeguard: the extrapolation raised the energy; take the plain step, which cannot.
            out.rejected += 1
            assert accel is not None
            accel.reset()
            U[:nf] = g
            if saved is not None:
                np.copyto(it.rotations, saved)
            e = it.local(U)
        energy = e
        out.energies.append(e)
        stop = it.callback is not None and it.callback(k + 1, e) is False
        if it.step_limit > 0 and last:
            out.converged = True
        if out.converged or stop:
            break
    return out


def lbfgs_iterations(it: Iterate, energy: float | None, history: LbfgsHistory, plain_start: int = 0) -> Outcome:
    """L-BFGS preconditioned by the global step (see :mod:`arap.solve.lbfgs`), with a backtracking line search.

    Each iteration: a direction from the history (the plain step when it is empty, or when ``it.rotations`` were
    fitted to another shape), a backtracking line search on the energy from step 1, the plain step if no trial
    lowered it, then the residual at the new iterate. The plain step's size, the convergence measure, costs a
    back-substitution: it is taken when the step was small, every ``CHECK_EVERY`` iterations, and at the end.

    When the energy settles with elements the solve turned over (:meth:`arap.method.unfold.Unfolder.settled`: an
    iteration lowered it by at most :data:`arap.method.unfold.SETTLED` of it, before it converged) or converges with
    them, ``it.unfold`` opens them and the iteration goes on from there (L-BFGS at once, with a new history). That run
    is kept if it ends lower than the iterate it opened, with no more elements turned over; it is given up as soon as
    it settles at or above that energy or with more elements turned over, and then the iteration goes on from the
    iterate it opened (without opening again). One iteration of ``it.cap`` is kept back for that. Every iteration,
    given up or not, is in the outcome's energies (and was passed to the callback); they rise once, where the
    elements were opened. A callback that stops the opened run leaves the solve where it is.

    Parameters
    ----------
    it : Iterate
    energy : float or None
        Energy at the start when ``it.rotations`` were fitted to it; None when they were fitted to another shape (a
        warm start towards new targets): the first step is then the plain one.
    history : LbfgsHistory
        Reset before use (a solver keeps one, so that its slots are allocated once).
    plain_start : int
        The first this many iterations take the plain step and keep no curvature pair (see :data:`PLAIN_START`).
    """
    unfold = it.unfold
    if unfold is None or it.cap < 3:
        return _lbfgs_run(it, energy, history, plain_start)
    nf, U = it.nf, it.U
    settled = False  # the last run was stopped by its watch

    def watch(most: int, ceiling: float = np.inf) -> Callable[[float, float], bool]:
        """Stop when the energy settles with more than ``most`` elements turned over, or at ``ceiling`` or above."""
        def stop(before: float, e: float) -> bool:
            nonlocal settled
            settled = unfold.settled(U, before, e, -1 if e >= ceiling else most)
            return settled
        return stop

    out = _lbfgs_run(it, energy, history, plain_start, watch(0))
    if not (out.converged or settled) or len(out.energies) >= it.cap - 1:
        return out
    folds, kept, e_kept = len(unfold.turned_over(U)), U[:nf].copy(), out.energies[-1]
    if not unfold(U):
        return out if out.converged else _resume(it, out, history, e_kept, None)
    # One iteration is kept back for the restored iterate. The opened run is given up as soon as it settles with
    # more elements turned over than there were, or not below the kept energy.
    settled = False
    opened = _resume(replace(it, cap=it.cap - 1), out, history, it.local(U), watch(folds, e_kept))
    if not (opened.converged or settled or len(opened.energies) >= it.cap - 1):
        return opened  # stopped by the callback
    if not settled and opened.energies[-1] < e_kept and len(unfold.turned_over(U)) <= folds:
        return opened
    U[:nf] = kept
    return _resume(it, opened, history, it.local(U), None)


def _resume(it: Iterate, before: Outcome, history: LbfgsHistory, energy: float,
            watch: Callable[[float, float], bool] | None) -> Outcome:
    """L-BFGS from ``it.U`` (at ``energy``, the rotations fitted to it), with a new history, after the iterations of
    ``before`` and within what is left of ``it.cap``: the outcome of both."""
    done, callback = len(before.energies), it.callback
    shifted = None if callback is None else (lambda k, e: callback(k + done, e))
    more = _lbfgs_run(replace(it, cap=it.cap - done, callback=shifted), energy, history, 0, watch)
    return Outcome(before.energies + more.energies, more.converged, more.residual, before.rejected + more.rejected)


def _lbfgs_run(it: Iterate, energy: float | None, history: LbfgsHistory, plain_start: int,
               watch: Callable[[float, float], bool] | None = None) -> Outcome:
    """One run of :func:`lbfgs_iterations`'s iteration, without unfolding; ``watch(previous energy, energy)`` after
    an iteration, True: stop there."""
    out = Outcome()
    nf, U, timings = it.nf, it.U, it.timings
    history.reset()
    x, grad, new_grad, rhs = history.buffers(nf, columns=U.shape[1])

    def fit_rhs(grad: Array) -> None:
        """Right-hand side for the rotations fitted to ``x``, and the residual ``A x − b`` into ``grad``."""
        t = time.perf_counter()
        it.rhs_gradient(U[:nf], rhs, grad)
        timings["rhs"] += time.perf_counter() - t

    def plain_step_from_here() -> Array:
        t = time.perf_counter()
        g = it.solve(rhs)
        timings["solve"] += time.perf_counter() - t
        return g

    fresh = energy is not None  # the rotations fit the start
    if fresh:
        x[:] = U[:nf]
        fit_rhs(grad)
    else:  # stale rotations: the first step is the plain one, no gradient
        t = time.perf_counter()
        it.rhs(rhs)
        timings["rhs"] += time.perf_counter() - t
    # The iterate the step starts from. After a stale start the first step is the plain one, taken as it is (no
    # energy to compare with) and kept in no curvature pair, so it is computed from U in place, without a copy.
    base = x if fresh else U[:nf]
    residual_at = -2  # iteration whose iterate the residual was measured at (0: the start)
    rhs_fresh = True
    for k in range(1, it.cap + 1):
        d_norm = -1.0  # the norm of d when known (the plain step's), else measured below
        placed = False  # U already holds x + d
        if fresh and len(history) and k > plain_start:
            t = time.perf_counter()
            d = history.direction(grad, it.solve)
            timings["acceleration"] += time.perf_counter() - t
        else:
            d = plain_step_from_here()
            d_norm = subtract_norm(d, base, U[:nf])
            placed = True
            out.residual, residual_at = d_norm / it.scale, k - 1
            out.converged = fresh and d_norm <= it.step_limit  # this plain step is the last
        for _ in range(LINE_SEARCH_HALVINGS):
            if not placed:
                np.add(x, d, out=U[:nf])
            placed = False
            e = it.local(U)
            if energy is None or e <= energy:
                break
            d *= 0.5
            d_norm *= 0.5
        else:  # no trial lowered the energy: the plain step from x, which cannot raise it
            out.rejected += 1
            history.reset()
            d = plain_step_from_here()
            d_norm = subtract_norm(d, x, U[:nf])
            e = it.local(U)
        check = not out.converged and it.step_limit > 0 and (
            (d_norm if d_norm >= 0 else step_norm(d)) <= CHECK_FACTOR * it.step_limit or k % CHECK_EVERY == 0)
        rhs_fresh = k < it.cap or check  # the last iteration of a capped run (a drag) needs no gradient
        if rhs_fresh:
            pair = fresh and k >= plain_start
            # The gradient is A x − b(R): sᵀ(A s − y) = sᵀ(b_new − b_old), for the scale of A⁻¹.
            before = step_dot(U[:nf], x, rhs) if pair and it.scale_initial else 0.0
            fit_rhs(new_grad)
            if pair:
                history.update(U[:nf], x, new_grad, grad,
                               step_dot(U[:nf], x, rhs) - before if it.scale_initial else None)
        grad, new_grad = new_grad, grad
        fresh = True
        previous, energy = energy, e
        out.energies.append(e)
        stop = it.callback is not None and it.callback(k, e) is False
        if check:
            out.residual, residual_at = subtract_norm(plain_step_from_here(), U[:nf]) / it.scale, k
            if out.residual * it.scale <= it.step_limit:
                out.converged = True
        if out.converged or stop or k == it.cap or (
                watch is not None and previous is not None and watch(previous, e)):
            break
        x[:] = U[:nf]  # the next iteration's base (the loop's last iterate is read from U)
        base = x
    if out.energies and residual_at < len(out.energies) - 1:
        if not rhs_fresh:
            fit_rhs(grad)
        out.residual = subtract_norm(plain_step_from_here(), U[:nf]) / it.scale
    return out
