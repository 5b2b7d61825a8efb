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
    interpolate: Callable[[list[Sample[P]], float], P] | None = None,
) -> Located[P]:
    """Shrink the sign-change bracket [a, b] of g(s) until |s_b - s_a| <= tol.

    ``evaluate(s)`` returns the Sample at s or None if the point could not be computed.
    ``lo``/``hi`` of the result are the final bracket ends ordered by s.

    ``interpolate(samples, s)`` (optional) builds a point at s from computed samples.  When no
    trial inside the bracket can be computed (next to a branch point the corrector's update
    stays at the rounding floor times the bordered matrix's condition ~ 1/distance, so Newton
    cannot meet its step tolerance in a band around the zero: 1-D Swift-Hohenberg's secondary
    branches, ~1e-5 wide), the zero is the inverse interpolation s(g = 0) through the computed
    samples nearest the bracket: quadratic through 3, checked against cubic through 4, and
    accepted (converged) when the two agree within max(tol, SINGULAR_FLOOR sqrt(tol)), the
    floor a bracket that cannot be split is accepted at (:func:`_interpolated_zero`).
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
    samples = [a, b]
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
            if not converged and interpolate is not None:
                zero = _interpolated_zero(samples, lo_s, hi_s, tol)
                if zero is not None:
                    point = interpolate(samples, zero)
                    lo, hi = (old, new) if old.s <= new.s else (new, old)
                    return Located(Sample(zero, 0.0, point), lo, hi, it, True)
            break
        samples.append(trial)
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


def nearest_samples(samples: list[Sample[Any]], s: float, k: int) -> list[Sample[Any]]:
    """The k samples nearest s (distinct s)."""
    uniq = {x.s: x for x in samples}
    return sorted(uniq.values(), key=lambda x: abs(x.s - s))[:k]


def _interpolated_zero(samples: list[Sample[Any]], lo_s: float, hi_s: float, tol: float) -> float | None:
    """s(g = 0) by inverse polynomial interpolation through the samples nearest the bracket
    [lo_s, hi_s]: the quadratic estimate (3 samples) if the cubic one (4 samples) agrees with
    it within max(tol, SINGULAR_FLOOR sqrt(tol)) and it lies in the bracket, else None."""
    mid = 0.5 * (lo_s + hi_s)
    near = nearest_samples(samples, mid, 4)
    if len(near) < 4 or len({x.g for x in near}) < 4:
        return None
    import numpy as np

    def estimate(pts: list[Sample[Any]]) -> float:
        g = np.array([x.g for x in pts])
        sv = np.array([x.s for x in pts])
        scale = float(np.max(np.abs(g)))  # Lagrange form of s(g) at g = 0
        gn = g / scale
        total = 0.0
        for i in range(len(pts)):
            w = 1.0
            for j in range(len(pts)):
                if j != i:
                    w *= (0.0 - gn[j]) / (gn[i] - gn[j])
            total += w * sv[i]
        return float(total)

    s2, s3 = estimate(near[:3]), estimate(near)
    # the same floor as a bracket that cannot be split (SINGULAR_FLOOR * sqrt(tol))
    if abs(s2 - s3) <= max(tol, SINGULAR_FLOOR * max(tol, 1e-300) ** 0.5) and lo_s <= s2 <= hi_s:
        return s2
    return None


def lagrange_state(samples: list[Sample[Any]], s: float, state: Callable[[Any], Any], k: int = 4) -> Any:
    """Interpolated state at s through the k samples nearest s (Lagrange in s)."""
    near = nearest_samples(samples, s, k)
    out = 0.0
    for i, a in enumerate(near):
        w = 1.0
        for j, b in enumerate(near):
            if j != i:
                w *= (s - b.s) / (a.s - b.s)
        out = out + w * state(a.point)
    return out


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
