"""Hopf points (HB): location, omega and the first Lyapunov coefficient (contin.hopf).

References are computed in each test independently of contin: closed forms (Lorenz, the
Brusselator's Fourier modes), scipy solves of the Hopf defining system (trace J = 0 of the 2-D
CSTR, F = 0 & J v = i omega v for the CO model) and Kuznetsov's l1 with exact multilinear forms.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from contin.continuation import trace
from contin.hopf import first_lyapunov, hopf_numbers
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from tests.hopf_models import AB, CO, Brusselator1D, HopfNormalForm, Lorenz

SIGMA, BETA = 10.0, 8.0 / 3.0


def lorenz_branch():
    r = 10.0
    x = math.sqrt(BETA * (r - 1))
    opts = ContinuationOptions(step=StepOptions(ds=0.5, ds_max=2.0), bounds={"rho": (1.5, 40.0)})
    return trace(Lorenz(), np.array([x, x, r - 1]), {"sigma": SIGMA, "rho": r, "beta": BETA}, "rho", opts)


def lorenz_l1_exact(rho: float) -> tuple[float, float]:
    """Kuznetsov's l1 (eq. 3.20) with the exact B of Lorenz (C = 0), q^H q = 1."""
    x = math.sqrt(BETA * (rho - 1))
    a = np.array([[-SIGMA, SIGMA, 0.0], [1.0, -1.0, -x], [x, x, -BETA]])  # rho - z = 1 at the equilibrium
    w, v = np.linalg.eig(a)
    i = int(np.argmax(w.imag))
    omega = w[i].imag
    q = v[:, i] / np.linalg.norm(v[:, i])
    wl, vl = np.linalg.eig(a.T)
    p = vl[:, int(np.argmin(np.abs(wl + 1j * omega)))]
    p = p / np.conj(np.vdot(p, q))

    def b(s, t):  # second derivative of the Lorenz field: (0, -(s1 t3 + s3 t1), s1 t2 + s2 t1)
        return np.array([0.0, -(s[0] * t[2] + s[2] * t[0]), s[0] * t[1] + s[1] * t[0]])

    qb = np.conj(q)
    r1 = np.linalg.solve(a, b(q, qb))
    r2 = np.linalg.solve(2j * omega * np.eye(3) - a, b(q, q))
    return omega, float((-2 * np.vdot(p, b(q, r1)) + np.vdot(p, b(qb, r2))).real / (2 * omega))


def test_lorenz_hopf_point_frequency_and_subcritical_l1():
    br = lorenz_branch()
    hb = br.points("HB")
    assert len(hb) == 1
    rho_h = 470.0 / 19.0  # sigma (sigma + beta + 3) / (sigma - beta - 1)
    assert hb[0].converged
    assert abs(hb[0].params["rho"] - rho_h) <= 1e-10 * rho_h
    assert hb[0].data["omega"] ** 2 == pytest.approx(1760.0 / 19.0, rel=1e-9)  # beta (sigma + rho_H)
    omega, l1 = lorenz_l1_exact(rho_h)
    assert hb[0].data["l1"] > 0 and "subcritical" in hb[0].note
    assert hb[0].data["l1"] == pytest.approx(l1, rel=1e-5)
    x = math.sqrt(BETA * (rho_h - 1))
    assert np.allclose(hb[0].state, [x, x, rho_h - 1], rtol=1e-9)


