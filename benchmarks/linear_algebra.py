"""Linear algebra by structure, per grid: ``python -m benchmarks.linear_algebra [--quick] [--no-trace] [--json FILE]``.

Prints, for gPCF (numpy engine, nubar = 0.3, e = 0.8, the banded n = 1 state's neighbourhood on
the uniform branch at H = 10) from Chebyshev N = 12 to fd4 N = 25600:

1. per grid: the structure contin chooses (``contin.linalg.structure``: dense / banded /
   sparse), and the seconds per bordered Newton iteration of the corrector
   (``contin.corrector.correct``: a whole correction of k iterations / k) against the sum of
   its parts measured in the same run -- residual, Jacobian (+ dF/dH), factorization of the
   bordered matrix, solve, each timed by itself in a loop.  The ratio is the corrector's
   overhead (target <= 1.5).  ``replay`` times the same correction's calls (k + 1 residuals at
   its iterates, k Jacobians, factorizations and solves) in their order but without the
   corrector's logic, per iteration; its ratio is what the corrector adds to the work it does.
   The two differ by the residual at the predictor ((k+1)/k residuals per iteration) and by
   what a part gains from running alone in a loop (warm caches and branch predictors: at
   cheb 12 the parts in sequence cost ~1.3x the parts in loops); ``dense LU`` is
   what a dense factorization of the same bordered matrix costs (where it fits), i.e. what the
   old size rule did below 800 unknowns;
2. the cost of a branch against N for FD: the uniform-shear branch H = 5 -> 12 at fixed steps,
   seconds per point and seconds per point per unknown (flat = linear in N);
3. peak memory (max RSS of a child process) of ``contin trace pitchfork --method fd4 --grid
   25600 --no-stability`` (target < 1 GB).

Times are CPU seconds (time.process_time; the fairer figure on a shared machine), best of
``repeats`` rounds (20; --quick 8) of timings of >= 20 ms of calls each, one BLAS thread
(contin.blas).  Why 20 rounds and not 5: with 4-5 busy processes on the 2 cores, a 20 ms batch
is often slowed by another process's cache and branch-predictor traffic, and min-of-5 left the
cheb 12-24 ratios scattering by +-0.2 from run to run (1.3-2.1 seen), each side catching a
clean batch or not by chance; with 20 rounds both sides reach their floor and repeated runs
agree to a few per cent.  The rounds stay interleaved, so the definition of the ratio is
unchanged.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from contin.blas import limit_blas_threads

GRIDS_FULL = [("cheb", 12), ("cheb", 24), ("cheb", 48), ("cheb", 96), ("cheb", 200), ("cheb", 300),
              ("fd4", 64), ("fd4", 256), ("fd4", 1024), ("fd4", 4096), ("fd4", 25600)]
GRIDS_QUICK = [("cheb", 12), ("cheb", 48), ("fd4", 256), ("fd4", 4096)]
BRANCH_GRIDS = (400, 1600, 6400, 25600)


def _calls(fn: Callable[[], Any], min_time: float) -> int:
    """Calls of ``fn`` that last about ``min_time`` CPU seconds (at least 1, at most 1000)."""
    t = time.process_time()
    fn()
    once = time.process_time() - t
    return max(1, min(1000, int(min_time / max(once, 1e-6))))


def cpu_best(fn: Callable[[], Any], repeats: int, budget: float = 3.0, min_time: float = 0.02) -> float:
    """CPU seconds per call of ``fn``: best of ``repeats`` timings of ~``min_time`` of calls each."""
    return interleaved_best({"fn": (fn, None)}, repeats, budget, min_time)["fn"]


def interleaved_best(fns: dict[str, tuple[Callable[[], Any], Callable[[], Any] | None]], repeats: int,
                     budget: float = 10.0, min_time: float = 0.02) -> dict[str, float]:
    """CPU seconds per call of each ``fn`` (name -> (fn, untimed set-up before each timing)).

    Each timing is a batch of calls lasting ~``min_time`` (one sub-millisecond call is at the
    mercy of the other processes on the shared machine: best-of-3 single calls scattered the
    cheb 12 ratio over 1.2-1.7), and the quantities are timed in turn, round after round, the
    best of ``repeats`` rounds kept: the iteration and its parts see the same load.
    """
    calls = {}
    for name, (fn, prepare) in fns.items():
        if prepare is not None:
            prepare()
        calls[name] = _calls(fn, min_time)
    best = dict.fromkeys(fns, math.inf)
    start = time.perf_counter()
    for _ in range(repeats):
        for name, (fn, prepare) in fns.items():
            if prepare is not None:
                prepare()
            t = time.process_time()
            for _ in range(calls[name]):
                fn()
            best[name] = min(best[name], (time.process_time() - t) / calls[name])
        if time.perf_counter() - start > budget:
            break
    return best


def newton_row(method: str, n_grid: int, repeats: int) -> dict[str, Any]:
    """Seconds per corrector iteration against residual + Jacobian + factorization + solve."""
    from contin.corrector import correct
    from contin.extended import ExtendedSystem
    from contin.linalg import bordered_dense, factorize_bordered, structure
    from contin.linalg import bordered as bordered_sparse
    from contin.options import NewtonOptions
    from problems.couette.model import CouetteProblem

    pb = CouetteProblem(method, n_grid)
    p = pb.params({"nu": 0.3, "e": 0.8, "H": 10.0})
    u = pb.uniform_state(p)
    system = ExtendedSystem(pb, p, "H")
    x = system.pack(u, 10.0)
    t = np.zeros(x.size)
    t[-1] = 1.0
    row = system.row(t)
    # a predictor off the solution by a smooth perturbation: a few real Newton iterations
    y = pb.grid.y
    bump = np.concatenate([0.01 * np.cos(np.pi * y), 0.01 * np.sin(np.pi * y), 0.01 * np.cos(np.pi * y), [0.0]])
    x_pred = x + np.concatenate([bump, np.zeros(x.size - 1 - bump.size), [0.05]])
    opts = NewtonOptions()
    corr = correct(system, x_pred, row, opts)
    iterations = max(corr.iterations, 1)
    # As in a Newton iteration: the residual at a new iterate (problems may cache what the
    # Jacobian at the same iterate reuses, so the residual is timed on alternating states and
    # the Jacobian right after a residual at its own state), J into the previous J (scratch),
    # the bordered matrix assembled and factorized in the previous one's buffer
    states = [x, x_pred]

    def residual_new() -> None:
        states.reverse()
        system.residual(states[0])

    jac, fp = system.jacobian(x)
    fact = factorize_bordered(jac, fp, row)
    buffer = getattr(factorize_bordered(jac, fp, row), "lu", None)
    rhs = np.ones(x.size)
    iterates = correction_iterates(system, x_pred, row, opts)

    def replay() -> None:
        """The correction's calls in its order on its iterates, without the corrector's logic."""
        buf = None
        system.residual(iterates[0])
        for xi, x_next in zip(iterates[:-1], iterates[1:]):
            jac_i, fp_i = system.jacobian(xi, scratch=True)
            fact_i = factorize_bordered(jac_i, fp_i, row, buf)
            buf = getattr(fact_i, "lu", None)
            fact_i.solve(rhs)
            system.residual(x_next)

    best = interleaved_best({
        "iteration": (lambda: correct(system, x_pred, row, opts), None),
        "replay": (replay, None),
        "residual": (residual_new, None),
        "jacobian": (lambda: system.jacobian(x, scratch=True), lambda: system.residual(x)),
        "factorization": (lambda: factorize_bordered(jac, fp, row, buffer), None),
        "solve": (lambda: fact.solve(rhs), None),
    }, repeats)
    t_iter = best["iteration"] / iterations
    t_replay = best["replay"] / iterations
    t_res, t_jac, t_fact, t_solve = best["residual"], best["jacobian"], best["factorization"], best["solve"]
    kind = structure(jac if not hasattr(jac, "tocsc") else bordered_sparse(jac, fp, row))
    dense_lu = math.nan
    if x.size <= 3000:
        from contin.linalg import factorize

        # contin's own dense path (a Fortran-ordered copy, then LAPACK getrf in place), as the
        # factorization column's: scipy.linalg.lu_factor adds its wrapper (check_finite, asarray)
        dense = bordered_dense(jac.toarray() if hasattr(jac, "toarray") else jac, fp, row)
        dense_lu = cpu_best(lambda: factorize(dense), repeats)
    parts = t_res + t_jac + t_fact + t_solve
    return {"grid": f"{method} {n_grid}", "unknowns": x.size, "structure": kind, "converged": corr.converged,
            "iterations": corr.iterations, "iteration": t_iter, "residual": t_res, "jacobian": t_jac,
            "factorization": t_fact, "solve": t_solve, "parts": parts, "ratio": t_iter / parts,
            "replay": t_replay, "ratio_replay": t_iter / t_replay, "dense_lu": dense_lu}


def correction_iterates(system: Any, x_pred: Any, row: Any, opts: Any) -> list[Any]:
    """The states one correction from ``x_pred`` evaluates its residual at (x_0 = x_pred, ...)."""
    from contin.corrector import correct

    seen: list[Any] = []
    residual = system.residual

    def recording(x: Any) -> Any:
        seen.append(np.array(x))
        return residual(x)

    system.residual = recording
    try:
        correct(system, x_pred, row, opts)
    finally:
        del system.residual
    return seen


def branch_row(n_grid: int) -> dict[str, Any]:
    """Uniform shear H = 5 -> 12 on fd4 N at fixed steps (ds = 0.5): CPU seconds per point."""
    from contin.continuation import trace
    from contin.options import ContinuationOptions, StepOptions
    from problems.couette.model import CouetteProblem

    pb = CouetteProblem("fd4", n_grid)
    p = pb.params({"nu": 0.3, "e": 0.8, "H": 5.0})
    opts = ContinuationOptions(step=StepOptions(ds=0.5, ds_max=0.5, ds_min=0.5), bounds={"H": (4.0, 12.0)},
                               resolution_tol=None)
    t = time.process_time()
    br = trace(pb, pb.uniform_state(p), p, "H", opts)
    cpu = time.process_time() - t
    points = len(br.ds)
    return {"N": n_grid, "unknowns": pb.size + 1, "points": points, "status": br.status,
            "per_point": cpu / points, "per_point_per_unknown": cpu / points / (pb.size + 1)}


def memory_row(n_grid: int = 25600) -> dict[str, Any]:
    """Peak RSS of the fd4 pitchfork trace in a child process."""
    import os
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "contin", "trace", "pitchfork", "-s", "nu=0.3", "-s", "e=0.8", "--method", "fd4",
               "--grid", str(n_grid), "--no-stability", "--engine", "numpy", "-q", "-o", os.path.join(tmp, "fd4.h5")]
        t = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t
    rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # KiB -> MiB (Linux)
    return {"command": " ".join(cmd[2:]), "exit": proc.returncode, "wall": wall, "max_rss_mib": rss}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.linear_algebra", description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer grids, no 25600 runs")
    ap.add_argument("--no-trace", action="store_true", help="skip the branch-cost and memory runs")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    args = ap.parse_args(argv)
    limit_blas_threads(1)
    repeats = 8 if args.quick else 20
    out: dict[str, Any] = {"newton": [], "branch": [], "memory": None}
    print(f"{'grid':>11} {'unknowns':>8} {'structure':>9} {'it':>3} {'iteration':>10} {'residual':>9} {'jacobian':>9} "
          f"{'factor':>9} {'solve':>9} {'sum':>9} {'ratio':>6} {'replay':>9} {'ratio':>6} {'dense LU':>9}   (CPU ms)")
    for method, n in GRIDS_QUICK if args.quick else GRIDS_FULL:
        r = newton_row(method, n, repeats)
        out["newton"].append(r)
        ms = {k: 1e3 * r[k] for k in ("iteration", "residual", "jacobian", "factorization", "solve", "parts", "replay",
                                      "dense_lu")}
        print(f"{r['grid']:>11} {r['unknowns']:>8} {r['structure']:>9} {r['iterations']:>3} {ms['iteration']:>10.3f} "
              f"{ms['residual']:>9.3f} {ms['jacobian']:>9.3f} {ms['factorization']:>9.3f} {ms['solve']:>9.3f} "
              f"{ms['parts']:>9.3f} {r['ratio']:>6.2f} {ms['replay']:>9.3f} {r['ratio_replay']:>6.2f} {ms['dense_lu']:>9.3f}",
              flush=True)
    worst = max(r["ratio"] for r in out["newton"])
    worst_replay = max(r["ratio_replay"] for r in out["newton"])
    print(f"largest ratio, iteration / sum of parts timed one by one: {worst:.2f} (target <= 1.5); "
          f"iteration / replay of the correction's calls: {worst_replay:.2f}")
    if not args.no_trace:
        print(f"\n{'fd4 N':>7} {'unknowns':>8} {'points':>6} {'s/point':>9} {'us/point/unknown':>17}")
        for n in BRANCH_GRIDS[:2] if args.quick else BRANCH_GRIDS:
            b = branch_row(n)
            out["branch"].append(b)
            print(f"{b['N']:>7} {b['unknowns']:>8} {b['points']:>6} {b['per_point']:>9.4f} {1e6 * b['per_point_per_unknown']:>17.3f}",
                  flush=True)
        if not args.quick:
            m = memory_row()
            out["memory"] = m
            print(f"\n{m['command']}: exit {m['exit']}, {m['wall']:.1f} s wall, peak RSS {m['max_rss_mib']:.0f} MiB "
                  "(target < 1024 MiB)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
