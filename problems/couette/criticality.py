"""Criticality of the shear-banding pitchfork of uniform shear: threshold and tricritical densities.

Uniform shear of granular plane Couette flow (no-slip, adiabatic walls, no gravity) loses
stability to the n = 1 shear-banding mode at the gap (physics.md section 4)

    H_1^c(nu, e) = pi psi,   psi^2 = (f4/f5) / B(nu, e),
    B = (f1/f1')(f2'/f2 + f5'/f5) - 2.

**Linear-instability threshold** nu_th(e): the root of the bracket B (B < 0 below it, so
psi is not finite and uniform shear has no branch point at any H: the banded branch
"bifurcates from infinity").  At e = 0.8, chi_JJ(0.65): nu_th = 0.15614.

**Pitchfork bend** a(nu): the banded branch leaves the BP as H - H_1^c ~ a delta^2 with
delta = Phi - nu_bar (a > 0 supercritical, a < 0 subcritical).  a = -a3/a1 comes from the
Lyapunov-Schmidt reduction at the uniform state at H_1^c
(:func:`contin.normalform.pitchfork_normal_form`); the stencil step is fixed in delta, not
in the null-vector amplitude, so that the truncation error does not depend on the grid,
and the fourth-order stencil error is removed by one Richardson step (steps d and 2d).

**Tricritical density** nu_tc(e), where a = 0, by two independent routes:

1. normal form: the root of a(nu) (Brent's method), the bend evaluated at the analytic
   H_1^c(nu);
2. continuation: trace uniform shear at a subcritical density nu_fold, switch at its first
   BP, locate the fold (LP) of the banded branch and continue it in (H, nu) with
   :func:`contin.foldcurve.trace_fold_curve`.  Near the tricritical point the normal form
   H - H_1^c = a delta^2 + b delta^4 (a ~ nu - nu_tc, b < 0) puts the fold at
   delta_LP^2 = -a/(2b) and H_LP - H_1^c = -a^2/(4b): the fold curve runs into the BP curve
   tangentially as nu -> nu_tc with nu_tc - nu ~ delta_LP^2.  There the augmented fold system
   itself becomes singular (the BP curve also solves it) and the tracer crawls; the curve's
   end is recognised by delta_LP -> 0 and H_LP -> H_1^c(nu), and nu_tc is the value at
   delta = 0 of a least-squares fit nu(delta) = nu_tc + c2 delta^2 + c3 delta^3 (the cubic
   term because delta = Phi - nu_bar is odd under the reflection only at leading order) to
   the points with |delta| <= ``delta_fit``.

References: M. Alam, YITP 2013 slides (seeds/001); Golubitsky & Schaeffer (1985) ch. III-IV
(tricritical / degenerate pitchfork); Moore & Spence (1980) (fold continuation).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
import numpy as np
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint
from contin.continuation import switch, trace
from contin.foldcurve import trace_fold_curve
from contin.normalform import null_vectors, pitchfork_normal_form
from contin.options import ContinuationOptions, NewtonOptions, StepOptions
from problems.couette.closures import coefficients, critical_gap_factor, packing_limit
from problems.couette.model import CouetteProblem

__all__ = [
    "Bend",
    "BandedFold",
    "FoldCurveEnd",
    "TricriticalNormalForm",
    "banded_fold",
    "bend_from_branches",
    "critical_gap",
    "instability_bracket",
    "pitchfork_bend",
    "pitchfork_halves",
    "threshold_density",
    "tricritical_by_fold_curve",
    "tricritical_density_normal_form",
    "uniform_shear_bp",
]


# --------------------------------------------------------------------------- analytic

def instability_bracket(nu: float, e: float, *, chi: str = "jj", num: float = 0.65) -> float:
    """B(nu, e) = (f1/f1')(f2'/f2 + f5'/f5) - 2 (physics.md section 4); psi is finite iff B > 0."""
    c = coefficients(np.float64(nu), e, chi, num)
    return float((c.f1 / c.f1_nu) * (c.f2_nu / c.f2 + c.f5_nu / c.f5) - 2.0)


def critical_gap(nu: float, e: float, n: int = 1, *, chi: str = "jj", num: float = 0.65) -> float:
    """H_n^c = n pi psi(nu, e); ValueError where uniform shear is linearly stable at every H."""
    psi = float(critical_gap_factor(np.float64(nu), e, chi, num))
    if not math.isfinite(psi):
        raise ValueError(f"uniform shear at nu = {nu:g}, e = {e:g} is stable at every gap (psi is not finite: "
                         "below the linear-instability threshold density)")
    return n * math.pi * psi


def threshold_density(e: float, *, chi: str = "jj", num: float = 0.65, xtol: float = 1e-14) -> float:
    """nu_th(e): the lowest density where B(nu, e) changes sign from - to + (psi becomes finite).

    The bracket is scanned on 2000 points of (0, packing limit) and the sign change refined
    by Brent's method.  At e = 0.8 (chi_JJ, nu_m = 0.65): 0.156138560298.
    """
    if not 0.0 < e < 1.0:
        raise ValueError(f"the threshold density needs 0 < e < 1, got e = {e:g}")
    top = packing_limit(chi, num)
    grid = np.linspace(1e-4, top * (1 - 1e-4), 2000)
    c = coefficients(grid, e, chi, num)
    b = (c.f1 / c.f1_nu) * (c.f2_nu / c.f2 + c.f5_nu / c.f5) - 2.0
    up = np.nonzero((b[:-1] < 0) & (b[1:] > 0))[0]
    if up.size == 0:
        raise ValueError(f"B(nu, e = {e:g}) has no sign change from - to + in (0, {top:g}): no threshold density")
    i = int(up[0])
    from scipy.optimize import brentq  # lazily: scipy.optimize is slow to import

    return float(brentq(lambda nu: instability_bracket(nu, e, chi=chi, num=num), grid[i], grid[i + 1],
                        xtol=xtol, rtol=4 * np.finfo(float).eps))


# --------------------------------------------------------------------------- normal form

@dataclass(frozen=True)
class Bend:
    """The pitchfork bend at (nu, e): H - H_c ~ a delta^2.

    a : Richardson-extrapolated bend -a3/a1 (> 0 supercritical)
    a_coarse : the bend with delta stencil 2d (a - a_coarse estimates the stencil error x 16)
    ratio : a3/a1 (= -a), the grid-independent quantity
    """

    nu: float
    e: float
    H_c: float
    a: float
    a_coarse: float
    ratio: float
    a3: float
    a1: float
    delta_step: float

    @property
    def criticality(self) -> str:
        return "supercritical" if self.a > 0 else "subcritical"

    @property
    def error(self) -> float:
        """Estimated stencil error of ``a`` (the Richardson correction)."""
        return abs(self.a - self.a_coarse) / 15.0


def _rounding_floor(problem: CouetteProblem, u: np.ndarray, p: dict[str, float]) -> tuple[float, np.ndarray]:
    """eps ||J||_inf max(1, ||u||_inf): the residual reachable on this grid, and J."""
    jac = sp.csr_matrix(problem.jacobian(u, p))
    norm = float(abs(jac).sum(axis=1).max())
    return np.finfo(float).eps * norm * max(1.0, float(np.abs(u).max())), jac


def pitchfork_bend(problem: CouetteProblem, nu: float, e: float, *, num: float = 0.65,
                   delta_step: float = 5e-4) -> Bend:
    """Bend a(nu) of the n = 1 pitchfork by Lyapunov-Schmidt reduction at (uniform shear, H_1^c).

    The null vector phi has unit Euclidean norm, so the same amplitude x means a different
    delta = kappa x on different grids; the stencil step is therefore amplitude = d / |kappa|
    with d = ``delta_step``, evaluated at d and 2d and combined as a(d) + (a(d) - a(2d))/15
    (the stencil error is O(d^4)).  The corrector tolerance is the grid's rounding floor with
    one polishing step (Chebyshev N = 48: ~1e-10 instead of the default 1e-13).
    """
    p = problem.params({"nu": nu, "e": e, "num": num})
    p["H"] = critical_gap(nu, e, chi=problem.chi, num=num)
    u = problem.uniform_state(p)
    tol, jac = _rounding_floor(problem, u, p)
    phi = null_vectors(sp.csc_matrix(jac)).phi
    kappa = abs(float(phi[problem.i_nu][-1]))  # Phi = nu(1/2) is linear in the state
    forms = [pitchfork_normal_form(problem, u, p, "H", amplitude=d / kappa, tol=tol, polish=1)
             for d in (delta_step, 2 * delta_step)]
    fine, coarse = forms[0].bend, forms[1].bend
    a = fine + (fine - coarse) / 15.0
    return Bend(nu=float(nu), e=float(e), H_c=float(p["H"]), a=float(a), a_coarse=float(coarse),
                ratio=float(-a), a3=float(forms[0].a3), a1=float(forms[0].a1), delta_step=float(delta_step))


@dataclass(frozen=True)
class TricriticalNormalForm:
    """nu_tc where the bend a(nu) vanishes, and the samples that bracketed it."""

    nu_tc: float
    H_tc: float
    samples: tuple[tuple[float, float], ...]  # (nu, a) of the scan
    evaluations: int


def tricritical_density_normal_form(problem: CouetteProblem, e: float, *, num: float = 0.65,
                                    nu_th: float | None = None, xtol: float = 1e-10) -> TricriticalNormalForm:
    """Root of a(nu) above the threshold: scan nu_th + (0.002 ... 0.2), then Brent's method.

    Raises ValueError when a(nu) does not change sign from - to + in the scan (no subcritical
    range above the threshold, or no supercritical range below nu_th + 0.2).
    """
    if nu_th is None:
        nu_th = threshold_density(e, chi=problem.chi, num=num)
    top = packing_limit(problem.chi, num)
    offsets = (0.002, 0.005, 0.01, 0.02, 0.04, 0.08, 0.14, 0.2)
    nus = [nu_th + d for d in offsets if nu_th + d < 0.9 * top]
    count = 0

    def a_of(nu: float) -> float:
        nonlocal count
        count += 1
        return pitchfork_bend(problem, nu, e, num=num).a

    samples: list[tuple[float, float]] = []
    for nu in nus:
        samples.append((nu, a_of(nu)))
        if len(samples) > 1 and samples[-2][1] < 0 < samples[-1][1]:
            break
    else:
        raise ValueError(f"the pitchfork bend a(nu) at e = {e:g} has no sign change from subcritical to "
                         f"supercritical in nu = {nus[0]:.4g} ... {nus[-1]:.4g}")
    lo, hi = samples[-2][0], samples[-1][0]
    from scipy.optimize import brentq

    nu_tc = float(brentq(a_of, lo, hi, xtol=xtol))
    return TricriticalNormalForm(nu_tc=nu_tc, H_tc=critical_gap(nu_tc, e, chi=problem.chi, num=num),
                                 samples=tuple(samples), evaluations=count)


# --------------------------------------------------------------------------- continuation

def _uniform_options(h_lo: float, h_hi: float, h_c: float, max_steps: int = 200) -> ContinuationOptions:
    # Uniform shear does not depend on H, so steps may be long; they must stay below
    # H_1^c / 2 so that the BPs at H_1^c and H_2^c = 2 H_1^c never share a step.
    ds_max = 0.1 * h_c
    return ContinuationOptions(bounds={"H": (h_lo, h_hi)}, max_steps=max_steps,
                               step=StepOptions(ds=min(0.02 * h_c, ds_max), ds_max=ds_max))


def uniform_shear_bp(problem: CouetteProblem, nu: float, e: float, *, num: float = 0.65,
                     h_range: tuple[float, float] | None = None,
                     options: ContinuationOptions | None = None,
                     branch_id: str = "0") -> tuple[Branch, SpecialPoint | None]:
    """Trace uniform shear in H and return (branch, first symmetry-breaking BP or None).

    ``h_range`` defaults to (0.5, 1.5) H_1^c around the analytic value (only the n = 1 BP lies
    inside); below the threshold density give it explicitly (e.g. (1, 2000)) to check that
    there is no BP at all.
    """
    p = problem.params({"nu": nu, "e": e, "num": num})
    if h_range is None:
        h_c = critical_gap(nu, e, chi=problem.chi, num=num)
        h_range = (0.5 * h_c, 1.5 * h_c)
    h_lo, h_hi = h_range
    scale = (h_hi - h_lo) / 2.0
    opts = options or _uniform_options(h_lo, h_hi, scale, max_steps=400)
    p["H"] = float(h_lo)
    branch = trace(problem, problem.uniform_state(p), p, "H", opts, branch_id=branch_id, kind="uniform shear")
    bps = [b for b in branch.branch_points if "symmetry-breaking" in b.note]
    return branch, (bps[0] if bps else None)


@dataclass
class BandedFold:
    """Uniform shear, the n = 1 banded branch switched at its BP, and the banded branch's fold."""

    uniform: Branch
    banded: Branch
    bp: SpecialPoint
    lp: SpecialPoint
    H_c: float


def banded_fold(problem: CouetteProblem, nu: float, e: float, *, num: float = 0.65,
                prefix: str = "1") -> BandedFold:
    """Locate the fold of the subcritical n = 1 banded branch at density ``nu``.

    Trace uniform shear across H_1^c, switch at the BP (one half of the pitchfork: the two
    halves are mirror images) and trace the banded branch down in H until its fold (stop_at
    LP1).  The first step off the BP is small (1e-4) because a strongly subcritical branch
    (a ~ -8e4 at nu = 0.16) leaves the BP almost parallel to the H axis of the arclength norm;
    not smaller: at 1e-5 the first points differ from the BP in H by ~1e-7, the BP's own
    location tolerance at H_c ~ 156 (e = 0.95), and their rounding made a spurious LP there.
    An LP within 1e-6 H_c of the BP is rejected as such noise.
    """
    h_c = critical_gap(nu, e, chi=problem.chi, num=num)
    uniform, bp = uniform_shear_bp(problem, nu, e, num=num, h_range=(0.8 * h_c, 1.2 * h_c), branch_id=prefix)
    if bp is None:
        raise ValueError(f"uniform shear at nu = {nu:g}, e = {e:g} shows no BP near H_1^c = {h_c:.6g}")
    # stop at the fold: the branch beyond it climbs back towards dense plugs that the grid need
    # not resolve, and nothing here uses it
    opts = ContinuationOptions(bounds={"H": (0.02 * h_c, 1.5 * h_c)}, max_steps=250,
                               step=StepOptions(ds=1e-3, ds_max=0.04 * h_c), detect_closed=False,
                               stop_at=("LP1",))
    halves = switch(problem, uniform, bp, opts, directions=(+1,), ds=1e-4, branch_id_prefix=f"{prefix}.n1")
    if not halves:
        raise ValueError(f"branch switching at the BP of uniform shear (nu = {nu:g}, H = {bp.params['H']:.6g}) failed")
    banded = halves[0]
    folds = [lp for lp in banded.fold_points if lp.params["H"] < bp.params["H"] * (1 - 1e-6)]
    if not folds and banded.fold_points:
        raise ValueError(f"the n = 1 banded branch at nu = {nu:g}, e = {e:g} turned within 1e-6 H_c of its BP "
                         "(an LP at the BP's location tolerance, not a fold)")
    if not folds:
        raise ValueError(f"the n = 1 banded branch at nu = {nu:g}, e = {e:g} has no fold below H_1^c "
                         "(the pitchfork is not subcritical there)")
    return BandedFold(uniform=uniform, banded=banded, bp=bp, lp=folds[0], H_c=h_c)


@dataclass
class FoldCurveEnd:
    """Where the fold curve ends on the BP curve, and the tricritical density from it.

    nu_end, H_end, delta_end : the traced point with the smallest |delta|
    gap_end : H_end - H_1^c(nu_end) (-> 0 at the end)
    nu_tc : nu at delta = 0 from the fit nu = nu_tc + c2 delta^2 + c3 delta^3
    nu_tc_error : the change of nu_tc when a delta^4 term is added to the fit (an error estimate)
    fit_points : distinct points (crawling steps merged) in the fit window delta_fit
    """

    branch: Branch
    nu_tc: float
    H_tc: float
    nu_end: float
    H_end: float
    delta_end: float
    gap_end: float
    nu_tc_error: float
    fit_points: int
    c2: float
    delta_fit: float
    notes: list[str] = field(default_factory=list)


def on_parabola_prefix(delta: np.ndarray, nu: np.ndarray, *, window: float = 0.01, factor: float = 3.0) -> int:
    """How many leading fold-curve points lie on the fold curve proper near its end.

    Near the tricritical point the fold curve is the parabola nu = nu_tc + c2 delta^2, so
    consecutive points have (nu_j - nu_{j-1}) / (delta_j^2 - delta_{j-1}^2) ~ c2.  The BP
    curve (uniform shear at H_1^c(nu), where the fold system is also solved, delta = 0 up to
    noise) crosses it at the tricritical point; a tracer that steps onto it keeps moving in nu
    with delta at noise level, and that ratio jumps.  Returns the index of the first point
    (|delta| < window) whose ratio is off the median of the earlier ones by more than
    ``factor``, else len(delta).  Crawling steps (delta^2 changed by < 1 %) are not tested.
    """
    d2 = np.asarray(delta, float) ** 2
    ratios: list[float] = []
    for j in range(1, d2.size):
        dd = d2[j] - d2[j - 1]
        if abs(delta[j]) > window or abs(dd) <= 1e-2 * d2[j - 1]:
            continue
        r = (nu[j] - nu[j - 1]) / dd
        if len(ratios) >= 2:
            q = r / float(np.median(ratios))
            if not 1 / factor <= q <= factor:
                return j
        ratios.append(r)
    return int(d2.size)


def _clusters(delta: np.ndarray, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge the points where the tracer crawled (|delta| equal to 1 %) into their mean.

    Near the tricritical point the augmented system is nearly singular and the tracer takes
    many tiny steps whose nu scatter at the 1e-9 level; as separate points they would
    dominate the least-squares fit.
    """
    order = np.argsort(np.abs(delta))
    d, n = np.abs(delta[order]), nu[order]
    groups: list[list[int]] = [[0]]
    for k in range(1, d.size):
        if d[k] <= 1.01 * d[groups[-1][0]]:
            groups[-1].append(k)
        else:
            groups.append([k])
    sign = np.sign(np.median(delta))  # one half of the fold curve: delta has one sign
    return (np.array([sign * d[g].mean() for g in groups]), np.array([n[g].mean() for g in groups]))


def _fit_end(delta: np.ndarray, nu: np.ndarray, window: float, degree: int = 3) -> tuple[float, float, int]:
    """nu(0) and c2 of nu = nu_tc + c2 delta^2 + ... + c_degree delta^degree on |delta| <= window."""
    sel = np.abs(delta) <= window
    d, n = delta[sel], nu[sel]
    if d.size < degree + 1:
        raise ValueError(f"only {d.size} fold-curve points with |delta| <= {window:g}; cannot extrapolate to delta = 0")
    a = np.column_stack([np.ones_like(d)] + [d**k for k in range(2, degree + 1)])
    coef = np.linalg.lstsq(a, n, rcond=None)[0]
    return float(coef[0]), float(coef[1]), int(d.size)


def _end_of_curve(curve: Branch) -> str:
    """Turn the tracer's failure at the tricritical point into the curve's regular end.

    The augmented fold system is singular where the fold curve meets the BP curve (the BP
    curve solves it too), so the tracer stops there with MX; once the caller has checked that
    the curve did reach the BP curve, that stop is the expected end point (EP).
    """
    if curve.status != "MX":
        return curve.message
    reason = curve.message
    curve.special_points = [replace(s, type="EP", note=f"fold curve ends on the BP curve (tricritical point); "
                                     f"the tracer stopped: {s.note}") if s.type == "MX" else s
                            for s in curve.special_points]
    curve.status = "EP"
    curve.message = f"ended on the BP curve at the tricritical point (tracer stopped: {reason})"
    return curve.message


def tricritical_by_fold_curve(problem: CouetteProblem, fold: BandedFold, e: float, *, num: float = 0.65,
                              delta_fit: float = 0.006, max_steps: int = 120,
                              options: ContinuationOptions | None = None) -> FoldCurveEnd:
    """Continue the banded branch's fold in (H, nu) until it ends on the BP curve.

    The fold curve is traced towards smaller H (larger nu: the subcritical fold shrinks onto
    the BP as nu -> nu_tc).  It must come within |delta| < delta_fit / 4 of the BP curve;
    otherwise ValueError (the curve left through a bound or the tracer gave up early).  A
    final MX at the BP curve becomes the curve's EP (see :func:`_end_of_curve`).

    nu_tc is extrapolated from the points with |delta| <= delta_fit (window doubled until it
    holds 5 distinct points); its error estimate is the change when a delta^4 term is added.
    """
    h_c = fold.H_c
    opts = options or ContinuationOptions(
        bounds={"H": (0.02 * h_c, 2.0 * h_c)}, max_steps=max_steps, detect_closed=False,
        # ds_max 0.01 H_c: with 0.03 the step that reaches |delta| ~ 3e-4 can land on the BP
        # curve (uniform states at H_1^c(nu), which also solve the fold system) and run along
        # it, depending on rounding (it did with one BLAS thread and not with two)
        step=StepOptions(ds=-0.002 * h_c, ds_max=0.01 * h_c, ds_min=1e-9),
        newton=NewtonOptions(max_iterations=12))
    curve = trace_fold_curve(problem, fold.lp, "nu", opts, parameter="H", both=False, branch_id="fold")
    keep = on_parabola_prefix(curve.observables["delta"], curve.params["nu"])
    delta = curve.observables["delta"][:keep]
    nu = curve.params["nu"][:keep]
    H = curve.params["H"][:keep]
    i = int(np.argmin(np.abs(delta)))
    if not abs(delta[i]) < delta_fit / 4:
        raise ValueError(f"the fold curve did not reach the BP curve: smallest |delta| = {abs(delta[i]):.3g} at "
                         f"nu = {nu[i]:.6g}, H = {H[i]:.6g} ({curve.message})")
    message = _end_of_curve(curve)
    d, n = _clusters(delta, nu)
    window = delta_fit
    while np.sum(np.abs(d) <= window) < 5 and window < 0.1:
        window *= 2
    nu_tc, c2, count = _fit_end(d, n, window)
    nu_tc4, _, _ = _fit_end(d, n, window, degree=4)
    gap = H[i] - critical_gap(nu[i], e, chi=problem.chi, num=num)
    notes = [f"fold curve: {len(curve)} points, closest approach to the BP curve |delta| = {abs(delta[i]):.2e} at "
             f"nu = {nu[i]:.9f}, H = {H[i]:.6f} (H - H_1^c = {gap:.2e}); {message}"]
    if keep < len(curve):
        notes.append(f"fold curve: the last {len(curve) - keep} points left the parabola nu = nu_tc + c2 delta^2 "
                     f"(the tracer crossed onto the BP curve at nu = {curve.params['nu'][keep]:.9f}); not used in the fit")
    return FoldCurveEnd(branch=curve, nu_tc=nu_tc, H_tc=critical_gap(nu_tc, e, chi=problem.chi, num=num),
                        nu_end=float(nu[i]), H_end=float(H[i]), delta_end=float(delta[i]), gap_end=float(gap),
                        nu_tc_error=float(abs(nu_tc4 - nu_tc)), fit_points=count, c2=c2, delta_fit=window,
                        notes=notes)


def bend_from_branches(branches: Sequence[Branch], H_c: float, nu: float, *, delta_max: float = 0.02,
                       ) -> tuple[float, float, int]:
    """Finite-amplitude bend: least squares H - H_c = a delta^2 + b delta^3 + c delta^4 on the
    points of ``branches`` (both halves of a pitchfork) with 1e-9 < |delta| <= delta_max.

    Returns (a, b, number of points).  Compare a with :func:`pitchfork_bend`.
    """
    ds, hs = [], []
    for b in branches:
        d = b.observables["phi"] - nu
        # points of uniform shear (the BP itself) carry delta at rounding level only
        sel = (np.abs(d) > 1e-9) & (np.abs(d) <= delta_max)
        ds.append(d[sel])
        hs.append(b.params["H"][sel] - H_c)
    d = np.concatenate(ds)
    h = np.concatenate(hs)
    if d.size < 5:
        raise ValueError(f"only {d.size} branch points with |delta| <= {delta_max:g}; need 5 for the bend fit")
    coef = np.linalg.lstsq(np.column_stack([d**2, d**3, d**4]), h, rcond=None)[0]
    return float(coef[0]), float(coef[1]), int(d.size)


def pitchfork_halves(problem: CouetteProblem, uniform: Branch, bp: SpecialPoint, *, delta_max: float = 0.05,
                     prefix: str = "0") -> list[Branch]:
    """Both halves of the n = 1 banded branch near its BP, traced until |delta| ~ delta_max."""
    h_c = bp.params["H"]
    opts = ContinuationOptions(bounds={"H": (0.5 * h_c, 1.5 * h_c)}, max_steps=60, detect_closed=False,
                               step=StepOptions(ds=1e-3, ds_max=2e-3 * h_c))
    halves = switch(problem, uniform, bp, opts, ds=1e-5, branch_id_prefix=f"{prefix}.n1")
    out = []
    for b in halves:
        d = np.abs(b.observables["phi"] - bp.params["nu"])
        beyond = np.nonzero(d > delta_max)[0]
        out.append(b if beyond.size == 0 else _truncate(b, int(beyond[0]) + 1))
    return out


def _truncate(branch: Branch, n: int) -> Branch:
    """The first ``n`` points of a branch (its special points beyond them dropped)."""
    keep = [s for s in branch.special_points if s.index < n]
    rows = np.arange(n) if branch.state_index is None else np.flatnonzero(branch.state_index < n)
    return replace(
        branch,
        params={k: v[:n] for k, v in branch.params.items()},
        observables={k: v[:n] for k, v in branch.observables.items()},
        states=branch.states[rows],
        tangents=branch.tangents[:n],
        ds=branch.ds[:n],
        newton_iterations=branch.newton_iterations[:n],
        special_points=keep,
        state_index=None if branch.state_index is None else branch.state_index[rows],
        stable=None if branch.stable is None else branch.stable[:n],
        n_unstable=None if branch.n_unstable is None else branch.n_unstable[:n],
        eigenvalues=None if branch.eigenvalues is None else branch.eigenvalues[:n],
        message=f"{branch.message}; kept the first {n} points (|delta| <= bend-fit window)",
    )
