"""Scenes of the Dsouza-Nott non-local model: ``nonlocal-shear``, ``nonlocal-cylinder``, ``nonlocal-muI``.

``nonlocal-shear`` (plane shear without gravity, :mod:`plane`):
  branch ``uniform.ell``: phi_w = phi_bar (uniform phi), continued in ell; every point is compared
  with the closed-form sinh profile (:class:`closures.PlaneShearAnalytic`) and the wall layer
  width gamma/|gamma'| with 1/(zeta tanh(zeta W/2)) (``extra['analytic']``).
  For each (K, mu_w) pair, (K, mu_w) and (K2, mu_w2) (defaults (1.65, 0.33) and (0.95, 0.1)):
  the coupled phi-u problem with the mean-phi constraint at phi_bar, continued through the
  default point in ell (``pair<k>.ell``, ell/W observable), mu_w (``pair<k>.mu_w``, mu_w/mu
  observable) and W (``pair<k>.W``).  The reflection invariants (phi even, u - 1/2 odd) are
  recorded on every point (observables asym_phi, asym_u) and their maxima reported.
Branch ids are deterministic (``--resume`` reuses finished branches).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.branch import Branch, relabel
from contin.continuation import trace_both
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult

from .closures import CriticalState, PlaneShearAnalytic
from .plane import DEFAULTS as PLANE_DEFAULTS
from .plane import PlaneShear

CS_DEFAULTS = {"phi_min": 0.5, "phi_max": 0.64, "n1": 2.0, "n2": 1.0}

SHEAR_DEFAULTS: dict[str, Any] = {
    **{k: PLANE_DEFAULTS[k] for k in ("W", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w")},
    "K2": 0.95, "mu_w2": 0.1, **CS_DEFAULTS,
    "ell_min": 1.0, "ell_max": 12.0, "W_min": 8.0, "W_max": 120.0,
}

#: Relative tolerance of the uniform-phi branch against the closed form (Chebyshev resolves it
#: to ~1e-14; the note flags anything worse, e.g. an FD grid or a layer thinner than the grid).
ANALYTIC_TOL = 1e-8


def numbers(request: SceneRequest, defaults: Mapping[str, Any], scene: str) -> dict[str, float]:
    """Defaults merged with the user's values, each a finite number (SceneError otherwise)."""
    out = dict(defaults)
    for name, value in request.params.items():
        if name not in defaults:
            raise SceneError(f"unknown parameter {name!r} for scene {scene!r}; its parameters are {', '.join(defaults)}")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise SceneError(f"parameter {name} of scene {scene!r} must be a number, got {value!r}") from None
        if not math.isfinite(v):
            raise SceneError(f"parameter {name} of scene {scene!r} must be finite, got {value!r}")
        out[name] = v
    return out


def critical_state(s: Mapping[str, float]) -> CriticalState:
    try:
        return CriticalState(s["phi_min"], s["phi_max"], s["n1"], s["n2"])
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _checked(problem: Any, p: Mapping[str, float]) -> None:
    try:
        problem.validate(p)
    except ValueError as exc:
        raise SceneError(str(exc)) from None


class _Emitter:
    def __init__(self, request: SceneRequest) -> None:
        self.request = request
        self.done: list[Branch] = []

    def run(self, branch_id: str, make: Any) -> Branch:
        if branch_id in self.request.completed:
            branch = self.request.completed[branch_id]
        else:
            self.request.report(f"tracing {branch_id}")
            branch = make()
        self.done.append(branch)
        relabel(self.done)
        self.request.finished(branch)
        return branch


def _trace(problem: Any, p: Mapping[str, float], parameter: str, lo: float, hi: float, ds: float,
           request: SceneRequest, branch_id: str, max_steps: int = 80) -> Branch:
    options = request.options_for(ContinuationOptions(
        bounds={parameter: (lo, hi)}, max_steps=max_steps, step=StepOptions(ds=ds, ds_max=10 * ds, ds_min=1e-8)))
    return trace_both(problem, problem.initial(p), dict(p), parameter, options, branch_id=branch_id,
                      progress=request.report)


def _plane_params(s: Mapping[str, float], K: float, mu_w: float) -> dict[str, float]:
    p = dict(PLANE_DEFAULTS)
    p.update({k: s[k] for k in ("W", "ell", "mu", "phi_bar", "phi_w")}, K=K, mu_w=mu_w)
    return p


