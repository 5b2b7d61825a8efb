"""Keller pseudo-arclength continuation with fold and branch-point detection.

Public entry points (the front door of contin's core):

- :func:`newton` -- Newton at fixed parameters (re-exported from ``contin.newton``);
- :func:`trace` -- one branch in one direction from a (possibly unconverged) start;
- :func:`trace_both` -- both directions, joined into one branch through the start point;
- :func:`switch` -- branch switching at a simple BP (first points from ``contin.switching``).

Algorithm of :func:`trace` (Keller 1977; Seydel 2010, ch. 4; AUTO-07p; BifurcationKit PALC):
unknowns x = (u, p); predictor x_k + ds t_k (tangent) or along the secant; bordered Newton
corrector (``contin.corrector``) factorizing [[J, F_p], [c^T]] once per iteration; the last
factorization gives the new tangent and the test functions (``contin.testfunctions``); sign
changes are located (``contin.locate``) by re-correcting at intermediate arclengths.  Steps
are rejected (ds halved) on corrector failure, inadmissible states or a tangent turning by
more than ``max_angle``; at ds_min a failure ends the run with MX.  Parameter bounds end the
run with EP exactly at the bound, and a branch that returns to its start is closed
(``contin.closure``).  A converged point the problem reports as under-resolved (optional
``under_resolved(u, p, tol)``, ``ContinuationOptions.resolution_tol``) ends the run with MX
without being stored: a smaller step cannot help, the grid must be refined.  A step across
which a BP test function changes sign without a BP that its location confirms is checked by
two half steps; if they end elsewhere, the step jumped onto a nearby branch and is retried
with half the ds (``DetectionOptions.retry_unconfirmed_bp``; logged in ``Branch.audit``).
With ``ContinuationOptions.adapt`` the grid is chosen and changed along the branch instead
(``contin.adapt``: start grid, refinement of the last accepted point and a retried step,
coarsening, relocation of under-resolved special points, MX only past ``max_grid``); every
point records its grid (``Branch.grid``).
"""

from __future__ import annotations

import logging
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.adapt import ACCEPTED_ABOVE_TOL, PRECISION_LIMIT, RESOLUTION_LIMIT, estimate_decides_check
from contin.blas import limited
from contin.bpdetect import EigenCounter, bp_eigen_count, kernel_dimension
from contin.branch import MAX_AUDIT, Branch, SpecialPoint, pad_rows, relabel
from contin.cancel import ENDS_AT_LAST_POINT, stop_reason, stop_requested
from contin.closure import closing_distance, landed
from contin.cloud import special_cloud
from contin.corrector import Correction, correct
from contin.extended import ExtendedSystem
from contin.linalg import factorize_bordered
from contin.locate import Sample, lagrange_state, locate_zero, outside_bracket
from contin.ndbp import nd_departures
from contin.newton import NewtonResult, newton
from contin.options import ContinuationOptions, StepOptions, effective_resolution_tol
from contin.pointtests import PointTest
from contin.pointtestset import point_tests
from contin.predictor import secant, tangent
from contin.problem import Array, has, require_protocol
from contin.rejoin import on_parent
from contin.stepsize import angle, next_step, reduced_step
from contin.switching import departures, first_step_options, prepend
from contin.testfunctions import Antisymmetric, TestValues, bp_value, detrended, sign_change

__all__ = ["NewtonResult", "newton", "relabel", "switch", "trace", "trace_both"]

log = logging.getLogger("contin")


#: Branch-jump protection (DetectionOptions.retry_unconfirmed_bp).  A located BP is confirmed
#: when its test function, scaled to 1 at the larger end of the step, has fallen below
#: BP_VANISH at the located point (a simple BP located to locate_tol leaves ~tol/ds, 1e-7 or
#: less; a sign change from landing on another branch leaves O(1)), and the point lies within
#: OFF_SEGMENT step lengths of the chord of the step (a regular arc within max_angle = 0.3 rad
#: bulges by ~L * angle / 8 = 0.04 L).  An unconfirmed step is a jump when two half steps end
#: more than SAME_POINT step lengths from where the whole step ended (the corrector converges
#: to ~1e-8; separate branches are apart by far more than 1e-3 of a step that can reach both).
BP_VANISH = 1e-3
OFF_SEGMENT = 0.5
SAME_POINT = 1e-3

#: _on_the_bound locates a zero beyond a bound only where the secant of its test function puts it
#: within this fraction of the step (a zero on the bound: ~1e-8; even g ~ s^(1/10) gives < 0.1).
NEAR_BOUND = 0.25

#: A located point whose test value's error puts its zero farther than this (relative to
#: max(1, |p|)) from the located parameter gets a note and a warning (:func:`position_doubt`).
POSITION_DOUBT = 1e-8


#: Appended to a failure at the first point: a wrong Jacobian is the usual cause.
JACOBIAN_HINT = "; check the Jacobian with contin.problem.check_jacobian"

#: Failures that happen before any Jacobian is used: the hint would send the user the wrong way
#: ('initial guess is inadmissible: state has non-finite entries; check the Jacobian ...').
_NOT_THE_JACOBIAN = ("initial guess is inadmissible", "residual is not finite at the initial guess",
                     "the residual or Jacobian raised")


#: Added to the hint for a curve (fold, Hopf: an augmented system with the user's ``problem``
#: inside) of a from_functions problem with difference Jacobians: BifurcationKit's chan (rows
#: ~1e4) stopped at its fold curve's first point with a residual of 6e-8 and the hint alone.
DIFFERENCES_HINT = ("; this curve's system differentiates J again, which central differences "
                    "(from_functions' default) give to ~1e-5: use method='cs' or an exact jacobian")


def _jacobian_hint(reason: str, problem: Any = None) -> str:
    if reason.startswith(_NOT_THE_JACOBIAN):
        return ""
    inner = getattr(problem, "problem", None)
    return JACOBIAN_HINT + (DIFFERENCES_HINT if getattr(inner, "central_differences", False) is True else "")


#: A BP that its location does not confirm: (point, reason, audit line); see _Tracer.detect.
Unconfirmed = tuple[SpecialPoint, str, str]


@dataclass
class _Point:
    x: Array
    t: Array
    tests: TestValues


class _RefineFirst(Exception):
    """Raised by :meth:`_Tracer.detect` when an LP/BP is bracketed on a grid that does not
    resolve its kernel (adaptive runs): the tracer refines and retries the step before locating."""

    def __init__(self, kind: str, error: float) -> None:
        super().__init__(kind)
        self.kind, self.error = kind, error


