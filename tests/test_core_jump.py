"""Branch-jump protection of trace (DetectionOptions.retry_unconfirmed_bp): a step across which a
BP test function changes sign without a BP being confirmed by its location is retried smaller.

Toy: F(x, lam) = (x - lam^2)(x - lam^2 + eps), two parallel parabolas eps = 0.01 apart and no
BP anywhere (F_x = +-eps on the two curves).  The tangent predictor from x = lam^2 misses the
curve by ~h^2 at a step h in lam, so from lam = 0 a step of 0.1 lands on the lower curve
x = lam^2 - eps; there F_x has the other sign, so the BP test function changes sign.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from contin.continuation import _Point, _Tracer, trace, trace_both
from contin.extended import ExtendedSystem
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from contin.testfunctions import TestValues as Values
from problems.demo import AllenCahn, ImperfectPitchfork, Transcritical

EPS = 0.01


class Twin:
    parameter_names = ("lam",)

    def residual(self, u, p):
        d = u[0] - p["lam"] ** 2
        return np.array([d * (d + EPS)])

    def jacobian(self, u, p):
        return sp.csc_matrix([[2 * (u[0] - p["lam"] ** 2) + EPS]])

    def dresidual_dp(self, u, p, name):
        return np.array([-2 * p["lam"] * (2 * (u[0] - p["lam"] ** 2) + EPS)])


def run(ds=0.1, ds_min=1e-8, retry=True, bp_eigenvalues=0):
    """The determinant's protection alone (bp_eigenvalues=0: the default eigenvalue count,
    contin.bpdetect, is a second protection, tested on its own below)."""
    opts = ContinuationOptions(step=StepOptions(ds=ds, ds_max=ds, ds_min=ds_min), bounds={"lam": (-1.0, 2.0)},
                               max_steps=200, detection=DetectionOptions(retry_unconfirmed_bp=retry,
                                                                         bp_eigenvalues=bp_eigenvalues))
    br = trace(Twin(), np.array([0.0]), {"lam": 0.0}, "lam", opts)
    off = br.states[:, 0] - br.params["lam"] ** 2  # 0 on the start curve, -eps on the other one
    return br, off


def jumps(br):
    return [a for a in br.audit if "BP test function changed sign" in a]


def test_a_long_step_jumps_without_the_protection():
    br, off = run(retry=False)
    assert br.status == "EP" and br.params["lam"][-1] == 2.0
    assert np.all(np.abs(off[1:] + EPS) < 1e-9)  # every point after the first on the other curve
    (bp,) = br.branch_points  # the jump shows up as a BP whose location fails
    assert not bp.converged and bp.note == "location did not converge" and 0 < bp.params["lam"] < 0.1
    assert jumps(br) == []


def test_the_default_eigenvalue_count_also_stops_the_jump():
    """Without the determinant's retry, the default eigenvalue count (bp_eigenvalues=None):
    one eigenvalue crossed zero but the located point has no kernel, so the step is re-taken."""
    br, off = run(retry=False, bp_eigenvalues=None)
    assert br.status == "EP" and br.params["lam"][-1] == 2.0
    assert np.max(np.abs(off)) < 1e-9 and br.branch_points == []
    assert any("re-stepped with half ds" in a for a in br.audit)


def test_the_protection_retries_the_step_and_stays_on_the_branch():
    br, off = run()
    assert br.status == "EP" and br.params["lam"][-1] == 2.0
    assert np.max(np.abs(off)) < 1e-9 and br.branch_points == []
    (entry,) = jumps(br)
    assert entry.startswith("step 1: lam=0 ds=0.1 rejected (jumped to another branch: two half steps end 0.1 step "
                            "lengths away from it): BP test function changed sign at lam=0.07")
    assert entry.endswith("but location did not converge")
    assert br.ds[1] == pytest.approx(0.05, rel=2e-3)  # the retried step: ds halved once (stored: its length)
    assert br.special_points[-1].type == "EP"


def test_at_ds_min_the_jump_is_kept_and_labelled():
    br, off = run(ds_min=0.1)
    assert np.all(np.abs(off[1:] + EPS) < 1e-9)  # as without the protection ...
    (bp,) = br.branch_points
    assert not bp.converged and bp.note == "location did not converge"
    (entry,) = jumps(br)  # ... but the audit says so
    assert entry.startswith("step 1: lam=0 ds=0.1 kept at ds_min, BP unconfirmed: BP test function changed sign")


def test_both_directions_are_protected():
    opts = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.1), bounds={"lam": (-1.0, 1.0)}, max_steps=200)
    br = trace_both(Twin(), np.array([0.0]), {"lam": 0.0}, "lam", opts)
    assert np.max(np.abs(br.states[:, 0] - br.params["lam"] ** 2)) < 1e-9 and br.branch_points == []
    assert len(jumps(br)) == 2  # one rejected step in each direction


@pytest.mark.parametrize("case", ["transcritical", "pitchfork", "allen-cahn"])
def test_genuine_bps_are_confirmed_and_the_trace_unchanged(case):
    """Real BPs (simple zeros of the test function) pass: the same points, BPs and steps as
    without the protection, and no retry in the audit."""
    if case == "transcritical":
        pb, u0, p, bounds = Transcritical(), np.array([0.0]), {"lam": -0.5}, (-1.0, 1.0)
    elif case == "pitchfork":
        pb, u0, p, bounds = ImperfectPitchfork(), np.array([0.0]), {"lam": -0.5, "alpha": 0.0, "beta": 0.0}, (-1.0, 2.0)
    else:
        pb = AllenCahn("cheb", 24)
        u0, p, bounds = np.zeros(pb.grid.size), {"lam": 0.5}, (0.0, 10.0)
    runs = []
    for retry in (True, False):
        opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.2), bounds={"lam": bounds}, max_steps=400,
                                   detection=DetectionOptions(retry_unconfirmed_bp=retry))
        runs.append(trace(pb, u0, p, "lam", opts))
    on, off = runs
    assert on.branch_points and all(bp.converged for bp in on.branch_points)
    assert jumps(on) == [] and on.audit == off.audit
    assert np.array_equal(on.params["lam"], off.params["lam"])
    assert [bp.params["lam"] for bp in on.branch_points] == [bp.params["lam"] for bp in off.branch_points]


def _point(x, t):
    return _Point(np.array(x, float), np.array(t, float), Values(1.0, (1.0, 0.0)))


def test_the_confirmation_rule():
    """A converged location confirms a BP only if the scaled test function has fallen below
    1e-3 of its larger end value and the point lies within half a step length of the chord."""
    tracer = _Tracer(ExtendedSystem(Twin(), {"lam": 0.0}, "lam"), ContinuationOptions(), None)
    a, b = _point([0.0, 0.0], [0.0, 1.0]), _point([0.0, 1.0], [0.0, 1.0])  # a step of length 1 in lam
    on_chord = _point([0.0, 0.4], [0.0, 1.0])
    assert tracer._unconfirmed(a, b, on_chord, 1e-9) is None
    assert tracer._unconfirmed(a, b, on_chord, -1e-3) is None
    assert tracer._unconfirmed(a, b, on_chord, 0.2) == "the test function does not vanish there (0.2 of its end value)"
    near = _point([0.45, 0.4], [0.0, 1.0])  # 0.45 off the chord (u enters with weight 1/n = 1)
    assert tracer._unconfirmed(a, b, near, 1e-9) is None
    far = _point([0.6, 1.3], [0.0, 1.0])  # beyond b: the distance is to the end point, 0.67
    assert tracer._unconfirmed(a, b, far, 1e-9) == "the located point lies 0.67 step lengths off the step"


def test_a_continuous_step_with_an_unlocated_bp_is_kept():
    """A real BP the locator cannot pin down (Allen-Cahn's first BP, lam = 1 on u = 0, with
    max_bisections = 2) is no jump: two half steps end where the step ended, so the step is
    kept (BP unconfirmed, as without the protection)."""
    pb = AllenCahn("cheb", 24)
    runs = []
    for retry in (True, False):
        opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.2), bounds={"lam": (0.0, 2.5)}, max_steps=400,
                                   detection=DetectionOptions(max_bisections=2, retry_unconfirmed_bp=retry,
                                                                     bp_eigenvalues=0))
        runs.append(trace(pb, np.zeros(pb.grid.size), {"lam": 0.5}, "lam", opts))
    on, off = runs
    (bp,) = on.branch_points
    assert not bp.converged and bp.note == "symmetry-breaking; location did not converge"
    assert abs(bp.params["lam"] - 1.0) < 1e-3
    assert np.array_equal(on.params["lam"], off.params["lam"]) and bp.params == off.branch_points[0].params
    (entry,) = jumps(on)
    assert " kept, BP unconfirmed (two half steps end at the same point: no jump): symmetry-breaking BP test function" in entry


def test_the_jump_rule_compares_two_half_steps_with_the_step():
    tracer = _Tracer(ExtendedSystem(Twin(), {"lam": 0.0}, "lam"), ContinuationOptions(), None)
    d = np.array([0.0, 1.0])  # the tangent at lam = 0 (x = lam^2 is flat there)
    a = _point([0.0, 0.0], d)
    on_start_curve = _point([0.01, 0.1], d)  # x = lam^2 at lam = 0.1
    on_other_curve = _point([0.0, 0.1], d)  # x = lam^2 - eps
    assert tracer.jumped(a, on_start_curve, d, 0.1) is None
    assert tracer.jumped(a, on_other_curve, d, 0.1) == "two half steps end 0.1 step lengths away from it"
