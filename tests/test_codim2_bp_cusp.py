"""Codim-2 (issue 12 sec. 4): cusps on fold curves, BP curves, bounds on the second parameter.

References: AUTO-07p's demo ``cusp`` (x' = mu + lam x - x^3, start x = 0, lam = 1, mu = 0,
continued in mu within [-2, 2], then the first LP in (mu, lam)): the fold curve is
lam = 3 x^2, mu = -2 x^3, with its cusp at (lam, mu) = (0, 0).  gPCF: H_1^c(nu) = pi psi(nu, e)
in closed form (problems.couette.pitchfork.analytic_critical_gaps, physics.md sec. 4).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from contin.bpcurve import trace_bp_curve
from contin.branch import relabel
from contin.continuation import trace, trace_both
from contin.foldcurve import trace_fold_curve
from contin.options import ContinuationOptions, StepOptions
from problems.bp_demos import Cusp
from problems.demo import Transcritical


def cusp_fold_curve(lam_bounds: tuple[float, float] = (-2.0, 2.0)):
    pb = Cusp()
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.1), bounds={"mu": (-2.0, 2.0)})
    br = trace_both(pb, np.array([0.0]), {"lam": 1.0, "mu": 0.0}, "mu", opts)
    relabel([br])
    lp = br.fold_points[0]
    # the fold at lam = 1: x = +-1/sqrt(3), mu = -+2/(3 sqrt(3))
    assert abs(lp.params["mu"]) == pytest.approx(2 / (3 * math.sqrt(3)), abs=1e-12)
    o2 = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.1), bounds={"mu": (-2.0, 2.0), "lam": lam_bounds},
                             max_steps=300)
    return trace_fold_curve(pb, lp, "lam", o2, parameter="mu")


def test_auto_cusp_demo_cp_at_origin_and_lam_bound_honoured() -> None:
    curve = cusp_fold_curve()
    (cp,) = curve.points("CP")
    assert cp.converged
    assert cp.params["lam"] == pytest.approx(0.0, abs=1e-10) and cp.params["mu"] == pytest.approx(0.0, abs=1e-10)
    # every point on lam = 3 x^2, mu = -2 x^3
    x = curve.states[:, 0]
    assert np.max(np.abs(curve.params["lam"] - 3 * x**2)) < 1e-10
    assert np.max(np.abs(curve.params["mu"] + 2 * x**3)) < 1e-10
    # the second parameter's bound lam = 2 ends both halves (it used to be ignored: the curve ran
    # on to the mu bound at lam = 3); there mu = -+2 (2/3)^(3/2)
    ends = curve.points("EP")
    assert len(ends) == 2 and all("reached bound lam=2" in e.note for e in ends)
    assert sorted(e.params["mu"] for e in ends) == pytest.approx([-2 * (2 / 3) ** 1.5, 2 * (2 / 3) ** 1.5], abs=1e-10)
    assert curve.params["lam"].max() <= 2.0 + 1e-12


def test_gpcf_bp_curve_is_n_pi_psi() -> None:
    """The symmetry-breaking pitchfork H_1^c continued in (nu, H) against pi psi(nu, e)."""
    from problems.couette.model import CouetteProblem
    from problems.couette.pitchfork import analytic_critical_gaps

    pb = CouetteProblem("cheb", 32, engine="numpy")
    p = pb.params({"nu": 0.3, "e": 0.8, "H": 8.0})
    base = trace(pb, pb.uniform_state(p), p, "H",
                 ContinuationOptions(step=StepOptions(ds=1.0, ds_max=3.0), bounds={"H": (8.0, 16.0)}))
    relabel([base])
    bp = base.branch_points[0]
    assert "symmetry-breaking" in bp.note
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"nu": (0.25, 0.35), "H": (1.0, 13.5)},
                               max_steps=100)
    curve = trace_bp_curve(pb, bp, "H", opts, parameter="nu")
    assert curve.kind == "bp-curve" and curve.status == "EP"
    ref = np.array([analytic_critical_gaps(nu, 0.8, 1)[0] for nu in curve.params["nu"]])
    assert np.max(np.abs(curve.params["H"] - ref) / ref) < 1e-10
    assert curve.params["nu"].max() == pytest.approx(0.35, abs=1e-12)  # first parameter's bound
    assert curve.params["H"].max() == pytest.approx(13.5, abs=1e-10)  # second parameter's bound
    assert curve.params["H"].max() <= 13.5 + 1e-10
    # the states stay symmetric and the null vectors antisymmetric (reduced coordinates)
    from contin.testfunctions import Antisymmetric

    n = pb.size
    anti = Antisymmetric.from_problem(pb, n)
    for row in curve.states:
        u, phi = row[:n], row[n:2 * n]
        assert np.max(np.abs(anti.apply(u) - u)) < 1e-12 and np.max(np.abs(anti.apply(phi) + phi)) < 1e-12


def test_bp_curve_refuses_a_bp_without_symmetry() -> None:
    pb = Transcritical()
    br = trace(pb, np.array([0.0]), {"lam": -0.5}, "lam",
               ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.1), bounds={"lam": (-1.0, 1.0)}))
    relabel([br])
    (bp,) = br.branch_points
    with pytest.raises(ValueError, match="not a symmetry-breaking BP"):
        trace_bp_curve(pb, bp, "lam", ContinuationOptions(), parameter="lam")


class ImperfectTranscritical:
    """lam x - x^2 + mu: the transcritical BP at lam = mu = 0 unfolded by mu; its fold curve
    x = lam/2, mu = -lam^2/4 passes through the BP without a cusp (psi . B(phi, phi) = -2)."""

    parameter_names = ("lam", "mu")

    def residual(self, u, p):
        return np.array([p["lam"] * u[0] - u[0] ** 2 + p["mu"]])

    def jacobian(self, u, p):
        import scipy.sparse as sp

        return sp.csr_matrix([[p["lam"] - 2 * u[0]]])

    def dresidual_dp(self, u, p, name):
        return np.array([u[0] if name == "lam" else 1.0])


def test_the_cusp_at_a_pitchforks_start_is_labelled_and_a_transcritical_has_none() -> None:
    """The fold curve of a pitchfork unfolded by p2 starts at its cusp and goes both ways; each
    half sees one sign of the cusp test, so before it was not labelled.  x' = mu + lam x - x^3:
    the BP at lam = mu = 0 is the cusp of lam = 3 x^2, mu = -2 x^3."""
    from contin.twoparam import continue_point

    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.1), bounds={"lam": (-1.0, 1.0)})
    two = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.1), bounds={"lam": (-1.0, 2.0), "mu": (-2.0, 2.0)},
                              max_steps=300)
    br = trace_both(Cusp(), np.array([0.0]), {"lam": -0.5, "mu": 0.0}, "lam", opts)
    (bp,) = br.points("BP")
    curve = continue_point(Cusp(), br, bp, "mu", two)
    (cp,) = curve.points("CP")
    assert cp.params["lam"] == pytest.approx(0.0, abs=1e-10) and cp.params["mu"] == pytest.approx(0.0, abs=1e-12)
    assert cp.converged and cp.note.startswith("cusp at the start") and abs(cp.state[0]) < 1e-10
    x = curve.states[:, 0]
    assert np.max(np.abs(curve.params["lam"] - 3 * x**2)) < 1e-10
    # the transcritical BP: the fold curve x = lam/2, mu = -lam^2/4 has no cusp
    br = trace_both(ImperfectTranscritical(), np.array([0.0]), {"lam": -0.5, "mu": 0.0}, "lam", opts)
    (bp,) = br.points("BP")
    curve = continue_point(ImperfectTranscritical(), br, bp, "mu", two)
    assert not curve.points("CP") and len(curve) > 20
    lam = curve.params["lam"]
    assert np.max(np.abs(curve.params["mu"] + lam**2 / 4)) < 1e-10 and lam.min() < 0 < lam.max()
