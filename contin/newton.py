"""Newton's method for F(u, p) = 0 at fixed parameters, with admissibility backtracking.

u_{k+1} = u_k + lambda_k du_k,  J(u_k) du_k = -F(u_k),  lambda_k = 2^{-j} the largest step
keeping u_{k+1} admissible (``problem.admissible``).  Converged when max|F| <= tol and
max|du| <= step_tol * max(1, max|u|).  Never raises on non-convergence.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from contin.linalg import dense_factorization, factorize, inf_norm
from contin.options import NewtonOptions
from contin.problem import Array, has, require_protocol

#: Halvings of an update that lands outside the problem's domain before Newton gives up.
MAX_BACKTRACKS = 12
#: Growth of the residual (relative to the first one) treated as divergence.
DIVERGENCE_FACTOR = 1e10
_EPS = float(np.finfo(float).eps)


@dataclass
class NewtonResult:
    """Outcome of :func:`newton` (also used by the continuation corrector).

    residual_history : max-norm residuals, the initial one first.
    iterations : number of Jacobian factorizations performed.
    """

    u: Array
    converged: bool
    iterations: int
    residual_history: list[float] = field(default_factory=list)
    message: str = ""


def max_norm(a: Array) -> float:
    """max |a_i| (0 for an empty array); NaN propagates.

    Through argmax, a C method: a ufunc reduction (np.maximum.reduce, let alone ndarray.max
    with its Python wrapper) costs ~2.5 us of set-up on a continuation-sized vector, argmax
    ~0.5 us, and the Newton loops take two or three of these norms per iteration.  The same
    value (a maximum is exact); argmax returns the first NaN where there is one.
    """
    if not a.size:
        return 0.0
    b = np.abs(a)
    return float(b[b.argmax()])


def rounding_floor(jac: Any, x: Array) -> float:
    """eps * ||J||_inf * max(1, ||x||_inf): the residual that rounding alone leaves.

    Discretized second derivatives have entries ~ N^2 (FD) or N^4 (Chebyshev), so an absolute
    residual tolerance can fall below what double precision can reach on fine grids; Newton
    then accepts this floor instead (together with a converged update).
    """
    return _EPS * inf_norm(jac) * max(1.0, max_norm(x))


def converged(options: NewtonOptions, r: float, lam: float, dx: Array, x: Array, jac: Any, x_jac: Array) -> bool:
    """The convergence test of :func:`newton` and :func:`contin.corrector.correct`: the taken
    update lam * dx is below options.step_tol * max(1, ||x||_inf) and the residual r at x below
    max(options.tol, :func:`rounding_floor` at the iterate ``x_jac`` J was taken at).  The floor
    (a norm of J) is evaluated only when the update is small and r is above options.tol."""
    step, step_tol = lam * max_norm(dx), options.step_tol
    # max(1, ||x||) >= 1 and rounding is monotone, so step <= step_tol already decides the step
    # test without the norm of x (the same outcome bit for bit; a NaN step fails both).
    if not step <= step_tol and not step <= step_tol * max(1.0, max_norm(x)):
        return False
    return r <= options.tol or r <= rounding_floor(jac, x_jac)


def backtrack(admissible: Any, x: Array, dx: Array) -> tuple[Array, float, str | None]:
    """x + lam dx with lam = 1, 1/2, 1/4, ... until admissible; returns (x_new, lam, reason)."""
    lam = 1.0
    reason = None
    for _ in range(MAX_BACKTRACKS):
        x_new = x + dx if lam == 1.0 else x + lam * dx  # 1.0 * dx == dx exactly
        reason = admissible(x_new)
        if reason is None:
            return x_new, lam, None
        lam *= 0.5
    return x, 0.0, reason


def newton(problem: Any, u0: Array, params: Mapping[str, float], options: NewtonOptions = NewtonOptions()) -> NewtonResult:
    """Solve F(u, params) = 0 from u0 by Newton's method (LU by ``contin.linalg.factorize``).

    Returns a :class:`NewtonResult`; non-convergence (singular Jacobian, divergence, too many
    iterations, inadmissible iterates) is reported in ``message``, never raised.  Floating-point
    warnings of diverging iterates are silenced: divergence is detected and reported instead.
    """
    with np.errstate(all="ignore"):
        try:
            return _newton(problem, u0, params, options)
        except ArithmeticError as exc:  # Python-float arithmetic of a problem (W**2 at W = 1e300)
            return NewtonResult(np.array(u0, dtype=float).ravel(), False, 0, [], arithmetic_failure(exc, "the initial guess"))


def arithmetic_failure(exc: ArithmeticError, where: str) -> str:
    """The failure message of a solve whose residual or Jacobian raised ``exc``.

    numpy arrays give inf/nan (caught as a non-finite residual), but a problem computing with
    Python floats raises OverflowError (``W**2`` at W = 1e300, reached by a step ``--ds 1e300``)
    or ZeroDivisionError.  That is a failed solve, as a non-finite residual is: the step is
    rejected and retried shorter, and a start point reports it in one line.
    """
    return (f"the residual or Jacobian raised {type(exc).__name__} ({exc}) near {where}: "
            "values out of the problem's range")


def _newton(problem: Any, u0: Array, params: Mapping[str, float], options: NewtonOptions) -> NewtonResult:
    require_protocol(problem)
    u = np.array(u0, dtype=float).ravel()
    p = dict(params)

    def admissible(v: Array) -> str | None:
        return problem.admissible(v, p) if has(problem, "admissible") else None  # type: ignore[no-any-return]

    reason = admissible(u)
    if reason is not None:
        return NewtonResult(u, False, 0, [], f"initial guess is inadmissible: {reason}")
    f = np.asarray(problem.residual(u, p), dtype=float)
    r = max_norm(f)
    history = [r]
    if not math.isfinite(r):
        return NewtonResult(u, False, 0, history, "residual is not finite at the initial guess")
    if r <= options.tol:
        return NewtonResult(u, True, 0, history, "converged")
    # Where J is factorized densely anyway, take it densely if the problem can (contin.problem).
    dense: bool | None = False if not has(problem, "dense_jacobian") else None
    for it in range(1, options.max_iterations + 1):
        if dense is None:
            jac = problem.jacobian(u, p)
            dense = dense_factorization(jac)
        jac = problem.dense_jacobian(u, p) if dense else problem.jacobian(u, p)
        fact = factorize(jac)  # a copy: jac stays intact for the rounding floor below
        if fact is None:
            return NewtonResult(u, False, it, history, f"singular Jacobian at iteration {it}")
        du = fact.solve(-f)
        u_new, lam, reason = backtrack(admissible, u, du)
        if reason is not None:
            return NewtonResult(u, False, it, history, f"Newton iterate inadmissible: {reason}")
        u_old, u = u, u_new
        f = np.asarray(problem.residual(u, p), dtype=float)
        r = max_norm(f)
        history.append(r)
        if not math.isfinite(r) or r > DIVERGENCE_FACTOR * max(history[0], 1.0):
            return NewtonResult(u, False, it, history, f"Newton diverged (residual {r:.3g})")
        if converged(options, r, lam, du, u, jac, u_old):
            return NewtonResult(u, True, it, history, "converged")
    return NewtonResult(u, False, options.max_iterations, history,
                        f"no convergence in {options.max_iterations} iterations (residual {history[-1]:.3g})")
