"""Zero-Hopf (ZH) and double-Hopf (HH) points on fold and Hopf curves (``contin.codim2tests``),
against closed forms of two small systems built for the purpose (defined, with their scenes for
the CLI, in tests/codim2_fixture_scenes.py):

- ``FoldHopf``: x' = a + b - x^2 + b x and an oscillator (v, w) with real part r = b - 1 + x,
  frequency 1 and cubic damping.  Folds: x = b/2, a = -b - b^2/4; Hopf points: x = 1 - b,
  a = (1 - b)(1 - 2 b) - b.  Both curves meet at the zero-Hopf point (a, b) = (-7/9, 2/3),
  x = 1/3.
- ``TwoOscillators``: u = 0 with two damped oscillators of frequencies 1 and 2 and real parts
  r1 = a + b + b^2 - 1, r2 = b - a/2.  The Hopf curve r1 = 0 (a = 1 - b - b^2) meets r2 = 0 where
  b^2 + 3 b - 1 = 0: the double-Hopf point b = (sqrt(13) - 3)/2, a = 2 b = sqrt(13) - 3
  (omega = 1, omega2 = 2).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from contin.continuation import trace, trace_both
from contin.foldcurve import trace_fold_curve
from contin.hopfcurve import trace_hopf_curve
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from tests.codim2_fixture_scenes import CoupledFoldHopf, FoldHopf, TwoOscillators

STEP = StepOptions(ds=0.02, ds_max=0.05)


def _fold_hopf_points():
    pb = FoldHopf()
    br = trace_both(pb, np.array([0.5, 0.0, 0.0]), {"a": 0.25, "b": 0.0}, "a",
               ContinuationOptions(step=STEP, bounds={"a": (-0.5, 2.0)}, max_steps=400))
    return pb, br


def _assert_decoupled_zero_hopf_normal_form(zh):
    """FoldHopf's ZH in xi = x - 1/3, Z = v + i w: xi' = -xi^2, Z' = i Z + xi Z - Z |Z|^2, i.e.
    (z = Z / sqrt(2), q1 unit) g200 = -1, g011 = 0, g110 = 1: B = 1 (q0 -> -q0 for B >= 0), C = 0,
    theta = Re g110 / g200 = -1; a degenerate ZH (C = 0: the oscillator does not feed back), so
    s = sign(B C) = 0 and E (which divides by C) is NaN."""
    assert zh.data["B"] == pytest.approx(1.0, rel=1e-8) and abs(zh.data["C"]) < 1e-12
    assert zh.data["theta"] == pytest.approx(-1.0, rel=1e-8) and zh.data["s"] == 0 and math.isnan(zh.data["E"])


def test_zero_hopf_on_the_fold_curve():
    pb, br = _fold_hopf_points()
    (lp,) = br.points("LP")
    assert abs(lp.params["a"]) < 1e-10
    curve = trace_fold_curve(pb, lp, "b", ContinuationOptions(step=STEP, bounds={"a": (-2, 1), "b": (-0.5, 1.2)},
                                                             max_steps=400), parameter="a")
    (zh,) = curve.points("ZH")
    assert zh.converged and "zero-Hopf" in zh.note
    assert zh.params["b"] == pytest.approx(2 / 3, abs=1e-10)
    assert zh.params["a"] == pytest.approx(-7 / 9, abs=1e-10)
    assert zh.state[0] == pytest.approx(1 / 3, abs=1e-10) and zh.data["omega"] == pytest.approx(1.0, rel=1e-10)
    _assert_decoupled_zero_hopf_normal_form(zh)
    # the fold curve itself is a = -b - b^2/4
    b = curve.params["b"]
    assert np.allclose(curve.params["a"], -b - b**2 / 4, atol=1e-10)


def test_zero_hopf_on_the_hopf_curve_and_no_spurious_bt_gh_hh():
    pb, br = _fold_hopf_points()
    (hb,) = br.points("HB")
    assert hb.params["a"] == pytest.approx(1.0, abs=1e-10)  # x = 1 - b = 1 at b = 0
    curve = trace_hopf_curve(pb, hb, "b", ContinuationOptions(step=STEP, bounds={"a": (-2, 2), "b": (-0.5, 1.0)},
                                                              max_steps=400), parameter="a")
    (zh,) = curve.points("ZH")
    assert zh.converged
    assert zh.params["b"] == pytest.approx(2 / 3, abs=1e-10)
    assert zh.params["a"] == pytest.approx(-7 / 9, abs=1e-10)
    assert zh.data["omega"] == pytest.approx(1.0, rel=1e-10)
    _assert_decoupled_zero_hopf_normal_form(zh)
    b = curve.params["b"]
    assert np.allclose(curve.params["a"], (1 - b) * (1 - 2 * b) - b, atol=1e-10)
    assert not curve.points("BT") and not curve.points("GH") and not curve.points("HH")


def test_double_hopf_on_the_hopf_curve():
    pb = TwoOscillators()
    br = trace(pb, np.zeros(4), {"a": 0.5, "b": 0.0}, "a",
               ContinuationOptions(step=STEP, bounds={"a": (0.5, 2.0)}, max_steps=200))
    (hb,) = br.points("HB")
    assert hb.params["a"] == pytest.approx(1.0, abs=1e-10) and hb.data["omega"] == pytest.approx(1.0, rel=1e-10)
    opts = ContinuationOptions(step=STEP, bounds={"a": (0.0, 2.0), "b": (-0.2, 0.8)}, max_steps=200)
    curve = trace_hopf_curve(pb, hb, "b", opts, parameter="a")
    (hh,) = curve.points("HH")
    assert hh.converged and "double Hopf" in hh.note
    assert hh.params["b"] == pytest.approx((math.sqrt(13) - 3) / 2, abs=1e-10)
    assert hh.params["a"] == pytest.approx(math.sqrt(13) - 3, abs=1e-10)
    assert hh.data["omega"] == pytest.approx(1.0, rel=1e-10) and hh.data["omega2"] == pytest.approx(2.0, rel=1e-10)
    # the normal form: z_k = Z_k / sqrt(2) (q unit), Z_k' = (i omega_k - |Z_k|^2) Z_k at the HH, so
    # z_k' = i omega_k z_k - 2 z_k |z_k|^2: p11 = p22 = -2, p12 = p21 = 0 (uncoupled), theta = delta = 0
    # (a 1:2 resonance, omega2 = 2 omega, without quadratic terms: the resonant solves are not needed)
    assert {k: hh.data[k] for k in HH_NF} == pytest.approx(HH_NF, abs=1e-8)
    assert not curve.points("ZH") and not curve.points("BT")
    b = curve.params["b"]
    assert np.allclose(curve.params["a"], 1 - b - b**2, atol=1e-10)
    # HH detection follows HB detection: off with detect_hopf=False
    off = trace_hopf_curve(pb, hb, "b", replace(opts, detection=DetectionOptions(detect_hopf=False)), parameter="a")
    assert not off.points("HH") and off.params["b"].max() > 0.6  # past the HH at b = 0.303


HH_NF = {"p11": -2.0, "p12": 0.0, "p21": 0.0, "p22": -2.0, "theta": 0.0, "delta": 0.0}


class SlavedBT:
    """The BT normal form (tests/hopf_models.BTNormalForm) with z' = (b2 + c) z: its Hopf curve is
    b1 = 0, omega^2 = -b2 for b2 < 0, neutral saddles for b2 > 0; the real eigenvalue b2 + c
    crosses 0 at b2 = -c."""

    parameter_names = ("b1", "b2")

    def __init__(self, c: float) -> None:
        self.c = c

    def residual(self, u, p):
        x, y, z = u
        return np.array([y, p["b1"] + p["b2"] * x + x * x - x * y, (p["b2"] + self.c) * z])

    def jacobian(self, u, p):
        x, y, z = u
        return sp.csr_matrix(np.array([[0.0, 1.0, 0.0], [p["b2"] + 2 * x - y, -x, 0.0], [0.0, 0.0, p["b2"] + self.c]]))

    def dresidual_dp(self, u, p, name):
        return np.array([0.0, 1.0, 0.0]) if name == "b1" else np.array([0.0, u[0], u[2]])


@pytest.mark.parametrize("c", [0.5, -0.5])
def test_zero_hopf_only_on_the_hopf_part_of_the_curve(c):
    """c = 0.5: the real eigenvalue crosses 0 at b2 = -0.5 on the Hopf part: ZH there (omega^2 =
    0.5).  c = -0.5: it crosses at b2 = 0.5, on the neutral-saddle part past the BT: no ZH (there
    is no Hopf pair; before, det J / kappa's sign change was labelled ZH there)."""
    pb = SlavedBT(c)
    start = {"b1": -0.5, "b2": -1.0}
    x0 = 0.5 * (1 - math.sqrt(1 - 4 * start["b1"]))  # x^2 - x + b1 = 0 through x = 0 at b1 = 0
    br = trace(pb, np.array([x0, 0.0, 0.0]), start, "b1",
               ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-1.0, 0.2)}, max_steps=200))
    (hb,) = [s for s in br.points("HB") if abs(s.params["b1"]) < 1e-8]
    curve = trace_hopf_curve(pb, hb, "b2", ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1),
                                                               bounds={"b2": (-2.0, 1.0)}, max_steps=200),
                             parameter="b1")
    assert len(curve.points("BT")) == 1 and curve.params["b2"].max() > 0.9
    zh = curve.points("ZH")
    if c > 0:
        (point,) = zh
        assert point.params["b2"] == pytest.approx(-0.5, abs=1e-10) and point.data["omega"] == pytest.approx(
            math.sqrt(0.5), rel=1e-10)
    else:
        assert not zh and not curve.points("HH")


