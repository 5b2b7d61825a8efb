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
from contin.cycles import CycleOptions, CycleProblem, continue_cycles, first_orbit, hopf_start, orbit_of
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
    for i in range(len(br)):
        _, nodes, _ = orbit_of(br.state(i), 2)
        np.testing.assert_allclose(np.hypot(nodes[:, 0], nodes[:, 1]), math.sqrt(mu[i]), rtol=1e-7)
    # the only nontrivial multiplier: exp(-2 mu T) (the radial linearization -2 mu over one period)
    np.testing.assert_allclose(br.eigenvalues[:, 0].real, np.exp(-2 * mu * period), rtol=1e-7, atol=1e-12)
    assert np.all(br.observables["floquet_error"] < 1e-10)
    assert br.stable.all() and not br.n_unstable.any()
    l2 = br.observables["l2norm"]
    np.testing.assert_allclose(l2, np.sqrt(mu), rtol=1e-7)  # |u| = sqrt(mu) all along the orbit
    mesh, nodes, period = orbit_of(br.state(-1), 2)
    t, u = CycleProblem(StuartLandau(), mesh, nodes).orbit(mesh.pack(nodes, period), samples=50)
    assert t.shape == (50,) and np.allclose(np.hypot(u[:, 0], u[:, 1]), math.sqrt(mu[-1]), rtol=1e-6)


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
    assert not br.points("BP")  # the fold of cycles is no branch point of cycles (the BP test keeps its sign)
    assert abs(lpc.params["mu"] + bb**2 / 4) < 1e-8
    _, nodes, period = orbit_of(lpc.state, 2)
    np.testing.assert_allclose(nodes[:, 0] ** 2 + nodes[:, 1] ** 2, bb / 2, rtol=1e-7)
    assert math.isclose(period, 2 * math.pi / w, rel_tol=1e-9)
    r2 = br.observables["l2norm"] ** 2  # |u| is constant on these circles
    exponent = br.observables["period"] * (2 * bb * r2 - 4 * r2**2)  # log of the multiplier (down to 1e-10)
    np.testing.assert_allclose(np.log(br.eigenvalues[:, 0].real), exponent, rtol=1e-6, atol=1e-9)
    small = r2 < bb / 2
    assert not br.stable[small].any() and br.stable[~small].all()


ROESSLER_B, ROESSLER_C = 2.0, 4.0


