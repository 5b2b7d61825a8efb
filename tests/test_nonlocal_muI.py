"""The mu(I) extension of the Dsouza-Nott model in plane shear, and the phi(I) comparison branch.

References computed here: scipy solve_bvp of the coupled problem with mu(I) inside the
gamma equation; the exact scaling P = U^2 P_1 of the local phi(I) law (phi = phi_max - A I
with I = U gamma / sqrt(P) makes (phi, gamma) independent of U); the report's mu(I) values.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_bvp

from contin.cli import main
from contin.continuation import newton
from problems.nonlocal_flow.closures import CriticalState, mu_of_I
from problems.nonlocal_flow.plane import DEFAULTS, PlaneShear


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)


def test_mu_of_I_is_the_report_form():
    I = np.array([1e-3, 0.05, 0.1005, 1.0])
    mu, dmu = mu_of_I(I, 0.3618, 0.3367, 0.1005)
    np.testing.assert_allclose(mu, 0.3618 + 0.3367 / (0.1005 / I + 1), rtol=1e-15)
    assert mu_of_I(0.0, 0.3618, 0.3367, 0.1005)[0] == 0.3618  # the quasi-static limit
    np.testing.assert_allclose(dmu, (mu_of_I(I + 1e-7, 0.3618, 0.3367, 0.1005)[0]
                                     - mu_of_I(I - 1e-7, 0.3618, 0.3367, 0.1005)[0]) / 2e-7, rtol=1e-7)


def test_mu_I_coupled_problem_against_solve_bvp():
    p = dict(DEFAULTS, U=0.5)
    cs = CriticalState()
    pb = PlaneShear("cheb", 64)
    res = newton(pb, pb.initial(p), p)
    assert res.converged
    x = res.u
    W, ell, K, U = p["W"], p["ell"], p["K"], p["U"]

    def rhs(y, s, q):
        phi, dphi, _, gam, dgam, _ = s
        pi, dpi, _ = cs.pi(phi)
        mu = mu_of_I(U * gam / np.sqrt(q[0]), p["mu"], p["dmu"], p["I0"])[0]
        return np.vstack([dphi, (pi - q[0]) / (ell**2 * dpi), phi, dgam,
                          q[0] * (1 - p["mu_w"] / mu) * gam / (ell**2 * pi), gam])

    def bc(a, b, q):
        return np.array([a[0] - p["phi_w"], b[0] - p["phi_w"], a[2], b[2] - p["phi_bar"] * W,
                         a[5] - K * a[3], b[5] - 1 + K * b[3], a[3] - b[3]])

    y = np.linspace(0, W, 400)
    s0 = np.vstack([np.full_like(y, p["phi_bar"]), 0 * y, p["phi_bar"] * y, np.full_like(y, 1 / W), 0 * y, y / W])
    sol = solve_bvp(rhs, bc, y, s0, p=[cs.pi(p["phi_bar"])[0]], tol=1e-10, max_nodes=100000)
    assert sol.success
    yy = pb.y(p)
    assert np.max(np.abs(pb.velocity(x, p) - sol.sol(yy)[5])) < 1e-7
    assert np.max(np.abs(x[pb.n:2 * pb.n] / W - sol.sol(yy)[3])) < 1e-7
    # inertia raises mu at the walls: the shear localizes more than in the quasi-static limit
    x0 = newton(pb, pb.initial(DEFAULTS), DEFAULTS).u
    assert pb.observables(x, p)["delta"] < pb.observables(x0, DEFAULTS)["delta"]


def test_phi_I_branch_scales_with_U_squared():
    pb = PlaneShear("cheb", 32, phi_model="phiI")
    sols = []
    for U in (0.1, 0.4, 1.3):
        p = dict(DEFAULTS, U=U)
        res = newton(pb, pb.initial(p), p)
        assert res.converged
        sols.append((U, res.u))
    (U0, x0) = sols[0]
    for U, x in sols[1:]:
        np.testing.assert_allclose(x[:-1], x0[:-1], atol=1e-12)
        assert x[-1] / U**2 == pytest.approx(x0[-1] / U0**2, rel=1e-12)
    # the local law: phi = phi_max - A I at every node, mean phi_bar
    p = dict(DEFAULTS, U=0.4)
    x = sols[1][1]
    np.testing.assert_allclose(x[:pb.n], CriticalState().phi_max - p["A_phi"] * pb.inertial_number(x, p), atol=1e-14)
    assert pb.grid.integrate(x[:pb.n]) == pytest.approx(p["phi_bar"], abs=1e-15)


def test_scene_runs(tmp_path):
    res = CliRunner().invoke(main, ["trace", "nonlocal-muI", "--grid", "32", "-s", "U_max=0.8", "--no-stability", "-q",
                                    "--json", "-o", str(tmp_path / "m.h5")], catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert [b["id"] for b in doc["branches"]] == ["muI.U", "phiI.U"]
    ex = doc["extra"]
    assert ex["muI"]["quasi_static_difference"] < 1e-14
    assert 0.3 < ex["muI"]["U_at_I_max_0.1"] < 0.8 and ex["muI"]["I_max_end"] > 0.1
    assert ex["phiI"]["P_over_U2_spread"] < 1e-10


@pytest.mark.parametrize("setting,expect", [("A_phi=0", "A_phi must be > 0"), ("I0=0", "I0 > 0"),
                                            ("U_max=-1", "need 0 < U_min_phiI < U_max"),
                                            ("phi_bar=0.65", "must lie strictly between")])
def test_bad_input(setting, expect, tmp_path):
    res = CliRunner().invoke(main, ["trace", "nonlocal-muI", "-s", setting, "-o", str(tmp_path / "x.h5")],
                             catch_exceptions=False)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 1 and len(lines) == 1 and lines[0].startswith("Error: ") and expect in lines[0], lines
