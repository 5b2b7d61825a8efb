"""The solve_bvp baseline (benchmarks/baseline_solve_bvp.py) is right before it is timed.

Numbers: uniform shear (physics.md section 4), the neutral mode at H_1^c, H_1^c = pi psi by
delta-pinning, the mode-n hierarchy H_n^c = n H_1^c, the order of the pinning extrapolation,
and the fold at nubar = 0.16 that natural-parameter continuation cannot pass.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.baseline_solve_bvp import (
    GPCF,
    M,
    NU,
    Q,
    T,
    U,
    _callbacks,
    banded_start,
    critical_gap_by_pinning,
    fixed_h_point,
    fold_by_pinning,
    natural_continuation,
    pinned_branch,
    richardson_delta2,
    start_near_critical,
)


@pytest.fixture(scope="module")
def m03():
    return GPCF(0.3, 0.8)


def test_uniform_shear_solves_the_first_order_system(m03):
    x = np.linspace(-0.5, 0.5, 41)
    y, s0 = m03.uniform(x)
    assert y[T, 0] == pytest.approx(0.48174, abs=5e-6)  # physics.md section 4 reference values
    assert s0 == pytest.approx(0.32282, abs=5e-6)
    dy = m03.rhs(x, y, s0, 13.0)
    exact = np.vstack([np.ones_like(x), 0 * x, 0 * x, 0 * x, np.full_like(x, 0.3)])  # d/dy of u=y, M=nubar(y+1/2)
    np.testing.assert_allclose(dy, exact, atol=1e-14)
    fun, bc, _, _ = _callbacks(m03, 13.0, None, "odd", True)
    np.testing.assert_allclose(bc(y[:, 0], y[:, -1], np.array([s0])), 0.0, atol=1e-15)


def test_exact_jacobians_match_finite_differences(m03):
    x = np.linspace(-0.5, 0.5, 7)
    y, s0 = m03.uniform(x)
    y = y + 0.03 * m03.mode(x, 13.0)
    p = np.array([s0, 13.0])
    fun, _, fun_jac, _ = _callbacks(m03, None, 0.01, "odd", True)
    df_dy, df_dp = fun_jac(x, y, p)
    h = 1e-6
    for j in range(5):
        e = np.zeros_like(y)
        e[j] = h
        np.testing.assert_allclose(df_dy[:, j, :], (fun(x, y + e, p) - fun(x, y - e, p)) / (2 * h), rtol=1e-7, atol=1e-7)
    for j in range(2):
        e = np.zeros(2)
        e[j] = h
        np.testing.assert_allclose(df_dp[:, j, :], (fun(x, y, p + e) - fun(x, y, p - e)) / (2 * h), rtol=1e-7, atol=1e-7)


def test_mode_is_neutral_exactly_at_critical_gap(m03):
    """J(uniform) mode = d(mode)/dy at H = H_1^c (the linearized BVP), and not at 1.1 H_1^c."""
    x = np.linspace(-0.5, 0.5, 201)
    y0, s0 = m03.uniform(x)
    hc = m03.critical_gap()
    assert hc == pytest.approx(13.0685, abs=1e-4)

    def defect(h):
        eps = 1e-30
        lin = m03.rhs(x, y0 + 1j * eps * m03.mode(x, h), s0, h).imag / eps
        dx = 1e-6
        deriv = (m03.mode(x + dx, h) - m03.mode(x - dx, h)) / (2 * dx)
        return np.max(np.abs(lin - deriv), axis=1)

    assert np.all(defect(hc) < 1e-8)
    assert defect(1.1 * hc)[Q] > 1e-2  # only the energy balance (Q') is off the neutral curve
    walls = m03.mode(x, hc)[[U, Q, M]][:, [0, -1]]  # the mode satisfies the homogeneous BCs
    np.testing.assert_allclose(walls, 0.0, atol=1e-14)


def test_richardson_in_delta_squared_is_exact_for_even_polynomials():
    d = (0.01, 0.02, 0.04)
    assert richardson_delta2(d, [7.0 + 3 * x**2 - 5 * x**4 for x in d]) == pytest.approx(7.0, abs=1e-12)


@pytest.mark.parametrize("tol", [1e-6, 1e-9])
def test_pinning_recovers_analytic_critical_gap(m03, tol):
    """Contract of the baseline at delta <= 0.01, 3 levels: relative error below 10 tol.

    Sources: truncation O(delta^6) of the extrapolation (~1e-11 at delta = 0.01) and the
    collocation error that solve_bvp's relative residual tol allows.  Observed over
    nubar in {0.2, 0.3, 0.5}, delta in {0.005, 0.01}, tol in 1e-4..1e-10: error <= 3 tol.
    """
    r = critical_gap_by_pinning(m03, delta=0.01, levels=3, tol=tol)
    assert r.success
    assert r.exact == pytest.approx(13.068529325, abs=1e-9)
    assert r.relative_error < 10 * tol


def test_pinning_extrapolation_order_odd_versus_top_pin(m03):
    """Odd pin: H(delta) is even (reflection y -> -y), two levels leave O(delta^4): ratio 16.

    Top pin nu(1/2) = nubar + delta: the even O(A^2) part of nu(1/2) adds a delta^3 term, so
    two levels leave O(delta^3): ratio 8.
    """
    err = {}
    for pin in ("odd", "top"):
        err[pin] = [critical_gap_by_pinning(m03, delta=d, levels=2, tol=1e-9, pin=pin).relative_error
                    for d in (0.04, 0.02)]
    assert 14.0 < err["odd"][0] / err["odd"][1] < 18.0
    assert 6.5 < err["top"][0] / err["top"][1] < 9.5


def test_mode_hierarchy_by_pinning(m03):
    """H_3^c = 3 pi psi (physics.md section 3, mode-n scaling)."""
    r = critical_gap_by_pinning(m03, n=3, delta=0.01, tol=1e-8)
    assert r.exact == pytest.approx(3 * m03.critical_gap(1), rel=1e-14)
    assert r.relative_error < 1e-7
    with pytest.raises(ValueError, match="even mode"):
        critical_gap_by_pinning(m03, n=2, pin="odd")


def test_natural_continuation_supercritical_follows_branch(m03):
    """nubar = 0.3 is supercritical: from 1.02 H_1^c up to H = 16 no fold, and the end point
    is the same solution that delta-pinning reaches at its amplitude."""
    start = start_near_critical(m03, 1.02 * m03.critical_gap(), 0.05, tol=1e-6)
    assert start.success and start.phi - 0.3 > 0.04
    run = natural_continuation(m03, start, 16.0, 0.5, tol=1e-6)
    assert run.status == "reached" and run.passed
    assert run.H[-1] == 16.0 and np.all(np.diff(run.H) > 0)
    last = run.points[-1].sol
    delta = 0.5 * (last.y[NU, -1] - last.y[NU, 0])
    pinned = pinned_branch(m03, np.linspace(delta / 8, delta, 8), tol=1e-8)
    assert pinned[-1].success
    assert pinned[-1].H == pytest.approx(16.0, rel=1e-5)
    assert pinned[-1].S == pytest.approx(run.points[-1].S, rel=1e-5)


def test_start_near_critical_detects_fall_back_to_uniform(m03):
    pt = start_near_critical(m03, 0.98 * m03.critical_gap(), 0.01)  # below H_1^c: only uniform shear
    assert not pt.success and "uniform" in pt.message


def test_natural_continuation_cannot_pass_subcritical_fold():
    """nubar = 0.16, e = 0.8: the banded branch turns at H_LP ~ 41.96 (subcritical pitchfork at
    H_1^c = 63.50).  Stepping H down from the upper branch, natural continuation stalls at the
    fold: it ends short of H = 30, within 0.1 of H_LP, still on the upper (phi > phi_LP) side."""
    model = GPCF(0.16, 0.8)
    assert model.critical_gap() == pytest.approx(63.50295, abs=1e-4)
    fold = fold_by_pinning(model, np.linspace(0.01, 0.1, 19), tol=1e-8)
    assert fold.H == pytest.approx(41.963, abs=2e-3)
    assert fold.H < model.critical_gap()  # subcritical: fold below H_1^c
    start = fixed_h_point(model, banded_start(model, 0.15, steps=10))
    assert start.H == pytest.approx(49.40, abs=0.01) and start.phi > 0.4
    run = natural_continuation(model, start, 30.0, 1.0, dh_min=1 / 64, max_nodes=2000)
    assert run.status in ("failed", "jumped") and not run.passed
    assert fold.H <= run.H[-1] < fold.H + 0.1
    assert np.all(run.phi > fold.phi)
    assert np.all(np.diff(run.H) < 0)


def test_bad_input_is_one_clear_error():
    with pytest.raises(ValueError, match="nubar must lie"):
        GPCF(0.65)
    with pytest.raises(ValueError, match="e must lie"):
        GPCF(0.3, 1.2)
    with pytest.raises(ValueError, match="no finite H_1"):
        critical_gap_by_pinning(GPCF(0.15))
    with pytest.raises(ValueError, match="pinning condition"):
        pinned_branch(GPCF(0.3), [0.01], pin="bottom")


def test_runner_comparison_picks_cheapest_config_meeting_each_target():
    from benchmarks.run import comparison_rows, table

    gap = [{"tol": 1e-4, "rel_error": 3e-5}, {"tol": 1e-6, "rel_error": 2e-7}, {"tol": 1e-8, "rel_error": 1e-9}]
    nat = [{"tol": 1e-4, "status": "reached", "s_per_point": 0.01},
           {"tol": 1e-6, "status": "reached", "s_per_point": 0.03},
           {"tol": 1e-8, "status": "failed", "s_per_point": 0.2}]
    cont = [{"method": "fd2", "N": 64, "rel_error": 3e-3, "banded_points": 20, "banded_phi_end": 0.5,
             "banded_s_per_point": 0.001},
            {"method": "cheb", "N": 32, "rel_error": 1e-11, "banded_points": 20, "banded_phi_end": 0.5,
             "banded_s_per_point": 0.004},
            {"method": "cheb", "N": 24, "rel_error": 1e-13, "banded_points": 6, "banded_phi_end": 0.3,
             "banded_s_per_point": 0.0001},  # fell back onto uniform shear: not a banded branch
            {"method": "fd6", "N": 32, "rel_error": 1e-7, "banded_points": 28, "banded_phi_end": 0.145,
             "banded_s_per_point": 0.003}]  # the mirror-image branch counts
    rows = comparison_rows(gap, nat, cont, targets=(1e-4, 1e-6, 1e-8))
    assert [r["baseline"] for r in rows] == ["tol=1e-04", "tol=1e-06", "-"]
    assert [r["contin"] for r in rows] == ["fd6 N=32", "fd6 N=32", "cheb N=32"]
    assert rows[0]["speedup"] == pytest.approx(0.01 / 0.003) and rows[1]["speedup"] == pytest.approx(10.0)
    assert np.isnan(rows[2]["speedup"])
    text = table("t", rows, [("target", "target", ".0e"), ("speedup", "x", ".2f")])
    assert text.splitlines()[2].split() == ["1e-04", "3.33"]


def test_runner_comparison_pairs_tol_and_initial_mesh():
    from benchmarks.run import comparison_rows

    # pinning accuracy and natural-continuation cost both depend on the initial mesh: each pair
    # is matched on (tol, initial nodes), and the cheapest pair meeting the target wins
    gap = [{"tol": 1e-4, "init_nodes": 21, "rel_error": 2e-6}, {"tol": 1e-4, "init_nodes": 101, "rel_error": 3e-7}]
    nat = [{"tol": 1e-4, "init_nodes": 21, "status": "reached", "s_per_point": 0.004, "cpu_per_point": 0.004, "cpu": 0.06},
           {"tol": 1e-4, "init_nodes": 101, "status": "reached", "s_per_point": 0.005, "cpu_per_point": 0.005, "cpu": 0.075}]
    cont = [{"method": "cheb", "N": 12, "rel_error": 1e-10, "banded_points": 29, "banded_phi_end": 0.57,
             "banded_cpu_per_point": 0.0005, "banded_s_per_point": 0.0005, "banded_cpu": 0.0145}]
    rows = comparison_rows(gap, nat, cont, targets=(1e-4, 1e-6))
    assert [r["baseline"] for r in rows] == ["tol=1e-04, 21 nodes", "tol=1e-04, 101 nodes"]
    assert rows[0]["speedup"] == pytest.approx(8.0) and rows[1]["speedup"] == pytest.approx(10.0)
