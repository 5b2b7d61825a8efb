"""Lyapunov-Schmidt normal forms against problems with known coefficients."""

import numpy as np
import pytest
import scipy.sparse as sp

from contin.normalform import hysteresis_alpha, null_vectors, pitchfork_normal_form
from problems.discretization import make_grid


class ImperfectPitchfork:
    """x^3 - lam x + alpha + beta x^2 = 0, embedded with a decoupled linear component."""

    parameter_names = ("lam", "alpha", "beta")

    def residual(self, u, p):
        x, z = u
        return np.array([x**3 - p["lam"] * x + p["alpha"] + p["beta"] * x**2, 2.0 * z + x**2])

    def jacobian(self, u, p):
        x, _ = u
        return sp.csr_matrix(np.array([[3 * x**2 - p["lam"] + 2 * p["beta"] * x, 0.0], [2 * x, 2.0]]))

    def order_parameter(self, u, p):
        return u[0]


class AllenCahnCheb:
    """u'' + lam (u - u^3) = 0 on [0, pi], u = 0 at both ends (Chebyshev)."""

    parameter_names = ("lam",)

    def __init__(self, n=40):
        self.grid = make_grid("cheb", n)
        self.x = (self.grid.y + 0.5) * np.pi
        self.d2 = self.grid.d2.toarray() / np.pi**2

    def residual(self, u, p):
        r = self.d2 @ u + p["lam"] * (u - u**3)
        r[0], r[-1] = u[0], u[-1]
        return r

    def jacobian(self, u, p):
        j = self.d2 + np.diag(p["lam"] * (1 - 3 * u**2))
        j[0, :] = 0
        j[-1, :] = 0
        j[0, 0] = j[-1, -1] = 1
        return sp.csr_matrix(j)

    def order_parameter(self, u, p):
        # u at x = pi/2 (the middle node): the amplitude of the sin x mode
        return u[len(u) // 2]


def test_scalar_pitchfork_coefficients_are_exact():
    nf = pitchfork_normal_form(
        ImperfectPitchfork(), np.zeros(2), {"lam": 0.0, "alpha": 0.0, "beta": 0.0}, "lam", unfolding=("alpha", "beta")
    )
    assert nf.a3 == pytest.approx(1.0, rel=1e-6)
    assert nf.a1 == pytest.approx(-1.0, rel=1e-6)
    assert nf.a0["alpha"] == pytest.approx(1.0, rel=1e-6)
    assert nf.a2["beta"] == pytest.approx(1.0, rel=1e-4)
    assert abs(nf.a2["alpha"]) < 1e-6 and abs(nf.a0["beta"]) < 1e-8
    assert abs(nf.a_quadratic) < 1e-8
    assert nf.bend == pytest.approx(1.0, rel=1e-6)
    assert nf.criticality == "supercritical"
    b, alpha, beta = nf.unfolding(0.3, {"alpha": 0.01, "beta": -0.2})
    assert (b, alpha, beta) == pytest.approx((0.3, 0.01, -0.2), rel=1e-4)


def test_allen_cahn_first_pitchfork_matches_amplitude_equation():
    # u = a sin x: (pi/2)(lam - 1) a - (3 pi/8) a^3 = 0 => lam - 1 = (3/4) a^2, so bend = 3/4
    prob = AllenCahnCheb()
    nf = pitchfork_normal_form(prob, np.zeros(prob.x.size), {"lam": 1.0}, "lam", amplitude=1e-2)
    assert nf.bend == pytest.approx(0.75, rel=1e-6)
    assert nf.criticality == "supercritical"


def test_null_vectors_of_singular_matrix():
    a = sp.csr_matrix(np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 0.0, 1.0]]))
    nv = null_vectors(a)
    assert nv.residual < 1e-12
    assert np.allclose(np.abs(nv.phi), np.abs(np.array([1.0, 1.0, -1.0]) / np.sqrt(3)))


def test_hysteresis_variety_is_a_triple_root():
    x0 = 0.37
    beta = -3 * x0
    lam = -beta**2 / 3
    alpha = hysteresis_alpha(beta)
    roots = np.roots([1.0, beta, -lam, alpha])
    assert np.allclose(roots, x0, atol=1e-4)
