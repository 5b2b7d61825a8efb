"""Benchmark runner: ``python -m benchmarks.run [--quick] [--no-contin] [--engines LIST] [--json FILE]``.

Prints tables of figures (these are measurements, not tests; tests/test_baseline.py checks
the numbers):

1. Baseline (scipy.integrate.solve_bvp, benchmarks/baseline_solve_bvp.py), nubar = 0.3,
   e = 0.8, no-slip / zero-flux walls, g = 0, at every tol 1e-4 ... 1e-8 and every initial mesh
   (``Config.nodes`` equispaced nodes: solve_bvp only ever adds nodes, so the initial mesh is a
   user's choice that sets the cost; the comparison takes the cheapest that meets each target):
   - H_1^c by delta-pinning (3 amplitudes, Richardson in delta^2): relative error against
     n pi psi, seconds per converged point, mesh nodes;
   - natural-parameter continuation in H along the banded n = 1 branch from 1.02 H_1^c:
     seconds per converged point, failed solves, mesh nodes;
   - nubar = 0.16 (subcritical): does natural continuation in H (downwards from the upper
     branch) get through the fold?  The fold is located independently by a pinning scan.
2. contin (hooks; skipped with a note if the modules are missing), for each engine of
   ``--engines`` (default: numpy, and numba where installed; problems.couette.compiled):
   - :func:`contin_newton_rows`: seconds per Newton iteration against N for cheb/fd2/fd4/fd6;
   - :func:`contin_trace_rows`: seconds per continuation step (uniform branch through the
     BP, then the switched banded branch) and the H_1^c error of the located BP against N;
   - :func:`pitchfork_scene_rows`: the whole ``pitchfork`` scene;
   - :func:`comparison_rows`: seconds per converged point at equal accuracy in H_1^c,
     baseline against contin (each engine), side by side.

Times are wall-clock (time.perf_counter), best of ``repeats``, with the CPU time
(time.process_time) of that call alongside ("cpu" columns: the fairer figure on a shared
machine).  BLAS is limited to one thread as in the CLI (contin.blas; CONTIN_BLAS_THREADS).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from benchmarks.baseline_solve_bvp import (
    GPCF,
    banded_start,
    critical_gap_by_pinning,
    fixed_h_point,
    fold_by_pinning,
    natural_continuation,
    start_near_critical,
)

NUBAR, E = 0.3, 0.8
H_END = 20.0  # end of the banded branch for the seconds-per-point figures (phi(1/2) ~ 0.567)


@dataclass(frozen=True)
class Config:
    """What one run measures; ``--quick`` shrinks every list."""

    tols: tuple[float, ...]
    repeats: int
    max_nodes: int  # solve_bvp max_nodes in the fold run (each failed solve grows the mesh to it)
    methods: dict[str, tuple[int, ...]]
    h_end: float
    contin: bool
    nodes: tuple[int, ...] = (101,)  # initial solve_bvp meshes (equispaced nodes) of the baseline rows
    engines: tuple[str, ...] = ("numpy",)  # CouetteProblem engines of the contin rows

    @classmethod
    def make(cls, quick: bool, contin: bool, engines: tuple[str, ...] | None = None) -> Config:
        if engines is None:
            engines = available_engines()
        if quick:
            return cls((1e-4, 1e-6, 1e-8), 1, 2000, {"cheb": (10, 12, 16, 24, 48), "fd2": (64,), "fd4": (64,), "fd6": (64,)},
                       16.0, contin, (21, 101), engines)
        return cls((1e-4, 1e-5, 1e-6, 1e-7, 1e-8), 3, 5000,
                   {"cheb": (8, 10, 12, 16, 24, 32, 48, 64, 96), "fd2": (32, 64, 128, 256), "fd4": (32, 64, 128, 256),
                    "fd6": (32, 64, 128, 256)},
                   H_END, contin, (11, 21, 51, 101), engines)


def available_engines() -> tuple[str, ...]:
    """numpy, and numba where it is installed (problems.couette.compiled)."""
    try:
        from problems.couette.compiled import available
    except ImportError:
        return ("numpy",)
    return ("numpy", "numba") if available() else ("numpy",)


Row = dict[str, Any]


#: CPU seconds (time.process_time) of the fastest call of the last :func:`best_of`.
LAST_CPU = [math.nan]


def best_of(repeats: int, fn: Callable[[], Any], budget: float = 5.0) -> tuple[float, Any]:
    """(smallest wall time, last result) over ``repeats`` calls; its CPU time in LAST_CPU[0].

    Calls after the first stop once ``budget`` seconds have been spent (slow runs, e.g.
    solve_bvp at tol 1e-8 on a coarse initial mesh, are timed once).
    """
    best, out = math.inf, None
    start = time.perf_counter()
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall = time.perf_counter() - t
        if wall < best:
            best, LAST_CPU[0] = wall, time.process_time() - c
        if time.perf_counter() - start > budget:
            break
    return best, out


# ------------------------------------------------------------------------------- baseline
def baseline_critical_gap_rows(cfg: Config) -> list[Row]:
    """H_1^c by delta-pinning (delta = 0.01, 3 levels) at each solve_bvp tol and initial mesh."""
    model = GPCF(NUBAR, E)
    rows = []
    for tol in cfg.tols:
        for nodes in cfg.nodes:
            sec, r = best_of(cfg.repeats, lambda tol=tol, nodes=nodes: critical_gap_by_pinning(
                model, delta=0.01, levels=3, tol=tol, nodes=nodes))
            rows.append({"tol": tol, "init_nodes": nodes, "Hc": r.estimate, "rel_error": r.relative_error,
                         "points": len(r.points), "s_per_point": sec / len(r.points),
                         "nodes": max(pt.nodes for pt in r.points)})
    return rows


def baseline_natural_rows(cfg: Config) -> list[Row]:
    """Natural continuation in H along the n = 1 branch from 1.02 H_1^c to ``cfg.h_end``, at each
    solve_bvp tol and initial mesh (the start's mesh; later points reuse the previous mesh)."""
    model = GPCF(NUBAR, E)
    h0 = 1.02 * model.critical_gap()
    rows = []
    for tol, nodes in ((t, m) for t in cfg.tols for m in cfg.nodes):
        def run(tol=tol, nodes=nodes):
            start = start_near_critical(model, h0, 0.05, tol=tol, nodes=nodes)
            if not start.success:
                raise RuntimeError(f"baseline start failed at tol {tol}: {start.message}")
            return natural_continuation(model, start, cfg.h_end, 0.5, tol=tol)

        try:
            sec, r = best_of(cfg.repeats, run)
        except RuntimeError as exc:  # the start fell back onto uniform shear on this mesh
            rows.append({"tol": tol, "init_nodes": nodes, "status": f"start failed: {exc}", "points": 0})
            continue
        rows.append({"tol": tol, "init_nodes": nodes, "status": r.status, "points": len(r.points), "failed": r.failed_solves,
                     "s_per_point": sec / len(r.points), "cpu": LAST_CPU[0], "cpu_per_point": LAST_CPU[0] / len(r.points), "nodes_max": max(pt.nodes for pt in r.points),
                     "phi_end": r.phi[-1], "H_end": r.H[-1]})
    return rows


def baseline_fold_row(cfg: Config) -> Row:
    """nubar = 0.16: natural continuation downwards in H from the upper banded branch."""
    model = GPCF(0.16, E)
    tol = 1e-6
    t = time.perf_counter()
    fold = fold_by_pinning(model, np.linspace(0.01, 0.1, 19), tol=1e-8)
    t_fold = time.perf_counter() - t
    start = fixed_h_point(model, banded_start(model, 0.15, steps=10, tol=tol), tol=tol)
    t = time.perf_counter()
    r = natural_continuation(model, start, 30.0, 1.0, tol=tol, dh_min=1 / 64, max_nodes=cfg.max_nodes)
    sec = time.perf_counter() - t
    return {"nubar": 0.16, "Hc": model.critical_gap(), "H_LP": fold.H, "phi_LP": fold.phi, "fold_scan_s": t_fold,
            "status": r.status, "passed_fold": r.passed, "H_last": r.H[-1], "phi_last": r.phi[-1],
            "points": len(r.points), "failed": r.failed_solves, "seconds": sec, "message": r.message}


# ------------------------------------------------------------------------------- contin hooks
def contin_available() -> str | None:
    """None if contin's continuation core and the gPCF problem import, else the reason."""
    try:
        import contin.continuation  # noqa: F401
        import problems.couette.model  # noqa: F401
    except Exception as exc:  # noqa: BLE001 -- report, do not fail the baseline figures
        return f"{type(exc).__name__}: {exc}"
    return None


def _couette(method: str, n: int, h: float, engine: str = "numpy"):
    """The benchmark problem, or None where ``engine`` does not cover it (too large for numba)."""
    from problems.couette.model import CouetteProblem
    from problems.couette.params import build_params

    try:
        prob = CouetteProblem(method, n, engine=engine)
    except ValueError:
        return None, None
    if engine != "numpy":  # compile (or load) the kernels outside the timings
        p = build_params({"nu": NUBAR, "e": E, "H": h})
        x = prob.uniform_state(p)
        prob.residual(x, p), prob.dense_jacobian(x, p), prob.dresidual_dp(x, p, "H")
    return prob, build_params({"nu": NUBAR, "e": E, "H": h})


def _trace_options(h_end: float):
    from contin.options import ContinuationOptions, StepOptions

    # The resolution guard (ContinuationOptions.resolution_tol) is off: the coarse grids' cost
    # and accuracy are measured as they are (H_1^c error and the phi(H_end) error columns).
    guard = {"resolution_tol": None} if "resolution_tol" in {f.name for f in dataclasses.fields(ContinuationOptions)} else {}
    return ContinuationOptions(step=StepOptions(ds=0.5, ds_max=1.0), bounds={"H": (5.0, h_end)}, max_steps=400,
                               **guard)


def contin_newton_rows(cfg: Config) -> list[Row]:
    """Seconds per Newton iteration (residual, sparse Jacobian, LU, solve) against N.

    Newton from uniform shear + 0.05 x (mode-1 shape) at H = 16 (a banded solution exists).
    """
    from contin.newton import newton
    from contin.options import NewtonOptions

    rows = []
    for engine, method, n in _contin_cases(cfg):
        prob, p = _couette(method, n, 16.0, engine)
        if prob is None:
            continue
        u0 = prob.uniform_state(p)
        y = prob.grid.y
        u0[prob.i_nu] -= 0.05 * np.cos(np.pi * (y + 0.5))
        sec, res = best_of(cfg.repeats, lambda: newton(prob, u0, p, NewtonOptions(tol=1e-10, max_iterations=20)))
        rows.append({"engine": engine, "method": method, "N": n, "unknowns": prob.size, "iterations": res.iterations,
                     "converged": res.converged, "s_per_iteration": sec / max(res.iterations, 1),
                     "cpu_per_iteration": LAST_CPU[0] / max(res.iterations, 1)})
    return rows


def contin_trace_rows(cfg: Config) -> list[Row]:
    """Uniform branch in H from 10 to h_end (BP at H_1^c), then the banded branch by switch."""
    from contin.continuation import switch, trace

    hc = GPCF(NUBAR, E).critical_gap()
    opts = _trace_options(cfg.h_end)
    rows = []
    for engine, method, n in _contin_cases(cfg):
        prob, p = _couette(method, n, 10.0, engine)
        if prob is None:
            continue
        t, c = time.perf_counter(), time.process_time()
        br = trace(prob, prob.uniform_state(p), p, "H", opts)
        t_uniform, c_uniform = time.perf_counter() - t, time.process_time() - c
        bps = [b for b in br.special_points if b.type == "BP"]
        row = {"engine": engine, "method": method, "N": n, "uniform_steps": len(br), "uniform_s_per_step": t_uniform / max(len(br), 1),
               "uniform_cpu_per_step": c_uniform / max(len(br), 1),
               "Hc": math.nan, "rel_error": math.nan, "bp_converged": False, "banded_points": 0,
               "banded_s_per_point": math.nan, "banded_phi_end": math.nan, "banded_status": "no BP"}
        if bps:
            bp = min(bps, key=lambda b: abs(b.params["H"] - hc))
            row.update(Hc=bp.params["H"], rel_error=abs(bp.params["H"] - hc) / hc, bp_converged=bp.converged)
            # Best of cfg.repeats, as for the baseline rows (best_of).
            try:
                t_banded, new = best_of(cfg.repeats, lambda: switch(prob, br, bp, opts, directions=(+1,)))
                c_banded = LAST_CPU[0]
            except ValueError as exc:
                new, row["banded_status"], t_banded, c_banded = [], f"switch failed: {exc}", math.nan, math.nan
            if new:
                b = new[0]
                walls = sorted((float(b.observables["nu_bottom"][-1]), float(b.observables["nu_top"][-1])))
                row.update(banded_points=len(b), banded_s_per_point=t_banded / max(len(b), 1),
                           banded_cpu_per_point=c_banded / max(len(b), 1), banded_cpu=c_banded,
                           banded_walls_end=walls, banded_H_end=float(b.parameter_values[-1]),
                           banded_s_per_newton=t_banded / max(int(np.sum(b.newton_iterations)), 1),
                           banded_phi_end=float(b.observables["phi"][-1]), banded_status=b.status,
                           banded_newton=int(np.sum(b.newton_iterations)))
        rows.append(row)
    _wall_density_errors(rows)
    return rows


def _contin_cases(cfg: Config) -> list[tuple[str, str, int]]:
    """(engine, method, N) of every contin row."""
    return [(engine, method, n) for engine in cfg.engines for method, ns in cfg.methods.items() for n in ns]


def _wall_density_errors(rows: list[Row]) -> None:
    """Error of the end state's wall densities against the finest Chebyshev grid of the run.

    The end state (H = h_end) is compared through its two wall densities, sorted so that the
    mirror image (nu_bottom <-> nu_top) of the same branch compares equal.
    """
    refs = [r for r in rows if r["method"] == "cheb" and r.get("banded_walls_end") is not None
            and r.get("banded_status") == "EP"]
    if not refs:
        return
    ref = max(refs, key=lambda r: r["N"])
    for r in rows:
        w = r.get("banded_walls_end")
        if w is not None and r is not ref and r.get("banded_status") == "EP" and r["banded_H_end"] == ref["banded_H_end"]:
            r["banded_walls_error"] = max(abs(a - b) for a, b in zip(w, ref["banded_walls_end"], strict=True))
    ref["banded_walls_error"] = math.nan
    ref["walls_reference"] = True


def pitchfork_scene_rows(cfg: Config) -> list[Row]:
    """Wall time of the whole ``pitchfork`` scene (Chebyshev N = 64, k_x = 0 stability), per engine.

    The first (untimed) run of each engine loads its compiled kernels; the timings are of
    the runs after it, as a user sees every run but the first after an install.
    """
    from contin.scene import SceneRequest, get_scene

    try:
        scene = get_scene("pitchfork")
    except ValueError as exc:
        return [{"status": f"not available: {exc}"}]
    rows = []
    for engine in cfg.engines:
        scene.run(SceneRequest(stability=False, engine=engine))
        rows.append({"engine": engine, **_pitchfork_scene_row(cfg, scene, engine)})
    return rows


def _pitchfork_scene_row(cfg: Config, scene: Any, engine: str) -> Row:
    from contin.scene import SceneRequest

    sec, res = best_of(cfg.repeats, lambda: scene.run(SceneRequest(engine=engine)))
    cpu = LAST_CPU[0]
    t, c = time.perf_counter(), time.process_time()
    scene.run(SceneRequest(stability=False, engine=engine))
    wall_ns, cpu_ns = time.perf_counter() - t, time.process_time() - c
    return {"status": "ok", "seconds": sec, "cpu": cpu, "seconds_no_stability": wall_ns, "cpu_no_stability": cpu_ns,
            "branches": len(res.branches),
            "points": sum(len(b) for b in res.branches),
            "special_points": sum(len(b.special_points) for b in res.branches)}


def contin_fold_row(method: str = "cheb", n: int = 32) -> Row:
    """nubar = 0.16: contin's banded branch from H_1^c through the fold (problems.couette.keypoints)."""
    from problems.couette.keypoints import banded_fold
    from problems.couette.model import CouetteProblem

    prob = CouetteProblem(method, n)
    t, c = time.perf_counter(), time.process_time()
    branches, lp = banded_fold(prob, 0.16, E)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    banded = branches[-1]
    h = banded.parameter_values
    passed = lp is not None and bool(np.any(h[lp.index + 1:] > lp.params["H"] + 1.0))
    return {"method": f"{method} N={n}", "H_LP": lp.params["H"] if lp else math.nan,
            "phi_LP": lp.order_parameter if lp else math.nan, "passed_fold": passed,
            "points": sum(len(b) for b in branches), "seconds": wall, "cpu": cpu,
            "s_per_point": wall / max(sum(len(b) for b in branches), 1)}


def comparison_rows(base_gap: list[Row], base_nat: list[Row], contin_rows: list[Row],
                    targets: Sequence[float] = (1e-4, 1e-6, 1e-8, 1e-10)) -> list[Row]:
    """Cheapest CPU seconds per converged banded point reaching each H_1^c accuracy target.

    One row per target and contin engine (numpy, numba: the rows' ``engine``).

    Baseline: the solve_bvp tol and initial mesh whose pinning estimate meets the target, timed
    on natural continuation with the same tol and initial mesh (the cheapest such pair).  contin: the (method, N) whose located BP meets it, timed on the
    switched banded branch; a switch that fell back onto uniform shear (both wall densities at
    the end within 0.1 of nubar; rows without them: |phi_end - nubar| <= 0.1, phi = nu(1/2)) is
    not a banded branch and does not count.  Either mirror image of the branch counts.  Times
    are CPU seconds where the rows have them (the wall-clock figures otherwise).
    """
    def key(r: Row) -> tuple:
        return r["tol"], r.get("init_nodes")

    def label(r: Row) -> str:
        return f"tol={r['tol']:.0e}" + (f", {r['init_nodes']} nodes" if r.get("init_nodes") is not None else "")

    nat = {key(r): r for r in base_nat if r["status"] == "reached"}
    base = [(nat[key(g)].get("cpu_per_point", nat[key(g)]["s_per_point"]), label(g), g["rel_error"],
             nat[key(g)].get("cpu", math.nan)) for g in base_gap if key(g) in nat]
    cont = [(r.get("banded_cpu_per_point", r["banded_s_per_point"]), f"{r['method']} N={r['N']}", r["rel_error"],
             r.get("banded_cpu", math.nan), r.get("engine", "numpy")) for r in contin_rows
            if r["banded_points"] > 1
            and max(abs(w - NUBAR) for w in r.get("banded_walls_end", [r["banded_phi_end"]])) > 0.1]
    engines = list(dict.fromkeys(c[4] for c in cont)) or ["numpy"]
    rows = []
    for target, engine in ((t, e) for t in targets for e in engines):
        b = min((c for c in base if c[2] <= target), default=None)
        c = min((c for c in cont if c[2] <= target and c[4] == engine), default=None)
        rows.append({"target": target, "engine": engine,
                     "baseline": b[1] if b else "-", "baseline_s": b[0] if b else math.nan,
                     "contin": c[1] if c else "-", "contin_s": c[0] if c else math.nan,
                     "speedup": (b[0] / c[0]) if (b and c) else math.nan,
                     "baseline_branch_s": b[3] if b else math.nan, "contin_branch_s": c[3] if c else math.nan,
                     "branch_speedup": (b[3] / c[3]) if (b and c) else math.nan})
    return rows


# ------------------------------------------------------------------------------- printing
def table(title: str, rows: list[Row], columns: Sequence[tuple[str, str, str]]) -> str:
    """Plain-text table; columns are (key, header, format spec)."""
    if not rows:
        return f"{title}\n  (no rows)\n"
    cells = [[("-" if r.get(k) is None else format(r[k], f)) for k, _, f in columns] for r in rows]
    heads = [h for _, h, _ in columns]
    widths = [max(len(h), *(len(c[i]) for c in cells)) for i, h in enumerate(heads)]
    line = "  ".join(h.rjust(w) for h, w in zip(heads, widths, strict=True))
    body = "\n".join("  ".join(c.rjust(w) for c, w in zip(cs, widths, strict=True)) for cs in cells)
    return f"{title}\n{line}\n{body}\n"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.run", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer tolerances, grids and repeats")
    ap.add_argument("--no-contin", action="store_true", help="baseline figures only")
    ap.add_argument("--json", metavar="FILE", help="also write all figures as JSON")
    ap.add_argument("--engines", default=None, metavar="LIST",
                    help="contin engines to time, e.g. numpy,numba (default: numpy, and numba where installed)")
    args = ap.parse_args(argv)
    engines = tuple(e for e in args.engines.split(",") if e) if args.engines else None
    cfg = Config.make(args.quick, not args.no_contin, engines)
    from contin.blas import limit_blas_threads

    limit_blas_threads()  # as the CLI does: one BLAS thread unless CONTIN_BLAS_THREADS says otherwise
    out: dict[str, Any] = {"python": platform.python_version(), "machine": platform.machine(), "quick": args.quick}
    warnings.simplefilter("ignore", RuntimeWarning)

    print(f"gPCF benchmarks: nubar = {NUBAR}, e = {E}, chi = jj (nu_m = 0.65), no-slip/zero-flux walls, g = 0; "
          f"H_1^c = pi psi = {GPCF(NUBAR, E).critical_gap():.10f}\n")
    out["baseline_critical_gap"] = gap = baseline_critical_gap_rows(cfg)
    print(table("[baseline] solve_bvp, H_1^c by delta-pinning (delta = 0.01/4, 0.01/2, 0.01; Richardson in delta^2)",
                gap, [("tol", "tol", ".0e"), ("init_nodes", "init nodes", "d"), ("Hc", "H_1^c", ".10f"),
                      ("rel_error", "rel.err", ".1e"),
                      ("s_per_point", "s/point", ".4f"), ("nodes", "nodes", "d")]))
    out["baseline_natural"] = nat = baseline_natural_rows(cfg)
    print(table(f"[baseline] solve_bvp, natural continuation in H, banded n=1 branch, H = 1.02 H_1^c -> {cfg.h_end}, dH = 0.5",
                nat, [("tol", "tol", ".0e"), ("init_nodes", "init nodes", "d"), ("status", "status", "s"),
                      ("points", "points", "d"),
                      ("failed", "failed", "d"), ("s_per_point", "s/point", ".4f"), ("cpu_per_point", "cpu s/point", ".4f"),
                      ("cpu", "cpu s", ".3f"), ("nodes_max", "max nodes", "d"),
                      ("phi_end", "phi(H_end)", ".6f")]))
    out["baseline_fold"] = fold = baseline_fold_row(cfg)
    print(table("[baseline] nubar = 0.16 (subcritical): natural continuation in H from H = 49.4 downwards",
                [fold], [("Hc", "H_1^c", ".3f"), ("H_LP", "H_LP (pinning)", ".4f"), ("status", "status", "s"),
                         ("passed_fold", "through fold", ""), ("H_last", "last H", ".4f"),
                         ("phi_last", "last phi", ".4f"), ("phi_LP", "phi_LP", ".4f"), ("points", "points", "d"),
                         ("failed", "failed", "d"), ("seconds", "seconds", ".2f")]))
    print(f"  {fold['message']}\n")

    if cfg.contin:
        reason = contin_available()
        if reason is not None:
            print(f"[contin] figures skipped: {reason}\n")
        else:
            with np.errstate(all="ignore"):
                out["contin_newton"] = newton_rows = contin_newton_rows(cfg)
                print(table("[contin] Newton iteration (residual + sparse Jacobian + LU + solve) at H = 16",
                            newton_rows, [("engine", "engine", "s"), ("method", "method", "s"), ("N", "N", "d"),
                                          ("unknowns", "unknowns", "d"),
                                          ("iterations", "iters", "d"), ("converged", "conv", ""),
                                          ("s_per_iteration", "s/iter", ".2e"),
                                          ("cpu_per_iteration", "cpu s/iter", ".2e")]))
                out["contin_trace"] = trace_rows = contin_trace_rows(cfg)
                print(table(f"[contin] trace H: uniform branch 10 -> {cfg.h_end} (BP), switch to banded branch",
                            trace_rows, [("engine", "engine", "s"), ("method", "method", "s"), ("N", "N", "d"),
                                         ("uniform_s_per_step", "s/step uniform", ".4f"),
                                         ("uniform_cpu_per_step", "cpu s/step", ".4f"),
                                         ("Hc", "H_1^c (BP)", ".10f"), ("rel_error", "rel.err", ".1e"),
                                         ("bp_converged", "located", ""), ("banded_points", "banded pts", "d"),
                                         ("banded_s_per_point", "s/point banded", ".4f"),
                                         ("banded_cpu_per_point", "cpu s/point", ".4f"),
                                         ("banded_cpu", "cpu s", ".3f"),
                                         ("banded_s_per_newton", "s/LU", ".2e"),
                                         ("banded_phi_end", "phi end", ".4f"),
                                         ("banded_walls_error", "walls err", ".1e"), ("banded_status", "status", "s")]))
                print("  walls err: max error of (nu_bottom, nu_top) at H_end against the finest Chebyshev grid; "
                      "resolution guard off\n")
                out["pitchfork_scene"] = scenes = pitchfork_scene_rows(cfg)
                if scenes[0].get("status") == "ok":
                    print(table("[contin] pitchfork scene (whole)", scenes,
                                [("engine", "engine", "s"), ("seconds", "wall s", ".2f"), ("cpu", "cpu s", ".2f"),
                                 ("seconds_no_stability", "wall s (no stab.)", ".2f"),
                                 ("cpu_no_stability", "cpu s (no stab.)", ".2f"), ("branches", "branches", "d"),
                                 ("points", "points", "d"), ("special_points", "special", "d")]))
                else:
                    print(f"[contin] pitchfork scene: {scenes[0]['status']}\n")
                out["contin_fold"] = cfold = contin_fold_row()
                print(table("[contin] nubar = 0.16: banded branch from H_1^c = 63.50 downwards (theta = 1e-4)",
                            [cfold], [("method", "grid", "s"), ("H_LP", "H_LP", ".6f"), ("phi_LP", "phi_LP", ".4f"),
                                      ("passed_fold", "through fold", ""), ("points", "points", "d"),
                                      ("seconds", "wall s", ".2f"), ("cpu", "cpu s", ".2f"),
                                      ("s_per_point", "s/point", ".4f")]))
                out["comparison"] = comp = comparison_rows(gap, nat, trace_rows)
                print(table("[side by side] CPU seconds per converged banded point (and per branch) at equal "
                            "accuracy in H_1^c",
                            comp, [("target", "rel.err <=", ".0e"), ("baseline", "baseline", "s"),
                                   ("engine", "contin engine", "s"),
                                   ("baseline_s", "s/point", ".5f"), ("contin", "contin", "s"),
                                   ("contin_s", "s/point", ".5f"), ("speedup", "baseline/contin", ".1f"),
                                   ("baseline_branch_s", "s/branch base", ".4f"),
                                   ("contin_branch_s", "s/branch contin", ".4f"),
                                   ("branch_speedup", "branch ratio", ".1f")]))
                print(f"  branch: baseline 1.02 H_1^c -> {cfg.h_end} (dH = 0.5), contin H_1^c -> {cfg.h_end} "
                      "(switch at the BP included)\n")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1, default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
