"""Demo scenes for the CLI: ``contin trace bratu`` and ``contin trace allen-cahn``.

- ``bratu``: u'' + lam e^u = 0 on [0, 1], Dirichlet; traced from u = 0 at lam = lam_min up
  through the fold lam* = 3.513830719125162 and back along the upper branch.
- ``allen-cahn``: u'' + lam (u - u^3) = 0 on [0, pi], Dirichlet; the trivial branch u = 0 for
  lam in [lam_min, lam_max], its branch points (lam = k^2) and both signs of every bifurcated
  branch.
- ``swift-hohenberg``: -(I + Delta)^2 u + lam u + nu u^3 - u^5 = 0 (problems.swift_hohenberg,
  BifurcationKit's automatic-diagram tutorial): u = 0 traced in lam, its BPs against
  lam_k = (1 - m_k)^2.
- bratu, allen-cahn and swift-hohenberg give a start point (``Scene.start``):
  ``contin trace SCENE --depth D`` builds their whole diagram with ``contin.diagram.explore``.
- ``stretched-bratu``: Bratu on a stretched coordinate (problems.demo.StretchedBratu, parameters
  lam and a): the fold branch in lam at a fixed a; its fold continued in a
  (``contin continue FILE --from LP1 --free a``) follows lam = lam*/(1 + a) into a layer of width
  ~ 1/a, so the grid a tolerance needs grows along the fold curve (``--tol``: segment-wise
  regridding).
- ``lorenz``: the Lorenz equilibrium C+ for rho in [rho_min, rho_max] (sigma = 10, beta = 8/3 by
  default): a subcritical Hopf point (HB) at rho = 470/19 with omega and l1.
- ``ab``: AUTO-07p's demo ab (problems.demo.AB, a CSTR): u = 0 at D = 0 traced in D up to D_max
  (B = 14, beta = 3): a subcritical and a supercritical Hopf point; ``contin continue FILE
  --from HB1 --free B`` traces their Hopf curve through a Bogdanov-Takens (BT, B = 64/3) and a
  generalized Hopf point (GH).
- ``brusselator``: the 1-D Brusselator (problems.demo.Brusselator, fields u and v on x in [0, 1],
  u = a, v = b/a at the ends): the homogeneous state traced in b over [b_min, b_max]; its first
  Hopf point (HB) against the closed form b_H = 1 + a^2 + (D1 + D2) pi^2 / L^2.  Adaptive like
  bratu (``--tol``, ``--special-tol``): the homogeneous state is exact on every grid, so the HB's
  two-grid position check (``contin.specialcheck.hopf_point_error``) alone chooses its grid.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.adapt import on_grid
from contin.branch import Branch, relabel
from contin.continuation import trace, trace_both
from contin.options import ContinuationOptions, StepOptions
from contin.resume import switch_reusing
from contin.scene import DiagramStart, Scene, SceneError, SceneRequest, SceneResult, scene_numbers
from problems.demo import AB, BRATU_FOLD, AllenCahn, Bratu, Brusselator, Lorenz, StretchedBratu


def _numbers(request: SceneRequest, defaults: Mapping[str, float], scene: str) -> dict[str, float]:
    """Defaults merged with the user's values, each checked to be a finite number."""
    out = scene_numbers(request, defaults, scene)
    if "lam_min" in out and not out["lam_min"] < out["lam_max"]:
        raise SceneError(f"need lam_min < lam_max, got lam_min={out['lam_min']:g}, lam_max={out['lam_max']:g}")
    return out


def _make(cls: type, method: str | None, grid: int) -> Any:
    """``cls(method, grid)`` with a bad discretization as a SceneError (one line)."""
    try:
        return cls(method or "cheb", grid)
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _problem(cls: type, request: SceneRequest, default_grid: int = 32) -> Any:
    return _make(cls, request.method, request.grid or default_grid)


def _on_start_grid(pb: Any, state: Any) -> np.ndarray:
    """A state of any grid of ``pb``'s method (adaptive runs) on ``pb``'s own nodes (the file's y)."""
    u = np.asarray(state, dtype=float)
    return u if u.size == pb.n else on_grid(pb, u.size - 1).transfer(u, pb)


def _emit(request: SceneRequest, done: list[Branch], branch: Branch) -> None:
    done.append(branch)
    relabel(done)  # earlier branches keep their labels; the new one continues the numbering
    request.finished(branch)


BRATU_DEFAULTS = {"lam_min": 0.0, "lam_max": 4.0}