class _Tracer:
    """State shared by the steps of one trace: system, options, symmetry and the records."""

    def __init__(self, system: ExtendedSystem, options: ContinuationOptions, anti: Antisymmetric | None) -> None:
        self.system = system
        self.options = options
        self.anti = anti
        self.points: list[_Point] = []
        self.ds: list[float] = []
        self.iterations: list[int] = []
        self.records: list[dict[str, float]] = []
        self.special: list[SpecialPoint] = []
        self.audit: list[str] = []
        k = bp_eigen_count(system.problem, options.detection, system.n) if options.detection.detect_branch_points else 0
        self.eigen = EigenCounter(k) if k else None
        self.point_tests: list[PointTest] = []  # HB, UZ (contin.pointtests)
        self.start_zeros: set[str] = set()  # notes of the UZs labelled at the start point (_start_zeros)
        self.grids: list[int | None] = []  # per point: the grid in force (adaptive runs only)
        self.adaptive = False
        # Adaptive runs: (kind, a, b) -> estimate if the kernel of an LP/BP bracketed by a, b is
        # under-resolved on the grid in force (contin.adapt.Adaptor.pre_locate), else None.
        self.pre_locate: Callable[[str, _Point, _Point], float | None] | None = None
        # audit lines of detection gaps (DETECTION_GAP) of the step detect() saw last, and its end
        self._gaps: list[str] = []
        self._gap_point: _Point | None = None

    def use_system(self, system: ExtendedSystem, anti: Antisymmetric | None) -> None:
        """Continue on ``system`` (the problem on another grid, ``contin.adapt``): its symmetry
        helper and its HB/UZ test functions, which are set up per grid."""
        self.system, self.anti = system, anti
        self.point_tests = point_tests(system.problem, system, self.options, system.n)

    @property
    def grid(self) -> int | None:
        """The grid size in force (None unless the run adapts its grid, ``contin.adapt``)."""
        return int(self.system.problem.grid_size) if self.adaptive else None

    # --- point construction ------------------------------------------------------------------
    def finish_point(self, corr: Correction, orient: Array) -> _Point:
        """Tangent and test functions at a corrected point from the corrector's factorization."""
        assert corr.factorization is not None
        x = corr.x
        if self.anti is not None:
            x = self.system.pack(self.anti.symmetrize(x[:-1]), x[-1])
        t = tangent(self.system, corr.factorization, orient)
        bp = bp_value(corr.factorization, corr.row, t)
        anti = None
        if self.anti is not None:  # a dense J when the reduction gathers densely anyway
            dense_ok = self.anti.reduces_densely(x.size - 1)
            anti = self.anti.det(self.system.state_jacobian(x, dense_ok=dense_ok))
        extra = {pt.name: pt.value(self.system, x) for pt in self.point_tests}
        return _Point(x, t, TestValues(float(t[-1]), bp, anti, extra))

    def correct_at(self, x_pred: Array, direction: Array) -> Correction:
        project = self.anti.symmetrize if self.anti is not None else None
        return correct(self.system, x_pred, self.system.row(direction), self.options.newton, project)

    # --- detection and location ----------------------------------------------------------------
    def _test_functions(self) -> list[tuple[str, str, Callable[[TestValues], tuple[float, float] | float]]]:
        det = self.options.detection
        out: list[tuple[str, str, Callable[[TestValues], Any]]] = []
        if det.detect_folds:
            out.append(("LP", "", lambda v: v.fold))
        if det.detect_branch_points:
            if self.anti is not None:
                out.append(("BP", "symmetry-breaking", lambda v: v.anti))
                out.append(("BP", "symmetric", lambda v: v.symmetric_bp))
            else:
                out.append(("BP", "", lambda v: v.bp))
        return out

    def detect(self, a: _Point, b: _Point, index: int,
               near: float | None = None) -> tuple[list[SpecialPoint], list[Unconfirmed]]:
        """Special points in the step from a to b (b is not yet appended; a is point ``index``),
        and the BPs among them that their location does not confirm (point, reason, audit
        line): a sign change of a BP test function without a BP, where the step may have
        jumped onto another branch.  Empty unless ``detection.retry_unconfirmed_bp``.

        Signs are compared by :func:`contin.testfunctions.sign_change`: a test value that is not
        finite at a or b gives no special point and a :data:`DETECTION_GAP` line in the audit.
        A user zero of the continuation parameter crossed twice in one step (the step turned at
        a fold: p - value has the same sign at both ends) is located on both sides of the
        located LP; if the fold was not located, the audit says such zeros may have been skipped.

        ``near`` (a fraction of the step): locate only the zeros that the secant of the (detrended)
        test function puts within that fraction of the step from a (:func:`_on_the_bound`).
        """
        found: list[tuple[float, SpecialPoint]] = []
        unconfirmed: list[Unconfirmed] = []
        sys = self.system
        det = self.options.detection
        s_end = [math.nan]  # <a.t, b.x - a.x>, computed at the first sign change

        def s_of_b() -> float:
            if math.isnan(s_end[0]):
                s_end[0] = sys.dot(a.t, b.x - a.x)
            return s_end[0]

        fold_at: list[tuple[float, _Point]] = []  # (s, point) of an LP located in this step

        def locate_one(kind: str, note: str, fn: Any, point_test: PointTest | None,
                       lo: tuple[float, _Point] | None = None, hi: tuple[float, _Point] | None = None) -> None:
            """Locate the zero of ``fn`` between lo and hi ((s, point); default a and b)."""
            va, vb = fn(a.tests), fn(b.tests)
            if isinstance(va, tuple):
                # (sign, log) with its exponential trend across the step taken out
                # (testfunctions.detrended: an underflow is never a zero)
                trend = detrended(va, vb, s_of_b())

                def g_of(v: TestValues, s: float, fn: Any = fn, trend: Any = trend) -> float:
                    return trend(fn(v), s)
            else:
                def g_of(v: TestValues, s: float, fn: Any = fn) -> float:
                    return float(fn(v))

            lo = lo if lo is not None else (0.0, a)
            hi = hi if hi is not None else (s_of_b(), b)
            sa, sb = Sample(lo[0], g_of(lo[1].tests, lo[0]), lo[1]), Sample(hi[0], g_of(hi[1].tests, hi[0]), hi[1])
            if near is not None and abs(sa.g) > near * abs(sa.g - sb.g):
                return  # the secant's zero lies beyond the fraction ``near`` of the step
            tol = det.locate_tol * max(1.0, abs(b.x[-1]))
            if det.locate and point_test is None and self.pre_locate is not None:
                # Refine before locating rather than locating on a grid that does not resolve
                # the point and again on the finer one (issue 14: 8 -> 16 at gPCF's H_1^c).
                err = self.pre_locate(kind, a, b)
                if err is not None:
                    raise _RefineFirst(kind, err)
            res = None
            if det.locate:

                def evaluate(s: float, g_of: Any = g_of) -> Sample[_Point] | None:
                    corr = self.correct_at(a.x + s * a.t, a.t)
                    if corr.factorization is None and corr.residual_history[-1] <= self.options.newton.tol:
                        # A solution where the bordered matrix is exactly singular: the
                        # trial hit the singular point itself, where g = 0.
                        return Sample(s, 0.0, _Point(corr.x, a.t, a.tests)) if point_test is None else None
                    if not corr.converged or sys.admissible(corr.x) is not None:
                        return None
                    pt = self.finish_point(corr, a.t)
                    g = g_of(pt.tests, s)
                    # a test function that cannot be evaluated there (NaN) counts as a failed trial
                    return Sample(s, g, pt) if math.isfinite(g) else None

                def interpolate(samples: list[Sample[_Point]], s: float) -> _Point:
                    # the branch is smooth through a BP (only the corrector fails next to it)
                    x = lagrange_state(samples, s, lambda p: p.x)
                    return _Point(x, a.t, a.tests)

                res = locate_zero(evaluate, sa, sb, tol=tol, max_iterations=det.max_bisections,
                                  interpolate=interpolate if point_test is None and kind == "BP" else None)
                best, converged, s_best = res.best.point, res.converged, res.best.s
            else:
                best, converged, s_best = hi[1], False, hi[0]
            if kind == "LP" and converged:
                fold_at.append((s_best, best))
            full_note = note
            if not converged:
                full_note = (note + "; " if note else "") + "location did not converge"
            elif kind == "BP":
                # a located BP lies inside its bracket and the bounds, or it is no location
                # (issue 12: Swift-Hohenberg secondary branches stored one outside both)
                outside = outside_bracket(best.x[-1], a.x[-1], b.x[-1], tol, self.options.bounds.get(sys.parameter))
                if outside is not None:
                    converged = False
                    full_note = (note + "; " if note else "") + f"location did not converge ({outside})"
            why = None
            if kind == "BP" and det.locate and det.retry_unconfirmed_bp:
                assert res is not None
                why = "location did not converge" if not converged else self._unconfirmed(a, b, best, res.best.g)
            sp = SpecialPoint(
                type=kind,
                index=index,
                params=sys.params_at(best.x[-1]),
                order_parameter=sys.order_parameter(best.x),
                state=best.x[:-1].copy(),
                # At a BP the kernel of [J F_p] is two-dimensional, so the tangent solved at the
                # located point is an arbitrary mix; the regular neighbours' mean is the branch's.
                tangent=sys.unit(a.t + b.t) if kind == "BP" else best.t.copy(),
                bracket=(float(a.x[-1]), float(b.x[-1])),
                converged=converged,
                note=full_note,
                grid=self.grid,
            )
            if point_test is not None:
                sp = point_test.finish(sys, sp, best.x)
                if converged and hasattr(point_test, "value_error"):
                    sp = position_doubt(sp, point_test.value_error(sys, best.x), sa, sb, sys.parameter,
                                        float(b.x[-1] - a.x[-1]))
            log.info("%s at %s=%.12g (%s)", kind, sys.parameter, best.x[-1], "converged" if converged else "not converged")
            found.append((s_best, sp))
            if why is not None:
                line = f"{note + ' ' if note else ''}BP test function changed sign at {sys.parameter}={best.x[-1]:.10g} but {why}"
                unconfirmed.append((sp, why, line))

        self._gaps, self._gap_point = [], b  # written to the audit if b is appended (append)

        def gap(what: str) -> None:
            line = f"step to point {index + 1}: {sys.parameter}={b.x[-1]:.10g} {DETECTION_GAP}: {what}"
            if line not in self._gaps:
                self._gaps.append(line)

        def not_finite(what: str, va: Any, vb: Any) -> None:
            where = " and ".join(f"point {k} ({sys.parameter}={x[-1]:.10g})"
                                 for k, x, v in ((index, a.x, va), (index + 1, b.x, vb)) if sign_change(v, v) is None)
            gap(f"the {what} test function was not finite at {where}; no special point of it can be "
                f"detected across this step")

        for kind, note, fn in self._test_functions():
            va, vb = fn(a.tests), fn(b.tests)
            changed = sign_change(va, vb)
            if changed is None:
                not_finite(f"{note + ' ' if note else ''}{kind}", va, vb)
            elif changed:
                locate_one(kind, note, fn, None)
        for pt in self.point_tests:
            va, vb = a.tests.extra[pt.name], b.tests.extra[pt.name]
            if any(isinstance(v, numbers.Real) and sign_change(v, v) is None for v in (va, vb)):
                not_finite(f"{pt.kind} {pt.name}", va, vb)
                continue
            for note, g in pt.crossings(va, vb):
                if index == 0 and note in self.start_zeros:  # labelled at the start point (_start_zeros)
                    continue
                locate_one(pt.kind, note, lambda v, g=g, name=pt.name: g(v.extra[name]), pt)
            turning = getattr(pt, "turning_crossings", None)
            if turning is None or sign_change(a.tests.fold, b.tests.fold) is not True:
                continue
            # the step turned at a fold: a value between the ends' and the fold's is crossed twice,
            # p - value has the same sign at both ends (a UZ 1e-8 below bratu's lam* was missed)
            if fold_at and fold_at[0][1].tests is not a.tests:  # (a trial that hit the fold exactly carries a's tests)
                s_f, f_pt = fold_at[0]
                for note, g in turning(va, vb, pt.value(sys, f_pt.x)):
                    fn = (lambda v, g=g, name=pt.name: g(v.extra[name]))
                    locate_one(pt.kind, note, fn, pt, hi=(s_f, f_pt))
                    locate_one(pt.kind, note, fn, pt, lo=(s_f, f_pt))
            else:
                reach = 2.0 * sys.norm(b.x - a.x)
                # (not `near`: that rebinds locate_one's `near` of this step, and the next point test's
                # location failed "can't multiply sequence by non-int of type 'float'")
                skipped = pt.beyond(va, vb, reach) if hasattr(pt, "beyond") else []
                if skipped:
                    gap(f"the step turned at a fold that was not located, so the {pt.kind} values "
                        f"{', '.join(skipped)} beyond both its ends may have been crossed twice and skipped")
        return [sp for _, sp in sorted(found, key=lambda f: f[0])], unconfirmed

    def jumped(self, a: _Point, b: _Point, direction: Array, ds: float) -> str | None:
        """Why the step from a (predictor direction ``direction``, length ds) to b left a's
        branch, or None if two half steps end where it ended (the second half is predicted
        along the half point's own tangent and corrected on b's hyperplane)."""
        sys = self.system
        half = self.correct_at(a.x + 0.5 * ds * direction, direction)
        if not half.converged or sys.admissible(half.x) is not None:
            return f"the half step failed ({half.message or 'inadmissible'})"
        m = self.finish_point(half, direction)
        along = sys.dot(direction, m.t)
        if along <= 0:
            return "the tangent at the half step points backwards"
        rest = ds * sys.dot(direction, direction) - sys.dot(direction, m.x - a.x)
        second = self.correct_at(m.x + (rest / along) * m.t, direction)
        if not second.converged:
            return f"the second half step failed ({second.message})"
        length = sys.norm(b.x - a.x)
        apart = sys.norm(second.x - b.x)
        if apart > SAME_POINT * length:
            return f"two half steps end {apart / length:.2g} step lengths away from it"
        return None

    def _unconfirmed(self, a: _Point, b: _Point, best: _Point, g_best: float) -> str | None:
        """Why a converged BP location between a and b is no BP (None if it is one)."""
        if abs(g_best) > BP_VANISH:  # the detrended test function is +-1 at both ends
            return f"the test function does not vanish there ({abs(g_best):.2g} of its end value)"
        sys = self.system
        seg = b.x - a.x
        length = sys.norm(seg)
        if length > 0:
            w = min(max(sys.dot(best.x - a.x, seg) / length**2, 0.0), 1.0)
            off = sys.norm(best.x - a.x - w * seg)
            if off > OFF_SEGMENT * length:
                return f"the located point lies {off / length:.2g} step lengths off the step"
        return None

    def append(self, pt: _Point, ds: float, iterations: int) -> None:
        if pt is self._gap_point:  # the detection gaps of the step that ends at pt (a rejected step's go)
            self.audit.extend(line for line in self._gaps if line not in self.audit)
            del self.audit[MAX_AUDIT:]
        self._gaps, self._gap_point = [], None
        self.points.append(pt)
        self.ds.append(ds)
        self.iterations.append(iterations)
        self.records.append(self.system.record(pt.x))
        self.grids.append(self.grid)

    def truncate(self, keep: int, last: _Point) -> None:
        """Keep the first ``keep`` points, the last of them replaced by ``last`` (that point
        re-solved on the grid in force), and the special points located before it: a retreat
        (``trace``: a refinement moved a special point behind the last point)."""
        for seq in (self.points, self.ds, self.iterations, self.records, self.grids):
            del seq[keep:]
        self.points[-1] = last
        self.records[-1] = self.system.record(last.x)
        self.grids[-1] = self.grid
        self.special = [sp for sp in self.special if sp.index < keep - 1]

    def end_point(self, type_: str, note: str, x: Array | None = None, t: Array | None = None) -> SpecialPoint:
        sys = self.system
        if x is None:
            last = self.points[-1]
            x, t = last.x, last.t
        return SpecialPoint(
            type=type_,
            index=max(len(self.points) - 1, 0),
            params=sys.params_at(x[-1]),
            order_parameter=sys.order_parameter(x) if self.points else float("nan"),
            state=x[:-1].copy(),
            tangent=None if t is None else t.copy(),
            bracket=(float(x[-1]), float(x[-1])),
            converged=type_ != "MX",
            note=note,
            grid=self.grid,
        )

    def build(self, parameter: str, status: str, message: str, closed: bool, n: int, **meta: Any) -> Branch:
        sys = self.system
        s = len(self.points)
        names = list(dict.fromkeys(k for r in self.records for k in r))
        obs = {k: np.array([r.get(k, np.nan) for r in self.records], dtype=float) for k in names}
        params = {k: np.full(s, v, dtype=float) for k, v in sys.params.items()}
        params[parameter] = np.array([p.x[-1] for p in self.points], dtype=float)
        every = self.options.save_every
        keep = np.arange(s)
        state_index = None
        if every > 1 and s:
            keep = np.unique(np.concatenate([np.arange(0, s, every), [s - 1]]))
            state_index = keep
        if self.adaptive and s:  # states of several sizes: NaN-padded rows (contin.branch.pad_rows)
            states = pad_rows([self.points[i].x[:-1] for i in keep])
            tangents = pad_rows([p.t for p in self.points])
            meta["grid"] = np.array(self.grids, dtype=np.int64)
            meta["sizes"] = np.array([p.x.size - 1 for p in self.points], dtype=np.int64)
        else:
            states = np.array([self.points[i].x[:-1] for i in keep], dtype=float).reshape(len(keep), n)
            tangents = np.array([p.t for p in self.points], dtype=float).reshape(s, n + 1)
        return _labelled(Branch(
            parameter=parameter,
            free=(parameter,),
            params=params,
            observables=obs,
            states=states,
            tangents=tangents,
            ds=np.array(self.ds, dtype=float),
            newton_iterations=np.array(self.iterations, dtype=np.int64),
            special_points=list(self.special),
            status=status,
            message=message,
            closed=closed,
            audit=self.audit,
            state_index=state_index,
            **meta,
        ))


