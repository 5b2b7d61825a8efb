"""The ``gravity`` scene: every branch of granular Couette flow at one Froude number.

``contin trace gravity -s nu=0.3 -s e=0.8 -s Fr=1000 --json``: the primary branch from the
near-uniform small-H state, plus every branch seeded from the gravity-free banded branches of
the first ``modes`` pitchforks by homotopy in G (route 1) and from the crossings of the
pitchforks' fold curves in (H, G) with G = Fr^-2 (route 2; problems.couette.gravity.discover),
de-duplicated and labelled (primary, isola, floating-plug, bottom-plug), with the stability pass
(k_x = 0) on every branch.  The notes and ``extra['found_by']`` say which routes found each
branch.

Defaults: Chebyshev N = 64 and H <= 70.  At N = 32 the dense plugs (nu -> nu_m = 0.65) are
under-resolved already at H ~ 30-40, and at nu = 0.3, Fr = 1000 the isola of the third
pitchfork spans H = 41.90 .. 63.48.  Without ``--grid`` each branch traced in H refines its own
grid where the resolution estimate (Chebyshev tail against the distance to packing,
problems.couette.resolution) exceeds the guard's tol 3e-5 (``GravitySettings.refine``,
``contin.adapt``: the state and tangent carried onto the finer grid, the branch continued), up
to ``-s max_grid=M`` (default :data:`GRAVITY_MAX_GRID`); past it the branch ends MX "under-resolved
... on the maximum grid M", and where double-precision rounding of the plug's distance to packing
exceeds tol it ends EP "precision limit".  The other branches, the seeds, homotopies and fold
curves stay on cheb 64, so a diagram that cheb 64 resolves is unchanged.  ``-s max_grid=0`` or
``--grid N``: one fixed grid, where the guard ends an under-resolved branch MX.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from contin.branch import relabel
from contin.options import AdaptOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult, require_started, scene_params
from problems.couette.gravity import HOMOTOPY_G_MIN, RESOLUTION_TOL, GravitySettings, discover, gravity_problem
from problems.couette.model import rebuilt_engine
from problems.couette.params import FR_MIN, G_MAX, H_RANGE
from problems.couette.pitchfork import state_on

GRAVITY_DEFAULTS: dict[str, Any] = {"nu": 0.3, "e": 0.8, "Fr": 1000.0, "H_min": 1.0, "H_max": 70.0,
                                    "walls": "noslip", "modes": 3, "max_grid": 256}

#: Default Chebyshev grid of the scene (see the module docstring).
GRAVITY_GRID = 64

#: Default largest grid a branch may refine to (``-s max_grid``; see the module docstring).
GRAVITY_MAX_GRID = 256


def _settings(request: SceneRequest) -> dict[str, Any]:
    out = scene_params(request, GRAVITY_DEFAULTS, "gravity")
    for name in ("nu", "e", "Fr", "H_min", "H_max", "modes", "max_grid"):
        try:
            out[name] = float(out[name])
        except (TypeError, ValueError):
            raise SceneError(f"parameter {name} of scene 'gravity' must be a number, got {out[name]!r}") from None
    if not (out["Fr"] > 0 and not math.isinf(out["Fr"])):
        raise SceneError(f"scene 'gravity' needs a finite Froude number Fr > 0, got {out['Fr']:g} (Fr = inf is the pitchfork scene)")
    fr_max = HOMOTOPY_G_MIN ** -0.5
    if not FR_MIN <= out["Fr"] <= fr_max:  # (qa19: Fr=1e-150 and 1e300 ended 'arithmetic failure (OverflowError)')
        raise SceneError(f"parameter Fr = {out['Fr']:g} is out of range; scene 'gravity' needs {FR_MIN:g} <= Fr <= "
                         f"{fr_max:g} (G = Fr^-2 within {HOMOTOPY_G_MIN:g}..{G_MAX:g}: its homotopy in G weighs the "
                         f"arclength by 1/G^2; Fr = inf is the pitchfork scene)")
    if not 0 < out["H_min"] < out["H_max"]:
        raise SceneError(f"need 0 < H_min < H_max, got H_min={out['H_min']:g}, H_max={out['H_max']:g}")
    for name in ("H_min", "H_max"):  # the model's range (qa19)
        if not H_RANGE[0] <= out[name] <= H_RANGE[1]:
            raise SceneError(f"parameter {name} = {out[name]:g} is out of range; it must satisfy {H_RANGE[0]:g} <= "
                             f"{name} <= {H_RANGE[1]:g} (gap in particle diameters)")
    if not (out["modes"] >= 1 and out["modes"] == int(out["modes"])):
        raise SceneError(f"modes must be a positive integer, got {out['modes']:g}")
    if not (out["max_grid"] >= 0 and out["max_grid"] == int(out["max_grid"])):
        raise SceneError(f"max_grid must be a non-negative integer (0: a fixed grid), got {out['max_grid']:g}")
    if out["walls"] not in ("noslip", "jj"):
        raise SceneError(f"walls must be 'noslip' or 'jj', got {out['walls']!r}")
    return out


def problem_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> Any:
    return gravity_problem(discretization.get("method", "cheb"), int(discretization.get("intervals", GRAVITY_GRID)),
                           str(parameters.get("walls", "noslip")), engine=rebuilt_engine(discretization.get("engine")))


def _refine(request: SceneRequest, s: Mapping[str, Any], pb: Any) -> AdaptOptions | None:
    """The branches' grid refinement (module docstring): None with ``--grid``, ``max_grid=0``
    or the resolution guard switched off (``--resolution-tol off``)."""
    tol = request.overrides.get("resolution_tol", RESOLUTION_TOL)
    if request.grid or not s["max_grid"] or tol is None:
        return None
    if s["max_grid"] < pb.N:
        raise SceneError(f"max_grid must be 0 (a fixed grid) or at least the start grid {pb.N}, got {s['max_grid']:g}")
    # Refinement only (no coarsening, special points to the same tol as states): a branch that
    # cheb 64 resolves is traced exactly as on the fixed grid.
    return AdaptOptions(tol=float(tol), max_grid=int(s["max_grid"]), coarsen_below=None, special_tol=float(tol))


def _first_refined(b: Any, n: int) -> float:
    """H at the first point of ``b`` on a grid finer than ``n``."""
    return float(b.params["H"][int(np.flatnonzero(np.asarray(b.grid) > n)[0])])


def run_gravity(request: SceneRequest) -> SceneResult:
    s = _settings(request)
    try:
        pb = gravity_problem(request.method or "cheb", request.grid or GRAVITY_GRID, s["walls"],
                             engine=request.engine or "numpy")
        params = pb.params({"nu": s["nu"], "e": s["e"], "Fr": s["Fr"], "H": s["H_min"]})
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    refine = _refine(request, s, pb)
    settings = GravitySettings(H_range=(s["H_min"], s["H_max"]), modes=int(s["modes"]), refine=refine)
    o = request.options_for(settings.h_options())
    settings = replace(settings, ds=o.step.ds, ds_max=o.step.ds_max, max_steps=o.max_steps)
    diagram = discover(pb, params, settings, progress=request.report)
    branches = diagram.branches
    if branches and not any(len(b) for b in branches):  # nothing computed: say why in one line (qa14:
        require_started(branches[0], "gravity")          # -s Fr=1e-3 was a raw numpy error, then an empty file)
    relabel(branches)
    if request.stability:
        for b in branches:  # the pass at k_x = 0, its audit, and the --kx columns with their Hopf points
            request.report(f"gravity: stability of branch {b.id}")
            request.run_stability(pb, b, params)
    for b in branches:
        request.finished(b)
    notes = [f"G = Fr^-2 = {params['G']:.6g}"]
    for b in branches:
        if b.grid is not None and int(np.max(b.grid)) > pb.N:
            notes.append(f"branch {b.id}: grid refined up to cheb {int(np.max(b.grid))} from H = "
                         f"{_first_refined(b, pb.N):.4g} (estimate above tol {refine.tol:g} on cheb {pb.N})")
    notes += [f"branch {b.id}: {b.kind}, traced from a {diagram.routes[b.id]} seed, found by "
              f"{' + '.join(diagram.found_by[b.id])}, {len(b.fold_points)} folds"
              + (", closed" if b.closed else "") for b in branches]
    notes += [f"branch {a} found again as {k} (dropped)" for a, k in diagram.duplicates]
    return SceneResult(
        branches=branches,
        parameters={**s, "G": params["G"]},
        discretization={"method": pb.grid.method, "intervals": pb.N, "engine": pb.engine},
        y=pb.grid.y,
        profiles=lambda state: pb.profiles(state_on(pb, state)),
        notes=notes,
        extra={"kinds": {b.id: b.kind for b in branches}, "routes": diagram.routes,
               "found_by": diagram.found_by, "duplicates": diagram.duplicates, "seeds": diagram.seeds},
    )


GRAVITY_SCENES = {
    "gravity": Scene(
        name="gravity",
        summary="Couette flow with gravity (Fr finite): primary, isolas, floating/bottom plugs in H",
        defaults=GRAVITY_DEFAULTS,
        run=run_gravity,
        x="H",
        y="phi",
        problem_factory=problem_factory,
    ),
}

#: alias for problems.couette.scenes (which registers ``SCENES`` of this module)
SCENES = GRAVITY_SCENES