def run_bratu(request: SceneRequest) -> SceneResult:
    p = _numbers(request, BRATU_DEFAULTS, "bratu")
    if p["lam_min"] >= BRATU_FOLD:
        raise SceneError(f"lam_min must lie below the fold lam*={BRATU_FOLD:.6f} (there are no solutions above it)")
    pb = _problem(Bratu, request)
    options = request.options_for(_bratu_options(p))
    done: list[Branch] = []
    if "0" in request.completed:
        branch = request.completed["0"]
    else:
        request.report("bratu: tracing from u = 0")
        branch = trace(pb, pb.initial(), {"lam": p["lam_min"]}, "lam", options, progress=request.report)
    _emit(request, done, branch)
    notes = [f"{lp.name}: lam = {lp.params['lam']:.15g} (exact {BRATU_FOLD}, error {lp.params['lam'] - BRATU_FOLD:.2g})"
             for lp in branch.fold_points]
    return SceneResult(
        branches=done,
        parameters=p,
        discretization={"method": pb.grid.method, "intervals": pb.grid.intervals},
        y=pb.x,
        profiles=lambda state: {"u": _on_start_grid(pb, state)},
        notes=notes,
    )


def _bratu_options(p: Mapping[str, float]) -> ContinuationOptions:
    return ContinuationOptions(bounds={"lam": (p["lam_min"], p["lam_max"])}, max_steps=60,
                               step=StepOptions(ds=0.05, ds_max=0.25))


def _dirichlet_discretization(pb: Any) -> dict[str, Any]:
    return {"method": pb.grid.method, "intervals": pb.grid.intervals}


def start_bratu(request: SceneRequest) -> DiagramStart:
    """u = 0 at lam = lam_min; the diagram is the fold branch (no BPs): its LP against lam*."""
    p = _numbers(request, BRATU_DEFAULTS, "bratu")
    pb = _problem(Bratu, request)

    def notes(d: Any) -> list[str]:
        return [f"{lp.name}: lam = {lp.params['lam']:.15g} (exact {BRATU_FOLD}, error {lp.params['lam'] - BRATU_FOLD:.2g})"
                for b in d.branches for lp in b.fold_points]

    return DiagramStart(problem=pb, state=pb.initial(), params={"lam": p["lam_min"]}, parameter="lam",
                        options=request.options_for(_bratu_options(p)), parameters=p,
                        discretization=_dirichlet_discretization(pb), y=pb.x,
                        profiles=lambda state: {"u": _on_start_grid(pb, state)}, notes=notes)


ALLEN_CAHN_DEFAULTS = {"lam_min": 0.0, "lam_max": 10.0}


def _allen_cahn_options(p: Mapping[str, float]) -> ContinuationOptions:
    return ContinuationOptions(bounds={"lam": (p["lam_min"], p["lam_max"])}, max_steps=200,
                               step=StepOptions(ds=0.05, ds_max=0.25))


def start_allen_cahn(request: SceneRequest) -> DiagramStart:
    """u = 0 at lam = lam_min: BPs of the trivial branch at lam = k^2, named against k^2 in the notes."""
    p = _numbers(request, ALLEN_CAHN_DEFAULTS, "allen-cahn")
    pb = _problem(AllenCahn, request)

    def notes(d: Any) -> list[str]:
        return [f"{bp.name}: lam = {bp.params['lam']:.12g} (expected {round(math.sqrt(bp.params['lam'])) ** 2})"
                for bp in d.branch("0").branch_points]

    return DiagramStart(problem=pb, state=pb.initial(), params={"lam": p["lam_min"]}, parameter="lam",
                        options=request.options_for(_allen_cahn_options(p)), parameters=p,
                        discretization=_dirichlet_discretization(pb), y=pb.x,
                        profiles=lambda state: {"u": _on_start_grid(pb, state)}, notes=notes)


