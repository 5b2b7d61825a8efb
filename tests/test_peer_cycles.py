"""Peer problems (periodic orbits) against the general core: published ODEs whose cycles AUTO-07p
and BifurcationKit continue from a Hopf point, written against contin's API and continued with
``contin.cycles.continue_cycles`` from the Hopf point contin locates.

References are computed here, independently of the collocation: closed forms (Hopf point,
omega_H, Liouville's product of the multipliers), and shooting with scipy: the orbit at the
continued parameter by ``scipy.optimize.root`` on the flow map of ``solve_ivp`` (DOP853, tol
1e-12) with a phase condition, started from our orbit, and its monodromy matrix from the
variational equation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import root

from contin.continuation import trace
from contin.cycles import CycleOptions, continue_cycles, orbit_of
from contin.options import ContinuationOptions, StepOptions


def shoot(rhs, jac, nodes0, period, q):
    """The periodic orbit of u' = rhs(u, q) near (nodes0, period): root on
    (phi_T(u0) - u0, (u0 - nodes0) . rhs(nodes0)) = 0, then the monodromy matrix at the solution
    (variational equation).  Returns u0, T and the multipliers (by modulus, largest first)."""
    n = nodes0.size
    f0 = rhs(nodes0, q)

    def field(t, v):
        out = np.empty_like(v)
        out[:n] = rhs(v[:n], q)
        if v.size > n:
            out[n:] = (jac(v[:n], q) @ v[n:].reshape(n, n)).ravel()
        return out

    def flow(u0, T, var=False):
        v0 = np.concatenate([u0, np.eye(n).ravel()]) if var else u0
        return solve_ivp(field, (0, T), v0, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]

    sol = root(lambda w: np.r_[flow(w[:n], w[n]) - w[:n], (w[:n] - nodes0) @ f0], np.r_[nodes0, period], tol=1e-13)
    assert sol.success, sol.message
    u0, T = sol.x[:n], float(sol.x[n])
    mult = np.linalg.eigvals(flow(u0, T, var=True)[n:].reshape(n, n))
    return u0, T, mult[np.argsort(-np.abs(mult))]


# ---------------------------------------------------------------------------------------------
# AUTO-07p demo lor: the Lorenz system

LOR = {"sigma": 10.0, "rho": 20.0, "beta": 8.0 / 3.0}


def lorenz_rhs(u, q):
    x, y, z = u
    return np.array([q["sigma"] * (y - x), q["rho"] * x - y - x * z, x * y - q["beta"] * z])


def lorenz_jac(u, q):
    x, y, z = u
    return np.array([[-q["sigma"], q["sigma"], 0.0], [q["rho"] - z, -1.0, -x], [y, x, -q["beta"]]])


def test_lorenz_unstable_cycles_from_the_subcritical_hopf_point():
    """AUTO demo lor (sigma = 10, beta = 8/3), from C+ = (sqrt(beta (rho - 1)), ., rho - 1): the
    Hopf point at rho_H = sigma (sigma + beta + 3) / (sigma - beta - 1) = 470/19 with
    omega_H^2 = beta (rho_H + sigma) (lambda = i omega in lambda^3 + (sigma + beta + 1) lambda^2
    + beta (rho + sigma) lambda + 2 beta sigma (rho - 1)), subcritical: the unstable cycles exist
    for rho < rho_H, their period growing towards the homoclinic orbit at rho ~ 13.926.  At
    rho ~ 22 and ~ 16 the period, orbit and multipliers against shooting; the product of the
    multipliers is exp(-(sigma + 1 + beta) T) (Liouville: the divergence is constant)."""
    from problems.demo import Lorenz

    s, b = LOR["sigma"], LOR["beta"]
    rho_h = s * (s + b + 3) / (s - b - 1)
    omega_h = math.sqrt(b * (rho_h + s))
    eq = trace(Lorenz(), Lorenz.equilibrium(LOR), LOR, "rho", ContinuationOptions(bounds={"rho": (15, 30)}))
    (hb,) = eq.points("HB")
    assert math.isclose(rho_h, 470 / 19, rel_tol=1e-15)
    assert abs(hb.params["rho"] - rho_h) < 1e-9  # measured 3e-12
    assert math.isclose(hb.data["omega"], omega_h, rel_tol=1e-9)
    assert hb.data["l1"] > 0  # subcritical

    # the period at the Hopf point: 2 pi / omega_H (the first orbit, amplitude 1e-4: O(eps^2) off)
    small = continue_cycles(Lorenz(), hb, "rho", ContinuationOptions(max_steps=1), CycleOptions(amplitude=1e-4))
    assert math.isclose(small.observables["period"][0], 2 * math.pi / omega_h, rel_tol=1e-8)  # measured 1.6e-10

    br = continue_cycles(Lorenz(), hb, "rho", ContinuationOptions(bounds={"rho": (14.5, 30)}, max_steps=60))
    rho, period = br.parameter_values, br.observables["period"]
    assert br.status == "EP" and math.isclose(rho[-1], 14.5, rel_tol=1e-12)
    assert np.all(rho < rho_h) and np.all(np.diff(rho) < 0)  # subcritical, towards smaller rho
    assert np.all(np.diff(period) > 0) and period[-1] > 2.5 * period[0]  # towards the homoclinic orbit
    assert not [p for p in br.special_points if p.type != "EP"]  # no LPC/PD/NS/BP on the way
    assert np.all(br.n_unstable == 1) and not br.stable.any()  # one multiplier outside the unit circle
    for target in (22.0, 16.0):
        i = int(np.argmin(np.abs(rho - target)))
        assert abs(rho[i] - target) < 0.3
        mesh, nodes, T = orbit_of(br.state(i), 3)
        q = {k: float(v[i]) for k, v in br.params.items()}
        u0, T_ref, mult = shoot(lorenz_rhs, lorenz_jac, nodes[0], T, q)
        assert math.isclose(T, T_ref, rel_tol=1e-7)  # measured 8e-11 (rho 22), 3.5e-9 (rho 16)
        assert np.abs(nodes[0] - u0).max() < 1e-6  # measured 4e-9, 7e-9
        run = solve_ivp(lambda t, u: lorenz_rhs(u, q), (0, T_ref), u0, method="DOP853", rtol=1e-12, atol=1e-12,
                        t_eval=mesh.t[:-1] * T_ref)
        assert np.abs(run.y.T - mesh.evaluate(nodes, mesh.t[:-1])).max() < 1e-6  # at the mesh points: 6.5e-9, 1.3e-7
        ours = br.eigenvalues[i][np.argsort(-np.abs(br.eigenvalues[i]))]
        assert math.isclose(mult[1].real, 1.0, abs_tol=1e-8)  # the trivial multiplier of the reference
        assert ours[0].real > 1 and math.isclose(ours[0].real, mult[0].real, rel_tol=1e-7)  # 6e-10, 1.1e-8
        # the contracting one, ~3e-5 and ~4e-9: by Liouville exp(-(sigma + 1 + beta) T) / mult[0] (the
        # shooting's own is good to ~1e-4 only: 1e-12 absolute integration error in M)
        small = math.exp(-(s + 1 + b) * T_ref) / mult[0].real
        assert math.isclose(abs(mult[2]), small, rel_tol=1e-3)
        assert math.isclose(abs(ours[1]), small, rel_tol=1e-3)  # measured 1e-8 (rho 22), 7e-5 (rho 16)



def test_lorenz_cycles_near_the_homoclinic_orbit_end_under_resolved():
    """On NTST = 40 the Lorenz cycles reach rho ~ 13.97, within 0.05 of the homoclinic orbit at
    rho_hom = 13.9265 (Sparrow 1982; no cycles of this family below it), the period 4x T_H; the last
    orbit against shooting.  The branch then ends with MX "under-resolved" naming NTST = 80 (the
    Floquet check of the sharpening orbit), not with wrong orbits."""
    from problems.demo import Lorenz

    eq = trace(Lorenz(), Lorenz.equilibrium(LOR), LOR, "rho", ContinuationOptions(bounds={"rho": (15, 30)}))
    (hb,) = eq.points("HB")
    br = continue_cycles(Lorenz(), hb, "rho", ContinuationOptions(bounds={"rho": (13.0, 30)}, max_steps=200),
                         CycleOptions(ntst=40))
    assert br.status == "MX" and "under-resolved" in br.message and "NTST = 80" in br.message
    rho, period = br.parameter_values, br.observables["period"]
    assert np.all(rho > 13.9265) and rho[-1] < 14.0
    assert period[-1] > 4 * 2 * math.pi / hb.data["omega"]
    i = len(br) - 1
    _, nodes, T = orbit_of(br.state(i), 3)
    q = {k: float(v[i]) for k, v in br.params.items()}
    _, T_ref, mult = shoot(lorenz_rhs, lorenz_jac, nodes[0], T, q)
    assert math.isclose(T, T_ref, rel_tol=1e-7)  # measured 2.6e-9
    assert math.isclose(br.eigenvalues[i, 0].real, mult[0].real, rel_tol=1e-5)  # ~1083: measured 1.8e-6
    assert br.n_unstable[i] == 1

# ---------------------------------------------------------------------------------------------
# The Brusselator (tests/peer_models.py)


def test_brusselator_stable_cycles_from_the_supercritical_hopf_point():
    """x' = a - (b + 1) x + x^2 y, y' = b x - x^2 y (a = 3/2), through ``from_functions`` with F
    alone: the Hopf point at b = 1 + a^2 with omega = a, supercritical (cycles for b > b_H,
    stable).  At b ~ 3.6 and b = 4.5 the period and the amplitude (max - min of x) against
    shooting, and the nontrivial multiplier against the shooting's monodromy and against
    Liouville's exp(int_0^T tr J(u(t)) dt) along the shot orbit (2-D: it is the only one)."""
    from tests import peer_models as pm

    a = pm.BRUSSELATOR["a"]
    pr = pm.brusselator()
    eq = trace(pr, np.array([a, pm.BRUSSELATOR["b"] / a]), pm.BRUSSELATOR, "b",
               ContinuationOptions(bounds={"b": (2.5, 4.5)}))
    (hb,) = eq.points("HB")
    assert abs(hb.params["b"] - (1 + a * a)) < 1e-9  # measured 4e-11
    assert math.isclose(hb.data["omega"], a, rel_tol=1e-9)
    assert hb.data["l1"] < 0  # supercritical

    small = continue_cycles(pr, hb, "b", ContinuationOptions(max_steps=1), CycleOptions(amplitude=1e-4))
    assert math.isclose(small.observables["period"][0], 2 * math.pi / a, rel_tol=1e-8)  # measured 3e-10

    br = continue_cycles(pr, hb, "b", ContinuationOptions(bounds={"b": (2.5, 4.5)}, max_steps=60))
    b, amp = br.parameter_values, br.observables["amplitude"]
    assert br.status == "EP" and math.isclose(b[-1], 4.5, rel_tol=1e-12)
    assert np.all(b > 1 + a * a) and np.all(np.diff(amp) > 0)
    assert not [p for p in br.special_points if p.type != "EP"]
    assert br.stable.all() and not br.n_unstable.any()  # the multiplier inside the unit circle
    assert np.all(np.abs(br.eigenvalues[:, 0]) < 1)
    for target in (3.6, 4.5):
        i = int(np.argmin(np.abs(b - target)))
        assert abs(b[i] - target) < 0.2
        mesh, nodes, T = orbit_of(br.state(i), 2)
        q = {k: float(v[i]) for k, v in br.params.items()}
        u0, T_ref, mult = shoot(pm.brusselator_F, pm.brusselator_J, nodes[0], T, q)
        assert math.isclose(T, T_ref, rel_tol=1e-7)  # measured 1e-10 (b 3.6), 5e-8 (b 4.5)
        run = solve_ivp(lambda t, u: pm.brusselator_F(u, q), (0, T_ref), u0, method="DOP853", rtol=1e-12,
                        atol=1e-12, dense_output=True)
        t = np.linspace(0, T_ref, 20001)
        x = run.sol(t)
        amp_ref = np.ptp(x[0])
        fine = mesh.evaluate(nodes, t / T_ref)[:, 0]
        assert math.isclose(np.ptp(fine), amp_ref, rel_tol=5e-5)  # the collocation polynomial: 2e-6, 5e-6
        assert math.isclose(amp[i], amp_ref, rel_tol=1e-3)  # max - min over the nodes only: 2e-4, 5e-4
        assert math.isclose(mult[0].real, 1.0, abs_tol=1e-8)  # the trivial one
        trJ = np.trace(np.array([pm.brusselator_J(v, q) for v in x.T]), axis1=1, axis2=2)
        liouville = math.exp(np.trapezoid(trJ, t))
        # down to ~2e-6 at b = 4.5: compared by the exponent, int tr J dt
        assert math.isclose(math.log(mult[1].real), math.log(liouville), rel_tol=1e-6)  # the references agree
        assert math.isclose(math.log(br.eigenvalues[i, 0].real), math.log(mult[1].real), rel_tol=1e-6)  # 3e-9, 4e-7
        assert abs(br.eigenvalues[i, 0].imag) < 1e-12


