"""``contin continue FILE.h5 --from LABEL --free NAME``: two-parameter continuation from a
labelled point of any stored run (AUTO's restart at a label with two free parameters).

The problem is rebuilt with the scene's ``problem_factory`` (as ``contin stability`` does);
the point (LP, BP; HB once Hopf curves exist) is continued in (the branch's parameter, NAME)
by :func:`contin.twoparam.continue_point`.  The curve is written to ``-o OUT.h5`` (same scene,
parameters and discretization as FILE; its states are the augmented (u, phi, NAME)), with
``XT`` points at the extrema of NAME (isola birth/death when NAME is an imperfection) and
``LP`` points at the extrema of the first parameter.

``--tol REL [--max-grid N]`` (problems with the grid hooks ``grid_size``, ``with_grid``,
``transfer``, ``error_estimate``): the curve starts on the point's own grid (``SpecialPoint.grid``
of an adaptive run's file, else the file's grid; a point that misses REL there is carried onto the
first finer grid that meets it), the resolution guard is set to REL for the
curve, and where it stops a half of the curve that half continues on a finer grid from its last
accepted point (segment-wise regridding, :class:`contin.foldcurve.SegmentRegrid`), up to N; the
file keeps every point's grid.  Every point also passes the two-grid check of its augmented solve
(:func:`contin.foldcurve.augmented_two_grid_error`, the analogue of a trace's solve check; a point
that misses REL there is recomputed on a finer grid); ``--no-solve-check`` switches it off.  Fold curves only (LP, and a BP that NAME unfolds): for Hopf and
BP curves --tol is an error.  Without --tol nothing changes: the fixed grid of the file and the
run's guard.

From an LPC of a file of orbits (``--from LPC1 --free NAME [--ntst N] [--ncol M]``): the curve of
folds of cycles in (the orbits' parameter, NAME) (``contin.lpccurve``, ``contin.cli.cycles_cmd``).

``--cycles`` (no ``--free``): from an HB the periodic orbits born there, from a PD of a file of
orbits the period-doubled ones, from a BP of one the bifurcating cycles (``--other-half``: the other
half), in the branch's parameter (``contin.cli.cycles_cmd``,
``contin.cycles``).
"""

from __future__ import annotations

import math
from typing import Any

import click

from contin.cli._base import echo_err, echo_json, fail, fmt, main, special_points_table
from contin.limits import MIN_MAX_GRID


def _what(point: Any, curve: Any) -> str:
    """'LP curve', 'HB curve', ...; from a BT, ZH or HH the curve it starts ('fold curve', 'Hopf curve')."""
    if point.type in ("BT", "ZH", "HH"):
        return {"fold-curve": "fold curve", "hopf-curve": "Hopf curve"}.get(curve.kind, "curve")
    return f"{point.type} curve"


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


def _refuse_own_input(file: str, output: str) -> None:
    """``-o`` naming the input file: the curve file would replace the run it comes from."""
    import os

    try:
        same = os.path.samefile(file, output)
    except OSError:  # the output does not exist yet
        same = False
    if same:
        fail(f"-o {output} is the input file {file}: the curve would replace the run it starts from; "
             "choose another output")


@main.command("continue")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--from", "label", required=True, metavar="LABEL", help="Special point to start from (LP1, BP2, ...).")
@click.option("--free", "second", default=None, metavar="NAME",
              help="Second free parameter (required without --cycles).")
@click.option("--branch", "branch_id", default=None, metavar="ID", help="Branch of the point (when the label is not unique).")
@click.option("--bounds", multiple=True, metavar="NAME=LO:HI",
              help="Bounds of either parameter (repeatable) [default: the run's bounds of the first].")
@click.option("--max-steps", type=click.IntRange(min=1, max=1_000_000), default=200, show_default=True,
              help="Steps per direction.")
@click.option("--ds", type=float, default=None, help="First step (arclength) [default: the run's].")
@click.option("--ds-max", type=float, default=None, help="Largest step [default: the run's].")
@click.option("--tol", type=click.FloatRange(min=0, min_open=True, max=1, max_open=True), default=None, metavar="REL",
              help="Adaptive grids: the resolution guard's tol for the curve (largest estimated relative error of a "
                   "point); where it stops the curve, the curve continues on a finer grid from its last point "
                   "(segment-wise). Starts on the point's own grid (finer if the point misses REL there). Fold curves only "
                   "(LP; BP unfolded by NAME).")
