"""Scenes of the two small systems of tests/test_zero_double_hopf.py, whose fold and Hopf curves
are known in closed form, for the tests of ``contin continue --from ZHk / HHk`` (loaded through
``CONTIN_SCENES=codim2_fixture_scenes:SCENES``):

- ``fold-hopf`` (:class:`FoldHopf`): x' = a + b - x^2 + b x and an oscillator (v, w) with real
  part r = b - 1 + x, frequency 1 and cubic damping.  Folds: x = b/2, a = -b - b^2/4; Hopf
  points: x = 1 - b, a = (1 - b)(1 - 2 b) - b; both curves meet at the zero-Hopf point
  (a, b) = (-7/9, 2/3).  The scene traces the branch in a at b = 0 (LP at a = 0, HB at a = 1).
- ``two-oscillators`` (:class:`TwoOscillators`): u = 0 with two damped oscillators of
  frequencies 1 and 2 and real parts r1 = a + b + b^2 - 1, r2 = b - a/2; the Hopf curves
  a = 1 - b - b^2 and a = 2 b meet at the double-Hopf point b = (sqrt(13) - 3)/2.  The scene
  traces u = 0 in a at b = 0 (HB at a = 1).

A fixture, not a demo.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from contin.branch import relabel
from contin.continuation import trace, trace_both
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneRequest, SceneResult


class FoldHopf:
    parameter_names = ("a", "b")

    def residual(self, u, p):
        x, v, w = u
        r, rho = p["b"] - 1 + x, v * v + w * w
        return np.array([p["a"] + p["b"] - x * x + p["b"] * x, r * v - w - v * rho, v + r * w - w * rho])

    def jacobian(self, u, p):
        x, v, w = u
        r, rho = p["b"] - 1 + x, v * v + w * w
        return sp.csr_matrix(np.array([[-2 * x + p["b"], 0.0, 0.0],
                                       [v, r - rho - 2 * v * v, -1 - 2 * v * w],
                                       [w, 1 - 2 * v * w, r - rho - 2 * w * w]]))

    def dresidual_dp(self, u, p, name):
        x, v, w = u
        return np.array([1.0, 0.0, 0.0]) if name == "a" else np.array([1 + x, v, w])


class TwoOscillators:
    parameter_names = ("a", "b")

    def _parts(self, p):
        return p["a"] + p["b"] + p["b"] ** 2 - 1, p["b"] - p["a"] / 2

    def residual(self, u, p):
        v1, w1, v2, w2 = u
        r1, r2 = self._parts(p)
        s1, s2 = v1 * v1 + w1 * w1, v2 * v2 + w2 * w2
        return np.array([r1 * v1 - w1 - v1 * s1, v1 + r1 * w1 - w1 * s1,
                         r2 * v2 - 2 * w2 - v2 * s2, 2 * v2 + r2 * w2 - w2 * s2])

    def jacobian(self, u, p):
        v1, w1, v2, w2 = u
        r1, r2 = self._parts(p)
        s1, s2 = v1 * v1 + w1 * w1, v2 * v2 + w2 * w2
        j = np.zeros((4, 4))
        j[:2, :2] = [[r1 - s1 - 2 * v1 * v1, -1 - 2 * v1 * w1], [1 - 2 * v1 * w1, r1 - s1 - 2 * w1 * w1]]
        j[2:, 2:] = [[r2 - s2 - 2 * v2 * v2, -2 - 2 * v2 * w2], [2 - 2 * v2 * w2, r2 - s2 - 2 * w2 * w2]]
        return sp.csr_matrix(j)

    def dresidual_dp(self, u, p, name):
        v1, w1, v2, w2 = u
        d1, d2 = (1.0, -0.5) if name == "a" else (1 + 2 * p["b"], 1.0)
        return np.array([d1 * v1, d1 * w1, d2 * v2, d2 * w2])


class CoupledFoldHopf(FoldHopf):
    """FoldHopf with the oscillator feeding back: x' = a + b - x^2 + b x + c (v^2 + w^2).  The
    fold and Hopf curves and their ZH are FoldHopf's (the coupling is quadratic in (v, w), which
    vanish on both curves), but l1 now has a pole at the ZH (B(q, qb) has a component along the
    zero eigenvector).  On the Hopf curve (x = 1 - b, rho = v^2 + w^2) the slaved
    xi = x - (1 - b) obeys xi' = lam xi - xi^2 + c rho, lam = 3 b - 2, so xi = -c rho / lam +
    c^2 rho^2 / lam^3 + ..., and z = v + i w obeys z' = i z + (xi - rho) z: l1 = 2 (-1 - c / lam)
    (|q| = 1: z = sqrt(2) w) vanishes at lam = -c, a GH at b = (2 - c)/3, where
    z' = i z - rho^2 z / c + ..., so l2 = -4 / c."""

    def __init__(self, c: float = 0.5) -> None:
        self.c = c

    def residual(self, u, p):
        r = super().residual(u, p)
        r[0] += self.c * (u[1] ** 2 + u[2] ** 2)
        return r

    def jacobian(self, u, p):
        j = super().jacobian(u, p).toarray()
        j[0, 1] += 2 * self.c * u[1]
        j[0, 2] += 2 * self.c * u[2]
        return sp.csr_matrix(j)


STEP = StepOptions(ds=0.02, ds_max=0.05)


def _fold_hopf_run(request: SceneRequest) -> SceneResult:
    opts = request.options_for(ContinuationOptions(step=STEP, bounds={"a": (-0.5, 2.0)}, max_steps=400))
    branch = trace_both(FoldHopf(), np.array([0.5, 0.0, 0.0]), {"a": 0.25, "b": 0.0}, "a", opts, branch_id="x")
    relabel([branch])
    request.finished(branch)
    return SceneResult(branches=[branch], parameters={"a": 0.25, "b": 0.0}, discretization={})


def _two_oscillators_run(request: SceneRequest) -> SceneResult:
    opts = request.options_for(ContinuationOptions(step=STEP, bounds={"a": (0.5, 2.0)}, max_steps=200))
    branch = trace(TwoOscillators(), np.zeros(4), {"a": 0.5, "b": 0.0}, "a", opts, branch_id="zero")
    relabel([branch])
    request.finished(branch)
    return SceneResult(branches=[branch], parameters={"a": 0.5, "b": 0.0}, discretization={})


SCENES = {
    "fold-hopf": Scene(name="fold-hopf", summary="test fixture (ZH)", defaults={}, run=_fold_hopf_run, x="a", y="x",
                       problem_factory=lambda parameters, discretization: FoldHopf()),
    "two-oscillators": Scene(name="two-oscillators", summary="test fixture (HH)", defaults={}, run=_two_oscillators_run,
                             x="a", y="v1", problem_factory=lambda parameters, discretization: TwoOscillators()),
}