def run_allen_cahn(request: SceneRequest) -> SceneResult:
    p = _numbers(request, ALLEN_CAHN_DEFAULTS, "allen-cahn")
    pb = _problem(AllenCahn, request)
    options = request.options_for(_allen_cahn_options(p))
    done: list[Branch] = []
    if "0" in request.completed:
        trivial = request.completed["0"]
    else:
        request.report("allen-cahn: tracing the trivial branch")
        trivial = trace(pb, pb.initial(), {"lam": p["lam_min"]}, "lam", options, kind="trivial",
                        progress=request.report)
    _emit(request, done, trivial)
    notes = []
    for bp in trivial.branch_points:
        k = math.sqrt(bp.params["lam"])
        notes.append(f"{bp.name}: lam = {bp.params['lam']:.12g} (expected {round(k) ** 2}, mode {round(k)}; {bp.note})")
        prefix = f"0.{bp.name}"
        ids = [f"{prefix}.1", f"{prefix}.2"]
        if all(i in request.completed for i in ids):
            children = [request.completed[i] for i in ids]
        else:  # each finished half is reused (a kill between the halves loses only the second)
            request.report(f"allen-cahn: switching at {bp.name} (lam = {bp.params['lam']:.6g})")
            children = switch_reusing(request.completed, pb, trivial, bp, options, branch_id_prefix=prefix)
        for child in children:
            _emit(request, done, child)
    return SceneResult(
        branches=done,
        parameters=p,
        discretization={"method": pb.grid.method, "intervals": pb.grid.intervals},
        y=pb.x,
        profiles=lambda state: {"u": _on_start_grid(pb, state)},
        notes=notes,
    )


SWIFT_HOHENBERG_DEFAULTS = {"lam": -0.7, "nu": 2.0, "l": 6.0, "lam_min": -1.0, "lam_max": 1.0}
#: Grid points of the Swift-Hohenberg scene without --grid (BifurcationKit's tutorial).
SWIFT_HOHENBERG_GRID = 200


def _swift_hohenberg(request: SceneRequest) -> tuple[Any, dict[str, float], ContinuationOptions]:
    """The problem, parameters and options of BifurcationKit's automatic-diagram tutorial:
    ds_max = 0.02 (at 0.05 the BPs of u = 0 at lam = 0.484 and 0.531 fall in one step)."""
    from problems.swift_hohenberg import SwiftHohenberg

    p = scene_numbers(request, SWIFT_HOHENBERG_DEFAULTS, "swift-hohenberg")
    if not p["lam_min"] <= p["lam"] <= p["lam_max"] or not p["lam_min"] < p["lam_max"]:
        raise SceneError(f"need lam_min <= lam <= lam_max and lam_min < lam_max, got {p['lam_min']:g}, "
                         f"{p['lam']:g}, {p['lam_max']:g}")
    if request.method not in (None, "fd2"):
        raise SceneError(f"scene 'swift-hohenberg' has one discretization (fd2, --grid N points), not {request.method!r}")
    if not p["l"] > 0:
        raise SceneError(f"the half length l must be > 0, got {p['l']:g}")
    try:
        pb = SwiftHohenberg(request.grid or SWIFT_HOHENBERG_GRID, p["l"])
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    options = request.options_for(ContinuationOptions(
        bounds={"lam": (p["lam_min"], p["lam_max"])}, max_steps=1000,
        step=StepOptions(ds=0.01, ds_max=0.02, max_angle=0.3)))
    return pb, p, options


def _swift_hohenberg_notes(pb: Any, trivial: Branch, lo: float, hi: float) -> list[str]:
    """The BPs of u = 0 against lam_k = (1 - m_k)^2 (problems.swift_hohenberg), and any not found."""
    exact = pb.trivial_branch_points(lo, hi)
    notes = []
    for bp in trivial.branch_points:
        k = int(np.argmin(np.abs(exact - bp.params["lam"]))) if exact.size else -1
        ref = f"closed form (1 - m_k)^2 = {exact[k]:.12g}, error {bp.params['lam'] - exact[k]:.2g}" if k >= 0 else "no closed form"
        notes.append(f"{bp.name} of u = 0: lam = {bp.params['lam']:.12g} ({ref})")
    if len(trivial.branch_points) != exact.size:
        notes.append(f"u = 0 has {exact.size} BPs in ({lo:g}, {hi:g}) by the closed form, "
                     f"{len(trivial.branch_points)} were detected")
    return notes


def _swift_hohenberg_result(pb: Any, p: Mapping[str, float]) -> dict[str, Any]:
    return {"parameters": dict(p), "discretization": {"method": "fd2", "intervals": pb.N}, "y": pb.x,
            "profiles": lambda state: {"u": np.asarray(state, dtype=float)}}


