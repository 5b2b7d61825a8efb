"""Cylindrical Couette flow of the Dsouza-Nott model (problems/nonlocal_flow/cylinder.py).

Reference computed here: at uniform phi (phi_w = phi_bar) the derived equation
ell^2 (gamma'' + gamma'/r - 4 gamma/r^2) = (1 - m (r_i/r)^2) gamma is the modified Bessel
equation of order nu = sqrt(4 - m r_i^2 / ell^2) in r/ell; gamma(r_o) = 0 (u = u' = 0 there),
u = -r int_r^{r_o} gamma/s ds (scipy quad) and the inner slip u - 1 = K gamma fix the solution.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import quad
from scipy.special import iv, kv

from contin.cli import main
from contin.continuation import newton
from contin.problem import check_jacobian
from problems.nonlocal_flow.cylinder import DEFAULTS, CylindricalCouette


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)


def bessel_u(p, r):
    ri = p["W"] / (p["ratio"] - 1)
    ro, ell, K = ri + p["W"], p["ell"], p["K"]
    nu = np.sqrt(4 - p["mu_w"] / p["mu"] * ri**2 / ell**2)
    c = iv(nu, ro / ell) / kv(nu, ro / ell)

    def g(x):
        return iv(nu, x / ell) - c * kv(nu, x / ell)

    def h(x):
        return -x * quad(lambda s: g(s) / s, x, ro, epsabs=1e-14, epsrel=1e-13, limit=200)[0]

    a = 1 / (h(ri) - K * g(ri))
    return np.array([a * h(x) for x in r])


def solve(pb, p):
    res = newton(pb, pb.initial(p), p)
    assert res.converged
    return res.u


@pytest.mark.parametrize("mu_w", [0.0, 0.05 * 0.3618])
def test_uniform_phi_matches_bessel_solution(mu_w):
    p = dict(DEFAULTS, phi_w=DEFAULTS["phi_bar"], mu_w=mu_w)
    pb = CylindricalCouette("cheb", 32)
    x = solve(pb, p)
    _, r = pb.radii(p)
    assert np.max(np.abs(x[pb.n:2 * pb.n] - bessel_u(p, r))) < 1e-12


@pytest.mark.parametrize("method,order,grids", [("fd2", 2, (32, 64, 128)), ("fd4", 4, (32, 64, 128)),
                                                ("fd6", 6, (32, 64, 128))])
def test_fd_convergence_orders(method, order, grids):
    p = dict(DEFAULTS, phi_w=DEFAULTS["phi_bar"], mu_w=0.0)
    errs = []
    for n in grids:
        pb = CylindricalCouette(method, n)
        _, r = pb.radii(p)
        errs.append(np.max(np.abs(solve(pb, p)[pb.n:2 * pb.n] - bessel_u(p, r))))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > order - 0.1) and np.all(orders < order + 0.8), orders


@pytest.mark.parametrize("operator", ["derived", "report"])
def test_jacobian_exact(operator):
    pb = CylindricalCouette("cheb", 20, operator=operator)
    p = dict(DEFAULTS)
    x = pb.initial(p)
    x[:pb.n] += 0.003 * np.cos(np.arange(pb.n))
    chk = check_jacobian(pb, x, p, parameters=pb.parameter_names)
    assert chk.relative_error < 1e-7
    assert max(chk.dp_errors.values()) < 1e-6


def test_derived_operator_vanishes_on_rigid_rotation_and_potential_vortex():
    r = np.linspace(5.0, 9.0, 7)
    for op, expect_vortex in (("derived", 0.0), ("report", -8.0)):
        a, b = CylindricalCouette(operator=op).a, CylindricalCouette(operator=op).b
        # u = r: u''' = 0, u' = 1; u = 1/r: u' = -1/r^2, u''' = -6/r^4
        np.testing.assert_allclose(a / r**2 + b / r**2, 0.0, atol=1e-15)
        np.testing.assert_allclose((-6 + a * -1 + b) / r**4, expect_vortex / r**4, atol=1e-15)


def test_coupled_solution_invariants():
    p = dict(DEFAULTS)
    pb = CylindricalCouette("cheb", 48)
    x = solve(pb, p)
    _, r = pb.radii(p)
    phi, u = x[:pb.n], x[pb.n:2 * pb.n]
    assert pb.grid.integrate(phi * r) / pb.grid.integrate(r) == pytest.approx(p["phi_bar"], abs=1e-15)
    assert u[-1] == 0.0 and abs((pb.d1 @ u)[-1]) < 1e-10
    # slip at the inner wall: u - 1 = K (u' - u/r) with gamma < 0 there
    gam = pb.shear_rate(x, p)
    assert u[0] - 1 == pytest.approx(p["K"] * gam[0], abs=1e-13)
    assert np.all(np.diff(u) < 0)


def run(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.mark.parametrize("setting,expect", [
    ("ratio=1", "radius ratio r_o/r_i must be > 1"),
    ("ell=0", "the non-local length ell must be > 0"),
    ("K=-1", "the slip coefficient K must be >= 0"),
    ("phi_bar=0.64", "phi_bar = 0.64 must lie strictly between"),
    ("mu_w=0.5", "mu_w < mu"),
    ("report_eqs=2", "report_eqs must be 0"),
])
def test_bad_input_is_one_error_line(setting, expect, tmp_path):
    res = run("trace", "nonlocal-cylinder", "-s", setting, "-o", str(tmp_path / "x.h5"))
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 1 and len(lines) == 1 and lines[0].startswith("Error: ") and expect in lines[0], lines


def test_scene_runs(tmp_path):
    res = run("trace", "nonlocal-cylinder", "--grid", "32", "-s", "ratio_max=3", "--no-stability", "-q", "--json",
              "-o", str(tmp_path / "c.h5"))
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert [b["id"] for b in doc["branches"]] == ["derived.ratio", "report.ratio"]
    assert all(b["status"] == "EP" for b in doc["branches"])
    assert 0 < doc["extra"]["derived"]["u_inner"] < 1