# ---------------------------------------------------------------------------------------------
# AUTO-07p demo plp: a fold of cycles


def orbit_top(mesh, nodes):
    """The point of largest s on the collocation orbit (sampled finely): the shooting's start."""
    u = mesh.evaluate(nodes, np.linspace(0, 1, 4001))
    return u[int(np.argmax(u[:, 0]))]


def plp_shooting_fold(u_top, period, rho_guess, sign=1, **params):
    """The fold of plp's cycles by solve_ivp shooting: the orbits labelled by c, the largest s on
    the orbit (unknowns a(0), T, rho with s(0) = c: periodicity and s'(0) = 0), the fold where
    rho(c) is extremal (minimize_scalar of sign * rho: 1 a minimum, -1 a maximum); ``params``: other
    parameters than the demo's.  Returns
    (rho, T) at the fold."""
    from scipy.optimize import fsolve, minimize_scalar

    from tests import peer_models as pm

    state = {"guess": np.array([u_top[1], period, rho_guess])}

    def orbit(c):
        def g(v):
            a0, t_end, rho = v
            q = {**pm.PLP, **params, "rho": rho}
            end = solve_ivp(lambda t, u: pm.plp_F(u, q), (0, t_end), [c, a0], method="DOP853", rtol=1e-12,
                            atol=1e-12).y[:, -1]
            return [end[0] - c, end[1] - a0, pm.plp_F(np.array([c, a0]), q)[0]]

        sol, _, ok, msg = fsolve(g, state["guess"], xtol=1e-13, full_output=True)
        assert ok == 1 or np.abs(g(sol)).max() < 1e-9, msg  # xtol 1e-13 can be below its noise
        state["guess"] = sol
        return sol

    c0 = u_top[0]
    res = minimize_scalar(lambda c: sign * orbit(c)[2], bracket=(c0 - 0.01, c0, c0 + 0.01), tol=1e-8)
    sol = orbit(res.x)
    return float(sol[2]), float(sol[1])