def run_swift_hohenberg(request: SceneRequest) -> SceneResult:
    """u = 0 traced both ways from lam; its BPs against the closed form (--depth: the whole diagram)."""
    pb, p, options = _swift_hohenberg(request)
    params = {"lam": p["lam"], "nu": p["nu"]}
    done: list[Branch] = []
    if "0" in request.completed:
        trivial = request.completed["0"]
    else:
        request.report("swift-hohenberg: tracing u = 0")
        trivial = trace_both(pb, np.zeros(pb.N), params, "lam", options, kind="trivial", progress=request.report)
    request.run_stability(pb, trivial, params)
    _emit(request, done, trivial)
    return SceneResult(branches=done, notes=_swift_hohenberg_notes(pb, trivial, p["lam_min"], p["lam_max"]),
                       **_swift_hohenberg_result(pb, p))


def start_swift_hohenberg(request: SceneRequest) -> DiagramStart:
    """u = 0 at lam (BifurcationKit's tutorial: -0.7), nu fixed; S u = -u gives the mirror images."""
    pb, p, options = _swift_hohenberg(request)
    return DiagramStart(problem=pb, state=np.zeros(pb.N), params={"lam": p["lam"], "nu": p["nu"]}, parameter="lam",
                        options=options, **_swift_hohenberg_result(pb, p),
                        notes=lambda d: _swift_hohenberg_notes(pb, d.branch("0"), p["lam_min"], p["lam_max"]))


STRETCHED_BRATU_DEFAULTS = {"a": 0.0, "lam_min": 0.0, "lam_max": 4.0}


def run_stretched_bratu(request: SceneRequest) -> SceneResult:
    """The fold branch in lam at fixed a (from u = 0 at lam_min); its LP against lam*/(1 + a)."""
    p = _numbers(request, STRETCHED_BRATU_DEFAULTS, "stretched-bratu")
    try:  # the range of a, before any computation (-s a=1e6 printed an OverflowError line)
        StretchedBratu.check_a(p["a"])
    except ValueError as exc:
        raise SceneError(f"parameter {exc}") from None
    if p["lam_min"] >= BRATU_FOLD / (1.0 + p["a"]):
        raise SceneError(f"lam_min must lie below the fold lam*/(1 + a) = {BRATU_FOLD / (1.0 + p['a']):.6f}")
    pb = _problem(StretchedBratu, request, default_grid=24)
    options = request.options_for(_bratu_options(p))
    done: list[Branch] = []
    if "0" in request.completed:
        branch = request.completed["0"]
    else:
        request.report(f"stretched-bratu: tracing from u = 0 at a = {p['a']:g}")
        branch = trace(pb, pb.initial(), {"lam": p["lam_min"], "a": p["a"]}, "lam", options, progress=request.report)
    _emit(request, done, branch)
    exact = float(StretchedBratu.fold_curve(p["a"]))
    notes = [f"{lp.name}: lam = {lp.params['lam']:.15g} (exact lam*/(1 + a) = {exact:.15g}, error "
             f"{lp.params['lam'] - exact:.2g})" for lp in branch.fold_points]
    return SceneResult(branches=done, parameters=p, discretization=_dirichlet_discretization(pb), y=pb.x,
                       profiles=lambda state: {"u": _on_start_grid(pb, state)}, notes=notes)


def stretched_bratu_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> StretchedBratu:
    """The problem of a stretched-bratu file, on its start grid (``contin.adapt.on_grid`` the others)."""
    return _make(StretchedBratu, discretization.get("method"), int(discretization.get("intervals") or 24))


LORENZ_DEFAULTS = {"sigma": 10.0, "beta": 8.0 / 3.0, "rho_min": 1.5, "rho_max": 40.0}


def run_lorenz(request: SceneRequest) -> SceneResult:
    p = _numbers(request, LORENZ_DEFAULTS, "lorenz")
    if not 1.0 < p["rho_min"] < p["rho_max"]:
        raise SceneError("need 1 < rho_min < rho_max (C+ exists for rho > 1)")
    params = {"sigma": p["sigma"], "beta": p["beta"], "rho": 0.5 * (p["rho_min"] + p["rho_max"])}
    options = request.options_for(ContinuationOptions(
        bounds={"rho": (p["rho_min"], p["rho_max"])}, max_steps=200, step=StepOptions(ds=0.5, ds_max=2.0)))
    done: list[Branch] = []
    if "0" in request.completed:
        branch = request.completed["0"]
    else:
        request.report("lorenz: tracing C+")
        branch = trace_both(Lorenz(), Lorenz.equilibrium(params), params, "rho", options, progress=request.report)
    _emit(request, done, branch)
    s, b = p["sigma"], p["beta"]
    notes = []
    if s > b + 1:
        rho_h = s * (s + b + 3) / (s - b - 1)
        notes = [f"{hb.name}: rho = {hb.params['rho']:.15g} (exact {rho_h:.15g}), omega = {hb.data['omega']:.12g} "
                 f"(exact {np.sqrt(b * (s + rho_h)):.12g}), l1 = {hb.data['l1']:.4g}" for hb in branch.points("HB")]
    return SceneResult(branches=done, parameters=p, notes=notes)


