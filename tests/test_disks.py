"""2-D disks (problems/disks, issue 17): closures, exact Jacobians, validity limits, closed-form
critical gaps against continuation, Savage's Eqs. 15/28, the pitchfork bend, seed 000's reduced
equation and the scenes from the CLI."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy.integrate import solve_bvp

from contin.continuation import trace
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from contin.problem import check_jacobian
from problems.disks.closures import (
    DiskClosure, critical_gap_factor, critical_gaps, homogeneous_stresses, kinetic_gap_factor, kn_in_time_units,
    pair_correlation, savage_contact_stresses,
)
from problems.disks.model import DiskCouetteProblem

SP = math.sqrt(math.pi)
BASE = dict(e=0.8, phi_inf=0.9, phi_f=0.7, m_f=0.01, phi_c=0.8, a0=0.3)


# ----------------------------------------------------------------------------- closures
@pytest.mark.parametrize("model", ["cs", "fv", "gf"])
@pytest.mark.parametrize("contact", [False, True])
def test_transport_partials_against_complex_step(model, contact):
    cl = DiskClosure(G=model, contact=contact)
    nu = np.array([0.05, 0.3, 0.6, 0.83, 0.88])
    T = np.array([0.7, 0.4, 1.3, 0.9, 2.0])
    tr = cl.transport(nu, T, BASE)
    h = 1e-30
    a, b = cl.transport(nu + 1j * h, T, BASE), cl.transport(nu, T + 1j * h, BASE)
    for name in ("p", "mu", "k", "D"):
        np.testing.assert_allclose(getattr(tr, name + "_nu"), getattr(a, name).imag / h, rtol=1e-12)
        np.testing.assert_allclose(getattr(tr, name + "_T"), getattr(b, name).imag / h, rtol=1e-12)


def test_pair_correlation_closed_forms():
    nu = np.linspace(0.05, 0.85, 9)
    g_cs, _ = pair_correlation(nu, "cs", 0.7, 0.9)
    np.testing.assert_allclose(g_cs, nu * (1 - 7 * nu / 16) / (1 - nu) ** 2, rtol=1e-14)  # Henderson g * nu
    g_fv, _ = pair_correlation(nu, "fv", 0.7, 0.9)
    np.testing.assert_allclose(g_fv, 1 / (1.7 * (np.sqrt(0.9 / nu) - 1)), rtol=1e-14)
    # with its (1+e), G_FV gives the free-volume equation of state p/(nT) = 1/(1 - sqrt(nu/phi_inf)) for any e
    for e in (0.5, 0.7, 1.0):
        np.testing.assert_allclose(1 + (1 + e) * pair_correlation(nu, "fv", e, 0.9)[0], 1 / (1 - np.sqrt(nu / 0.9)),
                                   rtol=1e-12)
    g_gf, _ = pair_correlation(nu, "gf", 0.7, 0.9)
    assert abs(g_gf[0] - g_cs[0]) < 1e-12 * g_cs[0] and abs(g_gf[-1] - g_fv[-1]) < 1e-6 * g_fv[-1]
    # at phi_f the global fit is the mean of both
    mid = pair_correlation(np.array([0.7]), "gf", 0.7, 0.9)[0]
    both = pair_correlation(np.array([0.7]), "cs", 0.7, 0.9)[0] + pair_correlation(np.array([0.7]), "fv", 0.7, 0.9)[0]
    assert mid[0] == pytest.approx(0.5 * both[0], rel=1e-14)


def test_kinetic_limits_are_two_dimensional_enskog():
    """'jr' normalization, elastic and dilute: f2 -> eta_0 = sqrt(pi)/8 (= (1/2d) sqrt(m T / pi) per
    rho_p d sqrt(T), m = rho_p pi d^2/4), f4 -> sqrt(pi)/2 (conductivity (2/d) sqrt(T/(pi m)) per unit mass);
    dense viscosity ratio 1 + 8/pi (Gass 1971); dissipation from the collision integral
    Gamma = sqrt(pi) (1-e^2) g n^2 d T_p^{3/2}/sqrt(m) = (rho_p/d) (4/sqrt(pi)) (1-e^2) nu^2 g T^{3/2}."""
    cl = DiskClosure("cs")
    nu = np.array([1e-7])
    f = cl.kinetic(nu, {**BASE, "e": 1.0})
    g = 1.0  # contact value at nu -> 0
    assert f.f2[0] == pytest.approx(SP / 8 / g, rel=1e-5)
    assert f.f4[0] == pytest.approx(SP / 2 / g, rel=1e-5)
    from problems.disks.closures import table1
    t = table1(1.0)
    assert t["a_eta"] / t["b_eta"] == pytest.approx(1 + 8 / math.pi, rel=1e-14)
    assert t["c_eta"] / t["b_eta"] == pytest.approx(2.0, rel=1e-14)
    nu = np.array([0.4])
    f = cl.kinetic(nu, {**BASE, "e": 0.7})
    gc = (1 - 7 * 0.4 / 16) / 0.6**2
    assert f.f5[0] == pytest.approx(4 / SP * (1 - 0.49) * 0.16 * gc, rel=1e-14)
    assert f.f1[0] == pytest.approx(0.4 * (1 + 1.7 * 0.4 * gc), rel=1e-14)
    # uniform shear T0 = f2/f5 is ESI Eq. 31 in both normalizations
    for norm in ("jr", "esi"):
        c2 = DiskClosure("cs", normalization=norm).kinetic(nu, {**BASE, "e": 0.7})
        G = 0.4 * gc
        t = table1(0.7)
        eq31 = (t["a_eta"] * G + t["b_eta"] / G + t["c_eta"]) / (16 * math.pi**-1.5 * G) / (1 - 0.49)
        assert c2.f2[0] / c2.f5[0] == pytest.approx(eq31, rel=1e-14)


# ----------------------------------------------------------------------------- model
@pytest.mark.parametrize("walls", ["noslip", "bumpy"])
@pytest.mark.parametrize("gravity", [False, True])
@pytest.mark.parametrize("closure", [DiskClosure("cs"), DiskClosure("gf", contact=True), DiskClosure("fv", contact=True)])
def test_exact_jacobian_against_finite_differences(walls, gravity, closure):
    pb = DiskCouetteProblem("cheb", 16, walls=walls, closure=closure, gravity=gravity)
    p = pb.params({"nu": 0.85 if closure.contact else 0.5, "H": 15.0, "G": 1e-3 if gravity else 0.0, "a0": 0.3})
    x = pb.initial_guess(p)
    n, y = pb.n, pb.grid.y
    x[:n] += 0.02 * np.cos(np.pi * (y + 0.5))
    x[n:2 * n] += 0.01 * np.sin(5 * y)
    x[2 * n:3 * n] *= 1 + 0.1 * np.sin(3 * y)
    if gravity:
        x[3 * n + 1:] = pb.cumulative_mass(x[:n]) + 1e-3 * np.sin(7 * y)
    names = ("H", "nu", "e") + (("G",) if gravity else ()) + (("a0", "phi_c") if closure.contact else ())
    chk = check_jacobian(pb, x, p, parameters=names)
    assert chk.relative_error < 1e-8
    scale = np.max(np.abs(pb.residual(x, p))) + 1.0
    assert max(chk.dp_errors.values()) < 1e-5 * scale


def test_validity_limits_are_one_sentence_errors():
    pb = DiskCouetteProblem("cheb", 8)
    with pytest.raises(ValueError, match=r"nu = 0.9 >= phi_inf = 0.9"):
        pb.params({"nu": 0.9})
    for e in (0.0, 1.2, -0.1):
        with pytest.raises(ValueError, match=r"outside \(0, 1\]"):
            pb.params({"e": e})
    with pytest.raises(ValueError, match="no steady uniform shear"):
        pb.uniform_state(pb.params({"e": 1.0}))
    cl = DiskClosure("gf", contact=True, normalization="esi")
    with pytest.raises(ValueError, match=r"<= phi_c = 0.8.*no contact part"):
        savage_contact_stresses(np.array([0.79, 0.85]), {**BASE, "e": 0.7}, cl)
    with pytest.raises(ValueError, match="phi_inf"):
        savage_contact_stresses(np.array([0.9]), {**BASE, "e": 0.7}, cl)
    with pytest.raises(ValueError, match="unknown pair correlation"):
        DiskClosure("xx")


def test_uniform_shear_is_exact_and_psi_forms_agree():
    for model in ("cs", "fv", "gf"):
        cl = DiskClosure(model)
        pb = DiskCouetteProblem("cheb", 24, closure=cl)
        p = pb.params({"nu": 0.5, "H": 17.0})
        assert np.max(np.abs(pb.residual(pb.uniform_state(p), p))) < 1e-12
        nus = np.linspace(0.2, 0.85, 27)
        a, b = critical_gap_factor(nus, BASE, cl), kinetic_gap_factor(nus, BASE, cl)
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
        ok = ~np.isnan(a)
        np.testing.assert_allclose(a[ok], b[ok], rtol=1e-12)


@pytest.mark.parametrize("model,nu", [("cs", 0.5), pytest.param("fv", 0.4, marks=pytest.mark.slow),
                                       pytest.param("gf", 0.75, marks=pytest.mark.slow)])
def test_critical_gaps_closed_form_against_continuation(model, nu):
    """Symmetry-breaking BPs (n = 1, 3) of uniform shear located by contin at n pi psi to 1e-10."""
    cl = DiskClosure(model)
    pb = DiskCouetteProblem("cheb", 24, closure=cl)
    p = pb.params({"nu": nu, "e": 0.8})
    hc = critical_gaps(p, cl, 3)
    p["H"] = 0.5 * hc[0]
    opts = ContinuationOptions(bounds={"H": (0.5 * hc[0], 3.3 * hc[0])}, max_steps=200,
                               step=StepOptions(ds=0.05 * hc[0], ds_max=0.3 * hc[0]),
                               detection=DetectionOptions(locate_tol=1e-13))
    br = trace(pb, pb.uniform_state(p), p, "H", opts)
    bps = br.branch_points
    assert len(bps) == 3
    assert "symmetry-breaking" in bps[0].note and "symmetry-breaking" in bps[2].note and "symmetric" in bps[1].note
    assert abs(bps[0].params["H"] - hc[0]) < 1e-10 * hc[0]
    assert abs(bps[2].params["H"] - hc[2]) < 1e-10 * hc[2]
    assert abs(bps[1].params["H"] - hc[1]) < 1e-6 * hc[1]  # mode 2: its test function locates to ~1e-8 only


def test_contact_critical_gaps_against_continuation():
    """Savage's dense closure: the closed form psi includes the contact partials."""
    cl = DiskClosure("gf", contact=True, normalization="esi")
    pb = DiskCouetteProblem("cheb", 32, closure=cl)
    p = pb.params({"nu": 0.84, "e": 0.7, "a0": 1.0})
    hc = critical_gaps(p, cl, 1)[0]
    assert math.isfinite(hc) and hc != pytest.approx(critical_gaps({**p, "a0": 0.0}, cl, 1)[0], rel=1e-3)
    p["H"] = 0.8 * hc
    opts = ContinuationOptions(bounds={"H": (0.8 * hc, 1.2 * hc)}, max_steps=50,
                               step=StepOptions(ds=0.05 * hc, ds_max=0.1 * hc),
                               detection=DetectionOptions(locate_tol=1e-13))
    (bp,) = trace(pb, pb.uniform_state(p), p, "H", opts).branch_points
    assert abs(bp.params["H"] - hc) < 1e-10 * hc


