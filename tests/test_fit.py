"""Least-squares fit of the pitchfork unfolding to branch data."""

import numpy as np
import pytest

from contin.fit import fit_unfolding


def _branch(b1, lam_c, alpha1, beta1, mu, delta, cubic_extra=0.0):
    # solve the unfolding for lam given delta (exactly, so the fit must recover the inputs)
    lam = lam_c + (delta**3 + cubic_extra * delta**5 + alpha1 * mu + beta1 * mu * delta**2) / (b1 * delta)
    return lam, delta


def test_fit_recovers_exact_unfolding():
    truth = dict(b1=0.8, lam_c=13.07, alpha1=-2.5, beta1=4.0)
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
