"""Two-parameter continuation of folds (limit points) through the standard augmented system.

A fold of F(u, p1, p2) = 0 is a solution with a singular Jacobian.  Fold curves are traced
in (p1, p2) as solutions of (Moore & Spence, SIAM J. Numer. Anal. 17, 1980; Govaerts 2000,
sec. 4.1; AUTO-07p's "ISW=2")

    F(u, p1, p2) = 0,      J(u, p1, p2) phi = 0,      c . phi - 1 = 0,

with unknowns U = (u, phi, p2) continued in p1 by the ordinary pseudo-arclength tracer.  The
Jacobian needs the second derivative of F in the direction phi; it is a difference of two
sparse Jacobians, (J(u + eps phi) - J(u - eps phi)) / (2 eps), which keeps J's sparsity
pattern and has O(eps^2) truncation error (eps ~ 1e-6 relative gives ~1e-12).

Extrema of p2 along the curve (type ``XT``) mark where isolas are born or die when p2 is an
imperfection parameter; extrema of p1 appear as ordinary ``LP`` of the augmented system.  A
point that is an extremum of both (p1 and p2 stationary together) is a cusp of the curve's
projection on the (p1, p2) plane, e.g. the hysteresis point alpha = beta^3/27 of the
imperfect pitchfork.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint, relabel
from contin.continuation import trace, trace_both
from contin.extended import l2_norm
from contin.normalform import null_vectors
from contin.options import ContinuationOptions
from contin.problem import Array, has


class FoldProblem:
    """The augmented fold system as a contin Problem (state U = [u, phi, p2])."""

    #: Locate cusps (CP) along the curve (``contin.cusp``).
    detect_cusps: bool = True

    def __init__(self, problem: object, second: str, normalisation: Array, eps: float = 1e-6) -> None:
        self.problem = problem
        self.second = second
        self.parameter_names = tuple(problem.parameter_names)  # type: ignore[attr-defined]
        self.c = np.asarray(normalisation, float)
        self.n = self.c.size
        self.eps = eps

    def split(self, state: Array, p: Mapping[str, float]) -> tuple[Array, Array, dict[str, float]]:
        n = self.n
        q = dict(p)
        q[self.second] = state[2 * n]
        return state[:n], state[n : 2 * n], q

    def residual(self, state: Array, p: Mapping[str, float]) -> Array:
        u, phi, q = self.split(state, p)
        jac = self.problem.jacobian(u, q)  # type: ignore[attr-defined]
        return np.concatenate([self.problem.residual(u, q), jac @ phi, [self.c @ phi - 1.0]])  # type: ignore[attr-defined]

    def _hessian_phi(self, u: Array, phi: Array, q: Mapping[str, float]) -> sp.spmatrix:
        h = self.eps * max(1.0, float(np.max(np.abs(u)))) / max(float(np.max(np.abs(phi))), 1e-300)
        plus = sp.csr_matrix(self.problem.jacobian(u + h * phi, q))  # type: ignore[attr-defined]
        minus = sp.csr_matrix(self.problem.jacobian(u - h * phi, q))  # type: ignore[attr-defined]
        return (plus - minus) / (2 * h)

    def _mixed(self, u: Array, phi: Array, q: Mapping[str, float], name: str) -> Array:
        """d/dp (J phi) = d/du(F_p) phi, by a central difference along phi."""
        h = self.eps * max(1.0, float(np.max(np.abs(u)))) / max(float(np.max(np.abs(phi))), 1e-300)
        dp = self.problem.dresidual_dp  # type: ignore[attr-defined]
        return (dp(u + h * phi, q, name) - dp(u - h * phi, q, name)) / (2 * h)

    def jacobian(self, state: Array, p: Mapping[str, float]) -> sp.spmatrix:
        u, phi, q = self.split(state, p)
        n = self.n
        jac = sp.csr_matrix(self.problem.jacobian(u, q))  # type: ignore[attr-defined]
        f_p2 = self.problem.dresidual_dp(u, q, self.second)  # type: ignore[attr-defined]
        blocks = [
            [jac, None, sp.csr_matrix(f_p2[:, None])],
            [self._hessian_phi(u, phi, q), jac, sp.csr_matrix(self._mixed(u, phi, q, self.second)[:, None])],
            [None, sp.csr_matrix(self.c[None, :]), None],
        ]
        out = sp.bmat(blocks, format="csr")
        assert out.shape == (2 * n + 1, 2 * n + 1)
        return out

    def dresidual_dp(self, state: Array, p: Mapping[str, float], name: str) -> Array:
        u, phi, q = self.split(state, p)
        return np.concatenate(
            [self.problem.dresidual_dp(u, q, name), self._mixed(u, phi, q, name), [0.0]]  # type: ignore[attr-defined]
        )

    def order_parameter(self, state: Array, p: Mapping[str, float]) -> float:
        u, _, q = self.split(state, p)
        if has(self.problem, "order_parameter"):
            return float(self.problem.order_parameter(u, q))  # type: ignore[attr-defined]
        return l2_norm(u)  # the same default as along ordinary branches

    def observables(self, state: Array, p: Mapping[str, float]) -> dict[str, float]:
        u, _, q = self.split(state, p)
        out = dict(self.problem.observables(u, q)) if has(self.problem, "observables") else {}  # type: ignore[attr-defined]
        out[self.second] = float(state[2 * self.n])
        return out

    def admissible(self, state: Array, p: Mapping[str, float]) -> str | None:
        u, _, q = self.split(state, p)
        if has(self.problem, "admissible"):
            return self.problem.admissible(u, q)  # type: ignore[attr-defined]
        return None

    def point_tests(self) -> list[object]:
        """Cusps (CP, ``contin.cusp``; unless ``detect_cusps`` is False) and Bogdanov-Takens
        points (BT) along the fold curve (``contin.hopfcurve.fold_bt_test``); no BT for problems
        with their own ``eigenproblem`` (their M is not the steady one)."""
        from contin.cusp import CuspTest

        tests: list[object] = [CuspTest(self)] if self.detect_cusps else []
        if has(self.problem, "eigenproblem"):
            return tests
        from contin.hopfcurve import fold_bt_test

        return tests + [fold_bt_test(self.problem, self.n, self.c, self.second)]

    def under_resolved(self, state: Array, p: Mapping[str, float], tol: float) -> str | None:
        """The wrapped problem's resolution guard (``contin.problem``) on the base state u.

        Only u is a state of the problem; the null vector phi is not checked.  The reason gets
        the second parameter's value appended (the tracer's message names only the first).
        None when the wrapped problem has no ``under_resolved`` hook.
        """
        if not has(self.problem, "under_resolved"):
            return None
        u, _, q = self.split(state, p)
        reason = self.problem.under_resolved(u, q, tol)  # type: ignore[attr-defined]
        return None if reason is None else f"{reason} (at {self.second} = {q[self.second]:.6g})"


def fold_start(problem: object, point: SpecialPoint, second: str) -> tuple[FoldProblem, Array]:
    """The augmented problem and its start vector at a located fold ``point``."""
    u = np.asarray(point.state, float)
    jac = sp.csc_matrix(problem.jacobian(u, point.params))  # type: ignore[attr-defined]
    phi = null_vectors(jac).phi
    fold = FoldProblem(problem, second, phi)
    return fold, np.concatenate([u, phi, [point.params[second]]])


def _locate_extremum(fold: FoldProblem, branch: Branch, i: int, options: ContinuationOptions) -> SpecialPoint | None:
    """Locate an extremum of p2 between points i and i+1 as a fold of the swapped system.

    An extremum of p2 along the fold curve is a limit point of the same augmented system
    continued in p2 with p1 carried in the state, so the tracer's own LP location (to its
    tolerance) does the work.
    """
    n = fold.n
    first = branch.parameter
    swapped = FoldProblem(fold.problem, first, fold.c, fold.eps)
    u_phi = branch.states[i, : 2 * n]
    start = np.concatenate([u_phi, [branch.params[first][i]]])
    params = {k: float(v[i]) for k, v in branch.params.items()}
    params[fold.second] = float(branch.states[i, 2 * n])
    direction = 1.0 if branch.tangents[i, 2 * n] > 0 else -1.0
    ds = max(min(abs(branch.ds[i + 1]), options.step.ds_max) / 4, 10 * options.step.ds_min)
    local = replace(
        options,
        step=replace(options.step, ds=direction * ds, ds_max=max(ds, options.step.ds_max / 4)),
        bounds={},
        max_steps=40,
        detection=replace(options.detection, detect_branch_points=False),
        detect_closed=False,
    )
    part = trace(swapped, start, params, fold.second, local)
    if not part.fold_points:
        return None
    lp = part.fold_points[0]
    state = np.concatenate([lp.state[: 2 * n], [lp.params[fold.second]]])
    params = {**lp.params, first: float(lp.state[2 * n])}
    return SpecialPoint(
        type="XT",
        index=int(i),
        params=params,
        order_parameter=lp.order_parameter,
        state=state,
        bracket=(float(branch.states[i, 2 * n]), float(branch.states[i + 1, 2 * n])),
        converged=lp.converged,
        note=f"extremum of {fold.second}",
    )


def _extrema(branch: Branch, fold: FoldProblem, options: ContinuationOptions) -> list[SpecialPoint]:
    """Extrema of p2 along a fold curve (sign changes of its tangent component), located."""
    column = 2 * fold.n
    t = branch.tangents[:, column]
    out = []
    for i in np.nonzero(np.sign(t[:-1]) * np.sign(t[1:]) < 0)[0]:
        point = _locate_extremum(fold, branch, int(i), options)
        if point is not None:
            out.append(point)
    return out


def as_fold_curve(branch: Branch, fold: FoldProblem, options: ContinuationOptions | None = None) -> Branch:
    """Turn a traced augmented branch into a fold curve: p2 as a parameter column, base states,
    and ``XT`` special points at the extrema of p2."""
    n = fold.n
    params = dict(branch.params)
    params[fold.second] = branch.states[:, 2 * n].copy()
    observables = {k: v for k, v in branch.observables.items() if k != fold.second}
    out = replace(
        branch,
        free=(branch.parameter, fold.second),
        params=params,
        observables=observables,
        kind="fold-curve",
    )
    specials = [
        replace(sp_, params={**sp_.params, fold.second: float(sp_.state[2 * n])}, note=sp_.note or f"extremum of {branch.parameter}")
        if sp_.type == "LP"
        else replace(sp_, params={**sp_.params, fold.second: float(sp_.state[2 * n])})
        for sp_ in branch.special_points
    ]
    specials += _extrema(branch, fold, options or ContinuationOptions())
    specials.sort(key=lambda s: (s.index, s.type))
    out.special_points = specials
    relabel([out])  # the XT points join the numbering (LP1, XT2, ...)
    return out


def trace_fold_curve(
    problem: object,
    point: SpecialPoint,
    second: str,
    options: ContinuationOptions,
    *,
    parameter: str | None = None,
    both: bool = True,
    branch_id: str = "fold",
) -> Branch:
    """Continue the fold ``point`` in (parameter, second); both directions joined.

    ``parameter`` defaults to the first parameter that varies at the fold (the caller's
    continuation parameter); the tracer's BP detection is switched off because the
    augmented system's own singularities are not branch points of the original problem.
    Returns a fold-curve :class:`Branch` (``kind='fold-curve'``) with ``XT`` points at the
    extrema of ``second`` and ``LP`` points at the extrema of ``parameter``.
    """
    if parameter is None:
        raise ValueError("trace_fold_curve needs the name of the first continuation parameter")
    fold, start = fold_start(problem, point, second)
    raw = trace_augmented(fold, start, point, second, 2 * fold.n, options, parameter=parameter, both=both,
                          branch_id=branch_id, kind="fold-curve")
    return as_fold_curve(raw, fold, replace(options, detection=replace(options.detection, detect_branch_points=False)))


def trace_augmented(augmented: object, start: Array, point: SpecialPoint, second: str, index: int,
                    options: ContinuationOptions, *, parameter: str, both: bool, branch_id: str, kind: str,
                    mirror_start: bool = False) -> Branch:
    """Trace an augmented two-parameter system (fold or BP curve) whose state holds the second
    parameter at ``index``, in ``parameter``, both directions joined.

    BP detection of the augmented system is off (its singularities are not the problem's).
    Bounds on ``second`` in ``options.bounds`` are honoured: the tracer lands on bounds of the
    continuation parameter only, so each half is cut at the located crossing of the bound (a
    UZ event, as for Hopf curves: ``contin.hopfcurve``) and ends there with EP.

    ``mirror_start``: the second half starts with minus the first half's start tangent instead of
    the tracer's own choice from the sign of d parameter/ds (needed at a cusp, where the parameter
    is extremal and that sign cannot tell the halves apart: :mod:`contin.twoparam`).
    """
    import math

    from contin.continuation import join, trace
    from contin.hopfcurve import _cut_at_bound, _second_bound_event

    lo, hi = options.bounds.get(second, (-math.inf, math.inf))
    p2 = float(point.params[second])
    if not lo <= p2 <= hi:
        raise ValueError(f"start value {second}={p2:g} lies outside its bounds ({lo:g}, {hi:g})")
    opts = replace(options, detection=replace(options.detection, detect_branch_points=False),
                   bounds={k: v for k, v in options.bounds.items() if k != second})
    bounded = math.isfinite(lo) or math.isfinite(hi)
    if bounded:
        opts = replace(opts, events={**opts.events, **_second_bound_event(augmented, second, lo, hi, index=index)})
    halves = []
    for direction in ((1, -1) if both else (1,)):
        tangent = halves[0].tangents[0] if mirror_start and halves else None
        half = trace(augmented, start, dict(point.params), parameter, opts, direction=direction, tangent=tangent,
                     branch_id=branch_id, kind=kind, parent=f"{point.name}")
        halves.append(_cut_at_bound(half, augmented, second, lo, hi, index=index) if bounded else half)
        if half.closed or (mirror_start and len(half) < 2):  # nothing to mirror: no second half
            break
    return halves[0] if len(halves) == 1 else join(halves[1], halves[0])
