"""``contin verify FILE.h5``: the achieved error of every stored point, against a finer grid.

The problem is rebuilt with the scene's ``problem_factory`` (as ``contin stability``); each point
of each one-parameter branch is carried onto a grid ``--factor`` times its own and re-solved
there at its parameters (:func:`contin.verify.verify_branch`).  Exit 0 when every point is within
tol, :data:`EXIT_INACCURATE` (4) with one line per failing branch when some are not (or could not
be checked).
"""

from __future__ import annotations

import math
from typing import Any

import click

from contin.cli._base import echo_err, echo_json, fail, fmt, main, table

#: exit code when some stored point's achieved error exceeds tol (or could not be checked)
EXIT_INACCURATE = 4


def _run_tol(meta: dict[str, Any]) -> float:
    """The tol the run promised: its adaptive tol, else its resolution guard's, else 3e-5."""
    options = meta.get("options") or {}
    adapt = options.get("adapt") if isinstance(options, dict) else None
    for value in ((adapt or {}).get("tol") if isinstance(adapt, dict) else None,
                  options.get("resolution_tol") if isinstance(options, dict) else None):
        if isinstance(value, int | float) and math.isfinite(value) and value > 0:
            return float(value)
    return 3e-5


def _run_max_grid(meta: dict[str, Any]) -> int:
    adapt = (meta.get("options") or {}).get("adapt")
    value = adapt.get("max_grid") if isinstance(adapt, dict) else None
    # twice the run's largest grid: a point on it is checked too (as the tracer's two-grid check does)
    return 2 * int(value) if isinstance(value, int | float) and value >= 1 else 1024


@main.command("verify")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option("--branch", "branch_id", default=None, metavar="ID", help="Check only this branch [default: all].")
@click.option("--factor", type=float, default=2.0, help="Fine grid = FACTOR x each point's grid (> 1).")
@click.option("--tol", type=float, default=None,
              help="Largest acceptable relative error [default: the run's adaptive tol, else its resolution tol].")
