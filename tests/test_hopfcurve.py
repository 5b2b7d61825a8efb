"""Hopf curves in two parameters and Bogdanov-Takens points on Hopf and fold curves
(contin.hopfcurve), with bounds on the second parameter.

References: the closed forms of the BT normal form; for the CO model an independent scipy solve
of the BT defining system F = 0, a2 = 0, a3 = 0 (a double zero root of the characteristic
polynomial lambda^3 + a1 lambda^2 + a2 lambda + a3 of the 3x3 Jacobian)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import fsolve

from contin.continuation import trace
from contin.foldcurve import trace_fold_curve
from contin.hopfcurve import trace_hopf_curve
from contin.options import ContinuationOptions, StepOptions
from tests.hopf_models import CO, BTNormalForm


def bt_branch(param_start, bounds):
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds=bounds, max_steps=200)
    x = 0.5 * (1 - math.sqrt(1 - 4 * param_start))  # the root of x^2 - x + b1 = 0 (b2 = -1) through x = 0
    return trace(BTNormalForm(), np.array([x, 0.0]), {"b1": param_start, "b2": -1.0}, "b1", opts)


def bt_hopf_curve():
    br = bt_branch(-0.5, {"b1": (-1.0, 0.2)})
    (hb,) = br.points("HB")
    assert abs(hb.params["b1"]) <= 1e-12 and hb.data["omega"] == pytest.approx(1.0, rel=1e-10)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b2": (-2.0, 1.0)}, max_steps=200)
    return trace_hopf_curve(BTNormalForm(), hb, "b2", opts, parameter="b1")


def test_bt_normal_form_hopf_curve_meets_bt_at_the_origin():
    curve = bt_hopf_curve()
    assert curve.kind == "hopf-curve" and curve.free == ("b1", "b2")
    (bt,) = curve.points("BT")
    assert bt.converged and abs(bt.params["b2"]) <= 1e-10 and abs(bt.params["b1"]) <= 1e-10
    b2 = curve.params["b2"]
    kappa = curve.observables["kappa"]
    assert np.allclose(curve.params["b1"], 0.0, atol=1e-10)  # the Hopf line b1 = 0
    assert np.allclose(kappa, -b2, atol=1e-9)  # omega^2 = -b2 (neutral saddles past BT)
    assert b2.min() == pytest.approx(-2.0, abs=1e-12) and b2.max() == pytest.approx(1.0, abs=1e-12)
    assert [s.type for s in curve.special_points if s.type == "EP"] == ["EP", "EP"]


def test_hopf_curve_round_trips_through_hdf5(tmp_path):
    from contin import io

    curve = bt_hopf_curve()
    (back,), _ = io.load(io.write(tmp_path / "hopf.h5", [curve]))
    assert back.kind == "hopf-curve" and back.free == ("b1", "b2")
    assert np.array_equal(back.params["b2"], curve.params["b2"])
    (bt,) = back.points("BT")
    assert bt.data["kappa"] == curve.points("BT")[0].data["kappa"]


def test_bt_normal_form_fold_curve_bt():
    br = bt_branch(0.0, {"b1": (-1.0, 1.0)})
    lp = br.points("LP")
    assert len(lp) == 1 and lp[0].params["b1"] == pytest.approx(0.25, rel=1e-10)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-1.0, 2.0)}, max_steps=60)
    curve = trace_fold_curve(BTNormalForm(), lp[0], "b2", opts, parameter="b1")
    (bt,) = curve.points("BT")
    assert bt.converged and abs(bt.params["b2"]) <= 1e-9 and abs(bt.params["b1"]) <= 1e-9
    assert np.allclose(curve.params["b1"], curve.params["b2"] ** 2 / 4, atol=1e-10)


def co_bt_reference(guess):
    model = CO()

    def system(z):
        u, p = z[:3], {**CO.PARAMS, "q2": z[3], "k": z[4]}
        j = np.asarray(model.jacobian(u, p))
        a2 = sum(np.linalg.det(j[np.ix_(ix, ix)]) for ix in ([0, 1], [0, 2], [1, 2]))
        return np.concatenate([model.residual(u, p), [a2, np.linalg.det(j)]])

    # from a perturbed guess, so that the solve does the work
    z, _, ok, msg = fsolve(system, np.asarray(guess) * (1 + 1e-3), xtol=1e-13, full_output=True)
    assert ok in (1, 3) and np.max(np.abs(system(z))) < 1e-13, msg
    return z


@pytest.fixture(scope="module")
def co_branch():
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.01), bounds={"q2": (0.5, 1.9)}, max_steps=3000)
    return trace(CO(), np.array([0.2, 0.05, 0.5]), CO.PARAMS, "q2", opts)


def test_co_hopf_curve_bogdanov_takens_points_and_k_bound(co_branch):
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"q2": (0.5, 2.2), "k": (0.0, 1.0)},
                               max_steps=600)
    curve = trace_hopf_curve(CO(), co_branch.points("HB")[0], "k", opts, parameter="q2")
    bts = curve.points("BT")
    assert len(bts) == 2
    for bt in bts:
        ref = co_bt_reference(np.concatenate([bt.state[:3], [bt.params["q2"], bt.params["k"]]]))
        assert bt.converged
        assert bt.params["q2"] == pytest.approx(ref[3], rel=1e-9)
        assert bt.params["k"] == pytest.approx(ref[4], rel=1e-9)
    assert sorted(round(bt.params["k"], 6) for bt in bts) == [0.722339, 0.971398]
    k = curve.params["k"]
    assert k.max() <= 1.0 + 1e-12 and curve.status == "EP"
    ends = curve.points("EP")
    assert len(ends) == 2 and all(abs(e.params["k"] - 1.0) <= 1e-10 for e in ends)
    # Hopf part: omega^2 = kappa > 0 is the imaginary part of an eigenvalue pair on the axis
    i = int(np.argmax(curve.observables["kappa"]))
    p = {**CO.PARAMS, "q2": curve.params["q2"][i], "k": k[i]}
    w = np.linalg.eigvals(np.asarray(CO().jacobian(curve.state(i)[:3], p)))
    pair = w[np.argmax(w.imag)]
    assert abs(pair.real) <= 1e-8 and pair.imag ** 2 == pytest.approx(curve.observables["kappa"][i], rel=1e-8)


@pytest.mark.slow
def test_co_fold_curve_bogdanov_takens_points(co_branch):
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"q2": (0.5, 2.2)}, max_steps=150)
    curve = trace_fold_curve(CO(), co_branch.points("LP")[0], "k", opts, parameter="q2")
    bts = curve.points("BT")
    assert len(bts) == 2
    for bt in bts:
        ref = co_bt_reference(np.concatenate([bt.state[:3], [bt.params["q2"], bt.params["k"]]]))
        assert bt.params["q2"] == pytest.approx(ref[3], rel=1e-9)
        assert bt.params["k"] == pytest.approx(ref[4], rel=1e-9)


def _co_k04_references():
    """HB and LP parameters q2 of the CO model at k = 0.4 (k is PARAMS' own value): F = 0 with the
    Routh-Hurwitz boundary a1 a2 = a3 (HB) or det J = 0 (LP), solved by fsolve from the
    one-parameter branch's rough neighbourhood (q2 ~ 1.04, 1.05)."""
    model = CO()

    def solve(condition, guess):
        def system(z):
            u, p = z[:3], {**CO.PARAMS, "q2": z[3]}
            return np.concatenate([model.residual(u, p), [condition(np.asarray(model.jacobian(u, p)))]])

        z, _, ok, msg = fsolve(system, guess, xtol=1e-14, full_output=True)
        assert ok in (1, 3) and np.max(np.abs(system(z))) < 1e-13, msg
        return z[3]

    def hopf(j):
        a2 = sum(np.linalg.det(j[np.ix_(ix, ix)]) for ix in ([0, 1], [0, 2], [1, 2]))
        return -np.trace(j) * a2 + np.linalg.det(j)

    return hopf, np.linalg.det, solve


def test_bt_switching_between_the_fold_and_the_hopf_curve(co_branch):
    """From a BT of the fold curve the Hopf curve starts (kappa = 0), and from a BT of that Hopf
    curve the fold curve: each passes k = 0.4 (CO.PARAMS' k) at the one-parameter branch's HB /
    LP values there, from independent solves (UZ events at k = 0.4 on the curves)."""
    from contin.twoparam import NotAvailable, continue_point

    at_k04 = {"k=0.4": lambda state, p: state[-1] - 0.4}  # p2 = k is the state's last entry
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"q2": (0.5, 2.2), "k": (0.0, 1.0)},
                               max_steps=600, events=at_k04)
    fold = trace_fold_curve(CO(), co_branch.points("LP")[0], "k", opts, parameter="q2")
    bt = min(fold.points("BT"), key=lambda s: s.params["k"])  # (q2, k) = (1.16120, 0.72234)
    hopf = continue_point(CO(), fold, bt, "k", opts)
    assert hopf.kind == "hopf-curve" and len(hopf) > 20
    hopf_test, det, solve = _co_k04_references()
    states = {}
    for sp in hopf.points("UZ"):
        states[sp.params["q2"]] = sp
    refs = sorted(solve(hopf_test, np.concatenate([sp.state[:3], [q2]]) * (1 + 1e-3)) for q2, sp in states.items())
    assert len(refs) == 2 and refs[0] < refs[1] - 1e-3  # both HBs of the k = 0.4 branch
    assert sorted(states) == pytest.approx(refs, rel=1e-9)
    assert sorted(sp.params["q2"] for sp in co_branch.points("HB")) == pytest.approx(refs, rel=1e-9)
    # the Hopf curve passes its start: kappa changes sign there (Hopf on one side, neutral saddles on the other)
    kappa = hopf.observables["kappa"]
    assert kappa.min() < 0 < kappa.max()
    (other,) = [s for s in hopf.points("BT") if abs(s.params["k"] - bt.params["k"]) > 1e-3]  # (1.41763, 0.97140)
    back = continue_point(CO(), hopf, other, "k", opts)
    assert back.kind == "fold-curve"
    lps = sorted(sp.params["q2"] for sp in back.points("UZ"))
    refs = sorted(solve(det, np.concatenate([sp.state[:3], [sp.params["q2"]]]) * (1 + 1e-3)) for sp in back.points("UZ"))
    assert len(lps) == 2 and lps == pytest.approx(refs, rel=1e-9)
    assert sorted(sp.params["q2"] for sp in co_branch.points("LP")) == pytest.approx(refs, rel=1e-9)
    # the curve's own parameters only; no regridding
    with pytest.raises(ValueError, match="--free k"):
        continue_point(CO(), fold, bt, "q1", opts)
    from contin.foldcurve import SegmentRegrid

    with pytest.raises(NotAvailable):
        continue_point(CO(), fold, bt, "k", opts, regrid=SegmentRegrid(None))


