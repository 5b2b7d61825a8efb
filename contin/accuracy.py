"""Speed against accuracy: re-run a scene on several discretizations and grids.

For every (method, N) the scene is run once (stability off: it measures the continuation,
not the eigenvalue pass) and its *key points* are collected:

- ``SceneResult.extra['key_points']`` -- ``{name: value}`` -- if the scene provides it (the
  scene knows which numbers matter, e.g. the critical gaps H_n^c of gPCF); otherwise
- every converged BP, LP and HB of every branch, named ``"<branch id>/<type><k>"`` (k-th point
  of that type along the branch, in branch order) with the value of the branch's
  continuation parameter.  The same name on two grids is the same point as long as the
  scene labels its branches deterministically (contin scenes do).

Errors are measured against a reference value per key point:

- its closed form, where the scene gives one (``SceneResult.extra['exact']``, ``{name: value}``;
  gPCF's H_1^c = n pi psi): then every grid's own error is shown, the finest included; else
- the finest Chebyshev grid of the run when 'cheb' is among the methods (spectral
  convergence: its error is far below every other entry's); else
- Richardson extrapolation of the highest-order FD method from its two finest grids with
  its nominal order p: v* = (v1 N1^p - v2 N2^p) / (N1^p - N2^p)  (v(N) = v* + C N^-p).

The observed order between consecutive grids N_a < N_b of one method is
log(e_a / e_b) / log(N_b / N_a).  Wall time (``time.perf_counter``) and CPU time
(``time.process_time``) are both recorded: on a shared machine the CPU time is the fairer
figure.  Peak memory is the tracemalloc peak of a second, separate run (tracemalloc slows
numpy-heavy code down, so it never overlaps the timed run); ``memory=False`` skips it.

Asking for an accuracy instead of a grid (``tols``; scenes with ``Scene.adaptive``): for each
tol the scene is also run with adaptive resolution (``SceneRequest.overrides['tol']``, no grid:
the scene's start grid; ``special_tol`` = tol too, since the key points are special points), its
key points are measured against the same reference, and the run is
compared with the cheapest fixed (method, N) run whose worst key-point error meets the same tol
(issue 14: achieved error <= tol, cost within 1.5x of that grid).  That request ("all") asks
every state of the run for tol too, more than the fixed grids deliver (their states only pass
the resolution guard, 3e-5).  A scene whose key points are special points of its traces
(``Scene.special_key_points``) is also run asking the key points alone for tol ("key points":
``special_tol`` = tol, the states at the scene's ``default_tol`` judged by their estimate alone,
``solve_check`` False: the fixed runs' guard, no more; the key points' positions keep their
two-grid checks, ``contin.specialcheck``), the request a user who wants a fold or branch point
to tol makes (``contin trace --special-tol T --no-solve-check``).  ``repeats`` > 1 times every
run that many times in interleaved rounds and keeps each run's smallest CPU time, so that a
change of the machine's load shifts both sides of a cost ratio alike.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import time
import tracemalloc
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from contin.scene import Scene, SceneRequest, SceneResult

#: Nominal convergence orders of the FD methods (Richardson reference without Chebyshev).
NOMINAL_ORDER = {"fd2": 2, "fd4": 4, "fd6": 6}
#: Default accuracy budgets of the recommendation table (relative error).
DEFAULT_TARGETS = (1e-3, 1e-4, 1e-6, 1e-8, 1e-10)


@dataclass
class Run:
    """One scene run at one discretization: timings, cost and its key points."""

    method: str
    grid: int
    wall: float
    cpu: float
    newton_iterations: int
    points: int
    peak_memory_mb: float
    values: dict[str, float]
    failed: str = ""  # the reason when the run raised (then values is empty)
    engine: str = ""  # the problem's engine as the scene reports it (SceneResult.discretization)
    grids_used: tuple[int, int] | None = None  # (smallest, largest) per-point grid of an adaptive run
    stopped: int = 0  # branches that ended MX (e.g. the resolution guard: the grid does not carry the job)
    exact: dict[str, float] = field(default_factory=dict)  # closed-form values of key points (extra['exact'])


@dataclass
class Row:
    """One key point at one discretization."""

    key: str
    method: str
    grid: int
    value: float
    reference: float
    error: float  # relative |value - reference| / max(|reference|, tiny); nan for the reference itself
    order: float  # observed order against the previous (coarser) grid of the same method
    wall: float
    cpu: float
    newton_iterations: int
    peak_memory_mb: float


@dataclass
class AdaptiveRow:
    """One adaptive run (asked for ``tol``) against the reference and the cheapest fixed grid.

    errors : relative error of each key point; worst_key : the key point of the largest
    met : every key point is within tol (False also when a key point is missing or the run failed)
    grids : (smallest, largest) grid any stored point of the run used
    fixed_method, fixed_grid, fixed_cpu : the cheapest fixed run whose worst error is <= tol
        (None / nan when no fixed run of the report meets it)
    ratio : cpu / fixed_cpu (nan without such a run)
    request : what asked for tol: "all" (states and key points) or "key points" (the key points,
        states at the scene's default_tol by their estimate; module docstring)
    """

    tol: float
    cpu: float
    wall: float
    newton_iterations: int
    values: dict[str, float]
    errors: dict[str, float]
    worst_error: float
    worst_key: str
    met: bool
    grids: tuple[int, int] | None
    fixed_method: str | None
    fixed_grid: int | None
    fixed_cpu: float
    ratio: float
    failed: str = ""
    request: str = "all"


#: The adaptive requests of ``contin accuracy --tols`` (module docstring).
REQUESTS = ("all", "key points")


@dataclass
class AccuracyReport:
    scene: str
    params: dict[str, Any]
    reference: dict[str, float]
    reference_from: str
    runs: list[Run]
    rows: list[Row] = field(default_factory=list)
    adaptive: list[AdaptiveRow] = field(default_factory=list)
    #: why the report is partial ("interrupted (Ctrl-C): 3 of 28 runs finished"), "" when complete
    incomplete: str = ""

    def to_json(self) -> dict[str, Any]:
        out = {
            "scene": self.scene, "params": {k: _jsonable(v) for k, v in self.params.items()},
            "reference": self.reference, "reference_from": self.reference_from,
            "runs": [asdict(r) for r in self.runs], "rows": [asdict(r) for r in self.rows],
            "recommendations": recommend(self), "adaptive": [asdict(a) for a in self.adaptive],
        }
        if self.incomplete:
            out["incomplete"] = self.incomplete
        return out

    @property
    def inaccurate(self) -> list[AdaptiveRow]:
        """The adaptive runs whose achieved error exceeds the tol they asked for."""
        return [a for a in self.adaptive if not a.met]


def _jsonable(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    return v


def exact_points(result: SceneResult) -> dict[str, float]:
    """The closed-form values of key points the scene gives (``extra['exact']``), else {}."""
    given = result.extra.get("exact") if isinstance(result.extra, Mapping) else None
    return {str(k): float(v) for k, v in given.items()} if isinstance(given, Mapping) else {}


def key_points(result: SceneResult) -> dict[str, float]:
    """The scene's key points (module docstring): ``extra['key_points']`` or its BPs, LPs and HBs."""
    given = result.extra.get("key_points") if isinstance(result.extra, Mapping) else None
    if given:
        return {str(k): float(v) for k, v in given.items()}
    out: dict[str, float] = {}
    for b in result.branches:
        if len(b.free) != 1:
            continue  # fold curves etc.: their special points are not one-parameter values
        counts: dict[str, int] = {}
        for sp in b.special_points:
            if sp.type not in ("BP", "LP", "HB") or not sp.converged:
                continue
            counts[sp.type] = counts.get(sp.type, 0) + 1
            out[f"{b.id}/{sp.type}{counts[sp.type]}"] = float(sp.params[b.parameter])
    return out


def _request(params: Mapping[str, Any], method: str, grid: int | None, overrides: Mapping[str, Any] | None,
             engine: str | None) -> SceneRequest:
    """The request of one accuracy run (stability off: only the key points are measured)."""
    return SceneRequest(params=dict(params), method=method, grid=grid, stability=False,
                        overrides=dict(overrides or {}), engine=engine)


def measure(scene: Scene, params: Mapping[str, Any], method: str, grid: int | None, *, memory: bool = True,
            overrides: Mapping[str, Any] | None = None, engine: str | None = None) -> Run:
    """Run ``scene`` once at (method, grid) and time it (plus a tracemalloc run if ``memory``).

    ``grid`` None: the scene's own start grid (an adaptive run, ``overrides['tol']``); the Run's
    grid is then the largest grid any stored point used and :func:`grids_used` gives both ends."""
    t0, c0 = time.perf_counter(), time.process_time()
    result = scene.run(_request(params, method, grid, overrides, engine))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = math.nan
    if memory:
        tracemalloc.start()
        try:
            scene.run(_request(params, method, grid, overrides, engine))
            peak = tracemalloc.get_traced_memory()[1] / 2**20
        finally:
            tracemalloc.stop()
    iters = sum(int(b.newton_iterations.sum()) for b in result.branches if len(b))
    points = sum(len(b) for b in result.branches)
    used = grids_used(result)
    if used is None and grid is None and result.discretization.get("intervals"):
        n = int(result.discretization["intervals"])  # an adaptive run that stayed on its start grid
        used = (n, n)
    if grid is None:
        grid = used[1] if used else int(result.discretization.get("intervals", 0) or 0)
    return Run(method, grid, wall, cpu, iters, points, peak, key_points(result),
               engine=str(result.discretization.get("engine", "")), grids_used=used,
               stopped=sum(1 for b in result.branches if b.status == "MX"), exact=exact_points(result))


def grids_used(result: SceneResult) -> tuple[int, int] | None:
    """(smallest, largest) grid of the stored points and special points of a scene's branches
    (None when no branch stores per-point grids: a fixed-grid run)."""
    sizes = []
    for b in result.branches:
        g = getattr(b, "grid", None)
        if g is not None and len(g):
            sizes += [int(x) for x in g if x > 0]
        sizes += [int(sp.grid) for sp in b.special_points if getattr(sp, "grid", None)]
    return (min(sizes), max(sizes)) if sizes else None


def run_accuracy(scene: Scene, params: Mapping[str, Any], methods: Sequence[str], grids: Sequence[int], *,
                 memory: bool = True, overrides: Mapping[str, Any] | None = None,
                 progress: Callable[[str], None] | None = None, engine: str | None = None,
                 tols: Sequence[float] = (), repeats: int = 1) -> AccuracyReport:
    """Measure every (method, grid) pair and tabulate errors against the reference.

    A pair whose scene run raises ValueError (e.g. a grid too small for the method) is kept as
    a failed :class:`Run` with the reason; other exceptions propagate.  One untimed run at the
    first method's coarsest grid goes first, so that the first timed run does not pay the
    one-off costs of a process (lazy imports, loading compiled kernels: ``engine``).

    ``tols``: also run the scene adaptively at each tol (module docstring; the scene must be
    ``adaptive``) and fill :attr:`AccuracyReport.adaptive`.  ``repeats``: interleaved timing
    rounds, each run keeping its smallest CPU time (the memory run is made once).
    """
    if not methods or not grids:
        raise ValueError("need at least one method and one grid")
    if tols and not scene.adaptive:
        raise ValueError(f"scene {scene.name!r} has no adaptive resolution: --tols needs an adaptive scene")
    if any(not (math.isfinite(t) and 0 < t < 1) for t in tols):
        raise ValueError(f"every tol must be a number in (0, 1), got {', '.join(map(str, tols))}")
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    with contextlib.suppress(ValueError):
        scene.run(_request(params, methods[0], min(int(g) for g in grids), overrides, engine))
    adaptive_method = "cheb" if "cheb" in methods else methods[0]
    jobs: list[tuple[str, int | None, float | None, str]] = [
        (m, n, None, "") for m in methods for n in sorted(set(int(g) for g in grids))]
    requests = REQUESTS if scene.special_key_points else REQUESTS[:1]
    jobs += [(adaptive_method, None, float(t), request) for request in requests for t in tols]
    best: dict[int, Run] = {}
    state = {"round": 1}
    try:
        _measure_jobs(scene, params, jobs, best, state, repeats=repeats, memory=memory, overrides=overrides,
                      progress=progress, engine=engine)
    except KeyboardInterrupt as exc:  # Ctrl-C/SIGTERM (contin.cli._runctl.Terminated): the finished runs
        # are the exception's partial_report (the CLI writes it, marked incomplete; qa17: all was lost)
        why = "terminated by SIGTERM" if type(exc).__name__ == "Terminated" else "interrupted (Ctrl-C)"
        where = f" (timing round {state['round']} of {repeats})" if repeats > 1 else ""
        exc.partial_report = _report(  # type: ignore[attr-defined]
            scene, params, jobs, best, incomplete=f"{why}: {len(best)} of {len(jobs)} runs finished{where}")
        raise
    return _report(scene, params, jobs, best)


def _report(scene: Scene, params: Mapping[str, Any], jobs: Sequence[tuple[str, int | None, float | None, str]],
            best: Mapping[int, Run], incomplete: str = "") -> AccuracyReport:
    """The report of the finished runs ``best`` (job index -> Run) of ``jobs``."""
    fixed = [best[i] for i, job in enumerate(jobs) if job[2] is None and i in best]
    reference, source = references(fixed)
    report = AccuracyReport(scene.name, dict(params), reference, source, fixed, incomplete=incomplete)
    report.rows = tabulate(fixed, reference)
    report.adaptive = [adaptive_row(best[i], job[2], report, job[3]) for i, job in enumerate(jobs)
                       if job[2] is not None and i in best]
    return report


def _measure_jobs(scene: Scene, params: Mapping[str, Any], jobs: Sequence[tuple[str, int | None, float | None, str]],
                  best: dict[int, Run], state: dict[str, int], *, repeats: int, memory: bool, overrides: Mapping[str, Any] | None,
                  progress: Callable[[str], None] | None, engine: str | None) -> None:
    """Run every job ``repeats`` times, keeping each one's fastest Run in ``best`` as it finishes
    (``state['round']``: the round under way, from 1)."""
    for rnd in range(repeats):
        state["round"] = rnd + 1
        for i, (method, n, tol, request) in enumerate(jobs):
            if i in best and best[i].failed:
                continue
            what = f"{method} N={n}" if tol is None else f"{method} tol={tol:g} ({request})"
            if progress is not None:
                progress(f"{scene.name}: {what}" + (f" (round {rnd + 1}/{repeats})" if repeats > 1 else ""))
            # the key points are special points: the accuracy asked for is theirs as well
            # (special_tol = tol; the tracer's default 1e-10 would locate them far beyond tol,
            # a different request from the fixed grid it is compared with)
            # ("key points": the states at the scene's default tol and judged by their estimate
            # alone, solve_check False: the fixed runs' guard; the key points' positions keep
            # their two-grid checks, contin.specialcheck)
            ov = dict(overrides or {}) if tol is None else {
                "special_tol": tol, **dict(overrides or {}), "tol": tol if request == "all" else scene.default_tol,
                **({} if request == "all" else {"solve_check": False})}
            try:
                run = measure(scene, params, method, n, memory=memory and rnd == 0, overrides=ov, engine=engine)
            except ValueError as exc:
                run = Run(method, n or 0, math.nan, math.nan, 0, 0, math.nan, {}, failed=str(exc).splitlines()[0])
            if i not in best or run.cpu < best[i].cpu:
                if i in best and not math.isnan(best[i].peak_memory_mb):
                    run.peak_memory_mb = best[i].peak_memory_mb
                best[i] = run


def adaptive_row(run: Run, tol: float, report: AccuracyReport, request: str = "all") -> AdaptiveRow:
    """An adaptive run's key points against ``report``'s reference and cheapest fixed grid."""
    errors = {k: relative_error(run.values[k], ref) for k, ref in report.reference.items() if k in run.values}
    missing = [k for k in report.reference if k not in run.values]
    worst_key = max(errors, key=errors.get) if errors else ""  # type: ignore[arg-type]
    worst = math.inf if missing or not errors or run.failed else errors[worst_key]
    if missing and not run.failed:
        worst_key = missing[0]
    rec = recommend(report, (tol,), complete_only=True)[0]
    ratio = run.cpu / rec["cpu"] if rec["method"] and rec["cpu"] > 0 else math.nan
    return AdaptiveRow(tol, run.cpu, run.wall, run.newton_iterations, dict(run.values), errors, worst, worst_key,
                       bool(worst <= tol), run.grids_used, rec["method"], rec["grid"], rec["cpu"], ratio,
                       failed=run.failed or (f"key point {missing[0]} not found" if missing else ""), request=request)


def references(runs: Iterable[Run]) -> tuple[dict[str, float], str]:
    """(reference value per key point, description) -- see the module docstring."""
    ok = [r for r in runs if not r.failed and r.values]
    numeric, source = _numeric_references(ok)
    exact = next((r.exact for r in ok if r.exact), {})
    if not exact:
        return numeric, source
    closed = [k for k in exact if k in numeric]
    if not closed:
        return numeric, source
    rest = [k for k in numeric if k not in exact]
    what = f"closed form for {', '.join(closed)}" + (f"; {source} for {', '.join(rest)}" if rest else "")
    return {k: (exact[k] if k in exact else v) for k, v in numeric.items()}, what


def _numeric_references(ok: Sequence[Run]) -> tuple[dict[str, float], str]:
    cheb = sorted((r for r in ok if r.method == "cheb"), key=lambda r: r.grid)
    if cheb:
        best = cheb[-1]
        return dict(best.values), f"cheb N={best.grid}"
    for method in sorted(NOMINAL_ORDER, key=NOMINAL_ORDER.get, reverse=True):  # type: ignore[arg-type]
        rs = sorted((r for r in ok if r.method == method), key=lambda r: r.grid)
        if len(rs) >= 2:
            (n2, r2), (n1, r1) = (rs[-2].grid, rs[-2]), (rs[-1].grid, rs[-1])
            p = NOMINAL_ORDER[method]
            ref = {k: (r1.values[k] * n1**p - r2.values[k] * n2**p) / (n1**p - n2**p)
                   for k in r1.values if k in r2.values}
            return ref, f"Richardson {method} N={n2},{n1} (order {p})"
    if ok:
        best = max(ok, key=lambda r: r.grid)
        return dict(best.values), f"{best.method} N={best.grid} (finest grid; no Richardson possible)"
    return {}, "none (every run failed)"


def relative_error(value: float, reference: float) -> float:
    return abs(value - reference) / max(abs(reference), 1e-300)


def tabulate(runs: Sequence[Run], reference: Mapping[str, float]) -> list[Row]:
    rows: list[Row] = []
    finest_cheb = max((r.grid for r in runs if r.method == "cheb" and not r.failed and r.values), default=None)
    for key, ref in reference.items():
        by_method: dict[str, list[Row]] = {}
        for r in runs:
            if r.failed or key not in r.values:
                continue
            is_ref = r.method == "cheb" and r.grid == finest_cheb and key not in r.exact
            err = math.nan if is_ref else relative_error(r.values[key], ref)
            prev = by_method.setdefault(r.method, [])
            order = math.nan
            if prev and prev[-1].error > 0 and err > 0 and math.isfinite(err) and math.isfinite(prev[-1].error):
                order = math.log(prev[-1].error / err) / math.log(r.grid / prev[-1].grid)
            row = Row(key, r.method, r.grid, r.values[key], ref, err, order, r.wall, r.cpu,
                      r.newton_iterations, r.peak_memory_mb)
            prev.append(row)
            rows.append(row)
    return rows


def recommend(report: AccuracyReport, targets: Sequence[float] = DEFAULT_TARGETS, *,
              complete_only: bool = False) -> list[dict[str, Any]]:
    """For each accuracy budget, the cheapest (CPU time) run whose worst key-point error meets it.

    ``complete_only``: only runs none of whose branches ended MX (the comparison for adaptive
    runs, which trace every branch to its end: a fixed grid that the resolution guard stops
    part-way did not do the same job, and its user would have to rerun it finer)."""
    worst: dict[tuple[str, int], float] = {}
    cost: dict[tuple[str, int], float] = {}
    stopped = {(r.method, r.grid) for r in report.runs if r.stopped}
    for row in report.rows:
        k = (row.method, row.grid)
        if math.isnan(row.error) or (complete_only and k in stopped):
            continue
        worst[k] = max(worst.get(k, 0.0), row.error)
        cost[k] = row.cpu
    n_keys = len(report.reference)
    complete = {k for k in worst if sum(1 for r in report.rows if (r.method, r.grid) == k) == n_keys}
    out = []
    for target in targets:
        cands = [k for k in complete if worst[k] <= target]
        best = min(cands, key=lambda k: cost[k]) if cands else None
        out.append({"target": target, "method": best[0] if best else None, "grid": best[1] if best else None,
                    "cpu": cost[best] if best else math.nan, "worst_error": worst[best] if best else math.nan})
    return out


# ------------------------------------------------------------------------------- output
COLUMNS = ("key", "method", "grid", "value", "reference", "error", "order", "wall", "cpu",
           "newton_iterations", "peak_memory_mb")


def write_outputs(report: AccuracyReport, directory: str | Path, *, plots: bool = True) -> list[Path]:
    """accuracy_<scene>.csv, .json and (``plots``) error-vs-N / error-vs-time PNGs in ``directory``."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    stem = f"accuracy_{report.scene}"
    written = []
    lines = [",".join(COLUMNS)]
    for r in report.rows:
        lines.append(",".join(_csv_cell(getattr(r, c)) for c in COLUMNS))
    for r in report.runs:
        if r.failed:
            lines.append(",".join(["#failed", r.method, str(r.grid), _csv_cell(r.failed)] + [""] * (len(COLUMNS) - 4)))
    if report.incomplete:  # a run stopped by Ctrl-C/SIGTERM: the rows of the finished runs only
        lines.append(",".join(["#incomplete", _csv_cell(report.incomplete)] + [""] * (len(COLUMNS) - 2)))
    _publish_text(d / f"{stem}.csv", "\n".join(lines) + "\n")
    written.append(d / f"{stem}.csv")
    _publish_text(d / f"{stem}.json", json.dumps(_clean(report.to_json()), indent=1) + "\n")
    written.append(d / f"{stem}.json")
    if report.adaptive:
        cols = ("tol", "request", "worst_error", "worst_key", "met", "cpu", "wall", "newton_iterations", "grid_min", "grid_max",
                "fixed_method", "fixed_grid", "fixed_cpu", "ratio", "failed")
        lines = [",".join(cols)]
        for a in report.adaptive:
            g = a.grids or (None, None)
            cells = (a.tol, a.request, a.worst_error, a.worst_key, a.met, a.cpu, a.wall, a.newton_iterations, g[0], g[1],
                     a.fixed_method, a.fixed_grid, a.fixed_cpu, a.ratio, a.failed)
            lines.append(",".join(_csv_cell("" if c is None else c) for c in cells))
        if report.incomplete:
            lines.append(",".join(["#incomplete", _csv_cell(report.incomplete)] + [""] * (len(cols) - 2)))
        _publish_text(d / f"{stem}_adaptive.csv", "\n".join(lines) + "\n")
        written.append(d / f"{stem}_adaptive.csv")
    if plots and report.rows:
        written += plot_report(report, d / f"{stem}")
    return written


def _publish_text(path: Path, text: str) -> None:
    """Write ``text`` atomically (temporary file + rename, contin.atomic)."""
    from contin.atomic import publish

    publish(path, lambda tmp: tmp.write_text(text))


def _csv_cell(v: Any) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    s = str(v)
    if any(c in s for c in ',"\n'):
        buf = []
        w = csv.writer(_ListWriter(buf))
        w.writerow([s])
        return buf[0].rstrip("\r\n")
    return s


class _ListWriter:
    def __init__(self, buf: list[str]) -> None:
        self.buf = buf

    def write(self, s: str) -> None:
        self.buf.append(s)


def _clean(obj: Any) -> Any:
    """NaN/inf -> None so the JSON is standard."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    return obj


def plot_report(report: AccuracyReport, stem: Path) -> list[Path]:
    """Two log-log figures, one panel per key point: error against N and against CPU time."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from contin.plot import save_figure

    keys = list(report.reference)
    ncol = min(3, len(keys))
    nrow = math.ceil(len(keys) / ncol)
    out = []
    for xname, xlabel, suffix in (("grid", "N (grid intervals)", "error_vs_N"), ("cpu", "CPU time of the run [s]", "error_vs_time")):
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.4 * nrow), squeeze=False)
        for ax, key in zip(axes.ravel(), keys):
            for method in dict.fromkeys(r.method for r in report.rows):
                pts = [(getattr(r, xname), r.error) for r in report.rows
                       if r.key == key and r.method == method and r.error > 0 and math.isfinite(r.error)]
                if pts:
                    xs, ys = zip(*pts)
                    ax.loglog(xs, ys, "o-", label=method, ms=4)
            ax.set_title(key, fontsize=9)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("relative error")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        for ax in axes.ravel()[len(keys):]:
            ax.set_visible(False)
        fig.suptitle(f"{report.scene}: error against reference ({report.reference_from})", fontsize=10)
        fig.tight_layout()
        path = Path(f"{stem}_{suffix}.png")
        save_figure(fig, path)
        plt.close(fig)
        out.append(path)
    return out