def run_shear(request: SceneRequest) -> SceneResult:
    s = numbers(request, SHEAR_DEFAULTS, "nonlocal-shear")
    cs = critical_state(s)
    try:
        pb = PlaneShear(request.method or "cheb", request.grid or 48, cs)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    pairs = [(s["K"], s["mu_w"]), (s["K2"], s["mu_w2"])]
    for K, mu_w in pairs:
        _checked(pb, _plane_params(s, K, mu_w))
    if not (0 < s["ell_min"] <= s["ell"] <= s["ell_max"]):
        raise SceneError(f"need 0 < ell_min <= ell <= ell_max, got {s['ell_min']:g}, {s['ell']:g}, {s['ell_max']:g}")
    if not (0 < s["W_min"] <= s["W"] <= s["W_max"]):
        raise SceneError(f"need 0 < W_min <= W <= W_max, got {s['W_min']:g}, {s['W']:g}, {s['W_max']:g}")
    em = _Emitter(request)
    notes: list[str] = []
    extra: dict[str, Any] = {}

    # 1. uniform phi: the closed form
    pu = _plane_params(s, s["K"], s["mu_w"])
    pu["phi_w"] = pu["phi_bar"]
    uni = em.run("uniform.ell", lambda: _trace(pb, pu, "ell", s["ell_min"], s["ell_max"], 0.1, request, "uniform.ell"))
    err_u, err_d = _analytic_errors(pb, uni, pu)
    extra["analytic"] = {"max_abs_error_u": err_u, "max_rel_error_delta": err_d}
    flag = "" if max(err_u, err_d) < ANALYTIC_TOL else f" -- ABOVE {ANALYTIC_TOL:g}: refine the grid"
    notes.append(f"uniform phi, ell in [{s['ell_min']:g}, {s['ell_max']:g}]: max |u - u_exact| = {err_u:.2g}, "
                 f"max rel. error of the wall layer width against 1/(zeta tanh(zeta W/2)) = {err_d:.2g}{flag}")

    # 2. coupled phi-u for both pairs
    for k, (K, mu_w) in enumerate(pairs, start=1):
        p = _plane_params(s, K, mu_w)
        ranges = {"ell": (s["ell_min"], s["ell_max"], 0.1),
                  "mu_w": (0.0, 0.98 * s["mu"], 0.01),
                  "W": (s["W_min"], s["W_max"], 1.0)}
        asym = 0.0
        for name, (lo, hi, ds) in ranges.items():
            bid = f"pair{k}.{name}"
            br = em.run(bid, lambda name=name, lo=lo, hi=hi, ds=ds, bid=bid: _trace(pb, p, name, lo, hi, ds, request, bid))
            asym = max(asym, float(np.max(br.observables["asym_phi"])), float(np.max(br.observables["asym_u"])))
            if br.status != "EP":
                notes.append(f"{bid}: ended {br.status}: {br.message}")
        obs = pb.observables(_solve(pb, p), p)
        an = PlaneShearAnalytic(p["W"], K, p["ell"], mu_w, p["mu"])
        extra[f"pair{k}"] = {"K": K, "mu_w": mu_w, "max_asymmetry": asym, "uniform_delta": an.wall_layer, **obs}
        notes.append(f"pair {k} (K = {K:g}, mu_w = {mu_w:g}) at ell = {p['ell']:g}, W = {p['W']:g}, phi_bar = {p['phi_bar']:g}: "
                     f"P = {obs['P']:.6g}, u(0) = {obs['u_slip']:.6g}, phi_mid = {obs['phi_mid']:.6g}, "
                     f"wall layer {obs['delta']:.4g} d_p (uniform phi: {an.wall_layer:.4g}, 1/zeta = {1 / an.zeta:.4g}); "
                     f"reflection invariants hold to {asym:.1g} on all its branches")
    return SceneResult(
        branches=em.done,
        parameters=s,
        discretization={"method": pb.grid.method, "intervals": pb.grid.intervals},
        y=pb.grid.y + 0.5,
        profiles=lambda state: _shear_profiles(pb, state),
        notes=notes,
        extra=extra,
    )


def _solve(pb: PlaneShear, p: Mapping[str, float]) -> np.ndarray:
    from contin.continuation import newton

    res = newton(pb, pb.initial(p), p)
    if not res.converged:
        raise SceneError(f"Newton did not converge at the start point ({res})")
    return res.u


def _shear_profiles(pb: PlaneShear, state: np.ndarray) -> dict[str, np.ndarray]:
    """phi, gamma W = du/d(y/W) and u - u(0) on y/W (u(0) = K gamma(0) needs K/W: see the branch)."""
    phi, g, _ = pb.split(np.asarray(state))
    rel = np.concatenate([[0.0], np.cumsum(pb.cells @ g)])
    return {"phi": phi.copy(), "gamma_W": g.copy(), "u_minus_u0": rel}


def _analytic_errors(pb: PlaneShear, branch: Branch, base: Mapping[str, float]) -> tuple[float, float]:
    """Max |u - u_exact| and max relative error of the wall-layer width along a uniform-phi branch."""
    eu = ed = 0.0
    idx = branch.state_index if branch.state_index is not None else np.arange(len(branch.states))
    for row, i in zip(branch.states, idx):
        p = dict(base)
        p.update({name: float(col[i]) for name, col in branch.params.items()})
        an = PlaneShearAnalytic(p["W"], p["K"], p["ell"], p["mu_w"], p["mu"])
        eu = max(eu, float(np.max(np.abs(pb.velocity(row, p) - an.u(pb.y(p))))))
        ed = max(ed, abs(float(branch.observables["delta"][i]) / an.wall_layer - 1.0))
    return eu, ed


SCENES = {
    "nonlocal-shear": Scene(
        name="nonlocal-shear",
        summary="Dsouza-Nott non-local model, plane shear: sinh profile, coupled phi-u at phi_bar, continuation in ell, mu_w, W",
        defaults=SHEAR_DEFAULTS,
        run=run_shear,
        x="ell",
        y="delta",
    ),
}