AB_DEFAULTS = {"B": 14.0, "beta": 3.0, "D_max": 0.5}


def run_ab(request: SceneRequest) -> SceneResult:
    p = _numbers(request, AB_DEFAULTS, "ab")
    if not p["D_max"] > 0:
        raise SceneError("need D_max > 0 (the branch starts at u = 0, D = 0)")
    if not (math.isfinite(p["B"]) and p["beta"] > -1 and abs(p["B"]) / (1 + p["beta"]) <= 700):
        # the temperature u2 = B u1 / (1 + beta) (u1 <= 1) enters exp: beyond 709 it overflows
        # (-s B=1e300 ended MX with a raw overflow warning and a hint to check the Jacobian)
        raise SceneError(f"need beta > -1 and |B| / (1 + beta) <= 700 (the steady temperature u2 = B u1 / (1 + beta) "
                         f"enters exp), got B = {p['B']:g}, beta = {p['beta']:g}")
    params = {"D": 0.0, "B": p["B"], "beta": p["beta"]}
    options = request.options_for(ContinuationOptions(
        bounds={"D": (0.0, p["D_max"])}, max_steps=2000, step=StepOptions(ds=0.01, ds_max=0.05)))
    done: list[Branch] = []
    if "0" in request.completed:
        branch = request.completed["0"]
    else:
        request.report("ab: tracing u in D from u = 0 at D = 0")
        branch = trace(AB(), np.zeros(2), params, "D", options, progress=request.report)
    _emit(request, done, branch)
    return SceneResult(branches=done, parameters=p, notes=[])


BRUSSELATOR_DEFAULTS = {**Brusselator.PARAMS, "b_min": 4.0, "b_max": 6.0}


def _brusselator_problem(discretization: Mapping[str, Any]) -> Brusselator:
    return _make(Brusselator, discretization.get("method"), int(discretization.get("intervals") or 32))