@click.option("--max-grid", type=click.IntRange(min=MIN_MAX_GRID), default=None, metavar="N",
              help="With --tol: the largest grid [default: the run's adaptive max_grid, else 512]; past it the "
                   "curve ends with MX.")
@click.option("--no-solve-check", "no_solve_check", is_flag=True, default=False,
              help="With --tol: accept a point of the curve by the resolution guard alone, without the two-grid "
                   "check of its augmented solve (AdaptOptions.solve_check = False; faster, but points next to a "
                   "fold can miss REL).")
@click.option("--cycles", is_flag=True, default=False,
              help="From an HB: the periodic orbits born there, in the branch's parameter (no --free); from a "
                   "PD of a file of orbits: the period-doubled orbits; from a BP of a file of orbits: the "
                   "bifurcating cycles.")
@click.option("--ntst", type=click.IntRange(min=2, max=10_000), default=None, metavar="N",
              help="With --cycles, or from an LPC (--free): mesh intervals of the orbits [default: 20; from an "
                   "LPC its orbit's].")
@click.option("--ncol", type=click.IntRange(min=1, max=7), default=None, metavar="M",
              help="With --cycles, or from an LPC (--free): Gauss collocation points per interval [default: 4; "
                   "from an LPC its orbit's].")
@click.option("--amplitude", type=float, default=None, metavar="EPS",
              help="With --cycles from an HB or a PD: amplitude of the first orbit [default: 1e-2 max(1, |u_H|)].")
@click.option("--uniform-mesh", is_flag=True, default=False,
              help="With --cycles: keep the uniform mesh (no adaptation every 5 steps).")