@pytest.fixture(scope="module")
def plp_cycles():
    """plp's equilibria in rho (the demo's run ``plp.ss``) and the cycles from HB1 past LPC1."""
    from tests import peer_models as pm

    pr = pm.plp()
    eq = trace(pr, np.array(pm.PLP_START), pm.PLP, "rho",
               ContinuationOptions(bounds={"rho": (0, 6)}, max_steps=500, step=StepOptions(ds=0.1, ds_max=3.0)))
    hb = eq.points("HB")[0]
    return pr, eq, continue_cycles(pr, hb, "rho", ContinuationOptions(bounds={"rho": (0, 6)}, max_steps=75))


def test_plp_fold_of_cycles_against_shooting(plp_cycles):
    """AUTO demo plp in rho: HB1 (F = 0, tr J = 0 solved by fsolve with the exact Jacobian) is
    subcritical; its unstable cycles grow towards smaller rho to a fold of cycles (LPC1 near
    rho = 2.7597; reference: the minimum of rho along the shooting family) and come back stable.
    The multiplier on either side against the shooting monodromy."""
    from scipy.optimize import fsolve

    from tests import peer_models as pm

    _, eq, br = plp_cycles
    hb = eq.points("HB")[0]

    def hopf(v):
        q = {**pm.PLP, "rho": v[2]}
        return [*pm.plp_F(v[:2], q), np.trace(pm.plp_J(v[:2], q))]

    ref = fsolve(hopf, [*hb.state, hb.params["rho"]], xtol=1e-12)
    assert np.abs(hopf(ref)).max() < 1e-10
    assert abs(hb.params["rho"] - ref[2]) < 1e-8  # measured 8e-11
    omega = math.sqrt(np.linalg.det(pm.plp_J(ref[:2], {**pm.PLP, "rho": ref[2]})))
    assert math.isclose(hb.data["omega"], omega, rel_tol=1e-7)  # 2e-11
    assert hb.data["l1"] > 0  # subcritical

    assert [p.type for p in br.special_points] == ["LPC", "EP"]
    (lpc,) = br.points("LPC")
    assert lpc.converged and "fold of cycles" in lpc.note
    rho = br.parameter_values
    assert rho.min() >= lpc.params["rho"] - 1e-12  # the fold is the branch's smallest rho
    mesh, nodes, period = orbit_of(lpc.state, 2)
    top = orbit_top(mesh, nodes)
    rho_fold, t_fold = plp_shooting_fold(top, period, lpc.params["rho"])
    assert abs(lpc.params["rho"] - rho_fold) < 1e-7  # measured 3.2e-9 (NTST = 20)
    assert math.isclose(period, t_fold, rel_tol=1e-7)  # 2.8e-9
    # unstable (one multiplier > 1) from the HB to the fold, stable after it
    idx = np.arange(len(br))  # the LPC itself (a multiplier at 1 to the Floquet error) is neither
    assert np.all(br.n_unstable[idx < lpc.index] == 1) and br.stable[idx > lpc.index].all()
    for i in (lpc.index - 10, len(br) - 1):
        _, nodes, T = orbit_of(br.state(i), 2)
        q = {k: float(v[i]) for k, v in br.params.items()}
        u0, T_ref, mult = shoot(pm.plp_F, pm.plp_J, nodes[0], T, q)
        assert math.isclose(T, T_ref, rel_tol=1e-7)
        if i < lpc.index:  # 6.3: measured 3e-8
            assert math.isclose(br.eigenvalues[i, 0].real, mult[0].real, rel_tol=1e-6)
        else:  # 3e-4, by its exponent: measured 5e-5 on NTST = 20 (the multiplier 4e-4 off; 2e-6 on
            # NTST = 40, 5e-10 on 80: the collocation error, amplified in a strongly contracting one)
            assert math.isclose(math.log(br.eigenvalues[i, 0].real), math.log(mult[1].real), rel_tol=2e-4)