def roessler_pd_by_shooting(a_attractor: float, lo: float, hi: float, loops: int) -> float:
    """The a in (lo, hi) where the Roessler orbit (b = 2, c = 4) of ``loops`` turns has a Floquet
    multiplier -1, by shooting with solve_ivp: the orbit by fsolve on the flow map from the
    section y = 0 (start: the attractor at ``a_attractor``, a stable orbit), its monodromy from
    the variational equation, brentq on the multiplier + 1.  Independent of the collocation."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq, fsolve

    b, c = ROESSLER_B, ROESSLER_C

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

    s = solve_ivp(rhs, (0, 600), np.array([1.0, 1.0, 0.0]), args=(a_attractor,), rtol=1e-10, atol=1e-10,
                  dense_output=True)
    ts = np.linspace(500, 600, 40001)
    ys = s.sol(ts)
    up = np.flatnonzero((ys[1, :-1] < 0) & (ys[1, 1:] >= 0))  # y = 0, y' > 0
    guess = [np.array([ys[0, up[0]], ys[2, up[0]], ts[up[loops]] - ts[up[0]]])]

    def pd(a):
        def g(v):
            u0 = np.array([v[0], 0.0, v[1]])
            return flow(u0, v[2], a) - u0

        guess[0] = fsolve(g, guess[0], xtol=1e-13)
        u0 = np.array([guess[0][0], 0.0, guess[0][1]])
        mu = np.linalg.eigvals(flow(u0, guess[0][2], a, var=True)[3:].reshape(3, 3))
        return float(mu[np.argmin(mu.real)].real) + 1.0

    return brentq(pd, lo, hi, xtol=1e-13)


@pytest.fixture(scope="module")
def roessler_cycles():
    """The Roessler cycles from the HB near a = 0.125, to a = 0.6."""
    from tests.cycle_models import Roessler

    a0, b, c = 0.05, ROESSLER_B, ROESSLER_C
    z0 = (c - math.sqrt(c * c - 4 * a0 * b)) / (2 * a0)
    hb = _hopf_of(Roessler(), np.array([a0 * z0, -z0, z0]), {"a": a0, "b": b, "c": c}, "a", (0.01, 0.6))
    return continue_cycles(Roessler(), hb, "a", ContinuationOptions(bounds={"a": (0.0, 0.6)}, max_steps=300))


def test_period_doubling_of_roessler_against_shooting(roessler_cycles):
    """Roessler (b = 2, c = 4): the cycle born at the HB near a = 0.125 doubles its period near
    a = 0.335 (reference: shooting, :func:`roessler_pd_by_shooting`)."""
    reference = roessler_pd_by_shooting(0.33, 0.32, 0.345, loops=1)
    br = roessler_cycles
    (pdp,) = br.points("PD")
    assert pdp.converged and "period doubling" in pdp.note
    assert not br.points("BP")  # a multiplier through -1 is no branch point of cycles
    assert abs(pdp.params["a"] - reference) < 1e-8
    assert math.isclose(pdp.data["multiplier"], -1.0, abs_tol=1e-9)
    before = br.parameter_values < pdp.params["a"]
    assert br.stable[before].all() and not br.stable[~before].any()


def test_period_doubled_branch_and_its_own_doubling(roessler_cycles):
    """From PD1 the period-doubled orbits (two turns, period 2 T at the PD): stable, closing after
    2 T but not after T (solve_ivp), and doubling again near a = 0.3748 (the period-4 onset; reference:
    shooting on the two-turn orbit)."""
    from scipy.integrate import solve_ivp

    from contin.cycles import continue_doubled
    from tests.cycle_models import Roessler

    pd1 = roessler_cycles.points("PD")[0]
    br = continue_doubled(Roessler(), pd1, "a", 3, ContinuationOptions(bounds={"a": (0.0, 0.6)}, max_steps=60),
                          CycleOptions(ntst=40))
    assert br.kind == "periodic-orbits" and br.parent == pd1.name
    assert math.isclose(br.observables["period"][0], 2 * pd1.data["period"], rel_tol=1e-3)
    (pd2,) = br.points("PD")
    assert not br.points("BP")
    reference = roessler_pd_by_shooting(0.37, 0.37, 0.38, loops=2)
    assert abs(pd2.params["a"] - reference) < 1e-8
    assert math.isclose(pd2.data["period"], 2 * pd1.data["period"], rel_tol=0.01)
    i = int(np.flatnonzero(br.parameter_values > 0.36)[0])
    mesh, nodes, period = orbit_of(br.state(i), 3)
    q = {k: float(v[i]) for k, v in br.params.items()}
    run = solve_ivp(lambda t, u: Roessler().residual(u, q), (0, period), nodes[0], method="DOP853", rtol=1e-12,
                    atol=1e-12, t_eval=[period / 2, period])
    assert np.abs(run.y[:, 1] - nodes[0]).max() < 1e-5  # closes after two turns
    assert np.abs(run.y[:, 0] - nodes[0]).max() > 0.1  # not after one
    before = br.parameter_values < pd2.params["a"]
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
    assert not br.points("BP")
    assert math.isclose(ns.data["theta"], p["w2"] * 2 * math.pi / W, abs_tol=1e-8)  # w2 T < pi here
    mu, period = br.parameter_values, br.observables["period"]
    pair = br.eigenvalues[:, :2]
    expected = np.exp((p["alpha"] - p["k"] * mu) * period)
    np.testing.assert_allclose(np.abs(pair), np.c_[expected, expected], rtol=1e-7)
    assert list(br.n_unstable) == [2 if m < 0.2 else 0 for m in mu]


def test_period_doubling_where_a_complex_pair_turns_real_within_one_step():
    """MoebiusPair (a = 0.05, b = -0.01, g = 1): the w-multipliers -exp(2 pi (b +- sqrt(mu - a^2)))
    are a complex pair up to mu = a^2 = 0.0025 and a real pair after, whose outer member passes -1
    at mu = a^2 + b^2 = 0.0026.  The step 7.3e-4 -> 2.9e-3 spans both: no real negative multiplier
    at its start to track, so the PD was missed (exit 0, no PD); the sign of prod (mu + 1) locates it."""
    from contin.options import StepOptions
    from tests.cycle_models import MoebiusPair

    a, b = 0.05, -0.01
    hb = _hopf_of(MoebiusPair(), np.zeros(4), {"mu": -0.3, "a": a, "b": b, "g": 1.0}, "mu", (-1, 1))
    opts = ContinuationOptions(bounds={"mu": (-1, 0.05)}, max_steps=300, step=StepOptions(ds=0.01, ds_max=0.05))
    br = continue_cycles(MoebiusPair(), hb, "mu", opts)
    assert [s.type for s in br.special_points] == ["PD", "EP"]
    (pdp,) = br.points("PD")
    assert pdp.converged and "period doubling" in pdp.note
    assert abs(pdp.params["mu"] - (a * a + b * b)) < 1e-9  # measured 1.5e-13
    assert math.isclose(pdp.data["multiplier"], -1.0, abs_tol=1e-9)
    assert pdp.bracket[0] < a * a < pdp.bracket[1]  # the pair was complex at the start of the step
    mu = br.parameter_values
    root = np.sqrt((mu - a * a).astype(complex))
    expected = np.c_[-np.exp(2 * np.pi * (b + root)), -np.exp(2 * np.pi * (b - root)), np.exp(-4 * np.pi * mu)]
    np.testing.assert_allclose(-np.sort(-np.abs(br.eigenvalues), axis=1), -np.sort(-np.abs(expected), axis=1),
                               rtol=1e-8, atol=1e-12)


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
    mesh, nodes, period = orbit_of(br.state(i), 2)
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
    """Past the fold of demo ab the orbits sharpen into relaxation oscillations that a uniform mesh
    of NTST = 20 does not resolve: the branch ends with MX naming the flow residual and a finer NTST
    instead of going on with wrong orbits; with the guard off (floquet_tol None) a warning names them."""
    from problems.demo import AB

    hb = ab_hopf()
    opts = ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=60)
    br = continue_cycles(AB(), hb, "D", opts, CycleOptions(adapt_mesh=False))
    assert br.status == "MX" and "under-resolved" in br.message and "NTST = 40" in br.message
    assert np.all(br.observables["flow_error"] <= 1e-4)
    off = continue_cycles(AB(), hb, "D", dataclasses.replace(opts, max_steps=25),
                          CycleOptions(floquet_tol=None, adapt_mesh=False))
    assert off.observables["flow_error"].max() > 1e-4
    assert any(line.startswith("warning: Floquet multipliers doubtful") for line in off.audit)


def test_adapted_mesh_follows_ab_past_its_fold():
    """With the mesh equidistributed every 5 steps (default) NTST = 20 follows demo ab's orbits past
    the fold onto the stable relaxation oscillations: the period of each stable orbit equals the
    period of the attractor integrated by solve_ivp (successive crossings of a section, independent
    of the collocation), and the LPC agrees with a uniform mesh four times finer."""
    from scipy.integrate import solve_ivp

    from problems.demo import AB

    pr = AB()
    hb = ab_hopf()
    opts = ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=40)
    br = continue_cycles(pr, hb, "D", opts)
    assert br.status == "EP" and br.message == "maximum number of steps (40) reached"
    (lpc,) = br.points("LPC")
    uniform = continue_cycles(pr, hb, "D", opts, CycleOptions(ntst=80, adapt_mesh=False))
    assert abs(lpc.params["D"] - uniform.points("LPC")[0].params["D"]) < 5e-9  # measured 1.3e-9
    after = np.arange(len(br)) > lpc.index
    assert br.stable[after].all() and not br.stable[~after].any()
    assert br.parameter_values[-1] > 0.17  # far past the fold (D_LPC = 0.1617), period 4.1 from 7.4
    checked = 0
    for i in np.flatnonzero(after)[::6]:
        mesh, nodes, period = orbit_of(br.state(i), 2)
        assert mesh.h.max() / mesh.h.min() > 3  # adapted, not uniform
        q = {k: float(v[i]) for k, v in br.params.items()}

        def section(t, u, u0=nodes[0, 0]):
            return u[0] - u0

        section.direction = float(np.sign(pr.residual(nodes[0], q)[0]))
        run = solve_ivp(lambda t, u: pr.residual(u, q), (0, 20 * period), nodes[0], method="DOP853",
                        rtol=1e-12, atol=1e-12, events=section)
        crossings = run.t_events[0]
        assert math.isclose(period, (crossings[-1] - crossings[-6]) / 5, rel_tol=1e-5)  # measured 4e-6 .. 5e-8
        checked += 1
    assert checked >= 3


# --- command line --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ab_file(tmp_path_factory):
    from click.testing import CliRunner

    from contin.cli import main

    path = tmp_path_factory.mktemp("cycles") / "ab.h5"
    r = CliRunner().invoke(main, ["trace", "ab", "-q", "-o", str(path)])
    assert r.exit_code == 0, r.output
    return path


def _cli(*args):
    from click.testing import CliRunner

    from contin.cli import main

    return CliRunner().invoke(main, [str(a) for a in args])


def test_cli_cycles_end_to_end(ab_file, tmp_path):
    """trace ab -> continue --from HB1 --cycles (past the fold, on adapted meshes) -> info, diagram;
    the file holds the branch continue_cycles computes with the run's step options; with
    --uniform-mesh the sharpening orbits end the branch: MX, exit 3, said so."""
    from contin import io
    from contin.options import StepOptions
    from problems.demo import AB

    out = tmp_path / "cyc.h5"
    r = _cli("continue", ab_file, "--from", "HB1", "--cycles", "--max-steps", "40", "-o", out)
    assert r.exit_code == 0, r.output
    (br,), meta = io.load(out)
    assert br.kind == "periodic-orbits" and br.parent == "HB1" and meta["diagram_y"] == "amplitude"
    assert meta["extra"]["cycles"] == {"ntst": 20, "ncol": 4, "n": 2, "adapt_mesh": True}
    (lpc,) = br.points("LPC")
    api = continue_cycles(AB(), ab_hopf(), "D", ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=40,
                                                                     step=StepOptions(ds=0.01, ds_max=0.05)))
    assert lpc.params["D"] == api.points("LPC")[0].params["D"]  # the run's steps (ds 0.01 .. 0.05): the same branch
    np.testing.assert_array_equal(br.states, api.states)
    coarse = _cli("continue", ab_file, "--from", "HB1", "--cycles", "--uniform-mesh", "--max-steps", "40")
    assert coarse.exit_code == 3, coarse.output
    assert "warning: the branch of periodic orbits ended with MX: under-resolved" in coarse.output
    assert br.eigenvalues.shape == (len(br), 1) and br.stable[-1] and not br.stable[0]
    info = _cli("info", out)
    assert info.exit_code == 0 and "periodic-orbits" in info.output and "LPC" in info.output
    # from an orbit file only a PD or BP (--cycles) or an LPC (--free: tests/test_lpc_curve.py)
    # continues: `--from HB2 --free B` / `--from HB2 --cycles` of a complete ab orbit file ended
    # 'Error: too many values to unpack (expected 2)' (an orbit's state read as an equilibrium's);
    # verify blamed the equilibrium's missing grid hooks
    for args in (["--from", br.special_points[-1].name, "--free", "B"], ["--from", "LPC1", "--cycles"]):
        r = _cli("continue", out, *args)
        errors = [ln for ln in r.output.splitlines() if ln.startswith("Error:")]
        assert r.exit_code == 1 and len(errors) == 1 and f"{args[1]} is on branch 0 of periodic orbits" in errors[0], \
            r.output
    v = _cli("verify", out)
    assert v.exit_code == 1 and "holds periodic orbits: contin verify re-solves steady states" in v.output
    assert f"Floquet multipliers of branch 0: outside the unit circle 0..1, stable at {int(br.stable.sum())} " \
           f"of {len(br)} points" in info.output and "kx=" not in info.output
    for y in ("amplitude", "period"):
        d = _cli("diagram", out, "-y", y, "-o", tmp_path / f"{y}.png")
        assert d.exit_code == 0, d.output
        assert (tmp_path / f"{y}.png").stat().st_size > 1000


@pytest.mark.parametrize("args, says", [
    (["--from", "EP3", "--cycles"], "or a period doubling (PD) or branch point (BP) of orbits; EP3 is none of these"),
    (["--from", "HB1", "--cycles", "--free", "B"], "--free B is for two-parameter curves"),
    (["--from", "HB1", "--ntst", "30", "--free", "B"], "--ntst needs --cycles"),
    (["--from", "HB1", "--uniform-mesh", "--free", "B"], "--uniform-mesh needs --cycles"),
    (["--from", "HB1"], "Missing option '--free'"),
    (["--from", "HB1", "--cycles", "--amplitude", "nan"], "--amplitude must be a finite number > 0"),
    (["--from", "HB1", "--cycles", "--bounds", "B=0:1"], "with --cycles only the branch's parameter 'D'"),
])
def test_cli_cycles_bad_input(ab_file, args, says):
    r = _cli("continue", ab_file, *args)
    assert r.exit_code not in (0, 3) and "Traceback" not in r.output
    errors = [line for line in r.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and says in errors[0], r.output


def test_cli_cycles_file_refused_by_steady_state_commands(ab_file, tmp_path):
    """stability reads a branch's states as steady states: for orbits it said 'too many values to
    unpack'.  (export --auto writes orbits in AUTO's periodic layout: tests/test_autoorbits.py.)"""
    out = tmp_path / "cyc.h5"
    assert _cli("continue", ab_file, "--from", "HB1", "--cycles", "--max-steps", "3", "-o", out).exit_code == 0
    r = _cli("stability", out, "--point", "1")
    assert r.exit_code == 1 and "holds periodic orbits" in r.output.splitlines()[-1]


def test_segments_with_a_new_phase_reference_join_into_one_branch():
    """Renewing the phase reference every 3 steps (segments) gives the branch of every 20 steps:
    the same LPC, one EP at the end, special points indexed between their bracketing points."""
    hb = _hopf_of(Bautin(), np.zeros(2), {"mu": -0.3, "b": 1.0, "w": 1.0}, "mu", (-1, 1))
    opts = ContinuationOptions(bounds={"mu": (-1, 0.3)}, max_steps=200)
    one = continue_cycles(Bautin(), hb, "mu", opts)
    many = continue_cycles(Bautin(), hb, "mu", opts, CycleOptions(rephase_every=3))
    assert [s.type for s in many.special_points] == ["LPC", "EP"] == [s.type for s in one.special_points]
    assert many.points("LPC")[0].params["mu"] == pytest.approx(-0.25, abs=1e-10)
    lpc = many.points("LPC")[0]
    mu = many.parameter_values
    r2 = many.observables["l2norm"] ** 2
    assert r2[lpc.index] < 0.5 < r2[lpc.index + 1]  # the fold (r^2 = b/2) between its neighbours
    assert many.special_points[-1].index == len(many) - 1 and mu[-1] == pytest.approx(0.3, abs=1e-14)
    assert np.all(many.ds[1:] > 0) and many.status == "EP" and "reached bound" in many.message
    # the orbits of every segment are the cycles
    assert np.abs(mu + r2 - r2**2).max() < 1e-7  # on the cycles: mu + b r^2 - r^4 = 0 (b = 1)


def test_mesh_adaptation_equidistributes_a_steep_front():
    """u = tanh(20 sin 2 pi t): three adaptations cut the interpolation error of NTST = 20 by more
    than 30 (the mesh gathers at the fronts t = 0, 1/2), and a sine keeps a near-uniform mesh."""
    mesh = Mesh(1, 20, 4)
    f = lambda t: np.tanh(20 * np.sin(2 * np.pi * t))  # noqa: E731
    tt = np.linspace(0, 1, 4001)

    def error(m):
        return np.abs(m.evaluate(f(m.node_times)[:, None], tt)[:, 0] - f(tt)).max()

    adapted = mesh
    for _ in range(3):
        adapted = adapted.adapted(f(adapted.node_times)[:, None])
    assert error(adapted) < error(mesh) / 30
    assert adapted.h[0] < 0.3 * adapted.h[5] and adapted.h[10] < 0.3 * adapted.h[15]
    smooth = mesh.adapted(np.sin(2 * np.pi * mesh.node_times)[:, None])
    assert smooth.h.max() / smooth.h.min() < 1.6


def test_branch_ends_where_the_orbits_shrink_to_the_other_hopf_point():
    """mu = p (1 - p): the cycles r^2 = p (1 - p) born at p = 0 shrink to the Hopf point p = 1; the
    branch ends there (HB, EP) instead of coming back over itself through amplitude 0 (it went on to
    p = 0 and back with spurious folds of cycles at both Hopf points, exit 0)."""
    from tests.cycle_models import TwoHopfLandau

    hb = _hopf_of(TwoHopfLandau(), np.zeros(2), {"p": -0.3, "w": W}, "p", (-1, 0.5))
    br = continue_cycles(TwoHopfLandau(), hb, "p", ContinuationOptions(bounds={"p": (-1, 2)}, max_steps=300))
    assert [s.type for s in br.special_points] == ["HB", "EP"]
    (end,) = br.points("HB")
    assert abs(end.params["p"] - 1.0) < 1e-8 and "shrink" in br.message and br.status == "EP"
    assert end.converged and "did not converge" not in end.note
    assert math.isclose(end.data["period"], 2 * math.pi / W, rel_tol=1e-9)
    p = br.parameter_values
    assert np.all(np.diff(p[:-1]) > 0) and len(br) < 300
    np.testing.assert_allclose(br.observables["l2norm"][:-1] ** 2, p[:-1] * (1 - p[:-1]), rtol=1e-7, atol=1e-12)


def test_ab_cycles_from_hb1_end_at_hb2():
    """Demo ab: the orbits born at HB1 (subcritical) turn at the LPC, become the stable relaxation
    oscillations and shrink to HB2 (supercritical), where the branch ends; HB2 equals the
    equilibrium branch's HB2 (located by contin's Hopf test on the steady states)."""
    from contin.options import StepOptions
    from problems.demo import AB

    opts = ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=2000, step=StepOptions(ds=0.01, ds_max=0.05))
    hb1, hb2 = trace(AB(), np.zeros(2), AB_PARAMS, "D", opts).points("HB")
    br = continue_cycles(AB(), hb1, "D", ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=300))
    assert [s.type for s in br.special_points] == ["LPC", "HB", "EP"]
    end = br.points("HB")[0]
    assert abs(end.params["D"] - hb2.params["D"]) < 1e-9
    assert math.isclose(end.data["omega"], hb2.data["omega"], rel_tol=1e-9)


class _SlowLandau(StuartLandau):
    """M u' = F with M = c I (c = 2.5): the Stuart-Landau orbits, time slowed by c."""

    C = 2.5

    def mass_matrix(self, u, p):
        import scipy.sparse as sp

        return self.C * sp.identity(2, format="csr")


