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
``nonlocal-cylinder`` (cylindrical Couette flow, :mod:`cylinder`): inner wall moving, outer fixed,
  the report's Eqs. 3.3-3.5 and boundary conditions, its fitted K = 0.63 and mu_w/mu = 0.99;
  phi(r), u(r) continued in the radius ratio r_o/r_i at fixed gap W (``derived.ratio``), and the
  same with the report's printed Laplacian and slip sign (``report.ratio``, ``report_eqs=1``
  runs only that one) for comparison.
``nonlocal-muI`` (the mu(I) extension in plane shear, :mod:`plane` with U > 0): mu(I) = mu_s +
  (mu_2 - mu_s) / (I0/I + 1) with the report's fit mu_s = 0.3618, mu_2 - mu_s = 0.3367,
  I0 = 0.1005, continued in the dimensionless wall speed U from the quasi-static limit U = 0
  (which is the nonlocal-shear problem: checked point by point) into I ~ 0.1-0.2 (``muI.U``), and
  the comparison branch ``phiI.U``: the local phi(I) rheology phi = phi_max - A_phi I in place of
  the phi equation (report Fig. 4), for which P = U^2 P_1 and the profiles do not depend on U
  (checked along the branch).
Branch ids are deterministic (``--resume`` reuses finished branches).

Rebuilding a file's problem (``Scene.problem_factory``, for ``contin verify`` and ``contin
continue``; the problems have the grid hooks of :mod:`problems.nonlocal_flow.grids`):
``nonlocal-shear`` stores states of one problem (every branch is :class:`PlaneShear` with the
file's critical state; the pairs and the uniform branch differ only in parameters, which the
branches store as columns).  ``nonlocal-cylinder`` does with ``report_eqs=1`` (the report's
operator alone); its default run stores branches of two operators (``derived.ratio``,
``report.ratio``), and its factory refuses those files in one sentence.  ``nonlocal-muI`` has
none: ``muI.U`` and ``phiI.U`` are states of two problems (the non-local phi equation and the
local phi(I) law), whatever its parameters.  None has a linear-stability operator (the mean
constraint and the boundary rows are algebraic), so all are ``Scene(stability=False)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.adapt import on_grid, point_problem
from contin.branch import Branch, relabel
from contin.continuation import trace_both
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult, require_started, scene_numbers

from .closures import CriticalState, PlaneShearAnalytic
from .cylinder import DEFAULTS as CYL_DEFAULTS
from .cylinder import CylindricalCouette
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


#: The tol of a run without --grid and --tol (``Scene.default_tol``), per scene: at most the
#: largest two-grid error of a state the former fixed default grid (cheb 48) stored -- plane
#: shear 3.2e-7 (pair 2 at ell = 1 and W = 120; the closed-form comparison asks ANALYTIC_TOL),
#: the cylinder 3.9e-11, mu(I) 3.8e-11 -- so that no stored state is less accurate than there.
DEFAULT_TOL = {"nonlocal-shear": ANALYTIC_TOL, "nonlocal-cylinder": 1e-10, "nonlocal-muI": 1e-10}


#: The pairs' mu_w branches run over 0 <= mu_w <= MU_W_SPAN mu (zeta^2 = (1 - mu_w/mu)/ell^2 > 0).
MU_W_SPAN = 0.98