# ----------------------------------------------------------------------------- Savage
def test_savage_contact_stresses_eq15_eq28_and_flow_curves():
    cl = DiskClosure("gf", contact=True, normalization="esi")
    p = {**BASE, "e": 0.7, "a0": 3.25e-2}
    phi = np.array([0.81, 0.84, 0.88])
    pcon, scon = savage_contact_stresses(phi, p, cl)
    np.testing.assert_allclose(pcon, 3.25e-2 * np.log(0.1 / (0.9 - phi)), rtol=1e-14)
    # Eq. 28 with f_eta, f_chi from Table 1 written out here
    from problems.disks.closures import table1
    t = table1(0.7)
    G = pair_correlation(phi, "gf", 0.7, 0.9)[0]
    f_eta = (1 + 1.7 * G) / (t["a_eta"] * G + t["b_eta"] / G + t["c_eta"])
    f_chi = (1 + 1.7 * G) / (t["a_chi"] * G)
    np.testing.assert_allclose(scon, pcon / np.sqrt(f_eta * f_chi), rtol=1e-13)
    # flow curves: Bagnold sigma ~ s^2 below phi_c, a yield stress sigma_con above
    s = np.array([1e-6, 1e-5])
    _, _, sig_lo = homogeneous_stresses(0.78, s, p, cl)
    assert math.log(sig_lo[1] / sig_lo[0]) / math.log(10) == pytest.approx(2.0, rel=1e-12)
    _, _, sig_hi = homogeneous_stresses(0.84, np.array([1e-9]), p, cl)
    assert sig_hi[0] == pytest.approx(scon[1], rel=1e-8)
    # the linear dashpot: e = exp(-pi z / sqrt(1 - z^2)) at z^2 = kn/2
    z = math.sqrt(kn_in_time_units(0.7) / 2)
    assert math.exp(-math.pi * z / math.sqrt(1 - z * z)) == pytest.approx(0.7, rel=1e-14)