#: Largest :meth:`Antisymmetric.equivariance_defect` of a problem whose symmetry is one at the
#: start point (rounding and finite-difference Jacobians stay far below; a symmetry that holds
#: only at other parameters is far above: stretched Bratu at a = 0.5 on cheb 24, 1e-2).
EQUIVARIANCE_TOL = 1e-6


def _symmetry(problem: Any, u: Array, symmetric: bool | None,
              params: Mapping[str, float] | None = None, parameter: str | None = None) -> Antisymmetric | None:
    """The antisymmetric-subspace helper if the branch is to be treated as S-invariant.

    With ``params`` and ``parameter``: S must also be a symmetry of F there (J and F_p
    equivariant at the invariant start state, :meth:`Antisymmetric.equivariance_defect`); a
    problem's ``symmetry`` that holds only at other parameters symmetrized every Newton iterate
    of the branch, and no step converged (ValueError when ``symmetric=True``, else None)."""
    if symmetric is False:
        return None
    anti = Antisymmetric.from_problem(problem, u.size)
    if anti is None:
        if symmetric:
            raise ValueError("symmetric=True but the problem provides no symmetry")
        return None
    invariant = anti.is_invariant(u)
    if symmetric and not invariant:
        raise ValueError("symmetric=True but the start state is not invariant under the problem's symmetry")
    if not invariant or anti.dimension == 0:
        return None
    if params is not None and parameter is not None:
        with np.errstate(all="ignore"):
            defect = anti.equivariance_defect(problem.jacobian(u, params), problem.dresidual_dp(u, params, parameter))
        if not defect <= EQUIVARIANCE_TOL:
            if symmetric:
                raise ValueError(f"symmetric=True but the problem's symmetry is not one of F at these parameters "
                                 f"(relative defect {defect:.2g} of J or dF/d{parameter})")
            log.info("symmetry not used: F is not equivariant at the start (defect %.2g)", defect)
            return None
    return anti


def _under_resolved(problem: Any, system: ExtendedSystem, x: Array, tol: float | None) -> str | None:
    """The problem's reason why the converged point x = (u, p) is not resolved by its grid, or None.

    None also when the guard is off (tol None) or the problem has no ``under_resolved`` hook.
    """
    if tol is None or not has(problem, "under_resolved"):
        return None
    reason = problem.under_resolved(x[:-1], system.params_at(x[-1]), tol)
    if reason is None:
        return None
    if reason.startswith(PRECISION_LIMIT + ": "):  # rounding, not the grid: a finer grid only raises it
        return f"{PRECISION_LIMIT} at {system.parameter} = {x[-1]:.6g}: {reason[len(PRECISION_LIMIT) + 2:]}"
    return f"under-resolved at {system.parameter} = {x[-1]:.6g}: {reason}"



#: Marks an audit line of a step across which a special point may have been missed (a test
#: function not finite at one end, a user zero crossed twice next to a fold that was not
#: located); the command line shows these lines as warnings (``contin.cli.trace``).
DETECTION_GAP = "detection gap"

#: The audit line of an FD branch whose check grid's test functions disagree with the special
#: points located on it (``trace``'s missed_crossings); the command line shows it as a warning.
MISSED_SPECIAL = "a special point may be missed"

#: Stored points a retreat re-solves on the finer grid at most (``trace``'s retreat_behind).
MAX_RETREAT = 20


def _sign_changed(a: Any, b: Any) -> bool:
    """Whether two values of a test function (a float, or a (sign, log) pair) have opposite,
    nonzero signs (:func:`contin.testfunctions.sign_change`; a value that is not finite is no
    change here, and ``_Tracer.detect`` says so in the audit)."""
    return sign_change(a, b) is True


def _guard_status(message: str) -> str:
    """The status a resolution stop (the fixed-grid guard's or adaptive refinement's) ends a branch
    with: EP at a precision limit (every stored point meets tol; a finer grid would only raise the
    rounding) or a resolution limit (every stored point meets tol; the estimate falls so slowly on
    the maximum grid that tol needs a grid far beyond it, ``contin.adapt``), MX when the grid does
    not resolve the branch."""
    return "EP" if message.startswith((PRECISION_LIMIT, RESOLUTION_LIMIT)) else "MX"


