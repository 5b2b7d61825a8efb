"""Two-parameter continuation of Hopf points, with Bogdanov-Takens (BT) and generalized Hopf (GH) detection.

A Hopf point of M u' = F(u, p1, p2) has a real two-dimensional invariant subspace of the
pencil (J, M) on which it acts with eigenvalues +-i omega.  With kappa = omega^2 the curve of
Hopf points is traced as the solutions of the standard augmented system (Govaerts,
*Numerical Methods for Bifurcations of Dynamical Equilibria*, SIAM 2000, sec. 4.4.2; the
"J^2 + kappa I" formulation of Roose & Hlavacek, SIAM J. Appl. Math. 45, 1985)

    F(u, p1, p2) = 0,   J v - M w = 0,   J w + kappa M v = 0,   c . v - 1 = 0,   d . v = 0,

unknowns U = (u, v, w, kappa, p2), continued in p1 by the ordinary pseudo-arclength tracer
(c, d: fixed vectors, Re q and Im q of the start's eigenvector q made orthogonal, so that the
two rows pick one v of the two-dimensional invariant subspace).  Both rows act on v: a row
c . w = 0 on w = M^{-1} J v instead degenerates at BT, where J maps the whole subspace onto
the kernel (the solution has w = 0 there and the augmented Jacobian is singular).  kappa > 0 on Hopf points
(omega = sqrt(kappa)); the same equations with kappa < 0 describe neutral saddles (real
eigenvalues +-sqrt(-kappa)), and at kappa = 0 (J v = M w, J w = 0: a Jordan block of the zero
eigenvalue) the curve passes a Bogdanov-Takens point, where it meets a fold curve.  BT is the
sign change of kappa, located like every test function by the tracer (``contin.locate``);
the part of the curve with kappa < 0 is kept and marked by the column ``kappa``.  On the Hopf
part, a sign change of the first Lyapunov coefficient l1 is a generalized Hopf (Bautin) point,
GH, where the Hopf bifurcation turns from super- to subcritical and a fold curve of limit cycles
begins (Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed., sec. 8.3;
``contin.hopfsystem.LyapunovTest``).

On fold curves (``contin.foldcurve``: J phi = 0) a BT is where the left null vector psi of J
becomes M-orthogonal to phi (the zero eigenvalue becomes double and non-semisimple): the test
function psi^T M phi / (|psi| |phi|) changes sign there (Govaerts 2000, sec. 4.3).
:func:`fold_bt_test` is the point test, passed with ``trace_fold_curve(..., bt=True)``.

M is taken as constant (independent of u and p), as everywhere in contin's Hopf code.  The
second derivatives the augmented Jacobian needs are central differences of the problem's
Jacobian along v and w (as ``contin.foldcurve`` does along phi).  The augmented system itself
(:class:`HopfCurveProblem`, :func:`hopf_basis`) lives in ``contin.hopfsystem``, which the
two-grid check of located Hopf points (``contin.specialcheck``) shares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.hopf import hopf_test
from contin.hopfsystem import HopfCurveProblem, KappaTest, LyapunovTest, _mass, hopf_basis
from contin.options import ContinuationOptions
from contin.pointtests import Crossing
from contin.problem import Array, has
from contin.testfunctions import sign_log_crossing

#: the public API (the augmented system's classes are ``contin.hopfsystem``'s, listed here too:
#: the Hopf-curve API they belong to)
__all__ = ["HopfCurveProblem", "KappaTest", "LyapunovTest", "as_hopf_curve", "fold_bt_test", "hopf_basis", "hopf_curve_start",
           "hopf_curve_start_at_bt",
           "trace_hopf_curve"]


def hopf_curve_start(problem: Any, point: SpecialPoint, second: str) -> tuple[HopfCurveProblem, Array]:
    """The augmented problem and its start vector at a located Hopf ``point`` (type HB).

    q (J q = i omega M q) is rotated by a phase so that Re q is orthogonal to Im q; then
    v = Re q / |Re q| (J v = -omega M Im q / |Re q|, so w = -omega Im q / |Re q|), c = v and
    d = Im q / |Im q| give c . v = 1, d . v = 0 (:func:`hopf_basis`).
    """
    if point.type != "HB":
        raise ValueError(f"a Hopf curve starts at an HB point, got {point.name} ({point.type})")
    omega = point.data.get("omega", math.nan)
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"{point.name} has no positive omega")
    u = np.asarray(point.state, float)
    params = dict(point.params)
    v, w, d = hopf_basis(problem, u, params, omega)
    c = v.copy()  # c . v = 1
    curve = HopfCurveProblem(problem, second, c, d)
    return curve, np.concatenate([u, v, w, [omega**2, params[second]]])


def hopf_curve_start_at_bt(problem: Any, u: Array, params: Mapping[str, float], second: str) -> tuple[HopfCurveProblem, Array]:
    """The augmented Hopf problem and its start vector at a Bogdanov-Takens point (u, p) of a fold
    curve, where kappa = 0: w = phi spans ker J and v is the generalized eigenvector, J v = M w,
    v orthogonal to phi (the bordered solve [[J, psi], [phi^T, 0]] [v; s] = [M phi; 0], s = 0 at
    an exact BT, where M phi lies in J's range); rows c = v / |v|^2 (c . v = 1) and d = phi
    (d . v = 0).  The augmented system is regular at BT (its rows act on v), so the curve is
    traced through it: kappa > 0 (Hopf points) on one side, kappa < 0 (neutral saddles) on the
    other (Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed., sec. 8.4)."""
    import scipy.sparse as sp

    from contin.codim2tests import generalized_null_vector
    from contin.normalform import null_vectors

    u = np.asarray(u, float)
    q = dict(params)
    jac = sp.csc_matrix(problem.jacobian(u, q))
    nulls = null_vectors(jac)
    phi, psi = nulls.phi, nulls.psi
    v = generalized_null_vector(jac, _mass(problem, u, q, jac.shape[0]), phi, psi)
    scale = float(v @ v)
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError("no generalized eigenvector at the BT point (J v = M phi has no solution)")
    curve = HopfCurveProblem(problem, second, v / scale, phi / float(np.linalg.norm(phi)))
    return curve, np.concatenate([u, v, phi, [0.0, q[second]]])


def as_hopf_curve(branch: Branch, curve: HopfCurveProblem) -> Branch:
    """A traced augmented branch as a Hopf curve: p2 as a parameter column, the base states,
    the ``kappa`` observable (omega^2); LP points are extrema of the first parameter."""
    n = curve.n
    params = dict(branch.params)
    params[curve.second] = branch.states[:, 3 * n + 1].copy()
    observables = {k: v for k, v in branch.observables.items() if k != curve.second}
    out = replace(branch, free=(branch.parameter, curve.second), params=params, observables=observables,
                  kind="hopf-curve")

    def fix(s: SpecialPoint) -> SpecialPoint:
        extra = {curve.second: float(s.state[3 * n + 1])}
        note = s.note or (f"extremum of {branch.parameter}" if s.type == "LP" else "")
        return replace(s, params={**s.params, **extra}, note=note)

    out.special_points = [fix(s) for s in branch.special_points]
    return out


def trace_hopf_curve(
    problem: Any,
    point: SpecialPoint,
    second: str,
    options: ContinuationOptions,
    *,
    parameter: str,
    both: bool = True,
    branch_id: str = "hopf",
    generalized_hopf: bool | None = None,
    start: tuple[HopfCurveProblem, Array] | None = None,
) -> Branch:
    """Continue the Hopf ``point`` in (parameter, second); both directions joined.

    BT points (type ``BT``) are located where kappa = omega^2 changes sign; past a BT the curve
    continues as a curve of neutral saddles (observable ``kappa`` < 0).  Generalized Hopf points
    (type ``GH``) are located where the first Lyapunov coefficient l1 changes sign on the Hopf
    part (``contin.hopfsystem.LyapunovTest``); ``generalized_hopf=None`` (default) detects them
    when the problem has no ``eigenproblem`` of its own (l1 needs J's own nonlinearity, as at
    HB points), True/False force it.  l1 costs about 30 Jacobians and two complex LUs per point
    (CO oxidation's Hopf curve: see README).  Zero-Hopf points (``ZH``: a real eigenvalue through
    zero, one LU per point) are detected for problems without their own ``eigenproblem``, and
    double-Hopf points (``HH``: a second pair through the imaginary axis) where
    ``options.detection`` would detect HB points on the problem (``contin.hopf.hopf_test``;
    ``detect_hopf=False`` switches it off); ``contin.codim2tests``.  ``start``: an augmented
    problem and start vector to use instead of the HB ``point``'s (:func:`hopf_curve_start_at_bt`:
    the Hopf curve from a BT of a fold curve; ``point`` then only gives the parameters).  Bounds
    in ``options.bounds`` on ``second`` end the run with EP on the bound (the tracer's bound
    landing, through the state's p2 entry: see :func:`_second_bound_event`).  BP and Hopf
    detection of the augmented system are off (its singularities are not the problem's).
    """
    from contin.continuation import join, trace

    lo, hi = options.bounds.get(second, (-math.inf, math.inf))
    if second in point.params and not lo <= float(point.params[second]) <= hi:  # as trace_fold_curve
        raise ValueError(f"start value {second}={float(point.params[second]):g} lies outside its bounds ({lo:g}, {hi:g})")
    curve, start_vector = hopf_curve_start(problem, point, second) if start is None else start
    curve.generalized_hopf = (not has(problem, "eigenproblem")) if generalized_hopf is None else bool(generalized_hopf)
    curve.zero_hopf = not has(problem, "eigenproblem")
    curve.base_hopf = hopf_test(problem, options.detection, curve.n)
    opts = replace(options, detection=replace(options.detection, detect_branch_points=False, detect_hopf=False),
                   bounds={k: v for k, v in options.bounds.items() if k != second})
    bounded = math.isfinite(lo) or math.isfinite(hi)
    ends = _second_bound_event(curve, second, lo, hi) if bounded else {}
    opts = replace(opts, events={**opts.events, **ends}) if bounded else opts
    meta = dict(branch_id=branch_id, kind="hopf-curve", parent=point.name, stop_events=tuple(ends))
    halves = []
    for direction in ((1, -1) if both else (1,)):
        half = trace(curve, start_vector, dict(point.params), parameter, opts, direction=direction, **meta)
        halves.append(_cut_at_bound(half, curve, second, lo, hi) if bounded else half)
        if halves[-1].closed:
            # a closed curve is whole after one half (as in trace_augmented): the other half went
            # round it again, every special point twice (AUTO's pp3: 6 ZH/LP/GH reported as 12)
            break
    raw = halves[0] if len(halves) == 1 else join(halves[1], halves[0])
    return _no_gh_at_zero_hopf(as_hopf_curve(raw, curve))


def _no_gh_at_zero_hopf(curve: Branch) -> Branch:
    """The curve without the GH points located in the same step as a ZH: l1 has a pole where a
    real eigenvalue passes 0 (its term p . B(q, J^-1 B(q, qb)); Kuznetsov's l1 tends to infinity
    along a Hopf curve towards a zero-Hopf point), so its sign changes there and the locator
    converged onto the pole: x' = a + b - x^2 + b x + (v^2 + w^2) / 2 with the oscillator of
    ``tests/test_zero_double_hopf.py`` reported a "converged" GH with l1 = -7.5e10 at its ZH
    (session 16).  A GH at a ZH is of codimension three."""
    from contin.branch import relabel

    steps = {sp.index for sp in curve.special_points if sp.type == "ZH"}
    kept = [sp for sp in curve.special_points if not (sp.type == "GH" and sp.index in steps)]
    if len(kept) == len(curve.special_points):
        return curve
    curve.special_points = kept
    relabel([curve])
    return curve


def _cut_at_bound(branch: Branch, curve: Any, second: str, lo: float, hi: float, index: int | None = None) -> Branch:
    """The branch up to its first crossing of a bound of ``second`` (the located UZ of
    :func:`_second_bound_event`), ending there with EP "reached bound ...".  The tracer's own
    bound landing works on the continuation parameter only; p2 is part of the state here, at
    ``index`` (default: its place in the Hopf-curve state; ``contin.foldcurve`` passes its own).

    The located UZ is then corrected onto the bound exactly: bordered Newton on
    [F(x); p2 - bound] = 0 (the continuation parameter free), from the UZ with p2 set to the
    bound; if that fails the UZ itself ends the branch."""
    from contin.corrector import correct
    from contin.extended import ExtendedSystem
    from contin.options import NewtonOptions

    tag = f"bound of {second}"
    j = 3 * curve.n + 1 if index is None else index  # p2's place in the state
    hits = [s for s in branch.special_points if s.type == "UZ" and s.note.startswith(tag)]
    first_out = _first_outside(branch, j, lo, hi)
    if not hits or (first_out is not None and first_out <= min(s.index for s in hits)):
        # no located crossing, or points beyond a bound stored before the first one: a half that
        # starts on a bound and leaves through it (no sign change there) and crosses back later.
        # `continue ab.h5 --from HB1 --free B --bounds B=14:20` (B = 14 at HB1) stored the Hopf curve
        # down to B = 10.5, GH and LP below the bound, cut only where it came back to B = 14 (qa18)
        return _stop_outside(branch, second, lo, hi, j)
    uz = min(hits, key=lambda s: s.index)
    i = uz.index
    n_keep = i + 1
    system = ExtendedSystem(curve, {**uz.params}, branch.parameter)
    x = system.pack(uz.state, uz.params[branch.parameter])
    bound = lo if abs(x[j] - lo) <= abs(x[j] - hi) else hi
    x_pred = x.copy()
    x_pred[j] = bound
    row = np.zeros_like(x)
    row[j] = 1.0
    landed = correct(system, x_pred, row, NewtonOptions(max_iterations=20))
    located = uz
    if landed.converged and np.all(np.isfinite(landed.x)):
        x = landed.x.copy()
        x[j] = bound
        uz = replace(uz, state=x[:-1].copy(), params={**uz.params, branch.parameter: float(x[-1])},
                     order_parameter=system.order_parameter(x))
    record = system.record(x)
    p2 = float(uz.state[j])
    end = SpecialPoint(type="EP", index=n_keep, params=dict(uz.params), order_parameter=uz.order_parameter,
                       state=uz.state.copy(), tangent=None if uz.tangent is None else uz.tangent.copy(),
                       bracket=uz.bracket, note=f"reached bound {second}={p2:g}")
    # a point of the crossing step on the bound itself (to its location tolerance) is in the range:
    # `contin continue F --from LP2 --free b --bounds b=-0.5:0.6666666666666666` (ZH at b = 2/3)
    # dropped the ZH located 1e-12 beyond the landed point, while a bound 1e-12 further kept it (qa17)
    on_bound = ON_BOUND * max(1.0, abs(bound))
    keep = [s for s in branch.special_points
            if s.type not in ("EP", "MX") and s is not located and (s.index < i or (s.index == i and s.params.get(branch.parameter) is not None
                                                                                and (_before(branch, s, uz)
                                                                                     or _within(s, j, lo, hi, on_bound))))]
    states = branch.states[:n_keep] if branch.state_index is None else branch.states[branch.state_index < n_keep]
    state_index = None if branch.state_index is None else np.append(branch.state_index[branch.state_index < n_keep], n_keep)
    cut = replace(
        branch,
        params={k: np.append(v[:n_keep], uz.params.get(k, v[-1])) for k, v in branch.params.items()},
        observables={k: np.append(v[:n_keep], record.get(k, math.nan)) for k, v in branch.observables.items()},
        states=np.vstack([states, uz.state[None, :]]),
        tangents=np.vstack([branch.tangents[:n_keep], (branch.tangents[i] if uz.tangent is None else uz.tangent)[None, :]]),
        ds=np.append(branch.ds[:n_keep], 0.0),
        newton_iterations=np.append(branch.newton_iterations[:n_keep], 0),
        special_points=keep + [end],
        status="EP",
        message=f"reached bound {second}={p2:g}",
        state_index=state_index,
        closed=False,  # the raw half may have closed beyond the bound (CO's Hopf curve past k = 1)
    )
    return cut


def _stop_outside(branch: Branch, second: str, lo: float, hi: float, j: int) -> Branch:
    """The branch up to its last point inside [lo, hi] in ``second`` (state entry ``j``), ending
    there with EP, when a point beyond a bound was stored without a located crossing: a half that
    starts on a bound and leaves through it (the bound event min(p2 - lo, hi - p2) is 0 at the
    start, so no sign change is seen).  `contin continue F --from LP1 --free a --bounds a=0:2` from
    a = 0 stored a down to -0.12, and the Hopf curve of lorenz's HB2 with sigma=10:30 sigma down
    to 5, exit 0 (qa15)."""
    from contin.overlap import slice_branch

    k = _first_outside(branch, j, lo, hi)
    if k is None:
        return branch
    p2 = branch.states[:, j]
    if k == 0:  # the start itself lies outside: the callers refuse that before tracing
        raise ValueError(f"start value {second}={p2[0]:g} lies outside its bounds ({lo:g}, {hi:g})")
    cut = slice_branch(branch, 0, k - 1)
    last = k - 1
    at = float(p2[last])
    end = SpecialPoint(type="EP", index=last, params={name: float(v[last]) for name, v in cut.params.items()},
                       order_parameter=float(cut.observables.get("phi", np.full(k, math.nan))[last]),
                       state=cut.states[last].copy(), tangent=cut.tangents[last].copy(),
                       note=f"reached bound {second}={at:g}")
    return replace(cut, special_points=[sp_ for sp_ in cut.special_points if sp_.type not in ("EP", "MX")] + [end],
                   status="EP", message=f"reached bound {second}={at:g}", closed=False)


def _first_outside(branch: Branch, j: int, lo: float, hi: float) -> int | None:
    """Index of the first stored point whose second parameter (state entry ``j``) lies beyond
    [lo, hi] (by more than 1e-9 relative), or None (also for a branch that stores every k-th state)."""
    if branch.state_index is not None or len(branch) == 0:
        return None
    p2 = branch.states[:, j]
    slack = 1e-9 * max(1.0, abs(lo) if math.isfinite(lo) else 0.0, abs(hi) if math.isfinite(hi) else 0.0)
    outside = np.flatnonzero((p2 < lo - slack) | (p2 > hi + slack))
    return int(outside[0]) if outside.size else None


#: a located point this close to a bound (relative to max(1, |bound|)) is on it: ten times the
#: tracer's default location tolerance (``DetectionOptions.locate_tol``)
ON_BOUND = 1e-10


def within_bounds(value: float, lo: float, hi: float) -> bool:
    """Whether ``value`` lies in [lo, hi] or on a bound to :data:`ON_BOUND` (relative to
    max(1, |bound|)): a located start point on a bound is in the range."""
    return lo - ON_BOUND * max(1.0, abs(lo)) <= value <= hi + ON_BOUND * max(1.0, abs(hi))


def _within(s: SpecialPoint, j: int, lo: float, hi: float, slack: float) -> bool:
    """Whether the second parameter of ``s`` (state entry ``j``) lies in [lo - slack, hi + slack]."""
    if s.state is None or len(s.state) <= j:
        return False
    return bool(lo - slack <= float(s.state[j]) <= hi + slack)


def _before(branch: Branch, s: SpecialPoint, uz: SpecialPoint) -> bool:
    """Whether s (in the same step as uz) lies before uz along the step."""
    p = branch.parameter
    a = branch.params[p][s.index]
    return abs(s.params[p] - a) <= abs(uz.params[p] - a)


def _second_bound_event(curve: Any, second: str, lo: float, hi: float, index: int | None = None) -> dict[str, Any]:
    """Events that vanish on the (finite) bounds of the second parameter (p2 is part of the state,
    so the tracer's bound landing does not see it): the run stops at the located crossing
    (``trace(..., stop_events=...)``) and is cut there (:func:`_cut_at_bound`).
    ``index``: p2's place in the state (default: the Hopf-curve state's).  One event per bound:
    the former min(p2 - lo, hi - p2) is 0 at a start on one bound, so a first step across the
    other bound showed no sign change (`contin continue pf.h5 --from BP1 --free nu --bounds
    nu=0.3:0.31` from nu = 0.3 stored nu up to 0.317, qa15)."""
    index = 3 * curve.n + 1 if index is None else index
    out: dict[str, Any] = {}
    if math.isfinite(lo):
        out[f"bound of {second} (lower)"] = lambda state, p: float(state[index]) - lo
    if math.isfinite(hi):
        out[f"bound of {second} (upper)"] = lambda state, p: hi - float(state[index])
    return out


def fold_bt_test(problem: Any, n: int, c: Array, second: str) -> Any:
    """The BT point test of a fold curve (``contin.foldcurve``: state [u, phi, p2], c . phi = 1)."""
    return _FoldBT(problem, n, np.asarray(c, float), second)


@dataclass
class _FoldBT:
    """tau = tr(adj(J) M), the coefficient of -lambda in det(J - lambda M), on a fold curve.

    Where J has the simple null vectors phi (right) and psi (left), adj(J) = k phi psi^T with k
    the product of the nonzero eigenvalues over psi^T phi, so tau = k psi^T M phi vanishes where
    psi^T M phi does: the zero eigenvalue becomes double and non-semisimple (BT).  tau is a
    polynomial in the entries of J, so it has no poles (psi^T M phi computed from a bordered
    solve alone has one wherever the border becomes orthogonal to psi).  It is evaluated as
    tau = -det A * (y^T M x), A = [[J, c], [c^T, 0]], A [x; .] = e, A^T [y; .] = e (Cramer),
    kept as (sign, log|tau|) like the BP determinant.
    """

    problem: Any
    n: int
    c: Array
    second: str
    name: str = "bt"
    kind: str = "BT"

    def value(self, system: Any, x: Array) -> tuple[float, float]:
        from contin.linalg import factorize_bordered

        n = self.n
        u = x[:n]
        q = system.params_at(x[-1])
        q[self.second] = float(x[2 * n])
        jac = self.problem.jacobian(u, q)
        m = _mass(self.problem, u, q, n)
        fact = factorize_bordered(jac, self.c, np.concatenate([self.c, [0.0]]))
        if fact is None:
            return (0.0, -math.inf)
        e = np.zeros(n + 1)
        e[-1] = 1.0
        xr = fact.solve(e)[:n]
        yl = fact.solve(e, trans="T")[:n]
        sign, logabs = fact.det_sign_log()
        ymx = float(yl @ (m @ xr))
        if ymx == 0 or sign == 0:
            return (0.0, -math.inf)
        return (-sign * math.copysign(1.0, ymx), logabs + math.log(abs(ymx)))

    def crossings(self, va: tuple[float, float], vb: tuple[float, float]) -> list[Crossing]:
        return sign_log_crossing(va, vb, "Bogdanov-Takens (psi^T M phi = 0)")

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        """The BT normal-form coefficients a, b at the base state (``contin.codim2tests``)."""
        from contin.codim2tests import bogdanov_takens_coefficients

        q = system.params_at(x[-1])
        q[self.second] = float(x[2 * self.n])
        return replace(sp_, data={**sp_.data, **bogdanov_takens_coefficients(self.problem, x[:self.n], q)})
