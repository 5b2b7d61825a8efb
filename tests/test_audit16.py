"""Accuracy audit of session 16's features (helper audit16), against independent references.

- l2 at a GH (``contin.codim2tests.second_lyapunov_estimate``): the Bautin normal form at its GH
  (``WarpedBautin`` of tests/test_hopf_gh.py: l2 = 4 s in its coordinates) with its state scaled
  by eps (u = eps y: l2 = 4 s / eps^4 in u, q normalized to 1 in u) and offset, and embedded in a
  large sparse system with slaved modes of decay rates 1e-6 .. 1e6 (J ill-conditioned; no feedback
  onto the oscillator: l2 unchanged);
- l1 at an HB (``contin.hopf.first_lyapunov_estimate``): the same scaled Bautin system at b2 != 0,
  l1 = 2 b2 / eps^2.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import scipy.sparse as sp

from test_hopf_gh import WarpedBautin, _rotation

ORIGIN = {"b1": 0.0, "b2": 0.0}


class ScaledBautin:
    """WarpedBautin in u = off + eps y: F(u) = eps G((u - off) / eps); J by complex step."""

    parameter_names = ("b1", "b2")

    def __init__(self, s, eps, off=0.0):
        self.base, self.eps, self.off = WarpedBautin(s, t=_rotation(0.7, 0.4)), eps, off

    def residual(self, u, p):
        return self.eps * self.base.residual((u - self.off) / self.eps, p)

    def jacobian(self, u, p):
        h = 1e-30 * self.eps
        return np.array([np.imag(self.residual(u + 1j * h * e, p)) / h for e in np.eye(3)]).T

    def mass_matrix(self, u, p):
        return np.eye(3)

    def dresidual_dp(self, u, p, name):
        h = 1e-30
        return np.imag(self.residual(u, {**p, name: p[name] + 1j * h})) / h


@pytest.mark.parametrize("eps", [1e-4, 1e-2, 1e2, 1e4])
def test_l2_of_a_scaled_bautin_system(eps):
    """Before: the difference steps were step * max(1, |u|_inf), blind to the scale of F's
    nonlinearity: l2 of this system was wrong by a relative 2.7e15 (eps = 1e-4), 2.9 (1e-2),
    0.56 (1e2), 1.1e8 (1e4), exit 0.  The step ladder finds the scale; the estimate is honest."""
    from contin.codim2tests import second_lyapunov_estimate

    for s in (1.0, -1.0):
        l2, err = second_lyapunov_estimate(ScaledBautin(s, eps), np.zeros(3), ORIGIN, 1.0)
        exact = 4 * s / eps ** 4
        assert l2 == pytest.approx(exact, rel=1e-6)
        assert err <= 1e-6 * abs(l2) and abs(l2 - exact) <= 10 * err + 1e-12 * abs(exact)


def test_l2_doubtful_is_said():
    """A state offset 1e4 with a nonlinearity on the scale 1e-4: the differences cannot resolve it
    (u + du rounds at 1e-12); l2 is off by a factor ~3 and the estimate says so."""
    from contin.codim2tests import L2_DOUBTFUL, second_lyapunov_estimate

    l2, err = second_lyapunov_estimate(ScaledBautin(1.0, 1e-4, 1e4), np.full(3, 1e4), ORIGIN, 1.0)
    exact = 4 / 1e-16
    assert abs(l2 - exact) > 0.1 * exact  # really wrong
    assert err > L2_DOUBTFUL * abs(l2) and err > 0.3 * abs(l2 - exact)  # and the estimate knows it


class SparseBautin:
    """WarpedBautin (x1, x2, x3) and n slaved modes z_k' = -d_k z_k + c_k x1^2, d_k from 1e-6 to 1e6
    (cond J ~ 1e12), sparse J; the z's do not feed back: l2 = 4 s."""

    parameter_names = ("b1", "b2")

    def __init__(self, s, n=300):
        self.base = WarpedBautin(s, t=_rotation(0.7, 0.4))
        self.d = np.logspace(-6, 6, n)
        self.c = np.cos(np.arange(n))

    def residual(self, u, p):
        return np.concatenate([self.base.residual(u[:3], p), -self.d * u[3:] + self.c * u[0] ** 2])

    def jacobian(self, u, p):
        n = len(self.d)
        top = sp.csr_matrix(self.base.jacobian(u[:3], p))
        col = sp.csr_matrix((2 * self.c * u[0])[:, None])
        return sp.bmat([[top, None], [sp.hstack([col, sp.csr_matrix((n, 2))]), sp.diags(-self.d)]], format="csr")


