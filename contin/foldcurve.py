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

Segment-wise regridding (:class:`SegmentRegrid`, ``trace_fold_curve(..., regrid=...)``): where
the resolution guard stops a fold curve on grid N, its last accepted point and tangent are
carried onto a finer grid (:meth:`FoldProblem.carry`) and the curve continues from there, so only
the part that needs the finer grid pays for it; the points keep their grids (``Branch.grid``).
Every point of a regridded curve also passes a two-grid check of its solve
(:func:`augmented_two_grid_error`, ``AdaptOptions.check_factor``): the guard bounds how well the
grid carries the state, not the error of the augmented solution, which next to a fold is that
truncation amplified by the inverse of the augmented Jacobian.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.adapt import PARAM_SCALE_FLOOR
from contin.branch import Branch, SpecialPoint, relabel
from contin.cancel import deferred
from contin.continuation import trace, trace_both
from contin.extended import l2_norm
from contin.hopf import hopf_test
from contin.normalform import null_vectors
from contin.options import AdaptOptions, ContinuationOptions
from contin.problem import Array, has


class FoldProblem:
    """The augmented fold system as a contin Problem (state U = [u, phi, p2])."""

    #: Locate cusps (CP) along the curve (``contin.cusp``).
    detect_cusps: bool = True
    #: The base problem's HopfTest (``contin.hopf.hopf_test``): zero-Hopf points (ZH) along the
    #: curve, where a pair of the base pencil crosses the imaginary axis (``contin.codim2tests``).
    base_hopf: Any = None

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
        """Cusps (CP, ``contin.cusp``; unless ``detect_cusps`` is False), zero-Hopf points (ZH,
        ``contin.codim2tests``; when ``base_hopf`` is set) and Bogdanov-Takens points (BT) along
        the fold curve (``contin.hopfcurve.fold_bt_test``); no BT for problems with their own
        ``eigenproblem`` (their M is not the steady one)."""
        from contin.cusp import CuspTest

        tests: list[object] = [CuspTest(self)] if self.detect_cusps else []
        if self.base_hopf is not None:
            from contin.codim2tests import BaseEigenTest

            tests.append(BaseEigenTest(self.base_hopf, self.base, "zh", "ZH",
                                       "zero-Hopf (a pair crosses the imaginary axis on the fold curve)"))
        if has(self.problem, "eigenproblem"):
            return tests
        from contin.hopfcurve import fold_bt_test

        return tests + [fold_bt_test(self.problem, self.n, self.c, self.second)]

    def base(self, state: Array, p: Mapping[str, float]) -> tuple[Array, dict[str, float]]:
        """The base state u and the base parameters (p2 in place) of an augmented state."""
        u, _, q = self.split(state, p)
        return u, q

    # --- grids (segment-wise regridding of a fold curve: :func:`trace_augmented`) ----------------
    @property
    def grid_size(self) -> int | None:
        """The wrapped problem's grid size (None for a problem without grids)."""
        return getattr(self.problem, "grid_size", None)

    def with_grid(self, size: int) -> FoldProblem:
        """The same augmented system on the wrapped problem's grid of ``size``; the normalisation
        c is carried over with the problem's linear ``transfer``."""
        from contin.adapt import on_grid

        other = on_grid(self.problem, int(size))
        out = FoldProblem(other, self.second, self.problem.transfer(self.c, other), self.eps)  # type: ignore[attr-defined]
        out.detect_cusps = self.detect_cusps
        out.base_hopf = None if self.base_hopf is None else replace(self.base_hopf, problem=other)
        return out

    def transfer(self, state: Array, other: FoldProblem) -> Array:
        """An augmented vector (u, phi, p2) -- a state, or the first 2n + 1 entries of a tangent --
        carried onto ``other``'s grid: the u and phi blocks with the problem's linear ``transfer``,
        p2 (and anything after it) as it is.  Linear; :meth:`carry` also renormalises phi."""
        n = self.n
        move = self.problem.transfer  # type: ignore[attr-defined]
        state = np.asarray(state, float)
        return np.concatenate([move(state[:n], other.problem), move(state[n:2 * n], other.problem), state[2 * n:]])

    def carry(self, state: Array, tangent: Array, other: FoldProblem) -> tuple[Array, Array]:
        """A point (u, phi, p2) and its tangent (du, dphi, dp2, dp1) carried onto ``other``'s grid:
        :meth:`transfer`, then phi scaled so that other.c . phi = 1 (the system's normalisation)
        and dphi by the same factor, minus its component that would change c . phi."""
        x = self.transfer(state, other)
        t = self.transfer(tangent, other)
        m = other.n
        scale = 1.0 / float(other.c @ x[m:2 * m])
        x[m:2 * m] *= scale
        t[m:2 * m] *= scale
        t[m:2 * m] -= float(other.c @ t[m:2 * m]) * x[m:2 * m]
        return x, t

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
    fold = _fold_at(fold, branch, i)
    n = fold.n
    first = branch.parameter
    swapped = FoldProblem(fold.problem, first, fold.c, fold.eps)
    row = branch.state(i)
    u_phi = row[: 2 * n]
    start = np.concatenate([u_phi, [branch.params[first][i]]])
    params = {k: float(v[i]) for k, v in branch.params.items()}
    params[fold.second] = float(row[2 * n])
    direction = 1.0 if branch.tangent(i)[2 * n] > 0 else -1.0
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
        bracket=(float(branch.state(i)[-1]), float(branch.state(i + 1)[-1])),
        converged=lp.converged,
        note=f"extremum of {fold.second}",
        grid=branch.grid_at(i),
    )


