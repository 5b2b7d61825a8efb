"""Two-parameter continuation of a located special point (AUTO's restart at a label with two
free parameters, ``ICP=[p1, p2]``).

:func:`continue_point` dispatches on the point's type through :data:`CURVES`:

- ``LP`` -- the fold curve through the Moore-Spence system F = 0, J phi = 0, c.phi = 1
  (:class:`contin.foldcurve.FoldProblem`, as in :func:`contin.foldcurve.trace_fold_curve`);
- ``BP`` -- when the second parameter unfolds the BP (psi . dF/dp2 != 0, psi the left null
  vector of J) the same system, regular at the BP: the curve is the fold curve of the unfolded
  bifurcation -- for a pitchfork broken by p2 the imperfect pitchfork's fold curve, whose
  projection on (p1, p2) has its cusp at the BP; for a transcritical BP (lam x - x^2 + mu) the
  fold curve x = lam/2, mu = -lam^2/4 through it.  When p2 keeps the BP (psi . dF/dp2 = 0, e.g.
  a symmetry-preserving parameter at a symmetry-breaking pitchfork) the plain system is
  singular there and the curve of pitchforks is traced by the system restricted to symmetric
  u and antisymmetric phi (Werner & Spence, SIAM J. Numer. Anal. 21, 1984;
  :func:`contin.bpcurve.trace_bp_curve`); any other BP kept by p2 is a clear error;
- ``HB`` -- the Hopf curve (:func:`contin.hopfcurve.trace_hopf_curve`; Bogdanov-Takens points
  located on it).

Other point types are a clear error (:class:`NotAvailable`); :func:`register_curve` adds one.
Bounds on the second parameter (``options.bounds[second]``) end the curve exactly on the bound:
the last point is corrected onto it with the roles of the parameters swapped.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from contin.bpcurve import trace_bp_curve
from contin.branch import Branch, SpecialPoint, relabel
from contin.continuation import join, newton, trace
from contin.extended import ExtendedSystem
from contin.foldcurve import FoldProblem, as_fold_curve, fold_start
from contin.normalform import null_vectors
from contin.hopfcurve import trace_hopf_curve
from contin.options import ContinuationOptions, NewtonOptions

#: curve(problem, point, second, options, parameter=..., branch_id=...) -> Branch
CurveTracer = Callable[..., Branch]


class NotAvailable(ValueError):
    """Two-parameter continuation of this point type is not implemented (yet)."""


def _fold_or_pitchfork(problem: Any, point: SpecialPoint, second: str, options: ContinuationOptions, *,
                       parameter: str, branch_id: str) -> Branch:
    """Both halves of the Moore-Spence curve through ``point``.

    Unlike :func:`contin.foldcurve.trace_fold_curve` (halves chosen by the sign of d parameter/ds)
    the second half starts with minus the first half's start tangent: at a pitchfork unfolded by
    ``second`` the curve has a cusp in (p1, p2), p1 is extremal there (d p1/ds = 0) and the sign
    of d p1/ds cannot tell the halves apart.
    """
    if point.type == "BP" and not _unfolds(problem, point, second):
        if "symmetry-breaking" not in point.note:
            raise ValueError(f"{second!r} does not unfold {point.name} (psi . dF/d{second} = 0: the branch point "
                             f"persists as {second} changes) and {point.name} is not a symmetry-breaking pitchfork, "
                             "so contin cannot continue it in two parameters")
        return trace_bp_curve(problem, point, second, options, parameter=parameter, branch_id=branch_id)
    fold, start = fold_start(problem, point, second)
    lo, hi = options.bounds.get(second, (-math.inf, math.inf))
    opts = replace(options, detection=replace(options.detection, detect_branch_points=False),
                   bounds={k: v for k, v in options.bounds.items() if k != second})
    common = dict(branch_id=branch_id, kind="fold-curve", parent=point.name)
    forward = _cut_at_bound(trace(fold, start, dict(point.params), parameter, opts, direction=+1, **common),
                            fold, second, lo, hi)
    if forward.closed or len(forward) < 2:
        return as_fold_curve(forward, fold, opts)
    backward = _cut_at_bound(trace(fold, start, dict(point.params), parameter, opts, direction=-1,
                                   tangent=forward.tangents[0], **common), fold, second, lo, hi)
    return as_fold_curve(join(backward, forward), fold, opts)


#: psi . dF/dp2 below this fraction of |psi| |dF/dp2| means p2 does not unfold the BP
UNFOLD_TOL = 1e-8


def _unfolds(problem: Any, point: SpecialPoint, second: str) -> bool:
    """True if ``second`` unfolds the BP at first order: psi . dF/dp2 != 0 (relative UNFOLD_TOL)."""
    import scipy.sparse as sp

    u = np.asarray(point.state, float)
    psi = null_vectors(sp.csc_matrix(problem.jacobian(u, point.params))).psi
    fp = np.asarray(problem.dresidual_dp(u, point.params, second), float)
    scale = float(np.linalg.norm(psi) * np.linalg.norm(fp))
    return scale > 0.0 and abs(float(psi @ fp)) > UNFOLD_TOL * scale


def _cut_at_bound(half: Branch, fold: FoldProblem, second: str, lo: float, hi: float) -> Branch:
    """``half`` (a traced augmented branch, state (u, phi, p2)) up to where p2 first leaves
    [lo, hi], ending with a point exactly on the bound and EP "reached bound ...".

    The tracer lands on bounds of its continuation parameter only; p2 is part of the state, so
    the crossing is corrected here: Newton on the same fold system with p2 fixed at the bound
    and the first parameter an unknown (FoldProblem with the roles swapped), from the linear
    interpolation of the two points around the crossing.
    """
    n = fold.n
    if half.state_index is not None or len(half) < 2:
        return half
    p2 = half.states[:, 2 * n]
    out = np.nonzero((p2 < lo) | (p2 > hi))[0]
    if out.size == 0 or out[0] == 0:
        return half
    i = int(out[0])
    bound = hi if p2[i] > hi else lo
    w = (bound - p2[i - 1]) / (p2[i] - p2[i - 1])
    first = half.parameter
    guess = (1 - w) * half.states[i - 1] + w * half.states[i]
    p1 = (1 - w) * half.params[first][i - 1] + w * half.params[first][i]
    params = {k: float(v[i - 1]) for k, v in half.params.items()}
    params[second] = bound
    swapped = FoldProblem(fold.problem, first, fold.c, fold.eps)
    res = newton(swapped, np.concatenate([guess[: 2 * n], [p1]]), params, NewtonOptions(max_iterations=20))
    keep = i
    specials = [sp for sp in half.special_points if sp.index < keep - 1 or (sp.index == keep - 1 and sp.type not in ("EP", "MX"))]
    cut = replace(half, params={k: v[:keep] for k, v in half.params.items()},
                  observables={k: v[:keep] for k, v in half.observables.items()},
                  states=half.states[:keep], tangents=half.tangents[:keep], ds=half.ds[:keep],
                  newton_iterations=half.newton_iterations[:keep], special_points=specials, status="EP",
                  message=f"reached bound {second}={bound:g}", closed=False)
    if not res.converged:
        cut.message += f" (landing on it failed: {res.message}; stopped before it)"
        return cut
    state = np.concatenate([res.u[: 2 * n], [bound]])
    at = {**params, first: float(res.u[2 * n])}
    system = ExtendedSystem(fold, at, first)
    x = system.pack(state, at[first])
    record = system.record(x)
    cut.params = {k: np.append(v, at[k]) for k, v in cut.params.items()}
    cut.observables = {k: np.append(v, record.get(k, np.nan)) for k, v in cut.observables.items()}
    cut.states = np.vstack([cut.states, state])
    cut.tangents = np.vstack([cut.tangents, cut.tangents[-1]])
    cut.ds = np.append(cut.ds, system.norm(x - system.pack(cut.states[-2], cut.params[first][-2])))
    cut.newton_iterations = np.append(cut.newton_iterations, res.iterations)
    cut.special_points = [*cut.special_points, SpecialPoint(
        type="EP", index=len(cut) - 1, params=dict(at), order_parameter=system.order_parameter(x), state=state,
        tangent=cut.tangents[-1], note=cut.message)]
    relabel([cut])
    return cut


def _hopf(problem: Any, point: SpecialPoint, second: str, options: ContinuationOptions, *,
          parameter: str, branch_id: str) -> Branch:
    return trace_hopf_curve(problem, point, second, options, parameter=parameter, branch_id=branch_id)


#: Point type -> tracer of its two-parameter curve.  A module that adds one (e.g. Hopf curves)
#: calls register_curve('HB', fn) on import.
CURVES: dict[str, CurveTracer] = {"LP": _fold_or_pitchfork, "BP": _fold_or_pitchfork, "HB": _hopf}


def register_curve(point_type: str, tracer: CurveTracer) -> None:
    """Make :func:`continue_point` trace ``point_type`` points (e.g. 'HB') with ``tracer``."""
    CURVES[point_type] = tracer


def continue_point(problem: Any, branch: Branch, point: SpecialPoint, second: str,
                   options: ContinuationOptions, *, branch_id: str | None = None) -> Branch:
    """The curve of ``point`` (a located LP, BP or HB of ``branch``) in (branch.parameter, ``second``).

    Bounds: ``options.bounds`` of either parameter; the curve ends exactly on them.

    Raises
    ------
    NotAvailable
        For a point type without a registered curve tracer (EP, MX, UZ...).
    ValueError
        For a bad second parameter, a point without a state, or a start the corrector cannot
        converge (e.g. a transcritical BP, where the fold system is singular).
    """
    first = branch.parameter
    names = tuple(getattr(problem, "parameter_names", ()))
    if second == first:
        raise ValueError(f"the second parameter must differ from the branch's parameter {first!r}")
    if names and second not in names:
        raise ValueError(f"unknown parameter {second!r}; the problem's parameters are {', '.join(names)}")
    if second not in point.params:
        raise ValueError(f"point {point.name} has no value of {second!r}")
    tracer = CURVES.get(point.type)
    if tracer is None:
        raise NotAvailable(f"{point.name}: only {', '.join(sorted(CURVES))} points can be continued in two parameters, "
                           f"not {point.type}")
    if point.state is None:
        raise ValueError(f"{point.name} has no stored state")
    curve = tracer(problem, point, second, options, parameter=first,
                   branch_id=branch_id if branch_id is not None else f"{point.name}.{second}")
    if len(curve) <= 1:
        raise ValueError(f"the {point.type} curve from {point.name} did not start: {curve.message}")
    return curve