def _check_bounds(problem: Any, options: ContinuationOptions, parameter: str, p0: float) -> tuple[float, float]:
    for name in options.bounds:
        if name not in problem.parameter_names:
            raise ValueError(f"bounds given for unknown parameter {name!r}; the problem has {', '.join(problem.parameter_names)}")
    lo, hi = options.bounds.get(parameter, (-math.inf, math.inf))
    if not lo <= p0 <= hi:
        raise ValueError(f"start value {parameter}={p0:g} lies outside its bounds ({lo:g}, {hi:g})")
    return float(lo), float(hi)


def start_state(u0: Any) -> Array:
    """``u0`` as a flat float array; TypeError naming it for text, None or complex values.

    ``np.array(u0, dtype=float)`` dropped the imaginary part of a complex start with only a
    ComplexWarning (the trace then ran from another state) and failed on text with numpy's
    'could not convert string to float' (session 14)."""
    arr = np.asarray(u0)
    if arr.dtype.kind == "c":
        if np.any(arr.imag != 0):
            raise TypeError("u0 (the start state) must be real, got complex values with nonzero imaginary parts")
        arr = arr.real
    elif arr.dtype.kind not in "biufO" or u0 is None:
        raise TypeError(f"u0 (the start state) must be an array of real numbers, got {type(u0).__name__} "
                        f"(dtype {arr.dtype})")
    try:
        return np.array(arr, dtype=float).ravel()
    except (TypeError, ValueError) as exc:  # an object array holding text or None
        raise TypeError(f"u0 (the start state) must be an array of real numbers ({exc})") from None


