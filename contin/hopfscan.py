"""Hopf points of a stored branch from its stability problem A(k) x = omega B(k) x.

The tracer locates Hopf points of J x = omega M x while it runs (``contin.hopf``).  Problems
whose stability is a family of eigenproblems in wavenumbers (``eigenproblem(u, p, kx, kz)``,
e.g. perturbations travelling along a channel) have a Hopf point at a given k wherever a
complex pair of that family crosses Re omega = 0 along the branch.  :func:`locate_hopf` finds
them after the fact, on a stored branch:

1. between neighbouring stored points i, i+1 whose unstable counts differ (or everywhere when
   no counts are given), the eigenvalues with Im omega > 0 at both ends are paired by mutual
   nearest neighbours (as in ``contin.hopf``); a pair whose real part changes sign brackets a
   Hopf point;
2. the zero of psi(p) = Re omega(p) -- omega(p) the eigenvalue nearest the segment
   [omega_i, omega_{i+1}] -- is found by the Illinois variant of regula falsi in the
   continuation parameter p, each trial state being the steady state at p re-solved by Newton
   from the linear interpolation of the stored states (``contin.newton``); the located p is
   exact to ``tol`` (relative), not an interpolation of eigenvalues;
3. the result is an ``HB`` special point with ``data = {omega, kx, kz}`` (omega = Im of the
   critical eigenvalue: the travelling mode's frequency; its phase speed is omega / kx), or,
   where a count changes without a complex crossing being located, a one-line reason;
4. count changes (or crossings) at most :data:`CHATTER_POINTS` stored points apart mean that
   the sign of Re omega flips faster than the branch's points resolve: the eigenvalue is at the
   noise level of the states (e.g. gPCF's travelling mode on plugs within 1e-9 of packing, where
   it flips sign at every point) or the steps are too long.  Such HBs are kept but their note says
   "doubtful", and a reason line names the stretch (:func:`doubtful_crossings`).

Requires a branch in one parameter whose stored points bracket the crossing without a fold in
between (Newton at fixed p would be ambiguous there: such intervals are reported, not guessed).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.options import NewtonOptions
from contin.problem import Array, has

#: Default relative tolerance of the located parameter.
DEFAULT_TOL = 1e-11

#: Crossings of Re omega = 0 at most this many stored points apart are not resolved by the
#: branch's points (:func:`doubtful_crossings`).
CHATTER_POINTS = 2


@dataclass
class HopfScan:
    """Result of :func:`locate_hopf`: the located HB points and the reasons for the rest."""

    points: list[SpecialPoint] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)


def _complex_upper(problem: Any, u: Array, params: Mapping[str, float], kx: float, kz: float,
                   dense_max: int, k: int) -> Array:
    from contin.hopf import complex_eigenvalues
    from contin.stability import operator_pair

    a, b = operator_pair(problem, u, params, kx=kx, kz=kz)
    return complex_eigenvalues(a, b, dense_max, k)


def locate_hopf(
    problem: Any,
    branch: Branch,
    params_fixed: Mapping[str, float] | None = None,
    *,
    kx: float = 0.0,
    kz: float = 0.0,
    counts: Array | None = None,
    tol: float = DEFAULT_TOL,
    newton: NewtonOptions = NewtonOptions(),
    dense_max: int = 600,
    k: int = 12,
    max_iterations: int = 80,
) -> HopfScan:
    """Hopf points of ``branch`` for the stability problem at (kx, kz) (module docstring).

    ``counts``: unstable counts per point (e.g. ``branch.n_unstable`` at kx = kz = 0, or the
    ``n_unstable_kx<k>`` observable); only intervals where they change (both ends known) are
    searched.  None searches every interval (one eigen-solve per stored point).
    """
    from contin.adapt import point_problem
    from contin.hopf import distance_to_segment, crossing_pairs
    from contin.newton import newton as solve

    out = HopfScan()
    par = branch.parameter
    pv = np.asarray(branch.params[par], dtype=float)
    s = len(branch)
    base = {kk: float(v) for kk, v in dict(params_fixed or {}).items()
            if isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool)}

    def params_at(i: int) -> dict[str, float]:
        return {**base, **{name: float(values[i]) for name, values in branch.params.items()}}

    def state(i: int) -> Array | None:
        try:
            return np.asarray(branch.state(i), dtype=float)
        except KeyError:
            return None

    if counts is not None:
        c = np.asarray(counts, dtype=float)
        intervals = [i for i in range(s - 1) if c[i] >= 0 and c[i + 1] >= 0 and np.isfinite(c[i])
                     and np.isfinite(c[i + 1]) and c[i] != c[i + 1]]
    else:
        intervals = list(range(s - 1))
    cache: dict[int, Array] = {}

    def eig(i: int) -> Array | None:
        if i not in cache:
            u = state(i)
            if u is None:
                return None
            cache[i] = _complex_upper(point_problem(problem, branch, i), u, params_at(i), kx, kz, dense_max, k)
        return cache[i]

    where = f" at kx={kx:g}" + (f", kz={kz:g}" if kz else "")
    for i in intervals:
        head = f"{par} = {pv[i]:.6g} .. {pv[i + 1]:.6g}{where}"
        ua, ub = state(i), state(i + 1)
        wa, wb = eig(i), eig(i + 1)
        if ua is None or ub is None or wa is None or wb is None:
            out.reasons.append(f"{head}: a state was not saved (save_every > 1); Hopf point not located")
            continue
        crossings = crossing_pairs(wa, wb)
        if not crossings:
            if counts is not None:
                out.reasons.append(f"{head}: the unstable count changes but no complex pair crosses Re omega = 0 "
                                   "(a real eigenvalue: an LP/BP of this stability problem)")
            continue
        if len(branch.free) != 1:
            out.reasons.append(f"{head}: complex pair crossing on a {len(branch.free)}-parameter curve; not located")
            continue
        # Points of an adaptive run lie on their own grids (contin.adapt.point_problem): the
        # location runs on point i's grid, with point i+1 carried onto it.
        here, there = point_problem(problem, branch, i), point_problem(problem, branch, i + 1)
        if there is not here:
            ub = there.transfer(ub, here)
        for mu_a, mu_b in crossings:
            sp, reason = _locate_one(here, branch, i, params_at, ua, ub, complex(mu_a), complex(mu_b), kx, kz,
                                     dense_max, k, tol, newton, max_iterations, solve, distance_to_segment)
            if sp is not None:
                sp = replace(sp, grid=branch.grid_at(i))
                out.points.append(sp)
            if reason is not None:
                out.reasons.append(f"{head}: {reason}")
    changed = intervals if counts is not None else sorted({sp.index for sp in out.points})
    for lo, hi in doubtful_crossings(changed):
        stretch = f"{par} = {pv[lo]:.6g} .. {pv[hi + 1]:.6g}{where}"
        why = (f"doubtful: Re omega changes sign at most {CHATTER_POINTS} stored points apart in {stretch}, faster "
               "than the branch's points resolve (eigenvalue at the noise level of the states, or steps too long)")
        out.points = [replace(sp, note=f"{sp.note}; {why}") if lo <= sp.index <= hi else sp for sp in out.points]
        out.reasons.append(f"{stretch}: {why}")
    return out


def doubtful_crossings(intervals: list[int], gap: int = CHATTER_POINTS) -> list[tuple[int, int]]:
    """Stretches (first, last interval) of sign changes at most ``gap`` stored points apart
    (interval i lies between points i and i+1); an isolated change is not in any."""
    out: list[tuple[int, int]] = []
    run: list[int] = []
    for i in sorted(intervals):
        if run and i - run[-1] > gap:
            if len(run) > 1:
                out.append((run[0], run[-1]))
            run = []
        run.append(i)
    if len(run) > 1:
        out.append((run[0], run[-1]))
    return out


def _locate_one(problem: Any, branch: Branch, i: int, params_at: Any, ua: Array, ub: Array, mu_a: complex,
                mu_b: complex, kx: float, kz: float, dense_max: int, k: int, tol: float, newton_opts: NewtonOptions,
                max_iterations: int, solve: Any, to_segment: Any) -> tuple[SpecialPoint | None, str | None]:
    """Illinois regula falsi on Re omega(p) between stored points i and i+1."""
    par = branch.parameter
    pa, pb = float(branch.params[par][i]), float(branch.params[par][i + 1])
    if not pa != pb:
        return None, "the bracketing points have the same parameter value"

    def evaluate(p: float) -> tuple[float, complex, Array] | None:
        w = (p - pa) / (pb - pa)
        q = params_at(i)
        q[par] = p
        res = solve(problem, (1 - w) * ua + w * ub, q, newton_opts)
        if not res.converged:
            return None
        # the re-solved state must lie on this piece of the branch, not on another branch
        span = float(np.max(np.abs(ub - ua))) + 1e-300
        if float(np.max(np.abs(res.u - ((1 - w) * ua + w * ub)))) > span + 1e-8 * max(1.0, float(np.max(np.abs(ua)))):
            return None
        v = _complex_upper(problem, res.u, q, kx, kz, dense_max, k)
        if v.size == 0:
            return None
        mu = complex(v[int(np.argmin(to_segment(v, mu_a, mu_b)))])
        return mu.real, mu, res.u

    ga, gb = mu_a.real, mu_b.real
    xa, xb = pa, pb
    best: tuple[float, complex, Array, float] | None = None
    side = 0
    width_tol = tol * max(1.0, abs(pa), abs(pb))
    converged = False
    for _ in range(max_iterations):
        x = xb - gb * (xb - xa) / (gb - ga) if gb != ga else 0.5 * (xa + xb)
        lo, hi = min(xa, xb), max(xa, xb)
        if not lo < x < hi:
            x = 0.5 * (xa + xb)
        trial = evaluate(x)
        if trial is None:
            trial = evaluate(0.5 * (xa + xb))
            x = 0.5 * (xa + xb)
            if trial is None:
                return None, f"Newton at fixed {par} failed near {x:.10g}; Hopf point not located"
        g, mu, u = trial
        if best is None or abs(g) < abs(best[0]):
            best = (g, mu, u, x)
        if g == 0:
            converged = True
            break
        if (g > 0) == (gb > 0):  # replaces b: keep a, halve its value if b was kept twice (Illinois)
            xb, gb = x, g
            if side == -1:
                ga *= 0.5
            side = -1
        else:
            xa, ga = xb, gb
            xb, gb = x, g
            side = +1
        if abs(xb - xa) <= width_tol:
            converged = True
            break
    assert best is not None
    g, mu, u, p = best
    q = params_at(i)
    q[par] = p
    order = float(problem.order_parameter(u, q)) if has(problem, "order_parameter") else math.nan
    note = f"complex pair crossing at kx={kx:g}" + (f", kz={kz:g}" if kz else "")
    if not converged:
        note += "; location did not converge"
    sp = SpecialPoint(type="HB", index=i, params=q, order_parameter=order, state=u.copy(), bracket=(pa, pb),
                      converged=converged, note=note,
                      data={"omega": mu.imag, "kx": float(kx), "kz": float(kz)})
    return sp, None


def number_new_points(branches: list[Branch]) -> None:
    """Give special points without a label (label 0, e.g. HBs added by :func:`locate_hopf`
    after the run was numbered) the next free labels, in branch order; others keep theirs."""
    from dataclasses import replace

    top = max((sp.label for b in branches for sp in b.special_points), default=0)
    for b in branches:
        new = []
        for sp in sorted(b.special_points, key=lambda s: s.index):
            if sp.label == 0:
                top += 1
                sp = replace(sp, label=top)
            new.append(sp)
        b.special_points = new
