"""Locating a zero of a test function between two branch points (Anderson-Bjorck regula falsi).

The branch between x_a and x_b is parametrised by the projected arclength
s = <t_a, x - x_a>_theta; each trial s is re-corrected onto the branch by the caller's
``evaluate(s)``.  The Anderson-Bjorck variant of regula falsi (BIT 13, 1973; it replaced the
Illinois variant, Dowell & Jarratt 1971, which needed ~30 trials per point on gPCF) keeps a
bracket and converges superlinearly for smooth test functions; a trial that fails to correct
falls back to the midpoint (then to 0.3 / 0.7 of the bracket).  Converged when the bracket in s is below ``tol`` (or g = 0 exactly).
The locator is generic in what a "point" is, so a fold-curve system can reuse it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

P = TypeVar("P")


@dataclass
class Sample(Generic[P]):
    s: float
    g: float
    point: P


@dataclass
class Located(Generic[P]):
    """Best point found, the final bracket in s, the iteration count and whether it converged."""

    best: Sample[P]
    lo: Sample[P]
    hi: Sample[P]
    iterations: int
    converged: bool


#: A bracket narrower than SINGULAR_FLOOR * sqrt(tol) that cannot be split further because
#: the corrector fails next to the singular point counts as located (near a simple BP the
#: bordered matrix has condition number ~ 1/distance, so Newton stalls at distances of
#: order sqrt(eps)).
SINGULAR_FLOOR = 1e-3


def locate_zero(
    evaluate: Callable[[float], Sample[Any] | None],
    a: Sample[P],
    b: Sample[P],
    *,
    tol: float,
    max_iterations: int,
) -> Located[P]:
    """Shrink the sign-change bracket [a, b] of g(s) until |s_b - s_a| <= tol.

    ``evaluate(s)`` returns the Sample at s or None if the point could not be computed.
    ``lo``/``hi`` of the result are the final bracket ends ordered by s.
    """
    if a.g * b.g > 0:
        raise ValueError("locate_zero needs a sign change of the test function")
    # Anderson-Bjorck regula falsi (Anderson & Bjorck, BIT 13, 1973): ``new`` is the most
    # recent end of the bracket, ``old`` the retained one.  When the retained end survives a
    # step its effective value is scaled by m = 1 - g_trial / g_new (0.5 if that is <= 0),
    # which undoes the one-sided creeping of plain regula falsi on a strongly curved g (here
    # a determinant ratio that varies by orders of magnitude across the step).  A bracket
    # that has not halved in two steps is bisected, so the worst case is about twice
    # bisection's count and noise in g near the zero cannot stall the locator.
    old, new = a, b
    gold, gnew = old.g, new.g
    it = 0
    converged = a.g == 0 or b.g == 0
    widths = [abs(b.s - a.s)]
    while not converged and it < max_iterations:
        it += 1
        lo_s, hi_s = min(old.s, new.s), max(old.s, new.s)
        width = hi_s - lo_s
        mid = 0.5 * (lo_s + hi_s)
        s = new.s - gnew * (new.s - old.s) / (gnew - gold) if gnew != gold else mid
        if len(widths) > 2 and widths[-1] > 0.5 * widths[-3]:
            s = mid
        # An estimate next to an end is kept but moved tol/2 inside: the trial then either
        # lands on the far side of the zero (bracket ~ tol/2, done) or shrinks the bracket.
        margin = min(1e-3 * width, 0.5 * tol)
        if not lo_s < s < hi_s:
            s = mid
        s = min(max(s, lo_s + margin), hi_s - margin)
        trial = None
        for cand in dict.fromkeys((s, mid, lo_s + 0.3 * width, lo_s + 0.7 * width)):
            trial = evaluate(cand)
            if trial is not None:
                break
        if trial is None:
            # The corrector cannot converge this close to a singular point: the bracket is
            # as narrow as the problem's conditioning allows.
            converged = width <= SINGULAR_FLOOR * max(tol, 1e-300) ** 0.5
            break
        if trial.g == 0:
            old = new = trial
            converged = True
            break
        if (trial.g > 0) == (new.g > 0):
            m = 1.0 - trial.g / new.g
            gold *= m if m > 0 else 0.5
        else:
            old, gold = new, new.g
        new, gnew = trial, trial.g
        widths.append(abs(new.s - old.s))
        converged = widths[-1] <= tol
    lo, hi = (old, new) if old.s <= new.s else (new, old)
    best = lo if abs(lo.g) <= abs(hi.g) else hi
    return Located(best, lo, hi, it, converged)


def outside_bracket(p: float, pa: float, pb: float, tol: float, bounds: tuple[float, float] | None = None) -> str | None:
    """Why a located parameter value p is no valid location of a branch point between branch
    points with values pa and pb (None if it is one): it lies outside [min, max] of the two (by
    more than tol) or outside the run's bounds.

    A BP between two regular points of a branch that does not fold inside the step lies
    between their parameter values; a "located" point elsewhere came from a trial that the
    corrector carried onto another branch.  (Folds are exempt: their parameter is an extremum
    and lies beyond both ends of its step by construction.)
    """
    lo, hi = min(pa, pb), max(pa, pb)
    if not lo - tol <= p <= hi + tol:
        return f"the located value {p:.10g} lies outside its bracket [{lo:.10g}, {hi:.10g}]"
    if bounds is not None and not bounds[0] - tol <= p <= bounds[1] + tol:
        return f"the located value {p:.10g} lies outside the bounds [{bounds[0]:g}, {bounds[1]:g}]"
    return None