@limited(lambda problem, u0, *args, **kwargs: np.size(u0))  # one BLAS thread on small problems (contin.blas)
def trace(
    problem: Any,
    u0: Array,
    params: Mapping[str, float],
    parameter: str,
    options: ContinuationOptions = ContinuationOptions(),
    *,
    direction: int = +1,
    tangent: Array | None = None,
    branch_id: str = "0",
    kind: str = "primary",
    parent: str = "",
    symmetric: bool | None = None,
    progress: Callable[[str], None] | None = None,
    stop_events: tuple[str, ...] = (),
) -> Branch:
    """Trace one branch of F(u, p) = 0 in ``parameter`` by pseudo-arclength continuation.

    Parameters
    ----------
    problem : Problem
        See ``contin.problem``.  Optional ``admissible(u, p) -> str | None`` restricts states
        to a physical domain; optional ``under_resolved(u, p, tol) -> str | None`` ends the
        run (MX, point not stored) where the grid no longer resolves the state; optional
        ``symmetry``/``symmetry_matrix`` enables the symmetry-breaking BP test on
        S-invariant branches.
    u0 : (n,) array
        Start guess; it is first corrected by Newton at fixed parameters.
    params : dict
        All parameter values (the continuation parameter's value is the start value).
    parameter : str
        The continuation parameter.
    options : ContinuationOptions
        Its resolution_tol is replaced inside a ``contin.options.resolution_override`` block
        (the command line's ``--resolution-tol``).
    direction : +1 or -1
        Initial direction: sign(options.step.ds) * direction is the sign of dp/ds at the
        start, or, with ``tangent`` given, the start tangent is ``direction * tangent``.
    tangent : (n+1,) array, optional
        Approximate start tangent in (u, p) (e.g. from branch switching).
    branch_id, kind, parent : labels stored on the Branch.
    symmetric : bool or None
        Treat the branch as S-invariant (None: decide from the start state).
    progress : callable, optional
        Receives short status lines.
    stop_events : names of ``options.events``
        The run ends (EP) after the step in which one of them is located: the bounds of the
        second parameter of two-parameter curves (``contin.hopfcurve._second_bound_event``),
        whose callers cut the branch there (the halves ran on to max_steps beyond the bound:
        AUTO's abc fold curve, 59 points kept of ~2100 corrected, 9.4 s).

    Returns
    -------
    Branch
        status 'EP' (bound, max_steps, closed loop) or 'MX' (failure, or a converged point
        under-resolved by the grid: 'under-resolved at p = ...: <problem's reason>'), with the
        reason in ``message`` and in the note of the final EP/MX special point.  Never raises for a
        failed Newton step; raises ValueError for invalid input.
    """
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}")
    require_protocol(problem)
    if not isinstance(options, ContinuationOptions):  # a dict met "'dict' object has no attribute 'step'"
        raise TypeError(f"options must be a ContinuationOptions, got {type(options).__name__}")
    sopt = options.step
    system = ExtendedSystem(problem, params, parameter, sopt.theta)
    u0 = start_state(u0)
    entry = (problem, u0)  # (a retrace on a finer smallest grid starts here: missed_crossings)
    try:
        # Only the shape is checked here; a non-finite residual (inf/nan from a division by zero at
        # extreme parameters) is the start point's Newton failure below, in one line, so numpy's
        # RuntimeWarnings would only repeat it on stderr (qa14: nonlocal-cylinder -s W=1e-300).
        with np.errstate(all="ignore"):
            f0 = np.asarray(problem.residual(u0, system.params), dtype=float)
    except ValueError as exc:
        raise ValueError(f"start state with {u0.size} entries does not fit the problem ({exc})") from None
    except ArithmeticError as exc:  # Python-float arithmetic of a problem (W**2 at W = 1e300)
        raise ValueError(f"the residual cannot be evaluated at the start point ({type(exc).__name__}: {exc}): "
                         f"a parameter is out of the problem's range") from None
    if f0.shape != u0.shape:
        raise ValueError(f"start state has {u0.size} entries but the residual has {f0.size}")
    n = u0.size
    system.n = n
    p0 = system.params[parameter]
    lo, hi = _check_bounds(problem, options, parameter, p0)
    meta = dict(kind=kind, parent=parent, id=branch_id)

    def say(msg: str) -> None:
        log.info(msg)
        if progress is not None:
            progress(msg)

    adaptor, problem0, grid_lines = None, problem, []
    if options.adapt is not None:  # adaptive resolution (contin.adapt): choose the start grid
        from contin.adapt import Adaptor, start_grid

        adaptor = Adaptor(options.adapt)
        adaptor.newton_options = options.newton
        problem, u0, grid_lines = start_grid(problem, u0, system.params, options.adapt, options.newton,
                                             coarsen=tangent is None, estimate=adaptor.estimate, parameter=parameter)
        if problem is not problem0:
            system = ExtendedSystem(problem, system.params, parameter, sopt.theta)
            if tangent is not None:
                tangent = np.asarray(tangent, dtype=float).ravel()
                tangent = system.pack(problem0.transfer(tangent[:-1], problem), tangent[-1])
        n = u0.size
        system.n = n
        problem0 = problem  # the grid x0 and the start tangent live on
    start = newton(problem, u0, system.params, options.newton)
    tracer = _Tracer(system, options, None)
    tracer.adaptive = adaptor is not None
    tracer.audit.extend(grid_lines)
    tracer.point_tests = point_tests(problem, system, options, n)
    if not start.converged:
        msg = f"Newton failed at the start point {parameter}={p0:g}: {start.message}{_jacobian_hint(start.message, problem)}"
        tracer.special.append(tracer.end_point("MX", msg, x=system.pack(u0, p0)))
        say(msg)
        return tracer.build(parameter, "MX", msg, False, n, **meta)
    anti = _symmetry(problem, start.u, symmetric, system.params, parameter)
    tracer.anti = anti
    x0 = system.pack(anti.symmetrize(start.u) if anti is not None else start.u, p0)
    # With adaptive resolution its estimate replaces the fixed-grid guard.
    resolution_tol = effective_resolution_tol(options) if adaptor is None else None
    coarse = _under_resolved(problem, system, x0, resolution_tol)
    if adaptor is not None and (err0 := adaptor.too_coarse(system, x0)) is not None:
        coarse = adaptor.at_start(system, x0, err0)
    if coarse is not None:
        msg = f"start point {coarse}"
        tracer.special.append(tracer.end_point("MX", msg, x=x0))
        say(msg)
        return tracer.build(parameter, "MX", msg, False, n, **meta)

    # Start tangent: bordered solve with the guess as bordering row; the guess is e_p (natural
    # direction) unless a tangent is given; a random row rescues a start exactly at a fold.
    if tangent is not None:
        raw = np.asarray(tangent, dtype=float).ravel()
        if raw.size != n + 1:
            raise ValueError(f"tangent must have n + 1 = {n + 1} entries, got {raw.size}")
        if not (np.all(np.isfinite(raw)) and np.any(raw != 0)):  # it failed every step with a RuntimeWarning (qa15)
            raise ValueError("tangent must be finite and nonzero")
        guess = direction * system.unit(raw)
    else:
        guess = np.zeros(n + 1)
        guess[-1] = math.copysign(1.0, sopt.ds) * direction
        guess = system.unit(guess)
    jac, fp = system.jacobian(x0)
    row = system.row(guess)
    fact = factorize_bordered(jac, fp, row)
    if fact is None:
        guess = system.unit(guess + 1e-3 * np.random.default_rng(0).standard_normal(n + 1))
        row = system.row(guess)
        fact = factorize_bordered(jac, fp, row)
    if fact is None:
        msg = f"singular extended Jacobian at the start point {parameter}={p0:g} (not a regular point)"
        tracer.append(_Point(x0, guess, TestValues(float(guess[-1]), (0.0, 0.0))), 0.0, start.iterations)
        tracer.special.append(tracer.end_point("MX", msg))
        return tracer.build(parameter, "MX", msg, False, n, **meta)
    first = tracer.finish_point(Correction(x0, True, 0, fact, row), guess)
    tracer.append(first, 0.0, start.iterations)
    _start_zeros(tracer, first)

    # The start point and tangent on the grid in force (for the closure test), carried onto a
    # new grid only when the test first needs them there: two transfers per grid change saved on
    # the many branches that never come near their start.
    closure_start: dict[int, tuple[Array, Array]] = {}

    def start_here() -> tuple[Array, Array]:
        key = id(system)
        if key not in closure_start:
            closure_start.clear()
            closure_start[key] = (x0, first.t) if adaptor is None else \
                (adaptor.carry(problem0, system, x0), system.unit(adaptor.carry(problem0, system, first.t)))
        return closure_start[key]
    if adaptor is not None:
        special_tol = min(options.adapt.tol, options.adapt.special_tol)
        from contin.specialcheck import has_position_check

        tracer.pre_locate = lambda kind, a, b: adaptor.pre_locate(
            tracer.system, kind, a, b, special_tol, checkable=has_position_check(kind, tracer.anti is not None))

    def refine_first(why: _RefineFirst, cur: _Point, new: _Point, stepped: _Point,
                     direction_vec: Array) -> list[SpecialPoint] | None:
        """An LP/BP bracketed by the step cur -> new on a grid too coarse for its kernel:
        refine at cur (None: retry the step there), or, if that fails, locate it on this grid
        (the located point's own check then notes it)."""
        assert adaptor is not None
        kernel = adaptor.kernel  # the bracket end's kernel that pre_locate judged (its grid suggestion)
        old = tracer.points[-1]
        if adaptor.refine(tracer, why.error, f"{why.kind} bracketed, kernel under-resolved", options.newton,
                          vector=None if kernel is None else (kernel[1], special_tol)) is None:
            retreat_behind(old)
            return None
        hook, tracer.pre_locate = tracer.pre_locate, None
        try:
            return _detect_checked(tracer, steps, cur, new, stepped, direction_vec, ds, sopt)
        finally:
            tracer.pre_locate = hook

    def retreat_behind(old: _Point) -> bool:
        """After a refinement at the last point for a special point ahead of it (``old``: the last
        point on the previous grid): where an LP or BP test function has another sign there on the
        finer grid, the finer grid's zero lies *behind* the point (an FD grid moves gPCF's H_n^c
        down as it is refined: fd2 8 -> 16 bracketed BP1 at H = 13.85 .. 17.1, fd2 16 has it at
        13.07), and tracing on from the point skipped it (``--method fd2 --tol 1e-4`` found none of
        the three BPs).  The stored points are then re-solved on the finer grid from the last one
        back until the sign is the old one, the tracer retreats to that point (the points after
        it are dropped, and retraced on the finer grid) and True is returned; False if no test
        function changed sign (or no stored point has the old sign: nothing to retreat to)."""
        assert adaptor is not None
        now = tracer.points[-1]
        moved = [fn for _, _, fn in tracer._test_functions() if _sign_changed(fn(old.tests), fn(now.tests))]
        if not moved:
            return False
        for j in range(len(tracer.points) - 2, max(len(tracer.points) - 2 - MAX_RETREAT, -1), -1):
            back = adaptor.carry_point(tracer, j, options.newton)
            if back is None:
                break
            if not any(_sign_changed(fn(old.tests), fn(back.tests)) for fn in moved):
                dropped = len(tracer.points) - 1 - j
                tracer.truncate(j + 1, back)
                adaptor.forget_points()
                if len(tracer.audit) < MAX_AUDIT:
                    tracer.audit.append(
                        f"retreated {dropped} point(s) to {parameter}={back.x[-1]:.10g} on grid {tracer.grid}: a test "
                        f"function changed sign at {parameter}={now.x[-1]:.10g} with the refinement, so the special "
                        "point lies behind it on the finer grid")
                adopt_grid()
                return True
        if len(tracer.audit) < MAX_AUDIT:  # said, not silent: a special point may lie behind
            tracer.audit.append(
                f"a test function changed sign at {parameter}={now.x[-1]:.10g} with the refinement to grid "
                f"{tracer.grid}, but no stored point up to {MAX_RETREAT} back has its old sign there: a special "
                "point may lie behind it, not located")
        return False

    def missed_crossings() -> tuple[str, int] | None:
        """An FD branch's located special points against its check grid: the LP/BP test functions
        of the first and last points re-solved on the grid ``check_factor`` times finer change
        sign an odd or even number of times; where that parity differs from the number of points
        of that kind the tracer located, a special point was missed (or is spurious) on the
        grids the branch ran on.  An exact state estimated at 0 lets an FD run coarsen to its
        smallest grid, whose spectrum can lack a bifurcation: ``contin trace savage-rheology
        --method fd2 --tol 1e-4`` traced uniform shear on fd2 8 through H_1^c and H_2^c and
        located none, exit 0 (session 15).  The grids and points are restored; (audit line, check
        grid) is returned, and the tracer retraces the branch with the check grid as its smallest
        grid (on max_grid: the audit line stays, a warning of ``contin trace``)."""
        assert adaptor is not None
        from contin.adapt import check_grid

        size = check_grid(problem, adaptor.opts.check_factor or 2.0, adaptor.opts)
        if size is None:
            return None
        keep = adaptor._snapshot(tracer)
        if not adaptor.regrid(tracer, size, "crossing check", 0.0, options.newton):
            return None
        try:
            first, last = adaptor.carry_point(tracer, 0, options.newton), tracer.points[-1]
            functions = tracer._test_functions()
        finally:
            adaptor._restore(tracer, keep)
        if first is None:
            return None
        odd = []
        for name, kind, fn in functions:
            found = sum(1 for sp in tracer.special if sp.type == name and (not kind or str(sp.note).startswith(kind)))
            changed = _sign_changed(fn(first.tests), fn(last.tests))
            if changed != (found % 2 == 1):
                odd.append(f"{f'{name} {kind}'.strip()} test function changes sign {'an odd' if changed else 'an even'} "
                           f"number of times there, {found} located")
        if not odd:
            return None
        return (f"{MISSED_SPECIAL} between {parameter}={tracer.points[0].x[-1]:.10g} and "
                f"{tracer.points[-1].x[-1]:.10g}: on the check grid {size} the {'; the '.join(odd)} on the grids "
                "of the run (refine the start grid with --grid, or use a finer method)"), int(size)

    def adopt_grid() -> None:
        """Continue on the grid the tracer moved to (contin.adapt): its system, problem and size;
        the start point for the closure test is carried onto it when the test first needs it."""
        nonlocal system, problem, n
        system, problem, n = tracer.system, tracer.system.problem, tracer.system.n
        closure_start.clear()

    def detect_or_refine(cur: _Point, new: _Point, stepped: _Point) -> tuple[list[SpecialPoint] | None, bool]:
        """(found, regridded) for the step cur -> new: the located special points (None: the
        step jumped onto another branch), or regridded = True when an LP/BP in the bracket
        needed a finer grid first -- the tracer then continues on it and the step is retried."""
        try:
            return _detect_checked(tracer, steps, cur, new, stepped, direction_vec, ds, sopt), False
        except _RefineFirst as why:
            found = refine_first(why, cur, new, stepped, direction_vec)
            if found is not None:
                return found, False
        adopt_grid()
        return None, True
    ds = abs(sopt.ds)
    travelled = 0.0
    closing = False
    status, message, closed = "EP", f"maximum number of steps ({options.max_steps}) reached", False
    steps = 0
    while steps < options.max_steps:
        if stop_requested():  # Ctrl-C/SIGTERM inside contin.cancel.stop_on_sigint: keep what was traced
            status, message = "MX", stop_reason() + ENDS_AT_LAST_POINT
            break
        cur = tracer.points[-1]
        if sopt.predictor == "secant" and len(tracer.points) > 1:
            direction_vec = secant(system, tracer.points[-2].x, cur.x)
        else:
            direction_vec = cur.t
        corr = tracer.correct_at(cur.x + ds * direction_vec, direction_vec)
        reason = None if corr.converged else corr.message
        new: _Point | None = None
        if reason is None:
            new = tracer.finish_point(corr, direction_vec)
            # The corrector checked every iterate, the returned one included; only a
            # symmetrized point (a new vector) needs the check.
            reason = None if new.x is corr.x else system.admissible(new.x)
            if reason is None:
                turn = angle(system, cur.t, new.t)
                if turn > sopt.max_angle and ds > sopt.ds_min * (1 + 1e-12):
                    reason = f"tangent turned by {turn:.3g} rad > max_angle"
        if reason is not None:
            if closing:  # the closing step failed: carry on as an ordinary branch
                closing = False
            if len(tracer.audit) < MAX_AUDIT:
                tracer.audit.append(f"step {steps + 1}: {parameter}={cur.x[-1]:.10g} ds={ds:.3g} rejected: {reason}")
            if ds <= sopt.ds_min * (1 + 1e-12):
                status = "MX"
                message = f"step failed at {parameter}={cur.x[-1]:.10g} with ds at ds_min={sopt.ds_min:g}: {reason}"
                if len(tracer.points) == 1:  # not one step from the start: most often a wrong Jacobian
                    message += _jacobian_hint(reason, problem)
                break
            ds = reduced_step(ds, sopt)
            continue
        assert new is not None
        if adaptor is not None and (err := adaptor.candidate_error(system, new.x)) is not None:
            # Not resolved (the estimate, or the two-grid error of the solve that the estimate
            # can under-read next to a BP/LP): refine at the last accepted point and retry the
            # step from there.  (The resolution limit fits the estimate's decay: not for a check.)
            checked = adaptor.checked is not None
            why = "two-grid error above tol" if checked else "estimate above tol"
            stop = adaptor.precision_limit(tracer, new.x)
            refined = stop is None and checked
            stop = (stop or (None if checked else adaptor.resolution_limit(tracer, new.x, err))
                    or adaptor.refine(tracer, err, why, options.newton))
            if stop is not None and stop.startswith(PRECISION_LIMIT):
                refined = False  # the finer grid's rounding estimate exceeds tol: that limit ends it
            if refined and stop is not None:
                # The two-grid error does not fall with refinement (or max_grid is reached).  Where
                # the fine grid's rounding is a part of tol, it is a floor: end EP there (the last
                # point back on the grid where it passed its check).  Otherwise the check cannot
                # decide (a kink's two-grid differences scatter with its position between the
                # nodes): the candidate is accepted by its estimate, and the audit says so.
                if adaptor.rounding_floor(system, new.x):
                    stop = adaptor.solve_floor(tracer, stop)
                    adopt_grid()
                    status, message = _guard_status(stop), stop
                    break
                adaptor.stalled = False
                if len(tracer.audit) < MAX_AUDIT:
                    tracer.audit.append(f"step {steps + 1}: {parameter}={new.x[-1]:.10g} {ACCEPTED_ABOVE_TOL}: two-grid "
                                        f"error {err:.2g} > tol, not lowered by refinement ({stop})")
            elif refined:
                adopt_grid()
                continue
            else:
                if stop is not None and adaptor.stalled and ds > sopt.ds_min * (1 + 1e-12):
                    # Refinement did not halve the candidate's estimate: try a candidate nearer the
                    # resolved last point before concluding that the estimate has a floor.
                    adaptor.stalled = False
                    if len(tracer.audit) < MAX_AUDIT:
                        tracer.audit.append(f"step {steps + 1}: {parameter}={cur.x[-1]:.10g} ds={ds:.3g} shortened: {stop}")
                    ds = reduced_step(ds, sopt)
                    continue
                if stop is not None:
                    # precision or resolution limit: every stored point meets tol and no grid (within max_grid) can go on (EP)
                    status, message = _guard_status(stop), stop
                    break
                adopt_grid()
                continue
        steps += 1

        if closing:
            if landed(system, start_here()[0], new.x):
                tracer.special.extend(tracer.detect(cur, new, len(tracer.points) - 1)[0])
                status, message, closed = "EP", "closed loop: the branch returned to its start point", True
                break
            closing = False

        # Parameter bound: land exactly on it with a parameter-fixed bordered correction.
        p_cur, p_new = cur.x[-1], new.x[-1]
        bound = lo if p_new < lo else hi if p_new > hi else None
        if bound is not None:
            # (relative, not absolute: with bounds (0, 1e-12) the start D = 0 counted as on the bound,
            # a one-point branch "reached bound D=1e-12", exit 0; `contin trace ab -s D_max=1e-12`, qa16)
            if abs(bound - p_cur) <= 1e-12 * max(abs(bound), abs(p_cur)):
                message = f"reached bound {parameter}={bound:g}"
                break
            frac = (bound - p_cur) / (p_new - p_cur)
            e_p = np.zeros(n + 1)
            e_p[-1] = 1.0
            x_pred = cur.x + frac * (new.x - cur.x)
            x_pred[-1] = bound
            land = correct(system, x_pred, e_p, options.newton)
            if not land.converged or system.admissible(land.x) is not None:
                if ds > sopt.ds_min * (1 + 1e-12):
                    # a long step across the bound (it may have jumped to another sheet): a shorter
                    # one lands, or steps on.  `continue sb.h5 --from LP1 --free a --ds 10` ended at
                    # its start point "reached bound lam=0 (landing on it failed ...)", EP, exit 0,
                    # lam = 3.5 far from the bound (qa18)
                    if len(tracer.audit) < MAX_AUDIT:
                        tracer.audit.append(f"step {steps}: {parameter}={p_cur:.10g} ds={ds:.3g} rejected: landing on "
                                            f"the bound {parameter}={bound:g} failed ({land.message})")
                    ds = reduced_step(ds, sopt)
                    steps -= 1
                    continue
                message = f"reached bound {parameter}={bound:g} (landing on it failed: {land.message}; stopped before it)"
                break
            coarse = _under_resolved(problem, system, land.x, resolution_tol)
            if coarse is not None:
                status, message = _guard_status(coarse), coarse
                break
            land.x[-1] = bound  # exact up to rounding already; make it exact
            if adaptor is not None:
                # The landed point is a new state: the checks of the candidate beyond the bound
                # are not its own (the fixed-grid guard above is off in adaptive runs).
                err = adaptor.candidate_error(system, land.x)
                if err is not None:
                    what = "two-grid error" if adaptor.checked is not None else "estimate"
                    stop = adaptor.refine(tracer, err, f"{what} above tol at the bound", options.newton)
                    if stop is None:  # refined at the last point: the step to the bound is retried
                        adopt_grid()
                        steps -= 1
                        continue
                    if len(tracer.audit) < MAX_AUDIT:
                        tracer.audit.append(f"step {steps}: {parameter}={bound:.10g} {ACCEPTED_ABOVE_TOL}: {what} "
                                            f"{err:.2g} > tol at the bound, not lowered by refinement ({stop})")
            stepped, new = new, tracer.finish_point(land, cur.t)
            found, regridded = detect_or_refine(cur, new, stepped)
            if regridded:
                steps -= 1
                continue
            if found is None:  # the step jumped onto another branch
                steps -= 1
                ds = reduced_step(ds, sopt)
                continue
            tracer.special.extend(found)
            tracer.special.extend(_on_the_bound(tracer, new, stepped, bound, len(tracer.points) - 1))
            tracer.append(new, system.norm(new.x - cur.x), corr.iterations)
            message = f"reached bound {parameter}={bound:g}"
            break

        coarse = _under_resolved(problem, system, new.x, resolution_tol)
        if coarse is not None:  # a smaller step would not help: the branch has left the grid's reach
            status, message = _guard_status(coarse), coarse
            break
        found, regridded = detect_or_refine(cur, new, new)
        if regridded:
            steps -= 1
            continue
        if found is None:  # the step jumped onto another branch
            steps -= 1
            ds = reduced_step(ds, sopt)
            continue
        if adaptor is not None and found:
            # Special points are located on the grid in force; one that grid does not resolve
            # (state, or the kernel fixing its position) is located again on a finer grid.
            adaptor.hold = None  # a special point is located: the hold of the last refinement ends
            err, kernel, kernels = -math.inf, None, []
            for sp in found:
                e_sp = adaptor.special_error(system, sp.type, system.pack(sp.state, sp.params[parameter]), sp.tangent)
                kernels.append(None if adaptor.kernel is None else adaptor.kernel[1])
                if e_sp > err:
                    err, kernel = e_sp, adaptor.kernel
            special_tol = min(options.adapt.tol, options.adapt.special_tol)
            # The position of a located LP / HB / symmetry-breaking BP is measured (a two-grid check,
            # contin.specialcheck) as well as estimated from its kernel's tail (an HB has none), which over-states
            # it on spectral grids and does not see an FD scheme's error at all (the tail of FD
            # profiles interpolated onto Chebyshev nodes: gPCF fd4 16 -> 32 located H_2^c 2.3e-4
            # off with special_tol 1e-6, its kernel "resolved").  The measurement decides where
            # the estimate exceeds special_tol, and refines where the estimate meets it but the
            # measurement exceeds special_tol beyond the check's own rounding (POSITION_FLOOR).
            from contin.specialcheck import POSITION_FLOOR, check_located

            checked = check_located(adaptor, system, found, tracer.anti is not None, kernels)
            kinds = "/".join(sorted({sp.type for sp in found}))
            measured = checked is not None and (err > special_tol or checked > max(special_tol, POSITION_FLOOR))
            if measured:
                tracer.audit.append(
                    f"located {kinds} at {parameter}={found[0].params[parameter]:.10g} on grid "
                    f"{system.problem.grid_size}: kernel estimate {err:.2g}, two-grid error of its position "
                    f"{checked:.2g} ({'meets' if checked <= special_tol else 'exceeds'} {special_tol:.2g})")
                err = checked
            if err <= special_tol:
                adaptor.special_resolved()
            elif adaptor.special_refinable(err, measured=measured, at=float(found[0].params[parameter]),
                                           finite_order=not estimate_decides_check(system.problem)):
                old = tracer.points[-1]
                if adaptor.refine(tracer, err, f"located {kinds} under-resolved", options.newton,
                                  vector=None if kernel is None else (kernel[1], special_tol), measured=measured) is None:
                    adopt_grid()
                    retreat_behind(old)
                    adaptor.hold = (float(tracer.points[-1].x[-1]), float(found[0].params[parameter]))
                    steps -= 1
                    continue
            if err > special_tol:
                grid = system.problem.grid_size
                what = (f"position not resolved by refinement (two-grid error {err:.2g} > tol on grid {grid}, not "
                        "falling with the grid: a rounding floor, a grid artefact, or past max_grid)" if measured else
                        f"kernel not resolved by refinement (estimate {err:.2g} > tol on grid {grid}): a grid artefact "
                        "or past max_grid")
                found = [replace(sp, note=(sp.note + "; " if sp.note else "") + what) for sp in found]
                if grid >= options.adapt.max_grid:
                    # Stopped by the grid limit, not by an error that does not fall: the next special
                    # point starts its own refinement history.  The memory of this one's last
                    # measurement (3.1e-6 of allen-cahn's BP1 on fd2 512 = max_grid) refused every
                    # later refinement (BP3 kept on fd2 72, 1.4e-3 off, with tol 1e-5 and "not
                    # falling with the grid"; session 14).  After a refinement that did not lower
                    # the error (a grid-scale artefact) the memory stays, as designed.
                    adaptor.special_resolved()
        tracer.special.extend(found)
        step_len = system.norm(new.x - cur.x)
        travelled += step_len
        tracer.append(new, step_len, corr.iterations)
        reached = _stop_label(tracer.special, options.stop_at)
        if reached is not None:
            message = f"stopped after {reached} (stop_at)"
            break
        event = next((sp.note for sp in found if sp.type == "UZ" and sp.note in stop_events), None)
        if event is not None:
            message = f"stopped at event {event}"
            break
        if steps % 20 == 0:
            say(f"branch {branch_id}: step {steps}, {parameter}={new.x[-1]:.6g}, ds={ds:.3g}")
        ds = next_step(ds, corr.iterations, sopt)
        if options.detect_closed and len(tracer.points) > 3:
            sigma = closing_distance(system, *start_here(), new.x, new.t, 1.5 * ds, travelled)
            if sigma is not None:
                closing, ds = True, sigma
        if adaptor is not None and not closing:
            adaptor.maybe_coarsen(tracer, options.newton)
            if tracer.system is not system:
                adopt_grid()

    if (adaptor is not None and tangent is None and status == "EP" and not closed and len(tracer.points) > 1
            and not estimate_decides_check(problem)):
        missed = missed_crossings()
        if missed is not None:
            line, size = missed
            if options.adapt.min_grid < size <= options.adapt.max_grid:
                # Retrace from the start with the check grid as the smallest grid: the run's
                # coarse grids lacked the crossing the check grid has.
                say(f"branch {branch_id}: {line}; retracing with min_grid {size}")
                start_pb, start_u = entry
                if int(start_pb.grid_size) < size:
                    finer_pb = start_pb.with_grid(size)
                    start_pb, start_u = finer_pb, np.asarray(entry[0].transfer(start_u, finer_pb), dtype=float)
                again = replace(options, adapt=replace(options.adapt, min_grid=size))
                retraced = trace(start_pb, start_u, params, parameter, again, direction=direction,
                                 branch_id=branch_id, kind=kind, parent=parent, symmetric=symmetric, progress=progress,
                                 stop_events=stop_events)
                retraced.audit.insert(0, f"retraced with min_grid {size} (AdaptOptions.min_grid was "
                                         f"{options.adapt.min_grid}): {line}")
                return retraced
            if len(tracer.audit) < MAX_AUDIT:
                tracer.audit.append(line)
    mark = "MX" if status == "MX" else "EP"
    note = message
    tracer.special.append(tracer.end_point(mark, note))
    say(f"branch {branch_id}: {status}: {message}")
    built = tracer.build(parameter, status, message, closed, n, **meta)
    cloud = special_cloud(built)
    if cloud is not None:  # exit EP with three LPs for one fold was a silent wrong answer
        log.warning("branch %s: %s", branch_id, cloud)
        built.audit = [*built.audit, cloud]
    return built


