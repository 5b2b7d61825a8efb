"""Granular Couette flow with gravity: imperfect pitchforks, isolas and fold curves.

With G = Fr^-2 > 0 the wall-normal momentum balance reads d(f1 T)/dy = -H^3 G nu
(physics.md section 2); the reflection y -> -y maps G -> -G (F(Sx, -G) = S F(x, G)), so
gravity is an imperfection of every symmetry-breaking pitchfork of uniform shear (A13 slides
"Bifurcation with gravity"; Alam et al., J. Fluid Mech. 523, 2005).  Uniform shear is no longer a
solution; the branch from small H (near-uniform) bends continuously onto the bottom-plug state
(the 'surviving attractor'), while dense-top ('floating plug') states lie on separate,
fold-bounded branches or isolas.

Pieces:

- :func:`gravity_problem` -- a CouetteProblem with the gravity term;
- :func:`gravity_free_branches` -- uniform shear and both signs of the banded branches at the
  first ``modes`` pitchforks (G = 0), via :mod:`problems.couette.pitchfork`;
- :func:`low_density_banded` -- below the threshold density (no BP) the banded branch from the
  density continuation;
- :func:`homotopy_in_G` -- a state continued in G at fixed H from G = 0 to the target G;
- :func:`trace_in_H` -- a branch at fixed G traced both ways in H
  (:func:`contin.jumps.trace_both_ways`: closed loops closed, jumps between nearby sheets
  retraced with smaller steps, self-overlapping halves trimmed);
- :class:`GravityCoordinates` -- the scaled (H/10, Phi, nu_bottom, T_mid) space in which the
  generic bookkeeping of :mod:`contin.overlap` (:func:`lies_on`, :func:`deduplicate`,
  :func:`on_branch`, :func:`trim_to_new`, :func:`trim_self_overlap`) compares gPCF branches;
- :func:`homotopy_seeds`, :func:`fold_seeds`, :func:`off_fold` -- the two isola-discovery
  routes of :mod:`contin.seeds` with the gPCF physics: banded states continued in G
  (theta = 1/G^2), fold curves in (H, G) crossing G;
- :func:`resolved` -- the resolution check of states from the (unguarded) fold curves;
- :func:`classify` -- 'primary' / 'isola' / 'floating-plug' / 'bottom-plug';
- :func:`discover` -- all branches at one G: which seeds (the physics), traced and
  de-duplicated by :func:`contin.seeds.discover`, labelled;
- :func:`fold_curves`, :func:`pitchfork_fold_curves`, :func:`extrema` -- fold curves in (H, G)
  (or (H, nu)) from the folds of a diagram or from the imperfect pitchforks, with the Fr at which
  each closed component is born and dies (XT extrema of G);
- :func:`branch_point_normal_forms` -- Lyapunov-Schmidt coefficients at every BP of the
  gravity-free problem, with the gravity imperfection d/dG;
- :func:`unfolding_branches` -- short branches near a BP at several small G, for
  :func:`contin.fit.fit_unfolding`.

Continuation in G: G is ~1e-6 while the state changes by O(1) per unit H^3 G, so the
arclength weight of the parameter is theta = 1/G_target^2 (the homotopy is then O(1) long).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from contin.adapt import on_grid, retrace_finer
from contin.branch import Branch, SpecialPoint
from contin.continuation import newton, trace_both
from contin.foldcurve import SegmentRegrid, trace_fold_curve
from contin.jumps import jumped, trace_both_ways
from contin.jumps import trim_self_overlap as _trim_self_overlap
from contin.normalform import PitchforkNormalForm, pitchfork_normal_form
from contin.options import (
    AdaptOptions,
    ContinuationOptions,
    DetectionOptions,
    NewtonOptions,
    StepOptions,
)
from contin.overlap import deduplicate as _deduplicate
from contin.overlap import distance_to_polyline as _distance_to_polyline
from contin.overlap import lies_on as _lies_on
from contin.overlap import near, params_at
from contin.overlap import slice_branch as slice_branch  # re-exported for existing callers
from contin.overlap import trim_to_new as _trim_to_new
from contin.seeds import Seed, homotopy
from contin.seeds import discover as core_discover
from contin.seeds import fold_seeds as core_fold_seeds
from contin.seeds import homotopy_seeds as core_homotopy_seeds
from contin.seeds import off_fold as core_off_fold
from contin.seeds import resolved as _resolved
from problems.couette.model import CouetteProblem

log = logging.getLogger("contin")
Array = np.ndarray

#: H span a run must cover before coming back along itself counts as a jump (trim_self_overlap).
OVERLAP_EXCURSION = 5.0

#: Kinds of gravity branches (Branch.kind).
KINDS = ("primary", "isola", "floating-plug", "bottom-plug")


def gravity_problem(method: str = "cheb", N: int = 32, walls: str = "noslip", chi: str = "jj",
                    engine: str = "numpy") -> CouetteProblem:
    """CouetteProblem with the gravity term H^3 G M (needed for G != 0)."""
    return CouetteProblem(method, N, walls=walls, chi=chi, gravity=True, engine=engine)


@dataclass(frozen=True)
class GravitySettings:
    """Step control of the gravity runs.

    H_range : gap interval of the diagrams
    ds_max : largest arclength step in H; near-crossings of the imperfect pitchforks are
        only O(G^(1/3)) apart, so larger steps jump between branches
    seed_H : gaps at which gravity-free banded states are continued in G (route 1)
    modes : pitchforks of uniform shear (n = 1..modes) whose banded branches seed route 1
    Fr_start : Froude number at which route 2 first finds the fold of each imperfect pitchfork
        (:func:`pitchfork_fold_curves`)
    fold_steps : steps per direction of each fold curve (route 2)
    refine : AdaptOptions of the branches traced in H (:func:`trace_in_H`); None: the fixed
        grid, where the resolution guard ends a branch MX 'under-resolved'.  With it each branch
        refines its own grid where its estimate exceeds ``refine.tol`` (``contin.adapt``: the
        dense plugs near packing), and ends MX only past ``refine.max_grid``; the seeds, fold
        curves and homotopies stay on the problem's grid.
    """

    H_range: tuple[float, float] = (1.0, 50.0)
    ds: float = 0.1
    ds_max: float = 0.2
    max_angle: float = 0.1
    max_steps: int = 1500
    seed_H: tuple[float, ...] = (16.0, 22.0, 30.0, 38.0, 44.0, 52.0, 60.0, 70.0, 85.0)
    modes: int = 3
    Fr_start: float = 2000.0
    fold_steps: int = 300
    refine: AdaptOptions | None = None

    def h_options(self, adaptive: bool = False) -> ContinuationOptions:
        """Options of a trace in H; ``adaptive``: with ``refine`` as ContinuationOptions.adapt."""
        return ContinuationOptions(
            bounds={"H": self.H_range}, max_steps=self.max_steps,
            step=StepOptions(ds=self.ds, ds_max=self.ds_max, max_angle=self.max_angle),
            detection=DetectionOptions(detect_branch_points=False),
            adapt=self.refine if adaptive else None,
        )

    def g0_options(self) -> ContinuationOptions:
        return ContinuationOptions(bounds={"H": self.H_range}, max_steps=400,
                                   step=StepOptions(ds=0.3, ds_max=1.0, max_angle=0.2))


#: The smallest target gravity of a G-homotopy (:func:`g_options` weighs the arclength by 1/G^2, which
#: must be a finite number: `contin trace gravity -s Fr=1e154` ended 'ZeroDivisionError', qa19); with
#: params.G_MAX the Froude numbers 1e-50 <= Fr <= 1e50 of the gravity scene.
HOMOTOPY_G_MIN = 1e-100


def g_options(G: float, max_steps: int = 80) -> ContinuationOptions:
    """Options of a continuation in G from 0 to ``G`` (theta = 1/G^2, see the module docstring)."""
    if not G > 0:
        raise ValueError(f"target gravity G must be > 0, got {G}")
    return ContinuationOptions(
        bounds={"G": (0.0, G)}, max_steps=max_steps,
        step=StepOptions(ds=0.1, ds_max=0.25, ds_min=1e-8, theta=1.0 / G**2),
        detection=DetectionOptions(detect_branch_points=False),
    )


# ----------------------------------------------------------------------------- G = 0
def gravity_free_branches(problem: CouetteProblem, params: Mapping[str, float], settings: GravitySettings,
                          progress: Callable[[str], None] | None = None) -> tuple[Branch, list[Branch]]:
    """Uniform shear (G = 0) traced in H and both signs of the banded branches at its first
    ``settings.modes`` branch points, ids g0 and g0.<k>.1 / g0.<k>.2, by the core diagram builder
    (problems.couette.pitchfork.banded_diagram)."""
    from problems.couette.pitchfork import banded_diagram

    p = {**params, "G": 0.0, "H": settings.H_range[0]}
    opts = settings.g0_options()

    def finish(b: Branch, bp: Any, k: int) -> None:
        if bp is None:
            b.kind = "uniform shear" if problem.walls == "noslip" else "base"

    d = banded_diagram(problem, p, opts, opts, lambda base: list(enumerate(base.branch_points[: settings.modes], start=1)),
                       H_scale=settings.H_range[1], base_id="g0", finish=finish, progress=progress)
    base = d.branch("g0")
    kids: list[Branch] = [b for b in d.branches if b.id != "g0"]
    if not base.branch_points and settings.modes >= 1:
        kids = low_density_banded(problem, p, settings, progress)
    return base, kids


#: Density and gap of the continuation in nu that reaches the banded branch below the
#: threshold density (as in the pitchfork scene, problems.couette.scenes).
LOW_DENSITY_START = 0.2
LOW_DENSITY_GAP = 60.0


def low_density_banded(problem: CouetteProblem, params: Mapping[str, float], settings: GravitySettings,
                       progress: Callable[[str], None] | None = None) -> list[Branch]:
    """Below the threshold density uniform shear has no BP ("bifurcation from infinity",
    physics.md section 6 row 3): the banded branch (both signs, ids g0.1.1/g0.1.2) is reached by
    continuation in nu at H = 60 from nu = 0.2 (problems.couette.pitchfork.density_continuation)
    and traced in H; empty when the gap 60 is outside H_range or the continuation fails."""
    from problems.couette.pitchfork import density_continuation, mirror_branch

    lo, hi = settings.H_range
    if not lo < LOW_DENSITY_GAP < hi:
        return []
    opts = settings.g0_options()
    try:
        x, _ = density_continuation(problem, params, LOW_DENSITY_START, params["nu"], LOW_DENSITY_GAP, opts,
                                    progress=progress)
    except ValueError as exc:
        log.info("no banded branch at nu = %g: %s", params["nu"], exc)
        return []
    b1 = trace_both(problem, x, {**params, "H": LOW_DENSITY_GAP}, "H", opts, branch_id="g0.1.1",
                    kind="banded n=1", parent=f"density continuation from nu={LOW_DENSITY_START:g}")
    b2 = mirror_branch(problem, b1, params, "g0.1.2")
    return [b1, b2]


# ----------------------------------------------------------------------------- continuation
#: Largest step in H of :func:`trace_in_H` at and below which a jump is not repaired again.
RETRACE_DS_MAX = 0.06


def homotopy_in_G(problem: CouetteProblem, state: Array, params: Mapping[str, float], G: float,
                  max_steps: int = 80) -> Array | None:
    """The state continued in G at fixed H from params['G'] (usually 0) up to ``G``
    (:func:`contin.seeds.homotopy`); None when the path does not reach G (a fold in G: the
    state does not survive that much gravity)."""
    return homotopy(problem, state, params, "G", G, g_options(G, max_steps))


def trace_in_H(problem: CouetteProblem, state: Array, params: Mapping[str, float], settings: GravitySettings,
               *, branch_id: str = "0", kind: str = "", parent: str = "",
               progress: Callable[[str], None] | None = None) -> Branch:
    """Both directions in H at fixed G (:func:`contin.jumps.trace_both_ways`): a closed loop
    (isola) is returned once, closed; open halves are cut where they come back along
    themselves (:func:`trim_self_overlap`), and a run showing a jump between sheets is retraced
    once with half the largest step (smaller steps keep the run on its sheet at the O(G)-narrow
    mode-2 near-crossing), unless ds_max <= :data:`RETRACE_DS_MAX`."""
    return trace_both_ways(problem, state, params, "H", settings.h_options(adaptive=True), coordinates=COORDINATES,
                           excursion=OVERLAP_EXCURSION, restep="whole", min_ds_max=RETRACE_DS_MAX,
                           symmetric=False, branch_id=branch_id, kind=kind, parent=parent, progress=progress)


#: Signs of a jump between sheets (contin.jumps.jumped).
_jumped = jumped


def trim_self_overlap(branch: Branch, tol: float = 2e-3, skip: int = 20, run: int = 5,
                      excursion: float = OVERLAP_EXCURSION) -> Branch:
    """:func:`contin.jumps.trim_self_overlap` in the gPCF coordinates (:class:`GravityCoordinates`).

    Near the imperfect pitchforks, in particular the mode-2 one that gravity unfolds only at
    second order, the sheets are O(G) apart and a step can land on the neighbour; the run then
    goes round a loop and comes back along its own earlier part.  ``excursion`` (in H) spares
    folds: just past a fold the branch runs close to its part before the fold, but only after
    an excursion of the fold's width in H.
    """
    return _trim_self_overlap(branch, COORDINATES, tol=tol, skip=skip, run=run, excursion=excursion)


# ----------------------------------------------------------------------------- bookkeeping
def _coordinates(branch: Branch, H_scale: float = 10.0) -> Array:
    """Points of a branch in a scaled (H, Phi, nu_bottom, T_mid) space used for comparisons."""
    ob = branch.observables
    cols = [branch.params["H"] / H_scale, ob["phi"], ob["nu_bottom"]]
    if "T_mid" in ob:
        cols.append(ob["T_mid"] / max(1.0, float(np.max(np.abs(ob["T_mid"])))))
    return np.column_stack(cols)


class GravityCoordinates:
    """contin.overlap.Coordinates of gPCF branches: (H/10, Phi, nu_bottom, T_mid scaled) for
    branches, (H/10, Phi, nu_bottom) for single states (from the problem's observables)."""

    def branch(self, b: Branch) -> Array:
        return _coordinates(b)

    def point(self, problem: Any, u: Array, p: Mapping[str, float]) -> Array:
        obs = problem.observables(u, p)
        return np.array([p["H"] / 10.0, obs["phi"], obs["nu_bottom"]])


COORDINATES = GravityCoordinates()


def lies_on(a: Branch, b: Branch, tol: float = 5e-3, fraction: float = 0.9) -> bool:
    """True when at least ``fraction`` of the points of ``a`` lie within ``tol`` of ``b``'s
    polyline in the scaled (H/10, Phi, nu_bottom, T_mid) space: ``a`` is (part of) ``b``."""
    return _lies_on(a, b, COORDINATES, tol, fraction)


def on_branch(problem: CouetteProblem, x: Array, p: Mapping[str, float], branch: Branch, tol: float = 2e-3) -> bool:
    """True when the state (x, p) lies within ``tol`` of ``branch`` (scaled H, Phi, nu_bottom)."""
    return near(problem, x, p, branch, COORDINATES, tol)


def deduplicate(branches: Sequence[Branch], tol: float = 5e-3) -> tuple[list[Branch], list[tuple[str, str]]]:
    """One branch per solution set (:func:`contin.overlap.deduplicate` in the gPCF coordinates)."""
    return _deduplicate(branches, COORDINATES, tol)


def dense_side(problem: CouetteProblem, branch: Branch) -> str:
    """'top' when the dense layer is mostly at the top wall (Phi = nu(1/2) > nu(-1/2)) along
    the branch, else 'bottom'."""
    top = branch.observables["nu_top"] > branch.observables["nu_bottom"]
    return "top" if np.mean(top) > 0.5 else "bottom"


def classify(problem: CouetteProblem, branch: Branch, H_min: float) -> str:
    """'isola' (closed), 'primary' (reaches the small-H bound, where the state is near-uniform),
    else 'floating-plug' / 'bottom-plug' by where the dense layer is (Phi = nu(1/2) vs nu(-1/2))."""
    if len(branch) == 0:  # its start did not converge (qa14: np.min of no H raised a raw numpy error)
        return "not started"
    if branch.closed:
        return "isola"
    H = branch.params["H"]
    if np.min(H) <= H_min * (1 + 1e-9):
        return "primary"
    return "floating-plug" if dense_side(problem, branch) == "top" else "bottom-plug"


def trim_to_new(problem: CouetteProblem, branch: Branch, seed: Array, known: Sequence[Branch],
                tol: float = 2e-3) -> Branch:
    """:func:`contin.overlap.trim_to_new` on (H/10, Phi, nu_bottom): near the imperfect
    pitchforks two branches pass within O(G^(1/3)) of each other and a step may land on the
    neighbour; the part of the run around the seed that is off every known branch is kept."""
    return _trim_to_new(branch, seed, known, COORDINATES, tol, columns=3)


_params_at = params_at

#: Largest estimated relative discretization error of a seed or fold-curve extremum that is
#: used (the continuation default, contin.options.ContinuationOptions.resolution_tol).
RESOLUTION_TOL = 3e-5


def resolved(problem: CouetteProblem, x: Array, p: Mapping[str, float], tol: float = RESOLUTION_TOL) -> bool:
    """True when the grid resolves the state (CouetteProblem.under_resolved: Chebyshev tail
    against the distance to packing).  Fold-curve traces are guarded by the core now
    (FoldProblem forwards the hook, with the run's resolution_tol); this check stays for
    stored points such as extrema located with the guard off, at the default tolerance."""
    return _resolved(problem, np.asarray(x)[: problem.size], p, tol)


# ----------------------------------------------------------------------------- discovery
@dataclass
class GravityDiagram:
    """All branches at one G, with how each was found.

    branches : de-duplicated, labelled (kind) branches
    routes : branch id -> 'small-H', 'homotopy' or 'fold-curve' (the route that found it)
    duplicates : (dropped id, kept id) pairs (a branch found again by another route)
    seeds : every seed tried, with its outcome (for the notes)
    found_by : branch id -> every route with a seed on that branch (first the tracing one)
    curves : the fold curves of route 2
    """

    G: float
    branches: list[Branch]
    routes: dict[str, str] = field(default_factory=dict)
    duplicates: list[tuple[str, str]] = field(default_factory=list)
    seeds: list[str] = field(default_factory=list)
    gravity_free: list[Branch] = field(default_factory=list)
    found_by: dict[str, list[str]] = field(default_factory=dict)
    curves: list[Branch] = field(default_factory=list)

    def of_kind(self, kind: str) -> list[Branch]:
        return [b for b in self.branches if b.kind == kind]


def _homotopy_seeds(problem: CouetteProblem, g0_branches: Sequence[Branch], G: float,
                    seed_H: Sequence[float]) -> list[Seed]:
    return core_homotopy_seeds(problem, g0_branches, "G", G, seed_H, g_options(G))


def homotopy_seeds(problem: CouetteProblem, g0_branches: Sequence[Branch], G: float,
                   seed_H: Sequence[float]) -> list[tuple[str, Array, dict[str, float]]]:
    """Route 1: states of the gravity-free banded branches at ``seed_H`` continued in G
    (:func:`contin.seeds.homotopy_seeds`), as (label, state, params)."""
    return [(s.label, s.state, dict(s.params)) for s in _homotopy_seeds(problem, g0_branches, G, seed_H)]


def _fold_seeds(problem: CouetteProblem, curves: Sequence[Branch], G: float, H_range: tuple[float, float]) -> list[Seed]:
    return core_fold_seeds(problem, curves, "G", G, "H", H_range, resolution_tol=RESOLUTION_TOL)


def fold_seeds(problem: CouetteProblem, curves: Sequence[Branch], G: float,
               H_range: tuple[float, float]) -> list[tuple[str, Array, dict[str, float]]]:
    """Route 2: points where fold curves in (H, G) cross the target G, polished on the fold
    system at G fixed (:func:`contin.seeds.fold_seeds`; each is a fold of the diagram at G, hence
    a seed for every fold-bounded branch and isola), as (label, state, params).  Crossings the
    grid does not resolve (near packing) are skipped."""
    return [(s.label, s.state, dict(s.params)) for s in _fold_seeds(problem, curves, G, H_range)]


def off_fold(problem: CouetteProblem, x: Array, p: Mapping[str, float], settings: GravitySettings,
             steps: int = 4) -> tuple[Array, dict[str, float]]:
    """A point a few continuation steps in H away from the fold (x, p) (:func:`contin.seeds.off_fold`)."""
    s = core_off_fold(problem, Seed("fold", x, dict(p), "fold-curve"), "H", settings.h_options(), steps)
    return s.state, dict(s.params)


def discover(problem: CouetteProblem, params: Mapping[str, float], settings: GravitySettings = GravitySettings(), *,
             g0_branches: Sequence[Branch] | None = None, base: Branch | None = None,
             curves: Sequence[Branch] | None = None,
             routes: Sequence[str] = ("homotopy", "fold-curve"),
             progress: Callable[[str], None] | None = None) -> GravityDiagram:
    """Every branch at G = params['G'] > 0 reachable from the small-H state, from the
    gravity-free banded branches (route 'homotopy': homotopy in G) and from fold curves
    crossing G (route 'fold-curve').

    ``g0_branches`` / ``base``: the gravity-free banded branches and uniform shear
    (:func:`gravity_free_branches`; computed when needed and not given).  ``curves``: fold
    curves in (H, G) for route 2; None = the pitchfork fold curves
    (:func:`pitchfork_fold_curves`, started at ``settings.Fr_start``).

    The physics is which seeds: the near-uniform small-H state, the banded states at
    ``settings.seed_H`` continued in G, the fold-curve crossings of G (moved off the fold
    first).  The bookkeeping is :func:`contin.seeds.discover` (a seed lying on a traced branch
    is recorded in ``found_by``, not traced again; branches trimmed to their new part and
    de-duplicated); each branch is then labelled (:func:`classify`).
    """
    G = float(params["G"])
    if not G > 0:
        raise ValueError("discover needs G > 0 (at G = 0 use the pitchfork scene)")
    bad = set(routes) - {"homotopy", "fold-curve"}
    if bad:
        raise ValueError(f"unknown discovery route(s) {sorted(bad)}; use 'homotopy' and/or 'fold-curve'")
    p0 = {**params, "H": settings.H_range[0]}
    g0 = list(g0_branches) if g0_branches is not None else []
    state: dict[str, Any] = {"base": base, "g0": g0, "curves": curves}

    def seeds() -> Iterator[Seed]:
        yield Seed("small-H state", problem.initial_guess(p0), p0, "small-H")
        need_g0 = "homotopy" in routes or ("fold-curve" in routes and curves is None)
        if need_g0 and (g0_branches is None or (base is None and "fold-curve" in routes and curves is None)):
            state["base"], state["g0"] = gravity_free_branches(problem, params, settings, progress)
        if "homotopy" in routes:
            yield from _homotopy_seeds(problem, state["g0"], G, settings.seed_H)
        if "fold-curve" in routes:
            if state["curves"] is None:
                assert state["base"] is not None
                state["curves"] = pitchfork_fold_curves(problem, params, state["base"], state["g0"],
                                                        H_range=settings.H_range, Fr_start=settings.Fr_start,
                                                        max_steps=settings.fold_steps, progress=progress)
            yield from _fold_seeds(problem, state["curves"], G, settings.H_range)

    def prepare(s: Seed) -> Seed:
        return core_off_fold(problem, s, "H", settings.h_options()) if s.route == "fold-curve" else s

    def trace_seed(s: Seed, bid: str) -> Branch:
        return trace_in_H(problem, s.state, s.params, settings, branch_id=bid, parent=s.label)

    say = progress or (lambda m: None)
    found = core_discover(problem, seeds(), trace_seed, COORDINATES, prepare=prepare, columns=3,
                          progress=lambda m: say(f"gravity: {m}"))
    for b in found.branches:
        b.kind = classify(problem, b, settings.H_range[0])
    return GravityDiagram(G=G, branches=found.branches, routes=found.routes, duplicates=found.duplicates,
                          seeds=found.notes, gravity_free=state["g0"], found_by=found.found_by,
                          curves=list(state["curves"] or []))


# ----------------------------------------------------------------------------- fold curves
def fold_curves(problem: CouetteProblem, branches: Sequence[Branch], second: str = "G", *,
                bounds: Mapping[str, tuple[float, float]] | None = None, max_steps: int = 300,
                ds_max: float = 0.5, regrid: SegmentRegrid | None = None) -> list[Branch]:
    """Fold curves in (H, second) through the folds of ``branches``; a fold already lying on
    a traced curve (within 1e-3 in H/10 and Phi) is not traced again.  ``regrid``: a curve the
    resolution guard stops continues on a finer grid from where it stopped
    (:class:`contin.foldcurve.SegmentRegrid`)."""
    opts = ContinuationOptions(bounds=dict(bounds or {}), max_steps=max_steps,
                               step=StepOptions(ds=0.1, ds_max=ds_max, max_angle=0.2))
    curves: list[Branch] = []
    for b in branches:
        for lp in b.fold_points:
            if not lp.converged:
                continue
            pt = np.array([[lp.params["H"] / 10.0, lp.order_parameter]])
            if any(np.min(_distance_to_polyline(pt, np.column_stack([c.params["H"] / 10.0, c.observables["phi"]]))) < 1e-3
                   for c in curves):
                continue
            c = trace_fold_curve(problem, lp, second, opts, parameter="H", branch_id=f"fold{len(curves)}", regrid=regrid)
            c.parent = f"{lp.name}@{b.id}"
            curves.append(c)
    return curves


def extrema(curves: Sequence[Branch], second: str = "G", *, problem: CouetteProblem | None = None) -> list[dict[str, Any]]:
    """XT points (extrema of ``second``) of fold curves with second > 0: where isolas / fold
    pairs are born (local minimum of G) or die (local maximum of G).  With ``problem`` each
    row also says whether the grid resolves the state there ('resolved', :func:`resolved`)."""
    out = []
    for c in curves:
        g = c.params[second]
        for s in c.points("XT"):
            val = s.params[second]
            # G <= 1e-12 (Fr >= 1e6) is the G = 0 pitchfork itself up to rounding: a fold curve
            # passes through it by the symmetry G -> -G (seen as a false "death" at G ~ 1e-22)
            if not val > (1e-12 if second == "G" else 0.0):
                continue
            i = min(max(s.index, 1), len(g) - 2)
            around = g[max(i - 3, 0): i + 4]
            kind = "max" if val >= np.max(around) - 1e-15 else "min"
            row = {"curve": c.id, "H": s.params["H"], second: val, "phi": s.order_parameter,
                   "extremum": kind, "converged": s.converged}
            if second == "G":
                row["Fr"] = float(val ** -0.5)
                row["event"] = "death" if kind == "max" else "birth"
            if problem is not None:
                row["resolved"] = resolved(problem, s.state, s.params)
            out.append(row)
    return out


# ----------------------------------------------------------------------------- normal forms
def branch_point_normal_forms(problem: CouetteProblem, base: Branch, *, amplitude: float = 1e-2) -> list[tuple[SpecialPoint, PitchforkNormalForm]]:
    """Lyapunov-Schmidt coefficients (a3, a1, a0[G], a2[G]) at every BP of the gravity-free
    base branch (``problem`` must have gravity=True so that dF/dG exists at G = 0)."""
    out = []
    for bp in base.branch_points:
        if not bp.converged:
            continue
        nf = pitchfork_normal_form(problem, bp.state, {**bp.params, "G": 0.0}, "H", unfolding=("G",),
                                   amplitude=amplitude, tol=1e-11, polish=1)
        out.append((bp, nf))
    return out


def unfolding_branches(problem: CouetteProblem, bp: SpecialPoint, G_values: Sequence[float], window: float,
                       *, ds_max: float = 0.02) -> list[Branch]:
    """Branches near the BP at each small G: every solution component crossing H = H_c
    within |H - H_c| <= window.

    At H = H_c the imperfect pitchfork has one or three solutions near Phi_c; they are found
    by homotopy in G from the BP state displaced by +- a small amount along the branch
    the BP state (the component through the near-uniform state) and from the mirror image of
    that component's state at H_c + window (the other, fold-bounded component), each traced
    in H inside the window.
    """
    Hc = bp.params["H"]
    settings = GravitySettings(H_range=(Hc - window, Hc + window), ds=0.005, ds_max=ds_max, max_angle=0.2,
                               max_steps=2000)
    out: list[Branch] = []
    for G in G_values:
        # start at the window's low end: the BP itself is singular (G ~ delta^3 there)
        p = {**bp.params, "G": 0.0, "H": Hc - window}
        x0 = newton(problem, problem.initial_guess(p), p, NewtonOptions(max_iterations=20)).u
        x = homotopy_in_G(problem, x0, p, G)
        if x is None:
            raise ValueError(f"homotopy in G from the BP at H = {Hc:.6g} failed for G = {G:g}")
        found: list[Branch] = []
        b = trace_in_H(problem, x, {**p, "G": G}, settings, branch_id=f"G{G:g}.{len(found)}")
        found.append(b)
        # the other component (fold-bounded, dense on the other side) lies near the mirror
        # image of the first one's end state (the mirror solves the -G problem; G is small)
        i = int(np.argmax(b.params["H"]))
        q = _params_at(b, i)
        res = newton(problem, problem.symmetry(b.state(i)), q, NewtonOptions(max_iterations=20))
        if res.converged and not on_branch(problem, res.u, q, b):
            found.append(trace_in_H(problem, res.u, q, settings, branch_id=f"G{G:g}.1"))
        out += found
    return out


# ----------------------------------------------------------------------------- phase diagram
@dataclass
class PhaseDiagram:
    """Fold curves in (H, G) from the symmetry-breaking pitchforks of uniform shear.

    curves : fold-curve branches (params 'H', 'G')
    extrema : :func:`extrema` rows (birth / death of fold pairs and isolas, with Fr)
    fr_min_floating_plug : the smallest Fr at which a floating-plug (dense-top) state exists:
        the largest G on the fold curve of the first pitchfork (its two folds merge there)
    unresolved : extrema at states the grid does not resolve (near packing), not trusted
    """

    curves: list[Branch]
    extrema: list[dict[str, Any]]
    fr_min_floating_plug: float
    critical_gaps: list[float]
    unresolved: list[dict[str, Any]] = field(default_factory=list)


def pitchfork_fold_curves(problem: CouetteProblem, params: Mapping[str, float], base: Branch, kids: Sequence[Branch],
                          *, H_range: tuple[float, float] = (1.0, 50.0), Fr_start: float = 2000.0,
                          max_steps: int = 300, progress: Callable[[str], None] | None = None,
                          refine: AdaptOptions | None = None, choose_grid: bool = False,
                          done: Mapping[str, Branch] | None = None,
                          on_curve: Callable[[Branch], None] | None = None) -> list[Branch]:
    """Fold curves in (H, G) through the imperfect symmetry-breaking pitchforks of ``base``
    (gravity-free uniform shear with its banded branches ``kids``, :func:`gravity_free_branches`).

    For each symmetry-breaking BP: the dense-top banded state at H_c + 3 (G = 0) is continued
    in G to Fr_start^-2, traced in H down to its fold, and the fold is continued in (H, G)
    both ways (through G = 0 at the BP into the mirror half G < 0, the reflected curve).
    Curve ids are 'fold<k>' (k-th symmetry-breaking BP), parents 'BP at H=...'.  When the
    imperfect pitchfork has no fold within 2 of H_c (subcritical: the banded branch turns back
    already at G = 0), the G = 0 fold of the banded branch is continued instead.  Without a BP
    (below the threshold density) the folds of the first gravity-free banded branch are
    continued in (H, G) instead.

    ``refine`` (AdaptOptions; None: the fixed grid, a fold curve the resolution guard stops ends
    MX): a pitchfork's fold curve that stops under-resolved is retraced on finer grids, up to
    ``refine.max_grid`` (:func:`contin.adapt.retrace_finer`); such a curve's ``grid`` column
    holds the grid it was traced on and its audit names the grids tried.

    ``choose_grid`` (with ``refine``; asking for an accuracy instead of a grid): each fold curve
    starts on the grid :func:`contin.adapt.start_grid` picks for its seed (the dense-top banded
    state at H_c + 3, G = 0: refined while its estimate exceeds ``refine.tol``, coarsened where it
    is far below), and its traces run with the resolution guard at ``refine.tol``
    (:func:`contin.options.resolution_override`), so a curve the chosen grid does not carry to
    ``refine.tol`` continues on a finer grid from where the guard stopped it
    (:class:`contin.foldcurve.SegmentRegrid`: the part before the stop keeps its grid, each
    direction from the seed refines on its own; the curve's ``grid`` column holds each point's
    grid and its audit the grid changes).

    ``done`` (by curve id, e.g. ``contin trace --resume``'s finished branches): a pitchfork whose
    curve 'fold<k>' is there is not traced again; ``on_curve`` is called with each curve as it is
    finished (the CLI stores it at once: a run stopped or killed later keeps it).
    """
    say = progress or (lambda m: None)
    bps = [bp for bp in base.branch_points if "symmetry-breaking" in bp.note and H_range[0] < bp.params["H"] < H_range[1]]
    curves: list[Branch] = []
    done = done or {}
    for k, bp in enumerate(bps):
        if f"fold{k}" in done:  # finished in an earlier run (--resume): reused, as every scene does
            curves.append(done[f"fold{k}"])
            continue
        # each pitchfork's fold curve on the grid that resolves it (the dense plugs at large H
        # need more points than the gravity-free branches it starts from): retraced on finer
        # grids while the resolution guard stops it (contin.adapt.retrace_finer)
        def compute(pb: CouetteProblem, k: int = k, bp: SpecialPoint = bp,
                    regrid: SegmentRegrid | None = None) -> list[Branch]:
            return _bp_fold_curves(pb, problem, params, base, kids, k, bp, H_range, Fr_start, max_steps, say, regrid)

        if refine is None:
            found, sizes = compute(problem), [int(problem.grid_size)]
        elif choose_grid:
            found, sizes = _fold_curves_at_tol(problem, params, kids, base, bp, compute, refine)
        else:
            _, found, sizes = retrace_finer(problem, compute, refine, suggest=_suggest_for_curves)
        for c in found:
            if c.grid is not None:  # regridded segment-wise (choose_grid): each point keeps its grid
                if len(sizes) > 1:
                    c.audit.append(f"fold curve retraced from grid {sizes[-1]} (grids tried {', '.join(map(str, sizes))})")
                continue
            c.grid = np.full(len(c), sizes[-1], dtype=np.int64) if sizes[-1] != int(problem.grid_size) else None
            if len(sizes) > 1:
                c.audit.append(f"fold curve retraced on grids {', '.join(map(str, sizes))}: under-resolved on the "
                               f"coarser ones")
        curves += found
        for c in found:
            if on_curve is not None:
                on_curve(c)
    if not bps and kids:
        # below the threshold density: the folds of the gravity-free banded branch (no BP)
        for c in fold_curves(problem, kids[:1], bounds={"H": H_range}, max_steps=max_steps):
            c.parent = f"fold of {kids[0].id} at G=0 ({c.parent})"
            curves.append(c)
    return curves


def _dense_top(params: Mapping[str, float], base: Branch, kids: Sequence[Branch], bp: SpecialPoint) -> tuple[Branch, int] | None:
    """The dense-top banded branch of pitchfork ``bp`` and its row nearest H_c + 3 (the seed of
    the pitchfork's fold curve), or None."""
    mode = base.branch_points.index(bp) + 1
    tops = [b for b in kids if b.id.startswith(f"g0.{mode}.") and b.observables["phi"][-1] > params["nu"]]
    if not tops:
        return None
    return tops[0], int(np.argmin(np.abs(tops[0].params["H"] - (bp.params["H"] + 3.0))))


def _fold_curves_at_tol(problem: CouetteProblem, params: Mapping[str, float], kids: Sequence[Branch], base: Branch,
                        bp: SpecialPoint, compute: Callable[[CouetteProblem], list[Branch]],
                        refine: AdaptOptions) -> tuple[list[Branch], list[int]]:
    """:func:`pitchfork_fold_curves` with ``choose_grid``: the start grid from the seed state; a
    curve the guard at ``refine.tol`` stops continues on a finer grid from its last accepted point
    (segment-wise, each direction on its own); retraced whole on finer grids only if a curve still
    stops below ``refine.max_grid``.  Returns the curves and the start grids tried."""
    from contin.adapt import finer, start_grid, under_resolved_stop
    from contin.options import resolution_override

    start = problem
    seed = _dense_top(params, base, kids, bp)
    if seed is not None:
        top, i = seed
        start, _, _ = start_grid(problem, np.asarray(top.state(i), float), _params_at(top, i), refine, NewtonOptions())
    # A curve the guard stops continues on a finer grid from its stop (segment-wise regridding,
    # contin.foldcurve.SegmentRegrid: the grid contin.adapt.finer picks there, i.e. the larger of
    # growth x N and the problem's suggest_grid): the part before the stop keeps the seed's grid.
    regrid = SegmentRegrid(refine)
    with resolution_override(refine.tol):
        found, sizes = compute(start, regrid=regrid), [int(start.grid_size)]
        # still stopped below max_grid (a carried point did not converge on the finer grid):
        # retraced whole on finer grids, as before segment-wise regridding
        if any(under_resolved_stop(c) and (c.grid is None or int(np.max(c.grid)) < refine.max_grid) for c in found):
            n_new = finer(start, None, None, refine)
            if n_new is not None:
                _, found, more = retrace_finer(start.with_grid(n_new), lambda pb: compute(pb, regrid=regrid), refine,
                                               suggest=lambda pb, stopped: suggest_grid_for(pb, stopped, tol=refine.tol))
                sizes += more
    return found, sizes


def suggest_grid_for(problem: CouetteProblem, stopped: Sequence[Branch], factor: float = 2.0,
                     tol: float = RESOLUTION_TOL) -> int:
    """Grid for branches (or fold curves: their states start with the problem's state) that
    stopped under-resolved: ``factor`` times what the resolution estimate asks for at their two
    ends (the plug keeps densifying past the stop, up to H_max, so the grid that just meets tol
    at the stop would stop again further on: cheb 48 at fold0's stop at nu = 0.3, 72 stops
    again, 96 reaches H = 70).  For :func:`contin.adapt.retrace_finer`."""
    n, want = problem.size, int(problem.grid_size)
    for c in stopped:
        for j in (0, len(c) - 1):
            p = {k: float(v[j]) for k, v in c.params.items()}
            asked = problem.suggest_grid(np.asarray(c.states[j][:n], float), p, tol)
            want = max(want, int(math.ceil(factor * asked)))
    return want


_suggest_for_curves = suggest_grid_for


def _on(problem: CouetteProblem, source: CouetteProblem, branch: Branch) -> Branch:
    """``branch`` with its fold points carried from ``source``'s grid onto ``problem``'s."""
    if problem is source:
        return branch
    moved = [replace(s, state=source.transfer(np.asarray(s.state, float), problem)) for s in branch.fold_points]
    return replace(branch, special_points=moved)


def _bp_fold_curves(problem: CouetteProblem, source: CouetteProblem, params: Mapping[str, float], base: Branch,
                    kids: Sequence[Branch], k: int, bp: SpecialPoint, H_range: tuple[float, float], Fr_start: float,
                    max_steps: int, say: Callable[[str], None], regrid: SegmentRegrid | None = None) -> list[Branch]:
    """The fold curve(s) of the k-th symmetry-breaking pitchfork ``bp`` on ``problem``'s grid
    (``base`` and ``kids`` were traced on ``source``'s; their states are carried over); with
    ``regrid`` a curve continues on finer grids where the resolution guard stops it."""
    G0 = Fr_start ** -2.0
    Hc = bp.params["H"]
    # dense-top half of the banded branch of this BP (ids g0.<mode>.1/2, both signs)
    seed = _dense_top(params, base, kids, bp)
    if seed is None:
        return []
    top, i = seed
    p = _params_at(top, i)
    u = top.state(i) if problem is source else source.transfer(np.asarray(top.state(i), float), problem)
    x = homotopy_in_G(problem, u, p, G0)
    lps = []
    if x is not None:
        local = GravitySettings(H_range=(max(H_range[0], Hc - 2.0), min(H_range[1], Hc + 4.0)), max_steps=400)
        b = trace_in_H(problem, x, {**p, "G": G0}, local, branch_id=f"seed{k}")
        lps = [lp for lp in b.fold_points if lp.converged and abs(lp.params["H"] - Hc) < 2.0]
    out = []
    if not lps:
        # subcritical pitchfork: its fold is on the banded branch already at G = 0
        for c in fold_curves(problem, [_on(problem, source, top)], bounds={"H": H_range}, max_steps=max_steps,
                             regrid=regrid):
            c.id = f"fold{k}"
            c.parent = f"fold of {top.id} at G=0 (BP at H={Hc:.6g})"
            out.append(c)
        return out
    say(f"gravity: fold curve from the pitchfork at H = {Hc:.6g} (cheb {problem.grid_size})")
    c = fold_curves(problem, [replace(b, special_points=lps[:1])], bounds={"H": H_range}, max_steps=max_steps,
                    regrid=regrid)[0]
    c.id = f"fold{k}"
    c.parent = f"BP at H={Hc:.6g}"
    return [c]


def phase_diagram(problem: CouetteProblem, params: Mapping[str, float], *, H_range: tuple[float, float] = (1.0, 50.0),
                  Fr_start: float = 2000.0, max_steps: int = 300,
                  progress: Callable[[str], None] | None = None, refine: AdaptOptions | None = None,
                  done: Mapping[str, Branch] | None = None,
                  on_curve: Callable[[Branch], None] | None = None) -> PhaseDiagram:
    """Fold curves in (H, G) through the imperfect pitchforks (symmetry-breaking BPs of uniform
    shear inside ``H_range``, :func:`pitchfork_fold_curves`) and their G-extrema.

    Extrema whose state the grid does not resolve (:func:`resolved`; e.g. the N = 32 pairs at
    H ~ 40.5-40.9, Fr = 926/1036 and 565/570, Phi = 0.62-0.63, that are absent at N = 48 and
    64) are left out of ``extrema`` and listed in ``unresolved``.  ``done`` and ``on_curve``: as for
    :func:`pitchfork_fold_curves`.
    """
    settings = GravitySettings(H_range=H_range, modes=3)
    base, kids = gravity_free_branches(problem, {**params, "G": 0.0}, settings, progress)
    curves = pitchfork_fold_curves(problem, params, base, kids, H_range=H_range, Fr_start=Fr_start,
                                   max_steps=max_steps, progress=progress, refine=refine, done=done,
                                   on_curve=on_curve)
    # each curve's extrema checked on the grid it was traced on (pitchfork_fold_curves)
    ext = [r for c in curves for r in extrema([c], problem=problem if c.grid is None else on_grid(problem, c.grid_at(0)))]
    ok = [r for r in ext if r["resolved"]]
    bad = [r for r in ext if not r["resolved"]]
    first = [r for r in ok if r["curve"] == "fold0" and r["extremum"] == "max"]
    fr_min = min((r["Fr"] for r in first), default=float("nan"))
    bps = [bp for bp in base.branch_points if "symmetry-breaking" in bp.note and H_range[0] < bp.params["H"] < H_range[1]]
    return PhaseDiagram(curves=curves, extrema=ok, fr_min_floating_plug=fr_min,
                        critical_gaps=[bp.params["H"] for bp in bps], unresolved=bad)