def _fold_at(fold: FoldProblem, branch: Branch, i: int) -> FoldProblem:
    """``fold`` on the grid of point ``i`` (a curve regridded segment-wise keeps per-point grids)."""
    g = branch.grid_at(i)
    if g is None or fold.grid_size is None or int(fold.grid_size) == g:
        return fold
    return fold.with_grid(g)


def _second_column(branch: Branch, tangents: bool = False) -> Array:
    """p2 (the last state entry) of every point of a raw augmented branch, or its tangent component."""
    if branch.sizes is None:
        return (branch.tangents if tangents else branch.states)[:, branch.states.shape[1] - 1].copy()
    return np.array([(branch.tangent(i) if tangents else branch.state(i))[int(branch.sizes[i]) - 1]
                     for i in range(len(branch))], dtype=float)


def _extrema(branch: Branch, fold: FoldProblem, options: ContinuationOptions) -> list[SpecialPoint]:
    """Extrema of p2 along a fold curve (sign changes of its tangent component), located."""
    t = _second_column(branch, tangents=True)
    out = []
    for i in np.nonzero(np.sign(t[:-1]) * np.sign(t[1:]) < 0)[0]:
        with deferred():  # each located in full: a Ctrl-C here dropped it from a curve stored as finished
            point = _locate_extremum(fold, branch, int(i), options)
        if point is not None:
            out.append(point)
    return out