def test_hopf_curve_from_a_start_outside_the_bounds_of_the_second_parameter_is_refused():
    """trace_hopf_curve from b2 = hb's value with bounds on b2 excluding it walked from the start to
    the bound and stored the points outside (qa15); trace_fold_curve refused such a start."""
    (hb,) = bt_branch(-0.5, {"b1": (-1.0, 0.2)}).points("HB")  # at b2 = -1
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b2": (-0.5, 1.0)}, max_steps=200)
    with pytest.raises(ValueError, match="start value b2=.* lies outside its bounds"):
        trace_hopf_curve(BTNormalForm(), hb, "b2", opts, parameter="b1")


def test_a_half_cut_at_a_bound_is_not_closed(co_branch):
    """CO's Hopf curve from its first HB, one direction, k within [0, 1]: the raw half runs on past
    k = 1 and closes there; cut at the bound it ends EP on it and is not a closed curve (it was
    marked closed, and trace_hopf_curve, which stops after a closed half, lost the other half and
    both GHs)."""
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"q2": (0.5, 2.2), "k": (0.0, 1.0)},
                               max_steps=600)
    half = trace_hopf_curve(CO(), co_branch.points("HB")[0], "k", opts, parameter="q2", both=False)
    assert half.message == "reached bound k=1" and not half.closed
    whole = trace_hopf_curve(CO(), co_branch.points("HB")[0], "k", opts, parameter="q2")
    assert len(whole.points("GH")) == 2 and not whole.closed
