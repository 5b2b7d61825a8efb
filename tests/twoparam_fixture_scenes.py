"""A scene of the imperfect pitchfork F = x^3 - lam x + mu + K mu x^2 + Q x^5 for the tests of
``contin continue`` and ``contin fit`` (loaded through
``CONTIN_SCENES=twoparam_fixture_scenes:SCENES``): the branch x = 0 in lam at mu = 0 (the
pitchfork at lam = 0), both halves of the pitchfork, and the branches at the mu of ``mus``.

A fixture, not a demo: F is its own canonical unfolding (b1 = 1, b2 = 0, alpha1 = 1,
beta1 = K, q5 = Q) and its fold curve is x -> (lam, mu) = (3x^2 + 2K mu x + 5Q x^4,
mu from F = 0) -- the closed forms the tests check.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from contin.branch import relabel
from contin.continuation import switch, trace_both
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from contin.scene import Scene, SceneRequest, SceneResult

DEFAULTS = {"K": 0.5, "Q": 0.2, "mus": "1e-4,3e-4", "lam_min": -0.3, "lam_max": 0.3}


class Pitchfork:
    parameter_names = ("lam", "mu", "K", "Q")

    def residual(self, u, p):
        x = u[0]
        return np.array([x**3 - p["lam"] * x + p["mu"] + p["K"] * p["mu"] * x**2 + p["Q"] * x**5])

    def jacobian(self, u, p):
        x = u[0]
        return sp.csr_matrix([[3 * x**2 - p["lam"] + 2 * p["K"] * p["mu"] * x + 5 * p["Q"] * x**4]])

    def dresidual_dp(self, u, p, name):
        x = u[0]
        return np.array([{"lam": -x, "mu": 1 + p["K"] * x**2, "K": p["mu"] * x**2, "Q": x**5}[name]])

    def order_parameter(self, u, p):
        return float(u[0])

    def observables(self, u, p):
        return {"x": float(u[0])}


def factory(parameters, discretization):
    return Pitchfork()


def run(request: SceneRequest) -> SceneResult:
    s = {**DEFAULTS, **request.params}
    K, Q = float(s["K"]), float(s["Q"])
    mus = [float(a) for a in str(s["mus"]).split(",") if a.strip()]
    pb = Pitchfork()
    opts = request.options_for(ContinuationOptions(
        bounds={"lam": (float(s["lam_min"]), float(s["lam_max"]))}, max_steps=2000,
        step=StepOptions(ds=0.002, ds_max=0.005, max_angle=0.1)))
    base = trace_both(pb, np.array([0.0]), {"lam": float(s["lam_min"]), "mu": 0.0, "K": K, "Q": Q}, "lam",
                      opts, branch_id="base")
    branches = [base]
    relabel(branches)
    bp = base.branch_points[0]
    off = ContinuationOptions(bounds=opts.bounds, max_steps=2000, step=opts.step,
                              detection=DetectionOptions(detect_branch_points=False))
    for k, b in enumerate(switch(pb, base, bp, off)):
        b.id = f"m0.{k}"
        branches.append(b)
    for m in mus:
        for k, (x0, lam0) in enumerate(((-0.6, float(s["lam_min"])), (0.6, float(s["lam_max"])))):
            p = {"lam": lam0, "mu": m, "K": K, "Q": Q}
            branches.append(trace_both(pb, np.array([x0]), p, "lam", off, branch_id=f"m{m:g}.{k}"))
    relabel(branches)
    for b in branches:
        request.finished(b)
    return SceneResult(branches=branches, parameters={"K": K, "Q": Q, "mu": 0.0, "lam": 0.0},
                       discretization={},
                       extra={"normal_form": {"imperfection": "mu", "delta": "x"}})


SCENES = {"imperfect-pitchfork": Scene(name="imperfect-pitchfork", summary="test fixture", defaults=DEFAULTS,
                                       run=run, x="lam", y="x", problem_factory=factory)}
