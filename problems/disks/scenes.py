"""Scenes of sheared granular disks (d = 2; docs/disks.md, issue 17).

- ``disks-pitchfork``: uniform shear between no-slip adiabatic walls traced in H for each pair
  correlation G (cs, fv, gf), its pitchforks against H_n^c = n pi psi (closed form), banded branches.
- ``disks-criticality``: sign of the cubic normal-form coefficient of the first pitchfork against the
  mean area fraction at several e; threshold and tricritical area fractions.
- ``savage-rheology``: Savage's dense closure (ESI normalization, Table 2): p_con, sigma_con (Eqs. 15,
  28) against phi0, flow curves across phi_c by continuation in the contact scale, and whether
  wall-bounded dense flow bands (pitchforks of uniform shear in H above phi_c).
- ``disks-steady``: the steady shear band of seed 000 between bumpy walls (mean area fraction 0.24,
  e = 0.85), continued in H from a narrow gap.

Rebuilding a file's problem (``Scene.problem_factory``, for ``contin verify`` and ``contin
continue``): disks-steady, savage-rheology and disks-pitchfork with one pair correlation
(``-s corr=cs|fv|gf``) store states of one problem, rebuilt here on the start grid of the run
(``discretization``; ``contin.adapt.on_grid`` carries it to each point's own grid).
disks-pitchfork with ``corr=all`` stores the branches of three closures (ids ``cs...``, ``fv...``,
``gf...``): its factory refuses in one sentence.  disks-criticality stores no branches (its
normal-form bends are computed inside the run) and has no factory.  None of the scenes has a linear-stability operator
(the residual's algebraic rows -- y-momentum, the mass constraint, boundary rows -- have no mass
matrix telling them from dynamics), so all are ``Scene(stability=False)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.adapt import point_problem
from contin.branch import Branch, relabel
from contin.continuation import trace
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from contin.resume import switch_reusing
from contin.scene import Scene, SceneError, SceneRequest, SceneResult, require_started, scene_numbers
from problems.disks.closures import (
    G_MODELS, DiskClosure, critical_gaps, homogeneous_stresses, kn_in_time_units, savage_contact_stresses,
)
from problems.disks.model import DEFAULTS, DiskCouetteProblem

_WORDS = {"corr", "walls"}

#: No Hopf detection: the steady residual has algebraic rows (y-momentum integrated, the mass
#: constraint, boundary rows) that DetectionOptions' automatic M = I test counts as dynamics.
#: The automatic test is on up to contin.options.HOPF_AUTO_MAX = 100 unknowns, i.e. cheb <= 32
#: here, so adaptive runs on coarse grids reported spurious HBs (disks-steady: HB at H = 2.375 with
#: omega = 2.3e-6 on cheb 8-16; none on the former fixed cheb 64, n = 196).
NO_HOPF = False


def _settings(request: SceneRequest, defaults: Mapping[str, Any], scene: str) -> dict[str, Any]:
    """Defaults merged with the request's parameters: numbers checked finite, words kept."""
    return scene_numbers(request, defaults, scene, words=_WORDS)


def _problem(request: SceneRequest, closure: DiskClosure, *, walls: str = "noslip", grid: int = 32) -> DiskCouetteProblem:
    try:
        return DiskCouetteProblem(request.method or "cheb", request.grid or grid, walls=walls, closure=closure)
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _params(pb: DiskCouetteProblem, values: Mapping[str, Any]) -> dict[str, float]:
    try:
        p = pb.params({k: v for k, v in values.items() if k in DEFAULTS})
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if p["e"] >= 1:
        raise SceneError("parameter e = 1 has no steady sheared state (no collisional dissipation); use e < 1")
    return p


def _emit(request: SceneRequest, done: list[Branch], branch: Branch) -> None:
    done.append(branch)
    relabel(done)
    request.finished(branch)