def test_savage_flow_curve_by_continuation_matches_eq28():
    """Uniform shear continued in the contact scale a0 (the inverse squared shear rate in Couette
    units): dS/da0 = sigma_con/a0 of Eq. 28 above phi_c, and S independent of a0 below."""
    cl = DiskClosure("gf", contact=True, normalization="esi")
    pb = DiskCouetteProblem("cheb", 12, closure=cl)
    for phi0 in (0.78, 0.85):
        p = pb.params({"nu": phi0, "e": 0.7, "a0": 0.0, "H": 10.0})
        opts = ContinuationOptions(bounds={"a0": (0.0, 50.0)}, max_steps=40, step=StepOptions(ds=0.5, ds_max=10.0))
        br = trace(pb, pb.uniform_state(p), p, "a0", opts)
        S, a0 = br.observables["shear_stress"], br.parameter_values
        assert a0[-1] == pytest.approx(50.0)
        if phi0 < 0.8:
            assert np.ptp(S) < 1e-12
        else:
            ref = savage_contact_stresses(np.array([phi0]), {**p, "a0": 1.0}, cl)[1][0]
            np.testing.assert_allclose((S - S[0]) / np.where(a0 > 0, a0, 1.0), np.where(a0 > 0, ref, 0.0), atol=1e-11)


