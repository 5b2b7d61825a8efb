"""Two-parameter fold continuation on the imperfect pitchfork x^3 - lam x + alpha + beta x^2.

Folds satisfy 3x^2 + 2 beta x - lam = 0, so along the fold curve (parametrised by x)
alpha = 2x^3 + beta x^2 and lam = 3x^2 + 2 beta x (Golubitsky & Schaeffer 1985, ch. III).
alpha has extrema at x = 0 (the bifurcation set alpha = 0) and x = -beta/3, where lam is
extremal too: the cusp on the hysteresis variety alpha = beta^3/27, lam = -beta^2/3.
"""

import numpy as np
import pytest

from contin.continuation import trace
from contin.foldcurve import FoldProblem, fold_start, trace_fold_curve
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from contin.problem import check_jacobian
from problems.demo import ImperfectPitchfork

BETA = 0.3


@pytest.fixture(scope="module")
def fold_curve():
    prob = ImperfectPitchfork()
    p = {"lam": 2.0, "alpha": 0.1, "beta": BETA}
    opts = ContinuationOptions(step=StepOptions(ds=-0.02, ds_max=0.05), bounds={"lam": (-1, 3)}, max_steps=400)
    branch = trace(prob, np.array([1.4]), p, "lam", opts)
    (lp,) = branch.fold_points
    opts2 = ContinuationOptions(
        step=StepOptions(ds=0.01, ds_max=0.02), bounds={"lam": (-0.5, 3), "alpha": (-1, 1)}, max_steps=500
    )
    return prob, lp, trace_fold_curve(prob, lp, "alpha", opts2, parameter="lam")


def test_fold_curve_follows_the_analytic_curve(fold_curve):
    _, _, fc = fold_curve
    x = fc.states[:, 0]
    assert fc.kind == "fold-curve" and fc.free == ("lam", "alpha")
    assert np.max(np.abs(fc.params["alpha"] - (2 * x**3 + BETA * x**2))) < 1e-9
    assert np.max(np.abs(fc.params["lam"] - (3 * x**2 + 2 * BETA * x))) < 1e-9
    assert x.min() < -0.5 and x.max() > 0.5  # both directions traced through the cusp


def test_fold_curve_extrema_are_located(fold_curve):
    _, _, fc = fold_curve
    xt = sorted(fc.points("XT"), key=lambda s: s.params["lam"])
    assert len(xt) == 2
    cusp, origin = xt
    assert cusp.params["alpha"] == pytest.approx(BETA**3 / 27, abs=1e-9)
    assert cusp.params["lam"] == pytest.approx(-(BETA**2) / 3, abs=1e-7)
    assert origin.params["alpha"] == pytest.approx(0.0, abs=1e-10)
    assert origin.params["lam"] == pytest.approx(0.0, abs=1e-8)
    (lp,) = fc.points("LP")  # extremum of lam: the cusp again
    assert lp.params["lam"] == pytest.approx(-(BETA**2) / 3, abs=1e-10)
    assert lp.params["alpha"] == pytest.approx(BETA**3 / 27, abs=1e-10)


def test_one_parameter_fold_lies_on_fold_curve(fold_curve):
    prob, lp, fc = fold_curve
    i = np.argmin(np.abs(fc.params["alpha"] - lp.params["alpha"]) + np.abs(fc.params["lam"] - lp.params["lam"]))
    # the start fold is a point of the curve, and the curve's residual vanishes there
    assert abs(fc.params["alpha"][i] - lp.params["alpha"]) < 1e-12
    x = lp.state[0]
    assert lp.params["alpha"] == pytest.approx(2 * x**3 + BETA * x**2, abs=1e-10)


def test_fold_system_jacobian_matches_finite_differences():
    prob = ImperfectPitchfork()
    p = {"lam": 0.5, "alpha": 0.1, "beta": BETA}
    fold = FoldProblem(prob, "alpha", np.array([1.0]))
    state = np.array([0.3, 0.9, 0.05])
    chk = check_jacobian(fold, state, p, parameters=("lam",))
    assert chk.relative_error < 1e-7
    assert chk.dp_errors["lam"] < 1e-7
