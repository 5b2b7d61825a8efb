"""Key points of gPCF for ``contin accuracy``: a small scene traced with the core directly.

``gpcf-keypoints`` (uniform shear, no-slip adiabatic walls, chi = jj, g = 0):

- ``Hc1``: the first symmetry-breaking BP on uniform shear at (nu, e) = (0.3, 0.8), exact
  value H_1^c = pi psi(nu, e) (physics.md section 4);
- ``LP_nu0.16``: the fold of the subcritical n = 1 banded branch at nu = 0.16, e = 0.8
  (H ~ 41.96; the solve_bvp baseline in benchmarks/ finds 41.963 by pinning).

``gpcf-frstar`` (gravity, Fr = G^-1/2): ``Fr*``, the smallest Froude number with a floating-plug
state at (nu, e) = (0.3, 0.8): the maximum of G along the (H, G) fold curve of the first
imperfect pitchfork (problems.couette.gravity.pitchfork_fold_curves; 254.12, the gravity-phase
scene and AUTO-07p's job d agree).  With ``--tol`` the fold curve's grid is chosen from its seed
and where the guard at tol stops the curve it continues on a finer grid from its last accepted
point (``choose_grid``; ``contin.foldcurve.SegmentRegrid``).

Each is traced as a user would: uniform branch in H through the BP, branch switching, banded
branch down to its fold, where it stops (AUTO's STOP LP1).  The result exposes ``extra['key_points']`` (see contin.accuracy).
The scene is adaptive: ``--tol`` (``SceneRequest.overrides['tol']``) lets every trace choose and
change its grid (``contin.adapt``); ``contin accuracy gpcf-keypoints --tols 1e-4,...`` compares
those runs with the fixed grids.
Register it for the CLI with ``CONTIN_SCENES=problems.couette.keypoints:SCENES``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from contin.branch import Branch, relabel
from contin.continuation import switch, trace
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult, scene_numbers
from problems.couette.closures import critical_gap_factor
from problems.couette.model import CouetteProblem
from problems.couette.params import build_params

DEFAULTS: dict[str, Any] = {"e": 0.8, "nu_super": 0.3, "nu_sub": 0.16}


def exact_hc1(nu: float, e: float) -> float:
    """H_1^c = pi psi(nu, e)."""
    return float(np.pi * critical_gap_factor(nu, e))


def first_bp_options(nu: float, e: float) -> ContinuationOptions:
    """The uniform-shear trace of :func:`first_bp`: H from 0.8 H_1^c to 1.2 H_1^c."""
    hc = exact_hc1(nu, e)
    return ContinuationOptions(step=StepOptions(ds=0.5, ds_max=2.0), bounds={"H": (0.8 * hc, 1.2 * hc)}, max_steps=200)


def fold_options(nu: float, e: float) -> ContinuationOptions:
    """The traces of :func:`banded_fold`: H in (0.6, 1.05) H_1^c, the banded branch stopped at
    its first fold (AUTO's STOP LP1: the key point is the fold, and the branch beyond it --
    back up to 1.05 H_1^c, where the adaptive tracer refines for the stiffening band -- is
    not needed; modelling only what the scene asks for).

    The subcritical branch bends steeply: H - H_c ~ -3500 a^2 in the theta = 1 norm (a the
    mode amplitude), so the first step off the BP needs ds ~ 1e-4.  Down-weighting H in the
    arclength (theta = 1e-4) makes ds = 0.01 work and halves the number of steps."""
    hc = exact_hc1(nu, e)
    return ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.5, theta=1e-4),
                               bounds={"H": (0.6 * hc, 1.05 * hc)}, max_steps=300,
                               stop_at=("LP1",))


def first_bp(problem: CouetteProblem, nu: float, e: float, options: ContinuationOptions | None = None) -> tuple[Branch, Any]:
    """Uniform shear in H from 0.8 H_1^c to 1.2 H_1^c and its first BP (None if none found)."""
    hc = exact_hc1(nu, e)
    p = build_params({"nu": nu, "e": e, "H": 0.8 * hc})
    opts = options or first_bp_options(nu, e)
    br = trace(problem, problem.uniform_state(p), p, "H", opts)
    bps = [s for s in br.special_points if s.type == "BP"]
    return br, (bps[0] if bps else None)


def banded_fold(problem: CouetteProblem, nu: float, e: float,
                options: ContinuationOptions | None = None) -> tuple[list[Branch], Any]:
    """The n = 1 banded branch from H_1^c(nu) downwards and its first LP (None if none)."""
    opts = options or fold_options(nu, e)
    base, bp = first_bp(problem, nu, e, opts)
    if bp is None:
        return [base], None
    new = switch(problem, base, bp, opts, directions=(+1,))
    for b in new:
        lps = [s for s in b.special_points if s.type == "LP"]
        if lps:
            return [base, b], lps[0]
    return [base, *new], None


def run(request: SceneRequest) -> SceneResult:
    values = scene_numbers(request, DEFAULTS, "gpcf-keypoints")
    try:
        problem = CouetteProblem(request.method or "cheb", request.grid or 32, engine=request.engine or "numpy")
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    base, bp = first_bp(problem, values["nu_super"], values["e"],
                        request.options_for(first_bp_options(values["nu_super"], values["e"])))
    branches, lp = banded_fold(problem, values["nu_sub"], values["e"],
                               request.options_for(fold_options(values["nu_sub"], values["e"])))
    keys: dict[str, float] = {}
    if bp is not None and bp.converged:
        keys["Hc1"] = bp.params["H"]
    if lp is not None and lp.converged:
        keys[f"LP_nu{values['nu_sub']:g}"] = lp.params["H"]
    base.id = "uniform_super"
    branches[0].id = "uniform_sub"
    done = [base, *branches]
    relabel(done)
    return SceneResult(branches=done, parameters=values,
                       discretization={"method": problem.method, "intervals": problem.N, "engine": problem.engine},
                       extra={"key_points": keys, "Hc1_exact": exact_hc1(values["nu_super"], values["e"]),
                              "exact": {"Hc1": exact_hc1(values["nu_super"], values["e"])}})


def problem_factory(parameters: Any, discretization: Any) -> CouetteProblem:
    """The problem of a gpcf-keypoints file (for ``contin continue`` from its fold, ``contin
    stability``, ``contin verify``): the pitchfork scenes' factory, whose defaults (no-slip walls,
    chi = jj, no Dufour term; numba only where it is installed) are this scene's; imported here so
    that loading this scene table does not load every gPCF scene."""
    from problems.couette.scenes import problem_factory as couette_factory

    return couette_factory(parameters, discretization)


FRSTAR_DEFAULTS: dict[str, Any] = {"nu": 0.3, "e": 0.8, "H_min": 1.0, "H_max": 30.0}
#: start grid of gpcf-frstar (fixed runs: the grid; adaptive runs: where the choice starts)
FRSTAR_GRID = 32


def run_frstar(request: SceneRequest) -> SceneResult:
    """Fr* = G_max^-1/2 along the first pitchfork's fold curve (module docstring)."""
    from contin.options import AdaptOptions
    from problems.couette.gravity import GravitySettings, extrema, gravity_free_branches, gravity_problem, pitchfork_fold_curves

    values = scene_numbers(request, FRSTAR_DEFAULTS, "gpcf-frstar")
    try:
        problem = gravity_problem(request.method or "cheb", request.grid or FRSTAR_GRID, engine=request.engine or "numpy")
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    p = problem.params({"nu": values["nu"], "e": values["e"], "G": 0.0})
    H_range = (values["H_min"], values["H_max"])
    base, kids = gravity_free_branches(problem, p, GravitySettings(H_range=H_range, modes=1))
    tol = request.overrides.get("tol")
    refine = None if tol is None else AdaptOptions(tol=float(tol), max_grid=int(request.overrides.get("max_grid") or 512))
    curves = pitchfork_fold_curves(problem, p, base, kids, H_range=H_range, refine=refine, choose_grid=refine is not None)
    first = [r for r in extrema(curves) if r["curve"] == "fold0" and r["extremum"] == "max"]
    keys = {"Fr*": min(r["Fr"] for r in first)} if first else {}
    base.id = "g0"
    done = [base, *kids, *curves]
    return SceneResult(branches=done, parameters=values,
                       discretization={"method": problem.method, "intervals": problem.N, "engine": problem.engine},
                       extra={"key_points": keys})


SCENES = {"gpcf-frstar": Scene("gpcf-frstar", "gPCF key point Fr*: the floating-plug limit on the first pitchfork's fold curve",
                               FRSTAR_DEFAULTS, run_frstar, x="H", y="G", adaptive=True),
          "gpcf-keypoints": Scene("gpcf-keypoints", "gPCF key points: H_1^c (nu=0.3) and the banded-branch fold at nu=0.16",
                                  DEFAULTS, run, x="H", y="phi", adaptive=True, problem_factory=problem_factory,
                                  special_key_points=True)}
