"""The norm of the Hopf eigenvector q in the first Lyapunov coefficient (``contin.hopf``).

l1 scales as |c|^2 under q -> c q, so it is a number only together with the norm of q.  With the
Euclidean q^H q = 1 the nodal values of a discretised PDE's q are O(1/sqrt(n)) and l1 falls like
1/n under refinement; with the problem's ``inner_product_weights`` (quadrature weights,
q^H W q ~ the L2 norm) it converges at the scheme's order.  Problems without the hook keep the
Euclidean norm bitwise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from contin.hopf import first_lyapunov, hopf_vectors
from problems.demo import Brusselator
from tests.hopf_models import Hidden, HopfNormalForm, Lorenz


def brusselator_l1(method: str, intervals: int, hide: bool = False) -> float:
    """l1 at the k = 1 Hopf point of the homogeneous Brusselator on the grid (exact b_H, omega_H
    with the grid's own Dirichlet eigenvalue: no location error enters)."""
    pb = Brusselator(method, intervals)
    par = dict(Brusselator.PARAMS)
    par["b"], omega = Brusselator.hopf_point(par, pb.dirichlet_eigenvalue())
    return first_lyapunov(Hidden(pb, keep=("mass_matrix",)) if hide else pb, pb.homogeneous(par), par, omega)


def test_brusselator_l1_converges_at_the_schemes_order_with_the_weights():
    """fd2 on N = 16, 32, 64: successive differences of l1 fall by 4 (observed order 2.0); the
    Chebyshev value (converged to ~1e-9, the finite-difference forms' level) is the limit, and
    the fd2 errors against it fall at order 2 too.  Measured: l1 = -0.2260821, -0.2259402,
    -0.2259058 (fd2), -0.2258944 (cheb 32); differences 1.42e-4, 3.44e-5."""
    l1 = [brusselator_l1("fd2", n) for n in (16, 32, 64)]
    d1, d2 = l1[1] - l1[0], l1[2] - l1[1]
    order = math.log2(d1 / d2)
    assert 1.9 < order < 2.1, (l1, order)
    ref = brusselator_l1("cheb", 32)
    assert ref == pytest.approx(-0.225894383, abs=2e-9)
    err = [abs(v - ref) for v in l1]
    assert 1.9 < math.log2(err[1] / err[2]) < 2.1 and err[2] < 2e-5
    assert all(v < 0 for v in l1)  # supercritical


def test_brusselator_euclidean_l1_scales_like_one_over_n():
    """The defect the hook removes: with q^H q = 1 (hook hidden) l1 halves with every doubling of
    the grid (ratios 2.0013, 2.0003 on fd2 16/32/64; the Chebyshev grid likewise), sign right
    and size an artefact: at N = 64 it is 1/64 of the converged value."""
    e = [brusselator_l1("fd2", n, hide=True) for n in (16, 32, 64)]
    assert e[0] / e[1] == pytest.approx(2.0, abs=0.01) and e[1] / e[2] == pytest.approx(2.0, abs=0.01)
    c = [brusselator_l1("cheb", n, hide=True) for n in (16, 32)]
    assert c[0] / c[1] == pytest.approx(2.0, abs=0.01)
    assert all(v < 0 for v in e + c)


def test_ode_without_the_hook_is_the_euclidean_l1():
    """Lorenz at rho_H = 470/19 has no hook: l1 is Kuznetsov's with the Euclidean q^H q = 1, within
    1e-8 of the formula with Lorenz's exact B (``test_hopf.lorenz_l1_exact``; measured 7e-10, the
    difference derivatives' error).  It compared bitwise with a constant of the earlier numpy/scipy
    stack, 1.1e-9 off the exact value, and failed under numpy 2.4.6 / scipy 1.17.1 for no defect."""
    from tests.test_hopf import BETA, SIGMA, lorenz_l1_exact

    s, b = SIGMA, BETA
    rho = s * (s + b + 3) / (s - b - 1)
    x = math.sqrt(b * (rho - 1))
    u, p = np.array([x, x, rho - 1]), {"sigma": s, "rho": rho, "beta": b}
    omega, l1 = lorenz_l1_exact(rho)
    assert omega == pytest.approx(math.sqrt(b * (s + rho)), rel=1e-13)
    assert first_lyapunov(Lorenz(), u, p, omega) == pytest.approx(l1, rel=1e-8)


@pytest.mark.parametrize("c", [4.0, 0.25, 3.0, 0.1])
def test_weights_scale_l1_exactly(c):
    """W = c I gives q^H q = 1/c, so l1 = l1_euclid / c = 2 a / c (the exact scaling law).  For
    c a power of 4, q is scaled by a power of 2 and the finite-difference steps of B and C (relative
    to max |q|) perturb u by the same vectors: bitwise l1_euclid / c.  Otherwise to the rounding of
    C's second differences (eps / h_C^2 ~ 1e-8 relative; measured 3e-9)."""
    p = {"mu": 0.0, "a": -0.7}
    e = first_lyapunov(HopfNormalForm(), np.zeros(2), p, 1.0)
    w = first_lyapunov(HopfNormalForm(c), np.zeros(2), p, 1.0)
    assert e == pytest.approx(-1.4, rel=1e-6) and w == pytest.approx(-1.4 / c, rel=1e-6)
    if math.log(c, 4).is_integer():
        assert w == e / c
    else:
        assert w == pytest.approx(e / c, rel=1e-8)


def test_hopf_vectors_weighted_normalisation():
    """q^H W q = 1 and p^H M q = 1 with the weights; None is the Euclidean q^H q = 1 bitwise."""
    pb = Brusselator("fd2", 16)
    par = dict(Brusselator.PARAMS)
    par["b"], omega = Brusselator.hopf_point(par, pb.dirichlet_eigenvalue())
    u = pb.homogeneous(par)
    jac, mass, w = pb.jacobian(u, par), pb.mass_matrix(u, par), pb.inner_product_weights(u, par)
    q, p = hopf_vectors(jac, mass, omega, weights=w)
    assert np.vdot(q, w * q).real == pytest.approx(1.0, rel=1e-13)
    assert np.vdot(p, mass @ q) == pytest.approx(1.0, rel=1e-12)
    q0, p0 = hopf_vectors(jac, mass, omega)
    q1, p1 = hopf_vectors(jac, mass, omega, weights=None)
    assert np.array_equal(q0, q1) and np.array_equal(p0, p1)
    assert np.linalg.norm(q0) == pytest.approx(1.0, rel=1e-14)


def test_bad_weights_are_one_clear_error():
    p = {"mu": 0.0, "a": -0.7}
    bad = HopfNormalForm()
    bad.inner_product_weights = lambda u, q: np.array([1.0, 0.0])
    with pytest.raises(ValueError, match="positive finite weights"):
        first_lyapunov(bad, np.zeros(2), p, 1.0)


def test_from_functions_takes_the_weights():
    """``from_functions(..., inner_product_weights=w)`` (an array or a function) is the hook."""
    from contin import from_functions

    def F(u, p):
        x, y = u
        r2 = x * x + y * y
        return np.array([p["mu"] * x - y + p["a"] * x * r2, x + p["mu"] * y + p["a"] * y * r2])

    p = {"mu": 0.0, "a": -0.7}
    for w in (np.full(2, 4.0), lambda u, q: np.full(2, 4.0)):
        pb = from_functions(F, np.zeros(2), p, method="cs", inner_product_weights=w)
        assert first_lyapunov(pb, np.zeros(2), p, 1.0) == pytest.approx(-0.35, rel=1e-6)
    assert first_lyapunov(from_functions(F, np.zeros(2), p, method="cs"), np.zeros(2), p, 1.0) == pytest.approx(-1.4, rel=1e-6)


def test_the_granular_problems_weights():
    """gPCF, the disks (with and without gravity's M) and the nonlocal problems: one weight per
    unknown, > 0, each profile's summing to 1 (the gap) and 1 for the scalar P."""
    from contin.problem import inner_product_weights
    from problems.couette.model import CouetteProblem
    from problems.disks.model import DiskCouetteProblem
    from problems.nonlocal_flow.cylinder import CylindricalCouette
    from problems.nonlocal_flow.plane import PlaneShear

    for pb, profiles in ((CouetteProblem("cheb", 16), 3), (CouetteProblem("fd2", 16, gravity=True), 4),
                         (DiskCouetteProblem("fd4", 16), 3), (DiskCouetteProblem("cheb", 12, gravity=True), 4),
                         (PlaneShear("cheb", 16), 2), (CylindricalCouette("fd2", 16), 2)):
        w = inner_product_weights(pb, np.zeros(pb.size), {})
        assert w.shape == (pb.size,) and w.min() > 0 and w.sum() == pytest.approx(profiles + 1, rel=1e-13)
        i_p = pb.i_P if hasattr(pb, "i_P") else 2 * pb.n
        assert w[i_p] == 1.0