def test_bogdanov_takens_normal_form_coefficients():
    """Kuznetsov's BT normal form x' = y, y' = b1 + b2 x + x^2 - x y has a = 1, b = s = -1 at the
    origin (q0 = (1, 0), q1 = (0, 1), p1 = (0, 1), p0 = (1, 0)); a rotation of the coordinates
    keeps |q0| and so a and b.  The BT points located on its Hopf and fold curves carry them."""
    from contin.codim2tests import bogdanov_takens_coefficients
    from tests.hopf_models import BTNormalForm
    from tests.test_hopfcurve import bt_branch, bt_hopf_curve

    origin = {"b1": 0.0, "b2": 0.0}
    assert bogdanov_takens_coefficients(BTNormalForm(), np.zeros(2), origin) == pytest.approx({"a": 1.0, "b": -1.0}, abs=1e-12)

    class Rotated:
        parameter_names = ("b1", "b2")
        t = np.array([[math.cos(0.7), -math.sin(0.7)], [math.sin(0.7), math.cos(0.7)]])

        def residual(self, v, p):
            return self.t.T @ BTNormalForm().residual(self.t @ v, p)

        def jacobian(self, v, p):
            return self.t.T @ BTNormalForm().jacobian(self.t @ v, p) @ self.t

        def dresidual_dp(self, v, p, name):
            return self.t.T @ BTNormalForm().dresidual_dp(self.t @ v, p, name)

    assert bogdanov_takens_coefficients(Rotated(), np.zeros(2), origin) == pytest.approx({"a": 1.0, "b": -1.0}, abs=1e-9)
    (on_hopf,) = bt_hopf_curve().points("BT")
    assert on_hopf.data["a"] == pytest.approx(1.0, abs=1e-8) and on_hopf.data["b"] == pytest.approx(-1.0, abs=1e-8)
    lp = bt_branch(0.2, {"b1": (-1.0, 0.3)}).points("LP")[0]
    fold = trace_fold_curve(BTNormalForm(), lp, "b2", ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1),
                                                                           bounds={"b2": (-2.0, 2.0)}, max_steps=200),
                            parameter="b1")
    (on_fold,) = fold.points("BT")
    assert on_fold.data["a"] == pytest.approx(1.0, abs=1e-8) and on_fold.data["b"] == pytest.approx(-1.0, abs=1e-8)