@click.option("--other-half", "other_half", is_flag=True, default=False,
              help="With --cycles from a BP of a file of orbits: the other half of the bifurcating branch "
                   "(-tau instead of +tau).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, help="HDF5 file of the curve.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def continue_command(file: str, label: str, second: str | None, branch_id: str | None, bounds: tuple[str, ...],
                     max_steps: int, ds: float | None, ds_max: float | None, tol: float | None, max_grid: int | None,
                     no_solve_check: bool, cycles: bool, ntst: int | None, ncol: int | None, amplitude: float | None,
                     uniform_mesh: bool, other_half: bool, output: str | None, as_json: bool) -> None:
    """Continue the point LABEL of FILE in two parameters (the branch's and --free NAME), or with
    --cycles the periodic orbits born at the Hopf point LABEL (in the branch's parameter)."""
    import dataclasses

    from contin import io
    from contin.jsonout import run_document
    from contin.restart import find_point, rebuild_problem

    for name, v in (("--ds", ds), ("--ds-max", ds_max)):
        if v is not None and not (math.isfinite(v) and v > 0):
            fail(f"{name} must be a finite number > 0, got {v}")
    if ds is not None and ds_max is not None and ds > ds_max:
        fail(f"--ds ({ds:g}) must not exceed --ds-max ({ds_max:g})")
    if max_grid is not None and tol is None:
        fail("--max-grid needs --tol (the grid is fixed without it)")
    if no_solve_check and tol is None:
        fail("--no-solve-check needs --tol (the check belongs to adaptive grids)")
    from contin.cli.cycles_cmd import check_cycle_flags

    # --ntst / --ncol also set the orbits of an LPC curve (--from LPCk --free NAME): checked once the point is known
    lpc_mesh = (ntst, ncol) if not cycles and second is not None else (None, None)
    cycle_options = check_cycle_flags(cycles, second, tol, *((None, None) if lpc_mesh[0] or lpc_mesh[1] else (ntst, ncol)),
                                      amplitude, uniform_mesh)
    if not cycles and second is None:
        fail("Missing option '--free' (the second free parameter; or --cycles from an HB)")
    box = parse_bounds(bounds)
    if output is not None:  # checked before any computing
        from contin.cli._runctl import check_hdf5_output

        check_hdf5_output(output)  # -o x.png wrote HDF5 into a .png
        io.check_writable(output)
        _refuse_own_input(file, output)
        from contin.atomic import OutputLock

        # one writer per output, as for trace: a curve written into a file another contin run is
        # writing was silently replaced by (or replaced) that run's next checkpoint.  Released
        # when the command ends (or by the kernel, when the process dies).
        click.get_current_context().call_on_close(OutputLock(output).acquire().release)
    branches, meta = io.load(file)
    branch, point = find_point(branches, label, branch_id, repr(file))
    # the period-doubled orbits at a PD, the bifurcating cycles at a BP of a file of orbits
    doubling = cycles and point.type in ("PD", "BP") and branch.kind == "periodic-orbits"
    # the curve of folds of cycles through an LPC in two parameters (contin.lpccurve)
    lpc = not cycles and point.type == "LPC" and branch.kind == "periodic-orbits"
    if (lpc_mesh[0] or lpc_mesh[1]) and not lpc:
        fail(f"{'--ntst' if lpc_mesh[0] else '--ncol'} needs --cycles, or an LPC start (--from LPCk --free NAME): it "
             "sets the collocation of periodic orbits")
    if lpc and tol is not None:
        fail("--tol is for fold curves on adaptive grids; for an LPC curve refine the orbits' mesh with --ntst")
    if branch.kind == "periodic-orbits" and not doubling and not lpc:  # 'too many values to unpack' from the orbit's state
        fail(f"{point.name} is on branch {branch.id} of periodic orbits: from such a file only a PD or a BP continues "
             "(--from PDk --cycles: the period-doubled orbits; --from BPk --cycles: the bifurcating cycles), or an LPC "
             "(--from LPCk --free NAME: the curve of folds of cycles); curves of PD or NS in two parameters are not "
             "implemented, and an HB there is where the orbits end on an "
             "equilibrium: continue from the Hopf point of the steady branch the orbits came from")
    if cycles and point.type != "HB" and not doubling:
        fail(f"--cycles starts at a Hopf point (HB), or a period doubling (PD) or branch point (BP) of orbits; "
             f"{point.name} is none of these (type {point.type}{' of a steady branch' if point.type in ('PD', 'BP') else ''})")
    if doubling and point.type == "BP" and amplitude is not None:
        # the first orbit of the bifurcating cycles is one step of --ds along the new branch's tangent:
        # --amplitude was silently ignored there (qa19b)
        fail(f"--amplitude sets the first orbit at a Hopf point or a PD; from the branch point {point.name} the first "
             "orbit is a step of --ds along the bifurcating branch (set --ds)")
    if other_half and not (doubling and point.type == "BP"):
        fail(f"--other-half is for --cycles from a branch point (BP) of a file of orbits, not {point.name} "
             f"({point.type}{'' if cycles else ', without --cycles'})")
    from contin.twoparam import continuable_types

    # before the grid checks: EP1 of an adaptive curve was sent to --tol (qa15)
    if point.type not in continuable_types() and not doubling and not lpc:
        fail(f"{point.name}: only {', '.join(continuable_types())} points can be continued in two parameters, "
             f"not {point.type}")
    from contin.twoparam import on_curve_message

    on_curve = on_curve_message(branch, point)
    if on_curve is not None:  # before the grid checks, as above
        fail(on_curve)
    first = branch.parameter
    unknown = [n for n in box if n not in (first, second)]
    if unknown and cycles:
        fail(f"--bounds names {unknown[0]!r}; with --cycles only the branch's parameter {first!r} can be bounded")
    if unknown:
        fail(f"--bounds names {unknown[0]!r}; only the two free parameters {first!r} and {second!r} can be bounded")
    try:
        options = io.options_from_dict(meta.get("options") or {})
    except (TypeError, ValueError):  # options chosen inside the scene (not stored as a full set)
        from contin.options import ContinuationOptions

        options = ContinuationOptions()
    step = options.step
    # --ds-max alone below the run's first step caps it (it ended "need ds_max >= |ds| >= ds_min > 0")
    new_ds = ds if ds is not None else min(abs(step.ds), ds_max if ds_max is not None else math.inf)
    new_max = ds_max if ds_max is not None else max(step.ds_max, new_ds)
    step = dataclasses.replace(step, ds=new_ds, ds_max=new_max, ds_min=min(step.ds_min, new_ds))
    run_bounds = {k: v for k, v in options.bounds.items() if k == first}
    run_bounds.update(box)
    # the run's adaptive settings are not the curve's: an augmented curve changes grid only
    # segment-wise (--tol, SegmentRegrid), never point by point in the tracer
    run_adapt = options.adapt
    options = dataclasses.replace(options, step=step, bounds=run_bounds, max_steps=max_steps, adapt=None)
    problem = rebuild_problem({**meta, "path": file})
    regrid = None
    own_grid = None  # a point of an adaptive run, continued on its own (fixed) grid
    if tol is not None:
        problem, options, regrid = _adaptive_setup(problem, point, options, run_adapt, tol, max_grid, meta, file,
                                                   solve_check=not no_solve_check)
    elif point.grid is not None and int(getattr(problem, "grid_size", point.grid)) != int(point.grid):
        from contin.adapt import missing_hooks, on_grid

        if point.type not in ("HB", "BP") or missing_hooks(problem):
            fail(f"{point.name} was computed on grid {point.grid} (an adaptive run; the file's grid is "
                 f"{problem.grid_size}): continue it with --tol REL, which starts on the point's own grid")
        # Hopf and BP curves cannot be regridded (--tol is refused for them), so the HB of an
        # adaptive run (contin trace brusselator: HB1 on grid 12, file grid 32) could not be continued
        # at all (qa14: each error sent the user to the other).  They run on the point's own grid.
        problem = on_grid(problem, int(point.grid))
        own_grid = int(point.grid)
    size = getattr(problem, "size", None)
    if (isinstance(size, int) and point.state is not None and size != len(point.state)
            and point.type not in ("BT", "ZH", "HH") and not doubling and not lpc):
        # (a BT, ZH or HH lies on a fold or Hopf curve: its augmented state is checked by contin.twoparam)
        fail(f"the state of {point.name} has {len(point.state)} entries but the problem rebuilt from {file} "
             f"has {size} unknowns")
    if lpc:
        from contin.cli.cycles_cmd import run_lpc_curve

        run_lpc_curve(problem, file, meta, branch, point, second, options, lpc_mesh[0], lpc_mesh[1], output, as_json)
        return
    if cycle_options is not None:
        from contin.cli.cycles_cmd import run_cycles

        run_cycles(problem, file, meta, branch, point, options, cycle_options, output, as_json, own_grid,
                   other_half=other_half)
        return
    from contin.cancel import stop_on_sigint
    from contin.twoparam import continue_point

    # The curve is the command's one result and is written at its end: the first Ctrl-C ends it at
    # its last point (written below, then exit 130), the second interrupts at once (qa14: Ctrl-C
    # lost the whole curve).
    from contin.cli._runctl import Terminated

    with stop_on_sigint(sigterm=Terminated) as stop:  # SIGTERM too (it lost the curve, qa16)
        if regrid is None:
            curve = continue_point(problem, branch, point, second, options)
            if own_grid is not None:  # the file's discretization is the run's start grid: every point says its own
                import numpy as np

                curve.grid = np.full(len(curve), own_grid, dtype=np.int64)
                curve.special_points = [dataclasses.replace(sp, grid=own_grid) for sp in curve.special_points]
        else:
            from contin.options import resolution_override

            with resolution_override(tol):
                curve = continue_point(problem, branch, point, second, options, regrid=regrid)
    interrupted = stop.requested
    from contin.cancel import is_stopped_branch

    # a stop that came after the branch was finished (while its end was located, its multipliers
    # computed) cut nothing short: the result is complete and written so (it was marked interrupted,
    # and `contin info` sent the user to compute it again; qa19)
    cut_short = interrupted and is_stopped_branch(curve)
    if output is not None:
        notes = [f"{_what(point, curve)} from {point.name} of branch {branch.id} in {file}, free {first}, {second}"]
        extra: dict[str, Any] = {"source": file, "from": point.name, "branch": branch.id, "free": [first, second]}
        if regrid is not None:
            notes.append(f"adaptive grids: tol {tol:g}, grids {_grids(curve)} (max {regrid.opts.max_grid})")
            extra["regrid"] = {"tol": tol, "max_grid": regrid.opts.max_grid}
        if own_grid is not None:
            notes.append(f"on the fixed grid {own_grid} of {point.name} (the run's start grid is "
                         f"{meta.get('discretization', {}).get('intervals', '?')})")
        from contin.cancel import STOPPED

        # a curve a stop request cut short is a partial result, marked as trace marks a stopped run
        # (it was written complete=True: `contin info` showed it as finished; qa18)
        io.write(output, [curve], scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                 discretization=meta.get("discretization", {}), options=options,
                 notes=notes, extra=extra, stopped=STOPPED[stop.reason] if cut_short else "",
                 diagram_x=first, diagram_y=meta.get("diagram_y") or "phi")
    if as_json:
        doc_extra: dict[str, Any] = {"from": point.name, "branch": branch.id, "free": [first, second]}
        if regrid is not None:
            doc_extra["regrid"] = {"tol": tol, "max_grid": regrid.opts.max_grid, "grids": _grid_sizes(curve)}
        doc = run_document(scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                           discretization=meta.get("discretization", {}), branches=[curve],
                           notes=[], extra=doc_extra,
                           output=output, stability={})
        echo_json(doc)
    echo_err(f"{_what(point, curve)} from {point.name} (branch {branch.id}, {first} = {fmt(point.params[first])}, "
             f"{second} = {fmt(point.params[second])}): {len(curve)} points, {curve.status} {curve.message}")
    if regrid is not None:
        echo_err(f"grids along the curve (tol {tol:g}): {_grids(curve)}")
    echo_err(special_points_table([curve]))
    if output is not None:
        echo_err(f"wrote {output}")
    from contin.cli._runctl import end_of_curve_run

    end_of_curve_run("the curve", len(curve), output, interrupted, stop, curve.status, curve.message, curve,
                     cut_short=cut_short)


def _grid_sizes(curve: Any) -> list[int]:
    """The grid sizes along a curve regridded segment-wise, ascending ([] without a grid column)."""
    return [] if curve.grid is None else sorted({int(g) for g in curve.grid})


def _grids(curve: Any) -> str:
    """:func:`_grid_sizes` as text, e.g. '24, 36, 56'."""
    return ", ".join(map(str, _grid_sizes(curve))) or "the start grid"


def _adaptive_setup(problem: Any, point: Any, options: Any, run_adapt: Any, tol: float, max_grid: int | None,
                    meta: Any, file: str, solve_check: bool = True) -> tuple[Any, Any, Any]:
    """``--tol``: the problem on the point's own grid, the options with the guard at tol, and the
    SegmentRegrid from the run's adaptive settings ``run_adapt`` (None: the defaults).  Its
    check_factor is the run's (AdaptOptions' default 2 where the run switched the check off:
    only ``--no-solve-check`` switches it off for the curve)."""
    import dataclasses

    from contin.adapt import missing_hooks, on_grid
    from contin.foldcurve import SegmentRegrid
    from contin.options import AdaptOptions

    if point.type == "HB":
        from contin.twoparam import NO_REGRID

        fail(NO_REGRID.format(what=f"{point.name} is a Hopf point"))
    missing = missing_hooks(problem)
    if missing:
        fail(f"--tol needs a problem with the grid hooks grid_size, with_grid, transfer, error_estimate; the problem "
             f"of scene {meta.get('scene', '')!r} in {file} ({type(problem).__name__}) lacks {', '.join(missing)}")
    problem = on_grid(problem, point.grid)
    base = run_adapt if run_adapt is not None else AdaptOptions()
    refine = dataclasses.replace(base, tol=tol, max_grid=max_grid if max_grid is not None else base.max_grid)
    if not solve_check:
        refine = dataclasses.replace(refine, solve_check=False)
    elif refine.check_factor is None or not refine.solve_check:
        refine = dataclasses.replace(refine, check_factor=refine.check_factor or AdaptOptions().check_factor,
                                     solve_check=True)
    start = int(problem.grid_size)
    if refine.max_grid < start:
        fail(f"--max-grid ({refine.max_grid}) is below the grid of {point.name} ({start})")
    options = dataclasses.replace(options, resolution_tol=tol)
    return problem, options, SegmentRegrid(refine)