def test_first_lyapunov_of_the_hopf_normal_form():
    """x' = mu x - y + a x r^2, y' = x + mu y + a y r^2 at mu = 0: with J q = i q, q = (1, -i)/sqrt 2
    (q^H q = 1) and x = z q + conj(z q), r^2 = 2 |z|^2, so z' = (mu + i) z + 2 a |z|^2 z and
    Kuznetsov's l1 = Re c1 / omega = 2 a: super- (a < 0) and subcritical (a > 0)."""
    for a in (-0.7, 0.4):
        l1 = first_lyapunov(HopfNormalForm(), np.zeros(2), {"mu": 0.0, "a": a}, 1.0)
        assert l1 == pytest.approx(2 * a, rel=1e-6)

    class Slow(HopfNormalForm):
        """2 u' = F(u): time runs half as fast, omega = 1/2, and l1 = Re c1 / omega is unchanged."""

        def mass_matrix(self, u, p):
            return 2.0 * np.eye(2)

    for a in (-0.7, 0.4):
        numbers = hopf_numbers(Slow(), np.zeros(2), {"mu": 0.0, "a": a})
        assert numbers["omega"] == pytest.approx(0.5, rel=1e-12)
        assert numbers["l1"] == pytest.approx(2 * a, rel=1e-6)
    # the mass matrix also enters detection: the branch in mu crosses at mu = 0 with omega = 1/2
    opts = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.2), bounds={"mu": (-1.0, 1.0)})
    (hb,) = trace(Slow(), np.zeros(2), {"mu": -1.0, "a": -0.7}, "mu", opts).points("HB")
    assert abs(hb.params["mu"]) <= 1e-11 and hb.data["omega"] == pytest.approx(0.5, rel=1e-12)
    assert hb.data["l1"] == pytest.approx(-1.4, rel=1e-6) and "supercritical" in hb.note


def ab_hopf_reference(b: float, beta: float) -> list[tuple[float, float, float]]:
    """Hopf points (D, u1, omega) of AUTO's ab at fixed B, beta from the closed-form conditions of
    the 2-D system.  On F = 0: D (1 - u1) e^{u2} = u1 and u2 = B u1 / (1 + beta), so
    J = [[-1/(1 - u1), u1], [-B u1/(1 - u1), -1 - beta + B u1]]; Hopf: trace J = 0, det J > 0."""

    def trace_j(u1):
        return -1 / (1 - u1) - 1 - beta + b * u1

    grid = np.linspace(1e-6, 1 - 1e-6, 20001)
    t = trace_j(grid)
    out = []
    for i in np.flatnonzero(np.sign(t[:-1]) != np.sign(t[1:])):
        u1 = brentq(trace_j, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
        u2 = b * u1 / (1 + beta)
        det = (1 + beta - b * u1) / (1 - u1) + b * u1 * u1 / (1 - u1)
        if det > 0:
            out.append((u1 * math.exp(-u2) / (1 - u1), u1, math.sqrt(det)))
    return out


@pytest.mark.parametrize("b", [14.0, 16.0])
def test_auto_ab_hopf_points_against_the_closed_form(b):
    """AUTO's demo ab: from the UZ points B = 14..17 of the trivial branch (c.ab.1), continue in
    D with beta = 3 (c.ab.2; D up to 0.5 here, past the demo's stop at 0.25, to reach the upper
    Hopf point): every HB matches trace J = 0 with det J > 0."""
    ref = ab_hopf_reference(b, 3.0)
    assert len(ref) == 2 and all(r[0] < 0.5 for r in ref)
    # c.ab.1: the trivial state u = 0 at D = 0 continued in B with UZR = 14, 15, 16, 17 and stop at 18
    first = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.2), bounds={"B": (0.0, 100.0)},
                                user_zeros={"B": (14.0, 15.0, 16.0, 17.0, 18.0)}, stop_at=("UZ5",))
    start = trace(AB(), np.zeros(2), {"D": 0.0, "B": 0.0, "beta": 3.0}, "B", first)
    uz = {round(sp.params["B"], 9): sp for sp in start.points("UZ")}
    assert sorted(uz) == [14.0, 15.0, 16.0, 17.0, 18.0] and start.parameter_values[-1] < 18.2
    # c.ab.2: from the UZ point continue in D
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"D": (0.0, 0.5)}, max_steps=2000)
    br = trace(AB(), uz[b].state, uz[b].params, "D", opts)
    hb = br.points("HB")
    assert len(hb) == 2
    for sp in hb:
        d_ref, u1_ref, om_ref = min(ref, key=lambda r: abs(r[1] - sp.state[0]))
        assert sp.converged
        assert abs(sp.params["D"] - d_ref) <= 1e-10 * d_ref
        assert sp.state[0] == pytest.approx(u1_ref, rel=1e-8)
        assert sp.data["omega"] == pytest.approx(om_ref, rel=1e-8)
        assert math.isfinite(sp.data["l1"])

    assert hb[0].data["l1"] > 0 > hb[1].data["l1"]  # lower HB subcritical, upper supercritical