def numbers(request: SceneRequest, defaults: Mapping[str, Any], scene: str) -> dict[str, float]:
    """Defaults merged with the user's values, each a finite number (SceneError otherwise)."""
    return scene_numbers(request, defaults, scene)


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
    def __init__(self, request: SceneRequest, scene: str) -> None:
        self.request = request
        self.scene = scene
        self.done: list[Branch] = []

    def run(self, branch_id: str, make: Any) -> Branch:
        if branch_id in self.request.completed:
            branch = self.request.completed[branch_id]
        else:
            self.request.report(f"tracing {branch_id}")
            branch = require_started(make(), self.scene)  # the scene reads its observables next
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
    for name in ("mu_w", "mu_w2"):  # -s mu_w=0.3617 said 'start value mu_w=0.3617 lies outside its bounds (0, 0.354564)'
        if not s[name] < MU_W_SPAN * s["mu"]:
            raise SceneError(f"{name} = {s[name]:g} must be below {MU_W_SPAN:g} mu = {MU_W_SPAN * s['mu']:g}: each pair "
                             f"is continued in mu_w from 0 to {MU_W_SPAN:g} mu through its own value")
    em = _Emitter(request, "nonlocal-shear")
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
                  "mu_w": (0.0, MU_W_SPAN * s["mu"], 0.01),
                  "W": (s["W_min"], s["W_max"], 1.0)}
        asym = 0.0
        traced: dict[str, Branch] = {}
        for name, (lo, hi, ds) in ranges.items():
            bid = f"pair{k}.{name}"
            br = traced[name] = em.run(bid, lambda name=name, lo=lo, hi=hi, ds=ds, bid=bid: _trace(pb, p, name, lo, hi, ds, request, bid))
            asym = max(asym, float(np.max(br.observables["asym_phi"])), float(np.max(br.observables["asym_u"])))
            if br.status != "EP":
                notes.append(f"{bid}: ended {br.status}: {br.message}")
        obs = _at_start(pb, traced["ell"], "ell", p)
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


