"""``contin trace SCENE``: run a scene, store it in HDF5, summarise its special points."""

from __future__ import annotations

import math

from typing import Any

import click

from contin.cli._base import (
    EXIT_INCOMPLETE,
    continued_from,
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
from contin.cli._runctl import (
    EXIT_TERMINATED,
    MAX_GRID,
    MAX_STEPS,
    MAX_TRACE_KX,
    Progress,
    Terminated,
    check_finite_positive,
    check_hdf5_output,
    check_kx,
    check_nonempty,
    sigterm_as_interrupt,
)
from contin.limits import MIN_MAX_GRID

#: a finished branch is published at once when the time since the last publish is at least
#: this many times that publish's duration (contin.io, "Crash safety"): publishing then takes at
#: most 1/5 of a run, and a SIGKILL loses at most ~4 publishes' worth of computing
CHECKPOINT_RATIO = 4.0


def _parse_kx(text: str | None) -> tuple[float, ...]:
    if text is None:
        return ()
    if not text.strip():  # --kx '' was accepted without a word (qa15)
        raise click.BadParameter("must not be empty (leave the option out for no extra wavenumbers)", param_hint="'--kx'")
    try:
        values = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {text!r}", param_hint="'--kx'") from None
    check_kx(values, most=MAX_TRACE_KX)
    return values


def _parse_uz(uz: tuple[str, ...], stop_at: str | None) -> dict[str, Any]:
    """``--uz NAME=V1,V2`` (repeatable) and ``--stop-at L1,L2`` as option overrides; checked here
    so that bad input is one ``Error:`` line before anything runs."""
    from contin.options import ContinuationOptions

    out: dict[str, Any] = {}
    zeros: dict[str, list[float]] = {}
    for item in uz:
        name, sep, values = item.partition("=")
        try:
            vals = [float(v) for v in values.split(",") if v.strip()]
        except ValueError:
            vals = []
        if not sep or not name.strip() or not vals:
            raise click.BadParameter(f"expected NAME=V1,V2,... with numbers, got {item!r}", param_hint="'--uz'")
        zeros.setdefault(name.strip(), []).extend(vals)
    labels = tuple(t.strip() for t in (stop_at or "").split(",") if t.strip())
    if stop_at is not None and not labels:  # '' ran to the end without a word (qa15)
        raise click.BadParameter(f"expected labels such as LP1 or UZ2, got {stop_at!r}", param_hint="'--stop-at'")
    try:  # the options' own validation: finite values, LP/BP/UZ/HB<k> labels
        ContinuationOptions(user_zeros=zeros, stop_at=labels)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="'--uz'" if zeros and not labels else "'--stop-at'") from None
    if zeros:
        out["user_zeros"] = zeros
    if labels:
        out["stop_at"] = labels
    return out


def _in_progress_options(stored: Any) -> Any:
    """The stored options in the form :func:`_resume_accuracy` and :func:`_resume_settings` read.

    A file the run had not finished (interrupted, killed, failed: the checkpoints) holds the
    command line's overrides as they were (``{"ds_max": 0.05, "tol": 1e-06}``), not the resolved
    options: both checks read it as a finished run's, so `trace bratu --resume F --ds-max 0.05` of
    a `--ds-max 0.05` run was refused ("computed with --ds-max None") and `--resume F --tol 1e-8` of
    a tol-1e-6 run was accepted, the file then claiming tol 1e-8 (qa16).  Such a dict becomes
    ``{"overrides": ..., "adapt": ...}`` (adapt None for a fixed grid; AdaptOptions' defaults
    for what the command line left out)."""
    if not isinstance(stored, dict) or not stored or any(k in stored for k in ("step", "adapt", "overrides", "note")):
        return stored
    from contin.options import AdaptOptions

    adapt = None
    if stored.get("tol") is not None:
        base = AdaptOptions()
        adapt = {"tol": stored["tol"],
                 "special_tol": stored.get("special_tol") if stored.get("special_tol") is not None else base.special_tol,
                 "max_grid": stored.get("max_grid") if stored.get("max_grid") is not None else base.max_grid,
                 "solve_check": stored.get("solve_check", True) is not False}
    return {"overrides": dict(stored), "adapt": adapt}


