"""Gravity (G = Fr^-2 > 0) in granular Couette flow: imperfect pitchforks, isolas, fold curves,
normal forms (problems.couette.gravity; physics.md sections 2, 6; A13 gravity slides)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from contin.continuation import join
from contin.fit import fit_unfolding
from contin.scene import SceneError, SceneRequest
from problems.couette.gravity import (
    GravitySettings,
    branch_point_normal_forms,
    deduplicate,
    discover,
    extrema,
    fold_curves,
    fold_seeds,
    gravity_free_branches,
    gravity_problem,
    homotopy_in_G,
    lies_on,
    on_branch,
    pitchfork_fold_curves,
    trace_in_H,
    trim_self_overlap,
    unfolding_branches,
)
from problems.couette.gravity_scenes import GRAVITY_SCENES

H1C = 13.0685293255  # n pi psi at nu = 0.3, e = 0.8 (physics.md section 4)


@pytest.fixture(scope="module")
def pb():
    return gravity_problem("cheb", 32)


@pytest.fixture(scope="module")
def g0(pb):
    p = pb.params({"nu": 0.3, "e": 0.8})
    return gravity_free_branches(pb, p, GravitySettings(H_range=(1.0, 20.0), modes=1))


@pytest.fixture(scope="module")
def normal_form(pb, g0):
    base, _ = g0
    return branch_point_normal_forms(pb, base)[0]


def test_gravity_branch_from_small_H_is_bottom_plug(pb):
    """Fr = 1000: the branch from the near-uniform small-H state bends continuously onto the
    bottom-plug state (no fold), the 'surviving attractor'; uniform shear is not a solution."""
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0, "H": 1.0})
    # its residual is the gravity term H^3 G M, largest at the walls, |M| = nu_bar / 2
    assert np.max(np.abs(pb.residual(pb.uniform_state(p), p))) == pytest.approx(1.0 * 1e-6 * 0.15, rel=1e-9)
    b = trace_in_H(pb, pb.initial_guess(p), p, GravitySettings(H_range=(1.0, 25.0)))
    assert b.status == "EP" and not b.fold_points
    i = np.argmax(b.params["H"])
    assert b.params["H"][i] == pytest.approx(25.0)
    ob = b.observables
    assert ob["nu_bottom"][i] > 0.5 and ob["phi"][i] < 0.15  # dense layer at the bottom wall
    assert abs(ob["phi"][np.argmin(b.params["H"])] - 0.3) < 1e-4  # near-uniform at H = 1


def test_normal_form_at_first_bp(normal_form):
    """Lyapunov-Schmidt at H_1^c: supercritical (bend > 0), gravity an imperfection (a0 != 0),
    no quadratic term at G = 0 (Z2 symmetry)."""
    bp, nf = normal_form
    assert bp.params["H"] == pytest.approx(H1C, rel=1e-8)
    assert nf.criticality == "supercritical"
    assert abs(nf.a_quadratic) < 1e-6 * abs(nf.a3)
    assert abs(nf.a0["G"]) > 100.0
    assert nf.a0["G"] / nf.a3 == pytest.approx(50.6, rel=0.02)


def test_unfolding_fit_agrees_with_lyapunov_schmidt_and_is_odd_in_G(pb, normal_form):
    """Branches at G = 2e-8, 5e-8, 1e-7 near H_1^c: the fitted b1 and alpha1 agree with the
    Lyapunov-Schmidt values within 5 %; the mirror images (S x solves the -G problem) give
    alpha(-G) = -alpha(G), and alpha -> 0 as G -> 0."""
    bp, nf = normal_form
    branches = unfolding_branches(pb, bp, [2e-8, 5e-8, 1e-7], window=0.3)
    lam = [b.params["H"] for b in branches]
    delta = [b.observables["phi"] - 0.3 for b in branches]
    mu = [float(b.params["G"][0]) for b in branches]
    fit = fit_unfolding(lam, delta, mu, delta_max=0.025, window=0.3, center=bp.params["H"])
    assert fit.b1 == pytest.approx(-nf.a1 / nf.a3, rel=0.05)
    assert fit.alpha1 == pytest.approx(nf.a0["G"] / nf.a3, rel=0.05)
    assert fit.critical_value == pytest.approx(H1C, abs=2e-3)
    # reflection: states S x at -G; Phi(S x) = nu(-1/2)
    mdelta = [b.observables["nu_bottom"] - 0.3 for b in branches]
    mirror = fit_unfolding(lam, mdelta, [-m for m in mu], delta_max=0.025, window=0.3, center=bp.params["H"])
    # alpha(-G) = alpha1' (-G) must equal -alpha(G) = -alpha1 G: the same coefficient (Phi of
    # the mirror is nu(-1/2), which differs from -delta at second order: agreement to the fit's
    # accuracy, not to rounding)
    assert mirror.alpha1 == pytest.approx(fit.alpha1, rel=0.05)
    assert mirror.alpha1 == pytest.approx(nf.a0["G"] / nf.a3, rel=0.05)
    assert mirror.b1 == pytest.approx(fit.b1, rel=0.05)
    b = branches[-1]
    x = b.state(len(b) // 2)
    q = {k: float(v[len(b) // 2]) for k, v in b.params.items()}
    assert np.max(np.abs(pb.residual(pb.symmetry(x), {**q, "G": -q["G"]}))) < 1e-9
    assert np.max(np.abs(pb.residual(pb.symmetry(x), q))) > 1e-6
    # alpha -> 0 with G: the near-BP offset of the branch through the near-uniform state
    offsets = [abs(np.interp(bp.params["H"], b.params["H"], d)) for b, d in zip(branches[::2], delta[::2])]
    assert offsets[0] < offsets[1] < offsets[2]
    assert offsets[0] == pytest.approx(abs(nf.a0["G"] / nf.a3 * 2e-8) ** (1 / 3), rel=0.1)


def test_fold_curve_ends_on_the_pitchfork(pb, g0):
    """The fold of the imperfect pitchfork at Fr = 2000, continued in (H, G) down to G = 0,
    ends on the BP of uniform shear (H_1^c, Phi = nu_bar)."""
    _, kids = g0
    top = next(b for b in kids if b.observables["phi"][-1] > 0.3)
    i = int(np.argmin(np.abs(top.params["H"] - 16.0)))
    G = 2000.0 ** -2
    p = {k: float(v[i]) for k, v in top.params.items()}
    x = homotopy_in_G(pb, top.state(i), p, G)
    assert x is not None
    b = trace_in_H(pb, x, {**p, "G": G}, GravitySettings(H_range=(12.0, 18.0)))
    assert len(b.fold_points) == 1
    assert trim_self_overlap(b) is b  # near the fold the two sheets are close: not a retrace
    curves = fold_curves(pb, [b], max_steps=40, ds_max=0.2)
    c = curves[0]
    g = c.params["G"]
    k = np.nonzero(np.sign(g[:-1]) != np.sign(g[1:]))[0]
    assert k.size >= 1
    j = int(k[0])
    w = g[j] / (g[j] - g[j + 1])
    H0 = c.params["H"][j] + w * (c.params["H"][j + 1] - c.params["H"][j])
    phi0 = c.observables["phi"][j] + w * (c.observables["phi"][j + 1] - c.observables["phi"][j])
    assert H0 == pytest.approx(H1C, abs=2e-3)
    assert phi0 == pytest.approx(0.3, abs=2e-3)
    # the fold of the one-parameter run lies on the curve (it is its start point)
    lp = b.fold_points[0]
    assert np.min(np.hypot(c.params["H"] - lp.params["H"], c.params["G"] / G - 1)) < 1e-8


def test_dedup_and_lies_on(pb):
    """A branch traced twice from different seeds is one solution set; a different one is not."""
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0, "H": 1.0})
    st = GravitySettings(H_range=(1.0, 12.0))
    a = trace_in_H(pb, pb.initial_guess(p), p, st, branch_id="a")
    i = len(a) // 2
    q = {k: float(v[i]) for k, v in a.params.items()}
    b = trace_in_H(pb, a.state(i), q, GravitySettings(H_range=(3.0, 8.0)), branch_id="b")
    assert lies_on(b, a) and not lies_on(a, b)
    kept, dropped = deduplicate([b, a])
    assert [k.id for k in kept] == ["a"] and dropped == [("b", "a")]
    assert on_branch(pb, a.state(i), q, a)


def test_trim_self_overlap_cuts_a_branch_that_retraces_itself(pb):
    """A run that comes back along its own earlier part (after a jump between nearby sheets)
    is cut where the overlap starts: the primary branch at Fr = 1000 joined with itself (H from
    12 down to 1 and back up, steps of 0.2 in H) keeps its first pass and the return up to where
    the excursion since the overlapped part exceeds 5 in H (H ~ 6); a branch that does not
    retrace itself is returned unchanged (a fold is not a retrace: see the fold-curve test)."""
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0, "H": 1.0})
    a = trace_in_H(pb, pb.initial_guess(p), p, GravitySettings(H_range=(1.0, 12.0)))
    assert trim_self_overlap(a) is a
    twice = join(a, a)
    n = len(a)
    assert len(twice) == 2 * n - 1
    cut = trim_self_overlap(twice)
    assert len(cut) > n and 5.0 < cut.params["H"][-1] <= 6.0
    assert np.all(np.diff(cut.params["H"][n - 1:]) > 0)  # one pass back up, not beyond
    assert "own earlier part" in cut.message
    assert cut.params["H"][n - 1] == pytest.approx(1.0)


def test_scene_rejects_bad_input():
    run = GRAVITY_SCENES["gravity"].run
    with pytest.raises(SceneError, match="finite Froude"):
        run(SceneRequest(params={"Fr": float("inf")}))
    with pytest.raises(SceneError, match="unknown parameter"):
        run(SceneRequest(params={"X": 1}))
    with pytest.raises(SceneError, match="H_min < H_max"):
        run(SceneRequest(params={"H_min": 10, "H_max": 5}))
    with pytest.raises(SceneError, match="modes must be a positive integer"):
        run(SceneRequest(params={"modes": 1.5}))


# ----------------------------------------------------------------------------- Fr = 1000 isola
# The isola of the third pitchfork (H_3^c = 39.206) at Fr = 1000, nu = 0.3, e = 0.8: closed,
# folds at H = 41.90019 (Phi = 0.3885) and 63.47749 (Phi = 0.5804) on cheb 64; cheb 48 gives
# 41.90019 and 63.47750.  Its fold curve has its largest G at Fr = 783.973, H = 47.7535 (cheb 48
# and 64 agree to 1e-7): the isola dies there.  (cheb 32 cannot resolve it: the guard stops it.)
FR1000_FOLDS = (41.90019, 63.47750)
FR_ISOLA_DEATH = 783.973


@pytest.fixture(scope="module")
def pbf():
    """cheb 64: at 48 the plug near the isola's right fold (min T = 0.011) is at the edge of
    the continuation's resolution guard (estimated error 3.1e-5 > 3e-5)."""
    return gravity_problem("cheb", 64)


