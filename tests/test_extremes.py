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
    stored state is admissible.  At cheb 32 the resolution guard ends the run (MX) near
    H = 44.5 = 1.49 H_1^c, with the plug 3.6e-5 below nu_m; cheb 48 reaches the bound with every
    state resolved (the advice), the plug 5e-6 below nu_m."""
    from contin.continuation import switch
    from problems.couette.resolution import resolution

    hc = float(np.pi * critical_gap_factor(0.6, 0.8))
    for n in (32, 48):
        prob, br = _uniform_trace(0.6, 0.8, 0.8 * hc, 1.2 * hc, n=n)
        bp = next(s for s in br.special_points if s.type == "BP")
        opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.5, theta=1e-3),
                                   bounds={"H": (0.5 * hc, 1.6 * hc)}, max_steps=150)
        new = switch(prob, br, bp, opts, directions=(+1,))
        assert new, "switching failed"
        b = new[0]
        for i in range(len(b)):
            p = build_params({"nu": 0.6, "e": 0.8, "H": float(b.parameter_values[i])})
            assert prob.admissible(b.state(i), p) is None
            assert resolution(prob, b.state(i), p).error <= 3e-5
            assert prob.momentum_balance(b.state(i), p)["shear_stress"] < 1e-6
        assert np.max(b.states[:, prob.i_nu]) < 0.65
        if n == 32:
            assert b.status == "MX" and b.message.startswith("under-resolved at H = ")
            assert 1.4 * hc < b.parameter_values[-1] < 1.55 * hc and "packing limit nu_m = 0.65" in b.message
        else:
            assert b.status == "EP" and b.parameter_values[-1] == 1.6 * hc
            assert 0 < 0.65 - np.max(b.states[:, prob.i_nu]) < 1e-5


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


def _gravity_trace(n: int, h_hi: float, max_steps: int = 400, **options):
    from contin.options import DetectionOptions
    from problems.couette.gravity import gravity_problem

    prob = gravity_problem("cheb", n)
    p = prob.params({**FR50, "H": 1.0})
    opts = ContinuationOptions(bounds={"H": (1.0, h_hi)}, max_steps=max_steps,
                               step=StepOptions(ds=0.1, ds_max=1.0, max_angle=0.2),
                               detection=DetectionOptions(detect_branch_points=False), **options)
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
    measures resolution, 1.7e-3 / 8.7e-6 / 8.4e-8 at cheb N = 32 / 48 / 64 with the guard off;
    the default guard stops N = 32 near H = 16 and N = 48 near H = 19.9, N = 64 reaches H = 20."""
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
    defects = {n: max(r[3] for r in _fr50_checks(*_gravity_trace(n, 20.0, resolution_tol=None))) for n in (32, 48)}
    assert defects[32] > 1e-4 and 1e-7 < defects[48] < 1e-4
    # The default resolution guard (3e-5) is stricter than 'defect < 1e-4': N = 32 and 48 end MX
    # under-resolved before H = 20 (near H = 16 and 19.9: tail of nu > 3e-5 of nu_m - max nu).
    for n, (lo, hi) in ((32, (15.0, 17.0)), (48, (18.5, 20.0))):
        prob, p, br = _gravity_trace(n, 20.0)
        h_stop, advice = _stop(br)
        assert lo < h_stop < hi and br.params["H"][-1] < h_stop and advice >= 1.5 * n
        assert max(r[3] for r in _fr50_checks(prob, p, br)) < 2e-5


def _stop(br) -> tuple[float, int]:
    """(value of H at the under-resolved point that ended the run, the grid the message advises)."""
    import re

    m = re.fullmatch(r"under-resolved at H = ([0-9.]+): .*; refine the grid \(try --grid (\d+)\)", br.message)
    assert br.status == "MX" and m, br.message
    return float(m.group(1)), int(m.group(2))


def prob_G(fr: float) -> float:
    from problems.couette.params import froude_to_gravity

    return froude_to_gravity(fr)


def test_strong_gravity_fr50_without_the_guard_runs_into_under_resolved_states():
    """Guard off (resolution_tol=None): Fr = 50 traced towards H = 60 at cheb N = 64 ends MX near
    H = 30.7 with Newton's 'no convergence', where nu_m - max nu is below 1e-7 and T_bottom ~ 1e-7;
    Newton's guard keeps every stored state admissible, but between H = 23 and the stop the stored
    states are under-resolved: shear-stress defect up to 0.12, pressure drop off H^3 G nubar by
    up to 3.6e-6.  This is what the resolution guard (next tests) prevents.  Up to H = 22.5 the
    pressure drop holds to 1e-7 here (to 1e-10: next test)."""
    prob, p, br = _gravity_trace(64, 60.0, resolution_tol=None)
    assert br.status == "MX" and "no convergence" in br.message
    assert 29.0 < br.params["H"][-1] < 32.0
    rows = _fr50_checks(prob, p, br)
    assert all(r[0] is None for r in rows)
    resolved = [r for r, h in zip(rows, br.params["H"]) if h <= 22.5]
    assert len(resolved) > 20
    assert max(abs(r[1]) for r in resolved) < 1e-7 and max(r[3] for r in resolved) < 1e-5
    assert max(r[3] for r in rows) > 0.1 and max(abs(r[1]) for r in rows) > 1e-6
    f = rows[-1][4]
    assert 0 < 0.65 - f["nu"].max() < 1e-6 and 0 < f["T"].min() < 1e-6


def test_strong_gravity_fr50_pressure_drop_exact_on_resolved_states():
    """Plain Newton (the chord corrector of commit 39ceb15 left 2.7e-8 here and was removed)."""
    prob, p, br = _gravity_trace(64, 60.0, resolution_tol=None)
    rows = _fr50_checks(prob, p, br)
    resolved = [r for r, h in zip(rows, br.params["H"]) if h <= 22.5]
    assert max(abs(r[1]) for r in resolved) < 1e-10