def co_hopf_reference(guess_u, guess_q2):
    """Hopf point of the CO model near a guess: F = 0 and the Routh-Hurwitz boundary of the 3x3
    Jacobian, a1 a2 = a3 for lambda^3 + a1 lambda^2 + a2 lambda + a3 (a pair +-i sqrt(a2))."""
    model, par = CO(), dict(CO.PARAMS)

    def system(z):
        u, q2 = z[:3], z[3]
        p = {**par, "q2": q2}
        j = np.asarray(model.jacobian(u, p))
        a1 = -np.trace(j)
        a2 = sum(np.linalg.det(j[np.ix_(ix, ix)]) for ix in ([0, 1], [0, 2], [1, 2]))
        a3 = -np.linalg.det(j)
        return np.concatenate([model.residual(u, p), [a1 * a2 - a3]])

    z, _, ok, msg = fsolve(system, np.concatenate([guess_u, [guess_q2]]), xtol=1e-14, full_output=True)
    # ok == 3 ("xtol too small, no further improvement") at the rounding floor: the residual decides
    assert ok == 1 or (ok == 3 and np.max(np.abs(system(z))) < 1e-13), msg
    p = {**par, "q2": z[3]}
    j = np.asarray(model.jacobian(z[:3], p))
    a2 = sum(np.linalg.det(j[np.ix_(ix, ix)]) for ix in ([0, 1], [0, 2], [1, 2]))
    return z[3], z[:3], math.sqrt(a2)


def test_co_oxidation_two_hopf_points():
    """BifurcationKit's tutorialCO: continuation in q2 from q2 = 0.6 up to 1.9 finds two HBs."""
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.01), bounds={"q2": (0.5, 1.9)}, max_steps=3000)
    br = trace(CO(), np.array([0.2, 0.05, 0.5]), CO.PARAMS, "q2", opts)  # the physical state (x, y, s in [0, 1])
    hb = br.points("HB")
    assert len(hb) == 2
    for sp in hb:
        q2, u, omega = co_hopf_reference(sp.state, sp.params["q2"])
        assert abs(sp.params["q2"] - q2) <= 1e-10 * q2
        assert np.allclose(sp.state, u, rtol=1e-8, atol=1e-12)
        assert sp.data["omega"] == pytest.approx(omega, rel=1e-8)
    assert len(br.points("LP")) == 2


def brusselator_hopf_reference(n: int, par: dict) -> list[float]:
    """l of the Hopf points of the trivial state (alpha, beta/alpha) of the discretized
    Brusselator: the Dirichlet second difference has eigenvalues lam_k = -4 sin^2(k pi / (2 (n+1))),
    and on mode k J is [[c1 lam + beta - 1, alpha^2], [-beta, c2 lam - alpha^2]] with
    c_i = D_i n^2 / l^2; Hopf where its trace vanishes with det > 0."""
    a, b, d1, d2 = par["alpha"], par["beta"], par["D1"], par["D2"]
    out = []
    for k in range(1, n + 1):
        lam = -4 * math.sin(k * math.pi / (2 * (n + 1))) ** 2
        l = n * math.sqrt((d1 + d2) * -lam / (b - 1 - a * a))
        c1, c2 = d1 * n * n / l**2, d2 * n * n / l**2
        if (c1 * lam + b - 1) * (c2 * lam - a * a) + a * a * b > 0:
            out.append(l)
    return sorted(out)