@pytest.fixture(scope="module")
def g0_f(pbf):
    p = pbf.params({"nu": 0.3, "e": 0.8})
    return gravity_free_branches(pbf, p, GravitySettings(H_range=(1.0, 70.0), modes=3))


def _isola_checks(d):
    """Every isola of a diagram is closed, has an even (non-zero) number of folds and no
    other branch of the diagram lies on it."""
    isolas = d.of_kind("isola")
    for iso in isolas:
        assert iso.closed and iso.status == "EP" and "closed loop" in iso.message
        assert len(iso.fold_points) > 0 and len(iso.fold_points) % 2 == 0
        assert not any(lies_on(b, iso) for b in d.branches if b is not iso)
    return isolas


@pytest.mark.slow
def test_isolas_at_Fr_400_closed_even_folds_found_by_both_routes(pbf, g0_f):
    """Fr = 400 (nu = 0.3, e = 0.8, cheb 64): two isolas, the floating plugs of the first
    pitchfork (folds H = 14.423, 33.555) and a small one from the second pitchfork's banded
    branch (folds 27.373, 33.613; gravity unfolds that pitchfork only at second order), both
    closed with two folds; the fold curves through their folds give seeds on them (fold points
    of the one-parameter runs lie on the two-parameter curves) that trace them again, and with
    both routes each is found once."""
    _, kids = g0_f
    p = pbf.params({"nu": 0.3, "e": 0.8, "Fr": 400.0})
    st = GravitySettings(H_range=(1.0, 50.0), seed_H=(16.0, 30.0))
    low = [b for b in kids if b.id.startswith(("g0.1.", "g0.2."))]
    d = discover(pbf, p, st, g0_branches=low, routes=("homotopy",))
    isolas = _isola_checks(d)
    assert len(isolas) == 2
    folds = sorted(sorted(s.params["H"] for s in iso.fold_points) for iso in isolas)
    assert folds[0] == pytest.approx([14.423, 33.555], abs=2e-3)
    assert folds[1] == pytest.approx([27.373, 33.613], abs=2e-3)
    for iso in isolas:
        assert np.mean(iso.observables["nu_top"] > iso.observables["nu_bottom"]) > 0.5  # dense top
    curves = fold_curves(pbf, isolas, max_steps=150)
    seeds = fold_seeds(pbf, curves, p["G"], st.H_range)
    for iso in isolas:
        on = sorted(q["H"] for _, x, q in seeds if on_branch(pbf, x, q, iso))
        assert on == pytest.approx(sorted(s.params["H"] for s in iso.fold_points), abs=1e-6 * 50)
    again = discover(pbf, p, st, routes=("fold-curve",), curves=curves)
    found = _isola_checks(again)
    assert len(found) == 2
    assert all(any(lies_on(f, iso) and lies_on(iso, f) for f in found) for iso in isolas)
    both = discover(pbf, p, st, g0_branches=low, curves=curves)
    assert len(_isola_checks(both)) == 2
    assert all(both.found_by[b.id] == ["homotopy", "fold-curve"] for b in both.of_kind("isola"))


