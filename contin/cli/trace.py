"""``contin trace SCENE``: run a scene, store it in HDF5, summarise its special points."""

from __future__ import annotations

import sys
import time
from typing import Any

import click

from contin.cli._base import (
    EXIT_INCOMPLETE,
    echo_err,
    echo_json,
    engine_option,
    error_line,
    fail,
    fmt,
    main,
    parse_settings,
    resolution_guard,
    resolution_tol_option,
    special_points_table,
)


class _Progress:
    """Status lines on stderr: one overwritten line on a terminal, nothing otherwise."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.t0 = time.perf_counter()
        self._open = False

    def status(self, message: str) -> None:
        if self.enabled:
            text = f"[{time.perf_counter() - self.t0:7.1f}s] {message}"
            sys.stderr.write("\r\x1b[K" + text[:200])
            sys.stderr.flush()
            self._open = True

    def line(self, message: str) -> None:
        if self.enabled:
            self.done()
            echo_err(f"[{time.perf_counter() - self.t0:7.1f}s] {message}")

    def done(self) -> None:
        if self._open:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
            self._open = False


def _parse_kx(text: str | None) -> tuple[float, ...]:
    if not text:
        return ()
    try:
        return tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {text!r}", param_hint="'--kx'") from None


def _stability_after_run(sc: Any, request: Any, result: Any, progress: _Progress, quiet: bool) -> None:
    """The stability pass the scene left undone, through ``sc.problem_factory``.

    Branches the scene left without stability columns get :meth:`SceneRequest.run_stability`
    (k_x = k_z = 0, audit, and the extra ``--kx`` columns); a scene that computed stability
    itself is trusted with the extra wavenumbers too.  Fold curves and other multi-parameter
    branches are skipped (their states are not states of the problem).  Failures become
    warnings: the traced branches are never lost to a stability problem.
    """
    def missing(b: Any) -> bool:
        return len(b.free) == 1 and len(b) > 0 and b.n_unstable is None

    todo = [b for b in result.branches if missing(b)]
    if not todo:
        return
    if sc.problem_factory is None:
        if not quiet and any(b.n_unstable is None for b in todo):
            echo_err(f"note: scene {sc.name!r} computed no stability and has no problem_factory; "
                     "branches are stored without stability")
        return
    try:
        problem = sc.problem_factory(result.parameters, result.discretization)
    except Exception as exc:  # noqa: BLE001 -- report, keep the branches
        echo_err(f"warning: stability skipped: cannot rebuild the problem ({error_line(exc)})")
        return
    for b in todo:
        progress.status(f"stability of branch {b.id} ({len(b)} points)")
        try:
            request.run_stability(problem, b, result.parameters)
        except Exception as exc:  # noqa: BLE001
            echo_err(f"warning: stability of branch {b.id} failed: {error_line(exc)}")
    progress.done()


def stability_summary(branch: Any) -> dict[str, Any] | None:
    """{kx, kz, n_unstable: [...], audit: [...]} of a branch, None without stability."""
    if branch.n_unstable is None:
        return None
    kx, kz = branch.stability_k or (0.0, 0.0)
    return {"kx": kx, "kz": kz, "n_unstable": branch.n_unstable, "audit": stability_messages(branch)}


def stability_messages(branch: Any) -> list[str]:
    """The audit messages of the stability pass (not the rejected-step diagnostics that
    :mod:`contin.continuation` stores as ``"step N: ..."``); a ``"stability audit: "`` prefix,
    which some scenes add, is removed."""
    return [m.removeprefix("stability audit: ") for m in branch.audit if not m.startswith("step ")]


@main.command("trace")
@click.argument("scene")
@click.option("-s", "--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set a scene parameter (repeatable); values are numbers, 'inf', or words (e.g. chi=cs).")
@click.option("--method", default=None, help="Discretization method (e.g. cheb, fd2, fd4, fd6).")
@click.option("--grid", type=click.IntRange(min=2), default=None, help="Number of grid intervals.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, writable=True), default=None,
              help="HDF5 file to write (checkpointed after every finished branch).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
@click.option("--no-stability", is_flag=True, help="Skip the linear-stability pass.")
@click.option("--kx", default=None, metavar="LIST", help="Extra streamwise wavenumbers for stability, e.g. 0.5,1.")
@click.option("--max-steps", type=click.IntRange(min=1), default=None, help="Maximum continuation steps per branch.")
@click.option("--ds", type=click.FloatRange(min=0, min_open=True), default=None, help="Initial arclength step.")
@click.option("--ds-max", type=click.FloatRange(min=0, min_open=True), default=None, help="Largest arclength step.")
@resolution_tol_option
@click.option("--tol", type=click.FloatRange(min=0, min_open=True, max=1, max_open=True), default=None, metavar="REL",
              help="Adaptive resolution: largest estimated relative discretization error of a point; the grid is "
                   "chosen and changed along each branch to meet it [default for adaptive scenes without --grid: "
                   "the scene's (gPCF 3e-5, the resolution guard's; demos 1e-10); with --grid and no --tol the "
                   "grid is fixed].")
@click.option("--max-grid", type=click.IntRange(min=4), default=None,
              help="Largest grid adaptive resolution may use [default 512]; past it a branch ends with MX.")
@engine_option
@click.option("--resume", type=click.Path(exists=True, dir_okay=False), default=None,
              help="Reuse the finished branches of an interrupted run (default -o: this file).")
@click.option("-q", "--quiet", is_flag=True, help="No progress lines and no summary table.")
def trace_command(scene: str, settings: tuple[str, ...], method: str | None, grid: int | None,
                  output: str | None, as_json: bool, no_stability: bool, kx: str | None,
                  max_steps: int | None, ds: float | None, ds_max: float | None,
                  resolution_tol: str | None, tol: float | None, max_grid: int | None, engine: str,
                  resume: str | None, quiet: bool) -> None:
    """Trace the branches of SCENE and report its special points.

    Human output (progress, summary table) goes to stderr; --json prints one JSON document
    to stdout.  Exit code 3 when the run finished but a branch ended with MX.

    Scenes marked adaptive choose their grid to meet --tol (the scene's default when no --grid
    is given; --grid alone fixes the grid, --grid with --tol is the start grid).
    """
    import contin.scene as scene_mod
    from contin import io
    from contin.jsonout import run_document

    params = parse_settings(settings)
    kx_values = _parse_kx(kx)
    guard, rtol = resolution_guard(resolution_tol)  # every trace of the run, also those a scene sets up itself
    sc = scene_mod.get_scene(scene)
    if sc.defaults:
        unknown = [n for n in params if n not in sc.defaults]
        if unknown:
            raise scene_mod.SceneError(
                f"unknown parameter {unknown[0]!r} for scene {scene!r}; its parameters are {', '.join(sc.defaults)}")
    step_overrides = {k: v for k, v in (("ds", ds), ("ds_max", ds_max), ("max_steps", max_steps)) if v is not None}
    overrides = dict(step_overrides)
    if resolution_tol is not None:
        overrides["resolution_tol"] = rtol
    if (tol is not None or max_grid is not None) and not sc.adaptive:
        fail(f"scene {scene!r} has no adaptive resolution (--tol, --max-grid); choose its grid with --grid")
    if sc.adaptive and (tol is not None or grid is None):
        overrides["tol"] = tol if tol is not None else sc.default_tol
        if max_grid is not None:
            if grid is not None and grid > max_grid:
                fail(f"--grid {grid} exceeds --max-grid {max_grid}")
            overrides["max_grid"] = max_grid

    completed: dict[str, Any] = {}
    if resume is not None:
        old, meta = io.load(resume)
        if meta["scene"] and meta["scene"] != scene:
            fail(f"{resume!r} holds a run of scene {meta['scene']!r}, not {scene!r}")
        for name, value in params.items():
            before = meta["parameters"].get(name)
            if before is not None and before != value:
                fail(f"{resume!r} was computed with {name}={fmt(before)}, not {fmt(value)}; resume with the same parameters")
        completed = {b.id: b for b in old}
        if output is None:
            output = resume

    progress = _Progress(enabled=not quiet and sys.stderr.isatty())
    writer = None
    if output is not None:  # checked before any computing
        writer = io.H5Writer(output, scene=scene, parameters={**sc.defaults, **params},
                             discretization={k: v for k, v in (("method", method), ("grid", grid)) if v is not None},
                             options=overrides, branches=completed.values(),
                             diagram_x=sc.x, diagram_y=sc.y)

    def on_branch(branch: Any) -> None:
        if writer is not None:
            writer.add_branch(branch)
        progress.line(f"branch {branch.id} ({branch.kind}{', from ' + branch.parent if branch.parent else ''}): "
                      f"{len(branch)} points, {branch.status} {branch.message}".rstrip())

    request = scene_mod.SceneRequest(
        params=params, method=method, grid=grid, stability=not no_stability, kx=kx_values,
        completed=completed, on_branch=on_branch, progress=progress.status, overrides=overrides, engine=engine)
    try:
        with guard:
            result = sc.run(request)
    except BaseException:
        progress.done()
        if writer is not None and writer.publishes:  # the published file stays (complete=False)
            echo_err(f"note: finished branches are saved in {writer.path} (continue with --resume {writer.path})")
        raise
    progress.done()
    if request.stability:
        _stability_after_run(sc, request, result, progress, quiet)

    if step_overrides and not request.resolved_options:
        echo_err(f"warning: scene {scene!r} does not apply --ds/--ds-max/--max-steps; they were ignored")
    options: Any = request.resolved_options[0] if request.resolved_options else (
        {"overrides": overrides, "note": "options chosen inside the scene"} if overrides else {})
    if writer is not None:
        writer.update(parameters=result.parameters, discretization=result.discretization, options=options,
                      notes=list(result.notes), extra=dict(result.extra), y=result.y, profiles=result.profiles)
        writer.set_branches(result.branches)
        writer.close()

    if as_json:
        echo_json(run_document(scene=scene, parameters=result.parameters, discretization=result.discretization,
                               branches=result.branches, notes=result.notes, extra=result.extra,
                               output=None if writer is None else str(writer.path),
                               stability={b.id: stability_summary(b) for b in result.branches}))
    if not quiet:
        echo_err(special_points_table(result.branches))
        for note in result.notes:
            echo_err(f"note: {note}")
        for b in result.branches:
            for message in stability_messages(b):
                if not any(message in note for note in result.notes):  # the scene reported it already
                    echo_err(f"audit: branch {b.id}: {message}")
        if writer is not None:
            echo_err(f"wrote {writer.path}")
    failed = [b for b in result.branches if b.status == "MX"]
    for b in failed:
        echo_err(f"warning: branch {b.id} ended with MX: {error_line(ValueError(b.message or 'failure'))}")
    if failed:
        raise click.exceptions.Exit(EXIT_INCOMPLETE)
