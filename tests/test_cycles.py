"""Periodic orbits from Hopf points (contin.collocation, contin.cycles, contin.floquet).

References are independent of the collocation: closed forms of the Stuart-Landau and Bautin
normal forms (radius, period, multiplier, fold of cycles), the collocation orders of de Boor &
Swartz (1973), and solve_ivp integrations / shooting of the ODE (orbit closure, period doubling).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from contin.branch import SpecialPoint
from contin.collocation import Mesh, lagrange_tables
from contin.continuation import trace
from contin.cycles import CycleOptions, CycleProblem, continue_cycles, first_orbit, hopf_start
from contin.newton import newton
from contin.options import ContinuationOptions
from contin.problem import check_jacobian
from tests.cycle_models import Bautin, StuartLandau

W = 2.0


def sl_hopf() -> SpecialPoint:
    """The HB of Stuart-Landau's trivial branch, located by contin (mu = 0, omega = w)."""
    b = trace(StuartLandau(), np.zeros(2), {"mu": -0.3, "w": W}, "mu", ContinuationOptions(bounds={"mu": (-1, 1)}))
    (hb,) = b.points("HB")
    return hb


def test_lagrange_tables_differentiate_polynomials_exactly():
    for ncol in (1, 2, 4, 7):
        z, w, L, D = lagrange_tables(ncol)
        s = np.arange(ncol + 1) / ncol
        assert math.isclose(w.sum(), 1.0, rel_tol=1e-14)
        for deg in range(ncol + 1):
            np.testing.assert_allclose(L @ s**deg, z**deg, atol=1e-13)
            np.testing.assert_allclose(D @ s**deg, deg * z ** max(deg - 1, 0) if deg else 0 * z, atol=1e-12)


def test_stuart_landau_branch_radius_period_multiplier():
    hb = sl_hopf()
    br = continue_cycles(StuartLandau(), hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.5)}, max_steps=80))
    assert br.kind == "periodic-orbits" and br.status == "EP" and len(br) > 5
    mu = br.parameter_values
    assert mu[0] > 0 and math.isclose(mu[-1], 0.5, rel_tol=1e-12)  # supercritical: cycles for mu > 0
    period = br.observables["period"]
    np.testing.assert_allclose(period, 2 * np.pi / W, rtol=1e-9)  # exact for every mu
    mesh = Mesh(2)
    for i in range(len(br)):
        nodes, _ = mesh.split(br.state(i))
        np.testing.assert_allclose(np.hypot(nodes[:, 0], nodes[:, 1]), math.sqrt(mu[i]), rtol=1e-7)
    # the only nontrivial multiplier: exp(-2 mu T) (the radial linearization -2 mu over one period)
    np.testing.assert_allclose(br.eigenvalues[:, 0].real, np.exp(-2 * mu * period), rtol=1e-7, atol=1e-12)
    assert np.all(br.observables["floquet_error"] < 1e-10)
    assert br.stable.all() and not br.n_unstable.any()
    l2 = br.observables["l2norm"]
    np.testing.assert_allclose(l2, np.sqrt(mu), rtol=1e-7)  # |u| = sqrt(mu) all along the orbit


def test_start_follows_the_normal_form():
    """The first orbit at amplitude eps = 2 |z| sits at mu = r^2 = eps^2 / 2 (l1 = -2 / w)."""
    eps = 0.05
    hb = sl_hopf()
    start = hopf_start(StuartLandau(), hb, "mu")
    assert math.isclose(start.dlambda, 1.0, rel_tol=1e-6)  # lambda = mu + i w
    _, predicted, _ = first_orbit(start, Mesh(2), "mu", eps)
    assert math.isclose(predicted, eps**2 / 2, rel_tol=1e-6)  # the prediction, before any Newton step
    br = continue_cycles(StuartLandau(), hb, "mu", ContinuationOptions(max_steps=1), CycleOptions(amplitude=eps))
    assert math.isclose(br.parameter_values[0], eps**2 / 2, rel_tol=1e-7)
    assert math.isclose(br.observables["period"][0], np.pi, rel_tol=1e-10)