def position_doubt(sp: SpecialPoint, error: float, sa: Sample[Any], sb: Sample[Any], parameter: str,
                   span: float) -> SpecialPoint:
    """``sp`` with a note and a warning when its position is uncertain beyond
    :data:`POSITION_DOUBT` max(1, |p|) (what the tests promise; below it the note would flag
    every GH of a complex-step Jacobian, ~1e-9, for nothing): the test
    value's estimated error ``error`` over its change across the step (samples ``sa``, ``sb``),
    times the step's parameter ``span``, is the parameter interval in which the zero may lie
    (``data['position_error']``).  A point test whose value comes from difference quotients
    (l1 at a GH) can have its zero located to the tolerance within its own noise: AUTO's pp3 with
    a difference Jacobian had both GHs 1e-6 (relative) off, marked converged, silently."""
    change = abs(sb.g - sa.g)
    if not (math.isfinite(error) and change > 0):
        return sp
    uncertain = error / change * abs(span)
    p = float(sp.params[parameter])
    if uncertain <= POSITION_DOUBT * max(1.0, abs(p)):
        return sp
    msg = (f"position uncertain to +-{uncertain:.1e} in {parameter} (the test value's difference error "
           f"{error:.1e}; an exact or complex-step Jacobian lowers it)")
    log.warning("%s at %s=%.10g: %s", sp.type, parameter, p, msg)
    return replace(sp, note=f"{sp.note}; {msg}" if sp.note else msg, data={**sp.data, "position_error": uncertain})