def _resume_accuracy(resume: str, stored: Any, overrides: dict[str, Any], *, tol: float | None,
                     special_tol: float | None, max_grid: int | None, no_solve_check: bool) -> None:
    """``--resume``: the new branches are computed to the accuracy of the stored ones.

    The file's adaptive settings (its options' ``adapt``) are taken over where the command does
    not give them, and a different ``--tol``/``--special-tol``/``--max-grid`` is refused, as
    another ``--grid`` is: ``--resume F --tol 1e-8`` of a tol-1e-6 run (or ``--resume F`` alone,
    which meant the scene's default 1e-10) recorded the finished tol-1e-6 branches as computed at
    the new tol (session 14).  A fixed-grid file stays fixed-grid; ``--tol`` on it is refused."""
    if not isinstance(stored, dict) or "adapt" not in stored:  # options chosen inside the scene: unknown
        return
    adapt = stored.get("adapt")
    if adapt is None:
        if tol is not None or special_tol is not None or max_grid is not None:
            fail(f"{resume!r} was computed on a fixed grid (no --tol); resume it without --tol, --special-tol, "
                 "--max-grid (or start a new run)")
        for key in ("tol", "special_tol", "max_grid", "solve_check"):
            overrides.pop(key, None)
        return
    if "tol" not in overrides:
        return
    for key, flag, given in (("tol", "--tol", tol), ("special_tol", "--special-tol", special_tol),
                             ("max_grid", "--max-grid", max_grid)):
        before = adapt.get(key)
        if before is None:
            continue
        if given is not None and float(given) != float(before):
            fail(f"{resume!r} was computed with {flag} {fmt(before)}, not {fmt(given)}; resume with the same "
                 "accuracy (or start a new run)")
        overrides[key] = int(before) if key == "max_grid" else float(before)
    if adapt.get("solve_check") is False:
        overrides["solve_check"] = False
    elif no_solve_check:
        fail(f"{resume!r} was computed with the solve check; resume it without --no-solve-check (or start a new run)")


def _resume_settings(resume: str, stored: Any, given: dict[str, Any]) -> None:
    """``--resume``: step settings given again must be the stored run's.  The finished branches are
    reused as they are, so `contin trace bratu --resume F --uz lam=2` of a run without that user zero
    wrote F again with no UZ and the new command line, exit 0 (qa15); --stop-at, --max-steps,
    --ds, --ds-max and --bp-eigs likewise.  Settings left out are the file's."""
    if not given or not isinstance(stored, dict):
        return
    if isinstance(stored.get("overrides"), dict):  # a scene that chose its options inside: the run's overrides
        before: dict[str, Any] = dict(stored["overrides"])
    else:
        step, det = stored.get("step") or {}, stored.get("detection") or {}
        before = {"max_steps": stored.get("max_steps"), "ds": abs(step["ds"]) if "ds" in step else None,
                  "ds_max": step.get("ds_max"), "user_zeros": stored.get("user_zeros") or {},
                  "stop_at": list(stored.get("stop_at") or []), "bp_eigenvalues": det.get("bp_eigenvalues")}
    flags = {"max_steps": "--max-steps", "ds": "--ds", "ds_max": "--ds-max", "user_zeros": "--uz",
             "stop_at": "--stop-at", "bp_eigenvalues": "--bp-eigs"}
    for key, value in given.items():
        if key not in flags:
            continue
        old = before.get(key)
        if key == "user_zeros":
            stored_uz = {str(k): {float(x) for x in v} for k, v in (old or {}).items()}
            same = all({float(x) for x in vals} <= stored_uz.get(name, set()) for name, vals in value.items())
            shown_old = ", ".join(f"{k}={','.join(fmt(x) for x in sorted(v))}" for k, v in stored_uz.items()) or "none"
            shown_new = ", ".join(f"{k}={','.join(fmt(float(x)) for x in v)}" for k, v in value.items())
        elif key == "stop_at":
            same = list(old or []) == list(value)
            shown_old, shown_new = ",".join(old or []) or "none", ",".join(value)
        elif key in ("ds", "ds_max"):
            same = old is not None and math.isclose(float(old), abs(float(value)), rel_tol=1e-12)
            shown_old, shown_new = ("its default" if old is None else fmt(old)), fmt(value)
        else:
            same = old == value
            shown_old, shown_new = ("its default" if old is None else fmt(old)), fmt(value)
        if not same:
            fail(f"{resume!r} was computed with {flags[key]} {shown_old}, not {shown_new}; its finished branches are "
                 f"reused as they are, so resume with the same settings (or start a new run)")