@pytest.mark.parametrize("n", [30, pytest.param(100, marks=pytest.mark.slow), pytest.param(300, marks=pytest.mark.slow)])
def test_brusselator_1d_three_hopf_points(n):
    """BifurcationKit's 1-D Brusselator tutorial: the trivial branch in l from 0.3 to 1.9 has three
    Hopf points of the discretization (n = 300: 600 unknowns, the shift-invert ARPACK path)."""
    par = Brusselator1D.PARAMS
    model = Brusselator1D(n)
    ref = [l for l in brusselator_hopf_reference(n, par) if l < 1.9]
    assert len(ref) == 3
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.1), bounds={"l": (0.3, 1.9)},
                               detection=DetectionOptions(detect_hopf=True))
    br = trace(model, model.trivial(par), par, "l", opts)
    hb = br.points("HB")
    assert [sp.params["l"] for sp in hb] == pytest.approx(ref, rel=1e-10)
    assert all(sp.converged for sp in hb)


def test_demo_models_have_exact_derivatives():
    from contin.problem import check_jacobian

    model = CO()
    chk = check_jacobian(model, np.array([0.05, 0.3, 0.45]), {**CO.PARAMS, "q2": 1.05}, parameters=model.parameter_names)
    assert chk.relative_error < 1e-7 and max(chk.dp_errors.values()) < 1e-7


def test_hopf_detection_is_on_by_default_for_large_n_with_a_mass_matrix():
    """detect_hopf=None at n = 400 unknowns: on when the problem states its dynamics (mass_matrix,
    here M = I), by shift-invert ARPACK (above HOPF_AUTO_MAX the auto mode is never dense); off
    without a mass matrix (M = I assumed only up to HOPF_AUTO_MAX unknowns)."""
    import scipy.sparse as sp

    from contin.hopf import hopf_test
    from contin.options import HOPF_AUTO_MAX

    class WithMass(Brusselator1D):
        def mass_matrix(self, u, p):
            return sp.identity(2 * self.n, format="csr")

    n = 200
    par = Brusselator1D.PARAMS
    model = WithMass(n)
    ref = [l for l in brusselator_hopf_reference(n, par) if l < 1.2]
    assert len(ref) == 2 and 2 * n > HOPF_AUTO_MAX
    test = hopf_test(model, DetectionOptions(), 2 * n)
    assert test is not None and test.dense_max == HOPF_AUTO_MAX
    assert hopf_test(Brusselator1D(n), DetectionOptions(), 2 * n) is None
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"l": (0.3, 1.2)}, detection=DetectionOptions())
    br = trace(model, model.trivial(par), par, "l", opts)
    hb = br.points("HB")
    assert [sp.params["l"] for sp in hb] == pytest.approx(ref, rel=1e-10)
    assert all(sp.converged for sp in hb)


@pytest.mark.parametrize("hi", [24.0, 470 / 19])
def test_beyond_a_bound_only_a_zero_on_the_bound_is_located(monkeypatch, hi):
    """Lorenz traced up to rho = hi with long steps: the last step ends at rho = 24.98, past the
    HB at 470/19.  On the bound 24 the HB, 0.74 beyond it (0.76 of the step), is not located at
    all (it was located, its l1 computed, and dropped: contin.continuation.NEAR_BOUND); a bound
    on the HB itself still reports it there (to 1e-12)."""
    import contin.continuation as cc
    from problems.demo import Lorenz as DemoLorenz

    brackets = []
    real = cc.locate_zero

    def spy(evaluate, sa, sb, **kw):
        brackets.append((float(sa.point.x[-1]), float(sb.point.x[-1])))
        return real(evaluate, sa, sb, **kw)

    monkeypatch.setattr(cc, "locate_zero", spy)
    p = {"sigma": 10.0, "beta": 8 / 3, "rho": 10.0}
    br = trace(DemoLorenz(), DemoLorenz.equilibrium(p), p, "rho",
               ContinuationOptions(step=StepOptions(ds=0.5, ds_max=4.0), bounds={"rho": (1.5, hi)}))
    assert br.params["rho"][-1] == hi
    if hi == 24.0:
        assert not br.points("HB") and brackets == []
    else:
        (hb,) = br.points("HB")
        assert hb.params["rho"] == pytest.approx(470 / 19, rel=1e-12) and hb.converged
        assert len(brackets) == 1 and brackets[0][0] == hi