def as_fold_curve(branch: Branch, fold: FoldProblem, options: ContinuationOptions | None = None) -> Branch:
    """Turn a traced augmented branch into a fold curve: p2 as a parameter column, base states,
    and ``XT`` special points at the extrema of p2."""
    params = dict(branch.params)
    params[fold.second] = _second_column(branch)
    observables = {k: v for k, v in branch.observables.items() if k != fold.second}
    out = replace(
        branch,
        free=(branch.parameter, fold.second),
        params=params,
        observables=observables,
        kind="fold-curve",
    )
    specials = [
        replace(sp_, params={**sp_.params, fold.second: float(sp_.state[-1])}, note=sp_.note or f"extremum of {branch.parameter}")
        if sp_.type == "LP"
        else replace(sp_, params={**sp_.params, fold.second: float(sp_.state[-1])})
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
    regrid: SegmentRegrid | None = None,
) -> Branch:
    """Continue the fold ``point`` in (parameter, second); both directions joined.

    ``parameter`` defaults to the first parameter that varies at the fold (the caller's
    continuation parameter); the tracer's BP detection is switched off because the
    augmented system's own singularities are not branch points of the original problem.
    Returns a fold-curve :class:`Branch` (``kind='fold-curve'``) with ``XT`` points at the
    extrema of ``second`` and ``LP`` points at the extrema of ``parameter``.

    ``regrid`` (:class:`SegmentRegrid`, for a problem with the grid hooks ``grid_size``,
    ``with_grid``, ``transfer``): where the resolution guard stops the curve, it continues on a
    finer grid from its last accepted point (each direction on its own) instead of ending MX;
    the curve's ``grid`` column then holds each point's grid and its audit the grid changes.
    """
    if parameter is None:
        raise ValueError("trace_fold_curve needs the name of the first continuation parameter")
    fold, start = fold_start(problem, point, second)
    fold.base_hopf = hopf_test(problem, options.detection, fold.n)
    raw = trace_augmented(fold, start, point, second, 2 * fold.n, options, parameter=parameter, both=both,
                          branch_id=branch_id, kind="fold-curve", regrid=regrid)
    return as_fold_curve(raw, fold, replace(options, detection=replace(options.detection, detect_branch_points=False)))


@dataclass(frozen=True)
class SegmentRegrid:
    """Segment-wise regridding of an augmented two-parameter curve (:func:`trace_augmented`).

    When the resolution guard (``ContinuationOptions.resolution_tol``, the problem's
    ``under_resolved``) stops a half of the curve at its last accepted point on grid N, that
    point and its tangent are carried onto a finer grid (the augmented system's ``with_grid`` /
    ``carry``: the state and null-vector blocks with the problem's linear ``transfer``, the
    parameters as they are, the null vector renormalised), corrected there on the
    pseudo-arclength hyperplane of the carried tangent, and the half continues from there in the
    same direction: one curve whose points keep the grid they were computed on
    (``Branch.grid``), with the grid changes in its audit.  The part before the stop is kept as
    computed (it met the guard there).

    Every point of the curve also passes the two-grid check of its augmented solve
    (:func:`augmented_two_grid_error`; ``opts.check_factor``, ``opts.check_above`` and ``opts.tol``,
    as for adaptive traces; check_factor None switches it off): a point that misses tol there ends
    its segment as the guard's stop does and is recomputed on a finer grid (:func:`_trace_half`).

    opts : growth, multiple and max_grid of the next grid (:func:`contin.adapt.finer`); tol,
        check_factor and check_above of the two-grid check
    suggest : optional ``suggest(problem, u, params) -> grid size`` for the stopped point (u and
        params of the wrapped problem); the next grid is the larger of it and the growth step
    """

    opts: AdaptOptions
    suggest: Callable[[Any, Array, Mapping[str, float]], float | None] | None = None

    def next_grid(self, problem: Any, u: Array, params: Mapping[str, float]) -> int | None:
        """The grid after ``problem``'s for a curve stopped at (u, params); None past max_grid."""
        from contin.adapt import _round, finer

        size = finer(problem, u, params, self.opts)
        if size is None:
            return None
        if self.suggest is not None:
            want = self.suggest(problem, u, params)
            if want is not None and math.isfinite(float(want)):
                size = min(max(size, _round(float(want), self.opts.multiple)), self.opts.max_grid)
        return size