def _detect_checked(tracer: _Tracer, step: int, cur: _Point, new: _Point, stepped: _Point, direction: Array,
                    ds: float, sopt: StepOptions) -> list[SpecialPoint] | None:
    """Special points of the step cur -> new (new: the corrected step ``stepped``, or the point
    landed on a bound from it), or None if the step jumped onto another branch and is to be
    retried with a smaller ds (:func:`_jump_retry`, on unconfirmed BPs only)."""
    found, unconfirmed = tracer.detect(cur, new, len(tracer.points) - 1)
    if unconfirmed:
        retry, found = _jump_retry(tracer, step, cur, stepped, direction, ds, sopt, found, unconfirmed)
        if retry:
            return None
    if tracer.eigen is not None:  # the eigenvalue-count cross-check (contin.bpdetect)
        return tracer.eigen.check(tracer, cur, new, found, ds, ds > sopt.ds_min * (1 + 1e-12))
    return found


def _on_the_bound(tracer: _Tracer, landed: _Point, stepped: _Point, bound: float, index: int) -> list[SpecialPoint]:
    """Special points on a parameter bound itself: a test function whose zero is the landed point
    (to rounding) may keep its sign there, so the step cur -> landed does not see it.  The zeros
    between the landed point and the step beyond the bound (``stepped``) that are located within
    the location tolerance of the bound belong to the branch (point ``index``'s step).  `contin
    continue F --from LP2 --free b --bounds a=-0.7777777777777778:2` (ZH at a = -7/9) reported no
    ZH, a bound 1e-12 further did (qa17).

    Only the zeros that the secant of their (detrended) test function puts within
    :data:`NEAR_BOUND` of the step beyond the bound are located: one at the bound has its test
    value ~ tol / step of the change across the step (~1e-8), and a zero farther out was located
    only to be dropped (an HB beyond the bound cost its location and its l1, a GH its l2: ~1500
    Jacobians)."""
    if not (stepped.tests.extra.keys() == landed.tests.extra.keys()):
        return []
    saved = tracer._gaps, tracer._gap_point  # detect() resets the step's detection-gap lines
    try:
        found, _ = tracer.detect(landed, stepped, index, near=NEAR_BOUND)
    except _RefineFirst:
        # a zero beyond the bound that adaptive resolution would refine before locating: past the
        # bound the branch is over, so no grid is changed for it (it escaped trace: Allen-Cahn fd2
        # --tol 1e-4 down to lam = 5, test_adapt)
        return []
    finally:
        tracer._gaps, tracer._gap_point = saved
    parameter = tracer.system.parameter
    tol = tracer.options.detection.locate_tol * max(1.0, abs(bound))
    return [replace(sp, index=index) for sp in found
            if sp.converged and abs(sp.params[parameter] - bound) <= tol]


def _jump_retry(tracer: _Tracer, step: int, cur: _Point, new: _Point, direction: Array, ds: float,
                sopt: StepOptions, found: list[SpecialPoint], unconfirmed: list[Unconfirmed]) -> tuple[bool, list[SpecialPoint]]:
    """Branch-jump protection for the step cur -> new, across which BP test functions changed
    sign without a BP confirmed by the location (``unconfirmed``: point and reason).

    Returns (True, found) if the step jumped onto another branch and is to be retried with a
    smaller ds; (False, found) if it is kept: unchanged for a continuous step, with the
    unconfirmed BPs marked ``converged=False`` ("not confirmed: ...") for a jump at ds_min.
    Either way ``branch.audit`` says so.

    A BP test function changes sign where [J F_p] loses rank, but also where a long step lands
    on a separate branch nearby (the tangent orientation or the determinant's sign differ
    there); the location then finds no zero.  The step is a jump when two half steps do not end
    where it ended (:meth:`_Tracer.jumped`): a shorter step stays on the branch (the
    predictor's error falls like ds^2).  A continuous step is kept as it is (a BP the locator
    could not pin down, e.g. where the branch crosses another one at a shallow angle), and so
    is a jump at ds_min, where a smaller step is not possible.
    """
    head = f"step {step}: {tracer.system.parameter}={cur.x[-1]:.10g} ds={ds:.3g}"
    retry = False
    if ds <= sopt.ds_min * (1 + 1e-12):
        what = "kept at ds_min, BP unconfirmed"
        relabel = {id(sp): why for sp, why, _ in unconfirmed if sp.converged}
        found = [replace(sp, converged=False, note=(sp.note + "; " if sp.note else "") + f"not confirmed: {relabel[id(sp)]}")
                 if id(sp) in relabel else sp for sp in found]
    else:
        jump = tracer.jumped(cur, new, direction, ds)
        retry = jump is not None
        what = f"rejected (jumped to another branch: {jump})" if retry else \
            "kept, BP unconfirmed (two half steps end at the same point: no jump)"
    if len(tracer.audit) < MAX_AUDIT:
        tracer.audit.append(f"{head} {what}: " + "; ".join(line for _, _, line in unconfirmed))
    return retry, found


def _labelled(branch: Branch) -> Branch:
    """``branch`` with its special points numbered 1, 2, ... along it (AUTO-style names LP1,
    BP2, ... without a call to :func:`contin.branch.relabel`; calling it on a whole run makes
    the labels unique within the run)."""
    relabel([branch])
    return branch


def _start_zeros(tracer: _Tracer, first: _Point) -> None:
    """Label the start point UZ for each user zero of the continuation parameter it sits on
    (within rounding, :meth:`contin.events.ParameterZeros.at_start`): p - value is 0 there, so
    no step crosses it and ``--uz lam=<start value>`` was reported nowhere (AUTO reports no UZ
    at a start point either; a user who asks for it is told).  The first step does not locate
    it again; it does not count for ``stop_at`` (AUTO's UZSTOP counts the UZs after the start)."""
    from contin.events import AT_START

    for pt in tracer.point_tests:
        at_start = getattr(pt, "at_start", None)
        if at_start is None:
            continue
        for note in at_start(float(first.x[-1])):
            sp = tracer.end_point("UZ", f"{note}; {AT_START}")
            tracer.special.append(pt.finish(tracer.system, sp, first.x))
            tracer.start_zeros.add(note)


