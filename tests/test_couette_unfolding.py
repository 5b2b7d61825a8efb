"""Gravity unfolding of the first pitchfork of uniform shear (nu = 0.3, e = 0.8, cheb 32):
Lyapunov-Schmidt against the fitted unfolding, oddness in G, fold-curve prediction
(problems.couette.unfolding; physics.md section 6 rows 10-12; issue 5 acceptance)."""

from __future__ import annotations

import numpy as np
import pytest

from contin.fit import fit_graph, fit_imperfections
from contin.foldcurve import trace_fold_curve
from contin.normalform import pitchfork_normal_form
from contin.options import ContinuationOptions, StepOptions
from problems.couette.gravity import gravity_problem
from problems.couette.unfolding import (
    branches_near_bp,
    first_pitchfork,
    fold_curve_check,
    fold_on_curve_at,
    ls_unfolding,
    odd_delta,
    odd_order_parameter,
    unfolding_data,
)

H1C = 13.0685293255  # n pi psi at nu = 0.3, e = 0.8 (physics.md section 4)
GS = (0.0, 1e-7, 3e-7, 1e-6, -1e-7, -3e-7)


@pytest.fixture(scope="module")
def pb():
    return gravity_problem("cheb", 32)


@pytest.fixture(scope="module")
def pitchfork(pb):
    return first_pitchfork(pb, 0.3, 0.8)


@pytest.fixture(scope="module")
def near(pb, pitchfork):
    base, bp = pitchfork
    return {G: branches_near_bp(pb, base, bp, G, 0.3) for G in GS}


@pytest.fixture(scope="module")
def ls(pb, pitchfork):
    _, bp = pitchfork
    return {h: ls_unfolding(pb, bp, amplitude=h) for h in (2e-2, 1e-2, 5e-3)}


@pytest.fixture(scope="module")
def fit(near, pitchfork):
    _, bp = pitchfork
    pos = [b for G, bs in near.items() if G >= 0 for b in bs]
    return fit_graph(*unfolding_data(pos, bp.params["H"]), critical_value=bp.params["H"], order=5)


@pytest.fixture(scope="module")
def fold_curve(pb, near, pitchfork):
    _, bp = pitchfork
    Hc = bp.params["H"]
    lp = next(b for b in near[3e-7] if b.fold_points).fold_points[0]
    opts = ContinuationOptions(bounds={"H": (Hc - 0.05, Hc + 0.5)}, max_steps=200,
                               step=StepOptions(ds=0.01, ds_max=0.02, max_angle=0.1))
    return trace_fold_curve(pb, lp, "G", opts, parameter="H")


def test_odd_order_parameter(pb, near):
    """l . x = (nu(1/2) - nu(-1/2))/2 and it changes sign under the reflection."""
    ell = odd_order_parameter(pb)
    b = near[1e-7][1]
    x = b.state(5)
    assert ell @ x == pytest.approx(odd_delta(b)[5], abs=1e-15)
    assert ell @ pb.symmetry(x) == pytest.approx(-(ell @ x), abs=1e-15)


def test_branch_components_near_the_pitchfork(near, pitchfork):
    """G = 0: two halves of the pitchfork (each switched, not mirrored) with delta of both signs.
    G = +-1e-7, +-3e-7: two components in the window, the fold-bounded one with one fold;
    G = 1e-6: its fold lies beyond the window (H_LP - H_c = 0.315), one component."""
    _, bp = pitchfork
    assert bp.params["H"] == pytest.approx(H1C, rel=1e-8)
    signs = sorted(np.sign(odd_delta(b)[-1]) for b in near[0.0])
    assert signs == [-1.0, 1.0]
    for G in (1e-7, 3e-7, -1e-7, -3e-7):
        assert len(near[G]) == 2
        assert sorted(len(b.fold_points) for b in near[G]) == [0, 1]
        # the fold-bounded component is dense on the side gravity pushes the plug away from:
        # delta > 0 (dense top, floating plug) for G > 0, its mirror for G < 0
        fb = next(b for b in near[G] if b.fold_points)
        assert np.all(np.sign(odd_delta(fb)) == np.sign(G))
    assert len(near[1e-6]) == 1