def augmented_two_grid_error(augmented: Any, state: Array, tangent: Array, params: Mapping[str, float],
                             parameter: str, theta: float, opts: AdaptOptions) -> tuple[float, int] | None:
    """Two-grid error of a point of an augmented two-parameter curve (the analogue of
    :func:`contin.adapt.two_grid_error` for a regridded fold curve): the point (state U = (u, phi,
    p2), ``params[parameter]`` = p1) and its tangent (dU, dp1) are carried onto the check grid
    (``check_factor`` times finer, :func:`contin.adapt.check_grid`) as :meth:`FoldProblem.carry`
    does, and one Newton correction of the whole augmented system is done there, bordered by the
    pseudo-arclength row of the carried tangent (the corrector's hyperplane; fixing p1 instead
    would be singular where the curve turns in p1):

        [G_U  G_p1] [dU ]   [-G(V, p1)]
        [  t . ·  ] [dp1] = [    0    ]

    The error is the largest of the state's relative error ||du|| / ||v + du|| in the wrapped
    problem's ``solution_error`` norm (:func:`contin.adapt.solution_error`; relative max-norm
    without the hook) and the relative changes |dp| / max(|p + dp|, PARAM_SCALE_FLOOR) of both
    parameters.  The null vector's change is not measured (as the guard does not estimate it):
    it enters through its effect on u and the parameters.

    Returns (error, check grid), None when the check grid rounds to the point's grid; the error
    is inf where the bordered Jacobian is singular or the correction is not finite.
    """
    from contin.adapt import check_grid, richardson, solution_error
    from contin.extended import ExtendedSystem
    from contin.linalg import factorize_bordered

    factor = opts.check_factor
    if factor is None:
        return None
    n_f = check_grid(augmented.problem, factor, opts)
    if n_f is None:
        return None
    fine = augmented.with_grid(n_f)
    x_f, t_f = augmented.carry(np.asarray(state, float), np.asarray(tangent, float)[:-1], fine)
    system = ExtendedSystem(fine, params, parameter, theta)
    system.n = x_f.size
    big = system.pack(x_f, float(params[parameter]))
    row = system.row(system.pack(t_f, float(tangent[-1])))
    with np.errstate(all="ignore"):
        jac, fp = system.jacobian(big)
        fact = factorize_bordered(jac, fp, row)
        if fact is None:
            return math.inf, n_f
        delta = fact.solve(np.concatenate([-system.residual(big), [0.0]]))
    if not np.all(np.isfinite(delta)):
        return math.inf, n_f
    m = fine.n
    u, du = x_f[:m], delta[:m]
    q = {**system.params_at(big[-1]), fine.second: float(big[-2])}
    errors = [solution_error(fine.problem, u, u + du, q)]
    for j in (-2, -1):  # p2 (the last state entry), p1
        errors.append(abs(float(delta[j])) / max(abs(float(big[j] + delta[j])), PARAM_SCALE_FLOOR))
    e = richardson(augmented.problem, n_f) * max(errors)
    return (e if math.isfinite(e) else math.inf), n_f


@dataclass
class _Checks:
    """The two-grid checks of one regridded curve (:func:`trace_augmented`): how many points were
    checked, the worst error among the accepted ones and how many were refused."""

    opts: AdaptOptions
    count: int = 0
    worst: float = 0.0
    refused: int = 0

    @property
    def on(self) -> bool:
        return self.opts.check_factor is not None and self.opts.solve_check

    def first_failure(self, aug: Any, seg: Branch, parameter: str, second: str,
                      theta: float, start: int = 0, stop: int | None = None) -> tuple[int, str] | None:
        """Check the points start .. stop - 1 of ``seg`` (one grid) in order: (index, reason) of
        the first whose two-grid error exceeds tol, else None.  Points whose guard estimate is at
        most check_above x tol are not checked on grids where the estimate decides that
        (:func:`contin.adapt.estimate_decides_check`; as :meth:`contin.adapt.Adaptor.solve_check`)."""
        from contin.adapt import estimate_decides_check, state_error

        tol = self.opts.tol
        n = int(aug.n)
        count, worst, where, n_f = 0, 0.0, None, None
        for i in range(start, len(seg) if stop is None else min(stop, len(seg))):
            try:
                x = seg.state(i)
            except KeyError:  # not saved (save_every): nothing to check
                continue
            t = seg.tangent(i)
            params = {k: float(v[i]) for k, v in seg.params.items()}
            q = {**params, second: float(x[-1])}
            if has(aug.problem, "error_estimate") and estimate_decides_check(aug.problem) and \
                    state_error(aug.problem, x[:n], q) <= self.opts.check_above * tol:
                continue
            out = augmented_two_grid_error(aug, x, t, params, parameter, theta, self.opts)
            if out is None:
                continue
            e, n_f = out
            count += 1
            self.count += 1
            if e > tol:
                self.refused += 1
                self.worst = max(self.worst, worst)
                self._line(seg, aug, count - 1, worst, where, n_f, parameter)
                reason = (f"under-resolved at {parameter} = {params[parameter]:.6g}: two-grid error {e:.2g} of the "
                          f"augmented solve > tol {tol:.2g} (check on grid {n_f}; {second} = {x[-1]:.6g})")
                seg.audit.append(f"two-grid check: {reason}")
                return i, reason
            if e >= worst:
                worst, where = e, params[parameter]
        self.worst = max(self.worst, worst)
        self._line(seg, aug, count, worst, where, n_f, parameter)
        return None

    @staticmethod
    def _line(seg: Branch, aug: Any, count: int, worst: float, where: float | None, n_f: int | None,
              parameter: str) -> None:
        if count:
            seg.audit.append(f"two-grid check on grid {int(aug.grid_size)} (check grid {n_f}): {count} points "
                             f"passed, worst error {worst:.2g} (at {parameter} = {where:.6g})")

    def summary(self) -> str:
        if not self.on:
            return ("two-grid check of the augmented solve: off ("
                    + ("check_factor None)" if self.opts.check_factor is None else "solve_check False)"))
        return (f"two-grid check of the augmented solve: {self.count} checks, worst accepted error {self.worst:.2g} "
                f"(tol {self.opts.tol:.2g}), {self.refused} points refused on their grid (recomputed on a finer one, or "
                f"past max_grid the curve ends before them)")