def test_strong_gravity_fr50_stop_is_labelled_under_resolved_near_packing():
    """Default guard (resolution_tol = 3e-5): the run stops MX at the first converged point whose
    estimated error exceeds 3e-5, between H = 21 and 23 (H = 21.84 at cheb 64: tail of nu 3.9e-5 of
    the distance to packing, plug 9.3e-5 below nu_m), without storing it.  Every stored state is resolved:
    shear-stress defect < 1e-6 (3.5e-7), pressure drop H^3 G nubar to 1e-8, mass nubar to 1e-12."""
    from problems.couette.resolution import resolution

    prob, p, br = _gravity_trace(64, 60.0)
    h_stop, advice = _stop(br)
    assert 21.0 < h_stop < 23.0 and 20.5 < br.params["H"][-1] < h_stop and advice >= 96
    assert "of the packing limit nu_m = 0.65" in br.message
    assert br.special_points[-1].type == "MX" and br.special_points[-1].note == br.message
    rows = _fr50_checks(prob, p, br)
    assert len(rows) > 20 and all(r[0] is None for r in rows)
    assert max(r[3] for r in rows) < 1e-6 and max(abs(r[1]) for r in rows) < 1e-8
    assert max(abs(r[2]) for r in rows) < 1e-12
    errors = [resolution(prob, br.state(i), {**p, "H": h}).error for i, h in enumerate(br.params["H"])]
    assert max(errors) <= 3e-5 and errors[-1] > 3e-6


def test_strong_gravity_fr50_advised_grid_resolves_further():
    """The advice (cheb >= 96) holds: at cheb 96 the run passes the cheb-64 stop and ends, labelled,
    between H = 25 and 28 (26.57: plug within 2.7e-6 of nu_m); no stored state has a
    shear-stress defect above 1e-6."""
    prob, p, br = _gravity_trace(96, 60.0)
    h_stop, _ = _stop(br)
    assert 25.0 < h_stop < 28.0 and br.params["H"][-1] > 23.0
    assert max(r[3] for r in _fr50_checks(prob, p, br)) < 1e-6


# ------------------------------------------------------------------ the resolution estimate itself

def test_chebyshev_coefficients_and_tail_of_known_series():
    from problems.couette.resolution import chebyshev_coefficients, tail
    from problems.discretization import make_grid

    y = make_grid("cheb", 16).y
    a = np.zeros(17)
    a[[0, 3, 16]] = [0.5, -0.25, 1e-9]
    values = np.polynomial.chebyshev.chebval(2 * y, a)
    assert np.max(np.abs(chebyshev_coefficients(values) - a)) < 1e-15
    assert tail(chebyshev_coefficients(values)) == pytest.approx(1e-9, rel=1e-6)
    # geometric decay rho^-k: the tail is the last coefficients' size, rho^-(N - 3) for N = 16
    rho = 3.0
    b = rho ** -np.arange(17.0)
    assert tail(chebyshev_coefficients(np.polynomial.chebyshev.chebval(2 * y, b))) == pytest.approx(rho ** -13)


@pytest.mark.parametrize("method,N", [("cheb", 32), ("fd2", 32), ("fd4", 16), ("fd6", 24)])
def test_uniform_shear_is_resolved_on_every_grid(method, N):
    """Constants and u = y have no tail on any grid (FD: the degree-7 interpolant is exact on them);
    what remains is the rounding estimate 0.2 eps N^2 nu_m / gap (3e-12 at cheb 32, gap 0.01; FD 5 N for N^2)."""
    from problems.couette.resolution import resolution

    prob = CouetteProblem(method, N)
    p = build_params({"nu": 0.64, "e": 0.8, "H": 50.0})
    r = resolution(prob, prob.uniform_state(p), p)
    assert r.truncation < 1e-13 and r.gap == pytest.approx(0.01, abs=1e-12)
    scale = N**2 if method == "cheb" else 5 * N  # rounding grows like 1/(smallest spacing)
    assert r.rounding == pytest.approx(0.2 * np.finfo(float).eps * scale * 0.65 / 0.01, rel=1e-9)
    assert r.error == r.rounding and r.precision_limited
    assert prob.under_resolved(prob.uniform_state(p), p, 1e-11) is None


def test_distance_to_packing_sets_the_scale():
    """The same tail counts gap^-1 times more next to nu_m: a T_64 ripple of 1e-10 on nu is resolved
    (relative 1e-10/0.6) on a profile 0.05 below packing and under-resolved on one 1e-6 below."""
    from problems.couette.resolution import resolution

    prob = CouetteProblem("cheb", 64)
    p = build_params({"nu": 0.3, "e": 0.8, "H": 20.0})
    y = prob.grid.y
    ripple = 1e-10 * np.cos(64 * np.arccos(2 * y))
    for top, expect in ((0.60, 1e-10 / 0.05), (0.65 - 1e-6, 1e-10 / 1e-6)):
        nu = 0.3 + (top - 0.3) * (y + 0.5) ** 2 + ripple
        x = prob.pack(nu, y, np.full(y.size, 0.1), 1.0)
        r = resolution(prob, x, p)
        assert r.field == "nu" and r.error == pytest.approx(expect, rel=1e-3)
    reason = prob.under_resolved(x, p, 3e-5)
    assert reason.startswith("Chebyshev tail of nu 1e-10 is 0.0001 of the distance to packing (> 3e-05)")
    assert "plug within 1e-06 of the packing limit nu_m = 0.65" in reason