def test_isola_at_Fr_1000_found_by_both_routes(pbf, g0_f):
    """Fr = 1000 (nu = 0.3, e = 0.8), the third pitchfork: the dense-top banded state continued
    in G (route 1) lies on a closed isola with two folds at H = 41.900 and 63.478; the fold
    curve of that pitchfork, started at Fr = 2000 near the BP (route 2), crosses G = 1e-6 at
    both folds and its seeds trace the same isola; with both routes the isola is found once,
    by both.  The fold curve's G-maximum (death of the isola) is at Fr = 783.97, H = 47.75."""
    base, kids = g0_f
    p = pbf.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0})
    mode3 = [b for b in kids if b.id.startswith("g0.3.")]
    assert len(mode3) == 2
    # H >= 35 keeps the (irrelevant) branch from the H_min state short
    st = GravitySettings(H_range=(35.0, 70.0), seed_H=(44.0,))
    curves = pitchfork_fold_curves(pbf, p, base, mode3, H_range=(30.0, 70.0), max_steps=120)
    assert [c.parent for c in curves] == ["BP at H=39.2056"]

    by_homotopy = discover(pbf, p, st, g0_branches=mode3, routes=("homotopy",))
    (iso,) = _isola_checks(by_homotopy)
    folds = sorted(s.params["H"] for s in iso.fold_points)
    assert folds == pytest.approx(FR1000_FOLDS, abs=2e-4)
    assert np.mean(iso.observables["nu_top"] > iso.observables["nu_bottom"]) > 0.9  # dense top

    by_fold_curve = discover(pbf, p, st, curves=curves, routes=("fold-curve",))
    (again,) = _isola_checks(by_fold_curve)
    assert by_fold_curve.routes[again.id] == "fold-curve"
    assert lies_on(again, iso) and lies_on(iso, again)
    seeds = sorted(q["H"] for _, _, q in fold_seeds(pbf, curves, p["G"], st.H_range))
    assert seeds == pytest.approx(folds, abs=1e-6 * 64)  # fold points lie on the fold curve

    both = discover(pbf, p, st, g0_branches=mode3, curves=curves)
    (once,) = _isola_checks(both)
    assert both.found_by[once.id] == ["homotopy", "fold-curve"]
    assert lies_on(once, iso)

    deaths = [r for r in extrema(curves, problem=pbf) if r["event"] == "death"]
    assert len(deaths) == 1 and deaths[0]["resolved"]
    assert deaths[0]["Fr"] == pytest.approx(FR_ISOLA_DEATH, rel=1e-5)
    assert deaths[0]["H"] == pytest.approx(47.7535, abs=1e-3)
    assert folds[0] < deaths[0]["H"] < folds[1]  # the isola shrinks onto that point