def _one(points):
    (point,) = points
    return point


def test_switching_at_zero_hopf_between_the_fold_and_the_hopf_curve():
    """From the ZH of the fold curve the Hopf curve starts (the pair +-i of the base pencil), and
    from the ZH of the Hopf curve the fold curve (the real zero eigenvalue's null vector): every
    point of each switched curve lies on the other curve's closed form (Hopf: x = 1 - b,
    a = (1 - b)(1 - 2 b) - b, omega = 1; fold: x = b/2, a = -b - b^2/4), both sides of the ZH are
    traced, and the start is the one ZH of the new curve, at (a, b) = (-7/9, 2/3)."""
    from contin.foldcurve import SegmentRegrid
    from contin.twoparam import NotAvailable, continue_point, continuable_types

    assert {"ZH", "HH"} <= set(continuable_types())
    pb, br = _fold_hopf_points()
    opts = ContinuationOptions(step=STEP, bounds={"a": (-2, 2), "b": (-0.5, 1.0)}, max_steps=400)
    fold = trace_fold_curve(pb, _one(br.points("LP")), "b", opts, parameter="a")
    hopf = continue_point(pb, fold, _one(fold.points("ZH")), "b", opts)
    assert hopf.kind == "hopf-curve" and hopf.free == ("a", "b")
    b, n = hopf.params["b"], 3
    assert b.min() < 0 and b.max() > 0.99  # both sides of b = 2/3
    assert np.max(np.abs(hopf.params["a"] - ((1 - b) * (1 - 2 * b) - b))) < 1e-10
    assert np.max(np.abs(hopf.states[:, 0] - (1 - b))) < 1e-10
    assert np.max(np.abs(hopf.observables["kappa"] - 1.0)) < 1e-10  # omega = 1 all along
    for i in range(len(hopf)):  # the base state is an equilibrium: F = 0 (fold-curve states are not: phi != 0)
        p = {"a": hopf.params["a"][i], "b": b[i]}
        assert np.max(np.abs(pb.residual(hopf.state(i)[:n], p))) < 1e-10
    start = _one(hopf.points("ZH"))
    assert start.params["a"] == pytest.approx(-7 / 9, abs=1e-10) and start.params["b"] == pytest.approx(2 / 3, abs=1e-10)
    assert "start: ZH" in start.note and start.data["omega"] == pytest.approx(1.0, rel=1e-10)
    assert not hopf.points("BT") and not hopf.points("HH") and not hopf.points("GH")

    back = continue_point(pb, hopf, start, "b", opts)
    assert back.kind == "fold-curve"
    b = back.params["b"]
    assert b.min() < 0 and b.max() > 0.99
    assert np.max(np.abs(back.params["a"] - (-b - b**2 / 4))) < 1e-10
    assert np.max(np.abs(back.states[:, 0] - b / 2)) < 1e-10
    start = _one(back.points("ZH"))
    assert start.params["a"] == pytest.approx(-7 / 9, abs=1e-10) and start.params["b"] == pytest.approx(2 / 3, abs=1e-10)
    assert "start: ZH" in start.note and start.data["omega"] == pytest.approx(1.0, rel=1e-10)
    # no regridding; no HH on a fold curve
    with pytest.raises(NotAvailable, match="zero-Hopf"):
        continue_point(pb, fold, _one(fold.points("ZH")), "b", opts, regrid=SegmentRegrid(None))
    with pytest.raises(NotAvailable, match="from a Hopf curve, not from a fold-curve"):
        continue_point(pb, fold, replace(_one(fold.points("ZH")), type="HH"), "b", opts)