def test_period_doubled_start_takes_the_problems_mass_matrix(roessler_cycles):
    """continue_doubled without ``mass`` (as `contin continue ORBITS --from PD1 --cycles` calls it)
    took M = I for a problem with M = c I: its orbits are Roessler's slowed by c, so the period-
    doubled orbits start at period 2 c T_PD.  The PD point of the slowed problem is Roessler's with
    the period c T (the same multipliers: time is only rescaled)."""
    import dataclasses

    import scipy.sparse as sp

    from contin.cycles import continue_doubled
    from tests.cycle_models import Roessler

    class SlowRoessler(Roessler):
        C = 2.5

        def mass_matrix(self, u, p):
            return self.C * sp.identity(3, format="csr")

    pd1 = roessler_cycles.points("PD")[0]
    mesh, nodes, period = orbit_of(pd1.state, 3)
    slow_pd = dataclasses.replace(pd1, state=np.concatenate([mesh.pack(nodes, SlowRoessler.C * period),
                                                             pd1.state[mesh.pack(nodes, period).size:]]))
    assert orbit_of(slow_pd.state, 3)[2] == SlowRoessler.C * period
    br = continue_doubled(SlowRoessler(), slow_pd, "a", 3, ContinuationOptions(bounds={"a": (0.0, 0.6)}, max_steps=3),
                          CycleOptions(ntst=40))
    assert math.isclose(br.observables["period"][0], 2 * SlowRoessler.C * period, rel_tol=1e-3)
    assert np.all(br.observables["flow_error"] < 1e-6)


