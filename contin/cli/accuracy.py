"""``contin accuracy SCENE``: the scene's key points against discretization and grid."""

from __future__ import annotations

from typing import Any

import click

from contin.cli._base import (
    echo_err,
    echo_json,
    engine_option,
    fmt,
    main,
    parse_settings,
    resolution_guard,
    resolution_tol_option,
    table,
)

DEFAULT_METHODS = "cheb,fd2,fd4,fd6"
DEFAULT_GRIDS = "16,24,32,48,64,96,128"
KNOWN_METHODS = ("cheb", "fd2", "fd4", "fd6")


def _split(text: str, kind: type, option: str) -> list[Any]:
    try:
        out = [kind(x.strip()) for x in text.split(",") if x.strip()]
    except ValueError:
        raise click.BadParameter(f"expected a comma-separated list, got {text!r}", param_hint=option) from None
    if not out:
        raise click.BadParameter("the list is empty", param_hint=option)
    # each value once (order kept): `--methods cheb,cheb` ran every grid twice and its budget
    # table said "not reached" for budgets cheb 16 meets (qa15)
    return list(dict.fromkeys(out))


@main.command("accuracy")
@click.argument("scene")
@click.option("-s", "--set", "settings", multiple=True, metavar="NAME=VALUE", help="Set a scene parameter (repeatable).")
@click.option("--methods", default=DEFAULT_METHODS, help="Comma-separated discretization methods.")
@click.option("--grids", default=DEFAULT_GRIDS, help="Comma-separated numbers of grid intervals.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON document on stdout.")
@click.option("-o", "--output", "outdir", type=click.Path(file_okay=False), default=None,
              help="Directory for the CSV, JSON and plots (e.g. results/accuracy).")
@click.option("--no-memory", is_flag=True, help="Skip the separate tracemalloc run (halves the time).")
@click.option("--no-plots", is_flag=True, help="Write the table only.")
@click.option("--tols", default=None, metavar="LIST",
              help="Also run the scene with adaptive resolution at each tol (comma-separated, e.g. 1e-4,1e-6; "
                   "adaptive scenes only): achieved error against tol and cost against the cheapest fixed grid "
                   "meeting it; scenes whose key points are special points also ask them alone (states at the "
                   "scene's default tol, as the fixed grids' guard).  Exit 4 when an achieved error exceeds its tol.")
@click.option("--repeats", default=1, show_default=True, type=click.IntRange(1, 100),
              help="Timing rounds, interleaved; each run keeps its smallest CPU time (fair cost ratios on a busy machine).")
@resolution_tol_option
@engine_option
@click.option("-q", "--quiet", is_flag=True, help="No progress lines and no table on stderr.")
def accuracy_command(scene: str, settings: tuple[str, ...], methods: str, grids: str, as_json: bool,
                     outdir: str | None, no_memory: bool, no_plots: bool, tols: str | None, repeats: int,
                     resolution_tol: str | None, engine: str, quiet: bool) -> None:
    """Re-trace SCENE's key points (BPs, LPs) at every METHOD x GRID.

    Reports each value, its relative error against the finest Chebyshev grid (or a
    Richardson estimate), the observed order, wall and CPU time, Newton iterations and peak
    memory, and which discretization is cheapest for each accuracy budget.  Coarse grids may
    be stopped by the resolution guard; --resolution-tol off keeps their answers as they are.
    With --tols, the scene is also run asking for each accuracy instead of a grid.
    """
    import contin.scene as scene_mod
    from contin.accuracy import run_accuracy, write_outputs

    params = parse_settings(settings)
    guard, _ = resolution_guard(resolution_tol)  # every trace of every run
    method_list = _split(methods, str, "'--methods'")
    unknown = [m for m in method_list if m not in KNOWN_METHODS]
    if unknown:
        raise ValueError(f"unknown method {unknown[0]!r}; choose from {', '.join(KNOWN_METHODS)}")
    grid_list = _split(grids, int, "'--grids'")
    if min(grid_list) < 2:
        raise ValueError(f"grids must be at least 2 intervals, got {min(grid_list)}")
    from contin.limits import MAX_GRID

    if max(grid_list) > MAX_GRID:
        raise ValueError(f"grids must be at most {MAX_GRID} intervals, got {max(grid_list)}")
    if len(set(grid_list)) < 2:  # the finest grid is the reference: one grid measured nothing (a table of nan)
        raise ValueError(f"--grids needs at least two different grid sizes (the finest is the reference), got {grids!r}")
    tol_list = _split(tols, float, "'--tols'") if tols is not None else []
    bad_tol = [t for t in tol_list if not 0 < t < 1]  # nan and inf fail this too
    if bad_tol:
        raise ValueError(f"--tols must be numbers in (0, 1), got {bad_tol[0]}")
    sc = scene_mod.get_scene(scene)
    if tol_list and not sc.adaptive:
        raise ValueError(f"scene {scene!r} has no adaptive resolution; --tols needs an adaptive scene")
    if not sc.discretized:  # `contin accuracy ab` printed a table of one ODE value per "grid", exit 0 (qa16)
        raise ValueError(f"scene {scene!r} is a system of ODEs without a discretization; accuracy compares "
                         f"discretizations (--methods x --grids)")
    if sc.defaults:
        bad = [n for n in params if n not in sc.defaults]
        if bad:
            raise scene_mod.SceneError(f"unknown parameter {bad[0]!r} for scene {scene!r}; its parameters are {', '.join(sc.defaults)}")
    if outdir is not None:
        from pathlib import Path

        Path(outdir).mkdir(parents=True, exist_ok=True)  # fail before computing
    from contin.cli._runctl import Progress

    # a line per run, and a heartbeat when stderr is not a terminal (long jobs show life in logs)
    progress = Progress(enabled=not quiet)

    def running(message: str) -> None:
        progress.line(f"running {message}")
        progress.note(message)  # the heartbeat repeats it (it said 'running: started' all along; qa18)

    try:
        with guard:
            report = run_accuracy(sc, params, method_list, grid_list, memory=not no_memory, engine=engine,
                                  progress=None if quiet else running,
                                  tols=tol_list, repeats=repeats)
    except KeyboardInterrupt as exc:  # Ctrl-C/SIGTERM lost every finished run (qa17): keep them, marked
        progress.close()
        _save_partial(getattr(exc, "partial_report", None), outdir, plots=not no_plots, as_json=as_json, quiet=quiet)
        raise  # the group's one Error line, exit 130 (143)
    finally:
        progress.close()
    if not report.reference:
        raise ValueError(f"no key points: every run of scene {scene!r} failed or found no BP/LP/HB "
                         f"({'; '.join(sorted({r.failed for r in report.runs if r.failed})) or 'no special points'})")
    written = write_outputs(report, outdir, plots=not no_plots) if outdir is not None else []
    if as_json:
        from contin.accuracy import _clean

        echo_json(_clean(report.to_json()))
    if not quiet:
        _show(report, written)
    if report.inaccurate:
        from contin.cli.verify import EXIT_INACCURATE

        for a in report.inaccurate:
            why = a.failed or f"achieved error {fmt(a.worst_error, 2)} at {a.worst_key} exceeds it"
            click.echo(f"inaccurate: adaptive run at tol {a.tol:g} ({a.request}): {why}", err=True)
        raise click.exceptions.Exit(EXIT_INACCURATE)