def test_ls_and_fit_agree_within_5_percent(ls, fit):
    """Issue 5 acceptance: b1, alpha1 and beta1 of the canonical unfolding
    delta^3 - B(H) delta + alpha(G) + beta(G) delta^2 + q5 delta^5 = 0 from Lyapunov-Schmidt
    and from the fit agree within 5 %; measured: within 0.2 %, and within the stated errors
    (fit: statistical + truncation; LS: change when the stencil is halved)."""
    lsu = ls[5e-3].unfolding
    err_ls = {k: abs(getattr(lsu, k) - getattr(ls[1e-2].unfolding, k)) for k in lsu.NAMES}
    err_fit = fit.errors()
    for name in ("b1", "alpha1", "beta1", "b2", "q5"):
        a, b = getattr(fit.unfolding, name), getattr(lsu, name)
        assert abs(a - b) <= 0.05 * abs(b), name
        assert abs(a - b) <= 3 * np.hypot(err_fit[name], err_ls[name]), name
    assert lsu.b1 == pytest.approx(0.0088522, rel=1e-4)
    assert lsu.alpha1 == pytest.approx(50.624, rel=1e-4)
    assert lsu.beta1 == pytest.approx(-1546.1, rel=1e-3)
    assert abs(fit.unfolding.beta1 - lsu.beta1) <= 0.005 * abs(lsu.beta1)
    assert fit.errors()["beta1"] < 0.005 * abs(fit.unfolding.beta1)  # identifiable: error below 0.5 %


def test_ls_stencil_convergence_and_leading_order(pb, pitchfork, ls):
    """The LS weight-5 coefficients converge with the stencil amplitude h like h^4 (beta1 moves
    1.5 from h = 0.02 to 0.01, 0.12 from 0.01 to 0.005: Richardson-consistent), and the
    leading-order b1, alpha1 equal those of the phi-normalised reduction
    (pitchfork_normal_form: b1 = -a1/a3, alpha1 = a0/a3 in delta = Phi - nu_bar) to 1e-4:
    the coordinates differ only at higher order.  The raw mu delta^2 coefficient differs
    between the two coordinates (-402.6 there, about -199 here): it is not a property of the
    solution set, the canonical beta1 is."""
    b = [ls[h].unfolding.beta1 for h in (2e-2, 1e-2, 5e-3)]
    assert abs(b[2] - b[1]) < 0.15 * abs(b[1] - b[0])
    assert abs(b[2] - b[1]) < 2e-4 * abs(b[2])
    _, bp = pitchfork
    nf = pitchfork_normal_form(pb, bp.state, {**bp.params, "G": 0.0}, "H", unfolding=("G",), tol=1e-11, polish=1)
    lsu = ls[5e-3].unfolding
    assert -nf.a1 / nf.a3 == pytest.approx(lsu.b1, rel=1e-4)
    assert nf.a0["G"] / nf.a3 == pytest.approx(lsu.alpha1, rel=1e-4)
    assert nf.a2["G"] / nf.a3 == pytest.approx(-402.6, rel=2e-3)
    assert ls[5e-3].coefficients["beta_raw"] == pytest.approx(-198.9, rel=2e-3)


def test_alpha_beta_vanish_at_fr_inf_and_are_odd_in_G(near, fit, pitchfork):
    """Issue 5 acceptance: per-G fits (no linearity in G assumed) give alpha(0) = beta(0) = 0
    (the two G = 0 halves are traced independently) and alpha(-G) = -alpha(G),
    beta(-G) = -beta(G) from branches computed at -G (SignedGravity), to 1e-8 relative;
    alpha(G)/G and beta(G)/G agree with the global alpha1, beta1 within their errors."""
    _, bp = pitchfork
    lam, d, mu = unfolding_data([b for bs in near.values() for b in bs], bp.params["H"])
    per = {r.mu: r for r in fit_imperfections(lam, d, mu, fit)}
    assert set(per) >= {0.0, 1e-7, 3e-7, -1e-7, -3e-7}
    z, ref = per[0.0], per[1e-7]
    assert abs(z.alpha) < 1e-8 * abs(ref.alpha) and abs(z.alpha) <= 3 * z.alpha_err
    assert abs(z.beta) < 1e-6 * abs(ref.beta) and abs(z.beta) <= 3 * z.beta_err
    for G in (1e-7, 3e-7):
        assert per[-G].alpha == pytest.approx(-per[G].alpha, rel=1e-8)
        assert per[-G].beta == pytest.approx(-per[G].beta, rel=1e-6)
        assert abs(per[G].alpha / G - fit.unfolding.alpha1) <= 3 * per[G].alpha_err / G
        assert abs(per[G].beta / G - fit.unfolding.beta1) <= 3 * per[G].beta_err / G
    assert per[1e-7].beta / 1e-7 == pytest.approx(fit.unfolding.beta1, rel=0.02)