def _stopped(writer: Any, exc: BaseException, *, can_resume: bool = True) -> None:
    """Record why the run stopped in the published file, say where the work is, drop the lock.

    An interrupt (Ctrl-C, SIGTERM), a full disk or a crash can be continued with --resume; bad
    input found late (ValueError, LookupError) would fail the same way again, so no --resume is
    suggested for it.  ``contin info`` says "failed: ...", not "interrupted", for any error.
    """
    from contin.cancel import CTRL_C, SIGTERM, STOPPED, is_stopped_branch, stopped_by

    interrupted = isinstance(exc, KeyboardInterrupt)
    # bad input would fail the same way again; a --depth run cannot be resumed (its note suggested
    # --resume, which --depth refuses: qa16)
    resumable = can_resume and not isinstance(exc, ValueError | LookupError)
    why = (STOPPED[SIGTERM] if isinstance(exc, Terminated) else STOPPED[CTRL_C] if interrupted
           else f"failed: {error_line(exc)}")
    try:
        if writer.publishes or any(len(b) > 0 for b in writer.branches):
            writer.update(stopped=why)
            writer.publish()
    except Exception:  # noqa: BLE001 -- the earlier published file stays as it was
        pass
    finally:
        writer.release()
    done = [b for b in writer.branches if len(b) > 0 and not is_stopped_branch(b)]
    partial = [b for b in writer.branches if len(b) > 0 and is_stopped_branch(b)]
    if writer.publishes and (done or partial):
        hint = f" (continue with --resume {writer.path})" if resumable else ""
        parts = [f"{len(done)} finished branch(es)"] if done else []
        again = "; --resume traces it again" if resumable else ""
        parts += [f"branch {b.id} up to its last point ({len(b)} points, {stopped_by(b)}{again})"
                  for b in partial]  # the branch in progress, ended at its last point by the first Ctrl-C/SIGTERM
        verb = "is" if len(parts) == 1 and not done else "are"
        echo_err(f"note: {' and '.join(parts)} {verb} saved in {writer.path}{hint}")


def stability_summary(branch: Any) -> dict[str, Any] | None:
    """{kx, kz, n_unstable: [...], audit: [...]} of a branch, None without stability."""
    if branch.n_unstable is None:
        return None
    kx, kz = branch.stability_k or (0.0, 0.0)
    return {"kx": kx, "kz": kz, "n_unstable": branch.n_unstable, "audit": stability_messages(branch)}


def audit_lines(branch: Any) -> list[str]:
    """The branch's audit lines for the terminal: the tracer's (grid changes, checks of located
    points) and the stability pass's, not the rejected-step diagnostics that
    :mod:`contin.continuation` stores as ``"step N: ..."``; a ``"stability audit: "`` prefix,
    which some scenes add, is removed."""
    return [m.removeprefix("stability audit: ") for m in branch.audit if not m.startswith("step ")]


def doubtful_points(branch: Any) -> list[str]:
    """The audit lines of points stored although their two-grid check exceeded tol
    (``contin.continuation.ACCEPTED_ABOVE_TOL``), of steps across which a special point may have
    been missed (``DETECTION_GAP``: a test function not finite, a user zero next to a fold not
    located), of FD branches whose check grid's test functions disagree with the located points
    (``MISSED_SPECIAL``), of switched branches that run along their parent
    (``contin.rejoin.REJOINED``) and of clouds of special points (``contin.cloud.CLOUD``): the terminal shows them as warnings, also with ``-q``."""
    from contin.continuation import ACCEPTED_ABOVE_TOL, DETECTION_GAP, MISSED_SPECIAL
    from contin.cloud import CLOUD
    from contin.rejoin import REJOINED

    return [m for m in branch.audit
            if (m.startswith("step ") and (ACCEPTED_ABOVE_TOL in m or DETECTION_GAP in m))
            or m.startswith((MISSED_SPECIAL, REJOINED, CLOUD))]


