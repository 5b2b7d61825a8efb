"""Seeds of a bifurcation diagram that branch switching cannot reach, and tracing from them.

Branches not connected to the start branch (isolas, fold-bounded sheets of an imperfect
bifurcation) are found from *seeds*: states known to solve F(u, p) = 0 at the diagram's
parameters, each traced and kept when it lies on no branch found before.

- :func:`homotopy` -- a state continued in a second parameter from its value to a target
  (e.g. from a problem with a symmetry, where branch switching reaches everything, to the
  imperfect one: Golubitsky & Schaeffer's unfolding, followed numerically);
- :func:`homotopy_seeds` -- states of given branches at given parameter values, continued so;
- :func:`fold_seeds` -- points where two-parameter fold curves cross the target value of the
  second parameter: each is a fold of the one-parameter diagram there, hence on a branch
  (this finds isolas, which are bounded by folds: an isola is born at an extremum of the second
  parameter along a fold curve; Seydel, Practical Bifurcation and Stability Analysis, 2010,
  sec. 2.10);
- :func:`off_fold` -- a point a few steps away from such a fold along its branch;
- :func:`discover` -- every seed traced once: a seed on a known branch is only recorded
  (which routes found which branch), branches are trimmed to their new part and de-duplicated.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from contin.branch import Branch
from contin.continuation import newton, trace
from contin.foldcurve import FoldProblem
from contin.options import ContinuationOptions, NewtonOptions
from contin.overlap import Coordinates, deduplicate, near, params_at, trim_to_new
from contin.problem import has

Array = np.ndarray


@dataclass(frozen=True)
class Seed:
    """A state (with all parameters) from which a branch is traced; ``route`` names how it was found."""

    label: str
    state: Array
    params: Mapping[str, float]
    route: str


def homotopy(problem: Any, state: Array, params: Mapping[str, float], name: str, target: float,
             options: ContinuationOptions) -> Array | None:
    """The state continued in ``name`` from params[name] to ``target``; None if it does not arrive.

    ``options.bounds[name]`` must end at ``target`` (the run stops there).  ``symmetric=False``:
    the homotopy usually breaks a symmetry, so a symmetric start is not treated as lying on an
    S-invariant branch.  None when the path turns back (a fold in ``name``: the state does not
    survive that far) or fails.
    """
    start = float(params[name])
    if target == start:
        return np.array(state, dtype=float)
    # dp/ds at the start has the sign of ds * direction: point it at the target
    direction = 1 if (target > start) == (options.step.ds > 0) else -1
    br = trace(problem, state, dict(params), name, options, direction=direction, symmetric=False, branch_id="homotopy")
    reached = br.status == "EP" and br.message.startswith(f"reached bound {name}")
    if not reached or abs(br.params[name][-1] - target) > 1e-12 * max(abs(target), 1e-300):
        return None
    return br.state(-1)


def homotopy_seeds(problem: Any, branches: Sequence[Branch], name: str, target: float, at: Sequence[float],
                   options: ContinuationOptions, route: str = "homotopy") -> list[Seed]:
    """States of ``branches`` at the stored points nearest to each continuation-parameter value
    in ``at`` (inside the branch's range), continued in ``name`` to ``target`` (:func:`homotopy`)."""
    out = []
    for br in branches:
        P = br.params[br.parameter]
        for v in at:
            if not (P.min() < v < P.max()):
                continue
            i = int(np.argmin(np.abs(P - v)))
            p = params_at(br, i)
            x = homotopy(problem, br.state(i), p, name, target, options)
            if x is not None:
                out.append(Seed(f"homotopy from {br.id} at {br.parameter}={p[br.parameter]:.4g}", x,
                                {**p, name: target}, route))
    return out


def resolved(problem: Any, u: Array, p: Mapping[str, float], tol: float | None) -> bool:
    """True unless the problem's ``under_resolved`` hook rejects the state at ``tol`` (None: no check)."""
    return tol is None or not has(problem, "under_resolved") or problem.under_resolved(np.asarray(u), p, tol) is None


def fold_seeds(problem: Any, curves: Sequence[Branch], second: str, value: float, parameter: str,
               window: tuple[float, float], *, resolution_tol: float | None = 3e-5,
               route: str = "fold-curve") -> list[Seed]:
    """Points where fold curves in (parameter, second) cross second = ``value``, polished by Newton
    on the fold system with ``second`` fixed and ``parameter`` free (Newton in the state at a
    fixed parameter next to a fold may have no solution to converge to).  Crossings outside
    ``window`` (open interval of ``parameter``) or not resolved by the grid (:func:`resolved`)
    are skipped; a curve started at a fold of this value meets it twice there (both halves
    start at it): reported once."""
    out: list[Seed] = []
    for c in curves:
        g = c.params[second]
        for i in np.nonzero(np.sign(g[:-1] - value) * np.sign(g[1:] - value) <= 0)[0]:
            j = int(i) if abs(g[i] - value) < abs(g[i + 1] - value) else int(i) + 1
            p = {**params_at(c, j), second: value}
            if not window[0] < p[parameter] < window[1]:
                continue
            st = c.state(j)
            n = (st.size - 1) // 2
            phi = st[n: 2 * n]
            fp = FoldProblem(problem, parameter, phi / float(phi @ phi))
            res = newton(fp, np.concatenate([st[: 2 * n], [p[parameter]]]), p, NewtonOptions(max_iterations=20))
            if res.converged and resolved(problem, res.u[:n], {**p, parameter: float(res.u[2 * n])}, resolution_tol):
                p = {**p, parameter: float(res.u[2 * n])}
                if any(abs(s.params[parameter] - p[parameter]) <= 1e-7 * abs(p[parameter])
                       and s.label.startswith(f"fold curve {c.id} ") for s in out):
                    continue
                out.append(Seed(f"fold curve {c.id} at {parameter}={p[parameter]:.6g}", res.u[:n], p, route))
    return out


def off_fold(problem: Any, seed: Seed, parameter: str, options: ContinuationOptions, steps: int = 4) -> Seed:
    """The seed moved a few continuation steps along its branch.

    A branch traced from exactly a fold does not report that fold (its test function is zero at
    the start, so no sign change is seen), and a closed isola would then show an odd number of
    folds; starting next to the fold, the run passes it and locates it.
    """
    b = trace(problem, seed.state, dict(seed.params), parameter, replace(options, max_steps=steps), symmetric=False,
              branch_id="off-fold")
    if len(b) < 2:
        return seed
    return replace(seed, state=b.state(len(b) - 1), params=params_at(b, len(b) - 1))


@dataclass
class Discovery:
    """Branches traced from seeds.

    branches : de-duplicated branches (ids '0', '1', ... in tracing order)
    routes : branch id -> route of the seed it was traced from
    found_by : branch id -> every route with a seed on that branch (first the tracing one)
    duplicates : (dropped id, kept id) pairs
    notes : every seed with its outcome
    """

    branches: list[Branch]
    routes: dict[str, str] = field(default_factory=dict)
    found_by: dict[str, list[str]] = field(default_factory=dict)
    duplicates: list[tuple[str, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def discover(problem: Any, seeds: Iterable[Seed], trace_seed: Callable[[Seed, str], Branch], coordinates: Coordinates,
             *, prepare: Callable[[Seed], Seed] | None = None, near_tol: float = 2e-3, trim_tol: float = 2e-3,
             dedup_tol: float = 5e-3, columns: int | None = None,
             progress: Callable[[str], None] | None = None) -> Discovery:
    """Trace every seed (in order) that lies on no branch traced before.

    ``prepare(seed)`` may move a seed first (e.g. :func:`off_fold` for fold seeds);
    ``trace_seed(seed, branch_id)`` traces it (e.g. ``contin.jumps.trace_both_ways``).  An open
    branch is trimmed to its part off the known branches (:func:`contin.overlap.trim_to_new`,
    on the first ``columns`` coordinates), then all are de-duplicated
    (:func:`contin.overlap.deduplicate`); the routes of a dropped branch are credited to its twin.
    """
    say = progress or (lambda m: None)
    traced: list[Branch] = []
    out = Discovery(branches=[])
    for seed in seeds:
        s = prepare(seed) if prepare is not None else seed
        twin = next((b for b in traced if near(problem, s.state, s.params, b, coordinates, near_tol)), None)
        if twin is not None:
            out.notes.append(f"{seed.label}: on known branch {twin.id}")
            if seed.route not in out.found_by[twin.id]:
                out.found_by[twin.id].append(seed.route)
            continue
        bid = f"{len(traced)}"
        say(f"tracing branch {bid} ({seed.label})")
        b = trace_seed(s, bid)
        if not b.closed:
            b = trim_to_new(b, s.state, traced, coordinates, trim_tol, columns)
        traced.append(b)
        out.routes[bid] = seed.route
        out.found_by[bid] = [seed.route]
        out.notes.append(f"{seed.label}: branch {bid} ({len(b)} points{', closed' if b.closed else ''})")
    kept, dup = deduplicate(traced, coordinates, dedup_tol)
    for a, k in dup:
        out.found_by[k] += [r for r in out.found_by[a] if r not in out.found_by[k]]
    out.branches = kept
    out.duplicates = dup
    out.routes = {b.id: out.routes[b.id] for b in kept}
    out.found_by = {b.id: out.found_by[b.id] for b in kept}
    return out