def test_no_generalized_hopf_at_the_pole_of_l1_and_l2_of_the_true_one():
    """CoupledFoldHopf (c = 0.5): l1 has a pole at the ZH (-7/9, 2/3); the Hopf curve through it
    reported a converged GH there (l1 = -7.5e10).  Now its only GH is the true one, at
    b = (2 - c)/3 = 1/2, a = (1 - b)(1 - 2 b) - b = -1/2, with l2 = -4/c = -8 (closed form: the
    class docstring); the Hopf curve switched from the fold curve's ZH has the same GH and none
    at its start."""
    from contin.twoparam import continue_point

    pb = CoupledFoldHopf(0.5)
    br = trace_both(pb, np.array([0.5, 0.0, 0.0]), {"a": 0.25, "b": 0.0}, "a",
                    ContinuationOptions(step=STEP, bounds={"a": (-0.5, 2.0)}, max_steps=400))
    opts = ContinuationOptions(step=STEP, bounds={"a": (-2, 2), "b": (-0.5, 1.0)}, max_steps=400)
    hopf = trace_hopf_curve(pb, _one(br.points("HB")), "b", opts, parameter="a")
    fold = trace_fold_curve(pb, _one(br.points("LP")), "b", opts, parameter="a")
    switched = continue_point(pb, fold, _one(fold.points("ZH")), "b", opts)
    # the ZH's normal form: in xi = x - 1/3, Z = v + i w, xi' = -xi^2 + c |Z|^2, Z' = i Z + xi Z - Z |Z|^2;
    # in z = Z / sqrt(2) (q1 unit): g200 = -1, g011 = 2 c, g110 = 1, g021 = -2, g300 = g111 = g210 = 0, so
    # (Kuznetsov sec. 8.5; q0 -> -q0 for B >= 0) B = 1, C = -2 c, s = -1, theta = -1,
    # E = Re[g110 Re g021 / g011 - g021 g200 / g011] = -1/c - 1/c = -2/c
    nf = {"B": 1.0, "C": -1.0, "E": -4.0, "s": -1.0, "theta": -1.0}
    assert {k: _one(fold.points("ZH")).data[k] for k in nf} == pytest.approx(nf, rel=1e-7)
    for curve in (hopf, switched):
        zh, gh = _one(curve.points("ZH")), _one(curve.points("GH"))
        assert zh.params["b"] == pytest.approx(2 / 3, abs=1e-10)
        assert {k: zh.data[k] for k in nf} == pytest.approx(nf, rel=1e-7)
        assert gh.params["b"] == pytest.approx(0.5, abs=1e-8) and gh.params["a"] == pytest.approx(-0.5, abs=1e-8)
        assert gh.converged and abs(gh.data["l1"]) < 1e-8
        assert gh.data["l2"] == pytest.approx(-8.0, abs=1e-6)