def test_mass_matrix_scales_time():
    """With M = c I the cycles are Stuart-Landau's with period c 2 pi / w and multiplier
    exp(-2 mu T / c) (the Hopf start, collocation and Floquet all use M)."""
    pr = _SlowLandau()
    hb = _hopf_of(pr, np.zeros(2), {"mu": -0.3, "w": W}, "mu", (-1, 1))
    assert math.isclose(hb.data["omega"], W / pr.C, rel_tol=1e-9)
    br = continue_cycles(pr, hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.5)}, max_steps=40))
    mu, period = br.parameter_values, br.observables["period"]
    np.testing.assert_allclose(period, pr.C * 2 * np.pi / W, rtol=1e-9)
    np.testing.assert_allclose(br.observables["l2norm"], np.sqrt(mu), rtol=1e-7)
    np.testing.assert_allclose(br.eigenvalues[:, 0].real, np.exp(-2 * mu * period / pr.C), rtol=1e-7)
    assert np.all(br.observables["flow_error"] < 1e-10)


def test_api_refuses_a_start_that_is_no_hopf_point():
    b = trace(StuartLandau(), np.zeros(2), {"mu": -0.3, "w": W}, "mu", ContinuationOptions(bounds={"mu": (-1, 1)}))
    (ep,) = [s for s in b.special_points if s.type == "EP"][:1]
    with pytest.raises(ValueError, match="periodic orbits start at a Hopf point"):
        continue_cycles(StuartLandau(), ep, "mu")

    class Pencil(StuartLandau):
        def eigenproblem(self, u, p, **kw):
            raise AssertionError("not to be called")

    with pytest.raises(ValueError, match="defines its own eigenproblem"):
        CycleProblem(Pencil(), Mesh(2), np.zeros((Mesh(2).nodes, 2)))
    hb = sl_hopf()
    with pytest.raises(ValueError, match="defines its own eigenproblem"):  # before its (failing) pencil
        continue_cycles(Pencil(), hb, "mu")


