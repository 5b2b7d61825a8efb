"""Scene ``bp-curve``: the symmetry-breaking pitchfork of uniform shear continued in (nu, H).

The first BP of uniform shear at density ``nu`` (``problems.couette.criticality.uniform_shear_bp``)
is continued in two parameters by ``contin.bpcurve.trace_bp_curve`` between ``nu_min`` and
``nu_max`` (and below ``H_max``): the curve H_1^c(nu) at fixed e, checked point by point against
the closed form pi psi(nu, e) (physics.md sec. 4).  ``extra``: nu range reached, number of points,
max relative deviation from pi psi.  Branches: '0' uniform shear, 'bp-curve' the curve.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from contin.bpcurve import trace_bp_curve
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult
from problems.couette import criticality as cr
from problems.couette.closures import critical_gap_factor
from problems.couette.criticality_scenes import _problem, _result, _settings

BP_CURVE_DEFAULTS: dict[str, Any] = {"nu": 0.3, "e": 0.8, "nu_min": 0.2, "nu_max": 0.5, "H_max": 1000.0,
                                     "chi": "jj", "num": 0.65}


def run_bp_curve(request: SceneRequest) -> SceneResult:
    s = _settings(request, BP_CURVE_DEFAULTS, "bp-curve")
    e, chi, num, nu = s["e"], s["chi"], s["num"], s["nu"]
    lo, hi, h_max = s["nu_min"], s["nu_max"], s["H_max"]
    if not lo <= nu <= hi:
        raise SceneError(f"nu = {nu:g} must lie in [nu_min, nu_max] = [{lo:g}, {hi:g}]")
    pb = _problem(request, chi)
    if not math.isfinite(float(critical_gap_factor(np.float64(nu), e, chi, num))):
        raise SceneError(f"uniform shear at nu = {nu:g}, e = {e:g} has no BP (below the threshold density)")
    try:
        base, bp = cr.uniform_shear_bp(pb, nu, e, num=num)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if bp is None:
        raise SceneError(f"continuation of uniform shear at nu = {nu:g}, e = {e:g} found no symmetry-breaking BP")
    request.finished(base)
    bp_h = bp.params["H"]
    if not bp_h < h_max:
        raise SceneError(f"H_1^c = {bp_h:.6g} at nu = {nu:g} is not below H_max = {h_max:g}")
    opts = request.options_for(ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), max_steps=400,
                                                   bounds={"nu": (lo, hi), "H": (1e-3, h_max)}))
    try:
        curve = trace_bp_curve(pb, bp, "H", opts, parameter="nu", branch_id="bp-curve")
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    curve.parent = f"BP@{base.id}"
    nus, hs = curve.params["nu"], curve.params["H"]
    ref = np.array([math.pi * float(critical_gap_factor(np.float64(v), e, chi, num)) for v in nus])
    dev = float(np.nanmax(np.abs(hs - ref) / ref)) if len(nus) else math.nan
    request.finished(curve)
    note = (f"BP curve H_1^c(nu) from nu = {nus.min():.6g} to {nus.max():.6g} ({len(nus)} points): "
            f"max relative deviation from pi psi(nu, e) {dev:.1e}")
    extra = {"nu": nu, "e": e, "nu_reached": [float(nus.min()), float(nus.max())], "points": int(len(nus)),
             "max_rel_deviation": dev, "status": curve.status, "message": curve.message}
    return _result(pb, [base, curve], {k: s[k] for k in BP_CURVE_DEFAULTS}, [note], extra)


SCENES: dict[str, Scene] = {
    "bp-curve": Scene(
        name="bp-curve",
        summary="gPCF: the symmetry-breaking pitchfork H_1^c(nu) continued in (nu, H), checked against pi psi",
        defaults=BP_CURVE_DEFAULTS,
        run=run_bp_curve,
        x="nu",
        y="H",
    ),
}
