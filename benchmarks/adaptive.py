"""Adaptive resolution against the cheapest fixed grid: ``python -m benchmarks.adaptive [--quick]``.

For each tol, the adaptive run (``ContinuationOptions.adapt``) and every fixed grid of a list
are timed on the same job, their errors measured against closed forms, and the cheapest fixed
grid whose errors are all <= tol is named; the table prints the adaptive cost over that
grid's cost (issue 14's target: within 1.5x).  Jobs:

- ``bratu``: u'' + lam e^u = 0 (problems.demo.Bratu, Chebyshev) from lam = 0.1 through the fold
  to lam = 0.02 on the upper branch, where u(1/2) = 9.35 and the profile is steep.  Errors: the
  fold lam* (problems.demo.BRATU_FOLD) and u(1/2) at the end against 2 ln cosh(theta/4),
  lam = theta^2 / (2 cosh^2(theta/4)).  A fixed grid must resolve the steepest point of the
  branch everywhere; the adaptive run refines only where the branch steepens.
- ``hc1``: gPCF uniform shear at nu = 0.3, e = 0.8 from 0.8 to 1.2 H_1^c (problems.couette); error
  of the located H_1^c against n pi psi.  The adaptive run starts on the default cheb 64 (a user
  who asks for an accuracy, not a grid) and finds its grid itself.

The adaptive runs ask for tol for the special points too (``special_tol`` = tol, as ``contin
accuracy --tols`` does): the errors measured are those of a fold and a BP, and the tracer's
default ``special_tol`` = 1e-10 would locate them far beyond tol -- a different request from the
fixed grid they are compared with.

Costs are CPU seconds (time.process_time, best of ``--repeats`` interleaved rounds: the fair
figure on a shared machine), BLAS on one thread.  These are measurements, not tests (tests/test_adapt.py checks
the accuracy side).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np


def _cpu(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    best, out = math.inf, None
    for _ in range(repeats):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


def bratu_job(tol: float | None, grid: int) -> Callable[[], list[float]]:
    """The Bratu run (adaptive for tol, else fixed on cheb ``grid``); returns its errors."""
    from scipy.optimize import brentq

    from contin.continuation import trace
    from contin.options import AdaptOptions, ContinuationOptions, StepOptions
    from problems.demo import BRATU_FOLD, Bratu

    def run() -> list[float]:
        pb = Bratu("cheb", grid)
        o = ContinuationOptions(bounds={"lam": (0.02, 4.0)}, max_steps=400, step=StepOptions(ds=0.1, ds_max=0.5),
                                adapt=None if tol is None else AdaptOptions(tol=tol, min_grid=8, special_tol=tol))
        b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)
        if b.status != "EP" or len(b.fold_points) != 1:
            return [math.inf]
        lam = float(b.params["lam"][-1])
        th = brentq(lambda t: t**2 / (2 * math.cosh(t / 4) ** 2) - lam, 4.7987, 300.0, xtol=1e-15)
        exact = 2 * math.log(math.cosh(th / 4))
        mid = pb.with_grid(b.grid_at(-1) or grid).order_parameter(b.state(-1), None)
        return [abs(b.fold_points[0].params["lam"] - BRATU_FOLD) / BRATU_FOLD, abs(mid - exact) / exact]

    return run


def hc1_job(tol: float | None, grid: int) -> Callable[[], list[float]]:
    from contin.options import AdaptOptions, ContinuationOptions, DetectionOptions, StepOptions
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    exact = pf.analytic_critical_gaps(0.3, 0.8, 1)[0]

    def run() -> list[float]:
        pb = CouetteProblem("cheb", grid)
        p = pb.params({"nu": 0.3, "e": 0.8})
        o = ContinuationOptions(bounds={"H": (0.8 * exact, 1.2 * exact)}, step=StepOptions(ds=0.1 * exact, ds_max=0.3 * exact),
                                detection=DetectionOptions(locate_tol=1e-13),
                                adapt=None if tol is None else AdaptOptions(tol=tol, min_grid=4, special_tol=tol))
        b = pf.trace_base(pb, p, 0.8 * exact, o)
        if len(b.branch_points) != 1:
            return [math.inf]
        return [abs(b.branch_points[0].params["H"] - exact) / exact]

    return run


JOBS = {
    "bratu": (bratu_job, list(range(8, 129, 4)), 32),
    "hc1": (hc1_job, [6, 8, 10, 12, 14, 16, 20, 24, 32], 64),
}


def rows(job: str, tols: list[float], repeats: int) -> list[dict[str, Any]]:
    """One row per tol.  Every fixed grid and every adaptive run is timed once per round, the
    rounds interleaved (``repeats`` of them), and each keeps its best time: a change of the
    machine's load during the run then shifts both sides alike (timing all fixed grids first
    and the adaptive runs after them did not)."""
    make, grids, start = JOBS[job]
    runs = [("fixed", n, make(None, n)) for n in grids] + [("adaptive", tol, make(tol, start)) for tol in tols]
    best = {(kind, key): (math.inf, None) for kind, key, _ in runs}
    for _ in range(repeats):
        for kind, key, fn in runs:
            cost, errs = _cpu(fn, 1)
            if cost < best[(kind, key)][0]:
                best[(kind, key)] = (cost, errs)
    fixed = [(n, best[("fixed", n)][0], max(best[("fixed", n)][1])) for n in grids]
    out = []
    for tol in tols:
        cost, errs = best[("adaptive", tol)]
        ok = [(n, c) for n, c, e in fixed if e <= tol]
        n_best, c_best = min(ok, key=lambda r: r[1]) if ok else (None, math.nan)
        out.append({"job": job, "tol": tol, "achieved": max(errs), "adaptive_s": cost, "fixed_grid": n_best,
                    "fixed_s": c_best, "ratio": cost / c_best if ok else math.nan})
    return out


def main(argv: list[str] | None = None) -> None:
    from contin.blas import limit_blas_threads

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one repeat, tol 1e-6 and 1e-10 only")
    ap.add_argument("--jobs", default="bratu,hc1")
    ap.add_argument("--repeats", type=int, default=5, help="interleaved rounds; each run keeps its best (default 5)")
    args = ap.parse_args(argv)
    limit_blas_threads(1)
    tols = [1e-6, 1e-10] if args.quick else [1e-4, 1e-6, 1e-8, 1e-10]
    repeats = 1 if args.quick else args.repeats
    print(f"{'job':6} {'tol':>7} {'achieved':>9} {'adaptive cpu s':>15} {'cheapest fixed':>15} {'fixed cpu s':>12} {'ratio':>6}")
    for job in args.jobs.split(","):
        for r in rows(job, tols, repeats):
            grid = "none" if r["fixed_grid"] is None else f"cheb {r['fixed_grid']}"
            print(f"{r['job']:6} {r['tol']:7.0e} {r['achieved']:9.1e} {r['adaptive_s']:15.3f} {grid:>15} "
                  f"{r['fixed_s']:12.3f} {r['ratio']:6.2f}")


if __name__ == "__main__":
    main()
