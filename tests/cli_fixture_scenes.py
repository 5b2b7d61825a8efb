"""Hand-built scenes for the IO/CLI/plot tests, loaded through ``CONTIN_SCENES``.

'toy': two branches of the pitchfork normal form v (lam - v^2) = 0 built by hand: the trivial
branch v = 0 (stable for lam < 0, unstable after the BP at lam = 0) and the bifurcated branch
lam = v^2 (stable, with an unconverged LP-labelled marker for the plot test).  Parameters
a (> 0 or SceneError), chi (a word), Fr (may be inf), delay (sleep after each branch),
fail ("none", "crash" after the first branch, "mx", "nanphi").
"""

from __future__ import annotations

import math
import time

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult

DEFAULTS = {"a": 1.0, "chi": "jj", "Fr": math.inf, "delay": 0.0, "fail": "none", "n": 3}
Y = np.linspace(-0.5, 0.5, 5)


def make_branch(bid: str, lam: np.ndarray, v: np.ndarray, stable: np.ndarray | None,
                sps: list[SpecialPoint], a: float = 1.0, **kw) -> Branch:
    s = lam.size
    states = np.column_stack([v, v**2, np.cos(lam)])
    return Branch(
        parameter="lam", free=("lam",),
        params={"lam": lam.astype(float), "a": np.full(s, a), "Fr": np.full(s, math.inf)},
        observables={"phi": v.astype(float), "energy": v**2 + lam},
        states=states, tangents=np.column_stack([states, np.ones(s)]) / 2.0,
        ds=np.r_[0.0, np.diff(lam)], newton_iterations=np.arange(s, dtype=np.int64) % 4,
        special_points=sps, status="EP", message="bound reached",
        stable=stable, n_unstable=None if stable is None else (~stable).astype(np.int64),
        id=bid, **kw)


def toy_branches(a: float = 1.0, n: int = 3) -> list[Branch]:
    lam = np.linspace(-1.0, 1.0, 9)
    v0 = np.zeros_like(lam)
    bp = SpecialPoint("BP", 4, {"lam": 0.0, "a": a, "Fr": math.inf}, 0.0, np.array([0.0, 0.0, 1.0]),
                      tangent=np.array([1.0, 0.0, 0.0, 0.0]), bracket=(-0.25, 0.25), converged=True, label=1)
    trivial = make_branch("0", lam, v0, lam <= 0.0, [bp], a, kind="primary")
    v = np.linspace(0.0, 1.0, 6)
    lp = SpecialPoint("LP", 2, {"lam": 0.16, "a": a, "Fr": math.inf}, 0.4, np.array([0.4, 0.16, math.cos(0.16)]),
                      bracket=(0.1, 0.2), converged=False, label=2, note="not converged")
    bif = make_branch("1", v**2, v, np.ones(6, dtype=bool), [lp], a, kind="bifurcated", parent="BP1@0")
    out = [trivial, bif]
    for k in range(2, n):
        extra = make_branch(str(k), v**2 + k, v, None, [], a, kind="extra", parent="0")
        out.append(extra)
    return out


def profiles(u: np.ndarray) -> dict[str, np.ndarray]:
    return {"nu": u[0] + 0 * Y, "T": u[1] * (1 + Y**2)}


def run(req: SceneRequest) -> SceneResult:
    p = {**DEFAULTS, **dict(req.params)}
    a = float(p["a"])
    if not a > 0:
        raise SceneError(f"a must be > 0, got {a:g}")
    opts = req.options_for(ContinuationOptions(step=StepOptions(ds=0.02), max_steps=100))
    reused = []
    branches = []
    for k, b in enumerate(toy_branches(a, int(p["n"]))):
        if b.id in req.completed:
            b = req.completed[b.id]
            reused.append(b.id)
        else:
            req.report(f"branch {b.id}: tracing")
            time.sleep(float(p["delay"]))
            if p["fail"] == "crash" and k == 1:
                raise RuntimeError("deliberate crash in the toy scene")
            if p["fail"] == "mx" and k == 1:
                b.status, b.message = "MX", "step size underflow at lam=0.16"
            if p["fail"] == "nanphi" and k == 0:
                b.observables["energy"][3] = math.nan
                b.special_points[0] = SpecialPoint(**{**b.special_points[0].__dict__, "order_parameter": math.nan})
        branches.append(b)
        req.finished(b)
    return SceneResult(branches=branches, parameters=p, discretization={"method": "none", "intervals": 4},
                       y=Y, profiles=profiles, notes=["toy scene"],
                       extra={"reused": reused, "ds": opts.step.ds, "max_steps": opts.max_steps,
                              "nan": math.nan, "inf": math.inf})


SCENES = {"toy": Scene(name="toy", summary="hand-built pitchfork branches", defaults=DEFAULTS, run=run,
                       x="lam", y="phi")}


# 'slow-bratu': two Bratu branches traced by contin.continuation.trace (lam 0.1 -> 0.3, then
# lam 0.1 -> 3 with ``delay`` seconds of sleep in each residual of the second), for the Ctrl-C /
# SIGTERM tests of a branch in progress; ``steps`` is the second branch's max_steps.
SLOW_DEFAULTS = {"delay": 0.0, "steps": 40}


def run_slow(req: SceneRequest) -> SceneResult:
    from contin.continuation import trace
    from problems.demo import Bratu

    p = {**SLOW_DEFAULTS, **dict(req.params)}

    class SlowBratu(Bratu):
        def residual(self, u, q):
            time.sleep(float(p["delay"]))
            return super().residual(u, q)

    branches = []
    for bid, pb, top, steps in (("0", Bratu("cheb", 8), 0.3, 100), ("1", SlowBratu("cheb", 8), 3.0, int(p["steps"]))):
        if bid in req.completed:
            b = req.completed[bid]
        else:
            opts = req.options_for(ContinuationOptions(bounds={"lam": (0.1, top)}, max_steps=steps,
                                                       step=StepOptions(ds=0.02, ds_max=0.02)))
            b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", opts)
            b.id, b.kind = bid, "primary"
        branches.append(b)
        req.finished(b)
    return SceneResult(branches=branches, parameters=p, discretization={"method": "cheb", "intervals": 8},
                       extra={"reused": sorted(req.completed)})


def _slow_stability_factory(parameters, discretization):
    """'slow-bratu-stab': the CLI's stability pass after the run, ``sdelay`` seconds per Jacobian."""
    from problems.demo import Bratu

    class SlowJacobian(Bratu):
        def jacobian(self, u, q):
            time.sleep(float(parameters.get("sdelay", 0.0)))
            return super().jacobian(u, q)

    return SlowJacobian("cheb", 8)


SCENES["slow-bratu-stab"] = Scene(name="slow-bratu-stab", summary="slow-bratu with a slow stability pass after it",
                                  defaults={**SLOW_DEFAULTS, "sdelay": 0.0}, run=run_slow, x="lam", y="phi",
                                  problem_factory=_slow_stability_factory)
SCENES["slow-bratu"] = Scene(name="slow-bratu", summary="two Bratu branches, the second slow", defaults=SLOW_DEFAULTS,
                             run=run_slow, x="lam", y="phi", stability=False)
