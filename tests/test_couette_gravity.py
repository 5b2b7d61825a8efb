"""Gravity (G = Fr^-2 > 0) in granular Couette flow: imperfect pitchforks, isolas, fold curves,
normal forms (problems.couette.gravity; physics.md sections 2, 6; A13 gravity slides)."""

from __future__ import annotations

import numpy as np
import pytest

from contin.fit import fit_unfolding
from contin.scene import SceneError, SceneRequest
from problems.couette.gravity import (
    GravitySettings,
    branch_point_normal_forms,
    deduplicate,
    discover,
    fold_curves,
    fold_seeds,
    gravity_free_branches,
    gravity_problem,
    homotopy_in_G,
    lies_on,
    on_branch,
    trace_in_H,
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


def test_scene_rejects_bad_input():
    run = GRAVITY_SCENES["gravity"].run
    with pytest.raises(SceneError, match="finite Froude"):
        run(SceneRequest(params={"Fr": float("inf")}))
    with pytest.raises(SceneError, match="unknown parameter"):
        run(SceneRequest(params={"X": 1}))
    with pytest.raises(SceneError, match="H_min < H_max"):
        run(SceneRequest(params={"H_min": 10, "H_max": 5}))


@pytest.mark.slow
def test_isola_closed_even_folds_found_by_both_routes(pb):
    """Fr = 400 (nu = 0.3, e = 0.8): the floating-plug states form an isola (closed, two
    folds, H in about [14.4, 33.6]); seeded again from the fold curve through its folds it
    is found again and not duplicated.  (At Fr = 1000 our floating-plug branch is
    fold-bounded, its upper fold at H = 59 lies outside H <= 50, so there is no isola there.)"""
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 400.0})
    st = GravitySettings(H_range=(1.0, 50.0))
    d = discover(pb, p, st, routes=("homotopy",))
    isolas = d.of_kind("isola")
    assert len(isolas) == 1
    iso = isolas[0]
    assert iso.closed and len(iso.fold_points) % 2 == 0 and len(iso.fold_points) == 2
    Hf = sorted(s.params["H"] for s in iso.fold_points)
    assert Hf[0] == pytest.approx(14.42, abs=0.05) and Hf[1] == pytest.approx(33.56, abs=0.05)
    assert np.mean(iso.observables["nu_top"] > iso.observables["nu_bottom"]) > 0.5  # floating plug
    curves = fold_curves(pb, [iso], max_steps=300)
    seeds = fold_seeds(pb, curves, p["G"], st.H_range)
    assert len(seeds) >= 2
    for _, x, q in seeds:
        assert on_branch(pb, x, q, iso)
    again = discover(pb, p, st, routes=("fold-curve",), curves=curves)
    assert len(again.of_kind("isola")) == 1 and lies_on(again.of_kind("isola")[0], iso)
    # fold points of the one-parameter run lie on the two-parameter fold curve: its crossings
    # of G = Fr^-2, polished on the fold system, are the isola's folds to the location tolerance
    Hs = sorted(q["H"] for _, _, q in seeds)
    for lp, h in zip(sorted(iso.fold_points, key=lambda s: s.params["H"]), Hs):
        assert h == pytest.approx(lp.params["H"], abs=1e-6 * lp.params["H"])