def test_plp_lpc_curve_against_shooting_folds(plp_cycles):
    """The demo's run ``plp.plp``: the curve of folds of cycles through LPC1 in (rho, s0), traced
    both ways to s0 = 109 and 111 (the demo's UZSTOP / UZR); at both ends rho and the period
    against the shooting fold at that s0."""
    from contin.lpccurve import trace_lpc_curve

    pr, _, br = plp_cycles
    (lpc,) = br.points("LPC")
    curve = trace_lpc_curve(pr, lpc, "s0", 2, ContinuationOptions(bounds={"s0": (109.0, 111.0)}, max_steps=40),
                            parameter="rho")
    s0, rho = curve.params["s0"], curve.params["rho"]
    assert [p.type for p in curve.special_points] == ["EP", "EP"]
    assert s0.min() == 109.0 and s0.max() == 111.0 and np.all(np.diff(s0) > 0) and np.all(np.diff(rho) > 0)
    for i in (int(np.argmin(s0)), int(np.argmax(s0))):
        mesh, nodes, period = orbit_of(curve.state(i), 2, None, 4)
        top = orbit_top(mesh, nodes)
        rho_fold, t_fold = plp_shooting_fold(top, period, float(rho[i]), s0=float(s0[i]))
        assert abs(rho[i] - rho_fold) < 1e-7  # measured 4.4e-9 (s0 = 109), 3.6e-9 (111)
        assert math.isclose(period, t_fold, rel_tol=1e-7)  # 5.9e-9, 1.3e-9