def test_switching_at_double_hopf_to_the_other_pair():
    """From the HH of the first oscillator's Hopf curve (a = 1 - b - b^2, omega = 1) the Hopf
    curve of the second oscillator starts: r2 = b - a/2 = 0, i.e. a = 2 b, with omega = 2 all
    along; its start is its one HH (omega 2, omega2 1) at b = (sqrt(13) - 3)/2."""
    from contin.twoparam import continue_point

    pb = TwoOscillators()
    br = trace(pb, np.zeros(4), {"a": 0.5, "b": 0.0}, "a",
               ContinuationOptions(step=STEP, bounds={"a": (0.5, 2.0)}, max_steps=200))
    opts = ContinuationOptions(step=STEP, bounds={"a": (-1.0, 2.0), "b": (-0.2, 0.8)}, max_steps=200)
    first = trace_hopf_curve(pb, _one(br.points("HB")), "b", opts, parameter="a")
    other = continue_point(pb, first, _one(first.points("HH")), "b", opts)
    assert other.kind == "hopf-curve"
    b = other.params["b"]
    assert b.min() == pytest.approx(-0.2, abs=1e-12) and b.max() == pytest.approx(0.8, abs=1e-12)  # bound to bound
    assert np.max(np.abs(other.params["a"] - 2 * b)) < 1e-10
    assert np.max(np.abs(other.observables["kappa"] - 4.0)) < 1e-10
    assert np.max(np.abs(other.states[:, :4])) < 1e-10  # the equilibrium u = 0
    start = _one(other.points("HH"))
    assert start.params["b"] == pytest.approx((math.sqrt(13) - 3) / 2, abs=1e-10)
    assert start.params["a"] == pytest.approx(math.sqrt(13) - 3, abs=1e-10)
    assert start.data == pytest.approx({"omega": 2.0, "omega2": 1.0, **HH_NF}, rel=1e-10, abs=1e-8)
    assert "start: HH" in start.note
    assert not other.points("ZH") and not other.points("BT")
    # and back: from the new curve's HH, the first oscillator's curve a = 1 - b - b^2
    again = continue_point(pb, other, start, "b", opts)
    b = again.params["b"]
    assert np.max(np.abs(again.params["a"] - (1 - b - b**2))) < 1e-10
    assert np.max(np.abs(again.observables["kappa"] - 1.0)) < 1e-10
    # the start of the new curve carries the HH's normal form with the pairs swapped (its own pair
    # is the source's second): an HH with made-up unequal coefficients
    made_up = {"p11": 1.0, "p12": 2.0, "p21": 3.0, "p22": 4.0, "theta": 0.5, "delta": 3.0}
    hh = _one(first.points("HH"))
    swapped = _one(continue_point(pb, first, replace(hh, data={**hh.data, **made_up}), "b", opts).points("HH"))
    assert {k: swapped.data[k] for k in made_up} == {"p11": 4.0, "p12": 3.0, "p21": 2.0, "p22": 1.0, "theta": 3.0,
                                                     "delta": 0.5}