def _on_own_grid(pb: Any, state: Any) -> tuple[Any, np.ndarray]:
    """(the problem on the grid of ``state``, state): a state of any grid of ``pb``'s method
    (adaptive runs store each point on its own grid; both problems hold 2 (N + 1) + 1 values)."""
    x = np.asarray(state, dtype=float)
    return (pb if x.size == pb.size else on_grid(pb, (x.size - 1) // 2 - 1)), x


def _on_start_grid(pb: Any, state: Any) -> np.ndarray:
    """A state of any grid of ``pb``'s method on ``pb``'s own nodes (the file's y)."""
    own, x = _on_own_grid(pb, state)
    return x if own is pb else own.transfer(x, pb)


def _at_start(pb: Any, branch: Branch, parameter: str, p: Mapping[str, float]) -> dict[str, float]:
    """The observables at the branch's start point p (the branch passes through it: trace_both
    from p), on that point's own grid; solved on ``pb``'s grid if the branch lacks it."""
    hit = np.flatnonzero(np.asarray(branch.params[parameter]) == p[parameter]) if len(branch) else []
    for i in hit:
        try:
            x = branch.state(int(i))
        except KeyError:
            continue
        return point_problem(pb, branch, int(i)).observables(x, p)
    return pb.observables(_solve(pb, p), p)


def _solve(pb: PlaneShear, p: Mapping[str, float]) -> np.ndarray:
    from contin.continuation import newton

    res = newton(pb, pb.initial(p), p)
    if not res.converged:
        raise SceneError(f"Newton did not converge at the start point: {res.message}")
    return res.u


def _shear_profiles(pb: PlaneShear, state: np.ndarray) -> dict[str, np.ndarray]:
    """phi, gamma W = du/d(y/W) and u - u(0) on y/W (u(0) = K gamma(0) needs K/W: see the branch),
    on ``pb``'s nodes for a state of any grid."""
    phi, g, _ = pb.split(_on_start_grid(pb, state))
    rel = np.concatenate([[0.0], np.cumsum(pb.cells @ g)])
    return {"phi": phi.copy(), "gamma_W": g.copy(), "u_minus_u0": rel}


def _analytic_errors(pb: PlaneShear, branch: Branch, base: Mapping[str, float]) -> tuple[float, float]:
    """Max |u - u_exact| and max relative error of the wall-layer width along a uniform-phi branch
    (each point on its own grid, ``Branch.grid``)."""
    eu = ed = 0.0
    idx = branch.state_index if branch.state_index is not None else np.arange(len(branch))
    for i in (int(j) for j in idx):
        row = branch.state(i)
        own = point_problem(pb, branch, i)
        p = dict(base)
        p.update({name: float(col[i]) for name, col in branch.params.items()})
        an = PlaneShearAnalytic(p["W"], p["K"], p["ell"], p["mu_w"], p["mu"])
        eu = max(eu, float(np.max(np.abs(own.velocity(row, p) - an.u(own.y(p))))))
        ed = max(ed, abs(float(branch.observables["delta"][i]) / an.wall_layer - 1.0))
    return eu, ed


MUI_DEFAULTS: dict[str, Any] = {
    **{k: PLANE_DEFAULTS[k] for k in ("W", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w", "dmu", "I0", "A_phi")},
    **CS_DEFAULTS, "U_max": 1.0, "U_min_phiI": 0.05,
}


def run_muI(request: SceneRequest) -> SceneResult:
    s = numbers(request, MUI_DEFAULTS, "nonlocal-muI")
    cs = critical_state(s)
    p = dict(PLANE_DEFAULTS)
    p.update({k: s[k] for k in p if k in s}, U=0.0)
    method, grid = request.method or "cheb", request.grid or 48
    try:
        pb = PlaneShear(method, grid, cs)
        pi_b = PlaneShear(method, grid, cs, phi_model="phiI")
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    _checked(pb, p)
    if not s["A_phi"] > 0:
        raise SceneError(f"the phi(I) slope A_phi must be > 0, got {s['A_phi']:g}")
    if not (0 < s["U_min_phiI"] < s["U_max"]):
        raise SceneError(f"need 0 < U_min_phiI < U_max, got {s['U_min_phiI']:g}, {s['U_max']:g}")
    em = _Emitter(request, "nonlocal-muI")
    notes: list[str] = []
    extra: dict[str, Any] = {}

    def trace_U(problem: PlaneShear, U0: float, bid: str) -> Branch:
        from contin.continuation import trace

        q = dict(p, U=U0)
        options = request.options_for(ContinuationOptions(
            bounds={"U": (U0, s["U_max"])}, max_steps=200, step=StepOptions(ds=0.02, ds_max=0.1, ds_min=1e-8)))
        return trace(problem, problem.initial(q), q, "U", options, branch_id=bid, progress=request.report)

    mui = em.run("muI.U", lambda: trace_U(pb, 0.0, "muI.U"))
    # U = 0 is the quasi-static model: the first point against the plane-shear problem with dmu = 0
    first = point_problem(pb, mui, 0)  # (its own grid: adaptive runs)
    quasi = _solve(first, dict(p, dmu=0.0))
    diff = float(np.max(np.abs(mui.state(0) - quasi)))
    I_max = np.asarray(mui.observables["I_max"])
    U = np.asarray(mui.params["U"])
    cross = np.flatnonzero((I_max[:-1] < 0.1) & (I_max[1:] >= 0.1))
    U_01 = float(np.interp(0.1, I_max[cross[0]:cross[0] + 2], U[cross[0]:cross[0] + 2])) if cross.size else float("nan")
    d = mui.observables["delta"]
    extra["muI"] = {"quasi_static_difference": diff, "U_at_I_max_0.1": U_01, "I_max_end": float(I_max[-1]),
                    "delta_start": float(d[0]), "delta_end": float(d[-1]),
                    "u_slip_start": float(mui.observables["u_slip"][0]), "u_slip_end": float(mui.observables["u_slip"][-1])}
    notes.append(f"mu(I): at U = 0 the state equals the quasi-static nonlocal-shear solution to {diff:.1g}; "
                 + (f"I_max = 0.1 at U = {U_01:.6g}; " if cross.size else "I_max stays below 0.1; ")
                 + f"from U = 0 to {U[-1]:g}: wall layer {d[0]:.4g} -> {d[-1]:.4g} d_p, slip u(0) "
                 f"{extra['muI']['u_slip_start']:.4g} -> {extra['muI']['u_slip_end']:.4g}, I_max = {I_max[-1]:.3g}")
    if mui.status != "EP":
        notes.append(f"muI.U: ended {mui.status}: {mui.message}")

    phb = em.run("phiI.U", lambda: trace_U(pi_b, s["U_min_phiI"], "phiI.U"))
    scaled = np.asarray(phb.observables["P"]) / np.asarray(phb.params["U"]) ** 2
    spread = float(np.max(np.abs(scaled / scaled[0] - 1.0)))
    extra["phiI"] = {"P_over_U2": float(scaled[0]), "P_over_U2_spread": spread,
                     "phi_wall": float(phb.observables["phi_wall"][0]), "phi_mid": float(phb.observables["phi_mid"][0]),
                     "I_max": float(phb.observables["I_max"][0])}
    notes.append(f"phi(I) comparison (A_phi = {s['A_phi']:g}): P = {scaled[0]:.6g} U^2 along the branch (spread {spread:.1g}); "
                 f"phi = {extra['phiI']['phi_wall']:.4g} at the walls and {extra['phiI']['phi_mid']:.4g} at mid-plane "
                 f"(phi_max = {cs.phi_max:g}: the local law packs the slowly sheared core to phi_max and dilutes the walls), "
                 f"against {float(mui.observables['phi_wall'][0]):.4g} and {float(mui.observables['phi_mid'][0]):.4g} for the non-local model")
    if phb.status != "EP":
        notes.append(f"phiI.U: ended {phb.status}: {phb.message}")
    return SceneResult(
        branches=em.done,
        parameters=s,
        discretization={"method": pb.grid.method, "intervals": pb.grid.intervals},
        y=pb.grid.y + 0.5,
        profiles=lambda state: _shear_profiles(pb, state),
        notes=notes,
        extra=extra,
    )


def _grid_of(discretization: Mapping[str, Any]) -> tuple[str, int]:
    """(method, intervals) of a stored run (the scenes' default grid is cheb 48)."""
    return str(discretization.get("method", "cheb")), int(discretization.get("intervals", discretization.get("grid", 48)))


def shear_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> PlaneShear:
    """The problem of a nonlocal-shear run: plane shear with the file's critical state."""
    method, n = _grid_of(discretization)
    cs = critical_state({k: float(parameters.get(k, v)) for k, v in CS_DEFAULTS.items()})
    return PlaneShear(method, n, cs)


CYL_SCENE_DEFAULTS: dict[str, Any] = {**CYL_DEFAULTS, "mu_w": CYL_DEFAULTS["mu_w"], **CS_DEFAULTS,
                                      "ratio_min": 1.1, "ratio_max": 6.0, "report_eqs": 0.0}


def run_cylinder(request: SceneRequest) -> SceneResult:
    s = numbers(request, CYL_SCENE_DEFAULTS, "nonlocal-cylinder")
    cs = critical_state(s)
    if s["report_eqs"] not in (0.0, 1.0):
        raise SceneError(f"report_eqs must be 0 (derived operator) or 1 (the report's printed one), got {s['report_eqs']:g}")
    ops = ["report"] if s["report_eqs"] == 1.0 else ["derived", "report"]
    p = {k: s[k] for k in CYL_DEFAULTS}
    _checked(CylindricalCouette(cs=cs), p)
    if not (1.0 < s["ratio_min"] <= s["ratio"] <= s["ratio_max"]):
        raise SceneError(f"need 1 < ratio_min <= ratio <= ratio_max, got {s['ratio_min']:g}, {s['ratio']:g}, {s['ratio_max']:g}")
    em = _Emitter(request, "nonlocal-cylinder")
    notes: list[str] = []
    extra: dict[str, Any] = {}
    problems: dict[str, CylindricalCouette] = {}
    for op in ops:
        try:
            pb = CylindricalCouette(request.method or "cheb", request.grid or 48, cs, operator=op)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        _checked(pb, p)
        problems[op] = pb
        bid = f"{op}.ratio"
        br = em.run(bid, lambda pb=pb, bid=bid: _trace(pb, p, "ratio", s["ratio_min"], s["ratio_max"], 0.02, request, bid))
        if br.status != "EP":
            notes.append(f"{bid}: ended {br.status}: {br.message}")
        obs = _at_start(pb, br, "ratio", p)
        extra[op] = obs
        changes = int(np.max(br.observables["gamma_sign_changes"]))
        notes.append(f"{op} equations at r_o/r_i = {p['ratio']:g}, W = {p['W']:g}: P = {obs['P']:.6g}, u(r_i) = {obs['u_inner']:.6g}, "
                     f"u(mid-gap) = {obs['u_mid']:.6g}, phi_mid = {obs['phi_mid']:.6g}"
                     + (f"; the shear rate changes sign on part of the branch ({changes} sign changes): outside the "
                        "model's flowing branch there" if changes else ""))
    first = problems[ops[0]]
    return SceneResult(
        branches=em.done,
        parameters=s,
        discretization={"method": first.grid.method, "intervals": first.grid.intervals},
        y=first.grid.y + 0.5,
        profiles=lambda state: _cylinder_profiles(first, state),
        notes=notes,
        extra=extra,
    )


def _cylinder_profiles(pb: CylindricalCouette, state: np.ndarray) -> dict[str, np.ndarray]:
    """phi and u on ``pb``'s nodes, for a state of any grid."""
    phi, u, _ = pb.split(_on_start_grid(pb, state))
    return {"phi": phi.copy(), "u": u.copy()}


def cylinder_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> CylindricalCouette:
    """The problem of a nonlocal-cylinder run with ``report_eqs=1`` (the report's operator only).

    A default run stores the branches of two operators (derived.ratio, report.ratio): refused."""
    if float(parameters.get("report_eqs", 0.0)) != 1.0:
        raise SceneError("nonlocal-cylinder with report_eqs = 0 stores the branches of two problems (the derived "
                         "operator, derived.ratio, and the report's, report.ratio), so no single problem can be "
                         "rebuilt; trace -s report_eqs=1 for a file of one problem")
    method, n = _grid_of(discretization)
    cs = critical_state({k: float(parameters.get(k, v)) for k, v in CS_DEFAULTS.items()})
    return CylindricalCouette(method, n, cs, operator="report")


SCENES = {
    "nonlocal-shear": Scene(
        name="nonlocal-shear",
        summary="Dsouza-Nott non-local model, plane shear: sinh profile, coupled phi-u at phi_bar, continuation in ell, mu_w, W",
        defaults=SHEAR_DEFAULTS,
        run=run_shear,
        x="ell",
        y="delta",
        adaptive=True,
        default_tol=DEFAULT_TOL["nonlocal-shear"],
        problem_factory=shear_factory,
        stability=False,
    ),
    "nonlocal-muI": Scene(
        name="nonlocal-muI",
        summary="Dsouza-Nott model with mu(I) in plane shear, continued in wall speed from the quasi-static limit; phi(I) comparison",
        defaults=MUI_DEFAULTS,
        run=run_muI,
        x="U",
        y="delta",
        adaptive=True,
        default_tol=DEFAULT_TOL["nonlocal-muI"],
        stability=False,  # and no problem_factory: muI.U and phiI.U are states of two problems
    ),
    "nonlocal-cylinder": Scene(
        name="nonlocal-cylinder",
        summary="Dsouza-Nott non-local model, cylindrical Couette flow (inner wall moving): phi(r), u(r) continued in r_o/r_i",
        defaults=CYL_SCENE_DEFAULTS,
        run=run_cylinder,
        x="ratio",
        y="phi",
        adaptive=True,
        default_tol=DEFAULT_TOL["nonlocal-cylinder"],
        problem_factory=cylinder_factory,
        stability=False,
    ),
}
