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


class GuardedPitchfork(ImperfectPitchfork):
    """The imperfect pitchfork with a declared "discretization error" 1e-5 * 10^(4 (x - 1/2)),
    which passes tol = 1e-5 exactly at x = 1/2 (contin's resolution guard, contin.problem)."""

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[tuple[int, float, float]] = []

    @staticmethod
    def error(x: float) -> float:
        return 1e-5 * 10.0 ** (4.0 * (x - 0.5))

    def under_resolved(self, u, p, tol):
        self.calls.append((u.size, float(u[0]), p["alpha"]))
        err = self.error(float(u[0]))
        return None if err <= tol else f"toy tail {err:.3g} > {tol:.3g}"


def _guarded_curve(tol):
    prob = GuardedPitchfork()
    p = {"lam": 2.0, "alpha": 0.1, "beta": BETA}
    opts = ContinuationOptions(step=StepOptions(ds=-0.02, ds_max=0.05), bounds={"lam": (-1, 3)}, max_steps=400,
                               resolution_tol=None)
    (lp,) = trace(prob, np.array([1.4]), p, "lam", opts).fold_points
    x_lp = lp.state[0]
    opts2 = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"lam": (-0.5, 3), "alpha": (-1, 1)},
                                max_steps=500, resolution_tol=tol)
    start = trace_fold_curve(prob, lp, "alpha", opts2, parameter="lam")
    return prob, x_lp, start


def test_fold_curve_is_guarded_on_its_base_state():
    """FoldProblem forwards under_resolved on u (not on phi or p2): the fold curve ends with MX
    before the first point with x > 1/2, which is not stored; the other direction is unaffected."""
    prob, x_lp, fc = _guarded_curve(1e-5)
    assert x_lp < 0.5  # the start fold is resolved
    x = fc.states[:, 0]
    assert fc.status == "MX" and x.max() <= 0.5 and x.min() < -0.5
    assert 0.5 - x.max() < 0.05  # stopped within one step (ds_max = 0.02 in the theta-norm) of x = 1/2
    assert all(prob.error(v) <= 1e-5 for v in x)
    # the hook saw the base state only (size 1 of the augmented 3) and alpha from the state
    assert {n for n, _, _ in prob.calls} == {1}
    assert all(a == pytest.approx(2 * v**3 + BETA * v**2, abs=1e-8) for _, v, a in prob.calls)
    forward = fc.message.split("forward: ", 1)[1]
    head, reason = forward.split(": ", 1)
    rejected_lam = float(head.rsplit("= ", 1)[1])
    assert head.startswith("under-resolved at lam = ") and rejected_lam > fc.params["lam"][np.argmax(x)]
    assert reason.startswith("toy tail ") and reason.endswith(")") and "(at alpha = " in reason
    mx = [s for s in fc.special_points if s.type == "MX"]
    assert len(mx) == 1 and mx[0].state[0] == x.max()


def test_fold_curve_guard_off_reaches_the_bounds():
    prob, _, fc = _guarded_curve(None)
    assert fc.status == "EP" and fc.states[:, 0].max() > 0.5 and prob.calls == []


def test_fold_problem_without_the_hook_forwards_nothing():
    fold = FoldProblem(ImperfectPitchfork(), "alpha", np.array([1.0]))
    assert fold.under_resolved(np.array([0.9, 1.0, 0.05]), {"lam": 0.5, "alpha": 0.0, "beta": BETA}, 1e-30) is None
    guarded = FoldProblem(GuardedPitchfork(), "alpha", np.array([1.0]))
    p = {"lam": 0.5, "alpha": 0.0, "beta": BETA}
    assert guarded.under_resolved(np.array([0.4, 1.0, 0.05]), p, 1e-5) is None
    assert guarded.under_resolved(np.array([0.9, 1.0, 0.05]), p, 1e-5) == "toy tail 0.000398 > 1e-05 (at alpha = 0.05)"


def test_a_stop_request_after_the_curve_is_traced_keeps_every_extremum(monkeypatch):
    """A Ctrl-C that came after both halves of a fold curve were traced, while its extrema of the
    second parameter were located: the locating traces stopped at once, so the XT points not yet
    located were dropped from a curve stored as finished (EP; `contin trace gravity-phase` lost
    fold0's second XT that way, and --resume keeps a finished curve as it is; qa18).  They are
    located in full (contin.cancel.deferred) and the request is still reported afterwards."""
    import contin.foldcurve as fc_mod
    from contin.cancel import request_stop, stop_on_sigint

    prob = ImperfectPitchfork()
    branch = trace(prob, np.array([1.4]), {"lam": 2.0, "alpha": 0.1, "beta": BETA}, "lam",
                   ContinuationOptions(step=StepOptions(ds=-0.02, ds_max=0.05), bounds={"lam": (-1, 3)}, max_steps=400))
    (lp,) = branch.fold_points
    locate = fc_mod._locate_extremum

    def ctrl_c_first(*args, **kwargs):
        request_stop()  # the signal arrives once the curve's steps are done
        return locate(*args, **kwargs)

    monkeypatch.setattr(fc_mod, "_locate_extremum", ctrl_c_first)
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"lam": (-0.5, 3), "alpha": (-1, 1)},
                               max_steps=500)
    with stop_on_sigint() as stop:
        curve = trace_fold_curve(prob, lp, "alpha", opts, parameter="lam")
    assert stop.requested
    xt = sorted(curve.points("XT"), key=lambda s: s.params["lam"])
    # both extrema of alpha = 2x^3 + beta x^2: the cusp (x = -beta/3) and the origin (x = 0)
    assert [round(s.params["alpha"], 9) for s in xt] == [round(BETA**3 / 27, 9), 0.0]