def test_cli_continue_from_zero_hopf_and_double_hopf(tmp_path, monkeypatch):
    """`contin continue FILE --from ZHk / HHk --free b` on the fixture scenes: the fold curve's ZH
    starts the Hopf curve, that curve's ZH the fold curve again, the Hopf curve's HH the other
    oscillator's Hopf curve; every stored curve lies on its closed form."""
    import json
    from pathlib import Path

    from click.testing import CliRunner

    from contin import io
    from contin.cli import main

    monkeypatch.syspath_prepend(str(Path(__file__).parent))
    monkeypatch.setenv("CONTIN_SCENES", "codim2_fixture_scenes:SCENES")

    def run(*args):
        res = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
        assert res.exit_code == 0, res.output
        return res

    def label(res, kind):
        (row,) = [sp for sp in json.loads(res.stdout)["special_points"] if sp["type"] == kind]
        return row["label"], row["params"]

    box = ("--bounds", "a=-2:2", "--bounds", "b=-0.5:1")
    first, fold, hopf, back = (tmp_path / f"{n}.h5" for n in ("run", "fold", "hopf", "back"))
    run("trace", "fold-hopf", "--no-stability", "-q", "-o", first)
    (branch,), _ = io.load(first)
    res = run("continue", first, "--from", _one(branch.points("LP")).name, "--free", "b", *box, "-o", fold, "--json")
    zh, at = label(res, "ZH")  # `continue --from LP` now detects ZH, as trace_fold_curve did
    assert at["a"] == pytest.approx(-7 / 9, abs=1e-10) and at["b"] == pytest.approx(2 / 3, abs=1e-10)
    res = run("continue", fold, "--from", zh, "--free", "b", *box, "-o", hopf, "--json")
    assert f"Hopf curve from {zh}" in res.stderr
    (curve,), _ = io.load(hopf)
    b = curve.params["b"]
    assert curve.kind == "hopf-curve" and b.min() < 0 and b.max() > 0.99
    assert np.max(np.abs(curve.params["a"] - ((1 - b) * (1 - 2 * b) - b))) < 1e-10
    (start,) = curve.points("ZH")
    assert start.params["b"] == pytest.approx(2 / 3, abs=1e-10) and start.params["a"] == pytest.approx(-7 / 9, abs=1e-10)
    _assert_decoupled_zero_hopf_normal_form(start)  # the ZH's normal form, through the file
    res = run("continue", hopf, "--from", start.name, "--free", "b", *box, "-o", back, "--json")
    assert f"fold curve from {start.name}" in res.stderr
    (curve,), _ = io.load(back)
    b = curve.params["b"]
    assert curve.kind == "fold-curve" and np.max(np.abs(curve.params["a"] - (-b - b**2 / 4))) < 1e-10

    first, hopf, other = (tmp_path / f"{n}.h5" for n in ("osc", "osc-hopf", "osc-other"))
    box = ("--bounds", "a=-1:2", "--bounds", "b=-0.2:0.8")
    run("trace", "two-oscillators", "--no-stability", "-q", "-o", first)
    (branch,), _ = io.load(first)
    res = run("continue", first, "--from", _one(branch.points("HB")).name, "--free", "b", *box, "-o", hopf, "--json")
    hh, at = label(res, "HH")
    assert at["b"] == pytest.approx((math.sqrt(13) - 3) / 2, abs=1e-10)
    res = run("continue", hopf, "--from", hh, "--free", "b", *box, "-o", other, "--json")
    assert f"Hopf curve from {hh}" in res.stderr
    (curve,), _ = io.load(other)
    b = curve.params["b"]
    assert np.max(np.abs(curve.params["a"] - 2 * b)) < 1e-10 and np.max(np.abs(curve.observables["kappa"] - 4)) < 1e-10
    (start,) = curve.points("HH")
    assert start.params["b"] == pytest.approx((math.sqrt(13) - 3) / 2, abs=1e-10)
    assert {k: start.data[k] for k in HH_NF} == pytest.approx(HH_NF, abs=1e-8)  # the HH's normal form, through the file