#: The note of a located special point whose measured position missed special_tol after every
#: refinement (``contin.continuation``): shown as a warning, as a doubtful state is.
UNRESOLVED_POSITION = "position not resolved by refinement"

#: The note of a special point whose location (bisection/secant of its test function) did not
#: converge (``contin.continuation``): a warning too.
UNCONVERGED_LOCATION = "location did not converge"


def doubtful_special_points(branch: Any) -> list[str]:
    """One line per special point whose measured position exceeded the run's special tol
    (note :data:`UNRESOLVED_POSITION`): the summary table showed it in its note column only,
    which ``-q`` hides (session 15: ``contin trace allen-cahn --method fd2 --tol 1e-4 -q`` said
    nothing of BP3 stored 2.8e-5 off lam = 9 where special_tol asks 1e-10)."""
    out = []
    for sp in getattr(branch, "special_points", ()):
        note = str(getattr(sp, "note", "") or "")
        where = ", ".join(f"{k}={float(v):.10g}" for k, v in sp.params.items() if k == branch.parameter)
        if UNRESOLVED_POSITION in note:
            out.append(f"{sp.name} at {where}: {note[note.index(UNRESOLVED_POSITION):]}")
        elif UNCONVERGED_LOCATION in note:
            # (savage-rheology's symmetric BP4 on cheb 32: 3.0e-10 off a cheb 96 solve where
            # special_tol asks 1e-10, said in the table's note only)
            out.append(f"{sp.name} at {where}: {note[note.index(UNCONVERGED_LOCATION):]} (its position is less "
                       "accurate than asked)")
    return out


def stability_messages(branch: Any) -> list[str]:
    """The audit messages of the stability pass alone (``contin.stability.is_stability_message``)."""
    from contin.stability import is_stability_message

    return [m for m in audit_lines(branch) if is_stability_message(m)]


