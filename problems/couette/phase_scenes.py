"""gPCF jobs that were commands of their own, as scenes (contin/ knows no physics):

- ``gravity-phase`` (was ``contin unfold``): fold curves of gravity-driven Couette flow in the
  (H, G = Fr^-2) plane through the imperfect symmetry-breaking pitchforks
  (:func:`problems.couette.gravity.phase_diagram`); ``extra`` holds where fold pairs / isolas
  are born and die (extrema of G along the curves, XT points), the smallest Fr with a
  floating-plug state (``fr_min_floating_plug``) and the critical gaps.
  ``contin trace gravity-phase -s H_max=70 --json -o phase.h5`` (without ``--grid`` a fold curve
  the resolution guard stops is retraced on a finer grid: ``contin.adapt.retrace_finer``).
- ``gravity-unfolding`` (was ``contin fit --compute``): uniform shear at G = 0 traced in H
  with its first pitchfork (labelled, e.g. BP1 on branch g0), both halves of the pitchfork, and
  every solution component in |H - H_c| <= window at each G of ``G`` (a comma list), each
  branch with the odd order parameter ``delta_s = (nu_top - nu_bottom)/2`` as an observable
  (problems.couette.unfolding).  Then ``contin fit FILE --at BP1`` (generic) fits the normal
  form; ``extra.normal_form`` names G and delta_s for it.  The scene's ``problem_factory``
  rebuilds the problem with ``delta_s`` among its observables, so the fit's Lyapunov-Schmidt
  comparison uses the same coordinate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.branch import relabel
from contin.options import AdaptOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult, scene_number, scene_params
from problems.couette.gravity import HOMOTOPY_G_MIN, gravity_problem, phase_diagram
from problems.couette.model import rebuilt_engine
from problems.couette.params import FR_MIN, G_MAX

PHASE_DEFAULTS: dict[str, Any] = {"nu": 0.3, "e": 0.8, "H_min": 1.0, "H_max": 50.0, "Fr_start": 2000.0}
#: default Chebyshev grid of gravity-phase (as the old `contin unfold --grid 32`)
PHASE_GRID = 32
UNFOLDING_DEFAULTS: dict[str, Any] = {"nu": 0.3, "e": 0.8, "G": "3e-8,1e-7,3e-7,1e-6", "window": 0.3}
UNFOLDING_GRID = 32
#: the gravities gravity-unfolding accepts (its G-homotopy weighs the arclength by 1/G^2)
G_RANGE = (1e-100, 1.0)


def _numbers(request: SceneRequest, defaults: Mapping[str, Any], scene: str, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """Defaults merged with the user's values; every numeric one a finite number."""
    out = scene_params(request, defaults, scene)
    for name in out:
        if name not in skip:
            out[name] = scene_number(scene, name, out[name])
    if not 0 < out["nu"] < 0.65:
        raise SceneError(f"scene {scene!r} needs 0 < nu < 0.65 (random close packing), got nu={out['nu']:g}")
    if not 0 < out["e"] <= 1:
        raise SceneError(f"scene {scene!r} needs a restitution coefficient 0 < e <= 1, got e={out['e']:g}")
    return out


def _problem(request: SceneRequest, grid: int) -> Any:
    try:
        return gravity_problem(request.method or "cheb", request.grid or grid, engine=request.engine or "numpy")
    except ValueError as exc:
        raise SceneError(str(exc)) from None