def test_l2_on_a_large_sparse_ill_conditioned_problem():
    """The slow modes' parts of H11 = -J^-1 B(q, qb) are ~1e6 times the oscillator's: the
    differences along H11 resolve its oscillator part poorly and l2 is good to ~2e-4 only (-3.99913
    at the default steps); the estimate covers the error."""
    from contin.codim2tests import L2_DOUBTFUL, second_lyapunov_estimate

    pb = SparseBautin(-1.0)
    l2, err = second_lyapunov_estimate(pb, np.zeros(3 + len(pb.d)), ORIGIN, 1.0)
    assert abs(l2 + 4.0) <= 2 * err and err <= L2_DOUBTFUL * 4
    pb.d = np.logspace(-2, 6, len(pb.d))  # cond J ~ 1e8: accurate
    l2, err = second_lyapunov_estimate(pb, np.zeros(3 + len(pb.d)), ORIGIN, 1.0)
    assert l2 == pytest.approx(-4.0, rel=1e-6) and err <= 1e-6 * 4


def test_gh_with_a_doubtful_l2_says_so(caplog):
    """LyapunovTest.finish (every located GH) stores l2_error, warns and notes 'l2 doubtful' when
    the estimate is above L2_DOUBTFUL |l2| (the offset system above); a resolvable scale (eps =
    1e-4, before wrong by 2.7e15 relative) is stored right, without a warning."""
    from contin.branch import SpecialPoint
    from contin.extended import ExtendedSystem
    from contin.hopfsystem import HopfCurveProblem, LyapunovTest

    for eps, off, doubtful in ((1e-4, 1e4, True), (1e-4, 0.0, False)):
        pb = ScaledBautin(1.0, eps, off)
        aug = HopfCurveProblem(pb, "b1", np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        system = ExtendedSystem(aug, dict(ORIGIN), "b2")
        x = np.concatenate([np.full(3, off), np.zeros(6), [1.0, 0.0, 0.0]])
        sp_ = SpecialPoint("GH", 0, dict(ORIGIN), math.nan, x[:-1], note="generalized Hopf (l1 = 0)")
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="contin"):
            gh = LyapunovTest(aug).finish(system, sp_, x)
        exact = 4 / eps ** 4
        assert ("l2 doubtful" in gh.note) == doubtful and ("l2 doubtful" in caplog.text) == doubtful
        assert gh.data["l2_error"] > 0.3 * abs(gh.data["l2"] - exact)
        if not doubtful:
            assert gh.data["l2"] == pytest.approx(exact, rel=1e-6)


@pytest.mark.parametrize("eps", [1e-4, 1e4])
def test_l1_of_a_scaled_bautin_system(eps):
    """Before: l1 at the HB of the Bautin system scaled by 1e-4 was off by a relative -1.2e5 (b2 =
    0.1: subcritical reported supercritical) and by 1e4 by -0.53; now within 3e-5 (the estimate
    within a factor 5)."""
    from contin.hopf import hopf_numbers

    for b2 in (0.1, -0.4):
        data = hopf_numbers(ScaledBautin(1.0, eps), np.zeros(3), {"b1": 0.0, "b2": b2})
        assert data["omega"] == pytest.approx(1.0, rel=1e-10)
        assert data["l1"] == pytest.approx(2 * b2 / eps ** 2, rel=3e-5) and "l1_error" not in data


def test_hb_with_a_doubtful_l1_says_so():
    """The offset 1e4 with the nonlinearity's scale 1e-4: l1 off by ~1e-2 relative, no step
    resolves it: hopf_numbers returns l1_error (the HB's note then says 'l1 doubtful')."""
    from contin.hopf import L1_DOUBTFUL, hopf_numbers

    data = hopf_numbers(ScaledBautin(1.0, 1e-4, 1e4), np.full(3, 1e4), {"b1": 0.0, "b2": 0.1})
    exact = 0.2 / 1e-8
    assert abs(data["l1"] - exact) > 1e-3 * exact
    assert data["l1_error"] > L1_DOUBTFUL * abs(data["l1"]) and data["l1_error"] > 0.3 * abs(data["l1"] - exact)


def test_traced_hb_of_a_scaled_bautin_system(caplog):
    """The HB of a trace in b1 (b2 = 0.1: subcritical): eps = 1e-4 located at b1 = 0 with l1 right
    (before: 'supercritical', l1 = -2.5e12 for 2e7); with the 1e4 offset its note and a warning say
    'l1 doubtful'."""
    from contin.continuation import trace
    from contin.options import ContinuationOptions, StepOptions

    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-0.5, 0.5)}, max_steps=100)
    for off, doubtful in ((0.0, False), (1e4, True)):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="contin"):
            br = trace(ScaledBautin(1.0, 1e-4, off), np.full(3, off), {"b1": -0.3, "b2": 0.1}, "b1", opts)
        (hb,) = br.points("HB")
        assert abs(hb.params["b1"]) < 1e-10 and hb.note.startswith("subcritical")
        assert ("l1 doubtful" in hb.note) == doubtful and ("l1 doubtful" in caplog.text) == doubtful
        if not doubtful:
            assert hb.data["l1"] == pytest.approx(0.2 / 1e-8, rel=3e-5)