# ----------------------------------------------------------------------------- criticality
def test_pitchfork_bend_normal_form_sign():
    from problems.disks.criticality import pitchfork_bend, threshold_density

    pb = DiskCouetteProblem("cheb", 24, closure=DiskClosure("cs"))
    nu_th = threshold_density({**BASE, "e": 0.8}, DiskClosure("cs"))
    assert math.isnan(float(critical_gap_factor(nu_th - 1e-6, BASE, DiskClosure("cs"))))
    assert math.isfinite(float(critical_gap_factor(nu_th + 1e-6, BASE, DiskClosure("cs"))))
    assert pitchfork_bend(pb, nu_th + 0.01, 0.8).a < 0  # subcritical just above the threshold
    b = pitchfork_bend(pb, 0.5, 0.8)
    assert b.a > 0 and b.error < 1e-4 * b.a


@pytest.mark.slow
def test_pitchfork_bend_normal_form_against_branch_fit():
    from problems.disks.criticality import bend_by_branch, pitchfork_bend

    pb = DiskCouetteProblem("cheb", 32, closure=DiskClosure("cs"))
    a_fit, _ = bend_by_branch(pb, 0.5, 0.8)
    assert a_fit == pytest.approx(pitchfork_bend(pb, 0.5, 0.8).a, rel=1e-3)