# --------------------------------------------------------------------------- gravity-phase
def run_phase(request: SceneRequest) -> SceneResult:
    s = _numbers(request, PHASE_DEFAULTS, "gravity-phase")
    if not 0 < s["H_min"] < s["H_max"]:
        raise SceneError(f"need 0 < H_min < H_max, got H_min={s['H_min']:g}, H_max={s['H_max']:g}")
    if not s["Fr_start"] > 0:
        raise SceneError(f"Fr_start (the Fr at which each fold is first found) must be > 0, got {s['Fr_start']:g}")
    fr_max = HOMOTOPY_G_MIN ** -0.5  # each fold is reached by a homotopy in G (qa19: Fr_start=1e300 ended
    if not FR_MIN <= s["Fr_start"] <= fr_max:  # 'target gravity G must be > 0', 1e-150 'OverflowError')
        raise SceneError(f"parameter Fr_start = {s['Fr_start']:g} is out of range; it must satisfy {FR_MIN:g} <= "
                         f"Fr_start <= {fr_max:g} (G = Fr^-2 within {HOMOTOPY_G_MIN:g}..{G_MAX:g}: the homotopy in G "
                         f"weighs the arclength by 1/G^2)")
    pb = _problem(request, PHASE_GRID)
    max_steps = int(request.overrides.get("max_steps", 300))
    params = pb.params({"nu": s["nu"], "e": s["e"]})
    # no --grid: a fold curve the resolution guard stops is retraced on finer grids (the
    # dense plugs at large H need more points than the start); --grid fixes the grid
    refine = None if request.grid else AdaptOptions(max_grid=int(request.overrides.get("max_grid") or 512))
    # each fold curve is stored as it is finished (they were passed on only at the end: a run
    # killed after 35 s of fold0 kept nothing), and --resume reuses the finished ones (it traced
    # them all again; a curve a Ctrl-C cut short is not among them); qa18
    d = phase_diagram(pb, params, H_range=(s["H_min"], s["H_max"]), Fr_start=s["Fr_start"], max_steps=max_steps,
                      progress=request.report, refine=refine, done=request.completed, on_curve=request.finished)
    relabel(d.curves)  # (the final labels: the CLI stores the result's branches at the end)
    notes = [f"fold curve {c.id} ended with MX: {c.message}" for c in d.curves if c.status == "MX"]
    notes.append(f"smallest Fr with a floating-plug state: {d.fr_min_floating_plug:.6g}")
    notes += [f"{r['event']} of fold pairs on {r['curve']} at H = {r['H']:.6g}, Fr = {r['Fr']:.6g}" for r in d.extrema]
    return SceneResult(
        branches=d.curves,
        parameters=dict(s),
        discretization={"method": pb.grid.method, "intervals": pb.N, "engine": pb.engine},
        notes=notes,
        extra={"critical_gaps": d.critical_gaps, "fr_min_floating_plug": d.fr_min_floating_plug,
               "births": [r for r in d.extrema if r["event"] == "birth"],
               "deaths": [r for r in d.extrema if r["event"] == "death"],
               "unresolved": d.unresolved, "max_steps": max_steps},
    )


# --------------------------------------------------------------------------- gravity-unfolding
class WithOddOrderParameter:
    """The gravity problem with ``delta_s = (nu_top - nu_bottom)/2`` among its observables (odd
    under the reflection y -> -y that maps G to -G; problems.couette.unfolding).  Everything
    else is delegated."""

    def __init__(self, problem: Any) -> None:
        self._problem = problem

    def __getattr__(self, name: str) -> Any:
        return getattr(self._problem, name)

    def observables(self, u: Any, p: Mapping[str, Any]) -> dict[str, float]:
        ob = dict(self._problem.observables(u, p))
        ob["delta_s"] = 0.5 * (ob["nu_top"] - ob["nu_bottom"])
        return ob


def unfolding_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> Any:
    return WithOddOrderParameter(gravity_problem(discretization.get("method", "cheb"),
                                                 int(discretization.get("intervals", UNFOLDING_GRID)),
                                                 engine=rebuilt_engine(discretization.get("engine"))))


def _gravities(text: Any) -> list[float]:
    try:
        values = [float(g) for g in str(text).split(",") if g.strip()]
    except ValueError:
        raise SceneError(f"G must be a comma-separated list of numbers, got {text!r}") from None
    if not values or not all(math.isfinite(g) and g > 0 for g in values):
        raise SceneError(f"G needs positive finite gravities G = Fr^-2 (G = 0 is added by itself), got {text!r}")
    # the G-homotopy's arclength weight 1/G^2 must be a finite number: G = 1e-200 ended 'arithmetic
    # failure (ZeroDivisionError)', G = 1e300 'OverflowError' (qa18); the unfolding is about small G
    far = [g for g in values if not G_RANGE[0] <= g <= G_RANGE[1]]
    if far:
        raise SceneError(f"G = {far[0]:g} is outside {G_RANGE[0]:g} <= G <= {G_RANGE[1]:g} (small gravities "
                         f"G = Fr^-2, Fr >= 1, near the gravity-free pitchfork)")
    twice = next((g for i, g in enumerate(values) if g in values[:i]), None)
    if twice is not None:  # each G's branches were traced and stored twice, under the same ids (qa18)
        raise SceneError(f"G lists the value {twice:g} twice, got {text!r}")
    return values