def _brusselator_profiles(pb: Brusselator, state: Any) -> dict[str, np.ndarray]:
    """u and v of a state of any grid of ``pb``'s method on ``pb``'s nodes."""
    x = np.asarray(state, dtype=float)
    if x.size != pb.n:
        x = on_grid(pb, x.size // 2 - 1).transfer(x, pb)
    u, v = pb.split(x)
    return {"u": u, "v": v}


def run_brusselator(request: SceneRequest) -> SceneResult:
    """The homogeneous state (a, b/a) from b_min to b_max; its HBs against the closed form."""
    p = _numbers(request, BRUSSELATOR_DEFAULTS, "brusselator")
    if not p["b_min"] < p["b_max"]:
        raise SceneError(f"need b_min < b_max, got b_min={p['b_min']:g}, b_max={p['b_max']:g}")
    if p["a"] == 0 or not p["L"] > 0 or not (p["D1"] >= 0 and p["D2"] >= 0):
        raise SceneError(f"need a != 0, L > 0, D1, D2 >= 0, got a={p['a']:g}, L={p['L']:g}, D1={p['D1']:g}, "
                         f"D2={p['D2']:g}")
    pb = _problem(Brusselator, request)
    params = {"b": p["b_min"], **{k: p[k] for k in ("a", "D1", "D2", "L")}}
    options = request.options_for(ContinuationOptions(bounds={"b": (p["b_min"], p["b_max"])}, max_steps=200,
                                                      step=StepOptions(ds=0.05, ds_max=0.25)))
    done: list[Branch] = []
    if "0" in request.completed:
        branch = request.completed["0"]
    else:
        request.report("brusselator: tracing the homogeneous state")
        branch = trace(pb, pb.homogeneous(params), params, "b", options, kind="homogeneous", progress=request.report)
    _emit(request, done, branch)
    notes = []
    diffusion = (p["D1"] + p["D2"]) * math.pi**2 / p["L"] ** 2
    for hb in branch.points("HB"):
        # Each HB against its own mode k: b_k = 1 + a^2 + (D1 + D2) k^2 pi^2 / L^2.  The note compared
        # every run's first HB with k = 1, which lies below b_min for -s a=1.5 or -s b_min=6: "relative
        # error 0.25" for the exact mode-2 point (session 14).
        k = max(1, round(math.sqrt(max(hb.params["b"] - 1 - p["a"] ** 2, 0.0) / diffusion))) if diffusion > 0 else 1
        b_h, omega_h = Brusselator.hopf_point(params, lam=(k * math.pi) ** 2)
        notes.append(f"{hb.name}: b = {hb.params['b']:.15g} (closed form of mode {k}, 1 + a^2 + (D1 + D2) {k * k} pi^2 "
                     f"/ L^2 = {b_h:.15g}, relative error {hb.params['b'] / b_h - 1:.2g}, grid {hb.grid}), omega = "
                     f"{hb.data.get('omega', math.nan):.12g} (closed form {omega_h:.12g})")
    return SceneResult(branches=done, parameters=p, discretization=_dirichlet_discretization(pb), y=pb.x,
                       profiles=lambda state: _brusselator_profiles(pb, state), notes=notes)


SCENES = {
    "bratu": Scene(
        name="bratu",
        summary="Bratu problem u'' + lam e^u = 0 on [0,1], Dirichlet: fold at lam* = 3.5138",
        defaults=BRATU_DEFAULTS,
        run=run_bratu,
        x="lam",
        y="phi",
        adaptive=True,
        default_tol=1e-10,  # the fold to 1e-13, as on the former fixed default grid (cheb 32)
        start=start_bratu,
    ),
    "allen-cahn": Scene(
        name="allen-cahn",
        summary="Allen-Cahn u'' + lam (u - u^3) = 0 on [0,pi], Dirichlet: pitchforks at lam = k^2",
        defaults=ALLEN_CAHN_DEFAULTS,
        run=run_allen_cahn,
        x="lam",
        y="phi",
        adaptive=True,
        default_tol=1e-10,  # the fold to 1e-13, as on the former fixed default grid (cheb 32)
        start=start_allen_cahn,
    ),
    "swift-hohenberg": Scene(
        name="swift-hohenberg",
        summary="1-D Swift-Hohenberg -(1+D^2)^2 u + lam u + nu u^3 - u^5 = 0 (BifurcationKit's automatic-diagram "
                "tutorial): u = 0 with BPs at (1 - m_k)^2",
        defaults=SWIFT_HOHENBERG_DEFAULTS,
        run=run_swift_hohenberg,
        x="lam",
        y="phi",
        start=start_swift_hohenberg,
    ),
    "stretched-bratu": Scene(
        name="stretched-bratu",
        summary="Bratu on a stretched coordinate (lam, a): fold curve lam = lam*/(1 + a), a layer of width ~1/a "
                "(contin continue --from LP1 --free a --tol: segment-wise regridding)",
        defaults=STRETCHED_BRATU_DEFAULTS,
        run=run_stretched_bratu,
        x="lam",
        y="phi",
        adaptive=True,
        default_tol=1e-10,
        problem_factory=stretched_bratu_factory,
    ),
    "brusselator": Scene(
        name="brusselator",
        summary="1-D Brusselator, fields u, v on [0,1], Dirichlet (a, b/a): homogeneous state in b, Hopf point at "
                "b_H = 1 + a^2 + (D1 + D2) pi^2 / L^2",
        defaults=BRUSSELATOR_DEFAULTS,
        run=run_brusselator,
        x="b",
        y="phi",
        adaptive=True,
        default_tol=1e-10,
        problem_factory=lambda parameters, discretization: _brusselator_problem(discretization),
    ),
    "ab": Scene(
        name="ab",
        summary="AUTO-07p demo ab (A -> B in a CSTR) in D: two Hopf points; contin continue FILE --from HB1 --free B: BT and GH",
        defaults=AB_DEFAULTS,
        run=run_ab,
        x="D",
        y="phi",
        problem_factory=lambda parameters, discretization: AB(),
        discretized=False,
    ),
    "lorenz": Scene(
        name="lorenz",
        summary="Lorenz equilibrium C+ in rho: subcritical Hopf point at rho = 470/19 (HB, omega, l1)",
        defaults=LORENZ_DEFAULTS,
        run=run_lorenz,
        x="rho",
        y="phi",
        problem_factory=lambda parameters, discretization: Lorenz(),
        discretized=False,
    ),
}
