"""gPCF at the edges of parameter space (issue 6): nearly elastic grains, dilute and nearly
packed flows, large gaps.  Each case is either traced correctly (grid stated) or must end
with a labelled reason; no inadmissible state (NaN, T <= 0, nu >= nu_m) may be accepted.

Exact values: H_n^c = n pi psi(nu, e) (physics.md section 4); uniform shear is an exact
discrete solution for every nu in (0, nu_m) (D1, D2 exact on constants and on u = y).
"""

from __future__ import annotations

import numpy as np
import pytest

from contin.continuation import newton, trace
from contin.options import ContinuationOptions, NewtonOptions, StepOptions
from problems.couette.closures import critical_gap_factor
from problems.couette.model import CouetteProblem
from problems.couette.params import build_params


def _uniform_trace(nu, e, h_lo, h_hi, n=32, method="cheb"):
    prob = CouetteProblem(method, n)
    p = build_params({"nu": nu, "e": e, "H": h_lo})
    opts = ContinuationOptions(step=StepOptions(ds=0.5, ds_max=(h_hi - h_lo) / 8), bounds={"H": (h_lo, h_hi)})
    return prob, trace(prob, prob.uniform_state(p), p, "H", opts)


@pytest.mark.parametrize("e,hc_expected", [(0.99, 78.37195444), (0.999, 251.88228429)])
def test_nearly_elastic_critical_gap_is_n_pi_psi(e, hc_expected):
    """e -> 1: H_1^c grows like (1 - e^2)^-1/2; cheb N = 32 still locates it to 1e-10."""
    hc = float(np.pi * critical_gap_factor(0.3, e))
    assert hc == pytest.approx(hc_expected, rel=1e-9)
    _, br = _uniform_trace(0.3, e, 0.8 * hc, 1.2 * hc)
    bps = [s for s in br.special_points if s.type == "BP"]
    assert br.status == "EP" and len(bps) == 1 and bps[0].note == "symmetry-breaking"
    assert abs(bps[0].params["H"] / hc - 1) < 1e-10


@pytest.mark.parametrize("nu", [0.02, 0.60, 0.64])
def test_uniform_shear_is_exact_and_admissible(nu):
    prob = CouetteProblem("cheb", 48)
    p = build_params({"nu": nu, "e": 0.8, "H": 50.0})
    x = prob.uniform_state(p)
    assert prob.admissible(x, p) is None
    assert np.max(np.abs(prob.residual(x, p))) < 1e-12 * max(1.0, float(np.max(np.abs(x))))
    res = newton(prob, x, p)
    assert res.converged and res.iterations == 0


def test_dilute_flow_has_no_banding_bifurcation():
    """nu = 0.02 lies below the threshold density 0.156 at e = 0.8: psi undefined, no BP up to H = 200."""
    assert np.isnan(critical_gap_factor(0.02, 0.8))
    _, br = _uniform_trace(0.02, 0.8, 1.0, 200.0)
    assert br.status == "EP" and not [s for s in br.special_points if s.type in ("BP", "LP")]


@pytest.mark.parametrize("nu,hc_expected", [(0.60, 29.925), (0.64, 66.652)])
def test_dense_flow_critical_gap(nu, hc_expected):
    """Near nu_m = 0.65 chi diverges; H_1^c stays n pi psi at cheb N = 32."""
    hc = float(np.pi * critical_gap_factor(nu, 0.8))
    assert hc == pytest.approx(hc_expected, rel=1e-3)
    _, br = _uniform_trace(nu, 0.8, 0.8 * hc, 1.2 * hc)
    bps = [s for s in br.special_points if s.type == "BP"]
    assert len(bps) == 1 and abs(bps[0].params["H"] / hc - 1) < 1e-10