def _h_options(request: SceneRequest, lo: float, hi: float, *, ds: float, ds_max: float, max_steps: int = 200,
               locate_tol: float = 1e-12) -> ContinuationOptions:
    return request.options_for(ContinuationOptions(
        bounds={"H": (lo, hi)}, max_steps=max_steps,
        step=StepOptions(ds=ds, ds_max=ds_max, ds_min=1e-8, newton_target=6, grow=2.0),
        detection=DetectionOptions(locate_tol=locate_tol, detect_hopf=NO_HOPF)))


def _profiles(pb: DiskCouetteProblem):
    # States of any grid (adaptive runs) are carried onto the start grid, whose y the file stores.
    return lambda state: pb.profiles(pb.state_on(state))


def _rebuilt(discretization: Mapping[str, Any], closure: DiskClosure, *, walls: str, grid: int) -> DiskCouetteProblem:
    """The run's start problem: ``discretization`` as the scene stored it ({'method', 'intervals'};
    a run's own ``--grid`` is stored as 'intervals'), ``grid`` when it names none."""
    n = discretization.get("intervals", discretization.get("grid", grid))
    return DiskCouetteProblem(str(discretization.get("method", "cheb")), int(n), walls=walls, closure=closure)


def _corr(parameters: Mapping[str, Any], scene: str) -> str:
    corr = str(parameters.get("corr", "cs"))
    if corr not in G_MODELS:
        raise SceneError(f"{scene}: corr = {corr!r} names no single pair correlation ({', '.join(G_MODELS)}), "
                         "so the file's problem cannot be rebuilt")
    return corr


# ----------------------------------------------------------------------------- disks-pitchfork
PITCHFORK_DEFAULTS: dict[str, Any] = {"nu": 0.5, "e": 0.8, "corr": "all", "modes": 3, "phi_inf": 0.9,
                                      "phi_f": 0.7, "m_f": 0.01, "banded_steps": 60}


def run_pitchfork(request: SceneRequest) -> SceneResult:
    s = _settings(request, PITCHFORK_DEFAULTS, "disks-pitchfork")
    models = G_MODELS if s["corr"] == "all" else (s["corr"],)
    if any(m not in G_MODELS for m in models):
        raise SceneError(f"parameter corr = {s['corr']!r} is not a pair correlation; choose all or one of {', '.join(G_MODELS)}")
    modes = s["modes"]
    if modes != int(modes) or not 1 <= modes <= 5:
        raise SceneError(f"parameter modes = {modes:g} must be an integer 1..5")
    modes = int(modes)
    done: list[Branch] = []
    notes: list[str] = []
    extra: dict[str, Any] = {}
    pb = None
    for model in models:
        closure = DiskClosure(G=model)
        pb = _problem(request, closure, grid=64)  # cheb 32 under-resolves the n = 1 plugs from H ~ 1.8 H_1^c
        p = _params(pb, s)
        hcs = critical_gaps(p, closure, modes)
        if not math.isfinite(hcs[0]):
            notes.append(f"G = {model}: psi is not finite at nu = {p['nu']:g} (no shear-banding pitchfork of uniform shear)")
            extra[model] = {"H_c": None}
            continue
        lo, hi = 0.5 * hcs[0], hcs[-1] + 0.5 * hcs[0]
        p["H"] = lo
        bid = f"{model}"
        if bid in request.completed:
            base = request.completed[bid]
        else:
            request.report(f"disks-pitchfork: G = {model}, uniform shear in H (H_1^c = {hcs[0]:.6g})")
            base = trace(pb, pb.uniform_state(p), p, "H",
                         _h_options(request, lo, hi, ds=0.02 * hcs[0], ds_max=0.1 * hcs[0]),
                         branch_id=bid, kind="uniform shear", progress=request.report)
        _emit(request, done, base)
        found = [float(b.params["H"]) for b in base.branch_points]
        errs = [f - h for f, h in zip(found, hcs)]
        extra[model] = {"H_c": hcs, "H_bp": found, "errors": errs,
                        "notes": [b.note for b in base.branch_points]}
        notes.append(f"G = {model}: H_n^c closed form {', '.join(f'{h:.10g}' for h in hcs)}; located "
                     + ", ".join(f"{b.name} {b.params['H']:.10g} ({b.params['H'] - h:+.1e}; {b.note})"
                                 for b, h in zip(base.branch_points, hcs)))
        banded = _h_options(request, 0.3 * hcs[0], hi, ds=0.01, ds_max=0.05 * hcs[0],
                            max_steps=int(s["banded_steps"]), locate_tol=1e-9)
        for j, bp in enumerate(base.branch_points[:modes], start=1):
            prefix = f"{bid}.n{j}"
            ids = [f"{prefix}.1", f"{prefix}.2"]
            if all(i in request.completed for i in ids):
                kids = [request.completed[i] for i in ids]
            else:
                request.report(f"disks-pitchfork: G = {model}, switching at {bp.name} (H = {bp.params['H']:.6g})")
                try:
                    kids = switch_reusing(request.completed, pb, base, bp, banded, branch_id_prefix=prefix)
                except ValueError as exc:
                    notes.append(f"G = {model}: switching at {bp.name} failed: {exc}")
                    continue
            for k in kids:
                _emit(request, done, k)
    assert pb is not None
    return SceneResult(branches=done, parameters={**s}, discretization={"method": pb.method, "intervals": pb.N},
                       y=pb.grid.y, profiles=_profiles(pb), notes=notes, extra=extra)


