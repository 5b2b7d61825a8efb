"""Scenes ``criticality`` and ``critical-gap`` (registered as the entry point
``contin.scenes: criticality``; logic in :mod:`problems.couette.criticality`).

``criticality`` (no-slip, adiabatic walls, no gravity), for given e, chi, num:
  - H_1^c(nu, e) = pi psi (analytic) and the BP located by continuation of uniform shear at
    density ``nu`` (default 0.3), with the pitchfork bend a there from the normal form and from
    a finite-amplitude fit of the two halves of the computed banded branch (|delta| <= 0.02);
  - the linear-instability threshold nu_th(e) (root of the bracket of psi);
  - the tricritical density nu_tc(e) where a = 0, from the normal form (root of a(nu)) and,
    independently, by continuation: the fold of the subcritical banded branch at ``nu_fold``
    (default ``auto`` = nu_th + 0.2 (nu_tc - nu_th); 0.16025 at e = 0.8) continued in (H, nu)
    until it ends on the BP curve.
  ``extra`` holds every number (keys documented in :func:`run_criticality`); branches: '0'
  uniform shear at nu, '0.n1.1'/'0.n1.2' the banded halves near its BP, '1' uniform shear at
  nu_fold, '1.n1.1' the banded branch through the fold, 'fold' the fold curve in (H, nu).
``critical-gap``: at one (nu, e): H_1^c analytic and by continuation (uniform shear traced
  over (0.5, 1.5) H_1^c), or, below the threshold, the check that uniform shear has no BP up to
  ``H_max`` (default 2000).  For the H_1^c(nu, e) contour sweep.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.branch import Branch, relabel
from contin.scene import Scene, SceneError, SceneRequest, SceneResult, scene_number, scene_params
from problems.couette import criticality as cr
from problems.couette.closures import CHI_MODELS, critical_gap_factor
from problems.couette.model import CouetteProblem
from problems.couette.params import build_params

CRITICALITY_DEFAULTS: dict[str, Any] = {"e": 0.8, "nu": 0.3, "nu_fold": "auto", "chi": "jj", "num": 0.65}
CRITICAL_GAP_DEFAULTS: dict[str, Any] = {"nu": 0.3, "e": 0.8, "chi": "jj", "num": 0.65, "H_max": 2000.0}
DEFAULT_GRID = 32


def _settings(request: SceneRequest, defaults: Mapping[str, Any], scene: str) -> dict[str, Any]:
    """Defaults merged with the user's values, each checked (SceneError: one sentence)."""
    values = scene_params(request, defaults, scene)
    if values["chi"] not in CHI_MODELS:
        raise SceneError(f"unknown radial distribution chi = {values['chi']!r}; choose one of {', '.join(CHI_MODELS)}")
    for name, value in values.items():
        if name == "chi" or (name == "nu_fold" and value == "auto"):
            continue
        values[name] = scene_number(scene, name, value)
    try:
        build_params({"nu": values["nu"], "e": values["e"], "num": values["num"]}, chi=values["chi"])
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if not values["e"] < 1.0:
        raise SceneError(f"parameter e = {values['e']:g} is out of range for scene {scene!r}; uniform shear needs "
                         "e < 1 (no steady temperature without dissipation)")
    return values


def _problem(request: SceneRequest, chi: str) -> CouetteProblem:
    try:
        return CouetteProblem(request.method or "cheb", request.grid or DEFAULT_GRID, chi=chi,
                              engine=request.engine or "numpy")
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _result(pb: CouetteProblem, branches: list[Branch], parameters: dict[str, Any], notes: list[str],
            extra: dict[str, Any]) -> SceneResult:
    relabel(branches)
    n = pb.size
    return SceneResult(
        branches=branches,
        parameters=parameters,
        discretization={"method": pb.method, "intervals": pb.N, "engine": pb.engine},
        y=pb.grid.y,
        # fold-curve states are [u, phi, nu]: their first block is the Couette state
        profiles=lambda state: pb.profiles(np.asarray(state)[:n]),
        notes=notes,
        extra=extra,
    )


