"""``contin continue FILE --from HB1 --cycles``: the periodic orbits born at a Hopf point (from a PD of
a file of orbits the period-doubled ones, from a BP of one the bifurcating cycles).

The helper of the ``continue`` command (``contin.cli.continue_cmd``) for ``--cycles``: the branch
of periodic orbits (``contin.cycles.continue_cycles``) in the run's parameter, written to ``-o``
as a branch of kind 'periodic-orbits' whose diagram is the amplitude against the parameter
(``contin diagram OUT.h5 -y period`` for the period).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from contin.cli._base import echo_err, echo_json, fail, fmt, special_points_table


def check_cycle_flags(cycles: bool, second: str | None, tol: float | None, ntst: int | None, ncol: int | None,
                      amplitude: float | None, uniform_mesh: bool = False) -> Any:
    """The CycleOptions of ``--cycles`` (None without it); one ``Error:`` line for flags that do
    not go together."""
    if not cycles:
        for name, v in (("--ntst", ntst), ("--ncol", ncol), ("--amplitude", amplitude),
                        ("--uniform-mesh", uniform_mesh or None)):
            if v is not None:
                fail(f"{name} needs --cycles (it sets the collocation of periodic orbits)")
        return None
    if second is not None:
        fail(f"--cycles continues the orbits in the branch's own parameter; --free {second} is for two-parameter "
             "curves (leave it out)")
    if tol is not None:
        fail("--tol is for fold curves on adaptive grids; with --cycles refine the orbits' mesh with --ntst")
    if amplitude is not None and not (math.isfinite(amplitude) and amplitude > 0):
        fail(f"--amplitude must be a finite number > 0, got {amplitude}")
    from contin.cycles import CycleOptions

    base = CycleOptions()
    return CycleOptions(ntst=ntst or base.ntst, ncol=ncol or base.ncol, amplitude=amplitude,
                        adapt_mesh=not uniform_mesh)


def _state_size(point: Any, meta: dict[str, Any]) -> int:
    """n of the problem: the HB's state, or (a PD of orbits) the file's own record."""
    if point.type in ("PD", "BP"):
        return int(((meta.get("extra") or {}).get("cycles") or {})["n"])
    return int(len(point.state))



def floquet_accuracy(branch: Any) -> str:
    """The summary's accuracy clause of a branch of orbits or an LPC curve: the largest distance of
    the trivial multiplier from 1 and the largest flow residual (``contin.floquet``)."""
    return (f"accuracy: trivial multiplier within {float(max(branch.observables['floquet_error'])):.1e} of 1 (a fold "
            f"of cycles makes it the square root of the error), flow residual <= "
            f"{float(max(branch.observables['flow_error'])):.1e}")


def run_cycles(problem: Any, file: str, meta: dict[str, Any], branch: Any, point: Any, options: Any, cycle: Any,
               output: str | None, as_json: bool, own_grid: int | None, other_half: bool = False) -> None:
    """Continue the orbits from ``point`` and report / write them (exit 3 when the branch ends
    with MX, as ``continue`` does for curves)."""
    from contin import io
    from contin.cancel import stop_on_sigint
    from contin.cli._runctl import Terminated
    from contin.cycles import continue_cycles

    first = branch.parameter
    with stop_on_sigint(sigterm=Terminated) as stop:
        try:
            if point.type in ("PD", "BP"):  # a PD / BP of a file of orbits
                from contin.cycles import continue_branch_point, continue_doubled

                stored = (meta.get("extra") or {}).get("cycles") or {}
                if not isinstance(stored.get("n"), int):
                    fail(f"{file} does not say the size n of its orbits (no 'cycles' entry): it was not written by "
                         "contin continue --cycles")
                parent_ncol = int(stored.get("ncol", cycle.ncol))
                if point.type == "PD":  # the period-doubled orbits
                    cycles = continue_doubled(problem, point, first, stored["n"], options, cycle,
                                              parent_ncol=parent_ncol, parent=point.name)
                else:  # the cycles bifurcating at a branch point of cycles (--other-half: along -tau)
                    cycles = continue_branch_point(problem, point, first, stored["n"], options, cycle,
                                                   parent_ncol=parent_ncol, direction=-1 if other_half else 1,
                                                   parent=point.name)
            else:
                cycles = continue_cycles(problem, point, first, options, cycle, parent=point.name)
        except ValueError as exc:
            fail(str(exc))
    interrupted = stop.requested
    from contin.cancel import is_stopped_branch

    # a stop that came after the branch was finished (while its end was located, its multipliers
    # computed) cut nothing short: the result is complete and written so (it was marked interrupted,
    # and `contin info` sent the user to compute it again; qa19)
    cut_short = interrupted and is_stopped_branch(cycles)
    if point.type == "PD":
        born = f"period 2 T = {fmt(2 * point.data['period']) if point.data.get('period') else '?'}"
    elif point.type == "BP":
        born = f"period T = {fmt(point.data['period']) if point.data.get('period') else '?'}"
    else:
        born = f"period 2 pi / omega = {fmt(2 * math.pi / point.data['omega']) if point.data.get('omega') else '?'}"
    what = {"PD": "period-doubled orbits", "BP": "bifurcating periodic orbits"}.get(point.type, "periodic orbits")
    summary = (f"{what} from {point.name} (branch {branch.id}, {first} = {fmt(point.params[first])}, {born}), "
               f"NTST = {cycle.ntst}, NCOL = {cycle.ncol}, {'adapted' if cycle.adapt_mesh else 'uniform'} mesh")
    if output is not None:
        extra = {"source": file, "from": point.name, "branch": branch.id, "free": [first],
                 "cycles": {"ntst": cycle.ntst, "ncol": cycle.ncol, "n": _state_size(point, meta),
                            "adapt_mesh": cycle.adapt_mesh}}
        notes = [summary + f" in {file}"]
        if own_grid is not None:
            notes.append(f"on the fixed grid {own_grid} of {point.name}")
        from contin.cancel import STOPPED

        # orbits a stop request cut short are a partial result, marked as continue marks its curves
        io.write(output, [cycles], scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                 discretization=meta.get("discretization", {}), options=dataclasses.replace(options, save_every=1),
                 notes=notes, extra=extra, stopped=STOPPED[stop.reason] if cut_short else "",
                 diagram_x=first, diagram_y="amplitude")
    if as_json:
        from contin.jsonout import run_document

        doc = run_document(scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                           discretization=meta.get("discretization", {}), branches=[cycles], notes=[],
                           extra={"from": point.name, "branch": branch.id, "free": [first],
                                  "cycles": {"ntst": cycle.ntst, "ncol": cycle.ncol, "adapt_mesh": cycle.adapt_mesh},
                                  "orbits": {first: cycles.parameter_values.tolist(),
                                             **{k: cycles.observables[k].tolist()
                                                for k in ("period", "amplitude", "l2norm", "flow_error")},
                                             "stable": cycles.stable.tolist()}},
                           output=output, stability={})
        echo_json(doc)
    echo_err(f"{summary}: {len(cycles)} points, {cycles.status} {cycles.message}")
    if len(cycles):
        t, a = cycles.observables["period"], cycles.observables["amplitude"]
        echo_err(f"period {fmt(t[0], 7)} .. {fmt(t[-1], 7)}, amplitude {fmt(a[0], 7)} .. {fmt(a[-1], 7)}, "
                 f"stable at {int(cycles.stable.sum())} of {len(cycles)} points; {floquet_accuracy(cycles)}")
    echo_err(special_points_table([cycles]))
    for line in cycles.audit:
        if line.startswith("warning: "):
            echo_err(line)
    if output is not None:
        echo_err(f"wrote {output}")
    from contin.cli._runctl import end_of_curve_run

    end_of_curve_run("the orbits", len(cycles), output, interrupted, stop, cycles.status, cycles.message, cycles,
                     cut_short=cut_short)


def run_lpc_curve(problem: Any, file: str, meta: dict[str, Any], branch: Any, point: Any, second: str,
                  options: Any, ntst: int | None, ncol: int | None, output: str | None, as_json: bool) -> None:
    """``contin continue ORBITS.h5 --from LPCk --free NAME``: the curve of folds of cycles through
    the LPC in (the branch's parameter, NAME) (``contin.lpccurve``), written to ``-o`` as a branch
    of kind 'lpc-curve' (its states the orbits, as on a cycle branch); exit 3 when it ends with MX."""
    from contin import io
    from contin.cancel import stop_on_sigint
    from contin.cli._runctl import Terminated
    from contin.cycles import CycleOptions
    from contin.lpccurve import trace_lpc_curve

    first = branch.parameter
    stored = (meta.get("extra") or {}).get("cycles") or {}
    if not isinstance(stored.get("n"), int):
        fail(f"{file} does not say the size n of its orbits (no 'cycles' entry): it was not written by "
             "contin continue --cycles")
    if second == first:
        fail(f"--free {second} is the branch's own parameter; name the second parameter of the LPC curve")
    if second not in point.params:
        fail(f"unknown parameter {second!r} (the problem has {', '.join(sorted(point.params))})")
    parent_ncol = int(stored.get("ncol", CycleOptions().ncol))
    n = int(stored["n"])
    own_ntst = len(point.state) // (n * parent_ncol + 1)  # [nodes, T, interior mesh]: NTST (n NCOL + 1)
    cycle = CycleOptions(ntst=ntst or own_ntst, ncol=ncol or parent_ncol)
    with stop_on_sigint(sigterm=Terminated) as stop:
        try:
            curve = trace_lpc_curve(problem, point, second, n, options, cycle, parameter=first,
                                    parent_ncol=parent_ncol)
        except ValueError as exc:
            fail(str(exc))
    from contin.cancel import is_stopped_branch

    interrupted = stop.requested
    cut_short = interrupted and is_stopped_branch(curve)  # a stop after the curve was finished cuts nothing
    summary = (f"LPC curve from {point.name} (branch {branch.id}, {first} = {fmt(point.params[first])}, "
               f"{second} = {fmt(point.params[second])}), NTST = {cycle.ntst}, NCOL = {cycle.ncol}")
    if output is not None:
        from contin.cancel import STOPPED

        extra = {"source": file, "from": point.name, "branch": branch.id, "free": [first, second],
                 "cycles": {"ntst": cycle.ntst, "ncol": cycle.ncol, "n": n, "adapt_mesh": False}}
        io.write(output, [curve], scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                 discretization=meta.get("discretization", {}), options=dataclasses.replace(options, save_every=1),
                 notes=[summary + f" in {file}"], extra=extra, stopped=STOPPED[stop.reason] if cut_short else "",
                 diagram_x=first, diagram_y=second)
    if as_json:
        from contin.jsonout import run_document

        doc = run_document(scene=meta.get("scene", ""), parameters=meta.get("parameters", {}),
                           discretization=meta.get("discretization", {}), branches=[curve], notes=[],
                           extra={"from": point.name, "branch": branch.id, "free": [first, second],
                                  "cycles": {"ntst": cycle.ntst, "ncol": cycle.ncol}},
                           output=output, stability={})
        echo_json(doc)
    echo_err(f"{summary}: {len(curve)} points, {curve.status} {curve.message}")
    if len(curve):
        t, a = curve.observables["period"], curve.observables["amplitude"]
        echo_err(f"period {fmt(min(t), 7)} .. {fmt(max(t), 7)}, amplitude {fmt(min(a), 7)} .. {fmt(max(a), 7)}; "
                 f"{floquet_accuracy(curve)}")
    echo_err(special_points_table([curve]))
    if output is not None:
        echo_err(f"wrote {output}")
    from contin.cli._runctl import end_of_curve_run

    end_of_curve_run("the curve", len(curve), output, interrupted, stop, curve.status, curve.message, curve,
                     cut_short=cut_short)
