"""A scene with the resolution-guard toy of tests/test_core_resolution.py, for the CLI tests of
``--resolution-tol`` (loaded through ``CONTIN_SCENES=resolution_fixture_scenes:SCENES``).

F(u, lam) = u - lam (1, 2) on lam in [0, 6] with the declared "discretization error"
10^(lam - 8): the guard (tol) stops a branch at lam = 8 + log10(tol), 3.477 at the default 3e-5.
Branch 'own' is traced with options the scene builds itself (not through options_for), as
gPCF scenes do for fold curves and homotopies: --resolution-tol must reach it too.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from contin.continuation import trace
from contin.options import ContinuationOptions, StepOptions
from contin.scene import Scene, SceneRequest, SceneResult

DIRECTION = np.array([1.0, 2.0])


class Toy:
    """F(u, lam) = u - lam DIRECTION with the declared error 10^(lam - 8), or, with ``jump_at``,
    0 below and 1 from there on; ``calls`` records every (lam, tol) the guard asked about."""

    parameter_names = ("lam",)

    def __init__(self, jump_at: float | None = None) -> None:
        self.calls: list[tuple[float, float]] = []
        self.jump_at = jump_at

    def residual(self, u, p):
        return u - p["lam"] * DIRECTION

    def jacobian(self, u, p):
        return sp.identity(2, format="csc")

    def dresidual_dp(self, u, p, name):
        return -DIRECTION

    def error(self, lam: float) -> float:
        if self.jump_at is not None:
            return 1.0 if lam >= self.jump_at else 0.0
        return 10.0 ** (lam - 8.0)

    def under_resolved(self, u, p, tol):
        self.calls.append((float(p["lam"]), tol))
        err = self.error(p["lam"])
        return None if err <= tol else f"toy tail {err:.3g} > {tol:.3g}"


def run(req: SceneRequest) -> SceneResult:
    base = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.25), bounds={"lam": (0.0, 6.0)})
    opts = req.options_for(base)
    branches = []
    for bid, o in (("0", opts), ("own", base)):
        b = trace(Toy(), np.zeros(2), {"lam": 0.0}, "lam", o, branch_id=bid)
        branches.append(b)
        req.finished(b)
    return SceneResult(branches=branches, parameters={}, discretization={"method": "none", "intervals": 2},
                       extra={"options_resolution_tol": opts.resolution_tol})


SCENES = {"guarded": Scene(name="guarded", summary="resolution-guard toy", defaults={}, run=run, x="lam", y="phi")}