@pytest.mark.parametrize("ncol", [2, 3, 4])
def test_collocation_orders(ncol):
    """Error of the Stuart-Landau orbit at mu = 1/2: O(h^{2 NCOL}) at the mesh points and in T
    (superconvergence), O(h^{NCOL + 1}) uniformly (de Boor & Swartz 1973)."""
    p = {"mu": 0.5, "w": W}
    r = math.sqrt(0.5)
    errs = []
    for ntst in (8, 16):
        mesh = Mesh(2, ntst, ncol)
        t = mesh.node_times
        guess = 0.9 * np.c_[np.cos(2 * np.pi * t), np.sin(2 * np.pi * t)]
        cp = CycleProblem(StuartLandau(), mesh, guess)
        res = newton(cp, mesh.pack(guess, 3.0), p)
        assert res.converged
        nodes, period = mesh.split(res.u)
        ph = math.atan2(nodes[0, 1], nodes[0, 0])
        exact = lambda s: r * np.c_[np.cos(2 * np.pi * s + ph), np.sin(2 * np.pi * s + ph)]  # noqa: E731
        e_mesh = np.abs(mesh.evaluate(nodes, mesh.t[:-1]) - exact(mesh.t[:-1])).max()
        tt = np.linspace(0, 1, 2001)
        e_uniform = np.abs(mesh.evaluate(nodes, tt) - exact(tt)).max()
        errs.append((e_mesh, abs(period - np.pi), e_uniform))
    (m1, p1, u1), (m2, p2, u2) = errs
    assert math.log2(m1 / m2) == pytest.approx(2 * ncol, abs=0.3)
    assert math.log2(p1 / p2) == pytest.approx(2 * ncol, abs=0.3)
    assert math.log2(u1 / u2) == pytest.approx(ncol + 1, abs=0.4)


def test_collocation_jacobian_is_exact():
    """Against central differences, on an orbit off the solution (all blocks nonzero)."""
    mesh = Mesh(2, 6, 3)
    t = mesh.node_times
    ref = np.c_[np.cos(2 * np.pi * t) + 0.3 * np.sin(4 * np.pi * t), 0.7 * np.sin(2 * np.pi * t)]
    cp = CycleProblem(Bautin(), mesh, ref)
    x = mesh.pack(ref * 1.1, 2.5)
    chk = check_jacobian(cp, x, {"mu": 0.1, "b": 0.8, "w": 1.3}, parameters=("mu", "b"))
    assert chk.relative_error < 1e-7
    assert max(chk.dp_errors.values()) < 1e-7


def _hopf_of(problem, u0, params, parameter, bounds):
    b = trace(problem, u0, params, parameter, ContinuationOptions(bounds={parameter: bounds}))
    return b.points("HB")[0]


def test_bautin_fold_of_cycles():
    """r' = r (mu + b r^2 - r^4): the subcritical cycles turn at mu = -b^2/4, r^2 = b/2 (LPC);
    multiplier exp(T (2 b r^2 - 4 r^4)) along the branch; unstable before the fold, stable after."""
    bb, w = 1.0, 1.0
    hb = _hopf_of(Bautin(), np.zeros(2), {"mu": -0.3, "b": bb, "w": w}, "mu", (-1, 1))
    assert hb.data["l1"] > 0  # subcritical
    br = continue_cycles(Bautin(), hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.3)}, max_steps=200))
    (lpc,) = br.points("LPC")
    assert lpc.converged and "fold of cycles" in lpc.note
    assert abs(lpc.params["mu"] + bb**2 / 4) < 1e-8
    nodes, period = Mesh(2).split(lpc.state)
    np.testing.assert_allclose(nodes[:, 0] ** 2 + nodes[:, 1] ** 2, bb / 2, rtol=1e-7)
    assert math.isclose(period, 2 * math.pi / w, rel_tol=1e-9)
    r2 = br.observables["l2norm"] ** 2  # |u| is constant on these circles
    exponent = br.observables["period"] * (2 * bb * r2 - 4 * r2**2)  # log of the multiplier (down to 1e-10)
    np.testing.assert_allclose(np.log(br.eigenvalues[:, 0].real), exponent, rtol=1e-6, atol=1e-9)
    small = r2 < bb / 2
    assert not br.stable[small].any() and br.stable[~small].all()