@main.command("trace")
@click.argument("scene")
@click.option("-s", "--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="Set a scene parameter (repeatable); values are numbers, 'inf', or words (e.g. chi=cs).")
@click.option("--method", default=None, help="Discretization method (e.g. cheb, fd2, fd4, fd6).")
@click.option("--grid", type=click.IntRange(min=2, max=MAX_GRID), default=None,
              help=f"Number of grid intervals (2..{MAX_GRID}).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, writable=True), default=None,
              help="HDF5 file to write (checkpointed after every finished branch).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
@click.option("--no-stability", is_flag=True, help="Skip the linear-stability pass.")
@click.option("--kx", default=None, metavar="LIST",
              help=f"Extra streamwise wavenumbers for stability, e.g. 0.5,1 (at most {MAX_TRACE_KX}, finite, |kx| <= 1e4).")
@click.option("--max-steps", type=click.IntRange(min=1, max=MAX_STEPS), default=None,
              help=f"Maximum continuation steps per branch (1..{MAX_STEPS}).")
@click.option("--ds", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Initial arclength step (a finite number > 0).")
@click.option("--ds-max", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Largest arclength step (a finite number > 0).")
@resolution_tol_option
@click.option("--tol", type=click.FloatRange(min=0, min_open=True, max=1, max_open=True), default=None, metavar="REL",
              help="Adaptive resolution: largest estimated relative discretization error of a point; the grid is "
                   "chosen and changed along each branch to meet it [default for adaptive scenes without --grid: "
                   "the scene's (gPCF 3e-5, the resolution guard's; demos 1e-10); with --grid and no --tol the "
                   "grid is fixed].")
@click.option("--max-grid", type=click.IntRange(min=MIN_MAX_GRID), default=None,
              help="Largest grid adaptive resolution may use [default 512]; past it a branch ends with MX.")
@click.option("--special-tol", "special_tol", type=click.FloatRange(min=0, min_open=True, max=1, max_open=True), default=None,
              metavar="REL",
              help="Adaptive resolution: largest estimated relative error of the kernel that fixes a located BP or "
                   "LP, and of the two-grid checked position of an LP, HB or symmetry-breaking BP "
                   "(AdaptOptions.special_tol); the point is located again on a finer grid above min(tol, REL) "
                   "[default 1e-10: special points far more accurate than the branch].")
@click.option("--no-solve-check", "no_solve_check", is_flag=True, default=False,
              help="Adaptive resolution: accept a point by its error estimate alone, without the two-grid check "
                   "of its solve (AdaptOptions.solve_check = False; faster, but points next to a BP or LP can miss "
                   "tol: check them with contin verify). The two-grid checks of located LPs', HBs' and BPs' positions stay.")
@engine_option
@click.option("--resume", type=click.Path(exists=True, dir_okay=False), default=None,
              help="Reuse the finished branches of an interrupted run (default -o: this file).")
@click.option("--uz", "uz", multiple=True, metavar="NAME=V1,V2,...",
              help="User zeros (UZ): locate the points where parameter NAME takes these values (repeatable).")
@click.option("--stop-at", "stop_at", default=None, metavar="LABELS",
              help="End each trace after the k-th point of a type, e.g. UZ1 or LP2,HB1 (AUTO's STOP/UZSTOP).")
@click.option("--bp-eigs", "bp_eigs", type=click.IntRange(min=0), default=None, metavar="K",
              help="Second BP detector: count the K eigenvalues of J nearest zero crossing it, cross-checked "
                   "with the determinant (finds even kernels and BPs sharing a step; kernel dimension in the note). "
                   "Default: K = 12 for problems of at most 100 unknowns without their own stability "
                   "eigenproblem; 0 switches it off.")
@click.option("--depth", type=click.IntRange(min=1, max=20), default=None, metavar="D",
              help="Automatic bifurcation diagram (contin.diagram.explore) from the scene's start point: trace, "
                   "switch at every BP to depth D (1 = the start branch only), each branch once, mirror images "
                   "stored by reflection; on the scene's fixed grid.")
@click.option("--max-branches", type=click.IntRange(min=1, max=10000), default=None, metavar="N",
              help="With --depth: stop switching once N branches are known [default 200].")
@click.option("-q", "--quiet", is_flag=True, help="No progress lines and no summary table.")
def trace_command(scene: str, settings: tuple[str, ...], method: str | None, grid: int | None,
                  output: str | None, as_json: bool, no_stability: bool, kx: str | None,
                  max_steps: int | None, ds: float | None, ds_max: float | None,
                  resolution_tol: str | None, tol: float | None, max_grid: int | None, special_tol: float | None, no_solve_check: bool, engine: str, uz: tuple[str, ...], stop_at: str | None,
                  bp_eigs: int | None, resume: str | None, depth: int | None, max_branches: int | None,
                  quiet: bool) -> None:
    """Trace the branches of SCENE and report its special points.

    Human output (progress, summary table) goes to stderr; --json prints one JSON document
    to stdout.  Exit code 3 when the run finished but a branch ended with MX.

    Scenes marked adaptive choose their grid to meet --tol (the scene's default when no --grid
    is given; --grid alone fixes the grid, --grid with --tol is the start grid).

    --depth D replaces the scene's own run by the generic diagram builder from the scene's
    start point (scenes that define one: ``contin scenes`` marks them).
    """
    import contin.scene as scene_mod
    from contin import io
    from contin.cancel import SIGTERM, is_stopped_branch, stop_on_sigint, stop_reason, stop_requested
    from contin.jsonout import run_document

    params = parse_settings(settings)
    kx_values = _parse_kx(kx)
    if no_stability and any(k != 0 for k in kx_values):  # it was dropped silently, exit 0 (qa15)
        fail(f"--kx {kx} asks for stability columns but --no-stability switches the stability pass off; "
             f"drop one of them")
    method = check_nonempty(method, "--method")
    check_finite_positive(ds, "--ds")
    check_finite_positive(ds_max, "--ds-max")
    check_hdf5_output(output)
    guard, rtol = resolution_guard(resolution_tol)  # every trace of the run, also those a scene sets up itself
    sc = scene_mod.get_scene(scene)
    if not sc.discretized and (method is not None or grid is not None):  # ignored, exit 0 (qa16)
        fail(f"scene {scene!r} is a system of ODEs without a discretization: --method and --grid do not apply")
    if sc.defaults:
        unknown = [n for n in params if n not in sc.defaults]
        if unknown:
            raise scene_mod.SceneError(
                f"unknown parameter {unknown[0]!r} for scene {scene!r}; its parameters are {', '.join(sc.defaults)}")
    step_overrides = {k: v for k, v in (("ds", ds), ("ds_max", ds_max), ("max_steps", max_steps)) if v is not None}
    step_overrides.update(_parse_uz(uz, stop_at))
    if bp_eigs is not None:
        step_overrides["bp_eigenvalues"] = bp_eigs
    overrides = dict(step_overrides)
    if resolution_tol is not None:
        overrides["resolution_tol"] = rtol
    if depth is None and max_branches is not None:
        fail("--max-branches needs --depth")
    if depth is not None:
        if sc.start is None:
            fail(f"scene {scene!r} gives no start point for --depth (it has its own run only)")
        if resume is not None or tol is not None or max_grid is not None or special_tol is not None:
            fail("--depth runs on a fixed grid and from scratch: drop --resume, --tol, --max-grid and --special-tol")
        import dataclasses
        from contin.diagram import explore

        def run_diagram(request: Any, start: Any = sc.start) -> Any:
            return explore(start(request), request, depth=depth, max_branches=max_branches)

        sc = dataclasses.replace(sc, run=run_diagram, adaptive=False)
    # the scene's resolution settings, as every sweep task of it gets them (Scene.accuracy_overrides)
    overrides.update(sc.accuracy_overrides(grid=grid, tol=tol, max_grid=max_grid, special_tol=special_tol,
                                           solve_check=not no_solve_check))

    completed: dict[str, Any] = {}
    resumed_attrs: dict[str, str] = {}
    if resume is not None:
        old, meta = io.load(resume)
        resumed_attrs = dict(meta.get("attrs") or {})
        if continued_from(meta) is not None:
            # its curve was taken for a finished branch and dropped from the file the run then
            # wrote over it: the curve lost, exit 0 (qa18)
            # (orbits of --cycles are no two-parameter curve: the message called them one, qa19b)
            orbits = any(getattr(b, "kind", "") == "periodic-orbits" for b in old)
            what = "periodic orbits of `contin continue --cycles`" if orbits else \
                "a two-parameter curve of `contin continue`"
            fail(f"{resume!r} holds {what} (from {continued_from(meta)}), not a run of `contin trace`; --resume "
                 f"continues a trace run (give another -o to keep the {'orbits' if orbits else 'curve'})")
        if meta["scene"] and meta["scene"] != scene:
            fail(f"{resume!r} holds a run of scene {meta['scene']!r}, not {scene!r}")
        for name, value in params.items():
            before = meta["parameters"].get(name)
            if before is not None and before != value:
                fail(f"{resume!r} was computed with {name}={fmt(before)}, not {fmt(value)}; resume with the same parameters")
        # The stored states belong to the file's discretization: another one is refused, and
        # none given means the file's (a resumed cheb-32 run silently mixed in cheb-64 states).
        stored = dict(meta["discretization"])
        if "grid" in stored and "intervals" not in stored:  # a checkpoint written before qa17 (key 'grid')
            stored["intervals"] = stored.pop("grid")
        for what, given, key in (("--method", method, "method"), ("--grid", grid, "intervals")):
            if key in stored and given is not None and str(given) != str(stored[key]):
                fail(f"{resume!r} was computed with {what} {stored[key]}, not {given}; resume with the same "
                     f"discretization (or start a new run)")
            if key not in stored and given is not None and not meta["complete"]:
                # an unfinished file records only the --method/--grid its run was given: none means the
                # scene's own (`--resume F --grid 64` of a --grid 32 run, or `--method fd4` of a default
                # run, was accepted, failed with 'matmul: dimension mismatch' and relabelled the file; qa17)
                fail(f"{resume!r} was computed without {what} (the scene's own discretization), not {what} "
                     f"{given}; resume without it (or start a new run)")
        method = method if method is not None or "method" not in stored else str(stored["method"])
        grid = grid if grid is not None or "intervals" not in stored else int(stored["intervals"])
        stored_options = _in_progress_options(meta.get("options"))
        if stored_options == {} and not meta["complete"]:
            # an unfinished run without overrides: no tol, so a fixed grid (an adaptive scene's run
            # always records its tol); `--resume F` of an interrupted `--grid 32` run of jj-walls
            # went on adaptively (states of 244 unknowns beside those of 100, the file saying cheb 32; qa17)
            stored_options = {"overrides": {}, "adapt": None}
        _resume_accuracy(resume, stored_options, overrides, tol=tol, special_tol=special_tol,
                         max_grid=max_grid, no_solve_check=no_solve_check)
        _resume_settings(resume, stored_options, step_overrides)
        if isinstance(stored_options, dict) and isinstance(stored_options.get("overrides"), dict):
            # the run's own command-line step settings where this command leaves them out: the
            # branches still to trace get them too (an interrupted --ds-max 0.05 run went on with 0.25)
            for key in ("ds", "ds_max", "max_steps", "user_zeros", "stop_at", "bp_eigenvalues"):
                if key not in step_overrides and stored_options["overrides"].get(key) is not None:
                    step_overrides[key] = overrides[key] = stored_options["overrides"][key]
        before_rtol = (meta.get("options") or {}).get("resolution_tol", "unknown") \
            if isinstance(meta.get("options"), dict) else "unknown"
        if resolution_tol is not None and before_rtol != "unknown" and before_rtol != rtol:
            fail(f"{resume!r} was computed with --resolution-tol {'off' if before_rtol is None else fmt(before_rtol)}, "
                 f"not {resolution_tol}; resume with the same accuracy (or start a new run)")
        # a branch a Ctrl-C or SIGTERM ended at its last point is partial: traced again, not reused
        completed = {b.id: b for b in old if not is_stopped_branch(b)}
        if output is None:
            output = resume
        check_hdf5_output(output)

    writer = None
    if output is not None:  # checked (and locked against a second writer) before any computing
        writer = io.H5Writer(output, scene=scene, parameters={**sc.defaults, **params},
                             # (the reader's key 'intervals': a checkpoint said 'grid', which --resume did not see, qa17)
                             discretization={k: v for k, v in (("method", method), ("intervals", grid)) if v is not None},
                             options=overrides, branches=completed.values(),
                             diagram_x=sc.x, diagram_y=sc.y, checkpoint_ratio=CHECKPOINT_RATIO,
                             extra={} if depth is None else {"depth": depth},  # (contin info of a stopped --depth run)
                             # the resumed file's own root attributes (a sweep task file's sweep_task, qa19)
                             attrs=resumed_attrs)
    progress = Progress(enabled=not quiet)

    handed_after_stop = []  # a finished branch was handed over after the stop request

    def on_branch(branch: Any) -> None:
        if writer is not None:
            writer.add_branch(branch)
        progress.line(f"branch {branch.id} ({branch.kind}{', from ' + branch.parent if branch.parent else ''}): "
                      f"{len(branch)} points, {branch.status} {branch.message}".rstrip())
        if stop_requested():
            # The run stops at the branch the first Ctrl-C/SIGTERM cut short, or at the scene's next
            # progress report after a finished branch (status_or_stop): a scene that hands its
            # branches over together at its end (gravity: discover, then one loop) lost every one
            # after the first (qa18), while a scene that hands each over as it finishes still stops
            # before its next branch.
            if is_stopped_branch(branch):
                stop_now()
            handed_after_stop.append(branch.id)

    def status_or_stop(message: str) -> None:
        if handed_after_stop and stop_requested():
            stop_now()
        progress.status(message)

    def stop_now() -> None:
        raise Terminated() if stop_reason() == SIGTERM else KeyboardInterrupt()

    def abort(exc: BaseException) -> None:
        """Save what was computed, say where, and end: Terminated as exit 143, others re-raised."""
        progress.close()
        if writer is not None:
            _stopped(writer, exc, can_resume=depth is None)
        if isinstance(exc, Terminated):
            echo_err("Error: terminated by SIGTERM")
            raise click.exceptions.Exit(EXIT_TERMINATED) from None
        raise exc

    request = scene_mod.SceneRequest(
        params=params, method=method, grid=grid, stability=not no_stability and sc.stability, kx=kx_values,
        completed=completed, on_branch=on_branch, progress=status_or_stop, overrides=overrides, engine=engine)
    stop = None
    try:
        # The first Ctrl-C or SIGTERM ends the branch in progress at its last point (contin.cancel);
        # on_branch stores it and stops the run; the second interrupts at once.
        with guard, sigterm_as_interrupt(), stop_on_sigint(sigterm=Terminated) as stop:
            result = sc.run(request)
            if stop_requested():  # a scene that passed no branch to on_branch after the stop
                if writer is not None:
                    writer.set_branches(result.branches)
                    if result.notes or result.extra:
                        # what the scene finished before the stop, also where its results are notes and
                        # extra, not branches (disks-criticality: the e values done; no file was written
                        # at all, qa18); published here, marked stopped by abort()
                        writer.update(parameters=result.parameters, discretization=result.discretization,
                                      notes=list(result.notes),
                                      extra={**result.extra, **({} if depth is None else {"depth": depth})})
                        writer.publish()
                stop_now()
    except BaseException as exc:
        if stop is not None and stop.requested and not isinstance(exc, KeyboardInterrupt):
            # an error that followed the stop (a scene that cannot use the shortened branch): the
            # run was interrupted, not failed (exit 1 with "failed: ..." before; qa16)
            echo_err(f"note: after the {'SIGTERM' if stop.reason == SIGTERM else 'Ctrl-C'} the scene ended with: "
                     f"{error_line(exc)}")
            exc = Terminated() if stop.reason == SIGTERM else KeyboardInterrupt()
        abort(exc)
    # The stability pass and the final write: a Ctrl-C, SIGTERM or error there kept only the branches
    # the last checkpoint had published (`trace slow-bratu-stab` + Ctrl-C in the pass: branch 1 lost,
    # the file not marked stopped; qa16); now every traced branch is saved, as during the run.
    try:
        progress.done()
        if not no_stability:
            def say(line: str) -> None:
                progress.done()
                if not (quiet and line.startswith("note: ")):
                    echo_err(line)

            scene_mod.stability_after_run(sc, request, result, say)
        progress.close()

        if step_overrides and not request.resolved_options:
            echo_err(f"warning: scene {scene!r} does not apply --ds/--ds-max/--max-steps/--uz/--stop-at/--bp-eigs; they were ignored")
        options: Any = request.resolved_options[0] if request.resolved_options else (
            {"overrides": overrides, "note": "options chosen inside the scene"} if overrides else {})
        from contin.hopfscan import number_new_points

        number_new_points(result.branches)  # HB points the stability pass located after the run
        if writer is not None:
            writer.update(parameters=result.parameters, discretization=result.discretization, options=options,
                          notes=list(result.notes), extra={**result.extra, **({} if depth is None else {"depth": depth})},
                          y=result.y, profiles=result.profiles)
            writer.set_branches(result.branches)
            writer.close()
    except BaseException as exc:
        if writer is not None:
            writer.complete = False  # (set by a close() whose publish failed)
            writer.set_branches(result.branches)
        abort(exc)

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
            for message in audit_lines(b):
                if not any(message in note for note in result.notes):  # the scene reported it already
                    echo_err(f"audit: branch {b.id}: {message}")
        if writer is not None:
            echo_err(f"wrote {writer.path}")
    from contin.stall import stalled

    for b in result.branches:
        for message in doubtful_points(b) + doubtful_special_points(b) + [m for m in [stalled(b)] if m]:
            echo_err(f"warning: branch {b.id}: {message}")
    failed = [b for b in result.branches if b.status == "MX"]
    for b in failed:
        echo_err(f"warning: branch {b.id} ended with MX: {error_line(ValueError(b.message or 'failure'))}")
    not_started = list(getattr(result, "not_started", []))
    for line in not_started:
        echo_err(f"warning: branch {error_line(ValueError(line.replace(': ', ' could not start (MX, not stored): ', 1)))}")
    if failed or not_started:
        raise click.exceptions.Exit(EXIT_INCOMPLETE)