def pitchfork_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> DiskCouetteProblem:
    """The problem of a disks-pitchfork run with one pair correlation (no-slip walls, its G).

    ``corr=all`` runs store branches of three problems (G = cs, fv, gf): refused in one sentence."""
    if str(parameters.get("corr")) == "all":
        raise SceneError("disks-pitchfork with corr = all stores the branches of three closures (G = cs, fv, gf; "
                         "branch ids cs..., fv..., gf...), one problem each, so no single problem can be rebuilt; "
                         "trace one closure with -s corr=cs|fv|gf to verify or continue its file")
    return _rebuilt(discretization, DiskClosure(G=_corr(parameters, "disks-pitchfork")), walls="noslip", grid=64)


# ----------------------------------------------------------------------------- disks-criticality
CRITICALITY_DEFAULTS: dict[str, Any] = {"corr": "cs", "nu_min": 0.05, "nu_max": 0.85, "dnu": 0.05,
                                        "e_list": "0.7,0.8,0.9,0.95", "phi_inf": 0.9, "phi_f": 0.7,
                                        "m_f": 0.01, "fold_checks": 1}


#: Largest number of area fractions disks-criticality computes per e (the default is 17).
MAX_CRITICALITY_POINTS = 1000


def run_criticality(request: SceneRequest) -> SceneResult:
    from problems.disks.criticality import bend_by_branch, pitchfork_bend, threshold_density, tricritical

    raw = dict(request.params)
    e_text = str(raw.pop("e_list", CRITICALITY_DEFAULTS["e_list"]))
    s = _settings(SceneRequest(params=raw), {k: v for k, v in CRITICALITY_DEFAULTS.items() if k != "e_list"},
                  "disks-criticality")
    try:
        es = [float(v) for v in e_text.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise SceneError(f"parameter e_list must be numbers separated by commas, got {e_text!r}") from None
    if not es or any(not 0 < e < 1 for e in es):
        raise SceneError(f"parameter e_list = {e_text!r}: every e must lie in (0, 1)")
    twice = next((e for i, e in enumerate(es) if e in es[:i]), None)
    if twice is not None:  # computed twice, the second result over the first (qa18)
        raise SceneError(f"parameter e_list = {e_text!r} lists e = {twice:g} twice")
    if s["corr"] not in G_MODELS:
        raise SceneError(f"parameter corr = {s['corr']!r} is not a pair correlation; choose one of {', '.join(G_MODELS)}")
    if not 0 < s["nu_min"] < s["nu_max"] < s["phi_inf"] or not s["dnu"] > 0:
        raise SceneError("need 0 < nu_min < nu_max < phi_inf and dnu > 0")
    if not s["phi_inf"] < 1:  # phi_inf = 1e300 ended in scipy's 'The function value at x=2e+297 is NaN'
        raise SceneError(f"maximum area fraction phi_inf = {s['phi_inf']:g} must lie in (0, 1)")
    count = math.floor((s["nu_max"] - s["nu_min"]) / s["dnu"] + 1e-9) + 1
    if count > MAX_CRITICALITY_POINTS:  # dnu = 1e-300 ended in numpy's 'Maximum allowed size exceeded'
        raise SceneError(f"nu_min = {s['nu_min']:g} to nu_max = {s['nu_max']:g} in steps dnu = {s['dnu']:g} are "
                         f"{count:.3g} area fractions; at most {MAX_CRITICALITY_POINTS} (each is a normal-form "
                         "computation per e): raise dnu")
    closure = DiskClosure(G=s["corr"])
    pb = _problem(request, closure, grid=24)
    extra_p = {k: s[k] for k in ("phi_inf", "phi_f", "m_f")}
    nus = np.round(np.arange(s["nu_min"], s["nu_max"] + 1e-9, s["dnu"]), 10)
    extra: dict[str, Any] = {"nu": nus.tolist(), "e": es, "curves": {}}
    notes: list[str] = []
    done: list[Branch] = []
    from contin.cancel import stop_requested

    for e in es:
        if stop_requested():  # the first Ctrl-C/SIGTERM: the run ends here (it waited ~40 s for the sweep, qa17)
            break
        base_p = {**DEFAULTS, **extra_p, "e": e}
        nu_th = threshold_density(base_p, closure)
        a = np.full(nus.size, np.nan)
        hc = np.full(nus.size, np.nan)
        for i, nu in enumerate(nus):
            if stop_requested():
                break
            if math.isfinite(nu_th) and nu <= nu_th:
                continue
            request.report(f"disks-criticality: e = {e:g}, nu = {nu:g}")
            try:
                b = pitchfork_bend(pb, float(nu), e, extra=extra_p)
            except (ValueError, RuntimeError) as exc:
                notes.append(f"e = {e:g}, nu = {nu:g}: no bend ({exc})")
                continue
            a[i], hc[i] = b.a, b.H_c
        if stop_requested():  # an e whose sweep was cut short has no result
            break
        tri = tricritical(pb, e, nus, a, extra=extra_p)
        # the sample next to the threshold is bracketed between threshold (a -> -inf) and the first sample
        first = int(np.flatnonzero(np.isfinite(a))[0]) if np.isfinite(a).any() else None
        if first is not None and a[first] > 0 and math.isfinite(nu_th):
            lo = nu_th + 1e-4
            try:
                a_lo = pitchfork_bend(pb, lo, e, extra=extra_p).a
                if a_lo < 0:
                    import scipy.optimize as so
                    tri.insert(0, float(so.brentq(lambda v: pitchfork_bend(pb, v, e, extra=extra_p).a, lo,
                                                  float(nus[first]), xtol=1e-8)))
            except (ValueError, RuntimeError):
                pass
        checks = []
        for k in range(int(s["fold_checks"])):
            finite = np.flatnonzero(np.isfinite(a))
            if finite.size <= k or stop_requested():
                break
            j = int(finite[len(finite) // 2 + k])
            request.report(f"disks-criticality: e = {e:g}, fold-route check at nu = {nus[j]:g}")
            try:
                a_branch, band = bend_by_branch(pb, float(nus[j]), e, extra=extra_p)
                checks.append({"nu": float(nus[j]), "normal_form": float(a[j]), "branch_fit": a_branch})
            except (ValueError, RuntimeError) as exc:
                notes.append(f"e = {e:g}: fold-route check at nu = {nus[j]:g} failed ({exc})")
        extra["curves"][f"{e:g}"] = {"a": [None if not math.isfinite(v) else float(v) for v in a],
                                    "H_c": [None if not math.isfinite(v) else float(v) for v in hc],
                                    "threshold": nu_th, "tricritical": tri, "fold_checks": checks}
        sub = [float(v) for v, x in zip(nus, a) if math.isfinite(x) and x < 0]
        notes.append(f"e = {e:g}: threshold nu_th = {nu_th:.6f}; tricritical nu_tc = "
                     f"{', '.join(f'{t:.6f}' for t in tri) or 'none'}; subcritical samples {sub or 'none'}; "
                     + "; ".join(f"fold route at nu = {c['nu']:g}: a = {c['branch_fit']:.6g} vs normal form "
                                 f"{c['normal_form']:.6g}" for c in checks))
    notes.append("Seed 000 (Saitoh & Hayakawa, Lees-Edwards, k_x != 0 mode, e -> 1 with eps^2 = sqrt(1-e) = 0.1^2): "
                 "supercritical below nu0 = 0.53, subcritical above; the wall-bounded k_x = 0 pitchfork here is "
                 "subcritical only in a thin layer above the threshold density (see docs/disks.md)")
    return SceneResult(branches=done, parameters={**s, "e_list": e_text},
                       discretization={"method": pb.method, "intervals": pb.N}, notes=notes, extra=extra)


# No problem_factory: the scene stores no branches (SceneResult.branches is empty); its bends
# and fold-route checks are normal-form computations and augmented solves inside the run.


# ----------------------------------------------------------------------------- savage-rheology
SAVAGE_DEFAULTS: dict[str, Any] = {"e": 0.7, "phi_c": 0.8, "phi_inf": 0.9, "phi_f": 0.7, "m_f": 0.01,
                                   "a0_over_kn": 3.25e-2, "corr": "gf", "nu_band": 0.84, "a0_band": 1.0}


def run_savage(request: SceneRequest) -> SceneResult:
    s = _settings(request, SAVAGE_DEFAULTS, "savage-rheology")
    if s["corr"] not in G_MODELS:
        raise SceneError(f"parameter corr = {s['corr']!r} is not a pair correlation; choose one of {', '.join(G_MODELS)}")
    if not s["phi_c"] < s["nu_band"]:
        raise SceneError(f"parameter nu_band = {s['nu_band']:g} <= phi_c = {s['phi_c']:g}: the dense (contact) closure "
                         "has no contact part there; the banding question is asked above phi_c")
    if not s["a0_over_kn"] >= 0:  # was accepted: negative contact stresses and flow curves, exit 0
        raise SceneError(f"parameter a0_over_kn = {s['a0_over_kn']:g} must be >= 0 (Savage's contact pressure scale a0 "
                         "in units of k_n; a0_band is checked the same way)")
    closure = DiskClosure(G=s["corr"], contact=True, normalization="esi")
    # cheb 96: the banded dense plug nears phi_inf within ~2 H_1^c (the resolution guard ends it there)
    pb = _problem(request, closure, grid=96)
    p = _params(pb, {**s, "nu": s["nu_band"], "a0": s["a0_band"]})
    kn = kn_in_time_units(s["e"])  # k_n in units m / t_m^2
    a0_esi = s["a0_over_kn"] / kn  # a0 in units m / t_m^2 (the ESI's stress unit with upsilon = d^2)
    q = {**p, "a0": s["a0_over_kn"]}  # contact stresses in units of k_n (ESI Fig. 3)
    phis = np.linspace(s["phi_c"] + 1e-3, min(0.895, s["phi_inf"] - 5e-3), 60)
    try:
        pcon, scon = savage_contact_stresses(phis, q, closure)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    extra: dict[str, Any] = {"phi0": phis.tolist(), "p_con_over_kn": pcon.tolist(), "sigma_con_over_kn": scon.tolist(),
                             "kn_t_m2_over_m": kn, "a0_esi_units": a0_esi}
    notes = [f"a0 = {s['a0_over_kn']:g} k_n; linear dashpot at e = {s['e']:g}: k_n = {1 / kn:.6g} m/t_m^2, "
             f"so a0 = {a0_esi:.6g} m/t_m^2"]
    # flow curves (closed form, ESI units) across phi_c
    rates = np.logspace(-6, -1, 41)
    curves = {}
    for phi0 in (0.70, 0.78, 0.80, 0.82, 0.84, 0.86):
        qq = {**p, "a0": a0_esi}
        _, pres, sig = homogeneous_stresses(phi0, rates, qq, closure)
        curves[f"{phi0:g}"] = {"p": np.asarray(pres).tolist(), "sigma": np.asarray(sig).tolist()}
    extra["flow_curves"] = {"s": rates.tolist(), "curves": curves}
    # ESI footnote 1: kinetic stresses at the largest MD rate s = 2.5e-3 (p_kin ~ 3.75e-4, sigma_kin ~ 3.75e-5)
    th, pk, sk = homogeneous_stresses(0.84, 2.5e-3, {**p, "a0": 0.0}, DiskClosure(G=s["corr"], normalization="esi"))
    notes.append(f"kinetic stresses at phi0 = 0.84, s = 2.5e-3 (ESI units m/t_m^2): p_kin = {float(pk):.4g}, "
                 f"sigma_kin = {float(sk):.4g} (in k_n: {float(pk) * kn:.3g}, {float(sk) * kn:.3g}; ESI footnote 1 "
                 "quotes 3.75e-4 and 3.75e-5)")
    done: list[Branch] = []
    # flow curve by continuation: uniform shear in the Couette scaling, where a0 = a0_phys / (rho_p gamma^2 d^2)
    # is the inverse squared shear rate; S(a0) is the shear stress in units rho_p (gamma d)^2
    for k, phi0 in enumerate((0.78, 0.84)):
        bid = f"a0.{k}"
        pp = {**p, "nu": phi0, "a0": 0.0, "H": 10.0}
        if bid in request.completed:
            br = request.completed[bid]
        else:
            request.report(f"savage-rheology: uniform shear at phi0 = {phi0:g} continued in a0")
            opts = request.options_for(ContinuationOptions(bounds={"a0": (0.0, 1e3)}, max_steps=80,
                                                           step=StepOptions(ds=0.05, ds_max=50.0, grow=2.0),
                                                           detection=DetectionOptions(detect_branch_points=False,
                                                                                      detect_hopf=NO_HOPF)))
            br = trace(pb, pb.uniform_state(pp), pp, "a0", opts, branch_id=bid, kind=f"uniform shear phi0={phi0:g}")
        _emit(request, done, require_started(br, "savage-rheology"))
        S = br.observables["shear_stress"]
        a0s = br.parameter_values
        slope = np.polyfit(a0s, S, 1)[0]
        if phi0 > s["phi_c"]:
            _, ref = savage_contact_stresses(np.array([phi0]), {**p, "a0": 1.0}, closure)
            notes.append(f"phi0 = {phi0:g}: dS/da0 along the a0 branch {slope:.12g}; Eq. 28 sigma_con/a0 = {float(ref[0]):.12g}")
        else:
            notes.append(f"phi0 = {phi0:g} < phi_c: S independent of a0 (spread {np.ptp(S):.2g}): no yield stress, Bagnold")
    # banding of wall-bounded dense flow: uniform shear in H at nu_band > phi_c
    hcs = critical_gaps(p, closure, 2)
    extra["band"] = {"nu": s["nu_band"], "a0": s["a0_band"], "H_c": hcs}
    if math.isfinite(hcs[0]):
        pp = {**p, "H": 0.5 * hcs[0]}
        bid = "band"
        if bid in request.completed:
            base = request.completed[bid]
        else:
            request.report(f"savage-rheology: uniform shear in H at nu = {s['nu_band']:g} (H_1^c = {hcs[0]:.6g})")
            base = trace(pb, pb.uniform_state(pp), pp, "H",
                         _h_options(request, 0.5 * hcs[0], 2.5 * hcs[0], ds=0.02 * hcs[0], ds_max=0.1 * hcs[0]),
                         branch_id=bid, kind="uniform shear")
        _emit(request, done, base)
        extra["band"]["H_bp"] = [float(b.params["H"]) for b in base.branch_points]
        notes.append(f"dense Savage flow at nu = {s['nu_band']:g}, a0 = {s['a0_band']:g} (Couette units): H_n^c = "
                     f"{', '.join(f'{h:.8g}' for h in hcs)}; BPs located at "
                     f"{', '.join(f'{b.params[chr(72)]:.8g}' for b in base.branch_points) or 'none'}")
        if base.branch_points:
            bp = base.branch_points[0]
            ids = ["band.n1.1", "band.n1.2"]
            if all(i in request.completed for i in ids):
                kids = [request.completed[i] for i in ids]
            else:
                kids = switch_reusing(request.completed, pb, base, bp,
                                      _h_options(request, 0.3 * hcs[0], 2.5 * hcs[0], ds=0.01,
                                                 ds_max=0.05 * hcs[0], max_steps=60, locate_tol=1e-9),
                                      branch_id_prefix="band.n1")
            for kid in kids:
                _emit(request, done, kid)
    else:
        notes.append(f"dense Savage flow at nu = {s['nu_band']:g}: psi not finite, uniform shear does not band")
    return SceneResult(branches=done, parameters={**s}, discretization={"method": pb.method, "intervals": pb.N},
                       y=pb.grid.y, profiles=_profiles(pb), notes=notes, extra=extra)


def savage_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> DiskCouetteProblem:
    """The problem of a savage-rheology run: Savage's contact closure (ESI normalization, its G),
    no-slip walls; every branch (a0.k, band, band.n1.k) is a state of it (the branches carry
    their own nu, a0, H columns)."""
    closure = DiskClosure(G=_corr(parameters, "savage-rheology"), contact=True, normalization="esi")
    return _rebuilt(discretization, closure, walls="noslip", grid=96)


# ----------------------------------------------------------------------------- disks-steady
STEADY_DEFAULTS: dict[str, Any] = {"nu": 0.24, "e": 0.85, "H": 128.0, "phi_w": 1.0, "ew": 0.5, "corr": "cs",
                                   "phi_inf": 0.9, "phi_f": 0.7, "m_f": 0.01}


def run_steady(request: SceneRequest) -> SceneResult:
    s = _settings(request, STEADY_DEFAULTS, "disks-steady")
    if s["corr"] not in G_MODELS:
        raise SceneError(f"parameter corr = {s['corr']!r} is not a pair correlation; choose one of {', '.join(G_MODELS)}")
    if not s["H"] > 2.0:
        raise SceneError(f"parameter H = {s['H']:g} must be > 2 (the run starts at H = 2)")
    if s["phi_w"] == 0:  # it used to end 'initial guess is inadmissible: state has non-finite entries'
        raise SceneError("disks-steady: phi_w = 0 (smooth walls) transmits no shear, so there is no sheared "
                         "steady state; use phi_w > 0")
    closure = DiskClosure(G=s["corr"])
    pb = _problem(request, closure, walls="bumpy", grid=64)
    p = _params(pb, {k: v for k, v in s.items() if k != "corr"})
    h_target = s["H"]
    p["H"] = 2.0
    done: list[Branch] = []
    if "0" in request.completed:
        br = request.completed["0"]
    else:
        request.report(f"disks-steady: bumpy walls, nu = {p['nu']:g}, e = {p['e']:g}, H = 2 -> {h_target:g}")
        opts = request.options_for(ContinuationOptions(
            bounds={"H": (1.0, h_target)}, max_steps=300,
            step=StepOptions(ds=0.1, ds_max=5.0, ds_min=1e-8, newton_target=6, grow=2.0),
            detection=DetectionOptions(locate_tol=1e-9, detect_hopf=NO_HOPF)))
        br = trace(pb, pb.initial_guess(p), p, "H", opts, branch_id="0", kind="bumpy-wall base",
                   progress=request.report)
    _emit(request, done, require_started(br, "disks-steady"))
    notes = [f"branch ends at H = {br.parameter_values[-1]:.6g} ({br.status}: {br.message})"]
    extra: dict[str, Any] = {}
    if br.parameter_values[-1] >= h_target * (1 - 1e-9):
        last = point_problem(pb, br, -1)  # the last point's own grid (adaptive runs)
        obs = {k: float(v[-1]) for k, v in br.observables.items()}
        nu, u, T, P, _ = last.unpack(br.state(-1))
        extra = {"H": h_target, "shear_stress": obs["shear_stress"], "pressure": obs["pressure"],
                 "nu_wall": float(nu[0]), "nu_centre": float(last.grid.interpolate(nu, np.array([0.0]))[0]),
                 "T_wall": float(T[0]), "T_centre": float(last.grid.interpolate(T, np.array([0.0]))[0]),
                 "slip": obs["slip_top"]}
        notes.append(f"H = {h_target:g}: nu wall {extra['nu_wall']:.5f}, centre {extra['nu_centre']:.5f}; T wall "
                     f"{extra['T_wall']:.5g}, centre {extra['T_centre']:.5g}; shear stress {extra['shear_stress']:.6g}, "
                     f"pressure {extra['pressure']:.6g}; wall slip {extra['slip']:.4f}")
    return SceneResult(branches=done, parameters={**s}, discretization={"method": pb.method, "intervals": pb.N},
                       y=pb.grid.y, profiles=_profiles(pb), notes=notes, extra=extra)


def steady_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> DiskCouetteProblem:
    """The problem of a disks-steady run: bumpy walls, Jenkins-Richman closure with its G."""
    return _rebuilt(discretization, DiskClosure(G=_corr(parameters, "disks-steady")), walls="bumpy", grid=64)


SCENES = {
    "disks-pitchfork": Scene(
        name="disks-pitchfork",
        summary="2-D disks (Jenkins-Richman): uniform-shear pitchforks at H_n^c = n pi psi for G = cs, fv, gf",
        defaults=PITCHFORK_DEFAULTS, run=run_pitchfork, x="H", y="phi", adaptive=True,
        problem_factory=pitchfork_factory, stability=False),
    "disks-criticality": Scene(
        name="disks-criticality",
        summary="2-D disks: super/subcritical first pitchfork vs mean area fraction and e; tricritical area fraction",
        defaults=CRITICALITY_DEFAULTS, run=run_criticality, x="H", y="phi", stability=False),
    "savage-rheology": Scene(
        name="savage-rheology",
        summary="Savage's dense closure (ESI Table 2): p_con, sigma_con vs phi0, flow curves, banding above phi_c",
        defaults=SAVAGE_DEFAULTS, run=run_savage, x="H", y="phi", adaptive=True,
        problem_factory=savage_factory, stability=False),
    "disks-steady": Scene(
        name="disks-steady",
        summary="seed 000's steady shear band of disks between bumpy walls (nu = 0.24, e = 0.85)",
        defaults=STEADY_DEFAULTS, run=run_steady, x="H", y="phi", adaptive=True,
        problem_factory=steady_factory, stability=False),
}