@pytest.mark.slow
def test_scene_fr1000_reports_every_isola_closed_and_found_twice():
    """``contin trace gravity -s nu=0.3 -s e=0.8 -s Fr=1000 --json`` (cheb 64, H <= 70, both
    routes): every isola is closed, has an even number of folds, is found by both routes and
    appears once; the third-pitchfork isola (folds 41.900, 63.478) is among them."""
    import json

    from click.testing import CliRunner

    from contin.cli import main

    r = CliRunner().invoke(main, ["trace", "gravity", "-s", "nu=0.3", "-s", "e=0.8", "-s", "Fr=1000", "--json",
                                  "--no-stability", "-q"])
    doc = json.loads(r.stdout)
    from problems.couette import compiled

    engine = "numba" if compiled.available() else "numpy"  # the CLI's default, auto
    assert doc["discretization"] == {"method": "cheb", "intervals": 64, "engine": engine}
    extra = doc["extra"]
    isolas = [b for b in doc["branches"] if b["kind"] == "isola"]
    assert len(isolas) >= 1
    folds_of = {}
    for sp in doc["special_points"]:
        if sp["type"] == "LP":
            folds_of.setdefault(sp["branch"], []).append(sp["params"]["H"])
    for b in isolas:
        assert b["closed"] and b["status"] == "EP"
        assert len(folds_of[b["id"]]) % 2 == 0 and folds_of[b["id"]]
        assert extra["found_by"][b["id"]] == ["homotopy", "fold-curve"]
        assert all(k != b["id"] for _, k in extra["duplicates"]) or len(isolas) == 1
    assert any(sorted(folds_of[b["id"]]) == pytest.approx(FR1000_FOLDS, abs=2e-4) for b in isolas)


