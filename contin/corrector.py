"""Bordered Newton corrector of pseudo-arclength continuation (Keller 1977).

Solves, for x = (u, p) near a predicted point x_pred,

    F(u, p) = 0,       c . (x - x_pred) = 0,

with c the theta-weighted predictor direction (``ExtendedSystem.row``).  Each iteration builds
and factorizes the bordered matrix [[J, F_p], [c^T]] once (``contin.linalg``: dense LAPACK for
small n, SuperLU above); the factorization of the last iteration is returned so the caller
reuses it for the tangent and the test functions.

Chord iterations (reusing one LU while the update is small) were measured on gPCF and not
kept: they save factorizations but need about twice the residual evaluations, which cost as
much at continuation sizes, and the step-size law (driven by the iteration count) then grows
steps faster than plain Newton's count allows, which let a fold-curve trace step past its end.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from contin.extended import ExtendedSystem
from contin.linalg import DenseLU, Factorization, factorize_bordered
from contin.newton import DIVERGENCE_FACTOR, arithmetic_failure, backtrack, converged, max_norm
from contin.options import NewtonOptions
from contin.problem import Array


@dataclass
class Correction:
    """Result of :func:`correct`: the point, its last factorization and the residual history."""

    x: Array
    converged: bool
    iterations: int
    factorization: Factorization | None
    row: Array
    residual_history: list[float] = field(default_factory=list)
    message: str = ""


def correct(system: ExtendedSystem, x_pred: Array, row: Array, options: NewtonOptions,
            project: Callable[[Array], Array] | None = None,
            give_up: Callable[[Array, Array], str | None] | None = None) -> Correction:
    """Bordered Newton from ``x_pred`` on [F(x); row . (x - x_pred)] = 0 (see :func:`_correct`)."""
    with np.errstate(all="ignore"):
        try:
            return _correct(system, x_pred, row, options, project, give_up)
        except ArithmeticError as exc:  # Python-float arithmetic of a problem (W**2 at W = 1e300)
            return Correction(np.array(x_pred, dtype=float), False, 0, None, row, [],
                              arithmetic_failure(exc, "the predicted point"))


def _correct(system: ExtendedSystem, x_pred: Array, row: Array, options: NewtonOptions,
             project: Callable[[Array], Array] | None = None,
             give_up: Callable[[Array, Array], str | None] | None = None) -> Correction:
    """Bordered Newton from ``x_pred`` on [F(x); row . (x - x_pred)] = 0.

    At least one iteration is always done so that a factorization at the solution exists (an
    exact predictor, e.g. on a trivial branch, would otherwise leave none).  Never raises.

    ``project`` (optional) maps the u-part of each Newton update into an invariant subspace
    containing the solution, e.g. the symmetrizer (u + S u)/2 on an S-invariant branch.  In
    exact arithmetic the update already lies there; projecting removes the rounding noise
    that a nearly singular mode outside the subspace (a symmetry-breaking BP nearby, where
    the bordered matrix is singular) would otherwise amplify into the iterate.

    ``give_up`` (optional) is called with (x, dx) after each unconverged update; a reason it
    returns ends the correction as not converged with that message (a caller that will reject
    the point anyway, e.g. for lying too far from the predictor, need not converge it).
    """
    x = np.array(x_pred, dtype=float)
    # Bound methods and options looked up once: this loop runs ~4 times per continuation step,
    # and at small n (cheb 12: 41 unknowns) an iteration is a few hundred microseconds of
    # Python-level calls, so every attribute look-up and temporary outside the four parts
    # (residual, Jacobian, factorization, solve) shows (benchmarks.linear_algebra).
    residual, jacobian, admissible = system.residual, system.jacobian, system.admissible
    f = residual(x)
    r = max_norm(f)
    history = [r]
    fact: Factorization | None = None
    if not math.isfinite(r):
        return Correction(x, False, 0, None, row, history, "residual is not finite at the predicted point")
    diverged = DIVERGENCE_FACTOR * max(r, 1.0)
    # The right-hand side -[F(x); row . (x - x_pred)] is written negated into one buffer (the
    # negation is exact: bitwise what solving with -rhs gave), x - x_pred into another.
    rhs = np.empty(x.size)
    rhs_u = rhs[:-1]
    offset = np.empty(x.size)
    # The dense bordered matrix of each iteration is assembled into one buffer and factorized in
    # place: only the last iteration's factorization is returned, so the previous one is dead
    # when the next is built (a fresh (n+1)^2 array per iteration costs page faults: ~1 ms of a
    # 13 ms iteration at n = 605).  Not shared between calls: the caller keeps the last one.
    buffer: Array | None = None
    for it in range(1, options.max_iterations + 1):
        jac, fp = jacobian(x, scratch=True)  # J is used in this iteration only
        fact = factorize_bordered(jac, fp, row, buffer)
        if fact is None:
            return Correction(x, False, it, None, row, history, f"singular bordered Jacobian at iteration {it}")
        if buffer is None and type(fact) is DenseLU:
            buffer = fact.lu
        np.negative(f, out=rhs_u)
        rhs[-1] = -row.dot(np.subtract(x, x_pred, out=offset))  # ndarray.dot: ddot as @, ~1 us less
        dx = fact.solve(rhs)
        if project is not None:
            dx[:-1] = project(dx[:-1])
        # The full step first, without backtrack's call: it is almost always admissible.
        x_new, lam = x + dx, 1.0
        if admissible(x_new) is not None:
            x_new, lam, reason = backtrack(admissible, x, dx)
            if reason is not None:
                return Correction(x, False, it, fact, row, history, f"Newton iterate inadmissible: {reason}")
        x_old, x = x, x_new
        f = residual(x)
        r = max_norm(f)
        history.append(r)
        if not math.isfinite(r) or r > diverged:
            return Correction(x, False, it, fact, row, history, f"Newton diverged (residual {r:.3g})")
        if converged(options, r, lam, dx, x, jac, x_old):
            return Correction(x, True, it, fact, row, history, "converged")
        if give_up is not None:
            why = give_up(x, lam * dx)
            if why is not None:
                return Correction(x, False, it, fact, row, history, why)
    return Correction(x, False, options.max_iterations, fact, row, history,
                      f"no convergence in {options.max_iterations} iterations (residual {history[-1]:.3g})")