def run_unfolding(request: SceneRequest) -> SceneResult:
    from problems.couette.unfolding import branches_near_bp, first_pitchfork, odd_delta

    s = _numbers(request, UNFOLDING_DEFAULTS, "gravity-unfolding", skip=("G",))
    Gs = _gravities(s["G"])
    if not s["window"] > 0:
        raise SceneError(f"window must be > 0, got {s['window']:g}")
    pb = _problem(request, UNFOLDING_GRID)
    base, bp = first_pitchfork(pb, s["nu"], s["e"])
    branches = [base]
    relabel(branches)
    bp = next(b for b in base.branch_points if b.index == bp.index)  # the same point, labelled
    if not s["window"] < bp.params["H"]:  # -s window=1e300 said 'parameter H = -1e+300 is out of range'
        raise SceneError(f"window = {s['window']:g} must be below the pitchfork's H_c = {bp.params['H']:.6g} "
                         "(the branches are traced on H_c - window .. H_c + window, and H > 0)")
    for G in [0.0, *Gs]:
        request.report(f"gravity-unfolding: branches near {bp.name} at G = {G:g}")
        try:
            branches += branches_near_bp(pb, base, bp, G, s["window"])
        except ValueError as exc:
            # a window narrower than the first step off the pitchfork (its branches start outside it):
            # -s window=1e-5 ended 'start value H=13.0687 lies outside its bounds (13.0685, 13.0685)', 1e-300
            # 'bounds for 'H' must satisfy lo < hi' (qa19)
            if "lies outside its bounds" in str(exc) or "must satisfy lo < hi" in str(exc):
                raise SceneError(f"window = {s['window']:g} is too narrow: the branches switched at {bp.name} (H_c = "
                                 f"{bp.params['H']:.10g}) start up to one step (ds = 0.002 in H) away from it, outside "
                                 f"H_c +- window ({exc}); give window >= 0.002") from None
            raise
    relabel(branches)
    for b in branches:
        b.observables["delta_s"] = np.asarray(odd_delta(b), float)
        request.finished(b)
    label = next(p.name for p in base.special_points if p.index == bp.index and p.type == "BP")
    return SceneResult(
        branches=branches,
        parameters={"nu": s["nu"], "e": s["e"], "G": 0.0, "G_values": Gs, "window": s["window"]},
        discretization={"method": pb.grid.method, "intervals": pb.N, "engine": pb.engine},
        y=pb.grid.y,
        profiles=pb.profiles,
        notes=[f"first pitchfork {label} of branch {base.id} at H = {bp.params['H']:.10g}; "
               f"fit with: contin fit FILE --at {label}"],
        extra={"normal_form": {"point": label, "branch": base.id, "imperfection": "G", "delta": "delta_s"}},
    )


PHASE_SCENES = {
    "gravity-phase": Scene(
        name="gravity-phase",
        summary="fold curves of gravity-driven Couette flow in (H, G = Fr^-2): isola birth/death, floating-plug limit Fr*",
        defaults=PHASE_DEFAULTS, run=run_phase, x="H", y="phi",
        problem_factory=lambda parameters, discretization: gravity_problem(
            discretization.get("method", "cheb"), int(discretization.get("intervals", PHASE_GRID)),
            engine=rebuilt_engine(discretization.get("engine"))),
    ),
    "gravity-unfolding": Scene(
        name="gravity-unfolding",
        summary="branches near the first pitchfork at small gravities G, for `contin fit FILE --at BP1`",
        defaults=UNFOLDING_DEFAULTS, run=run_unfolding, x="H", y="delta_s", problem_factory=unfolding_factory,
    ),
}
