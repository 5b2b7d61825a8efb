"""A tiny scene for the sweep tests, importable by worker processes (``CONTIN_SCENES``).

Scene 'normalform': the fold normal form u^2 = lam - a traced in lam, with an LP exactly at
lam = a, phi = 0, and the pitchfork normal form v (lam - b - v^2) = 0 with a BP exactly at
lam = b.  'delay' sleeps (seconds) so that a sweep can be killed mid-run; 'fail' = 'crash'
raises a RuntimeError, 'mx' ends the branch with MX; a outside [-5, 5] is a SceneError.
"""

from __future__ import annotations

import time

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.options import ContinuationOptions, effective_resolution_tol
from contin.scene import Scene, SceneError, SceneRequest, SceneResult

DEFAULTS = {"a": 0.0, "b": 1.0, "delay": 0.0, "fail": "none"}


def _branch(bid: str, lam: np.ndarray, u: np.ndarray, params: dict, sps: list[SpecialPoint]) -> Branch:
    n = lam.size
    cols = {k: np.full(n, float(v)) for k, v in params.items() if isinstance(v, float)}
    cols["lam"] = lam
    return Branch(parameter="lam", free=("lam",), params=cols, observables={"phi": u},
                  states=u[:, None].copy(), tangents=np.zeros((n, 2)), ds=np.zeros(n),
                  newton_iterations=np.zeros(n, dtype=np.int64), special_points=sps, status="EP",
                  message="bound", id=bid)


def run(req: SceneRequest) -> SceneResult:
    p = {**DEFAULTS, **dict(req.params)}
    unknown = set(p) - set(DEFAULTS)
    if unknown:
        raise SceneError(f"unknown parameter {sorted(unknown)[0]!r}")
    a, b = float(p["a"]), float(p["b"])
    if not -5.0 <= a <= 5.0:
        raise SceneError(f"a must lie in [-5, 5], got {a:g}")
    if p["fail"] == "crash":
        raise RuntimeError("deliberate crash")
    time.sleep(float(p["delay"]))
    fixed = {k: float(v) for k, v in p.items() if k in ("a", "b", "delay")}
    u = np.linspace(-1.0, 1.0, 21)  # contains u = 0 exactly (index 10)
    lp = SpecialPoint("LP", 10, {**fixed, "lam": a}, 0.0, np.zeros(1), label=1)
    fold = _branch("0", a + u**2, u, fixed, [lp])
    bp = SpecialPoint("BP", 10, {**fixed, "lam": b}, 0.0, np.zeros(1), label=2)
    pitch = _branch("1", b + u**2, u, fixed, [bp])
    if p["fail"] == "mx":
        pitch.status, pitch.message = "MX", "step size underflow"
    return SceneResult(branches=[fold, pitch], parameters=dict(p),
                       extra={"fold_lam": a, "a_plus_b": a + b, "label": f"a={a:g}",
                              # what a trace in this run would use (the sweep's resolution_tol option)
                              "resolution_tol": effective_resolution_tol(ContinuationOptions())})


SCENES = {"normalform": Scene("normalform", "fold and pitchfork normal forms (sweep tests)", DEFAULTS, run,
                              x="lam")}