def test_admissibility_guard_rejects_unphysical_states():
    prob = CouetteProblem("cheb", 16)
    p = build_params({"nu": 0.64, "e": 0.8, "H": 10.0})
    x = prob.uniform_state(p)
    bad_nu = x.copy()
    bad_nu[prob.i_nu][3] = 0.65
    bad_t = x.copy()
    bad_t[prob.i_T][5] = -1e-3
    bad_nan = x.copy()
    bad_nan[7] = np.nan
    assert "packing limit 0.65" in prob.admissible(bad_nu, p)
    assert "temperature not positive" in prob.admissible(bad_t, p)
    assert "non-finite" in prob.admissible(bad_nan, p)
    # Newton refuses to start from, and never steps into, an inadmissible state
    res = newton(prob, bad_nu, p, NewtonOptions())
    assert not res.converged and "inadmissible" in res.message


def test_banded_branch_near_packing_never_stores_inadmissible_states():
    """nu = 0.6, n = 1 banded branch up to 1.6 H_1^c: the dense band approaches nu_m; every
    stored state is admissible and the run either reaches the bound or ends labelled."""
    from contin.continuation import switch

    hc = float(np.pi * critical_gap_factor(0.6, 0.8))
    prob, br = _uniform_trace(0.6, 0.8, 0.8 * hc, 1.2 * hc)
    bp = [s for s in br.special_points if s.type == "BP"][0]
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.5, theta=1e-3), bounds={"H": (0.5 * hc, 1.6 * hc)},
                               max_steps=150)
    new = switch(prob, br, bp, opts, directions=(+1,))
    assert new, "switching failed"
    b = new[0]
    for i in range(len(b)):
        p = build_params({"nu": 0.6, "e": 0.8, "H": float(b.parameter_values[i])})
        assert prob.admissible(b.state(i), p) is None
    assert np.max(b.states[:, prob.i_nu]) < 0.65
    assert b.status == "EP" or b.message