def _head(branch: Branch, k: int, message: str) -> Branch:
    """Points 0..k of a one-grid ``branch`` (special points before k kept), ending MX at k with
    ``message`` (an under-resolved stop, which :func:`_trace_half` continues on a finer grid)."""
    from contin.overlap import params_at, slice_branch

    end = SpecialPoint(type="MX", index=k, params=params_at(branch, k), order_parameter=float(branch.order_parameter[k]),
                       state=np.array(branch.state(k), float), tangent=np.array(branch.tangent(k), float), note=message,
                       grid=branch.grid_at(k))
    out = slice_branch(branch, 0, k)
    out.special_points = [s for s in out.special_points if s.index < k and s.type not in ("EP", "MX")] + [end]
    out.status, out.message, out.closed, out.audit = "MX", message, False, list(branch.audit)
    return out


def _chain(first: Branch, second: Branch) -> Branch:
    """One half from two segments traced in the same direction: ``second`` starts at ``first``'s
    last point (carried onto a finer grid), which replaces it; ``first``'s end (EP/MX) is dropped.
    Status and message are ``second``'s."""
    from contin.jumps import concat

    end = len(first) - 1
    head = replace(first, special_points=[s for s in first.special_points
                                          if not (s.type in ("EP", "MX") and s.index >= end)])
    out = concat(head, second)
    out.status = second.status
    out.audit = list(first.audit) + list(second.audit)
    return out