@pytest.mark.slow
def test_nu016_isola_at_Fr_2500_dies_at_2426(pbf):
    """nu = 0.16 (subcritical pitchfork, banded fold at H = 41.963 at G = 0): at Fr = 2500 the
    floating plugs form an isola (folds H = 51.433, 61.865), found by both routes (route 2
    continues the G = 0 fold of the banded branch in (H, G)); its fold curve has its largest G
    at Fr = 2426.2, H = 55.89 (death, between the slides' 2500 and 2350 panels), and the
    primary's hysteresis pair annihilates at Fr = 2824.1, H = 38.86."""
    p0 = pbf.params({"nu": 0.16, "e": 0.8})
    st = GravitySettings(H_range=(1.0, 80.0), modes=1)
    base, kids = gravity_free_branches(pbf, p0, st)
    assert [round(lp.params["H"], 3) for lp in kids[0].fold_points] == [41.963]
    curves = pitchfork_fold_curves(pbf, p0, base, kids, H_range=st.H_range)
    deaths = sorted((r["Fr"], r["H"]) for r in extrema(curves, problem=pbf) if r["event"] == "death")
    assert len(deaths) == 2
    assert deaths[0][0] == pytest.approx(2426.18, rel=1e-5) and deaths[0][1] == pytest.approx(55.893, abs=1e-2)
    assert deaths[1][0] == pytest.approx(2824.10, rel=1e-5) and deaths[1][1] == pytest.approx(38.857, abs=1e-2)
    p = pbf.params({"nu": 0.16, "e": 0.8, "Fr": 2500.0})
    d = discover(pbf, p, replace(st, seed_H=(60.0, 70.0)), g0_branches=kids, base=base, curves=curves)
    (iso,) = _isola_checks(d)
    assert sorted(s.params["H"] for s in iso.fold_points) == pytest.approx([51.433, 61.865], abs=2e-3)
    assert d.found_by[iso.id] == ["homotopy", "fold-curve"]


@pytest.mark.slow
def test_phase_diagram_retraces_a_stopped_fold_curve_on_a_finer_grid():
    """Issue 14 sec. 1 (no --grid for gravity-phase): on cheb 16 the resolution guard stops the
    first pitchfork's fold curve at H = 22.7 (Fr* then 254.1196, 3e-6 off); with ``refine`` the
    curve is retraced on the grid twice the estimate's suggestion (cheb 64), reaches H = 30 and
    gives Fr* = 254.12037995 (the cheb 96 value of results/gravity/unfold_nu0.3.json,
    254.120379954, to 1e-10)."""
    from contin.options import AdaptOptions
    from problems.couette.gravity import phase_diagram

    pb = gravity_problem("cheb", 16, engine="auto")
    p = pb.params({"nu": 0.3, "e": 0.8})
    fixed = phase_diagram(pb, p, H_range=(1.0, 30.0))
    assert [c.status for c in fixed.curves] == ["MX"] and "under-resolved" in fixed.curves[0].message
    d = phase_diagram(pb, p, H_range=(1.0, 30.0), refine=AdaptOptions())
    (c,) = d.curves
    assert c.status == "EP" and c.grid_at(0) == c.grid_at(len(c) - 1) > 16
    assert any("retraced on grids 16, " in line for line in c.audit)
    assert d.fr_min_floating_plug == pytest.approx(254.120379954, rel=1e-10)
    assert abs(fixed.fr_min_floating_plug - 254.120379954) > 1e-4  # the coarse grid's value is off