@click.option("--max-grid", type=int, default=None, help="Largest fine grid [default: twice the run's max_grid, else 1024].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
@click.option("-q", "--quiet", is_flag=True, help="Only the summary lines.")
def verify_command(file: str, branch_id: str | None, factor: float, tol: float | None, max_grid: int | None,
                   as_json: bool, quiet: bool) -> None:
    """Re-solve every stored point of FILE on a finer grid and report its achieved relative error.

    The adaptive tracer checks an estimate of each state's representation; next to a branch
    point or fold the solution's error can exceed it.  Exit codes: 0 all points within tol,
    4 some points exceed tol or could not be checked, 1 bad input.
    """
    from contin import io
    from contin.verify import verify_branch

    if not (math.isfinite(factor) and factor > 1):
        fail(f"--factor must be a finite number > 1, got {factor}")
    if tol is not None and not (math.isfinite(tol) and tol > 0):
        fail(f"--tol must be a finite number > 0, got {tol}")
    if max_grid is not None and max_grid < 1:
        fail(f"--max-grid must be at least 1, got {max_grid}")
    branches, meta = io.load(file)
    ids = [b.id for b in branches]
    if branch_id is not None:
        if branch_id not in ids:
            fail(f"no branch {branch_id!r} in {file}; branches: {', '.join(ids) or 'none'}")
        branches = [branches[ids.index(branch_id)]]
        if len(branches[0].free) != 1:
            fail(f"branch {branch_id} of {file} has free parameters {', '.join(branches[0].free)}: "
                 "only one-parameter branches can be re-solved at fixed parameters")
    orbits = [b.id for b in branches if b.kind == "periodic-orbits"]
    if orbits and len(orbits) == len(branches):  # it blamed the equilibrium's missing grid hooks
        fail(f"branch {orbits[0]} of {file} holds periodic orbits: contin verify re-solves steady states on a "
             "finer grid; an orbit's accuracy is its flow_error and floquet_error (contin info), and a finer "
             "mesh is contin continue --cycles --ntst")
    todo = [b for b in branches if len(b.free) == 1 and len(b) > 0 and b.kind != "periodic-orbits"]
    if not todo:
        fail(f"{file} has no one-parameter branch with stored points to verify")
    problem = _problem_of(meta, file)
    from contin.adapt import missing_hooks

    missing = missing_hooks(problem)
    if missing:
        fail(f"the problem of {file} ({type(problem).__name__}) cannot change its grid (it lacks "
             f"{', '.join(missing)}), so its points cannot be re-solved on a finer grid")
    tol = _run_tol(meta) if tol is None else tol
    max_grid = _run_max_grid(meta) if max_grid is None else max_grid
    params = dict(meta.get("parameters", {}))
    done_ids = {b.id for b in todo}
    skipped = [b.id for b in branches if b.id not in done_ids]
    if skipped and not quiet and not as_json:
        echo_err(f"note: skipped branches {', '.join(skipped)} (multi-parameter or empty)")

    results = []
    for b in todo:
        if not quiet and not as_json:
            echo_err(f"verifying branch {b.id} ({len(b)} points)")
        results.append(verify_branch(problem, b, params, factor=factor, tol=tol, max_grid=max_grid))

    bad = [r for r in results if not r.ok]
    if as_json:
        echo_json({"file": file, "tol": tol, "factor": factor, "ok": not bad, "branches": [
            {"branch": r.branch, "checked": len(r.checked), "exceeding": [p.index for p in r.exceeding],
             "unchecked": [{"index": p.index, "reason": p.message} for p in r.unchecked],
             "singular": [{"index": p.index, "reason": p.message} for p in r.singular],
             "max_error": r.max_error, "points": [
                 {"index": p.index, "params": dict(p.params), "grid": p.grid, "fine_grid": p.fine_grid,
                  "estimate": p.estimate, "error": p.error, "observable_error": p.observable_error}
                 for p in r.points]} for r in results]})
    else:
        # no point checked: '-' (the column said 'nan' beside FAIL; qa18)
        rows = [(r.branch, len(r.points), len(r.checked), fmt(r.max_error, 3) if r.checked else "-", len(r.exceeding),
                 len(r.unchecked),
                 len(r.singular), "ok" if r.ok else "FAIL") for r in results]
        click.echo(f"{file}: stored points re-solved on {fmt(factor, 3)}x finer grids, tol {fmt(tol, 3)}")
        click.echo(table(rows, ("branch", "points", "checked", "max error", "> tol", "unchecked", "singular", "")))
        if not quiet:
            worst = [(r.branch, p.index, *(fmt(v, 6) for k, v in p.params.items() if k in (_free(r, todo))),
                      p.grid, p.fine_grid, fmt(p.estimate, 2), fmt(p.error, 2), fmt(p.observable_error, 2))
                     for r in results for p in r.worst(3) if p.error > 0]
            if worst:
                click.echo("worst points:")
                click.echo(table(worst, ("branch", "index", "at", "grid", "fine grid", "estimate", "error",
                                         "order-parameter error")))
    if not quiet and not as_json:
        for r in results:
            for p in r.singular:
                echo_err(f"note: branch {r.branch} point {p.index}: {p.message}; its position is checked by "
                         "the locator (special_tol), not here")
    for r in bad:
        parts = []
        if r.exceeding:
            worst = r.worst(1)[0]
            where = ", ".join(f"{k} = {fmt(worst.params[k], 6)}" for k in _free(r, todo))
            parts.append(f"{len(r.exceeding)} of {len(r.checked)} checked points exceed tol {fmt(tol, 3)} "
                         f"(max error {fmt(r.max_error, 2)} at point {worst.index}, {where}, grid {worst.grid}, "
                         f"estimate {fmt(worst.estimate, 2)})")
        if r.unchecked:
            parts.append(f"{len(r.unchecked)} points could not be checked ({r.unchecked[0].message})")
        echo_err(f"inaccurate: branch {r.branch}: " + "; ".join(parts))
    if bad:
        raise click.exceptions.Exit(EXIT_INACCURATE)


def _problem_of(meta: dict[str, Any], file: str) -> Any:
    """The run's problem: the scene's ``problem_factory`` (:func:`contin.restart.rebuild_problem`),
    else the problem of the scene's automatic-diagram start built for the file's parameters and
    discretization (bratu, allen-cahn: scenes without a factory, so trace adds no stability pass)."""
    from contin.restart import rebuild_problem

    try:
        return rebuild_problem({**meta, "path": file})
    except ValueError as exc:
        first = exc
    from contin.scene import SceneRequest, get_scene

    try:
        scene = get_scene(str(meta.get("scene") or ""))
    except ValueError:
        scene = None
    if scene is None or scene.start is None:
        fail(str(first))
    disc = dict(meta.get("discretization") or {})
    params = {k: v for k, v in dict(meta.get("parameters") or {}).items()
              if isinstance(v, int | float) and not isinstance(v, bool)}
    try:
        request = SceneRequest(params=params, method=disc.get("method"),
                               grid=int(disc["intervals"]) if "intervals" in disc else None, stability=False)
        return scene.start(request).problem
    except Exception as exc:  # noqa: BLE001 -- one line: the file cannot be re-solved
        fail(f"{first}; its automatic-diagram start failed too ({exc})")


def _free(check: Any, branches: list[Any]) -> tuple[str, ...]:
    """The free parameter of the checked branch (the point's 'at')."""
    return next(tuple(b.free) for b in branches if str(b.id) == check.branch)