def test_period_doubling_of_roessler_against_shooting():
    """Roessler (b = 2, c = 4): the cycle born at the HB near a = 0.125 doubles its period near
    a = 0.335; reference: the a where a multiplier of the orbit is -1, by shooting with solve_ivp
    (periodic orbit by fsolve on the flow map, monodromy from the variational equation)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq, fsolve

    from tests.cycle_models import Roessler

    b, c = 2.0, 4.0

    def rhs(t, v, a):
        x, y, z = v[:3]
        out = np.empty_like(v)
        out[:3] = [-y - z, x + a * y, b + z * (x - c)]
        if v.size > 3:
            out[3:] = (np.array([[0, -1, -1], [1, a, 0], [z, 0, x - c]]) @ v[3:].reshape(3, 3)).ravel()
        return out

    def flow(u0, period, a, var=False):
        v0 = np.concatenate([u0, np.eye(3).ravel()]) if var else u0
        return solve_ivp(rhs, (0, period), v0, args=(a,), method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]

    # an initial orbit: the attractor at a = 0.33 (a stable cycle), cut at y = 0, y' > 0
    s = solve_ivp(rhs, (0, 300), np.array([1.0, 1.0, 0.0]), args=(0.33,), rtol=1e-10, atol=1e-10, dense_output=True)
    ts = np.linspace(250, 300, 20001)
    ys = s.sol(ts)
    up = np.flatnonzero((ys[1, :-1] < 0) & (ys[1, 1:] >= 0))
    guess = [np.array([ys[0, up[0]], ys[2, up[0]], ts[up[1]] - ts[up[0]]])]

    def pd(a):
        def g(v):
            u0 = np.array([v[0], 0.0, v[1]])
            return flow(u0, v[2], a) - u0

        guess[0] = fsolve(g, guess[0], xtol=1e-13)
        u0 = np.array([guess[0][0], 0.0, guess[0][1]])
        mu = np.linalg.eigvals(flow(u0, guess[0][2], a, var=True)[3:].reshape(3, 3))
        return float(mu[np.argmin(mu.real)].real) + 1.0

    reference = brentq(pd, 0.32, 0.345, xtol=1e-13)

    a0 = 0.05
    z0 = (c - math.sqrt(c * c - 4 * a0 * b)) / (2 * a0)
    hb = _hopf_of(Roessler(), np.array([a0 * z0, -z0, z0]), {"a": a0, "b": b, "c": c}, "a", (0.01, 0.6))
    br = continue_cycles(Roessler(), hb, "a", ContinuationOptions(bounds={"a": (0.0, 0.6)}, max_steps=300))
    (pdp,) = br.points("PD")
    assert pdp.converged and "period doubling" in pdp.note
    assert abs(pdp.params["a"] - reference) < 1e-8
    assert math.isclose(pdp.data["multiplier"], -1.0, abs_tol=1e-9)
    before = br.parameter_values < pdp.params["a"]
    assert br.stable[before].all() and not br.stable[~before].any()


def test_neimark_sacker_of_a_driven_pair():
    """The driven oscillator's multipliers exp((alpha - k mu) T +- i w2 T) leave the unit circle at
    mu = alpha / k with angle w2 T (closed form, tests/cycle_models.DrivenPair)."""
    from tests.cycle_models import DrivenPair

    p = {"mu": -0.3, "w": W, "alpha": 0.2, "k": 1.0, "w2": 0.7}
    hb = _hopf_of(DrivenPair(), np.zeros(4), p, "mu", (-1, 1))
    br = continue_cycles(DrivenPair(), hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.5)}, max_steps=100))
    (ns,) = br.points("NS")
    assert ns.converged and abs(ns.params["mu"] - 0.2) < 1e-9
    assert math.isclose(ns.data["theta"], p["w2"] * 2 * math.pi / W, abs_tol=1e-8)  # w2 T < pi here
    mu, period = br.parameter_values, br.observables["period"]
    pair = br.eigenvalues[:, :2]
    expected = np.exp((p["alpha"] - p["k"] * mu) * period)
    np.testing.assert_allclose(np.abs(pair), np.c_[expected, expected], rtol=1e-7)
    assert list(br.n_unstable) == [2 if m < 0.2 else 0 for m in mu]


AB_PARAMS = {"D": 0.0, "B": 14.0, "beta": 3.0}


def ab_hopf() -> SpecialPoint:
    """HB1 of AUTO's demo ab, traced as the scene ``ab`` does (u = 0 at D = 0, in D)."""
    from contin.options import StepOptions
    from problems.demo import AB

    opts = ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=2000, step=StepOptions(ds=0.01, ds_max=0.05))
    return trace(AB(), np.zeros(2), AB_PARAMS, "D", opts).points("HB")[0]


