"""Criticality of the first shear-banding pitchfork of 2-D uniform shear (scene ``disks-criticality``).

At (uniform shear, H_1^c) of :class:`problems.disks.model.DiskCouetteProblem` (no-slip walls) the
bend a of H - H_1^c ~ a delta^2 (delta = Phi - nu_bar) comes from contin's Lyapunov-Schmidt normal
form (:func:`contin.normalform.pitchfork_normal_form`, a = -a3/a1 > 0 supercritical), with the
stencil Richardson-extrapolated as in problems.couette.criticality; the fold route fits
H - H_c = a delta^2 + b delta^3 + c delta^4 to the switched banded branch near the BP.  The
tricritical area fraction is the root of a(nu) (Brent).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize as so
import scipy.sparse as sp

from contin.continuation import switch, trace
from contin.normalform import null_vectors, pitchfork_normal_form
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from problems.disks.closures import critical_gaps
from problems.disks.model import DiskCouetteProblem


@dataclass(frozen=True)
class Bend:
    nu: float
    e: float
    H_c: float
    a: float
    a_coarse: float

    @property
    def criticality(self) -> str:
        return "supercritical" if self.a > 0 else "subcritical"

    @property
    def error(self) -> float:
        return abs(self.a - self.a_coarse) / 15.0


def pitchfork_bend(problem: DiskCouetteProblem, nu: float, e: float, *, delta_step: float = 5e-4,
                   extra: dict[str, float] | None = None) -> Bend:
    """Bend a of the n = 1 pitchfork at (nu, e) by normal form (Richardson over stencils d, 2d)."""
    p = problem.params({**(extra or {}), "nu": nu, "e": e})
    hc = critical_gaps(p, problem.closure, 1)[0]
    if not math.isfinite(hc):
        raise ValueError(f"uniform shear at nu = {nu:g}, e = {e:g} has no pitchfork (psi not finite)")
    p["H"] = hc
    u = problem.uniform_state(p)
    jac = sp.csc_matrix(problem.jacobian(u, p))
    tol = np.finfo(float).eps * float(abs(jac).sum(axis=1).max()) * max(1.0, float(np.abs(u).max()))
    phi = null_vectors(jac).phi
    kappa = abs(float(phi[problem.i_nu][-1]))
    forms = [pitchfork_normal_form(problem, u, p, "H", amplitude=d / kappa, tol=tol, polish=1)
             for d in (delta_step, 2 * delta_step)]
    fine, coarse = forms[0].bend, forms[1].bend
    return Bend(nu=float(nu), e=float(e), H_c=float(hc), a=float(fine + (fine - coarse) / 15.0), a_coarse=float(coarse))


def bend_by_branch(problem: DiskCouetteProblem, nu: float, e: float, *, delta_max: float = 0.02,
                   extra: dict[str, float] | None = None) -> tuple[float, Any]:
    """The fold route: trace uniform shear across H_1^c, switch, fit H - H_c = a d^2 + b d^3 + c d^4
    on |delta| <= delta_max of the banded half; returns (a, banded branch)."""
    p = problem.params({**(extra or {}), "nu": nu, "e": e})
    hc = critical_gaps(p, problem.closure, 1)[0]
    p["H"] = 0.9 * hc
    opts = ContinuationOptions(bounds={"H": (0.9 * hc, 1.1 * hc)}, max_steps=50,
                               step=StepOptions(ds=0.05 * hc, ds_max=0.05 * hc),
                               detection=DetectionOptions(locate_tol=1e-12))
    base = trace(problem, problem.uniform_state(p), p, "H", opts)
    bps = [b for b in base.branch_points if "symmetry-breaking" in b.note]
    if not bps:
        raise ValueError(f"no symmetry-breaking BP on uniform shear near H_1^c = {hc:.6g}")
    bp = bps[0]
    o2 = ContinuationOptions(bounds={"H": (0.5 * hc, 1.5 * hc)}, max_steps=60, detect_closed=False,
                             step=StepOptions(ds=2e-3, ds_max=0.01 * hc))
    (band,) = switch(problem, base, bp, o2, directions=(+1,), ds=1e-3)
    d = band.observables["phi"] - nu
    h = band.parameter_values - bp.params["H"]
    keep = (np.abs(d) <= delta_max) & (np.abs(d) > 1e-6)
    if keep.sum() < 5:
        raise ValueError("too few banded points within delta_max of the BP for the fold-route fit")
    A = np.column_stack([d[keep] ** 2, d[keep] ** 3, d[keep] ** 4])
    coef = np.linalg.lstsq(A, h[keep], rcond=None)[0]
    return float(coef[0]), band


def tricritical(problem: DiskCouetteProblem, e: float, nus: np.ndarray, bends: np.ndarray, *,
                extra: dict[str, float] | None = None, xtol: float = 1e-8) -> list[float]:
    """Every root of a(nu) bracketed by sign changes of the sampled ``bends``, refined by Brent."""
    roots = []
    ok = np.isfinite(bends)
    for i in range(len(nus) - 1):
        if ok[i] and ok[i + 1] and np.sign(bends[i]) != np.sign(bends[i + 1]):
            roots.append(float(so.brentq(lambda v: pitchfork_bend(problem, v, e, extra=extra).a,
                                         nus[i], nus[i + 1], xtol=xtol)))
    return roots


def threshold_density(p: dict[str, float], closure: Any, *, lo: float = 1e-3, hi: float | None = None) -> float:
    """Largest area fraction below ``hi`` (default 0.999 phi_inf) where psi stops being finite:
    the root of the bracket of :func:`problems.disks.closures.critical_gap_factor` (nan if none)."""
    from problems.disks.closures import uniform_temperature

    def bracket(nu: float) -> float:
        q = {**p, "nu": nu}
        t0 = uniform_temperature(np.float64(nu), q, closure)
        tr = closure.transport(np.float64(nu), t0, q)
        return float((tr.mu_nu + tr.D_nu) - (tr.mu_T + tr.D_T) * tr.p_nu / tr.p_T)

    top = 0.999 * p["phi_inf"] if hi is None else hi
    grid = np.linspace(lo, top, 500)
    vals = np.array([bracket(v) for v in grid])
    change = np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))
    if change.size == 0:
        return math.nan
    i = int(change[0])
    return float(so.brentq(bracket, grid[i], grid[i + 1], xtol=1e-14, rtol=1e-14))
