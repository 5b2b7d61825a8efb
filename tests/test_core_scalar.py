"""Scalar problems with closed-form answers: imperfect pitchfork, transcritical, isola."""

import numpy as np
import pytest

from contin.branch import relabel
from contin.continuation import switch, trace, trace_both
from contin.options import ContinuationOptions, StepOptions
from problems.demo import ImperfectPitchfork, Isola, Transcritical

OPTS = ContinuationOptions(bounds={"lam": (-1.0, 2.0)}, max_steps=400, step=StepOptions(ds=0.05, ds_max=0.1))


@pytest.mark.parametrize("alpha, beta", [(0.1, 0.0), (-0.05, 0.0), (0.1, 0.3), (0.02, -0.5)])
def test_imperfect_pitchfork_folds_at_analytic_locations(alpha, beta):
    pb = ImperfectPitchfork()
    p = {"lam": 2.0, "alpha": alpha, "beta": beta}
    # every solution component at lam = 2: the three real roots of x^3 - 2x + alpha + beta x^2
    roots = sorted(r.real for r in np.roots([1, beta, -2, alpha]) if abs(r.imag) < 1e-12)
    found = []
    for x0 in roots:
        br = trace_both(pb, np.array([x0]), p, "lam", OPTS)
        assert br.status == "EP"
        found += [(lp.params["lam"], lp.order_parameter) for lp in br.fold_points]
        assert not br.branch_points
    # two of the three roots lie on the same (folded) component: each fold is seen twice
    expected = ImperfectPitchfork.folds(alpha, beta)
    expected = [(lam, x) for lam, x in expected if -1 < lam < 2]
    assert len(expected) >= 1
    for lam, x in expected:
        hits = [f for f in found if abs(f[1] - x) < 1e-6]
        assert hits and all(abs(h[0] - lam) < 1e-10 for h in hits)
    assert len({round(f[1], 6) for f in found}) == len(expected)


def test_perfect_pitchfork_bp_and_switching_to_sqrt_lambda():
    pb = ImperfectPitchfork()
    br = trace_both(pb, np.array([0.0]), {"lam": -0.5, "alpha": 0.0, "beta": 0.0}, "lam", OPTS)
    (bp,) = br.branch_points
    assert abs(bp.params["lam"]) < 1e-10 and bp.converged
    branches = switch(pb, br, bp, OPTS)
    assert len(branches) == 2
    signs = set()
    for nb in branches:
        x, lam = nb.order_parameter, nb.parameter_values
        assert np.max(np.abs(x**2 - lam)) < 1e-10
        assert lam[-1] == 2.0 and nb.status == "EP"
        signs.add(np.sign(x[-1]))
        assert x[-1] == pytest.approx(np.sign(x[-1]) * np.sqrt(2.0), abs=1e-12)
    assert signs == {-1.0, 1.0}


def test_transcritical_switching_follows_x_equals_lambda():
    pb = Transcritical()
    br = trace_both(pb, np.array([0.0]), {"lam": -0.5}, "lam", OPTS)
    (bp,) = br.branch_points
    assert abs(bp.params["lam"]) < 1e-10
    ends = []
    for nb in switch(pb, br, bp, OPTS):
        assert np.max(np.abs(nb.order_parameter - nb.parameter_values)) < 1e-10
        ends.append(nb.parameter_values[-1])
    assert sorted(ends) == [-1.0, 2.0]  # the new branch crosses in both directions


@pytest.mark.parametrize("c, r, ds", [(2.0, 1.0, 0.05), (0.0, 0.3, 0.02), (5.0, 2.0, 0.1)])
def test_isola_closes_with_exactly_two_folds(c, r, ds):
    pb = Isola()
    br = trace(pb, np.array([r]), {"lam": c, "c": c, "r": r}, "lam",
               ContinuationOptions(max_steps=1000, step=StepOptions(ds=ds, ds_max=4 * ds)))
    relabel([br])
    assert br.closed and br.status == "EP" and "closed loop" in br.message
    assert [sp.type for sp in br.special_points] == ["LP", "LP", "EP"]
    lps = sorted(lp.params["lam"] for lp in br.fold_points)
    assert lps == pytest.approx([c - r, c + r], abs=1e-10)
    assert all(abs(lp.order_parameter) < 1e-6 for lp in br.fold_points)
    # the loop is traced once: the start point is not repeated and every point lies on the circle
    x, lam = br.order_parameter, br.parameter_values
    assert np.allclose(x**2 + (lam - c) ** 2, r**2, atol=1e-10)
    d_last = np.hypot(x[-1] - x[0], lam[-1] - lam[0])
    assert d_last > 1e-3 * r
    angles = np.unwrap(np.arctan2(x, lam - c))
    assert abs(angles[-1] - angles[0]) < 2 * np.pi  # less than one full turn
    assert abs(angles[-1] - angles[0]) > np.pi  # more than half of it
    assert len(br) < 200
