"""A scene whose branch crawls (for the tests of ``contin.stall``; loaded through
``CONTIN_SCENES=stall_fixture_scenes:SCENES``): u = p - A s(p) sin(k p) with s(p) a smooth step
at p = 0, so that for p > 0 the branch wiggles on a wavelength 2 pi / k = 6.3e-5 with slope A k
= 10 and the tracer, started with ds = 0.1 at p = -1, crawls once it is past 0."""

from __future__ import annotations

import numpy as np

from contin.continuation import trace
from contin.fromfunctions import from_functions
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneRequest, SceneResult

DEFAULTS = {"A": 1e-4}
K = 1e5


def residual(u, p):
    s = 0.5 * (1 + np.tanh(p["p"] / 0.01))
    return np.array([u[0] - p["p"] + p["A"] * s * np.sin(K * p["p"])])


def dresidual_dp(u, p, name):
    x = p["p"]
    s, ds = 0.5 * (1 + np.tanh(x / 0.01)), 0.5 / 0.01 / np.cosh(x / 0.01) ** 2
    if name == "p":
        return np.array([-1 + p["A"] * (ds * np.sin(K * x) + s * K * np.cos(K * x))])
    return np.array([s * np.sin(K * x)])


def problem(params):
    return from_functions(residual, np.array([-1.0]), {"p": -1.0, **params}, jacobian=lambda u, p: np.array([[1.0]]),
                          dF_dp=dresidual_dp, mass_matrix=np.eye(1))


def run(request: SceneRequest) -> SceneResult:
    params = {**DEFAULTS, **request.params}
    opts = request.options_for(ContinuationOptions(max_steps=80, step=StepOptions(ds=0.1, ds_max=0.1),
                                                   bounds={"p": (-2.0, 2.0)}))
    branch = trace(problem(params), np.array([-1.0]), {"p": -1.0, **params}, "p", opts)
    request.finished(branch)
    return SceneResult(branches=[branch], parameters={"p": -1.0, **params}, discretization={})


SCENES = {"wiggle": Scene(name="wiggle", summary="test fixture: a branch that crawls", defaults=DEFAULTS, run=run,
                          x="p", y="phi", problem_factory=lambda parameters, discretization: problem(parameters))}
