"""Scenes of granular plane Couette flow: ``contin trace pitchfork`` and ``contin trace jj-walls``.

``pitchfork`` (no-slip, adiabatic walls, no gravity; physics.md sections 3-4):
  uniform shear is traced in H from min(H_max/20, H_1^c/2) to H_max (default 3.3 H_1^c) with steps
  of at most 0.4 pi psi, its BPs H_n^c are detected and named by mode (compared with n pi psi in the
  notes and ``extra``; missing modes are named), and at the BPs of modes 1..``modes`` (default 3) both
  signs of the banded branch are followed to H_max (the second sign of a symmetry-breaking mode as
  the mirror image of the first).  Folds are marked.  Below the threshold density where psi stops
  being finite (e = 0.8: nu = 0.15614) uniform shear has no BP ("bifurcation from infinity"): the
  banded branch is then reached by continuing a banded state in nu at fixed H (parameter ``H``,
  default 60) from nu = 0.2 and traced in H both ways; a note says so.
``jj-walls``: the same with Johnson-Jackson walls (``phi_w``, ``ew``): uniform shear is not a
  solution; the symmetric base branch is traced in H from ``CouetteProblem.initial_guess`` (Newton
  first) with ds_max = 0.025 H_max (longer steps jump between the base branch and the isolated
  branch next to it; a trace that still jumps is repeated with ds_max halved), and every BP on it
  (up to ``modes``) is switched at; a switched branch that comes back onto the base branch is
  re-traced with smaller steps.  A symmetric branch not connected to the base branch (the slip
  guess at H_max converging off the base branch: JJ walls unfold the no-slip mode-2 pitchfork) is
  traced both ways as branch 's1'.  The notes say, per branch, its H range, Phi at both ends,
  folds, BPs, max |Phi - Phi_base(H)| and the k_x = 0 unstable counts (also ``extra['departure']``,
  ``extra['isolated']``).  Defaults (nu = 0.3, e = 0.8, phi_w = 0.5, ew = 0.9, cheb 64, H <= 43.13):
  one BP (symmetry-breaking, H = 18.15134523), the n = 1 branch both signs, s1 with a fold at
  H = 33.14946 (problems.couette.pitchfork docstring).

Both: the k_x = 0 stability pass on every branch (FD states on a Chebyshev grid, see
``problems.couette.pitchfork``), the audit (disagreements in the notes and ``branch.audit``),
banded-branch BPs re-checked on a 1.5x finer grid, extra wavenumbers (``--kx``) stored in
``extra['stability_kx'][branch_id][kx] = {'growth_rate': [...], 'n_unstable': [...]}`` (max Re
omega at k_z = 0 per point).  ``extra`` also holds ``H_c`` (detected, analytic, relative error),
``criticality`` per banded branch and ``folds``.

Both are built by the core diagram builder (``contin.diagram.bifurcation_diagram``, depth 2:
the base branch from its start upwards in H, the banded branches at the selected BPs; its
retraces with halved ds_max repair steps that jumped between branches); the scene keeps the
physics: which BPs (modes 1..``modes`` named against n pi psi, or the first ``modes`` with JJ
walls), the coordinates telling states apart (H and the two wall densities, swapped by the
reflection), the jump test of a switched branch (back on the base branch, by Newton), the
grid re-check of banded BPs.

Branch ids are deterministic (``--resume`` reuses finished branches): '0' base, 'n<k>.1' / 'n<k>.2'
the two signs of the branch from the k-th BP, 's1' the isolated symmetric JJ branch.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.branch import Branch, relabel
from contin.continuation import trace_both
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult
from problems.couette import pitchfork as pf
from problems.couette.closures import CHI_MODELS
from problems.couette.model import WALLS, CouetteProblem, rebuilt_engine
from problems.couette.params import H_RANGE, build_params

PITCHFORK_DEFAULTS: dict[str, Any] = {
    "nu": 0.3, "e": 0.8, "H": "auto", "H_max": "auto", "modes": 3, "walls": "noslip", "chi": "jj",
    "num": 0.65, "phi_w": 0.5, "ew": 0.9, "dufour": 0,
}
JJ_DEFAULTS: dict[str, Any] = {**PITCHFORK_DEFAULTS, "walls": "jj"}
#: ds_max of the JJ branches as a fraction of H_max: at nu = 0.3, e = 0.8 steps of ~4 in H jump
#: from the steep part of the base branch onto the isolated symmetric branch next to it, and from
#: the n = 1 branch back onto the base branch (the diagram builder's retraces halve ds_max when
#: that happens anyway).
JJ_BASE_DS_MAX = 0.025

#: ds_max of uniform shear as a fraction of H_1^c = pi psi, the spacing of its BPs (at most one BP per step).
BASE_STEPS_PER_MODE_GAP = 0.4

#: Density of the banded start state when uniform shear has no BP at the requested density.
LOW_DENSITY_START = 0.2
#: Default fixed gap of that density continuation.
LOW_DENSITY_GAP = 60.0
#: the smallest continuation step in H of the pitchfork / jj-walls scenes
SCENE_DS_MIN = 1e-7


def _settings(request: SceneRequest, defaults: Mapping[str, Any], scene: str) -> tuple[dict[str, float], dict[str, Any]]:
    """(model parameters, scene settings) from the request, each checked (SceneError: one sentence)."""
    values = dict(defaults)
    for name, value in request.params.items():
        if name in ("Fr", "G"):
            raise SceneError(f"scene {scene!r} is gravity-free; use a gravity scene to set {name}")
        if name not in defaults:
            raise SceneError(f"unknown parameter {name!r} for scene {scene!r}; its parameters are {', '.join(defaults)}")
        values[name] = value
    walls, chi = str(values["walls"]), str(values["chi"])
    if walls not in WALLS:
        raise SceneError(f"parameter walls = {walls!r} is not a wall model; choose one of {', '.join(WALLS)}")
    if chi not in CHI_MODELS:
        raise SceneError(f"parameter chi = {chi!r} is not a radial distribution; choose one of {', '.join(CHI_MODELS)}")
    try:
        p = build_params({k: values[k] for k in ("nu", "e", "num", "phi_w", "ew")}, chi=chi)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if p["e"] >= 1:
        raise SceneError("parameter e = 1 has no steady sheared state (no collisional dissipation); use e < 1")
    out: dict[str, Any] = {"walls": walls, "chi": chi}
    for name in ("H", "H_max"):
        v = values[name]
        if v == "auto" or v is None:
            out[name] = None
            continue
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise SceneError(f"parameter {name} must be a number or 'auto', got {values[name]!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise SceneError(f"parameter {name} = {v:g} is out of range; it must be a positive finite gap")
        if not H_RANGE[0] <= v <= H_RANGE[1]:  # (qa19: the model's range; -s H_max=1e300 ran on and on)
            raise SceneError(f"parameter {name} = {v:g} is out of range; it must satisfy {H_RANGE[0]:g} <= {name} <= "
                             f"{H_RANGE[1]:g} (gap in particle diameters)")
        out[name] = v
    try:
        modes = float(values["modes"])
    except (TypeError, ValueError):
        raise SceneError(f"parameter modes must be an integer 1..6, got {values['modes']!r}") from None
    if modes != int(modes) or not 1 <= modes <= 6:
        raise SceneError(f"parameter modes = {values['modes']!r} is out of range; it must be an integer 1..6")
    out["modes"] = int(modes)
    dufour = values["dufour"]
    if dufour not in (0, 1, 0.0, 1.0, "on", "off"):
        raise SceneError(f"parameter dufour = {dufour!r} must be 0 (off, the default) or 1 (the Dufour heat flux "
                         f"-kappa_h grad(nu) on)")
    out["dufour"] = dufour in (1, 1.0, "on")
    return p, out


def problem_factory(parameters: Mapping[str, Any], discretization: Mapping[str, Any]) -> CouetteProblem:
    """Rebuild the gravity-free problem of a stored run (``contin stability`` uses it)."""
    return CouetteProblem(str(discretization.get("method", "cheb")), int(discretization.get("intervals", 64)),
                          walls=str(parameters.get("walls", "noslip")), chi=str(parameters.get("chi", "jj")),
                          dufour=bool(parameters.get("dufour", False)),
                          engine=rebuilt_engine(discretization.get("engine")))


def _problem(request: SceneRequest, walls: str, chi: str, default_grid: int = 64, dufour: bool = False) -> CouetteProblem:
    try:
        return CouetteProblem(request.method or "cheb", request.grid or default_grid, walls=walls, chi=chi,
                              dufour=dufour, engine=request.engine or "numpy")
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def _options(request: SceneRequest, H_lo: float, H_hi: float, *, ds: float, ds_max: float) -> ContinuationOptions:
    """Step control for few points per branch: Newton needs ~4 iterations at tol 1e-10, so a
    target of 6 with growth 2 lets ds reach ds_max within ~10 steps off a BP."""
    if not min(abs(ds), ds_max) >= SCENE_DS_MIN:  # a range too narrow for the step control (qa15)
        raise SceneError(f"the range H = {H_lo:.6g}..{H_hi:.6g} is too narrow to trace: its steps "
                         f"(ds = {ds:.3g}, ds_max = {ds_max:.3g}) fall below the smallest step ds_min = "
                         f"{SCENE_DS_MIN:g}; widen it (a larger H_max)")
    return request.options_for(ContinuationOptions(
        bounds={"H": (H_lo, H_hi)}, max_steps=200,
        step=StepOptions(ds=ds, ds_max=ds_max, ds_min=SCENE_DS_MIN, newton_target=6, grow=2.0),
        detection=DetectionOptions(locate_tol=1e-9)))


class _Run:
    """Bookkeeping of one scene run: finished branches in order, resume, notes."""

    def __init__(self, request: SceneRequest, problem: CouetteProblem, params: dict[str, float]) -> None:
        self.request = request
        self.problem = problem
        self.params = params
        self.done: list[Branch] = []
        self.notes: list[str] = []
        self.not_started: list[str] = []
        self.kx_extra: dict[str, dict[str, Any]] = {}

    def cached(self, *ids: str) -> list[Branch] | None:
        if all(i in self.request.completed for i in ids):
            return [self.request.completed[i] for i in ids]
        return None

    def finish(self, branch: Branch, *, stability_from: Branch | None = None) -> Branch:
        """Stability (or a copy from the branch it mirrors), audit, extra k_x; then publish."""
        req, pb = self.request, self.problem
        # (a reused branch without stability: its run was stopped in the stability pass, qa17)
        fresh = branch.id not in req.completed or branch.n_unstable is None
        if req.stability and fresh:
            if stability_from is not None and stability_from.n_unstable is not None:
                branch.stable = stability_from.stable.copy()
                branch.n_unstable = stability_from.n_unstable.copy()
                branch.eigenvalues = stability_from.eigenvalues.copy()
                before = list(branch.audit)
                msgs = pf.audit_branch(branch)
                branch.audit = before + [f"stability audit: {m}" for m in msgs]
            else:
                req.report(f"stability of branch {branch.id} ({len(branch)} points)")
                msgs = pf.stability(pb, branch, self.params)
            self.notes += [f"stability audit, branch {branch.id}: {m}" for m in msgs]
        elif req.stability and branch.n_unstable is not None:
            self.notes += [f"stability audit, branch {branch.id}: {m[len('stability audit: '):]}"
                           for m in branch.audit if m.startswith("stability audit: ")]
        if req.stability:
            for kx in req.kx:
                if kx == 0:
                    continue
                src = stability_from if stability_from is not None else branch
                key = f"{kx:g}"
                cached = self.kx_extra.get(src.id, {}).get(key)
                data = cached if cached is not None else pf.growth_rates(pb, src, self.params, kx)
                if data is None:  # a stop request ended the pass: no column
                    continue
                self.kx_extra.setdefault(branch.id, {})[key] = data
                # Also as observable columns, as contin.stability.growth_columns gives every other
                # scene: `contin diagram -y growth_rate_kx0.5` (nan where the eigenproblem failed).
                counts = np.asarray(data["n_unstable"], dtype=float)
                branch.observables[f"growth_rate_kx{key}"] = np.asarray(data["growth_rate"], dtype=float)
                branch.observables[f"n_unstable_kx{key}"] = np.where(counts < 0, np.nan, counts)
        if branch.status == "MX" and not branch.message.startswith("mirror image"):
            self.notes.append(f"branch {branch.id} stopped (MX): {branch.message}")
        self.done.append(branch)
        relabel(self.done)
        req.finished(branch)
        return branch


def _h_max(settings: Mapping[str, Any], hc1: float) -> float:
    if settings["H_max"] is not None:
        return settings["H_max"]
    if not math.isfinite(hc1):
        return 3.3 * LOW_DENSITY_GAP
    return 3.3 * hc1


def run_pitchfork(request: SceneRequest, defaults: Mapping[str, Any] = PITCHFORK_DEFAULTS,
                  scene: str = "pitchfork") -> SceneResult:
    p, st = _settings(request, defaults, scene)
    pb = _problem(request, st["walls"], st["chi"], dufour=st["dufour"])
    nu, e = p["nu"], p["e"]
    modes = st["modes"]
    analytic = pf.analytic_critical_gaps(nu, e, modes, chi=st["chi"], num=p["num"], dufour=st["dufour"])
    hc1 = analytic[0]
    H_max = _h_max(st, hc1)
    # the base branch runs over H_max/20..H_max in steps of 0.05 H_max (JJ walls: 0.025 H_max), at
    # least ds_min: -s H_max=1e-6 ended "Error: need ds_max >= |ds| >= ds_min > 0, got ds_max=2e-07, ..."
    h_floor = SCENE_DS_MIN / (JJ_BASE_DS_MAX if st["walls"] == "jj" else 0.05)
    if H_max < h_floor:
        raise SceneError(f"parameter H_max = {H_max:g} is out of range: the base branch is traced over "
                         f"H = H_max/20..H_max in steps of at least ds_min = {SCENE_DS_MIN:g}, which needs "
                         f"H_max >= {h_floor:g} (H is the gap in particle diameters; the kinetic theory "
                         f"means H >> 1)")
    low_density = st["walls"] == "noslip" and not math.isfinite(hc1)
    H_fixed = st["H"] if st["H"] is not None else LOW_DENSITY_GAP
    if low_density and not H_fixed < H_max:
        raise SceneError(f"the density-continuation gap H = {H_fixed:g} must lie below H_max = {H_max:g}")
    H_lo = H_max / 20.0
    if st["walls"] == "noslip" and math.isfinite(hc1):
        # Uniform shear must start below H_1^c = pi psi, else the first BP found is a higher mode
        # (H_max = 1000 started at 50 > H_3^c and called H_21^c "BP1").
        H_lo = min(H_lo, 0.5 * hc1)
    H_start = st["H"] if (st["walls"] == "jj" and st["H"] is not None) else H_lo
    if not H_lo <= H_start <= H_max:
        raise SceneError(f"parameter H = {H_start:g} must lie between H_max/20 = {H_lo:g} and H_max = {H_max:g}")
    p["H"] = H_start
    run = _Run(request, pb, p)
    jj = st["walls"] == "jj"
    base_ds_max = (JJ_BASE_DS_MAX if jj else 0.2) * H_max
    if not jj and math.isfinite(hc1):
        # Consecutive H_n^c are pi psi apart: a step over two of them sees no sign change of the
        # BP test function and skips both (H_max = 200 skipped modes 4, 6, 7, ...).
        base_ds_max = min(base_ds_max, BASE_STEPS_PER_MODE_GAP * hc1)
    base_opts = _options(request, H_lo, H_max, ds=min(0.05 * H_max, base_ds_max), ds_max=base_ds_max)
    band_ds_max = (JJ_BASE_DS_MAX if jj else 0.1) * H_max
    # ds at most ds_max: -s H_max=1e-3 ended "Error: need ds_max >= |ds| >= ds_min > 0, got ds_max=0.0001, ds=0.02"
    band_opts = _options(request, H_lo, H_max, ds=min(0.02, band_ds_max), ds_max=band_ds_max)
    extra: dict[str, Any] = {"H_max": H_max, "walls": st["walls"], "modes": modes}

    # ---- the diagram: base branch and the banded branches at its BPs (contin.diagram builds it;
    # the scene chooses the BPs and names them by mode, and re-checks banded BPs on a finer grid)
    named = st["walls"] == "noslip" and math.isfinite(hc1)
    request.report(f"{scene}: tracing the base branch in H from {H_start:.4g} to {H_max:.4g}")
    d = _diagram(run, p, H_start, H_max, hc1, named, modes, base_opts, band_opts, jj)
    base = d.branch("0")
    if len(base) == 0:  # say the real cause in one line (it used to surface as "Error: phi")
        raise SceneError(f"{scene}: the base branch could not start: {base.message}"
                         + ("; phi_w = 0 (specular walls) transmits no shear, use phi_w > 0"
                            if jj and p["phi_w"] == 0 else ""))
    # a switch whose branch came back onto a known one (its parent: the switch did not leave it) is
    # a missing branch of the diagram as much as one that found no start point (fd2 --tol 1e-3
    # --special-tol 1e-3 traced n2.1/n2.2 back onto uniform shear and dropped them silently)
    # It is also a warning and exit 3, as a branch that could not start: a note alone let
    # `-s e=0.9999999 --grid 24` (numpy 2.4 / scipy 1.17: the switches at all three BPs came back
    # onto uniform shear) exit 0 with no banded branch at all.
    missing = [s_ for s_ in d.skipped
               if "switching found no" in s_ or "cannot switch" in s_ or ": lies on branch" in s_]
    run.notes += [f"switching at {s_}" for s_ in missing]
    run.not_started += [s_.replace(": lies on branch", ": its switched branch lies on branch", 1)
                        .replace(": probe lies on branch", ": its switched branch lies on branch", 1) for s_ in missing]
    bps = sorted(base.branch_points, key=lambda b: b.params["H"])
    bp_list = _selected(base, hc1, named, modes)
    if named:
        run.notes += pf.mode_notes(base, hc1, H_start, H_max)
    if st["walls"] == "noslip":
        detected = [b.params["H"] for b in bps]
        rows = []
        for n, hc in enumerate(analytic, start=1):
            near = min(detected, key=lambda h: abs(h - hc), default=math.nan) if math.isfinite(hc) else math.nan
            if not abs(near - hc) <= 0.02 * hc:  # e.g. H_n^c beyond H_max: not detected, not the nearest other BP
                near = math.nan
            rows.append({"n": n, "analytic": hc, "detected": near,
                         "rel_error": abs(near - hc) / hc if math.isfinite(near) else math.nan})
        extra["H_c"] = rows
    else:
        extra["H_c"] = [{"n": k, "detected": b.params["H"], "phi": b.order_parameter, "note": b.note,
                         "converged": b.converged} for k, b in enumerate(bps, start=1)]

    # ---- banded branches: criticality of both signs at each selected BP
    banded: list[Branch] = []
    crit: list[dict[str, Any]] = []
    for k, bp in bp_list:
        # a branch that could not start has no points (run.not_started names it; its departure and
        # criticality fits read observables it does not have: jj-walls -s nu=0.02 ended 'Error: phi')
        for b in (x for x in d.branches if x.id in (f"n{k}.1", f"n{k}.2") and len(x)):
            banded.append(b)
            crit.append({**pf.criticality(b, bp.params["H"], bp.order_parameter), "n": k})

    # ---- low density: no BP on uniform shear
    if low_density:
        threshold = pf.threshold_density(e, chi=st["chi"], num=p["num"])
        run.notes.append(f"uniform shear has no BP at nu = {nu:g}, e = {e:g}: psi is finite only above the threshold "
                         f"density nu = {threshold:.6f} (bifurcation from infinity); the banded branch was reached by "
                         f"continuation in nu at H = {H_fixed:g} from nu = {LOW_DENSITY_START:g}")
        extra["threshold_density"] = threshold
        ids = ("n1.1", "n1.2")
        pair = run.cached(*ids)
        if pair is None:
            request.report(f"{scene}: continuing a banded state in nu from {LOW_DENSITY_START:g} to {nu:g} at H = {H_fixed:g}")
            try:
                x, _aux = pf.density_continuation(pb, p, LOW_DENSITY_START, nu, H_fixed, band_opts,
                                                  progress=request.report)
            except ValueError as exc:
                raise SceneError(f"could not reach a banded state at nu = {nu:g}: {exc}") from None
            b1 = trace_both(pb, x, {**p, "H": H_fixed}, "H", band_opts, branch_id="n1.1", kind="banded n=1",
                            parent=f"density continuation from nu={LOW_DENSITY_START:g} at H={H_fixed:g}")
            b2 = pf.mirror_branch(pb, b1, p, "n1.2")
            b2.message = f"mirror image of branch {b1.id} (reflection y -> -y)"
            pair = [b1, b2]
        run.finish(pair[0])
        run.finish(pair[1], stability_from=pair[0])
        banded += pair
    elif st["walls"] == "noslip" and not named and len(bps) < min(modes, sum(h <= H_max for h in analytic)):
        run.notes.append(f"only {len(bps)} BPs found on uniform shear below H_max = {H_max:.6g}")
    if jj:
        _jj_walls(run, base, bps, banded, base_opts, extra, H_lo, H_max, modes)

    extra["criticality"] = crit
    extra["folds"] = pf.fold_table(run.done)
    if run.kx_extra:
        extra["stability_kx"] = run.kx_extra
    for row in crit:
        if row["n"] == 1 and row["branch"].endswith(".1") and bp_list and row["points"]:
            run.notes.append(f"pitchfork at H = {bp_list[0][1].params['H']:.10g} is {row['kind']} "
                             f"(H - H_c = a delta^2, a = {row['a']:.6g})")
    if st["walls"] == "noslip" and "H_c" in extra:
        for row in extra["H_c"]:
            if math.isfinite(row["detected"]):
                run.notes.append(f"H_{row['n']}^c = {row['detected']:.10g} (analytic n pi psi = {row['analytic']:.10g}, "
                                 f"relative error {row['rel_error']:.2g})")
    return SceneResult(
        branches=run.done,
        parameters={**{k: p[k] for k in ("nu", "e", "num")}, **({"phi_w": p["phi_w"], "ew": p["ew"]} if st["walls"] == "jj" else {}),
                    "H": H_fixed if low_density else H_start, "H_max": H_max, "modes": modes,
                    "walls": st["walls"], "chi": st["chi"], "dufour": int(st["dufour"])},
        discretization={"method": pb.method, "intervals": pb.N, "engine": pb.engine},
        y=pb.grid.y,
        # States of any grid (adaptive runs) are carried onto the start grid, whose y the file stores.
        profiles=lambda state: {k: v for k, v in pb.profiles(pf.state_on(pb, state)).items() if k in ("nu", "u", "T")},
        notes=run.notes,
        extra=extra,
        not_started=run.not_started,
    )


def _selected(base: Branch, hc1: float, named: bool, modes: int) -> list[tuple[int, Any]]:
    """(k, BP) of the base branch to switch at: with no-slip walls the BPs of modes 1..modes, named
    by mode (H_n^c = n pi psi), not by order -- a skipped or spurious BP must not shift the names of
    the others; otherwise the first ``modes`` BPs in H."""
    bps = sorted(base.branch_points, key=lambda b: b.params["H"])
    if named:
        by_mode = {pf.bp_mode(b.params["H"], hc1): b for b in reversed(bps)}
        return [(n, by_mode[n]) for n in range(1, modes + 1) if n in by_mode]
    return list(enumerate(bps[:modes], start=1))


def _diagram(run: _Run, p: dict[str, float], H_start: float, H_max: float, hc1: float, named: bool, modes: int,
             base_opts: ContinuationOptions, band_opts: ContinuationOptions, jj: bool) -> Any:
    """The base branch and both signs of the banded branch at each selected BP
    (:func:`pitchfork.banded_diagram`); the scene's part: which BPs (:func:`_selected`), the kinds,
    the grid re-check of banded BPs (:func:`pitchfork.confirm_branch_points`; the mirror image
    inherits the verdicts), notes, stability and checkpointing (``_Run.finish``)."""
    pb, request = run.problem, run.request

    def finish(b: Branch, bp: Any, k: int) -> None:
        if bp is None:
            b.kind = "base" if jj else "uniform shear"
            if named:
                pf.name_modes(b, hc1)
            return
        b.kind = f"bifurcated from BP at H={bp.params['H']:.6g}" if jj else f"banded n={k}"
        run.notes.extend(f"branch {b.id}: {m}" for m in b.audit if " re-traced with " in m)
        run.notes.extend(pf.confirm_branch_points(pb, b, p, band_opts))

    def on_branch(b: Branch, source: Branch | None) -> None:
        if len(b) == 0:  # nothing to store; the base branch's failure is one Error line (run_pitchfork)
            if b.id != "0":  # a banded branch: it was dropped silently and the run exited 0 (qa14)
                run.not_started.append(f"{b.id}: {b.message}")
                run.notes.append(f"branch {b.id} could not start: {b.message}")
            return
        run.finish(b, stability_from=source)
        if b.id == "0":
            run.notes.extend(m for m in b.audit if " re-traced with " in m)

    return pf.banded_diagram(pb, p, base_opts, band_opts, lambda base: _selected(base, hc1, named, modes),
                             H_scale=H_max, finish=finish, on_branch=on_branch, completed=request.completed,
                             progress=request.report)


def _describe(branch: Branch, dep: np.ndarray | None = None) -> str:
    """One sentence on what a branch does: H range, Phi at its ends, folds, BPs, k_x = 0 stability."""
    H, phi = branch.parameter_values, branch.observables["phi"]
    parts = [f"H {H.min():.6g}..{H.max():.6g}, Phi {phi[0]:.6g} -> {phi[-1]:.6g}"]
    lps = branch.fold_points
    if lps:
        parts.append("folds at H = " + ", ".join(f"{lp.params['H']:.8g} (Phi = {lp.order_parameter:.6g})" for lp in lps))
    if branch.branch_points:
        parts.append("BPs at H = " + ", ".join(f"{b.params['H']:.8g} ({b.note or 'BP'})" for b in branch.branch_points))
    uz = [s for s in branch.special_points if s.type == "UZ"]
    if uz:
        parts.append("demoted grid artefacts at H = " + ", ".join(f"{s.params['H']:.6g}" for s in uz))
    if dep is not None and np.any(np.isfinite(dep)):
        parts.append(f"|Phi - Phi_base| grows to {np.nanmax(dep):.4g}")
    if branch.n_unstable is not None:
        counts = sorted({int(c) for c in branch.n_unstable[1:] if c >= 0}) if "@" in branch.parent else \
            sorted({int(c) for c in branch.n_unstable if c >= 0})
        parts.append("k_x = 0 unstable modes: " + ", ".join(str(c) for c in counts))
    parts.append(f"ends: {branch.message}")
    return "; ".join(parts)


def _jj_walls(run: _Run, base: Branch, bps: list, banded: list[Branch], options: ContinuationOptions,
              extra: dict[str, Any], H_lo: float, H_max: float, modes: int) -> None:
    """JJ walls: the isolated symmetric branch (traced with the base branch's ``options``), departures
    from the base branch, and the notes."""
    pb, p, request = run.problem, run.params, run.request
    if not bps:
        run.notes.append(f"the JJ base branch has no BP for H in [{H_lo:.4g}, {H_max:.4g}]")
    for k, b in enumerate(bps, start=1):
        ids = [nb.id for nb in banded if nb.parent == f"{b.name}@{base.id}"]
        done = (f"switched: branches {', '.join(ids)}" if ids else
                f"not switched (modes = {modes})" if k > modes else "switching failed (see the notes)")
        run.notes.append(f"BP on the JJ base branch at H = {b.params['H']:.10g}, Phi = {b.order_parameter:.8g} "
                         f"({b.note or 'BP'}): {done}")
    if not any(b.note.startswith("symmetric") for b in bps) and len(base) >= 2:
        # (a base branch of one point has no slope: -s phi_w=1e-20 ended 'Error: attempt to get argmax of
        # an empty sequence', qa19)
        phi, H = base.observables["phi"], base.parameter_values
        slope = np.abs(np.diff(phi) / np.diff(H))
        k = int(np.argmax(slope))
        state = "dense walls" if phi[-1] > p["nu"] else "dense centre"
        run.notes.append(
            f"no symmetric BP on the JJ base branch: JJ walls break the hidden symmetry that keeps the no-slip mode-2 "
            f"pitchfork, so it unfolds; the base branch is steepest near H = {0.5 * (H[k] + H[k + 1]):.4g} "
            f"(|dPhi/dH| = {slope[k]:.3g}) and ends with {state} (Phi = {phi[-1]:.6g} at H = {H[-1]:.6g})")
    cached = run.cached("s1")
    if cached:
        iso, note = cached[0], "isolated symmetric branch s1 (resumed)"
    else:
        request.report("jj-walls: looking for a symmetric branch off the base branch")
        iso, note = pf.isolated_symmetric_branch(pb, base, p, options, progress=request.report)
        if iso is not None and len(iso) == 0:  # found, but its start point failed (under-resolved at nu = 0.02)
            run.not_started.append(f"{iso.id}: {iso.message}")
            note = f"{note.split(':')[0]} could not start: {iso.message}"
            iso = None
        if iso is not None:
            run.notes += pf.confirm_branch_points(pb, iso, p, options)
            run.notes += [m for m in iso.audit if " re-traced with " in m]
    run.notes.append(note)
    if iso is not None:
        run.finish(iso)
    departures: dict[str, dict[str, float]] = {}
    for b in [*banded, *([iso] if iso is not None else [])]:
        dep = pf.departure(pb, b, base, p)
        departures[b.id] = {"max": float(np.nanmax(dep)), "end": float(dep[-1]),
                            "first": float(dep[1]) if len(dep) > 1 else math.nan}
        if b.id.startswith("n") and not departures[b.id]["max"] > 1e-3:
            run.notes.append(f"branch {b.id} does not leave the base branch (max |Phi - Phi_base| = "
                             f"{departures[b.id]['max']:.2g}): the switch fell back")
        run.notes.append(f"branch {b.id} ({b.kind}): {_describe(b, dep)}")
    run.notes.insert(0, f"base branch 0: {_describe(base)}")
    extra["departure"] = departures
    extra["isolated"] = {"found": iso is not None, "note": note}


def run_jj_walls(request: SceneRequest) -> SceneResult:
    return run_pitchfork(request, JJ_DEFAULTS, "jj-walls")


SCENES: dict[str, Scene] = {
    "pitchfork": Scene(
        name="pitchfork",
        summary="gPCF, no-slip walls, no gravity: uniform shear in H, BPs at H_n^c = n pi psi, banded branches n = 1..3",
        defaults=PITCHFORK_DEFAULTS,
        run=run_pitchfork,
        problem_factory=problem_factory,
        x="H",
        y="phi",
        adaptive=True,
    ),
    "jj-walls": Scene(
        name="jj-walls",
        summary="gPCF with Johnson-Jackson walls, no gravity: symmetric base branch in H and the branches at its BPs",
        defaults=JJ_DEFAULTS,
        run=run_jj_walls,
        problem_factory=problem_factory,
        x="H",
        y="phi",
        adaptive=True,
    ),
}

# ---- gravity scenes (owned by problems/couette/gravity_scenes.py): register them on the next line.
from problems.couette.gravity_scenes import GRAVITY_SCENES  # noqa: E402  (gravity scenes live in their own module)

SCENES.update(GRAVITY_SCENES)
# ---- gPCF jobs that were CLI commands (unfold, fit --compute): problems/couette/phase_scenes.py
from problems.couette.phase_scenes import PHASE_SCENES  # noqa: E402

SCENES.update(PHASE_SCENES)
