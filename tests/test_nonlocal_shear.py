"""Plane shear of the Dsouza-Nott non-local model (problems/nonlocal_flow, docs/nonlocal.md).

References computed here: the closed-form sinh profile (re-derived: the ODE and both slip
conditions are checked on the formula itself), its FD/Chebyshev convergence orders, an
independent scipy solve_bvp solution of the coupled phi-u boundary-value problem with the mean
constraint, finite-difference Jacobians (contin.problem.check_jacobian), and bad input through
the real CLI.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_bvp

from contin.cli import main
from contin.continuation import newton
from contin.problem import check_jacobian
from problems.nonlocal_flow.closures import CriticalState, PlaneShearAnalytic
from problems.nonlocal_flow.plane import DEFAULTS, PlaneShear

PAIRS = [(1.65, 0.33), (0.95, 0.1)]


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)


def params(**kw):
    p = dict(DEFAULTS)
    p.update(kw)
    return p


def solve(pb, p):
    res = newton(pb, pb.initial(p), p)
    assert res.converged
    return res.u


@pytest.mark.parametrize("K,mu_w", PAIRS)
def test_sinh_profile_solves_the_ode_and_both_slip_conditions(K, mu_w):
    an = PlaneShearAnalytic(40.0, K, 3.0, mu_w, 0.3618)
    z, b, W = an.zeta, an.beta, 40.0
    y = np.linspace(0, W, 11)
    # u = 1/2 + sinh(z (y - W/2)) / (2 b): u''' = z^2 u' (l^2 u''' = (1 - mu_w/mu) u')
    d3 = z**3 * np.cosh(z * (y - W / 2)) / (2 * b)
    np.testing.assert_allclose(3.0**2 * d3, (1 - mu_w / 0.3618) * an.dudy(y), rtol=1e-13)
    assert an.u(0.0) - K * an.dudy(0.0) == pytest.approx(0.0, abs=1e-15)  # wall at rest: u = K u'
    assert an.u(W) + K * an.dudy(W) == pytest.approx(1.0, abs=1e-15)  # moving wall: u - 1 = -K u'
    assert an.u(W / 2) == pytest.approx(0.5, abs=1e-15)
    # the report's sign is the mirror image: it violates the slip condition at the wall at rest
    assert abs(an.report_profile(0.0) - K * -an.dudy(0.0)) > 0.5


def test_report_sign_puts_the_wall_at_rest_at_093():
    an = PlaneShearAnalytic(40.0, 1.65, 3.0, 0.33, 0.3618)
    z = np.sqrt(1 - 0.33 / 0.3618) / 3.0
    beta = 1.65 * z * np.cosh(20 * z) + np.sinh(20 * z)
    assert an.report_profile(0.0) == pytest.approx(0.5 + np.sinh(20 * z) / (2 * beta), rel=1e-15)
    assert round(float(an.report_profile(0.0)), 2) == 0.93
    assert an.u(0.0) == pytest.approx(1 - 0.9275545365286193, rel=1e-12)


@pytest.mark.parametrize("K,mu_w", PAIRS)
def test_uniform_phi_matches_closed_form_to_rounding(K, mu_w):
    p = params(K=K, mu_w=mu_w, phi_w=DEFAULTS["phi_bar"])
    pb = PlaneShear("cheb", 64)
    x = solve(pb, p)
    an = PlaneShearAnalytic(p["W"], K, p["ell"], mu_w, p["mu"])
    y = pb.y(p)
    assert np.max(np.abs(pb.velocity(x, p) - an.u(y))) < 5e-14
    assert np.max(np.abs(x[pb.n:2 * pb.n] / p["W"] - an.dudy(y))) < 5e-14
    # uniform phi: P = Pi(phi_bar), phi = phi_bar exactly
    assert x[-1] == pytest.approx(CriticalState().pi(p["phi_bar"])[0], rel=1e-14)
    obs = pb.observables(x, p)
    assert obs["delta"] == pytest.approx(an.wall_layer, rel=1e-11)


@pytest.mark.parametrize("method,order,grids", [("fd2", 2, (32, 64, 128)), ("fd4", 4, (32, 64, 128)),
                                                ("fd6", 6, (24, 48, 96))])
def test_fd_convergence_orders(method, order, grids):
    p = params(phi_w=DEFAULTS["phi_bar"])
    an = PlaneShearAnalytic(p["W"], p["K"], p["ell"], p["mu_w"], p["mu"])
    errs = []
    for n in grids:
        pb = PlaneShear(method, n)
        errs.append(np.max(np.abs(pb.velocity(solve(pb, p), p) - an.u(pb.y(p)))))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > order - 0.1) and np.all(orders < order + 0.7), orders


def test_chebyshev_converges_exponentially_on_a_thin_layer():
    # pair 2 at ell = 1.5: zeta W/2 = 11.3, layer 1.8 d_p: the error falls by > 10x per 2 nodes
    p = params(K=0.95, mu_w=0.1, ell=1.5, phi_w=DEFAULTS["phi_bar"])
    an = PlaneShearAnalytic(p["W"], 0.95, 1.5, 0.1, p["mu"])
    errs = []
    for n in (14, 16, 18, 20, 24):
        pb = PlaneShear("cheb", n)
        errs.append(np.max(np.abs(pb.velocity(solve(pb, p), p) - an.u(pb.y(p)))))
    assert all(b < a / 10 for a, b in zip(errs, errs[1:])), errs
    pb = PlaneShear("cheb", 96)
    assert np.max(np.abs(pb.velocity(solve(pb, p), p) - an.u(pb.y(p)))) < 1e-13


@pytest.mark.parametrize("phi_model,extra", [("nonlocal", {}), ("nonlocal", {"U": 0.7}), ("phiI", {"U": 0.7})])
def test_jacobian_exact(phi_model, extra):
    pb = PlaneShear("cheb", 20, phi_model=phi_model)
    p = params(**extra)
    x = pb.initial(p)
    rng = np.random.default_rng(3)
    x[:pb.n] += 0.004 * rng.standard_normal(pb.n)
    x[pb.n:2 * pb.n] *= 1 + 0.1 * rng.standard_normal(pb.n)
    names = ("W", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w", "U", "dmu", "I0", "A_phi")
    chk = check_jacobian(pb, x, p, parameters=names)
    assert chk.relative_error < 1e-7
    assert max(chk.dp_errors.values()) < 1e-6


def _bvp_reference(p, cs=CriticalState()):
    """The coupled problem by scipy solve_bvp: states (phi, phi', m, gamma, gamma', u), parameter P."""
    W, ell, K = p["W"], p["ell"], p["K"]
    g = 1 - p["mu_w"] / p["mu"]

    def rhs(y, s, q):
        phi, dphi, _, gam, dgam, _ = s
        pi, dpi, _ = cs.pi(phi)
        return np.vstack([dphi, (pi - q[0]) / (ell**2 * dpi), phi, dgam, q[0] * g * gam / (ell**2 * pi), gam])

    def bc(a, b, q):
        return np.array([a[0] - p["phi_w"], b[0] - p["phi_w"], a[2], b[2] - p["phi_bar"] * W,
                         a[5] - K * a[3], b[5] - 1 + K * b[3], a[3] - b[3]])

    y = np.linspace(0, W, 400)
    s0 = np.vstack([np.full_like(y, p["phi_bar"]), 0 * y, p["phi_bar"] * y, np.full_like(y, 1 / W), 0 * y, y / W])
    sol = solve_bvp(rhs, bc, y, s0, p=[cs.pi(p["phi_bar"])[0]], tol=1e-10, max_nodes=100000)
    assert sol.success, sol.message
    return sol


@pytest.mark.parametrize("K,mu_w", PAIRS)
def test_coupled_problem_against_solve_bvp(K, mu_w):
    p = params(K=K, mu_w=mu_w)
    pb = PlaneShear("cheb", 64)
    x = solve(pb, p)
    ref = _bvp_reference(p)
    y = pb.y(p)
    phi_ref, u_ref = ref.sol(y)[0], ref.sol(y)[5]
    assert x[-1] == pytest.approx(ref.p[0], rel=1e-7)
    assert np.max(np.abs(x[:pb.n] - phi_ref)) < 1e-8
    assert np.max(np.abs(pb.velocity(x, p) - u_ref)) < 1e-7
    # the mean constraint, and the reflection invariants: phi even, u - 1/2 odd
    assert pb.grid.integrate(x[:pb.n]) == pytest.approx(p["phi_bar"], abs=1e-15)
    obs = pb.observables(x, p)
    assert obs["asym_phi"] < 1e-13 and obs["asym_u"] < 1e-13
    # dilated walls: phi_w < phi_mid, and the shear localizes more than at uniform phi
    an = PlaneShearAnalytic(p["W"], K, p["ell"], mu_w, p["mu"])
    assert obs["phi_mid"] > p["phi_bar"] > p["phi_w"]
    assert obs["delta"] < an.wall_layer


def test_resolution_guard_flags_thin_layers_only():
    p = params(K=0.95, mu_w=0.1, ell=1.0)
    coarse, fine = PlaneShear("cheb", 32), PlaneShear("cheb", 96)
    reason = coarse.under_resolved(solve(coarse, p), p, 3e-5)
    assert reason is not None and "need a finer --grid than 32" in reason
    assert fine.under_resolved(solve(fine, p), p, 3e-5) is None
    # the shipped defaults are resolved on the scene's grid far below the guard
    pb = PlaneShear("cheb", 48)
    assert pb.under_resolved(solve(pb, params()), params(), 1e-10) is None


def test_mu_I_at_zero_speed_is_the_quasi_static_model():
    pb = PlaneShear("cheb", 32)
    x0 = solve(pb, params())
    x1 = solve(pb, params(U=0.0, dmu=0.5, I0=0.01))
    np.testing.assert_allclose(x1, x0, atol=1e-14)


def run(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


BAD = [
    (["phi_bar=0.64"], "phi_bar = 0.64 must lie strictly between"),
    (["phi_bar=0.7"], "phi_bar = 0.7 must lie strictly between"),
    (["mu_w=0.4"], "wall friction must be below the internal friction (mu_w < mu)"),
    (["mu_w2=0.3618"], "wall friction must be below the internal friction (mu_w < mu)"),
    (["ell=0"], "the non-local length ell must be > 0, got ell = 0"),
    (["ell=-2"], "the non-local length ell must be > 0, got ell = -2"),
    (["K=-0.5"], "the slip coefficient K must be >= 0, got K = -0.5"),
    (["phi_w=0.45"], "phi_w = 0.45 must lie in (phi_min, phi_max)"),
    (["foo=1"], "unknown parameter 'foo' for scene 'nonlocal-shear'"),
]


@pytest.mark.parametrize("settings,expect", BAD)
def test_bad_input_is_one_error_line(settings, expect, tmp_path):
    args = ["trace", "nonlocal-shear"]
    for s in settings:
        args += ["-s", s]
    res = run(*args, "-o", str(tmp_path / "x.h5"))
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 1
    assert len(lines) == 1 and lines[0].startswith("Error: ") and expect in lines[0], lines
    assert res.stdout == ""


def test_bad_input_in_a_subprocess(tmp_path):
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("CONTIN_SCENES", "CONTIN_DEBUG")}
    res = subprocess.run([sys.executable, "-m", "contin", "trace", "nonlocal-shear", "-s", "phi_bar=0.64", "-o",
                          str(tmp_path / "x.h5")], capture_output=True, text=True, env=env, timeout=120)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 1 and len(lines) == 1 and lines[0].startswith("Error: "), res.stderr
    assert "phi_bar = 0.64 must lie strictly between" in lines[0] and "Traceback" not in res.stderr
    assert res.stdout == ""


def test_scene_runs_small(tmp_path):
    out = tmp_path / "s.h5"
    res = run("trace", "nonlocal-shear", "--grid", "32", "-s", "ell_min=2", "-s", "ell_max=4", "-s", "W_min=32", "-s", "W_max=48", "--no-stability",
              "-q", "--json", "-o", str(out))
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["extra"]["analytic"]["max_abs_error_u"] < 1e-12
    assert doc["extra"]["analytic"]["max_rel_error_delta"] < 1e-9
    for k in (1, 2):
        assert doc["extra"][f"pair{k}"]["max_asymmetry"] < 1e-12
    assert {b["id"] for b in doc["branches"]} == {"uniform.ell", "pair1.ell", "pair1.mu_w", "pair1.W",
                                                 "pair2.ell", "pair2.mu_w", "pair2.W"}
    assert all(b["status"] == "EP" for b in doc["branches"])


@pytest.mark.slow
def test_default_scene_reaches_every_bound(tmp_path):
    res = run("trace", "nonlocal-shear", "--no-stability", "-q", "--json", "-o", str(tmp_path / "d.h5"))
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert all(b["status"] == "EP" for b in doc["branches"])
    for k, (K, mu_w) in enumerate(PAIRS, start=1):
        ex = doc["extra"][f"pair{k}"]
        an = PlaneShearAnalytic(40.0, K, 3.0, mu_w, 0.3618)
        assert ex["uniform_delta"] == pytest.approx(an.wall_layer, rel=1e-14)
        assert ex["delta"] < an.wall_layer  # dilated walls sharpen the layer
        assert ex["max_asymmetry"] < 1e-12