# ----------------------------------------------------------------------------- ZH / HH switching
class _TwoOscillators:
    """tests.codim2_fixture_scenes.TwoOscillators with the second frequency f (1:1 resonance as
    f -> 1), in coordinates y with u = T y (T a fixed random matrix, cond 9.8: J non-normal, the
    two pairs' eigenvectors not orthogonal).  Hopf curves: a = 1 - b - b^2 (omega 1) and a = 2 b
    (omega f), meeting at the HH b = (sqrt(13) - 3)/2."""

    parameter_names = ("a", "b")

    def __init__(self, f):
        from tests.codim2_fixture_scenes import TwoOscillators

        self.base, self.f = TwoOscillators(), f
        rng = np.random.default_rng(1)
        self.t = np.eye(4) + 0.8 * rng.standard_normal((4, 4))
        self.ti = np.linalg.inv(self.t)

    def _res(self, u, p):
        v1, w1, v2, w2 = u
        r1, r2 = self.base._parts(p)
        s1, s2 = v1 * v1 + w1 * w1, v2 * v2 + w2 * w2
        f = self.f
        return np.array([r1 * v1 - w1 - v1 * s1, v1 + r1 * w1 - w1 * s1,
                         r2 * v2 - f * w2 - v2 * s2, f * v2 + r2 * w2 - w2 * s2])

    def residual(self, y, p):
        return self.ti @ self._res(self.t @ y, p)

    def jacobian(self, y, p):
        u = self.t @ y
        j = self.base.jacobian(u, p).toarray()
        v2, w2 = u[2:]
        j[2, 3], j[3, 2] = -self.f - 2 * v2 * w2, self.f - 2 * v2 * w2
        return sp.csr_matrix(self.ti @ j @ self.t)

    def dresidual_dp(self, y, p, name):
        return self.ti @ self.base.dresidual_dp(self.t @ y, p, name)


@pytest.mark.parametrize("f", [1.0001, 1.000001])
def test_double_hopf_switch_next_to_a_one_to_one_resonance(f):
    """From the HH of the omega = 1 curve, omega2 = f within 1e-6 of it: the switched curve is the
    other pair's (a = 2 b, kappa = f^2 at every point, the start included: 1e-10, where the old
    curve's kappa = 1 differs by 2e-6), not the old one retraced."""
    from contin.continuation import trace
    from contin.hopfcurve import trace_hopf_curve
    from contin.options import ContinuationOptions, StepOptions
    from contin.twoparam import continue_point

    step = StepOptions(ds=0.02, ds_max=0.05)
    pb = _TwoOscillators(f)
    br = trace(pb, np.zeros(4), {"a": 0.5, "b": 0.0}, "a",
               ContinuationOptions(step=step, bounds={"a": (0.5, 2.0)}, max_steps=200))
    opts = ContinuationOptions(step=step, bounds={"a": (-1.0, 2.0), "b": (-0.2, 0.8)}, max_steps=200)
    first = trace_hopf_curve(pb, br.points("HB")[0], "b", opts, parameter="a")
    (hh,) = first.points("HH")
    assert hh.data["omega2"] == pytest.approx(f, abs=1e-12)
    other = continue_point(pb, first, hh, "b", opts)
    b = other.params["b"]
    assert b.min() == pytest.approx(-0.2) and b.max() == pytest.approx(0.8)
    assert np.max(np.abs(other.params["a"] - 2 * b)) < 1e-10
    assert np.max(np.abs(other.observables["kappa"] - f * f)) < 1e-10
    (start,) = other.points("HH")
    assert start.params["b"] == pytest.approx((math.sqrt(13) - 3) / 2, abs=1e-10)
    assert "doubtful" not in start.note
    # the check behind it: a start whose kappa is the other pair's (the source curve retraced)
    from contin.twoparam import _pair_check

    assert "start doubtful: kappa" in _pair_check(other, hh, 1.0)  # omega = 1: the source curve's pair
    assert _pair_check(other, hh, f) == ""