@pytest.mark.slow
def test_large_gap_boundary_layers_need_a_finer_grid():
    """H = 500 at nu = 0.3, e = 0.8: uniform shear is exact at any grid; the BP n = 38 near
    H = 38 H_1^c = 496.6 is located to 1e-8 at cheb N = 128 (modes up to n = 38 need it)."""
    hc = float(np.pi * critical_gap_factor(0.3, 0.8))
    n_mode = int(500 // hc)
    _, br = _uniform_trace(0.3, 0.8, (n_mode - 0.5) * hc, 500.0, n=128)
    bps = [s for s in br.special_points if s.type == "BP"]
    assert len(bps) == 1
    assert abs(bps[0].params["H"] / (n_mode * hc) - 1) < 1e-8


# ------------------------------------------------------------------ strong gravity, Fr = 50
# G = Fr^-2 = 4e-4 at nu = 0.3, e = 0.8: the dense bottom plug approaches nu_m = 0.65
# exponentially in H (nu_m - max nu = 3.5e-1, 4.6e-4, 1.3e-5, 2e-7 at H = 1, 20, 24.5, 30)
# and the bottom temperature with it (T_bottom 2.5e-4 at H = 20, 1.3e-7 at H = 30.7).

FR50 = {"nu": 0.3, "e": 0.8, "Fr": 50.0}


def _gravity_trace(n: int, h_hi: float, max_steps: int = 400):
    from contin.options import DetectionOptions
    from problems.couette.gravity import gravity_problem

    prob = gravity_problem("cheb", n)
    p = prob.params({**FR50, "H": 1.0})
    opts = ContinuationOptions(bounds={"H": (1.0, h_hi)}, max_steps=max_steps,
                               step=StepOptions(ds=0.1, ds_max=1.0, max_angle=0.2),
                               detection=DetectionOptions(detect_branch_points=False))
    return prob, p, trace(prob, prob.initial_guess(p), p, "H", opts, symmetric=False)


def _fr50_checks(prob, p, br):
    """Per stored point: admissibility, pressure drop / (H^3 G nubar) - 1, mass - nubar, shear defect."""
    from problems.couette.closures import coefficients

    rows = []
    for i in range(len(br)):
        x = br.state(i)
        q = {**p, "H": float(br.params["H"][i])}
        f = prob.profiles(x)
        pyy = coefficients(f["nu"], q["e"], "jj", q["num"]).f1 * f["T"]  # p_yy = f1(nu) T
        drop = (pyy[0] - pyy[-1]) / (q["H"] ** 3 * q["G"] * q["nu"])  # y[0] = -1/2 (bottom)
        rows.append((prob.admissible(x, q), drop - 1.0, prob.grid.integrate(f["nu"]) - q["nu"],
                     prob.momentum_balance(x, q)["shear_stress"], f))
    return rows


def test_strong_gravity_fr50_bottom_plug_resolved_up_to_h20():
    """Fr = 50, H in [1, 20]: the trace reaches the bound with admissible states; the weight of
    the column is carried by the normal stress, p_yy(-1/2) - p_yy(1/2) = H^3 G nubar (the
    integrated y-momentum balance, physics.md section 2), and the mass is nubar.  The shear
    stress S = f2 sqrt(T) u' must be constant (x-momentum, not imposed pointwise): its defect
    measures resolution, 1.7e-3 / 8.7e-6 / 8.4e-8 at cheb N = 32 / 48 / 64 -> N >= 48."""
    assert prob_G(50.0) == pytest.approx(4e-4, rel=1e-15)
    prob, p, br = _gravity_trace(64, 20.0)
    assert br.status == "EP" and br.message.startswith("reached bound H") and br.params["H"][-1] == 20.0
    assert not br.fold_points
    rows = _fr50_checks(prob, p, br)
    for adm, drop, mass, shear, f in rows:
        assert adm is None
        assert 0 < f["nu"].min() and f["nu"].max() < 0.65 and f["T"].min() > 0
        assert abs(drop) < 1e-8 and abs(mass) < 1e-12
        assert shear < 1e-6
    f = rows[-1][4]
    assert f["nu"][0] == pytest.approx(0.6496, abs=1e-4)  # bottom plug near nu_m at H = 20
    assert f["nu"][-1] < 0.1 and f["T"][0] < 1e-3 * f["T"][-1]  # dilute, hot top
    defects = {n: max(r[3] for r in _fr50_checks(*_gravity_trace(n, 20.0))) for n in (32, 48)}
    assert defects[32] > 1e-4 and 1e-7 < defects[48] < 1e-4


def prob_G(fr: float) -> float:
    from problems.couette.params import froude_to_gravity

    return froude_to_gravity(fr)


def test_strong_gravity_fr50_stops_mx_where_the_plug_reaches_packing():
    """Fr = 50 traced towards H = 60 at cheb N = 64 ends MX near H = 30.7, where nu_m - max nu
    is below 1e-7 and T_bottom ~ 1e-7; no stored state is inadmissible (Newton's guard).  Up to
    H = 22.5 (shear defect < 1e-5 at N = 64) the pressure drop is H^3 G nubar to 1e-10; it
    degrades to 3e-5 at the under-resolved points before the stop (xfail test below)."""
    prob, p, br = _gravity_trace(64, 60.0)
    assert br.status == "MX" and br.message
    assert 29.0 < br.params["H"][-1] < 32.0
    rows = _fr50_checks(prob, p, br)
    assert all(r[0] is None for r in rows)
    resolved = [r for r, h in zip(rows, br.params["H"]) if h <= 22.5]
    assert len(resolved) > 20
    assert max(abs(r[1]) for r in resolved) < 1e-10 and max(r[3] for r in resolved) < 1e-5
    f = rows[-1][4]
    assert 0 < 0.65 - f["nu"].max() < 1e-6 and 0 < f["T"].min() < 1e-6


@pytest.mark.xfail(strict=True, reason=(
    "Fr = 50, cheb 64: between H = 23 and the MX at H = 30.7 the stored states are under-resolved "
    "(shear-stress defect 2e-4 -> 0.125, pressure drop off H^3 G nubar by up to 2.8e-5, while "
    "nu_m - max nu falls to 8.6e-8) yet pass admissible(); "
    "the MX message says 'no convergence', not the packing-limit reason.  Needs a resolution/"
    "near-packing guard in Newton or the problem (not in this test's files)."))
def test_strong_gravity_fr50_stop_is_labelled_with_the_admissibility_reason():
    prob, p, br = _gravity_trace(64, 60.0)
    rows = _fr50_checks(prob, p, br)
    assert max(r[3] for r in rows) < 1e-3 and max(abs(r[1]) for r in rows) < 1e-8
    assert "packing limit" in br.message