def run_criticality(request: SceneRequest) -> SceneResult:
    """Threshold and tricritical densities at one e (module docstring).

    ``extra`` keys: e, chi, num, grid; nu, H1c_analytic, H1c_continuation, H1c_rel_error,
    bend_normal_form (a at nu), bend_fit (finite-amplitude fit), bend_fit_points, criticality;
    nu_th; nu_tc_normal_form, H_tc_normal_form, normal_form_evaluations; nu_fold, H_LP, phi_LP;
    nu_tc_fold_curve, H_tc_fold_curve, fold_curve_end {nu, H, delta, H_minus_H1c},
    nu_tc_fit_error; nu_tc_difference (fold curve - normal form).
    """
    s = _settings(request, CRITICALITY_DEFAULTS, "criticality")
    e, chi, num, nu = s["e"], s["chi"], s["num"], s["nu"]
    pb = _problem(request, chi)
    notes: list[str] = []
    branches: list[Branch] = []

    def emit(branch: Branch) -> None:
        branches.append(branch)
        relabel(branches)
        request.finished(branch)

    try:
        request.report("criticality: threshold density")
        nu_th = cr.threshold_density(e, chi=chi, num=num)
        if s["nu_fold"] != "auto" and not s["nu_fold"] > nu_th:
            raise SceneError(f"nu_fold = {s['nu_fold']:g} must lie in the subcritical range above the threshold "
                             f"density nu_th = {nu_th:.6f} (and below the tricritical density)")
        if not nu > nu_th:
            raise SceneError(f"nu = {nu:g} lies below the threshold density nu_th = {nu_th:.6f} at e = {e:g}: "
                             "uniform shear has no BP there; choose nu > nu_th")
        hc = cr.critical_gap(nu, e, chi=chi, num=num)
        request.report(f"criticality: uniform shear at nu = {nu:g}")
        uniform, bp = cr.uniform_shear_bp(pb, nu, e, num=num, branch_id="0")
        emit(uniform)
        if bp is None:
            raise SceneError(f"continuation of uniform shear at nu = {nu:g} found no BP in "
                             f"({0.5 * hc:.6g}, {1.5 * hc:.6g}) around H_1^c = {hc:.6g}")
        bend = cr.pitchfork_bend(pb, nu, e, num=num)
        request.report("criticality: banded branch near the BP")
        halves = cr.pitchfork_halves(pb, uniform, bp, prefix="0")
        for h in halves:
            emit(h)
        a_fit, _, n_fit = cr.bend_from_branches(halves, bp.params["H"], nu)

        request.report("criticality: tricritical density from the normal form")
        tnf = cr.tricritical_density_normal_form(pb, e, num=num, nu_th=nu_th)
        nu_fold = s["nu_fold"]
        if nu_fold == "auto":
            nu_fold = nu_th + 0.2 * (tnf.nu_tc - nu_th)
        if not nu_th < nu_fold < tnf.nu_tc:
            raise SceneError(f"nu_fold = {nu_fold:g} must lie in the subcritical range ({nu_th:.6f}, {tnf.nu_tc:.6f})")
        request.report(f"criticality: fold of the banded branch at nu = {nu_fold:.6g}")
        fold = cr.banded_fold(pb, nu_fold, e, num=num, prefix="1")
        emit(fold.uniform)
        emit(fold.banded)
        request.report("criticality: fold curve in (H, nu)")
        end = cr.tricritical_by_fold_curve(pb, fold, e, num=num)
        emit(end.branch)
    except ValueError as exc:  # the library's one-sentence errors
        if isinstance(exc, SceneError):
            raise
        raise SceneError(str(exc)) from None

    notes += [
        f"e = {e:g}: linear-instability threshold nu_th = {nu_th:.9f} (psi finite above it)",
        f"nu = {nu:g}: H_1^c = {hc:.10g} (pi psi), continuation BP at {bp.params['H']:.10g} "
        f"(relative difference {abs(bp.params['H'] - hc) / hc:.1e}); bend a = {bend.a:.6g} "
        f"(normal form), {a_fit:.6g} (fit of the banded branch): {bend.criticality}",
        f"tricritical density: nu_tc = {tnf.nu_tc:.9f} (normal form, a = 0), {end.nu_tc:.9f} (fold curve from "
        f"nu = {nu_fold:.5g} ending on the BP curve); difference {end.nu_tc - tnf.nu_tc:.1e}",
        *end.notes,
    ]
    extra = {
        "e": e, "chi": chi, "num": num, "grid": {"method": pb.method, "intervals": pb.N},
        "nu": nu,
        "H1c_analytic": hc,
        "H1c_continuation": bp.params["H"],
        "H1c_rel_error": abs(bp.params["H"] - hc) / hc,
        "bend_normal_form": bend.a,
        "bend_normal_form_error": bend.error,
        "bend_fit": a_fit,
        "bend_fit_points": n_fit,
        "criticality": bend.criticality,
        "nu_th": nu_th,
        "nu_tc_normal_form": tnf.nu_tc,
        "H_tc_normal_form": tnf.H_tc,
        "normal_form_evaluations": tnf.evaluations,
        "nu_fold": nu_fold,
        "H1c_fold": fold.H_c,
        "H_LP": fold.lp.params["H"],
        "phi_LP": fold.lp.order_parameter,
        "nu_tc_fold_curve": end.nu_tc,
        "H_tc_fold_curve": end.H_tc,
        "fold_curve_end": {"nu": end.nu_end, "H": end.H_end, "delta": end.delta_end, "H_minus_H1c": end.gap_end},
        "nu_tc_fit_error": end.nu_tc_error,
        "nu_tc_difference": end.nu_tc - tnf.nu_tc,
    }
    parameters = {"e": e, "nu": nu, "nu_fold": nu_fold, "chi": chi, "num": num}
    return _result(pb, branches, parameters, notes, extra)


