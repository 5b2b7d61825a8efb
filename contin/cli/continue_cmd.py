"""``contin continue FILE.h5 --from LABEL --free NAME``: two-parameter continuation from a
labelled point of any stored run (AUTO's restart at a label with two free parameters).

The problem is rebuilt with the scene's ``problem_factory`` (as ``contin stability`` does);
the point (LP, BP; HB once Hopf curves exist) is continued in (the branch's parameter, NAME)
by :func:`contin.twoparam.continue_point`.  The curve is written to ``-o OUT.h5`` (same scene,
parameters and discretization as FILE; its states are the augmented (u, phi, NAME)), with
``XT`` points at the extrema of NAME (isola birth/death when NAME is an imperfection) and
``LP`` points at the extrema of the first parameter.
"""

from __future__ import annotations

import math
from typing import Any

import click

from contin.cli._base import echo_err, echo_json, fail, fmt, main, special_points_table


def parse_bounds(items: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """``NAME=LO:HI`` items -> {name: (lo, hi)}; LO, HI finite (or -inf/inf), LO < HI."""
    out = {}
    for item in items:
        name, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        try:
            a, b = float(lo), float(hi)
        except ValueError:
            a = b = math.nan
        if not (sep and sep2 and name.strip()) or math.isnan(a) or math.isnan(b) or not a < b:
            fail(f"--bounds needs NAME=LO:HI with numbers LO < HI (e.g. G=0:1e-4), got {item!r}")
        out[name.strip()] = (a, b)
    return out


@main.command("continue")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--from", "label", required=True, metavar="LABEL", help="Special point to start from (LP1, BP2, ...).")
@click.option("--free", "second", required=True, metavar="NAME", help="Second free parameter.")
@click.option("--branch", "branch_id", default=None, metavar="ID", help="Branch of the point (when the label is not unique).")
@click.option("--bounds", multiple=True, metavar="NAME=LO:HI",
              help="Bounds of either parameter (repeatable) [default: the run's bounds of the first].")
@click.option("--max-steps", type=click.IntRange(min=1, max=1_000_000), default=200, show_default=True,
              help="Steps per direction.")
@click.option("--ds", type=float, default=None, help="First step (arclength) [default: the run's].")
@click.option("--ds-max", type=float, default=None, help="Largest step [default: the run's].")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, help="HDF5 file of the curve.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def continue_command(file: str, label: str, second: str, branch_id: str | None, bounds: tuple[str, ...],
                     max_steps: int, ds: float | None, ds_max: float | None, output: str | None, as_json: bool) -> None:
    """Continue the point LABEL of FILE in two parameters (the branch's and --free NAME)."""
    import dataclasses

    from contin import io
    from contin.jsonout import run_document
    from contin.restart import find_point, rebuild_problem

    for name, v in (("--ds", ds), ("--ds-max", ds_max)):
        if v is not None and not (math.isfinite(v) and v > 0):
            fail(f"{name} must be a finite number > 0, got {v}")
    if ds is not None and ds_max is not None and ds > ds_max:
        fail(f"--ds ({ds:g}) must not exceed --ds-max ({ds_max:g})")
    box = parse_bounds(bounds)
    if output is not None:  # checked before any computing
        from contin.cli._runctl import check_hdf5_output

        check_hdf5_output(output)  # -o x.png wrote HDF5 into a .png
        io.check_writable(output)
    branches, meta = io.load(file)
    branch, point = find_point(branches, label, branch_id, repr(file))
    first = branch.parameter
    unknown = [n for n in box if n not in (first, second)]
    if unknown:
        fail(f"--bounds names {unknown[0]!r}; only the two free parameters {first!r} and {second!r} can be bounded")
    try:
        options = io.options_from_dict(meta.get("options") or {})
    except (TypeError, ValueError):  # options chosen inside the scene (not stored as a full set)
        from contin.options import ContinuationOptions

        options = ContinuationOptions()
    step = options.step
    new_ds = ds if ds is not None else abs(step.ds)
    new_max = ds_max if ds_max is not None else max(step.ds_max, new_ds)
    step = dataclasses.replace(step, ds=new_ds, ds_max=new_max, ds_min=min(step.ds_min, new_ds))
    run_bounds = {k: v for k, v in options.bounds.items() if k == first}
    run_bounds.update(box)
    options = dataclasses.replace(options, step=step, bounds=run_bounds, max_steps=max_steps)
    problem = rebuild_problem({**meta, "path": file})
    size = getattr(problem, "size", None)
    if isinstance(size, int) and point.state is not None and size != len(point.state):
        fail(f"the state of {point.name} has {len(point.state)} entries but the problem rebuilt from {file} "
             f"has {size} unknowns")
    from contin.twoparam import continue_point

    curve = continue_point(problem, branch, point, second, options)
    if output is not None:
        io.write(output, [curve], scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                 discretization=meta.get("discretization", {}), options=options,
                 notes=[f"{point.type} curve from {point.name} of branch {branch.id} in {file}, free {first}, {second}"],
                 extra={"source": file, "from": point.name, "branch": branch.id, "free": [first, second]},
                 diagram_x=first, diagram_y=meta.get("diagram_y") or "phi")
    if as_json:
        doc = run_document(scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                           discretization=meta.get("discretization", {}), branches=[curve],
                           notes=[], extra={"from": point.name, "branch": branch.id, "free": [first, second]},
                           output=output, stability={})
        echo_json(doc)
    echo_err(f"{point.type} curve from {point.name} (branch {branch.id}, {first} = {fmt(point.params[first])}, "
             f"{second} = {fmt(point.params[second])}): {len(curve)} points, {curve.status} {curve.message}")
    echo_err(special_points_table([curve]))
    if output is not None:
        echo_err(f"wrote {output}")
    if curve.status == "MX":
        from contin.cli._base import EXIT_INCOMPLETE

        echo_err(f"warning: the curve ended with MX: {curve.message}")
        raise click.exceptions.Exit(EXIT_INCOMPLETE)