def trace_augmented(augmented: object, start: Array, point: SpecialPoint, second: str, index: int,
                    options: ContinuationOptions, *, parameter: str, both: bool, branch_id: str, kind: str,
                    mirror_start: bool = False, regrid: SegmentRegrid | None = None) -> Branch:
    """Trace an augmented two-parameter system (fold or BP curve) whose state holds the second
    parameter at ``index``, in ``parameter``, both directions joined.

    BP detection of the augmented system is off (its singularities are not the problem's).
    Bounds on ``second`` in ``options.bounds`` are honoured: the tracer lands on bounds of the
    continuation parameter only, so each half is cut at the located crossing of the bound (a
    UZ event, as for Hopf curves: ``contin.hopfcurve``) and ends there with EP.

    ``mirror_start``: the second half starts with minus the first half's start tangent instead of
    the tracer's own choice from the sign of d parameter/ds (needed at a cusp, where the parameter
    is extremal and that sign cannot tell the halves apart: :mod:`contin.twoparam`).

    ``regrid`` (:class:`SegmentRegrid`; the augmented system needs ``grid_size``, ``with_grid``,
    ``carry`` and ``problem``, as :class:`FoldProblem` has, and ``index`` must be its last state
    entry): a half that the resolution guard stops continues on a finer grid from its last
    accepted point, each half on its own; every point of the result has its grid in ``grid``.
    """
    lo, hi = options.bounds.get(second, (-math.inf, math.inf))
    p2 = float(point.params[second])
    if not lo <= p2 <= hi:
        raise ValueError(f"start value {second}={p2:g} lies outside its bounds ({lo:g}, {hi:g})")
    opts = replace(options, detection=replace(options.detection, detect_branch_points=False),
                   bounds={k: v for k, v in options.bounds.items() if k != second})
    if regrid is not None and index != len(start) - 1:
        raise ValueError("segment-wise regridding needs the second parameter as the last state entry")
    halves: list[Branch] = []
    checks = None if regrid is None else _Checks(regrid.opts)
    first: list[Array] = []  # the first half's start tangent on the start grid (before any regridding)
    for direction in ((1, -1) if both else (1,)):
        tangent = first[0] if mirror_start and first else None
        half = _trace_half(augmented, start, point, second, index, opts, lo, hi, parameter=parameter,
                           direction=direction, tangent=tangent, branch_id=branch_id, kind=kind, regrid=regrid,
                           checks=checks, start_tangent=first)
        halves.append(half)
        # nothing to mirror without a start tangent; a first half of the start point alone (it starts on a
        # bound of `second` and leaves through it, cut there) still has one (qa15: it ended the curve)
        if half.closed or (mirror_start and not first):
            break
    from contin.continuation import join

    out = halves[0] if len(halves) == 1 else join(halves[1], halves[0])
    if checks is not None:
        out.audit.append(checks.summary())
    return out


