"""Locating a zero of a test function between two branch points (Illinois regula falsi).

The branch between x_a and x_b is parametrised by the projected arclength
s = <t_a, x - x_a>_theta; each trial s is re-corrected onto the branch by the caller's
``evaluate(s)``.  The Illinois variant of regula falsi (Dowell & Jarratt, BIT 11, 1971) keeps a
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
    """
    if a.g * b.g > 0:
        raise ValueError("locate_zero needs a sign change of the test function")
    lo, hi = a, b
    glo, ghi = lo.g, hi.g  # effective values, halved Illinois-style
    last = ""
    it = 0
    converged = lo.g == 0 or hi.g == 0
    while not converged and it < max_iterations:
        it += 1
        mid = 0.5 * (lo.s + hi.s)
        s = hi.s - ghi * (hi.s - lo.s) / (ghi - glo) if ghi != glo else mid
        margin = 1e-3 * abs(hi.s - lo.s)
        if not (min(lo.s, hi.s) + margin < s < max(lo.s, hi.s) - margin):
            s = mid
        trial = None
        width = hi.s - lo.s
        for cand in dict.fromkeys((s, mid, lo.s + 0.3 * width, lo.s + 0.7 * width)):
            trial = evaluate(cand)
            if trial is not None:
                break
        if trial is None:
            # The corrector cannot converge this close to a singular point: the bracket is
            # as narrow as the problem's conditioning allows.
            converged = abs(hi.s - lo.s) <= SINGULAR_FLOOR * max(tol, 1e-300) ** 0.5
            break
        if trial.g == 0:
            lo = hi = trial
            converged = True
            break
        if (trial.g > 0) == (lo.g > 0):
            lo, glo = trial, trial.g
            if last == "lo":
                ghi *= 0.5
            last = "lo"
        else:
            hi, ghi = trial, trial.g
            if last == "hi":
                glo *= 0.5
            last = "hi"
        converged = abs(hi.s - lo.s) <= tol
    best = lo if abs(lo.g) <= abs(hi.g) else hi
    return Located(best, lo, hi, it, converged)