def _save_partial(report: Any, outdir: str | None, *, plots: bool, as_json: bool, quiet: bool = False) -> None:
    """After Ctrl-C/SIGTERM: write the finished runs' report (atomically, marked incomplete) and say so."""
    if report is None:
        return
    from contin.accuracy import _clean, write_outputs

    what = report.incomplete
    if not report.runs and not report.adaptive:
        echo_err(f"note: {what}; nothing to save")
        return
    if as_json:
        echo_json(_clean(report.to_json()))
    written = write_outputs(report, outdir, plots=plots) if outdir is not None else []
    shown = not quiet and bool(report.rows)
    if shown:  # the finished runs' table, as a complete run shows it
        _show(report, [])
    if outdir is None:
        echo_err(f"note: {what}; " + ("their rows are shown above; no file is written (no -o DIR)" if shown
                                      else "they are not saved (no -o DIR)"))
        return
    echo_err(f"note: {what}; their rows are saved in {written[0]} (marked incomplete, reference "
             f"{report.reference_from})")


def _show(report: Any, written: list[Any]) -> None:
    """The tables of ``report`` and the files written, on stderr."""
    from contin.accuracy import recommend

    import math

    def cell(v: float, digits: int) -> str:
        """'-' where a value is undefined (the reference's own error, the order of a first grid, memory
        not measured): the table said 'nan' there (qa18); the CSV and JSON keep NaN / null."""
        return "-" if isinstance(v, float) and math.isnan(v) else fmt(v, digits)

    rows = [(r.key, r.method, r.grid, cell(r.value, 13), cell(r.error, 2), cell(r.order, 3), f"{r.cpu:.3f}",
             f"{r.wall:.3f}", r.newton_iterations, cell(r.peak_memory_mb, 3)) for r in report.rows]
    echo_err(table(rows, ("key point", "method", "N", "value", "rel.error", "order", "cpu s", "wall s",
                          "newton", "peak MB")))
    echo_err(f"reference: {report.reference_from}")
    for r in report.runs:
        if r.failed:
            echo_err(f"failed: {r.method} N={r.grid}: {r.failed}")
    rec = [(f"{x['target']:.0e}", x["method"] or "-", x["grid"] or "-",
            fmt(x["cpu"], 3) if x["method"] else "-", fmt(x["worst_error"], 2) if x["method"] else "not reached")
           for x in recommend(report)]
    echo_err(table(rec, ("budget", "method", "N", "cpu s", "worst error")))
    if report.adaptive:
        rows = [(f"{a.tol:.0e}", a.request, fmt(a.worst_error, 2), a.worst_key, "yes" if a.met else "NO",
                 "-" if a.grids is None else f"{a.grids[0]}..{a.grids[1]}", f"{a.cpu:.3f}",
                 f"{a.fixed_method} {a.fixed_grid}" if a.fixed_method else "none",
                 fmt(a.fixed_cpu, 3) if a.fixed_method else "-", fmt(a.ratio, 3) if a.fixed_method else "-")
                for a in report.adaptive]
        echo_err(table(rows, ("tol", "asked of", "achieved", "worst key point", "met", "grids", "cpu s",
                              "cheapest fixed", "its cpu s", "ratio")))
    for path in written:
        echo_err(f"wrote {path}")
