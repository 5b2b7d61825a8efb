"""A Roessler scene (b = 2, c = 4; the steady state traced in a) for the tests of ``contin continue
--cycles`` from a PD (loaded through ``CONTIN_SCENES=cycle_fixture_scenes:SCENES``): its HB near
a = 0.125 starts cycles that double their period near a = 0.335."""

from __future__ import annotations

import math

import numpy as np

from contin.continuation import trace
from contin.options import ContinuationOptions
from contin.scene import Scene, SceneRequest, SceneResult
from tests.cycle_models import Roessler

DEFAULTS = {"b": 2.0, "c": 4.0}


def factory(parameters, discretization):
    return Roessler()


def run(request: SceneRequest) -> SceneResult:
    s = {**DEFAULTS, **request.params}
    a0, b, c = 0.05, float(s["b"]), float(s["c"])
    z0 = (c - math.sqrt(c * c - 4 * a0 * b)) / (2 * a0)
    opts = request.options_for(ContinuationOptions(bounds={"a": (0.01, 0.6)}))
    branch = trace(Roessler(), np.array([a0 * z0, -z0, z0]), {"a": a0, "b": b, "c": c}, "a", opts)
    request.finished(branch)
    return SceneResult(branches=[branch], parameters={"a": a0, "b": b, "c": c}, discretization={})


SCENES = {"roessler": Scene(name="roessler", summary="test fixture", defaults=DEFAULTS, run=run, x="a", y="phi",
                            problem_factory=factory)}


PITCHFORK_DEFAULTS = {"beta": 0.5, "q": 0.0}


def pitchfork_run(request: SceneRequest) -> SceneResult:
    """The trivial equilibrium of CyclePitchfork traced in mu across its HB at mu = 0."""
    from tests.cycle_models import CyclePitchfork

    s = {**PITCHFORK_DEFAULTS, **request.params}
    opts = request.options_for(ContinuationOptions(bounds={"mu": (-0.3, 1.0)}))
    params = {"mu": -0.3, "beta": float(s["beta"]), "q": float(s["q"])}
    branch = trace(CyclePitchfork(), np.zeros(3), params, "mu", opts)
    request.finished(branch)
    return SceneResult(branches=[branch], parameters=params, discretization={})


def pitchfork_factory(parameters, discretization):
    from tests.cycle_models import CyclePitchfork

    return CyclePitchfork()


SCENES["cycle-pitchfork"] = Scene(name="cycle-pitchfork", summary="test fixture: a pitchfork of cycles at mu = beta",
                                  defaults=PITCHFORK_DEFAULTS, run=pitchfork_run, x="mu", y="phi",
                                  problem_factory=pitchfork_factory)