def _is_start_zero(sp: SpecialPoint) -> bool:
    """Whether ``sp`` is a UZ that :func:`_start_zeros` labelled at a branch's start point."""
    from contin.events import AT_START

    return sp.type == "UZ" and sp.note.endswith(AT_START)


def _stop_label(special: list[SpecialPoint], stop_at: tuple[str, ...]) -> str | None:
    """The first label of ``stop_at`` (e.g. 'LP1') whose count of that type is reached, else None
    (a UZ at the start point does not count, :func:`_start_zeros`)."""
    for label in stop_at:
        if sum(sp.type == label[:2] and not _is_start_zero(sp) for sp in special) >= int(label[2:]):
            return label
    return None


def join(backward: Branch, forward: Branch) -> Branch:
    """One branch from two traces out of the same start point (backward reversed, then forward)."""
    r = backward.reversed()
    m = len(r)
    if m == 0:
        return forward
    if len(forward) == 0:
        return r
    off = m - 1
    # the start point is both halves' first point: its UZ (_start_zeros) is kept once (the
    # reversed half's copy: Branch.reversed moved it to index off - 1, between its last two points)
    at_start = {sp.note for sp in r.special_points if _is_start_zero(sp)}
    sps = list(r.special_points) + [replace(sp, index=sp.index + off) for sp in forward.special_points
                                    if not (sp.index == 0 and sp.type == "UZ" and sp.note in at_start)]

    def cat(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.concatenate([a[:-1], b])

    sizes = grid = None
    if r.grid is not None or forward.grid is not None or r.sizes is not None or forward.sizes is not None:
        # Halves on different grids (adaptive runs): pad both to the wider one.
        width = max(r.states.shape[1], forward.states.shape[1])
        twidth = max(r.tangents.shape[1], forward.tangents.shape[1])

        def widen(b: Branch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            n_b = b.sizes if b.sizes is not None else np.full(len(b), b.states.shape[1], dtype=np.int64)
            st = pad_rows(list(b.states), width)
            tg = pad_rows([b.tangents[i, : int(n_b[i]) + b.tangent_extra] for i in range(len(b))], twidth)
            return st, tg, n_b

        rs, rt, rn = widen(r)
        fs, ft, fn = widen(forward)
        r = replace(r, states=rs, tangents=rt)
        forward = replace(forward, states=fs, tangents=ft)
        sizes = cat(rn, fn)
        if r.grid is not None and forward.grid is not None:
            grid = cat(r.grid, forward.grid)

    if r.state_index is None and forward.state_index is None:
        states, state_index = cat(r.states, forward.states), None
    else:
        ri, fi = r.stored_points, forward.stored_points
        keep = ri < m - 1
        states = np.concatenate([r.states[keep], forward.states])
        state_index = np.concatenate([ri[keep], fi + off])
    status = "MX" if "MX" in (r.status, forward.status) else "EP"
    return _labelled(Branch(
        parameter=forward.parameter,
        free=forward.free,
        params={k: cat(r.params[k], forward.params[k]) for k in forward.params},
        observables={k: cat(r.observables[k], forward.observables[k]) for k in forward.observables if k in r.observables},
        states=states,
        tangents=cat(r.tangents, forward.tangents),
        ds=np.concatenate([r.ds, forward.ds[1:]]),
        newton_iterations=np.concatenate([r.newton_iterations, forward.newton_iterations[1:]]),
        special_points=sps,
        status=status,
        message=f"backward: {backward.message}; forward: {forward.message}",
        closed=False,
        kind=forward.kind,
        parent=forward.parent,
        id=forward.id,
        audit=r.audit + forward.audit,
        state_index=state_index,
        grid=grid,
        sizes=sizes,
    ))


def trace_both(
    problem: Any,
    u0: Array,
    params: Mapping[str, float],
    parameter: str,
    options: ContinuationOptions = ContinuationOptions(),
    **kwargs: Any,
) -> Branch:
    """Trace in both directions from the start and join the halves through the start point.

    A closed loop found by the forward trace is returned as is (it needs no second half).
    Keyword arguments are passed to :func:`trace` (not ``direction``).
    """
    forward = trace(problem, u0, params, parameter, options, direction=+1, **kwargs)
    if forward.closed or len(forward) == 0:
        return forward
    backward = trace(problem, u0, params, parameter, options, direction=-1, **kwargs)
    return join(backward, forward)


def switch(
    problem: Any,
    branch: Branch,
    point: SpecialPoint | str,
    options: ContinuationOptions = ContinuationOptions(),
    *,
    directions: tuple[int, ...] = (+1, -1),
    branch_id_prefix: str | None = None,
    ds: float | None = None,
    symmetric: bool | None = None,
) -> list[Branch]:
    """Trace the branches bifurcating at the BP ``point`` of ``branch`` (or its label, e.g. ``"BP1"``).

    The first point of each half-branch comes from the algebraic bifurcation equation
    (:func:`contin.switching.departures`), or, at a BP whose kernel dimension d > 1 was recorded
    (``contin.bpdetect``), from the reduced bifurcation equations in d amplitudes
    (:func:`contin.ndbp.nd_departures`; one branch per root direction, ``directions`` and
    ``symmetric`` ignored); each is traced on from there and starts with the BP.

    Parameters
    ----------
    directions : signs of the new tangent to follow (both halves of the new branch by default).
    branch_id_prefix : ids are f"{prefix}.{k}" (default prefix f"{branch.id}.{point.name}").
    ds : length of the first step off the BP (default |options.step.ds|).

    Returns
    -------
    list of Branch
        kind='bifurcated', parent=f"{point.name}@{branch.id}", each starting at the BP.

    Raises
    ------
    ValueError
        If ``point`` is not a BP with a tangent, the BP is not simple (b = 0 in the ABE), or no
        direction gives a new branch (the reason per direction; never an empty list).
    """
    if isinstance(point, str):  # a label: switch(pb, branch, "BP1", opts) met "'str' object has no attribute 'type'"
        named = [sp for sp in branch.special_points if sp.name == point]
        if not named:
            raise ValueError(f"no point {point!r} on branch {branch.id}; its labels are "
                             f"{', '.join(sp.name for sp in branch.special_points) or 'none'}")
        point = named[0]
    if not isinstance(point, SpecialPoint):
        raise TypeError(f"point must be a SpecialPoint of the branch (e.g. branch.branch_points[0]) or its label, "
                        f"got {type(point).__name__}")
    if point.type != "BP" or point.tangent is None:
        raise ValueError(f"switching needs a BP with its tangent, got {point.type} ({point.name})")
    # a BP without a usable state ended in numpy's "matmul: dimension mismatch ..." or "operands
    # could not be broadcast together ..." (qa15); its size is checked on its grid by departures
    state = None if point.state is None else np.asarray(point.state, dtype=float).ravel()
    if state is None or state.size == 0 or not np.all(np.isfinite(state)):
        raise ValueError(f"switching at {point.name} needs its located state, and it has "
                         f"{'none' if state is None or state.size == 0 else 'non-finite entries'}")
    tangent_size, extra = np.asarray(point.tangent).size, int(getattr(branch, "tangent_extra", 1))
    if tangent_size != state.size + extra:
        raise ValueError(f"{point.name}: its state ({state.size} entries) and tangent ({tangent_size}) do not fit "
                         f"together (the tangent has {extra} entr{'y' if extra == 1 else 'ies'} more)")
    param = branch.parameter
    dim = kernel_dimension(point)
    nd = dim is not None and dim > 1
    if nd:
        deps = nd_departures(problem, branch, point, options, dim, ds=ds)
    else:
        deps = departures(problem, branch, point, options, directions=directions, ds=ds)
    prefix = branch_id_prefix if branch_id_prefix is not None else f"{branch.id}.{point.name}"
    parent = f"{point.name}@{branch.id}"
    out: list[Branch] = []
    failed: list[str] = []
    for k, dep in enumerate(deps, start=1):
        if isinstance(dep, str):  # no accepted first step in this direction
            failed.append(dep)
            continue
        system = dep.system  # on the BP's own grid (adaptive runs: contin.adapt.on_grid)
        new = trace(system.problem, dep.start[:-1], system.params_at(dep.start[-1]), param,
                    first_step_options(options, dep.step), tangent=dep.tangent, branch_id=f"{prefix}.{k}",
                    kind="bifurcated", parent=parent, symmetric=None if nd else symmetric)
        if nd:
            new.audit.insert(0, f"switched at {point.name} (kernel dimension {dim}) along the reduced root {dep.note}")
        new = prepend(system, new, dep.x0, dep.tangent)
        # a step onto the parent (a BP passed by turning onto it) leaves the branch stored with
        # status EP and the parent's points: said as an audit line, a warning on the command line
        rejoined = on_parent(problem, branch, new, system.params_at(dep.start[-1]))
        if rejoined is not None:
            log.warning("branch %s %s", new.id, rejoined)
            new.audit = [*new.audit, rejoined]
        out.append(new)
    if not out:  # never an empty list without a reason
        where = f"{point.name} ({param} = {point.params[param]:.10g}" + (f", kernel dimension {dim})" if nd else ")")
        raise ValueError(f"switching at {where} found no new branch: "
                         + (f"none along any of the {len(deps)} reduced roots" if nd else "; ".join(failed)))
    return out