def test_gravity_scene_refines_only_branches_that_need_it():
    """Without --grid the scene refines a branch's grid only where its estimate exceeds tol: a
    diagram cheb 64 resolves (Fr = 1000 to H = 8) stays on cheb 64 with no refinement note and
    no grid column; max_grid below the start grid, or negative, is one error."""
    import json

    from click.testing import CliRunner

    from contin.cli import main

    r = CliRunner().invoke(main, ["trace", "gravity", "-s", "Fr=1000", "-s", "H_max=8", "-s", "modes=1",
                                  "--no-stability", "--json", "-q"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["discretization"]["intervals"] == 64
    assert not any("refined" in note for note in doc["notes"])
    r = CliRunner().invoke(main, ["trace", "gravity", "-s", "max_grid=-1", "-q"])
    assert r.exit_code == 1
    assert r.stderr.strip() == "Error: max_grid must be a non-negative integer (0: a fixed grid), got -1"
    r = CliRunner().invoke(main, ["trace", "gravity", "-s", "max_grid=48", "-q"])
    assert r.exit_code == 1
    assert r.stderr.strip() == "Error: max_grid must be 0 (a fixed grid) or at least the start grid 64, got 48"


def test_strong_gravity_branch_refines_its_grid_instead_of_ending_mx():
    """Fr = 50: the bottom plug approaches packing exponentially in H.  On a fixed cheb 64 the
    resolution guard ends the primary branch MX at H = 21.84; with ``GravitySettings.refine``
    the same trace refines 64 -> 96 before the guard's stop (H = 21.23, by the two-grid check) and reaches
    H = 24, every point meeting tol on its own grid; below the change it is the fixed-grid run
    point for point; its end state equals an independent cheb 128 solve; past max_grid it ends
    MX with that reason."""
    from contin.adapt import AdaptOptions, on_grid
    from contin.newton import newton

    pb64 = gravity_problem("cheb", 64)
    p = pb64.params({"nu": 0.3, "e": 0.8, "Fr": 50.0, "H": 1.0})
    st = GravitySettings(H_range=(1.0, 24.0), modes=1)
    fixed = trace_in_H(pb64, pb64.initial_guess(p), p, st)
    assert fixed.status == "MX" and "under-resolved" in fixed.message
    assert fixed.params["H"][-1] == pytest.approx(21.62, abs=0.01)  # its last stored state
    refine = AdaptOptions(tol=3e-5, max_grid=256, coarsen_below=None, special_tol=3e-5)
    b = trace_in_H(pb64, pb64.initial_guess(p), p, replace(st, refine=refine))
    assert b.status == "EP" and b.params["H"][-1] == pytest.approx(24.0, abs=1e-12)
    (change,) = b.grid_changes
    i, old, new = change
    # the two-grid check of the solve (AdaptOptions.check_factor, on by default) refines at H = 21.23,
    # one step before the estimate alone would (21.62): there the cheb 64 point is 2x finer off by > tol
    assert (old, new) == (64, 96) and b.params["H"][i] == pytest.approx(21.23, abs=0.01)
    assert any("two-grid error above tol" in line for line in b.audit)
    H = b.params["H"]
    for j in range(len(b)):
        q = {**p, "H": float(H[j])}
        assert on_grid(pb64, b.grid_at(j)).error_estimate(b.state(j), q) <= 3e-5
    np.testing.assert_array_equal(H[:i], fixed.params["H"][:i])  # the fixed-grid path up to the change
    np.testing.assert_array_equal(b.states[:i, : pb64.size], fixed.states[:i])
    pb128 = gravity_problem("cheb", 128)
    q = {**p, "H": 24.0}
    ref = newton(pb128, on_grid(pb64, 96).transfer(b.state(len(b) - 1), pb128), q)
    assert ref.converged
    phi = pb128.observables(ref.u, q)["phi"]
    assert b.observables["phi"][-1] == pytest.approx(phi, rel=1e-7)
    capped = trace_in_H(pb64, pb64.initial_guess(p), p, replace(st, refine=replace(refine, max_grid=80)))
    assert capped.status == "MX" and "on the maximum grid 80" in capped.message