def _trace_half(augmented: Any, start: Array, point: SpecialPoint, second: str, index: int,
                opts: ContinuationOptions, lo: float, hi: float, *, parameter: str, direction: int,
                tangent: Array | None, branch_id: str, kind: str, regrid: SegmentRegrid | None,
                checks: _Checks | None = None, start_tangent: list[Array] | None = None) -> Branch:
    """One half of :func:`trace_augmented`: a trace, and with ``regrid`` its continuations on
    finer grids while the resolution guard stops it.

    With ``regrid`` and ``checks`` on (``AdaptOptions.check_factor``), every point of a segment
    also passes the two-grid check of its augmented solve (:func:`augmented_two_grid_error`, run
    on the traced segment in order): at the first point that fails it the segment ends (MX,
    under-resolved) and that point is carried onto a finer grid and corrected there, as the
    guard's stop carries its last point; a carried start point that fails is carried onto a finer
    grid still.  A point no grid up to max_grid passes is dropped (the half ends MX at the point
    before it).  ``start_tangent`` (a list) receives the first segment's start tangent."""
    from contin.adapt import under_resolved_stop
    from contin.continuation import trace
    from contin.corrector import correct
    from contin.extended import ExtendedSystem
    from contin.hopfcurve import _cut_at_bound, _second_bound_event

    bounded = math.isfinite(lo) or math.isfinite(hi)

    def run(aug: Any, x0: Array, params: Mapping[str, float], o: ContinuationOptions, d: int,
            t: Array | None) -> Branch:
        idx = len(x0) - 1 if regrid is not None else index
        ends = _second_bound_event(aug, second, lo, hi, index=idx) if bounded else {}
        if bounded:
            o = replace(o, events={**o.events, **ends})
        seg = trace(aug, x0, dict(params), parameter, o, direction=d, tangent=t, branch_id=branch_id, kind=kind,
                    parent=f"{point.name}", stop_events=tuple(ends))
        seg = _cut_at_bound(seg, aug, second, lo, hi, index=idx) if bounded else seg
        if regrid is not None:
            size = int(aug.grid_size)
            seg.grid = np.full(len(seg), size, dtype=np.int64)
            seg.special_points = [replace(s, grid=size) for s in seg.special_points]
        return seg

    def checked(aug: Any, x0: Array, params: Mapping[str, float], o: ContinuationOptions, d: int,
                t: Array | None) -> tuple[Branch, int | None]:
        """:func:`run`, up to its first point that fails the two-grid check (MX there), and that
        index.  The start point is checked first, on a one-step trace, so that a start that
        fails costs no whole segment."""
        if checks is None or not checks.on:
            return run(aug, x0, params, o, d, t), None
        probe = run(aug, x0, params, replace(o, max_steps=1), d, t)
        if len(probe) == 0:
            return probe, None
        failure = checks.first_failure(aug, probe, parameter, second, opts.step.theta, stop=1)
        if failure is not None:
            return _head(probe, 0, failure[1]), 0
        seg = probe if o.max_steps <= 1 else run(aug, x0, params, o, d, t)
        failure = checks.first_failure(aug, seg, parameter, second, opts.step.theta, start=1) if len(seg) > 1 else None
        if failure is None:
            return seg, None
        k, reason = failure
        return _head(seg, k, reason), k

    if regrid is None:
        half = run(augmented, start, point.params, opts, direction, tangent)
    else:
        half, k = checked(augmented, start, point.params, opts, direction, tangent)
    if start_tangent is not None and not start_tangent and len(half) > 0:
        start_tangent.append(np.array(half.tangent(0), float))
    if regrid is None:
        return half
    failed = k is not None  # the half's last point failed its two-grid check
    aug = augmented
    while under_resolved_stop(half) and len(half) >= 1 and not half.closed:
        last = len(half) - 1
        x_last, t_last = half.state(last), half.tangent(last)
        params = {k: float(v[last]) for k, v in half.params.items()}
        q = {**params, second: float(x_last[-1])}
        size = regrid.next_grid(aug.problem, x_last[: int(aug.n)], q)
        seg, other = None, aug
        while size is not None:
            other = aug.with_grid(size)
            x, t = aug.carry(x_last, t_last[:-1], other)
            system = ExtendedSystem(other, params, parameter, opts.step.theta)
            system.n = x.size
            tt = system.unit(system.pack(t, float(t_last[-1])))
            corr = correct(system, system.pack(x, params[parameter]), system.row(tt), opts.newton)
            if not corr.converged or system.admissible(corr.x) is not None:
                half.audit.append(f"{kind} not continued on grid {size} from {parameter} = {params[parameter]:.6g}: "
                                  f"the carried point did not converge there ({corr.message})")
                break
            budget = opts.max_steps - int(np.sum(half.ds > 0))
            if budget <= 0:
                break
            ds = min(max(abs(float(half.ds[-1])), abs(opts.step.ds)), opts.step.ds_max)
            o = replace(opts, max_steps=budget, step=replace(opts.step, ds=ds))
            line = (f"grid {int(aug.grid_size)} -> {size} at {parameter} = {corr.x[-1]:.6g}, {second} = "
                    f"{corr.x[-2]:.6g}: {half.message}")
            seg, k = checked(other, corr.x[:-1], {**params, parameter: float(corr.x[-1])}, o, +1, tt)
            if len(seg) > 0 and k != 0:
                seg.audit.insert(0, line)
                break
            # the carried point itself is under-resolved on this grid (its start check, or its
            # two-grid check): finer still
            if k == 0:
                half.audit.append(f"{kind} not continued on grid {size}: {seg.message}")
            seg = None
            size = regrid.next_grid(other.problem, corr.x[: other.n], {**q, parameter: float(corr.x[-1])})
        if seg is None:
            break
        half = _chain(half, seg)
        failed = k is not None
        aug = other
    if failed and len(half) >= 2:
        # the last point failed its two-grid check and no finer grid took it: the half ends at
        # the point before it (every stored point passed)
        half = _head(half, len(half) - 2, f"{half.message}; no finer grid (max_grid "
                                          f"{regrid.opts.max_grid}) resolves it: the curve ends at the point before")
    return half