# ----------------------------------------------------------------------------- seed 000's reduced equation
def _sh_reduced_solution(nu_wall, tau_over_p, e, H, y_eval):
    """Saitoh & Hayakawa's d/dy(F dnu/dy) = G (seed 000), written out here from Table 1 with their
    p(nu) = (nu/2)[1 + (1+e) nu g] and theta = 2T; kappa_SH = f4/(2 sqrt 2), eta_SH = sqrt(2) f2,
    lambda = 0, and the dissipation constant sqrt(2/pi) of Jenkins-Richman in this normalization
    (their slide prints 1/sqrt(2 pi); docs/disks.md).  Solved by scipy's solve_bvp with Dirichlet
    nu at the walls from a flat start."""
    ap = (1 + e) / SP * ((1 + e) * (3 * e - 1) / (4 * (7 - 3 * e)) + 2 / math.pi)
    bp = 2 / (SP * (7 - 3 * e))
    cp = (1 + e) * (3 * e + 1) / (2 * SP * (7 - 3 * e))
    ak = (1 + e) / SP * (9 * (1 + e) ** 2 * (2 * e - 1) / (4 * (19 - 15 * e)) + 4 / math.pi)
    bk = 16 / (SP * (1 + e) * (19 - 15 * e))
    ck = 6 * (2 * e * e + e + 1) / (SP * (19 - 15 * e))

    def g(nu):
        return (1 - 7 * nu / 16) / (1 - nu) ** 2

    def fields(nu):
        G = nu * g(nu)
        p = nu / 2 * (1 + (1 + e) * G)
        eta = math.sqrt(2) * math.pi / 4 * nu * (ap * G + bp / G + cp)
        kap = math.pi / 4 * nu * (ak * G + bk / G + ck) / (2 * math.sqrt(2))
        return G, p, eta, kap

    def dnu2g(nu):  # d(nu^2 g)/dnu = d(nu G)/dnu, G = nu g
        h = 1e-6
        return ((nu + h) ** 2 * g(nu + h) - (nu - h) ** 2 * g(nu - h)) / (2 * h)

    def F(nu):
        G, p, eta, kap = fields(nu)
        return p ** -1.5 * (kap / (2 * p) * (1 + (1 + e) * dnu2g(nu)))

    def Gsrc(nu):
        G, p, eta, kap = fields(nu)
        return 2 * tau_over_p**2 * p**0.5 / eta - math.sqrt(2 / math.pi) * (1 - e * e) * nu * G / p**1.5

    def rhs(y, z):
        return np.vstack([z[1] / F(z[0]), Gsrc(z[0])])

    def bc(za, zb):
        return np.array([za[0] - nu_wall[0], zb[0] - nu_wall[1]])

    y = np.linspace(-H / 2, H / 2, 401)
    z0 = np.vstack([np.full_like(y, 0.5 * (nu_wall[0] + nu_wall[1])), np.zeros_like(y)])
    sol = solve_bvp(rhs, bc, y, z0, tol=1e-9, max_nodes=100000)
    assert sol.success, sol.message
    return sol.sol(y_eval)[0]


@pytest.mark.parametrize("H,N", [(40.0, 32), pytest.param(128.0, 64, marks=pytest.mark.slow)])
def test_steady_band_solves_saitoh_hayakawa_reduced_equation(H, N):
    pb = DiskCouetteProblem("cheb", N, walls="bumpy", closure=DiskClosure("cs"))
    p = pb.params({"nu": 0.24, "e": 0.85, "phi_w": 1.0, "ew": 0.5, "H": 2.0})
    opts = ContinuationOptions(bounds={"H": (1.0, H)}, max_steps=300,
                               step=StepOptions(ds=0.1, ds_max=5.0, newton_target=6, grow=2.0))
    br = trace(pb, pb.initial_guess(p), p, "H", opts)
    assert br.parameter_values[-1] == pytest.approx(H)
    x = br.states[-1]
    nu, u, T, P, _ = pb.unpack(x)
    q = {**p, "H": H}
    S = pb.shear_stress(x, q)
    assert np.ptp(S) < 1e-8 * abs(S[0])
    assert pb.grid.weights @ nu == pytest.approx(0.24, abs=1e-13)
    ref = _sh_reduced_solution((nu[0], nu[-1]), S[0] / P, 0.85, H, H * pb.grid.y)
    assert np.max(np.abs(ref - nu)) < 1e-6
    assert np.max(nu) - np.min(nu) > 0.01  # a real band, not uniform


