"""``contin sweep SWEEP.toml -o DIR``: run a parameter sweep (see :mod:`contin.sweep`)."""

from __future__ import annotations

import click

from contin.cli._base import EXIT_INCOMPLETE, echo_err, echo_json, main


@main.command("sweep")
@click.argument("sweep_file", metavar="SWEEP.toml", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Output directory (task files in DIR/tasks, summary in DIR/summary.h5 and .json).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Worker processes (default and at most: the CPUs this process may use; a larger N is "
                   "capped, with a note); Dask workers with --scheduler local-dask.")
@click.option("--scheduler", default=None, metavar="ADDRESS|local-dask",
              help="Run on Dask distributed: a scheduler address tcp://HOST:PORT, or local-dask for a "
                   "LocalCluster (needs pip install -e '.[dask]').")
@click.option("--retry-failed", is_flag=True, help="Recompute tasks that failed (MX or error) in an earlier run.")
@click.option("-q", "--quiet", is_flag=True, help="No progress lines on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as one JSON document to stdout.")
def sweep_command(sweep_file: str, outdir: str, jobs: int | None, scheduler: str | None,
                  retry_failed: bool, quiet: bool, as_json: bool) -> None:
    """Run every grid point of SWEEP.toml as an independent scene run.

    Resumable: tasks whose files exist in DIR/tasks are skipped, so rerunning after an
    interruption computes only the unfinished tasks.  A failing task is recorded with its
    reason and does not stop the sweep.  Exit code 0 if every task succeeded, 3 if some
    failed (see DIR/summary.json), 1 for a bad sweep file or setting.

    \b
    Example:
      contin sweep results/sweeps/demo_bratu.toml -o out/bratu -j 4
    """
    from contin.cli._runctl import EXIT_TERMINATED, Progress, Terminated, sigterm_as_interrupt
    from contin.sweep import load_sweep, open_executor, run_sweep, worker_count

    spec = load_sweep(sweep_file)
    if scheduler is None or scheduler == "local-dask":  # a remote scheduler has its own workers
        jobs, capped = worker_count(jobs)
        if capped and not quiet:
            echo_err(capped)
    beat = Progress(enabled=not quiet)  # heartbeat between task lines on a non-terminal

    def progress(line: str) -> None:
        echo_err(line)
        beat.note(line)

    from contin.sweep import other_sweep

    replaced = other_sweep(outdir, spec)
    if replaced is not None:  # also with -q: a summary is lost
        echo_err(f"warning: {replaced}")
    try:
        with sigterm_as_interrupt(), open_executor(scheduler, jobs) as executor:
            summary = run_sweep(spec, outdir, executor=executor, jobs=jobs, progress=None if quiet else progress,
                                retry_failed=retry_failed)
    except Terminated:  # like Ctrl-C: the summary of the finished tasks is written; rerun to resume
        echo_err(f"Error: terminated by SIGTERM; finished tasks are kept in {outdir} (rerun the same command to resume)")
        raise SystemExit(EXIT_TERMINATED) from None
    finally:
        beat.close()
    c = summary.counts()
    failed = c["MX"] + c["error"] + c["lost"]
    for name in summary.missing_extra():  # it was null in every task, without a word (qa18)
        echo_err(f"warning: record = extra.{name}: no task's extra results hold {name!r} (null in every task); "
                 f"the scene's extra names are in any task file (contin info --json)")
    if not quiet:
        parts = [f"{c[s]} {s}" for s in ("ok", "MX", "error", "lost") if c[s] or s == "ok"]
        echo_err(f"sweep: {c['tasks']} tasks ({', '.join(parts)}; {c['cached']} from earlier runs) "
                 f"-> {summary.outdir / 'summary.h5'}")
    if as_json:
        echo_json(summary.to_dict())
    if failed:
        raise SystemExit(EXIT_INCOMPLETE)
