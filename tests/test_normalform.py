"""Lyapunov-Schmidt normal forms against problems with known coefficients."""

from typing import ClassVar

import numpy as np
import pytest
import scipy.sparse as sp

from contin.normalform import (
    hysteresis_alpha,
    null_vectors,
    pitchfork_normal_form,
    pitchfork_unfolding,
)
from problems.discretization import make_grid
from tests.hopf_models import Hidden


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


class UnfoldedPitchfork:
    """F = M(x, lam) [x^3 - b1 lam x + a1 mu + be mu x^2 + c mu lam + q5 x^5 + q3 lam x^3 + q1 lam^2 x]
    with a multiplier M = 1 + m x^2 + n lam (contact equivalence: same solution set), embedded
    with a decoupled linear component."""

    parameter_names = ("lam", "mu")
    coef: ClassVar[dict[str, float]] = {"b1": 0.8, "a1": 2.0, "be": -3.0, "c": 0.7, "q5": 0.5, "q3": -0.4, "q1": 0.3}

    def __init__(self, m=0.0, n=0.0):
        self.m, self.n = m, n

    def _g(self, x, lam, mu):
        k = self.coef
        return (x**3 - k["b1"] * lam * x + k["a1"] * mu + k["be"] * mu * x**2 + k["c"] * mu * lam
                + k["q5"] * x**5 + k["q3"] * lam * x**3 + k["q1"] * lam**2 * x)

    def residual(self, u, p):
        x, z = u
        mult = 1.0 + self.m * x**2 + self.n * p["lam"]
        return np.array([mult * self._g(x, p["lam"], p["mu"]), 2.0 * z + x**2])

    def jacobian(self, u, p):
        x, _ = u
        h = 1e-7
        d = (self.residual([x + h, 0.0], p)[0] - self.residual([x - h, 0.0], p)[0]) / (2 * h)
        return sp.csr_matrix(np.array([[d, 0.0], [2 * x, 2.0]]))

    def lam_exact(self, x, mu):
        """lam on the solution set: the root of the quadratic in lam nearest lam = 0."""
        k = self.coef
        a = k["q1"] * x
        b = -k["b1"] * x + k["c"] * mu + k["q3"] * x**3
        c = x**3 + k["a1"] * mu + k["be"] * mu * x**2 + k["q5"] * x**5
        return 2 * c / (-b + np.sign(-b) * np.sqrt(b * b - 4 * a * c))


def test_pitchfork_unfolding_is_the_solution_set_and_independent_of_the_multiplier():
    """The canonical unfolding from the Lyapunov-Schmidt stencil reproduces the exact solution
    set lam(x, mu) to next order (error O(eps^6) with x ~ eps, mu ~ eps^3), and it does not
    change under contact equivalence (multiplier 1 + m x^2 + n lam), while the raw mu x^2
    coefficient does: beta_raw alone is not a property of the solution set."""
    p0 = {"lam": 0.0, "mu": 0.0}
    ell = np.array([1.0, 0.0])
    plain = pitchfork_unfolding(UnfoldedPitchfork(), np.zeros(2), p0, "lam", "mu", ell, amplitude=0.02)
    twisted = pitchfork_unfolding(UnfoldedPitchfork(m=0.9, n=-1.3), np.zeros(2), p0, "lam", "mu", ell, amplitude=0.02)
    k = UnfoldedPitchfork.coef
    assert plain.coefficients["b1"] == pytest.approx(k["b1"], rel=1e-7)
    assert plain.coefficients["alpha1"] == pytest.approx(k["a1"], rel=1e-7)
    assert plain.coefficients["beta_raw"] == pytest.approx(k["be"], rel=1e-5)
    assert plain.coefficients["c"] == pytest.approx(k["c"], rel=1e-5)
    assert twisted.coefficients["beta_raw"] == pytest.approx(k["be"] + 0.9 * k["a1"], rel=1e-5)
    u, v = plain.unfolding, twisted.unfolding
    # canonical beta1 = beta_raw - c/b1 + q3 alpha1/b1 (multipliers 1 + n lam, 1 + m x^2)
    assert u.beta1 == pytest.approx(k["be"] - k["c"] / k["b1"] + k["q3"] * k["a1"] / k["b1"], rel=1e-5)
    for name in u.NAMES:
        assert getattr(v, name) == pytest.approx(getattr(u, name), rel=1e-5), name
    prob = UnfoldedPitchfork()
    for eps in (0.04, 0.02):
        x = eps * np.array([-2.0, -1.0, 1.0, 1.5, 2.0])
        mu = 0.3 * eps**3
        err = np.max(np.abs(u.lam(x, mu) - prob.lam_exact(x, mu)))
        lead = np.max(np.abs(x**2 / k["b1"] + k["a1"] * mu / (k["b1"] * x) - prob.lam_exact(x, mu)))
        assert err < 0.05 * lead
        if eps == 0.04:
            err_big = err
    assert err_big / err == pytest.approx(64.0, rel=0.25)  # O(eps^6)


