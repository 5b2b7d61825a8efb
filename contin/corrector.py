"""Bordered Newton corrector of pseudo-arclength continuation (Keller 1977).

Solves, for x = (u, p) near a predicted point x_pred,

    F(u, p) = 0,       c . (x - x_pred) = 0,

with c the theta-weighted predictor direction (``ExtendedSystem.row``).  A Newton iteration
builds and factorizes the bordered matrix [[J, F_p], [c^T]] once (``contin.linalg``: dense
LAPACK for small n, SuperLU above); once the update is below CHORD_START (relative), the next
iterations are chord iterations that reuse that LU while they contract (Deuflhard, *Newton
Methods for Nonlinear Problems*, 2004, sec. 2.1.4: the simplified Newton method).  The last
factorization is returned so the caller reuses it for the tangent and the test functions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from contin.extended import ExtendedSystem
from contin.linalg import Factorization, factorize_bordered_norm
from contin.newton import _EPS, DIVERGENCE_FACTOR, backtrack, max_norm
from contin.options import NewtonOptions
from contin.problem import Array


#: Relative Newton update below which the next iterations reuse the factorization (chord).
CHORD_START = 1e-3
#: A chord update must be at most this fraction of the previous update to keep the chord going.
CHORD_CONTRACTION = 0.1


@dataclass
class Correction:
    """Result of :func:`correct`: the point, its last factorization and the residual history.

    iterations : number of Jacobian factorizations (Newton iterations; chord iterations, which
        reuse one, are not counted); the residual history has one entry per iteration of either kind.
    """

    x: Array
    converged: bool
    iterations: int
    factorization: Factorization | None
    row: Array
    residual_history: list[float] = field(default_factory=list)
    message: str = ""


def correct(system: ExtendedSystem, x_pred: Array, row: Array, options: NewtonOptions,
            project: Callable[[Array], Array] | None = None, *, chord: bool = True) -> Correction:
    """Bordered Newton from ``x_pred`` on [F(x); row . (x - x_pred)] = 0 (see :func:`_correct`)."""
    with np.errstate(all="ignore"):
        return _correct(system, x_pred, row, options, project, chord)


def _correct(system: ExtendedSystem, x_pred: Array, row: Array, options: NewtonOptions,
             project: Callable[[Array], Array] | None = None, allow_chord: bool = True) -> Correction:
    """Bordered Newton from ``x_pred`` on [F(x); row . (x - x_pred)] = 0.

    With ``allow_chord`` the returned factorization may be that of an iterate up to
    CHORD_START (relative) away from the solution: accurate enough for the next tangent and
    the signs of the test functions along a branch.  Locating a special point needs the test
    functions to rounding accuracy at the trial points: pass ``allow_chord=False`` (plain
    Newton; its last factorization is within the final update of the solution).

    At least one iteration is always done so that a factorization at the solution exists (an
    exact predictor, e.g. on a trivial branch, would otherwise leave none).  Never raises.

    ``project`` (optional) maps the u-part of each Newton update into an invariant subspace
    containing the solution, e.g. the symmetrizer (u + S u)/2 on an S-invariant branch.  In
    exact arithmetic the update already lies there; projecting removes the rounding noise
    that a nearly singular mode outside the subspace (a symmetry-breaking BP nearby, where
    the bordered matrix is singular) would otherwise amplify into the iterate.
    """
    x = np.array(x_pred, dtype=float)
    f = system.residual(x)
    history = [max_norm(f)]
    fact: Factorization | None = None
    if not math.isfinite(history[0]):
        return Correction(x, False, 0, None, row, history, "residual is not finite at the predicted point")
    chord = False
    previous = math.inf
    lus = 0  # factorizations: the iteration count reported (step-size control reads it)
    tol = options.tol
    rhs = np.empty(x.size)
    for it in range(1, options.max_iterations + 1):
        if not chord:
            jac, fp = system.jacobian(x)
            fact, jnorm = factorize_bordered_norm(jac, fp, row)
            lus += 1
            tol = max(options.tol, _EPS * jnorm * max(1.0, max_norm(x)))
            if fact is None:
                return Correction(x, False, lus, None, row, history, f"singular bordered Jacobian at iteration {it}")
        assert fact is not None
        rhs[:-1] = f
        rhs[-1] = row @ (x - x_pred)
        dx = fact.solve(-rhs)
        if project is not None:
            dx[:-1] = project(dx[:-1])
        x_new, lam, reason = backtrack(system.admissible, x, dx)
        if reason is not None:
            return Correction(x, False, lus, fact, row, history, f"Newton iterate inadmissible: {reason}")
        x = x_new
        f = system.residual(x)
        r = max_norm(f)
        history.append(r)
        if not math.isfinite(r) or r > DIVERGENCE_FACTOR * max(history[0], 1.0):
            return Correction(x, False, lus, fact, row, history, f"Newton diverged (residual {r:.3g})")
        step = lam * max_norm(dx)
        scale = max(1.0, max_norm(x))
        if r <= tol and step <= options.step_tol * scale:
            if chord:
                x, f = _polish(system, fact, x, f, x_pred, row, project, history)
            return Correction(x, True, lus, fact, row, history, "converged")
        # Chord iterations: once the update is small the Jacobian barely changes, so the next
        # iteration reuses this LU (residual + back-substitution only), for as long as each
        # chord update contracts by CHORD_CONTRACTION; otherwise a fresh Jacobian is built.
        if chord:
            chord = step <= CHORD_CONTRACTION * previous
        else:
            chord = allow_chord and lam == 1.0 and step <= CHORD_START * scale
        previous = step
    return Correction(x, False, lus, fact, row, history,
                      f"no convergence in {options.max_iterations} iterations (residual {history[-1]:.3g})")


def _polish(system: ExtendedSystem, fact: Factorization, x: Array, f: Array, x_pred: Array, row: Array,
            project: Callable[[Array], Array] | None, history: list[float]) -> tuple[Array, Array]:
    """One more chord update after a chord iteration met the tolerances.

    Newton's last update leaves an error ~ (previous error)^2, far below the tolerances; a
    chord iteration only reduces it by its contraction factor (< CHORD_CONTRACTION), which
    would leave converged states at the tolerance.  One more back-substitution restores the
    accuracy plain Newton delivers; it is kept only if admissible and not worse.
    """
    rhs = np.empty(x.size)
    rhs[:-1] = f
    rhs[-1] = row @ (x - x_pred)
    dx = fact.solve(-rhs)
    if project is not None:
        dx[:-1] = project(dx[:-1])
    x_new = x + dx
    if system.admissible(x_new) is not None:
        return x, f
    f_new = system.residual(x_new)
    r = max_norm(f_new)
    if not r <= history[-1]:
        return x, f
    history.append(r)
    return x_new, f_new