def test_plp_second_fold_from_the_other_hopf_point(plp_cycles):
    """From HB2 (rho ~ 4.65, subcritical) the unstable cycles grow towards larger rho to LPC2, the
    maximum of rho along the family (near 5.0078; reference: shooting), and are stable after it."""
    pr, eq, _ = plp_cycles
    hb = eq.points("HB")[1]
    assert hb.data["l1"] > 0 and hb.params["rho"] > 4.5
    br = continue_cycles(pr, hb, "rho", ContinuationOptions(bounds={"rho": (0, 6)}, max_steps=45))
    assert [p.type for p in br.special_points] == ["LPC", "EP"]
    (lpc,) = br.points("LPC")
    assert br.parameter_values.max() <= lpc.params["rho"] + 1e-12
    mesh, nodes, period = orbit_of(lpc.state, 2)
    rho_fold, t_fold = plp_shooting_fold(orbit_top(mesh, nodes), period, lpc.params["rho"], sign=-1)
    assert abs(lpc.params["rho"] - rho_fold) < 1e-7  # measured 1.3e-10
    assert math.isclose(period, t_fold, rel_tol=1e-7)  # 1.1e-9
    idx = np.arange(len(br))
    assert np.all(br.n_unstable[idx < lpc.index] == 1) and br.stable[idx > lpc.index].all()