@pytest.mark.parametrize("f", [1e-4, 1e-8])
def test_zero_hopf_switch_with_a_tiny_omega(f):
    """FoldHopf with the oscillator's frequency f (the ZH next to a triple zero): the Hopf curve
    from the fold curve's ZH lies on x = 1 - b, a = (1 - b)(1 - 2 b) - b with kappa = f^2 (to
    1e-12 relative), and the fold curve back from its ZH on x = b/2, a = -b - b^2/4."""
    from contin.continuation import trace_both
    from contin.foldcurve import trace_fold_curve
    from contin.options import ContinuationOptions, StepOptions
    from contin.twoparam import continue_point
    from tests.codim2_fixture_scenes import FoldHopf

    class Slow(FoldHopf):
        def residual(self, u, p):
            r = FoldHopf.residual(self, u, p)
            x, v, w = u
            return r + np.array([0.0, (1 - f) * w, (f - 1) * v])

        def jacobian(self, u, p):
            j = FoldHopf.jacobian(self, u, p).toarray()
            j[1, 2] += 1 - f
            j[2, 1] += f - 1
            return sp.csr_matrix(j)

    step = StepOptions(ds=0.02, ds_max=0.05)
    pb = Slow()
    br = trace_both(pb, np.array([0.5, 0.0, 0.0]), {"a": 0.25, "b": 0.0}, "a",
                    ContinuationOptions(step=step, bounds={"a": (-0.5, 2.0)}, max_steps=400))
    opts = ContinuationOptions(step=step, bounds={"a": (-2, 2), "b": (-0.5, 1.0)}, max_steps=400)
    fold = trace_fold_curve(pb, br.points("LP")[0], "b", opts, parameter="a")
    (zh,) = fold.points("ZH")
    assert zh.data["omega"] == pytest.approx(f, rel=1e-7)
    hopf = continue_point(pb, fold, zh, "b", opts)
    b = hopf.params["b"]
    assert b.min() < 0 and b.max() > 0.99
    assert np.max(np.abs(hopf.params["a"] - ((1 - b) * (1 - 2 * b) - b))) < 1e-10
    assert np.max(np.abs(hopf.states[:, 0] - (1 - b))) < 1e-10
    fe = 1.0 - (1.0 - f)  # the fixture's frequency in floating point (exact: Sterbenz)
    assert np.max(np.abs(hopf.observables["kappa"] - fe * fe)) < 1e-12 * f * f
    back = continue_point(pb, hopf, hopf.points("ZH")[0], "b", opts)
    b = back.params["b"]
    assert np.max(np.abs(back.params["a"] - (-b - b ** 2 / 4))) < 1e-10
    assert np.max(np.abs(back.states[:, 0] - b / 2)) < 1e-10


# ----------------------------------------------------------------------------- continue curves
def test_stored_ab_curves_against_fsolve_of_their_defining_systems():
    """Every point of results/ab_hopf.h5 (Hopf curve, 1871 points) and results/ab_fold.h5 (the
    fold curve switched at its BT, 453 points) solves F = 0 with tr J = 0 (det J = 0) to 1e-12
    (fsolve from the stored point, benchmarks.audit_curves; measured 4.3e-13 and 3.2e-14)."""
    from pathlib import Path

    from benchmarks.audit_curves import ab_model, audit_curve
    from contin import io

    root = Path(__file__).resolve().parent.parent / "results"
    for name in ("ab_hopf.h5", "ab_fold.h5"):
        branches, meta = io.load(str(root / name))
        f, j = ab_model(float(meta["parameters"]["beta"]))
        (b,) = [b for b in branches if b.kind in ("fold-curve", "hopf-curve")]
        err, _ = audit_curve(b.kind, 2, np.asarray(b.states), np.asarray(b.params["D"]), np.asarray(b.params["B"]), f, j)
        assert err < 1e-12, name


@pytest.mark.parametrize("eps, b2_tol", [(1e-4, 1e-6), (1e4, 3e-5)])
def test_gh_of_a_scaled_bautin_system(eps, b2_tol):
    """The GH of the Hopf curve b1 = 0 is at b2 = 0 (l1 = 2 b2 / eps^2) with l2 = -4 / eps^4.
    Before: scaled by 1e-4 the curve had no GH, by 1e4 it was at b2 = 0.021, 'converged' (the GH
    test's l1 at the default steps); now the steps of l1 are chosen at the curve's first point
    (LyapunovTest.step_scale).  b2_tol: l1's accuracy at that scale (rounding: ~2e-5 of l1)."""
    from contin.continuation import trace
    from contin.hopfcurve import trace_hopf_curve
    from contin.options import ContinuationOptions, StepOptions

    pb = ScaledBautin(-1.0, eps)
    step = StepOptions(ds=0.05, ds_max=0.1)
    br = trace(pb, np.zeros(3), {"b1": -0.3, "b2": -0.4}, "b1",
               ContinuationOptions(step=step, bounds={"b1": (-0.5, 0.5)}, max_steps=100))
    curve = trace_hopf_curve(pb, br.points("HB")[0], "b1",
                             ContinuationOptions(step=step, bounds={"b2": (-0.4, 0.3)}, max_steps=100), parameter="b2")
    (gh,) = curve.points("GH")
    assert abs(gh.params["b2"]) < b2_tol and abs(gh.params["b1"]) < 1e-10
    assert gh.data["l2"] == pytest.approx(-4 / eps ** 4, rel=1e-6) and "doubtful" not in gh.note