def run_critical_gap(request: SceneRequest) -> SceneResult:
    """H_1^c at one (nu, e): analytic and by continuation (module docstring).

    ``extra``: nu, e, psi (None below the threshold), H1c_analytic, H1c_continuation,
    H1c_rel_error (None below the threshold), unstable (psi finite), bp_found, H_max.
    """
    s = _settings(request, CRITICAL_GAP_DEFAULTS, "critical-gap")
    e, chi, num, nu, h_max = s["e"], s["chi"], s["num"], s["nu"], s["H_max"]
    if not h_max > 1.0:
        raise SceneError(f"H_max = {h_max:g} must be > 1")
    pb = _problem(request, chi)
    psi = float(critical_gap_factor(np.float64(nu), e, chi, num))
    unstable = math.isfinite(psi)
    try:
        if unstable:
            hc = math.pi * psi
            branch, bp = cr.uniform_shear_bp(pb, nu, e, num=num)
        else:
            hc = None
            branch, bp = cr.uniform_shear_bp(pb, nu, e, num=num, h_range=(1.0, h_max))
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if unstable:
        if bp is None:
            raise SceneError(f"continuation of uniform shear at nu = {nu:g}, e = {e:g} found no BP near "
                             f"H_1^c = {hc:.6g}")
        note = (f"H_1^c = {hc:.10g} (pi psi), continuation {bp.params['H']:.10g}, relative difference "
                f"{abs(bp.params['H'] - hc) / hc:.1e}")
    else:
        note = (f"nu = {nu:g} lies below the threshold density at e = {e:g} (psi not finite); "
                + ("uniform shear has no BP for H <= " + f"{h_max:g}" if bp is None
                   else f"but continuation found a BP at H = {bp.params['H']:.6g} (unexpected)"))
    extra = {
        "nu": nu, "e": e, "psi": psi if unstable else None,
        "H1c_analytic": hc,
        "H1c_continuation": None if bp is None else bp.params["H"],
        "H1c_rel_error": None if (bp is None or hc is None) else abs(bp.params["H"] - hc) / hc,
        "unstable": unstable,
        "bp_found": bp is not None,
        "H_max": h_max,
    }
    request.finished(branch)
    return _result(pb, [branch], {"nu": nu, "e": e, "chi": chi, "num": num, "H_max": h_max}, [note], extra)


CRITICALITY_SCENES: dict[str, Scene] = {
    "criticality": Scene(
        name="criticality",
        summary="gPCF: threshold density nu_th(e) and tricritical density nu_tc(e) (normal form and fold curve)",
        defaults=CRITICALITY_DEFAULTS,
        run=run_criticality,
        x="H",
        y="phi",
    ),
    "critical-gap": Scene(
        name="critical-gap",
        summary="gPCF: H_1^c(nu, e) = pi psi checked by continuation of uniform shear (or: no BP below threshold)",
        defaults=CRITICAL_GAP_DEFAULTS,
        run=run_critical_gap,
        x="H",
        y="phi",
    ),
}