def test_cli_cycles_json(ab_file, tmp_path):
    import json

    r = _cli("continue", ab_file, "--from", "HB1", "--cycles", "--max-steps", "4", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output[r.output.index("{"): r.output.rindex("}") + 1])
    extra = doc["extra"]
    assert extra["from"] == "HB1" and extra["cycles"] == {"ntst": 20, "ncol": 4, "adapt_mesh": True}
    (branch,) = doc["branches"]
    assert branch["kind"] == "periodic-orbits" and branch["n_points"] == 5
    orbits = extra["orbits"]
    assert len(orbits["D"]) == len(orbits["period"]) == 5 and orbits["stable"] == [False] * 5
    from contin import io

    (steady,), _ = io.load(ab_file)
    omega = steady.points("HB")[0].data["omega"]
    assert abs(orbits["period"][0] / (2 * math.pi / omega) - 1) < 1e-3  # the first orbit, amplitude 0.01


def test_orbits_stay_admissible():
    """The base problem's admissible(u, p) holds at every node of every stored orbit (here r < 0.6:
    the branch stops short of mu = 0.36 instead of computing orbits outside the domain)."""

    class Bounded(StuartLandau):
        def admissible(self, u, p):
            return None if u @ u < 0.36 else "r >= 0.6"

    hb = sl_hopf()
    br = continue_cycles(Bounded(), hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.5)}, max_steps=80))
    assert br.parameter_values.max() < 0.36 and br.parameter_values.max() > 0.3
    for i in range(len(br)):
        _, nodes, _ = orbit_of(br.state(i), 2)
        assert np.all(np.sum(nodes**2, axis=1) < 0.36)