def test_fold_curve_ends_on_bp_and_follows_the_predicted_unfolding(fold_curve, ls, fit, pitchfork):
    """The fold curve through the fold at G = 3e-7, traced in (H, G), reaches G = 0 at the BP
    (H_c to 1e-9: its H-extremum) and then mirrors into G < 0.  Along it, H_LP - H_c from the
    next-order unfolding (LS or fitted coefficients) matches the computed folds to 5e-4
    relative for 1e-8 <= G <= 1e-7 and 1e-2 up to G = 1e-6, against 1e-2 .. 8e-2 for the
    leading order 3/b1 (alpha1 G/2)^(2/3); the error of the next order falls like G^(4/3) (the
    first omitted weight).  The exponent fitted to the computed folds on [1e-9, 1e-8] is 2/3
    within 2e-3 (0.6677) and equals the predicted local exponent within 5e-4."""
    _, bp = pitchfork
    Hc = bp.params["H"]
    c = fold_curve
    lps = [s for s in c.points("LP")]
    assert any(abs(s.params["H"] - Hc) < 1e-9 and abs(s.params["G"]) < 1e-15 for s in lps)
    assert c.params["G"].min() < 0 < c.params["G"].max()
    for unf in (ls[5e-3].unfolding, fit.unfolding):
        chk = fold_curve_check(unf, c, Hc, (1e-9, 1e-6))
        small = [r for r in chk["points"] if 1e-8 <= r["G"] <= 1e-7]
        assert len(small) >= 3
        assert max(abs(r["rel_error"]) for r in small) < 5e-4
        assert chk["max_rel_error"] < 1e-2
        assert max(abs(r["rel_error_leading"]) for r in small) > 1e-2
        assert chk["max_rel_error_leading"] > 5e-2
        first, last = small[0], small[-1]
        rate = np.log(last["rel_error"] / first["rel_error"]) / np.log(last["G"] / first["G"])
        assert rate == pytest.approx(4 / 3, abs=0.15)
        # exponent on [1e-9, 1e-8]: 2/3 plus the O(d^2) correction (+1e-3 there, +5e-3 on [1e-8, 1e-7])
        assert chk["exponent_range"][1] <= 1e-8
        assert chk["exponent"] == pytest.approx(2 / 3, abs=2e-3)
        g = np.array([r["G"] for r in chk["points"] if r["G"] <= 1e-8])
        pred = np.array([unf.fold(x)[0] for x in g])
        assert chk["exponent"] == pytest.approx(np.polyfit(np.log(g), np.log(pred), 1)[0], abs=5e-4)


def test_one_parameter_folds_lie_on_the_fold_curve(pb, near, fold_curve):
    """Issue 5 acceptance: the folds located on the one-parameter runs in H at G = 1e-7 and at
    G = -1e-7 (separate continuations) lie on the fold curve traced from the fold at G = 3e-7:
    the curve corrected to that G (fold system with G fixed) has the same H to 1e-8 and the
    same state to 1e-6 (the LP locator's tolerance)."""
    for G in (1e-7, -1e-7):
        lp = next(b for b in near[G] if b.fold_points).fold_points[0]
        assert lp.converged
        H, x = fold_on_curve_at(pb, fold_curve, G)
        assert H == pytest.approx(lp.params["H"], abs=1e-8)
        assert np.max(np.abs(x - lp.state)) < 1e-6


def test_hysteresis_point_is_outside_the_perturbative_range(ls):
    """alpha1 > 0 > beta1: the line (alpha1 G, beta1 G) meets the hysteresis variety
    alpha = beta^3/27 only at G = 0 (no hysteresis point at either sign of G).  Were the sign
    of beta1 the other, the point would be at |G| = (27 alpha1/|beta1|^3)^(1/2) = 6.1e-4
    (Fr = 41) with delta = |beta|/3 = 0.31, six times the fitted window |delta| <= 0.05:
    not observable within the unfolding's range either way."""
    u = ls[5e-3].unfolding
    assert u.alpha1 > 0 > u.beta1
    assert u.hysteresis() is None
    G = np.sqrt(27 * u.alpha1 / abs(u.beta1) ** 3)
    assert G == pytest.approx(6.08e-4, rel=0.01)
    assert G**-0.5 == pytest.approx(40.6, rel=0.01)
    assert abs(u.beta1) * G / 3 == pytest.approx(0.313, rel=0.01)