# ----------------------------------------------------------------------------- CLI
def test_cli_scenes_list_and_bad_input(tmp_path):
    from click.testing import CliRunner

    from contin.cli import main

    r = CliRunner().invoke(main, ["scenes"])
    for name in ("disks-pitchfork", "disks-criticality", "savage-rheology", "disks-steady"):
        assert name in r.output
    for args, what in ((["-s", "nu=0.95"], "phi_inf"), (["-s", "e=1.5"], "outside (0, 1]"), (["-s", "corr=xx"], "pair correlation")):
        r = CliRunner().invoke(main, ["trace", "disks-pitchfork", *args, "-q", "-o", str(tmp_path / "x.h5")])
        assert r.exit_code == 1 and what in r.output and "Traceback" not in r.output
    for args, what in ((["-s", "nu_band=0.79"], "no contact part"), (["-s", "phi_c=0.95", "-s", "nu_band=0.96"], "phi_inf")):
        r = CliRunner().invoke(main, ["trace", "savage-rheology", *args, "-q", "-o", str(tmp_path / "y.h5")])
        assert r.exit_code == 1 and what in r.output and "Traceback" not in r.output and r.output.count("\n") == 1


def test_gravity_continuation_keeps_hydrostatic_balance():
    """Continuation in G = Fr^-2 from uniform shear: d p/dy = -H^3 G nu (differentiated y-momentum),
    constant shear stress and the mass constraint, to the grid's accuracy; the reflection maps G -> -G."""
    pb = DiskCouetteProblem("cheb", 32, closure=DiskClosure("cs"), gravity=True)
    p = pb.params({"nu": 0.4, "e": 0.8, "H": 10.0, "G": 0.0})
    opts = ContinuationOptions(bounds={"G": (0.0, 2e-3)}, max_steps=40, step=StepOptions(ds=1e-2, ds_max=0.2))
    br = trace(pb, pb.uniform_state(p), p, "G", opts, symmetric=False)
    assert br.parameter_values[-1] == pytest.approx(2e-3)
    x = br.states[-1]
    q = {**p, "G": 2e-3}
    nu, u, T, P, M = pb.unpack(x)
    pr = pb.closure.transport(nu, T, q).p
    grad = pb.grid.d1 @ pr + q["H"] ** 3 * q["G"] * nu
    assert np.max(np.abs(grad)) < 1e-8 * np.max(pr)
    S = pb.shear_stress(x, q)
    assert np.ptp(S) < 1e-9 * abs(S[0])
    assert pb.grid.weights @ nu == pytest.approx(0.4, abs=1e-14)
    assert nu[0] > nu[-1] + 0.01  # denser at the bottom
    # F(S x, -G) = S F(x, G)
    z = x + 1e-2 * np.sin(np.arange(x.size))  # a generic state, F(z) = O(1)
    lhs, rhs = pb.residual(pb.symmetry(z), {**q, "G": -q["G"]}), pb.symmetry(pb.residual(z, q))
    assert np.max(np.abs(rhs)) > 1e-3
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-12 * np.max(np.abs(rhs)) * pb.n**2)


def test_resolution_guard_measures_distance_to_phi_inf():
    """Uniform shear is resolved on any grid; a plug profile steepening towards phi_inf is not (the 3-D
    estimate with the disks' packing limit)."""
    pb = DiskCouetteProblem("cheb", 16, closure=DiskClosure("gf"))
    p = pb.params({"nu": 0.5})
    assert pb.under_resolved(pb.uniform_state(p), p, 3e-5) is None
    x = pb.uniform_state(p)
    y = pb.grid.y
    x[:pb.n] = 0.5 + 0.3999 * np.tanh(40 * (y - 0.3)) * (y > 0.3)  # a plug reaching 0.8999 at the top wall
    reason = pb.under_resolved(x, p, 3e-5)
    assert reason is not None and "packing" in reason and "0.9" in reason