def test_sign_change_without_a_hopf_point_ends_with_mx(monkeypatch):
    """Where the signed amplitude changes sign but the Hopf system cannot be solved, the branch does
    not claim a Hopf point: MX, the HB marked not converged, the message says why."""
    import contin.hopfsystem
    from tests.cycle_models import TwoHopfLandau

    def broken(*args, **kwargs):
        raise ValueError("no eigenvector")

    hb = _hopf_of(TwoHopfLandau(), np.zeros(2), {"p": -0.3, "w": W}, "p", (-1, 0.5))
    monkeypatch.setattr(contin.hopfsystem, "hopf_basis", broken)
    br = continue_cycles(TwoHopfLandau(), hb, "p", ContinuationOptions(bounds={"p": (-1, 2)}, max_steps=300))
    assert br.status == "MX" and "but no Hopf point solves there" in br.message and "no eigenvector" in br.message
    assert [s.type for s in br.special_points] == ["HB", "MX"] and not br.points("HB")[0].converged


def test_cli_period_doubled_orbits_from_pd(tmp_path, monkeypatch):
    """trace roessler -> --cycles from HB1 -> --cycles from PD of that file: the period-doubled
    orbits (period 2 T at the start), written and readable; a PD of a steady run is refused."""
    from contin import io

    here = __import__("pathlib").Path(__file__).parent
    monkeypatch.syspath_prepend(str(here))
    monkeypatch.setenv("CONTIN_SCENES", "cycle_fixture_scenes:SCENES")
    run, cyc, dbl = tmp_path / "r.h5", tmp_path / "c.h5", tmp_path / "d.h5"
    assert _cli("trace", "roessler", "-q", "--no-stability", "-o", run).exit_code == 0
    r = _cli("continue", run, "--from", "HB1", "--cycles", "--max-steps", "60", "-o", cyc)
    assert r.exit_code == 0, r.output
    (orbits,), _ = io.load(cyc)
    pd = orbits.points("PD")[0]
    r = _cli("continue", cyc, "--from", pd.name, "--cycles", "--ntst", "40", "--max-steps", "10", "-o", dbl)
    assert r.exit_code == 0, r.output
    assert r.output.startswith(f"period-doubled orbits from {pd.name}")
    (doubled,), meta = io.load(dbl)
    assert doubled.parent == pd.name and meta["extra"]["cycles"]["n"] == 3 and meta["extra"]["cycles"]["ntst"] == 40
    assert math.isclose(doubled.observables["period"][0], 2 * pd.data["period"], rel_tol=1e-3)
    r = _cli("continue", run, "--from", "EP2", "--cycles")
    assert r.exit_code == 1 and "--cycles starts at a Hopf point (HB), or a period doubling (PD) or branch point (BP)" in r.output