def test_ab_period_at_the_hopf_point_and_orbit_closure():
    """AUTO demo ab, cycles from HB1: the period tends to 2 pi / omega at the HB (omega from a scipy
    solve of F = 0, tr J = 0, det J = omega^2), and an orbit integrated by solve_ivp from its first
    node for one period closes, and passes through the collocation nodes, to 1e-6."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import fsolve

    from problems.demo import AB

    pr = AB()

    def hopf(v):
        u, d = v[:2], v[2]
        q = {**AB_PARAMS, "D": d}
        return [*pr.residual(u, q), np.trace(pr.jacobian(u, q).toarray())]

    hb = ab_hopf()
    sol = fsolve(hopf, [*hb.state, hb.params["D"]], xtol=1e-14)
    omega = math.sqrt(np.linalg.det(pr.jacobian(sol[:2], {**AB_PARAMS, "D": sol[2]}).toarray()))
    small = continue_cycles(pr, hb, "D", ContinuationOptions(max_steps=1), CycleOptions(amplitude=1e-4))
    assert math.isclose(small.observables["period"][0], 2 * math.pi / omega, rel_tol=1e-6)

    br = continue_cycles(pr, hb, "D", ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=12))
    assert br.parent == "HB1" and len(br) == 13
    assert np.all(br.parameter_values < hb.params["D"])  # subcritical (l1 > 0): cycles below D_H
    assert np.all(np.diff(br.observables["amplitude"]) > 0)
    i = 10
    mesh = Mesh(2)
    nodes, period = mesh.split(br.state(i))
    q = {k: float(v[i]) for k, v in br.params.items()}
    run = solve_ivp(lambda t, u: pr.residual(u, q), (0, period), nodes[0], method="DOP853", rtol=1e-12,
                    atol=1e-12, t_eval=mesh.node_times * period)
    err = np.abs(run.y.T - nodes)
    assert err[::4].max() < 1e-6  # the mesh points (superconvergent, O(h^8))
    assert err.max() < 1e-4  # every node (O(h^5) inside the intervals)
    end = solve_ivp(lambda t, u: pr.residual(u, q), (0, period), nodes[0], method="DOP853", rtol=1e-12, atol=1e-12)
    assert np.abs(end.y[:, -1] - nodes[0]).max() < 1e-6
    assert not br.stable.any()  # the subcritical branch before its fold: one multiplier > 1
    assert np.all(br.eigenvalues[1:, 0].real > 1)


def test_under_resolved_orbits_end_the_branch():
    """Past the fold of demo ab the orbits sharpen into relaxation oscillations that NTST = 20
    does not resolve: the branch ends with MX naming the flow residual and a finer NTST instead of
    going on with wrong orbits; with the guard off (floquet_tol None) a warning names them."""
    from problems.demo import AB

    hb = ab_hopf()
    opts = ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=60)
    br = continue_cycles(AB(), hb, "D", opts)
    assert br.status == "MX" and "under-resolved" in br.message and "NTST = 40" in br.message
    assert np.all(br.observables["flow_error"] <= 1e-4)
    off = continue_cycles(AB(), hb, "D", dataclasses.replace(opts, max_steps=25), CycleOptions(floquet_tol=None))
    assert off.observables["flow_error"].max() > 1e-4
    assert any(line.startswith("warning: Floquet multipliers doubtful") for line in off.audit)
