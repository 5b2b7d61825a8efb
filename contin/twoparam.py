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
  located on it);
- ``BT`` of a fold or Hopf curve -- the other curve through it, in the same two parameters
  (a Hopf curve's BT starts the fold curve, a fold curve's BT the Hopf curve, from kappa = 0:
  :func:`contin.hopfcurve.hopf_curve_start_at_bt`);
- ``ZH`` of a fold or Hopf curve -- likewise the other curve (a Hopf curve's ZH starts the fold
  curve of its real zero eigenvalue, a fold curve's ZH the Hopf curve of its pair +-i omega);
- ``HH`` of a Hopf curve -- the Hopf curve of its other pair (+-i omega2).

Other point types are a clear error (:class:`NotAvailable`); :func:`register_curve` adds one.
Bounds on the second parameter (``options.bounds[second]``) end the curve on the bound: the
located crossing of a bound event (:func:`contin.foldcurve.trace_augmented`, as for every
fold, BP and Hopf curve).

Adaptive grids (``continue_point(..., regrid=SegmentRegrid(...))``, the CLI's
``contin continue --tol``): the Moore-Spence curves -- LP and the fold curve of a BP that the
second parameter unfolds -- are regridded segment-wise (:func:`contin.foldcurve.trace_augmented`):
where the resolution guard stops a half, its last accepted point continues on a finer grid and
every point keeps its grid (``Branch.grid``); every point also passes the two-grid check of its
augmented solve (:func:`contin.foldcurve.augmented_two_grid_error`, ``AdaptOptions.check_factor``),
and one that misses tol there is recomputed on a finer grid.  BP curves (:mod:`contin.bpcurve`: reduced
coordinates whose symmetric/antisymmetric bases belong to one grid) and Hopf curves
(:mod:`contin.hopfcurve`: another augmented layout, no grid transfer of its blocks) have no
regridding yet: asking for it raises :class:`NotAvailable`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from contin.bpcurve import trace_bp_curve
from contin.branch import Branch, SpecialPoint, base_state_size, relabel
from contin.foldcurve import SegmentRegrid, as_fold_curve, fold_start, trace_augmented
from contin.normalform import null_vectors
from contin.hopf import hopf_test
from contin.hopfcurve import trace_hopf_curve
from contin.options import ContinuationOptions

#: curve(problem, point, second, options, parameter=..., branch_id=...) -> Branch
CurveTracer = Callable[..., Branch]


class NotAvailable(ValueError):
    """Two-parameter continuation of this point type is not implemented (yet)."""


#: The message of :class:`NotAvailable` for regridding a curve that cannot be regridded.
NO_REGRID = ("adaptive grids are not available for BP/Hopf curves ({what}); continue it on a fixed grid "
             "(without --tol / regrid)")


def _fold_or_pitchfork(problem: Any, point: SpecialPoint, second: str, options: ContinuationOptions, *,
                       parameter: str, branch_id: str, regrid: SegmentRegrid | None = None) -> Branch:
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
        if regrid is not None:
            raise NotAvailable(NO_REGRID.format(what=f"{point.name} is a symmetry-breaking pitchfork that {second!r} "
                                                     "keeps: its curve is a BP curve"))
        return trace_bp_curve(problem, point, second, options, parameter=parameter, branch_id=branch_id)
    fold, start = fold_start(problem, point, second)
    # ZH detection as in trace_fold_curve (it was off here: `contin continue --from LP` found no ZH)
    fold.base_hopf = hopf_test(problem, options.detection, fold.n)
    raw = trace_augmented(fold, start, point, second, 2 * fold.n, options, parameter=parameter, both=True,
                          branch_id=branch_id, kind="fold-curve", mirror_start=True, regrid=regrid)
    curve = as_fold_curve(raw, fold, replace(options, detection=replace(options.detection, detect_branch_points=False)))
    if point.type == "BP" and fold.detect_cusps:
        curve = _cusp_at_start(curve, fold, point)
    return curve


def _cusp_at_start(curve: Branch, fold: Any, source: SpecialPoint) -> Branch:
    """Mark the start of a BP's fold curve as a cusp (CP) when it is one.

    A pitchfork unfolded by p2 is the cusp of the imperfect pitchfork's fold curve, which starts
    there and goes both ways: each half sees one sign of the cusp test psi . B(phi, phi), so the
    tracer brackets no zero and the cusp went unlabelled (x' = mu + lam x - x^3 from its BP in
    (lam, mu): no CP).  The cusp test at the start's two neighbours decides (opposite signs:
    the start is the cusp; a transcritical BP's fold curve keeps one sign through it).  Points
    on other grids than the start's (segment-wise regridding) are not compared."""
    from contin.cusp import CuspTest
    from contin.extended import ExtendedSystem

    s = _start_index(curve, source)
    if s is None or not 0 < s < len(curve) - 1:
        return curve
    if curve.grid is not None and len({int(curve.grid[i]) for i in (s - 1, s, s + 1)}) > 1:
        return curve
    system = ExtendedSystem(fold, {k: float(v[s]) for k, v in curve.params.items()}, curve.parameter)
    test = CuspTest(fold)

    def cusp_value(i: int) -> float:
        return test.value(system, system.pack(curve.state(i), curve.params[curve.parameter][i]))

    before, after = cusp_value(s - 1), cusp_value(s + 1)
    if not (math.isfinite(before) and math.isfinite(after)) or before == 0 or after == 0 or (before > 0) == (after > 0):
        return curve
    return _mark_start(curve, s, "CP", f"cusp at the start: {source.name}, the pitchfork that {curve.free[1]} unfolds")


def _start_index(curve: Branch, source: SpecialPoint) -> int | None:
    """The index of the curve's point at the source point's (p1, p2) (its corrected start), or None."""
    first, second = curve.free
    if len(curve) == 0:  # the start failed (the caller says so)
        return None
    p1, p2 = curve.params[first], curve.params[second]
    scale1, scale2 = max(1.0, abs(source.params[first])), max(1.0, abs(source.params[second]))
    distance = np.abs(p1 - source.params[first]) / scale1 + np.abs(p2 - source.params[second]) / scale2
    s = int(np.argmin(distance))
    return s if distance[s] <= 1e-8 else None


def _mark_start(curve: Branch, s: int, kind: str, note: str, data: dict[str, float] | None = None) -> Branch:
    """The curve with its point s labelled ``kind``: a point of that type the tracer located in
    a step next to s (rounding noise about a zero at the start) is dropped."""
    p1 = curve.params[curve.parameter]
    kept = [sp for sp in curve.special_points if not (sp.type == kind and sp.index in (s - 1, s))]
    start = SpecialPoint(type=kind, index=s, params={k: float(v[s]) for k, v in curve.params.items()},
                         order_parameter=float(curve.order_parameter[s]), state=curve.state(s).copy(),
                         tangent=curve.tangent(s).copy(), bracket=(float(p1[s]), float(p1[s])), converged=True,
                         note=note, data=dict(data or {}))
    curve.special_points = sorted(kept + [start], key=lambda sp: sp.index)
    relabel([curve])
    return curve


#: psi . dF/dp2 below this fraction of |psi| |dF/dp2| means p2 does not unfold the BP
UNFOLD_TOL = 1e-8

#: ... or below this fraction of |psi| (|J|_F |u| + |dF/dp2|).  Where p2 keeps the BP, dF/dp2 =
#: -J du/dp2 lies in J's range and psi . dF/dp2 is only the rounding of J^T psi times |du/dp2|;
#: when |dF/dp2| << |J| |du/dp2| that rounding passes the relative test.  gPCF's symmetric mode-2
#: pitchfork on uniform shear in e: 2.4e-8 relative, 5e-13 on this scale, so `contin continue
#: pf.h5 --from BP2 --free e` traced the BP locus as a "fold curve" with spurious cusps (CP, some
#: "converged"), exit 0 (session 14).  Gravity G unfolding the mode-1 pitchfork: 0.42 and 1.3e-3.
UNFOLD_ABS_TOL = 1e-10


def _unfolds(problem: Any, point: SpecialPoint, second: str) -> bool:
    """True if ``second`` unfolds the BP at first order: psi . dF/dp2 != 0 (relative UNFOLD_TOL,
    and UNFOLD_ABS_TOL against the size of J u: not the rounding of a BP that p2 keeps)."""
    import scipy.sparse as sp

    u = np.asarray(point.state, float)
    jac = sp.csc_matrix(problem.jacobian(u, point.params))
    psi = null_vectors(jac).psi
    fp = np.asarray(problem.dresidual_dp(u, point.params, second), float)
    dot = abs(float(psi @ fp))
    norm_psi, norm_fp = float(np.linalg.norm(psi)), float(np.linalg.norm(fp))
    scale = norm_psi * norm_fp
    size = norm_psi * (float(sp.linalg.norm(jac)) * float(np.linalg.norm(u)) + norm_fp)
    return scale > 0.0 and dot > UNFOLD_TOL * scale and dot > UNFOLD_ABS_TOL * size


def _hopf(problem: Any, point: SpecialPoint, second: str, options: ContinuationOptions, *,
          parameter: str, branch_id: str, regrid: SegmentRegrid | None = None) -> Branch:
    if regrid is not None:
        raise NotAvailable(NO_REGRID.format(what=f"{point.name} is a Hopf point"))
    return trace_hopf_curve(problem, point, second, options, parameter=parameter, branch_id=branch_id)


#: Point type -> tracer of its two-parameter curve.  A module that adds one (e.g. Hopf curves)
#: calls register_curve('HB', fn) on import.  Tracers take ``regrid`` (a SegmentRegrid or None)
#: and raise NotAvailable if they cannot regrid.
CURVES: dict[str, CurveTracer] = {"LP": _fold_or_pitchfork, "BP": _fold_or_pitchfork, "HB": _hopf}


def on_curve_message(branch: Branch, point: SpecialPoint) -> str | None:
    """Why ``point`` of a two-parameter curve cannot start a curve (None: it can, or ``branch`` is a
    one-parameter branch).  Of a curve's points only a BT, ZH or HH starts one (the other curve through it);
    an LP there is an extremum of the first parameter, not a fold of a branch, and its augmented
    state is no state of the problem: ``contin continue ab_hopf.h5 --from LP4 --free B`` ended
    "Error: too many values to unpack (expected 2)" (qa16)."""
    if len(branch.free) < 2 or point.type in SWITCH_TYPES:
        return None
    what = point.note.split(";")[0].strip() if point.note else ""
    kind = branch.kind.replace("-", " ") if branch.kind and "curve" in branch.kind else "two-parameter curve"
    return (f"{point.name} lies on the {kind} {branch.id} in "
            f"({', '.join(branch.free)}){' (' + what + ')' if what else ''}: of a curve's points only a BT, ZH or HH "
            f"starts another curve; continue the LP, HB or BP points of one-parameter branches")


def start_within_bounds(options: ContinuationOptions, point: SpecialPoint,
                        names: tuple[str, ...]) -> ContinuationOptions:
    """``options`` with the bounds of ``names`` checked against the start ``point``'s values.

    A point on a bound (to its location tolerance, 1e-12 beyond it) is in the range: the bound is
    moved onto it (`--from HH2 --bounds b=<HH2's b>:0.8` said 'start value b=0.302776 of HH2 lies
    outside its bounds (0.302776, 0.8)', qa17; the LPC curve the same, qa19b).  Raises ValueError,
    with 10 digits, for a start outside."""
    from contin.hopfcurve import within_bounds

    for name in names:
        lo, hi = options.bounds.get(name, (-math.inf, math.inf))
        value = float(point.params[name])
        if not within_bounds(value, lo, hi):
            raise ValueError(f"start value {name}={value:.10g} of {point.name} lies outside its bounds "
                             f"({lo:.10g}, {hi:.10g})")
        if not lo <= value <= hi:  # on a bound to its tolerance: the bound moves onto it
            options = replace(options, bounds={**options.bounds, name: (min(lo, value), max(hi, value))})
    return options


def continuable_types() -> list[str]:
    """The point types :func:`continue_point` continues: :data:`CURVES`' and BT, ZH, HH.

    BT, ZH, HH (:data:`SWITCH_TYPES`): the other curve through a Bogdanov-Takens, zero-Hopf or
    double-Hopf point."""
    return sorted([*CURVES, *SWITCH_TYPES])


def register_curve(point_type: str, tracer: CurveTracer) -> None:
    """Make :func:`continue_point` trace ``point_type`` points (e.g. 'HB') with ``tracer``."""
    CURVES[point_type] = tracer


def _resolved_start(problem: Any, point: SpecialPoint, second: str, options: ContinuationOptions,
                    regrid: SegmentRegrid) -> tuple[Any, SpecialPoint]:
    """``problem`` and ``point`` on the first grid, from the point's own on, where the point's state
    meets the resolution guard (``under_resolved`` at the effective resolution_tol): a point
    located on a grid that resolves it to a looser tol is carried (the problem's ``transfer``)
    onto the finer grids :meth:`SegmentRegrid.next_grid` picks, up to max_grid; the tracer's
    Newton start then puts it on the fold (or BP) of that grid.  Unchanged without the hook, with
    the guard off, or when the point meets tol where it is (or no finer grid meets it)."""
    from contin.adapt import on_grid
    from contin.options import effective_resolution_tol
    from contin.problem import has

    tol = effective_resolution_tol(options)
    if tol is None or not has(problem, "under_resolved"):
        return problem, point
    u = np.asarray(point.state, float)
    params = dict(point.params)
    here, state = problem, u
    while here.under_resolved(state, params, tol) is not None:
        size = regrid.next_grid(here, state, params)
        if size is None:
            return problem, point  # the tracer's start check says why
        finer = on_grid(here, size)
        state = here.transfer(state, finer)
        here = finer
    if here is problem:
        return problem, point
    return here, replace(point, state=state, grid=int(here.grid_size), tangent=None)


#: codim-2 points of fold and Hopf curves that start another curve through them
#: (:func:`_from_codim2`): the point type -> the curve kinds it is continued from
SWITCH_TYPES: dict[str, tuple[str, ...]] = {"BT": ("fold-curve", "hopf-curve"), "ZH": ("fold-curve", "hopf-curve"),
                                            "HH": ("hopf-curve",)}


def _from_codim2(problem: Any, branch: Branch, point: SpecialPoint, second: str,
                 options: ContinuationOptions, *, branch_id: str) -> Branch:
    """The other curve through a BT, ZH or HH of a fold or Hopf curve, in the same two parameters.

    - BT of a Hopf curve (state [u, v, w, kappa, p2]): the fold curve through it (its null
      vector: ``contin.foldcurve.fold_start``); BT of a fold curve (state [u, phi, p2]): the Hopf
      curve (:func:`contin.hopfcurve.hopf_curve_start_at_bt`, kappa = 0 there);
    - ZH of a Hopf curve: the fold curve through it (the null vector of the real zero
      eigenvalue); ZH of a fold curve: the Hopf curve of the pair +-i omega that crosses the
      imaginary axis there (``omega`` of the ZH's data and its eigenvector:
      :func:`contin.hopfcurve.hopf_curve_start`);
    - HH of a Hopf curve: the Hopf curve of the other pair (``omega2`` of the HH's data).

    The start of the new curve is labelled as the source point (:func:`_start_as`)."""
    from contin.foldcurve import trace_fold_curve
    from contin.hopfcurve import hopf_curve_start_at_bt, trace_hopf_curve

    kinds = SWITCH_TYPES[point.type]
    if branch.kind not in kinds or len(branch.free) != 2:
        curves = " or ".join(k.replace("-", " ").replace("hopf", "Hopf") for k in kinds)
        raise NotAvailable(f"{point.name}: a {point.type} is continued from a {curves}, not from a {branch.kind} branch")
    if second != branch.free[1]:
        raise ValueError(f"{point.name} lies on a curve in ({branch.free[0]}, {branch.free[1]}): the curve through it "
                         f"is traced in the same parameters, --free {branch.free[1]}")
    state = np.asarray(point.state, float)
    n = base_state_size(branch.kind, state.size)  # [u, phi, p2] or [u, v, w, kappa, p2]
    size = getattr(problem, "size", None)
    if n is None or (isinstance(size, int) and size != n):
        raise ValueError(f"the state of {point.name} ({state.size} entries) is not a {branch.kind} state of this problem")
    params = dict(point.params)
    params[second] = float(state[-1])
    try:  # a problem without a declared size (the demos): its residual says whether u fits (a file edited
        # to another curve kind sent n = 1 to ab's Jacobian: "not enough values to unpack", qa16)
        fits = np.shape(problem.residual(state[:n], params)) == (n,)
    except (ValueError, IndexError, TypeError):
        fits = False
    if not fits:
        raise ValueError(f"the state of {point.name} ({state.size} entries) is not a {branch.kind} state of this "
                         f"problem (its base state of {n} entries does not fit the problem's residual)")
    to_fold = branch.kind == "hopf-curve" and point.type in ("BT", "ZH")
    data: dict[str, float] = {}
    if point.type == "ZH" or point.type == "HH":
        key = "omega2" if point.type == "HH" else "omega"
        omega = float(point.data.get(key, math.nan))
        if not to_fold and not (math.isfinite(omega) and omega > 0):
            raise ValueError(f"{point.name} has no positive {key}: the Hopf pair of the new curve is unknown")
        data = {"omega": omega}
        if point.type == "HH":
            data["omega2"] = float(point.data.get("omega", math.nan))
            # the other pair must be another frequency than the curve's own (sqrt(kappa) of the state):
            # with omega2 = omega (a damaged file) the curve it lies on was traced again as "the Hopf
            # curve from HH2", exit 0 (qa17); a 1:1 resonance cannot tell the two pairs apart either
            kappa = float(state[3 * n]) if state.size > 3 * n else math.nan
            own = math.sqrt(kappa) if kappa > 0 else math.nan
            # (to 1e-9: a genuine pair 1e-6 apart switches correctly, audit16's test, so only a
            # rounding-level coincidence is refused)
            if math.isfinite(own) and abs(omega - own) <= 1e-9 * own:
                raise ValueError(f"{point.name}'s omega2 = {omega:.10g} is the frequency of the Hopf curve it lies "
                                 f"on (omega = {own:.10g}): the other pair is unknown (a damaged file, or a 1:1 "
                                 "resonance where the two pairs cannot be told apart)")
    # the normal form of the source point (contin.codim2tests), where it was computed; an HH's
    # pairs swap roles on the new curve (its own pair is the source's omega2)
    swap = {"p11": "p22", "p22": "p11", "p12": "p21", "p21": "p12", "theta": "delta", "delta": "theta"}
    nf_keys = {"ZH": {k: k for k in ("B", "C", "E", "s", "theta")}, "HH": swap}.get(point.type, {})
    normal_form = {new: float(point.data[old]) for old, new in nf_keys.items() if old in point.data}
    base = replace(point, type="LP" if to_fold else "HB", state=state[:n].copy(), params=params, tangent=None,
                   data=data)
    if to_fold:
        curve = trace_fold_curve(problem, base, second, options, parameter=branch.parameter, branch_id=branch_id)
    elif point.type == "BT":
        start = hopf_curve_start_at_bt(problem, state[:n], params, second)
        curve = trace_hopf_curve(problem, base, second, options, parameter=branch.parameter, branch_id=branch_id,
                                 start=start)
    else:  # the Hopf curve of the pair omega (ZH of a fold curve, the other pair of an HH)
        curve = trace_hopf_curve(problem, base, second, options, parameter=branch.parameter, branch_id=branch_id)
    if point.type == "BT":
        data = {k: v for k, v in point.data.items() if k in ("a", "b")}  # the BT's normal form, where it was located
    doubt = ""
    if not to_fold and point.type in ("ZH", "HH"):
        doubt = _pair_check(curve, point, float(data["omega"]))
    return _start_as(curve, point, branch.kind, {**data, **normal_form}, doubt)


#: Relative difference of the switched Hopf curve's kappa at its start from omega^2 of the pair
#: it was started on (ZH, HH) above which the start is reported doubtful
PAIR_TOL = 1e-6


def _pair_check(curve: Branch, source: SpecialPoint, omega: float) -> str:
    """'' when the Hopf curve switched at a ZH or HH has kappa = omega^2 of the pair it was started
    on at its start point, else a note (and a warning): the corrector may have taken another pair
    (next to a 1:1 resonance at an HH, omega2 ~ omega, it would retrace the source curve)."""
    import logging

    s = _start_index(curve, source)
    kappa = curve.observables.get("kappa") if curve.observables else None
    if s is None or kappa is None:
        return ""
    k0, want = float(kappa[s]), omega * omega
    if abs(k0 - want) <= PAIR_TOL * want:
        return ""
    msg = (f"start doubtful: kappa = {k0:.10g} at the start, not omega^2 = {want:.10g} of the pair "
           f"{source.name} gave (another pair was taken)")
    logging.getLogger("contin").warning("%s: %s", source.name, msg)
    return msg


def _start_as(curve: Branch, source: SpecialPoint, kind: str, data: dict[str, float], doubt: str = "") -> Branch:
    """The curve with its start marked as the BT, ZH or HH it came from.

    The new curve starts on the zero of its own test function of that type (BT: kappa or
    psi^T M phi; ZH: det J / kappa or the real part of the crossing pair; HH: the real part of
    the other pair), so the tracer brackets a sign change of rounding noise in the first step on
    either side and "locates" such a point there: on ab's fold curve from the Hopf curve's BT,
    5.5e-7 off B = 64/3, marked converged.  That point is replaced by the start point itself
    (corrected onto the new curve, where the source point is), with ``data`` (BT: its normal
    form a, b; ZH: omega and its normal form B, C, E, s, theta; HH: omega and omega2 of the new
    curve and the normal form p11 ... delta, the pairs swapped).  A Hopf curve from a ZH also
    loses a GH next to its start: l1 has a pole there (J singular), no zero
    (:func:`contin.hopfcurve._no_gh_at_zero_hopf`)."""
    s = _start_index(curve, source)
    if s is None:  # the start was not kept (not expected): leave the curve as traced
        return curve
    kappa = curve.observables.get("kappa")
    if curve.kind == "hopf-curve" and "omega" in data and kappa is not None and float(kappa[s]) > 0:
        # the new curve's own frequency at its start, not the value the file gave as its guess (a
        # damaged omega = 3 was shown as the start's 'omega=3' on the curve of omega 1; qa17)
        data = {**data, "omega": math.sqrt(float(kappa[s]))}
    if source.type == "ZH" and curve.kind == "hopf-curve":  # l1's pole at the start (J singular) is no GH
        curve.special_points = [sp for sp in curve.special_points if not (sp.type == "GH" and sp.index in (s - 1, s))]
    note = f"start: {source.name} of the {kind.replace('-', ' ').replace('hopf', 'Hopf')}"
    return _mark_start(curve, s, source.type, f"{note}; {doubt}" if doubt else note, data=data)


def continue_point(problem: Any, branch: Branch, point: SpecialPoint, second: str,
                   options: ContinuationOptions, *, branch_id: str | None = None,
                   regrid: SegmentRegrid | None = None) -> Branch:
    """The curve of ``point`` (LP, BP, HB; BT, ZH, HH: the other curve) in (branch.parameter, ``second``).

    From a located LP, BP or HB of ``branch`` its own curve; from a BT, ZH or HH of a fold or Hopf
    curve the other curve through it (:func:`_from_codim2`).

    Bounds: ``options.bounds`` of either parameter; the curve ends exactly on them.

    ``regrid`` (:class:`contin.foldcurve.SegmentRegrid`; a problem with the grid hooks
    ``grid_size``, ``with_grid``, ``transfer``, ``error_estimate``, moved onto the point's own grid
    ``point.grid`` when it has one, as points of adaptive runs do, and onto a finer grid when the
    point's state does not meet the guard's tol there): fold curves
    (LP, and BP unfolded by ``second``) that the resolution guard stops continue on finer grids
    segment-wise; the guard's tol is ``options.resolution_tol`` or a
    :func:`contin.options.resolution_override`.  The curve's ``grid`` holds every point's grid.

    Raises
    ------
    NotAvailable
        For a point type without a registered curve tracer (EP, MX, UZ...), and with ``regrid``
        for Hopf points and BPs whose curve is a BP curve.
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
    if tracer is None and point.type not in SWITCH_TYPES:
        raise NotAvailable(f"{point.name}: only {', '.join(continuable_types())} points can be continued in two "
                           f"parameters, not {point.type}")
    on_curve = on_curve_message(branch, point)
    if on_curve is not None:
        raise NotAvailable(on_curve)
    # every curve kind (the Hopf curve checked none: `--from HB2 --free sigma --bounds sigma=20:30`
    # from sigma = 10 stored points down to sigma = 5, exit 0)
    options = start_within_bounds(options, point, (first, second))
    if point.state is None:
        raise ValueError(f"{point.name} has no stored state")
    if point.type in SWITCH_TYPES:
        if regrid is not None:
            what = {"BT": "a Bogdanov-Takens", "ZH": "a zero-Hopf", "HH": "a double-Hopf"}[point.type]
            raise NotAvailable(NO_REGRID.format(what=f"{point.name} is {what} point"))
        curve = _from_codim2(problem, branch, point, second, options,
                             branch_id=branch_id if branch_id is not None else f"{point.name}.{second}")
        from contin.cancel import is_stopped_branch

        if len(curve) <= 1 and not is_stopped_branch(curve):  # (it ended in 'argmin of an empty sequence', qa17)
            what = curve.kind.replace("-curve", "").replace("hopf", "Hopf").replace("fold", "fold")
            raise ValueError(f"the {what} curve from {point.name} did not start: {curve.message}")
        return curve
    kw: dict[str, Any] = {}
    if regrid is not None:
        if point.type == "HB":  # before the hook check: the clearer message
            raise NotAvailable(NO_REGRID.format(what=f"{point.name} is a Hopf point"))
        from contin.adapt import missing_hooks, on_grid

        missing = missing_hooks(problem)
        if missing:
            raise ValueError(f"adaptive grids need the problem hooks {', '.join(missing)} "
                             f"({type(problem).__name__} lacks them)")
        problem = on_grid(problem, point.grid)  # a point of an adaptive run: its own grid
        problem, point = _resolved_start(problem, point, second, options, regrid)
        kw["regrid"] = regrid
    curve = tracer(problem, point, second, options, parameter=first,
                   branch_id=branch_id if branch_id is not None else f"{point.name}.{second}", **kw)
    from contin.cancel import is_stopped_branch

    if len(curve) <= 1 and not is_stopped_branch(curve):  # (a Ctrl-C before its first step: exit 130, not
        # "did not start: interrupted (Ctrl-C)" with exit 1, qa16; the caller saves the start point)
        raise ValueError(f"the {point.type} curve from {point.name} did not start: {curve.message}")
    return curve