@functools.cache
def _band_start(H: float = 40.0):
    """The bumpy-wall band at H, traced once on cheb 32 from H = 2: (problem, state, parameters)."""
    pb0 = DiskCouetteProblem("cheb", 32, walls="bumpy", closure=DiskClosure("cs"))
    p = pb0.params({"nu": 0.24, "e": 0.85, "phi_w": 1.0, "ew": 0.5, "H": 2.0})
    opts = ContinuationOptions(bounds={"H": (1.0, H)}, max_steps=300, resolution_tol=None,
                               step=StepOptions(ds=0.1, ds_max=5.0, newton_target=6, grow=2.0))
    br = trace(pb0, pb0.initial_guess(p), p, "H", opts)
    assert br.parameter_values[-1] == pytest.approx(H)
    return pb0, br.states[-1], {**p, "H": H}


def _steady_band_stress(method, N):
    """Wall shear stress of the band on (method, N): the cheb 32 state resampled and corrected by Newton."""
    from contin.continuation import newton

    pb0, x0, p = _band_start()
    pb = DiskCouetteProblem(method, N, walls="bumpy", closure=DiskClosure("cs"))
    nu, u, T, P, _ = pb0.unpack(x0)
    res = newton(pb, pb.pack(*(pb0.grid.interpolate(f, pb.grid.y) for f in (nu, u, T)), P), p)
    assert res.converged
    return pb.observables(res.u, p)["shear_stress"]


@pytest.mark.parametrize("method,grids,order", [
    ("fd2", (16, 32, 64), 2.0),
    ("fd4", (32, 64, 128), 4.0),
])
def test_steady_band_convergence_order(method, grids, order):
    """Bumpy-wall band (nu = 0.24, H = 40): the wall shear stress of fd2 / fd4 converges to the
    Chebyshev value (cheb 32; cheb 64 and 96 agree with it to 1e-10) at the schemes' orders (measured 2.19, 2.19;
    fd4 3.60, 3.81: the one-sided wall rows carry odd powers too, see problems/discretization.py)."""
    ref = _steady_band_stress("cheb", 32)  # within 1e-10 of cheb 64
    errs = [abs(_steady_band_stress(method, n) - ref) for n in grids]
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(len(errs) - 1)]
    assert all(order - 0.2 < q < order + 0.5 for q in orders[-1:]), orders
    assert all(q > order - 0.5 for q in orders), orders


def test_disks_scenes_are_adaptive_steady_band_meets_the_reduced_equation(tmp_path):
    """disks-steady without --grid: adaptive (tol 3e-5; cheb 8..32 instead of the former fixed cheb 64),
    no Hopf points (spurious ones on coarse grids), and the band at H = 40 still solves Saitoh &
    Hayakawa's reduced equation (scipy solve_bvp) to 1e-6."""
    from click.testing import CliRunner

    from contin import io
    from contin.adapt import point_problem
    from contin.cli import main
    from contin.scene import get_scene

    for name in ("disks-pitchfork", "savage-rheology", "disks-steady"):
        assert get_scene(name).adaptive
    out = tmp_path / "s.h5"
    r = CliRunner().invoke(main, ["trace", "disks-steady", "-s", "H=40", "-q", "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    (br,), _ = io.load(out)
    assert br.status == "EP" and br.grid is not None and max(br.grid) < 64
    assert not [s for s in br.special_points if s.type == "HB"]
    pb0 = DiskCouetteProblem("cheb", 64, walls="bumpy", closure=DiskClosure("cs"))
    pb = point_problem(pb0, br, -1)
    x = br.state(-1)
    nu, u, T, P, _ = pb.unpack(x)
    q = pb.params({"nu": 0.24, "e": 0.85, "phi_w": 1.0, "ew": 0.5, "H": 40.0})
    S = pb.shear_stress(x, q)
    ref = _sh_reduced_solution((nu[0], nu[-1]), S[0] / P, 0.85, 40.0, 40.0 * pb.grid.y)
    assert np.max(np.abs(ref - nu)) < 1e-6
