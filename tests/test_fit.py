"""Least-squares fit of the pitchfork unfolding to branch data."""

import numpy as np
import pytest

from contin.fit import fit_unfolding


def _branch(b1, lam_c, alpha1, beta1, mu, delta, cubic_extra=0.0):
    # solve the unfolding for lam given delta (exactly, so the fit must recover the inputs)
    lam = lam_c + (delta**3 + cubic_extra * delta**5 + alpha1 * mu + beta1 * mu * delta**2) / (b1 * delta)
    return lam, delta


def test_fit_recovers_exact_unfolding():
    truth = {"b1": 0.8, "lam_c": 13.07, "alpha1": -2.5, "beta1": 4.0}
    lams, deltas, mus = [], [], []
    for mu in (0.0, 1e-5, -1e-5, 2e-5):
        for sign in (1, -1):
            d = sign * np.linspace(0.01, 0.05, 15)
            lam, d = _branch(truth["b1"], truth["lam_c"], truth["alpha1"], truth["beta1"], mu, d)
            lams.append(lam)
            deltas.append(d)
            mus.append(mu)
    fit = fit_unfolding(lams, deltas, mus)
    assert fit.b1 == pytest.approx(0.8, rel=1e-10)
    assert fit.critical_value == pytest.approx(13.07, rel=1e-12)
    assert fit.alpha1 == pytest.approx(-2.5, rel=1e-8)
    assert fit.beta1 == pytest.approx(4.0, rel=1e-8)
    assert fit.rms_residual < 1e-14


def test_fit_error_bars_cover_higher_order_bias():
    lams, deltas, mus = [], [], []
    for mu in (0.0, 1e-5, -1e-5):
        for sign in (1, -1):
            d = sign * np.linspace(0.005, 0.03, 20)
            lam, d = _branch(0.8, 13.07, -2.5, 4.0, mu, d, cubic_extra=3.0)
            lams.append(lam)
            deltas.append(d)
            mus.append(mu)
    fit = fit_unfolding(lams, deltas, mus, critical_value=13.07)
    # quintic term biases b1 at O(delta^2); the fit must stay within 5 % and report a nonzero error
    assert fit.b1 == pytest.approx(0.8, rel=0.05)
    assert fit.b1_err > 0
    with pytest.raises(ValueError, match="points inside the fit window"):
        fit_unfolding(lams, deltas, mus, delta_max=1e-9)


def test_fit_errors_are_honest_for_badly_scaled_imperfections():
    # mu ~ 1e-8 (gravity G = Fr^-2) makes the raw normal matrix singular to working precision;
    # the reported sigma of beta1 must still cover its actual error under noise.
    rng = np.random.default_rng(1)
    lams, deltas, mus = [], [], []
    for mu in (2e-8, 5e-8, 1e-7, -5e-8):
        for sign in (1, -1):
            d = sign * np.linspace(0.005, 0.03, 25)
            lam, d = _branch(0.8, 13.07, -5000.0, 40000.0, mu, d)
            lams.append(lam + 1e-7 * rng.standard_normal(lam.size))
            deltas.append(d)
            mus.append(mu)
    fit = fit_unfolding(lams, deltas, mus, critical_value=13.07)
    for value, err, truth in ((fit.b1, fit.b1_err, 0.8), (fit.alpha1, fit.alpha1_err, -5000.0), (fit.beta1, fit.beta1_err, 40000.0)):
        assert err > 0
        assert abs(value - truth) < 5 * err


def _canonical_branches(u, mus, deltas):
    """Exact solution sets of delta^3 - (b1 l + b2 l^2) delta + alpha1 mu + beta1 mu delta^2 + q5 delta^5 = 0
    as (l, delta) per mu (l from the quadratic B(l) = delta^2 + alpha/delta + beta delta + q5 delta^4)."""
    lams, ds, ms = [], [], []
    for mu in mus:
        d = deltas
        rhs = d**2 + u.alpha1 * mu / d + u.beta1 * mu * d + u.q5 * d**4
        ok = u.b1**2 + 4 * u.b2 * rhs > 0  # beyond: no solution with small l (outside any window)
        lams.append(2 * rhs[ok] / (u.b1 + np.sqrt(u.b1**2 + 4 * u.b2 * rhs[ok])))
        ds.append(d[ok])
        ms.append(mu)
    return lams, ds, ms


def test_graph_fit_recovers_the_canonical_unfolding_with_honest_errors():
    """Exact branches of a canonical unfolding with Couette-like scales (b1 ~ 1e-2, alpha1 ~ 50,
    beta1 ~ -1500, mu ~ 1e-7): fit_graph recovers every coefficient within its reported error,
    the errors shrink with the fitted order, and alpha(mu), beta(mu) per mu are odd in mu and
    vanish at mu = 0."""
    from contin.fit import fit_graph, fit_imperfections
    from contin.normalform import Unfolding

    truth = Unfolding(0.0, b1=0.009, b2=-0.003, alpha1=50.0, beta1=-1500.0, q5=-30.0)
    d = np.concatenate([-np.linspace(0.05, 0.002, 120), np.linspace(0.002, 0.05, 120)])
    mus = (0.0, 3e-8, 1e-7, 3e-7, -1e-7)
    lam, ds, ms = _canonical_branches(truth, mus, d)
    fits = {order: fit_graph(lam, ds, ms, critical_value=0.0, order=order, window=0.15, delta_max=0.035) for order in (3, 5)}
    for order, fit in fits.items():
        err = fit.errors()
        for name in truth.NAMES:
            assert abs(getattr(fit.unfolding, name) - getattr(truth, name)) <= 3 * err[name], (order, name)
        assert fit.condition < 1e6
    f5 = fits[5]
    assert f5.unfolding.beta1 == pytest.approx(-1500.0, rel=2e-3)
    assert f5.unfolding.alpha1 == pytest.approx(50.0, rel=1e-5)
    assert f5.errors()["beta1"] < 0.1 * fits[3].errors()["beta1"]
    per = {r.mu: r for r in fit_imperfections(lam, ds, ms, f5, window=0.15, delta_max=0.035)}
    assert abs(per[0.0].alpha) < 1e-12 and abs(per[0.0].beta) < 1e-9
    assert per[-1e-7].alpha == pytest.approx(-per[1e-7].alpha, rel=1e-10)
    assert per[-1e-7].beta == pytest.approx(-per[1e-7].beta, rel=1e-8)
    for m in (3e-8, 1e-7):
        assert abs(per[m].alpha - 50.0 * m) <= 3 * per[m].alpha_err + 1e-6 * 50.0 * m
        assert abs(per[m].beta + 1500.0 * m) <= 3 * per[m].beta_err


def test_graph_fit_refuses_unidentifiable_designs():
    from contin.fit import fit_graph

    lam = [np.linspace(0.01, 0.2, 30)]
    d = [np.sqrt(lam[0] / 100.0)]
    with pytest.raises(ValueError, match="mu != 0"):
        fit_graph(lam, d, [0.0], critical_value=0.0)
    # a single mu cannot separate mu delta from delta^4 and mu^2/delta^2 from mu/delta... (rank)
    with pytest.raises(ValueError, match="singular|points inside"):
        fit_graph(lam, d, [1e-7], critical_value=0.0, delta_max=0.011)