def test_ctrl_c_keeps_the_orbits_computed_so_far(ab_file, tmp_path):
    """The first Ctrl-C ends the orbits at the last one computed: the file holds them, marked
    incomplete ('interrupted'), then one Error line and exit 130 (as continue does for curves)."""
    import os
    import signal

    from contin import io
    from tests.signals import signalled

    out = tmp_path / "cyc.h5"
    code, stderr = signalled(["continue", str(ab_file), "--from", "HB1", "--cycles", "--ds", "1e-4", "--ds-max", "1e-4",
                              "--max-steps", "100000", "-o", str(out)], signal.SIGINT,
                             lambda: (tmp_path / ".cyc.h5.lock").exists(), env=os.environ,
                             what="the output lock (computing starts)", after=2.0)
    errors = [line for line in stderr.splitlines() if line.startswith("Error:")]
    assert code == 130 and errors == ["Error: interrupted (Ctrl-C)"], stderr
    assert f"are saved in {out}" in stderr
    (br,), meta = io.load(out)
    assert meta["complete"] is False and meta["stopped"] == "interrupted"
    assert br.kind == "periodic-orbits" and len(br) > 3 and "interrupted" in br.message


def test_state_dependent_mass_matrix_is_refused():
    """M is taken constant (its value at the Hopf point): an M(u) would give wrong orbits silently."""
    import scipy.sparse as sp

    class Varying(_SlowLandau):
        def mass_matrix(self, u, p):
            return sp.diags([2.5 + u[0] ** 2, 2.5])

    hb = _hopf_of(_SlowLandau(), np.zeros(2), {"mu": -0.3, "w": W}, "mu", (-1, 1))
    with pytest.raises(ValueError, match="constant mass matrix"):
        continue_cycles(Varying(), hb, "mu")