def test_unfolding_fold_and_hysteresis():
    """Fold of the pure cubic: lam_LP = (3/b1) (alpha1 mu/2)^(2/3) exactly; with beta, b2, q5 the
    next-order fold matches the stationary point of the exact graph to O(d^6); the hysteresis
    point of the cubic truncation is a triple root; alpha1 beta1 < 0 has none."""
    from contin.normalform import Unfolding

    cubic = Unfolding(0.0, b1=0.5, b2=0.0, alpha1=2.0, beta1=0.0, q5=0.0)
    mu = 1e-3
    assert cubic.fold(mu)[0] == pytest.approx(3 / 0.5 * (2.0 * mu / 2) ** (2 / 3), rel=1e-12)
    full = Unfolding(0.0, b1=0.5, b2=-0.3, alpha1=2.0, beta1=4.0, q5=1.5)

    def exact_lam(d, m):  # B(lam) = b1 lam + b2 lam^2 = d^2 + alpha/d + beta d + q5 d^4
        rhs = d**2 + full.alpha1 * m / d + full.beta1 * m * d + full.q5 * d**4
        return 2 * rhs / (full.b1 + np.sqrt(full.b1**2 + 4 * full.b2 * rhs))

    errs = []
    for m in (1e-6, 1e-7):
        d = np.linspace(0.3, 3.0, 200001) * np.cbrt(full.alpha1 * m / 2)
        exact = float(np.min(exact_lam(d, m)))
        lam_f, _ = full.fold(m)
        assert lam_f == pytest.approx(exact, rel=1e-2)
        errs.append(abs(lam_f / exact - 1))
        assert abs(full.fold_expansion(m) / exact - 1) < 0.05 * abs(full.fold(m, leading=True)[0] / exact - 1)
    assert errs[0] / errs[1] == pytest.approx(10 ** (4 / 3), rel=0.3)  # relative error O(d^4)
    hyst = Unfolding(0.0, b1=1.0, b2=0.0, alpha1=2.0, beta1=5.0, q5=0.0).hysteresis()
    assert hyst is not None
    a, b = 2.0 * hyst["mu"], 5.0 * hyst["mu"]
    roots = np.roots([1.0, b, -hyst["lam"], a])
    assert np.allclose(roots, hyst["delta"], atol=1e-4)
    assert Unfolding(0.0, b1=1.0, b2=0.0, alpha1=2.0, beta1=-5.0, q5=0.0).hysteresis() is None


def _allen_cahn_bend(intervals, order_parameter=True, weights=True):
    """Bend of Allen-Cahn's first pitchfork off u = 0 on fd2 (lam_c the grid's own smallest
    Dirichlet eigenvalue of -d^2/dx^2 on [0, pi]: no location error enters)."""
    from problems.demo import AllenCahn

    pb = AllenCahn("fd2", intervals)
    inner = pb.grid.d2[1:-1, 1:-1].toarray() / pb.length**2
    lam = float(np.min(np.linalg.eigvalsh(-(inner + inner.T) / 2)))
    keep = [name for name, on in (("order_parameter", order_parameter), ("inner_product_weights", weights)) if on]
    return pitchfork_normal_form(Hidden(pb, keep=keep), np.zeros(pb.n), {"lam": lam}, "lam")


def test_branch_point_bend_converges_with_the_grid_in_the_weighted_norm():
    """Without an order parameter delta is the amplitude along the null vector.  Euclidean
    (|phi| = 1: x ~ sqrt(n) times the L2 amplitude) the bend falls like 1/n: 0.0934, 0.0468, 0.0234
    on fd2 16/32/64.  In the problem's ``inner_product_weights`` norm delta is the L2 amplitude of
    u = A sin x (|sin|_2^2 = pi/2, lam - 1 = (3/4) A^2) and the bend converges at order 2 to
    3/(2 pi) = 0.4774648: 0.4759328, 0.4770815, 0.4773690 (errors 1.5e-3, 3.8e-4, 9.6e-5).  With the
    order parameter u(pi/5) the hook changes nothing (kappa carries phi's scale): bitwise the
    same coefficients, bend -> 3/(4 sin^2(pi/5))."""
    import math

    grids = (16, 32, 64)
    euclid = [_allen_cahn_bend(n, order_parameter=False, weights=False).bend for n in grids]
    assert euclid[0] / euclid[1] == pytest.approx(2.0, abs=0.01) and euclid[1] / euclid[2] == pytest.approx(2.0, abs=0.01)
    weighted = [_allen_cahn_bend(n, order_parameter=False).bend for n in grids]
    err = [abs(b - 3 / (2 * math.pi)) for b in weighted]
    assert 1.95 < math.log2(err[0] / err[1]) < 2.05 and 1.95 < math.log2(err[1] / err[2]) < 2.05
    assert err[2] < 1e-4
    d1, d2 = weighted[1] - weighted[0], weighted[2] - weighted[1]
    assert 1.95 < math.log2(d1 / d2) < 2.05
    for n in grids:
        with_op = _allen_cahn_bend(n)
        without = _allen_cahn_bend(n, weights=False)
        assert (with_op.a3, with_op.a1, with_op.kappa) == (without.a3, without.a1, without.kappa)
    assert with_op.bend == pytest.approx(3 / (4 * math.sin(math.pi / 5) ** 2), rel=1e-3)
