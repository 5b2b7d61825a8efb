"""Parameter sweeps: many independent scene runs over a grid, through any ``concurrent.futures`` executor.

A sweep file (TOML) names a scene, fixed parameters, a grid of swept parameters (cartesian
product) and what to record::

    [sweep]
    scene = "bratu"
    record = ["special_points", "extra"]   # or point types ("LP", "BP", ...) / "extra.NAME"

    [fixed]
    N = 40

    [grid]
    a = [0.5, 1.0, 2.0]                    # a list ...
    b = {start = 0.0, stop = 1.0, num = 5} # ... or evenly spaced values (log = true: geometric)

    [options]                              # optional; all keys optional
    method = "cheb"
    grid = 48
    max_steps = 400
    stability = false
    resolution_tol = "off"                 # or a number > 0 (default: the core's 3e-5)
    tol = 1e-6                             # adaptive scenes: as trace --tol (also max_grid,
                                           # special_tol, solve_check = false)

A task resolves its accuracy as ``contin trace`` does (:meth:`contin.scene.Scene.accuracy_overrides`):
an adaptive scene without ``grid`` runs adaptively at ``tol`` (default: the scene's ``default_tol``),
``grid`` alone fixes the grid.  After the run it gets the stability pass ``trace`` runs
(:func:`contin.scene.stability_after_run`; ``stability = false`` switches it off), so a task
file holds the branches and stability columns of ``contin trace`` with the same settings; the
pass's ``note:``/``warning:`` lines are among the task's notes.

Design (style notes B4): one task = one scene run at one grid point.  Tasks are pure, picklable,
top-level calls (:func:`run_task`: scene name + full parameters + options in, compact result
dict out) that also write their own HDF5 file ``DIR/tasks/<key>.h5`` (:func:`contin.io.write`
plus the attribute ``sweep_task``, the compact result as JSON), published with ``os.replace``
so a task file is either absent or complete.  The key is a hash of (scene, parameters,
options, contin version), so an interrupted sweep resumes by skipping the keys whose files
exist.  The parent process is the only writer of the merged summary (``DIR/summary.h5`` and
``DIR/summary.json``, both published atomically).

The executor is the seam: ``None`` means a local :class:`~concurrent.futures.ProcessPoolExecutor`
with BLAS/OpenMP pinned to one thread per worker; Dask distributed's
``Client.get_executor()`` plugs in unchanged (:func:`open_executor`).  With a remote Dask
cluster the output directory must be on a file system shared with the workers.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import itertools
import json
import logging
import math
import multiprocessing
import os
import time
import tomllib
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import (
    CancelledError,
    Executor,
    Future,
    ProcessPoolExecutor,
    as_completed,
)
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from contin.atomic import OutputLock, publish
from contin.jsonout import dumps as json_dumps
from contin.jsonout import to_jsonable
from contin.options import check_resolution_tol, resolution_override
from contin.scene import ENGINES, Scene, SceneError, SceneRequest, get_scene, stability_after_run

__all__ = [
    "SweepError",
    "SweepSpec",
    "SweepSummary",
    "Task",
    "TaskRecord",
    "check_spec",
    "load_sweep",
    "open_executor",
    "parse_sweep",
    "read_task_file",
    "run_sweep",
    "run_task",
    "task_key",
    "other_sweep",
    "write_summary",
]

_log = logging.getLogger("contin")

SUMMARY_FORMAT = "contin-sweep"
SUMMARY_FORMAT_VERSION = 1
POINT_TYPES = ("BP", "LP", "EP", "MX", "UZ", "XT", "CP")
#: Keys of the ``[options]`` table and their types.
OPTION_TYPES: dict[str, tuple[type, ...]] = {
    "method": (str,),
    "grid": (int,),
    "max_steps": (int,),
    "ds": (int, float),
    "ds_max": (int, float),
    "stability": (bool,),
    "kx": (list,),
    "resolution_tol": (int, float, str),  # a tolerance > 0, or "off" (the CLI's --resolution-tol)
    "engine": (str,),  # SceneRequest.engine: auto (default), numpy or numba
    # adaptive resolution, as `contin trace --tol --max-grid --special-tol --no-solve-check`
    # (Scene.accuracy_overrides; adaptive scenes only)
    "tol": (int, float),
    "max_grid": (int,),
    "special_tol": (int, float),
    "solve_check": (bool,),
}
#: How the accuracy settings are called in a sweep file (Scene.accuracy_overrides messages).
_ACCURACY_NAMES = {k: f"option {k!r}" for k in ("tol", "max_grid", "special_tol", "solve_check", "grid")}
_SECTIONS = {"sweep": {"scene", "record", "description"}, "fixed": None, "grid": None, "options": set(OPTION_TYPES)}
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class SweepError(ValueError):
    """A bad sweep file or setting: one clear sentence."""


# --------------------------------------------------------------------------- sweep files

@dataclass(frozen=True)
class Task:
    """One grid point: ``swept`` values, the full ``params`` (fixed + swept) and its ``key``."""

    index: int
    key: str
    swept: dict[str, Any]
    params: dict[str, Any]

    @property
    def file(self) -> str:
        """Task file name relative to the sweep directory."""
        return f"tasks/{self.key}.h5"


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep (see the module docstring for the file format).

    grid : swept parameter -> tuple of values, in file order (the first varies slowest).
    record : entries 'special_points', a point type ('LP', 'BP', ...), 'extra' or 'extra.NAME'.
    options : the ``[options]`` table (keys of :data:`OPTION_TYPES`).
    """

    scene: str
    grid: dict[str, tuple[Any, ...]]
    fixed: dict[str, Any] = field(default_factory=dict)
    record: tuple[str, ...] = ("special_points",)
    options: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    source: str = ""

    @property
    def n_tasks(self) -> int:
        return math.prod(len(v) for v in self.grid.values())

    def tasks(self, settings: Mapping[str, Any] | None = None) -> list[Task]:
        """The cartesian product of the grid, with stable keys (``settings``: the scene's
        :func:`task_settings`, part of the keys)."""
        names = list(self.grid)
        out = []
        for i, values in enumerate(itertools.product(*(self.grid[n] for n in names))):
            swept = dict(zip(names, values, strict=True))
            params = {**self.fixed, **swept}
            out.append(Task(i, task_key(self.scene, params, self.options, settings=settings), swept, params))
        return out

    def to_dict(self) -> dict[str, Any]:
        """The sweep as a TOML-shaped dict (stored in the summary)."""
        return {
            "sweep": {"scene": self.scene, "record": list(self.record), "description": self.description},
            "fixed": dict(self.fixed),
            "grid": {k: list(v) for k, v in self.grid.items()},
            "options": dict(self.options),
        }


def _where(source: str) -> str:
    return f" in {source}" if source else ""


def _grid_values(name: str, spec: Any, where: str) -> tuple[Any, ...]:
    if isinstance(spec, (list, tuple)):
        if not spec:
            raise SweepError(f"swept parameter {name!r}{where} has an empty list of values")
        seen: list[Any] = []
        for v in spec:
            if not isinstance(v, (int, float, str, bool)):
                raise SweepError(f"swept parameter {name!r}{where} has a value of type {type(v).__name__}; "
                                 "use numbers or strings")
            if v in seen:
                raise SweepError(f"swept parameter {name!r}{where} lists the value {v!r} twice")
            seen.append(v)
        return tuple(float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in spec)
    if isinstance(spec, dict):
        unknown = set(spec) - {"start", "stop", "num", "log"}
        missing = {"start", "stop", "num"} - set(spec)
        if unknown or missing:
            raise SweepError(f"swept parameter {name!r}{where} must be a list or a table with keys start, stop, "
                             f"num (and optional log); got keys {sorted(spec)}")
        start, stop, num, log = spec["start"], spec["stop"], spec["num"], spec.get("log", False)
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in (start, stop)):
            raise SweepError(f"swept parameter {name!r}{where}: start and stop must be finite numbers")
        if not isinstance(num, int) or isinstance(num, bool) or num < 1:
            raise SweepError(f"swept parameter {name!r}{where}: num must be an integer >= 1, got {num!r}")
        if not isinstance(log, bool):
            raise SweepError(f"swept parameter {name!r}{where}: log must be true or false, got {log!r}")
        if num > 1 and start == stop:
            raise SweepError(f"swept parameter {name!r}{where}: start == stop with num = {num} repeats one value")
        import numpy as np

        if log:
            if start <= 0 or stop <= 0:
                raise SweepError(f"swept parameter {name!r}{where}: log spacing needs start, stop > 0")
            values = np.geomspace(start, stop, num)
        else:
            values = np.linspace(start, stop, num)
        return tuple(float(v) for v in values)
    raise SweepError(f"swept parameter {name!r}{where} must be a list or a table {{start, stop, num}}, "
                     f"got {type(spec).__name__}")


def parse_sweep(doc: Mapping[str, Any], source: str = "") -> SweepSpec:
    """Validate a sweep document (the parsed TOML) and return its :class:`SweepSpec`.

    Checks the structure only; :func:`check_spec` checks it against the scene.

    Raises
    ------
    SweepError
        With one sentence naming the offending key.
    """
    where = _where(source)
    for section in doc:
        if section not in _SECTIONS:
            raise SweepError(f"unknown table [{section}]{where}; allowed: {', '.join('[' + s + ']' for s in _SECTIONS)}")
    for section, allowed in _SECTIONS.items():
        table = doc.get(section, {})
        if not isinstance(table, dict):
            raise SweepError(f"[{section}]{where} must be a table")
        if allowed is not None:
            for key in table:
                if key not in allowed:
                    raise SweepError(f"unknown key {key!r} in [{section}]{where}; allowed: {', '.join(sorted(allowed))}")
    head = doc.get("sweep", {})
    scene = head.get("scene")
    if not isinstance(scene, str) or not scene:
        raise SweepError(f"[sweep]{where} needs scene = \"NAME\"")
    record = head.get("record", ["special_points"])
    if isinstance(record, str):
        record = [record]
    if not isinstance(record, list) or not record:
        raise SweepError(f"record{where} must be a non-empty list, e.g. [\"special_points\"]")
    for r in record:
        if not isinstance(r, str) or not (r in ("special_points", "extra") or r in POINT_TYPES
                                          or (r.startswith("extra.") and len(r) > 6)):
            raise SweepError(f"cannot record {r!r}{where}; use 'special_points', a point type "
                             f"({', '.join(POINT_TYPES)}), 'extra' or 'extra.NAME'")
    fixed = dict(doc.get("fixed", {}))
    for name, value in fixed.items():
        if not isinstance(value, (int, float, str, bool)):
            raise SweepError(f"fixed parameter {name!r}{where} must be a number, string or boolean")
    grid_doc = doc.get("grid", {})
    if not grid_doc:
        raise SweepError(f"the [grid] table{where} is empty or missing; list at least one swept parameter")
    grid = {name: _grid_values(name, spec, where) for name, spec in grid_doc.items()}
    both = sorted(set(grid) & set(fixed))
    if both:
        raise SweepError(f"parameter {both[0]!r}{where} is both fixed and swept")
    options = dict(doc.get("options", {}))
    for key, value in options.items():
        types = OPTION_TYPES[key]
        if not isinstance(value, types) or (isinstance(value, bool) and bool not in types):
            raise SweepError(f"option {key!r}{where} must be of type {' or '.join(t.__name__ for t in types)}, "
                             f"got {value!r}")
    if "kx" in options and not all(isinstance(k, (int, float)) and not isinstance(k, bool) for k in options["kx"]):
        raise SweepError(f"option 'kx'{where} must be a list of numbers")
    if "resolution_tol" in options:
        try:
            _resolution_tol(options)
        except ValueError:
            raise SweepError(f"option 'resolution_tol'{where} must be a number > 0 or \"off\", "
                             f"got {options['resolution_tol']!r}") from None
    if "engine" in options and options["engine"] not in ENGINES:
        raise SweepError(f"option 'engine'{where} must be one of {', '.join(ENGINES)}, got {options['engine']!r}")
    for key in ("tol", "special_tol"):
        if key in options and not 0 < options[key] < 1:
            raise SweepError(f"option {key!r}{where} must be a relative error in (0, 1), got {options[key]}")
    from contin.limits import MIN_MAX_GRID

    if "max_grid" in options and options["max_grid"] < MIN_MAX_GRID:
        raise SweepError(f"option 'max_grid'{where} must be >= {MIN_MAX_GRID}, got {options['max_grid']}")
    for key in ("grid", "max_steps"):
        if key in options and options[key] < 1:
            raise SweepError(f"option {key!r}{where} must be >= 1, got {options[key]}")
    # (ds > 0 as for `contin trace --ds`: a negative ds was accepted and its sign silently dropped,
    # the branch traced the scene's way; qa18)
    if "ds" in options and not (options["ds"] > 0 and math.isfinite(options["ds"])):
        raise SweepError(f"option 'ds'{where} must be a finite number > 0 (the first step's length; the scene "
                         f"chooses the direction), got {options['ds']}")
    if "ds_max" in options and not (options["ds_max"] > 0 and math.isfinite(options["ds_max"])):
        raise SweepError(f"option 'ds_max'{where} must be a finite number > 0, got {options['ds_max']}")
    from contin.limits import MAX_ABS_KX, MAX_GRID, MAX_STEPS, MAX_TRACE_KX  # the command line's limits

    for key, most in (("grid", MAX_GRID), ("max_steps", MAX_STEPS), ("max_grid", MAX_GRID)):
        if key in options and options[key] > most:
            raise SweepError(f"option {key!r}{where} must be at most {most}, got {options[key]}")
    kx = options.get("kx", [])
    if len(kx) > MAX_TRACE_KX or not all(math.isfinite(k) and abs(k) <= MAX_ABS_KX for k in kx):
        raise SweepError(f"option 'kx'{where} must hold at most {MAX_TRACE_KX} finite numbers with |kx| <= {MAX_ABS_KX:g}")
    if any(k != 0 for k in kx) and options.get("stability") is False:  # dropped silently (qa15)
        raise SweepError(f"option 'kx'{where} asks for stability columns but 'stability = false' switches the "
                         f"stability pass off; drop one of them")
    description = head.get("description", "")
    if not isinstance(description, str):
        raise SweepError(f"description{where} must be a string")
    return SweepSpec(scene=scene, grid=grid, fixed=fixed, record=tuple(record), options=options,
                     description=description, source=source)


def load_sweep(path: str | os.PathLike[str]) -> SweepSpec:
    """Read and validate a sweep file (TOML); SweepError with one sentence if it is bad."""
    p = Path(path)
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise SweepError(f"no such sweep file: {str(p)!r}") from None
    except IsADirectoryError:
        raise SweepError(f"sweep file {str(p)!r} is a directory") from None
    except tomllib.TOMLDecodeError as exc:
        raise SweepError(f"{str(p)!r} is not valid TOML ({exc})") from None
    return parse_sweep(doc, source=str(p))


def check_spec(spec: SweepSpec) -> Scene:
    """The sweep's scene; SceneError for an unknown scene, SweepError for a parameter the scene
    does not document (its ``defaults``)."""
    scene = get_scene(spec.scene)
    if not scene.discretized and (spec.options.get("method") is not None or spec.options.get("grid") is not None):
        raise SweepError(f"scene {spec.scene!r} is a system of ODEs without a discretization{_where(spec.source)}: "
                         f"options method and grid do not apply")
    if scene.defaults:
        for name in [*spec.fixed, *spec.grid]:
            if name not in scene.defaults:
                raise SweepError(f"scene {spec.scene!r} has no parameter {name!r}{_where(spec.source)}; "
                                 f"its parameters: {', '.join(scene.defaults)}")
    try:
        accuracy_overrides(scene, spec.options)
    except SceneError as exc:
        raise SweepError(f"{exc}{_where(spec.source)}") from None
    return scene


def accuracy_overrides(scene: Scene, options: Mapping[str, Any]) -> dict[str, Any]:
    """The adaptive-resolution overrides of a task of ``scene`` with the sweep's ``options``:
    those of ``contin trace`` with the same ``grid``/``tol``/``max_grid``/``special_tol``/
    ``solve_check`` (:meth:`contin.scene.Scene.accuracy_overrides`, SceneError if they do not fit
    the scene)."""
    return scene.accuracy_overrides(grid=options.get("grid"), tol=options.get("tol"), max_grid=options.get("max_grid"),
                                    special_tol=options.get("special_tol"),
                                    solve_check=options.get("solve_check", True) is not False, names=_ACCURACY_NAMES)


def task_settings(scene: Scene, options: Mapping[str, Any]) -> dict[str, Any]:
    """What a task of ``scene`` computes with beyond its ``[options]`` table, for its key: the
    resolved accuracy (:func:`accuracy_overrides`), when there is one.  Empty otherwise, so the
    keys of fixed-grid sweeps are those of earlier versions; a task of an adaptive scene without
    ``grid`` has another key than the one an earlier version computed on the scene's fixed
    default grid, so such a task file is not reused in a sweep of adaptive tasks.  (The stability
    pass after the run is not part of the key: a task file from before it is reused as it is,
    without the columns the scene did not compute itself.)"""
    accuracy = accuracy_overrides(scene, options)
    return {"accuracy": accuracy} if accuracy else {}


def _canonical(value: Any) -> Any:
    """JSON-ready value with ints as floats, so that ``e = 1`` and ``e = 1.0`` share a key."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        return to_jsonable(float(value))
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return to_jsonable(value)


def task_key(scene: str, params: Mapping[str, Any], options: Mapping[str, Any], version: str | None = None,
             settings: Mapping[str, Any] | None = None) -> str:
    """Stable hash of (scene, parameters, options, contin version, and the task's
    :func:`task_settings` when there are any): 20 hex digits (SHA-256)."""
    if version is None:
        from contin import __version__ as version
    doc = {"scene": scene, "params": _canonical(params), "options": _canonical(options), "contin": version}
    if settings:
        doc["settings"] = _canonical(settings)
    text = json.dumps(doc, sort_keys=True, allow_nan=False, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


# --------------------------------------------------------------------------- one task

def _resolution_tol(options: Mapping[str, Any]) -> float | None:
    """The ``resolution_tol`` option as a trace setting ("off": None, the guard off)."""
    value = options["resolution_tol"]
    return None if value == "off" else check_resolution_tol(value)


def _request(params: Mapping[str, Any], options: Mapping[str, Any], scene: Scene) -> SceneRequest:
    """The scene request of one task, as ``contin trace`` builds it for the same settings: the
    step overrides, ``resolution_tol``, the accuracy of :func:`accuracy_overrides`; no stability
    pass on a scene without a linear-stability operator (``Scene.stability`` False), whatever
    the sweep's ``stability`` option."""
    overrides = {k: options[k] for k in ("max_steps", "ds", "ds_max") if k in options}
    if "resolution_tol" in options:  # (scenes read it from the overrides too: gravity's fold seeds)
        overrides["resolution_tol"] = _resolution_tol(options)
    overrides.update(accuracy_overrides(scene, options))
    return SceneRequest(
        params=dict(params),
        method=options.get("method"),
        grid=options.get("grid"),
        stability=bool(options.get("stability", True)) and scene.stability,
        kx=tuple(float(k) for k in options.get("kx", ())),
        overrides=overrides,
        engine=options.get("engine", "auto"),
    )


@contextlib.contextmanager
def _quiet_scene_loading() -> Iterator[None]:
    """Silence the 'skipping scenes from ...' warnings in workers: the parent already reported
    broken scene modules when it checked the sweep, once rather than once per task."""
    log = logging.getLogger("contin")
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(level)


def _special_point(sp: Any, branch_id: str) -> dict[str, Any]:
    return {
        "type": sp.type,
        "label": sp.name,
        "branch": str(branch_id),
        "params": dict(sp.params),
        "phi": sp.order_parameter,
        "converged": bool(sp.converged),
        "note": sp.note,
    }


def run_task(scene_name: str, params: Mapping[str, Any], options: Mapping[str, Any],
             path: str | None = None) -> dict[str, Any]:
    """Run one scene at one parameter set and return its compact, JSON-ready result.

    Result keys: ``key``, ``status`` ('ok'; 'MX' if a branch ended in failure; 'error' if the
    scene raised), ``reason`` (why, '' when ok), ``special_points`` (list of
    ``{type, label, branch, params, phi, converged, note}``), ``extra`` (the scene's extra
    results), ``branches`` (status summaries), ``notes``, ``parameters`` (the full set used),
    ``seconds``.  Never raises for a failing scene: bad parameters and crashes are results.
    When ``path`` is given the task also writes its HDF5 file there (:func:`_write_task_file`).
    """
    from contin.hopfscan import number_new_points
    from contin.jsonout import branch_summary

    t0 = time.perf_counter()
    key = task_key(scene_name, params, options)
    base: dict[str, Any] = {"key": key, "status": "ok", "reason": "", "special_points": [], "extra": {},
                            "branches": [], "notes": [], "parameters": dict(params)}
    result = None
    try:
        with _quiet_scene_loading():
            scene = get_scene(scene_name)
        base["key"] = key = task_key(scene_name, params, options, settings=task_settings(scene, options))
        with resolution_override(_resolution_tol(options)) if "resolution_tol" in options else contextlib.nullcontext():
            request = _request(params, options, scene)
            result = scene.run(request)
            if options.get("stability", True):  # the pass `contin trace` runs after the scene's run
                stability_after_run(scene, request, result, lambda line: result.notes.append(line.removeprefix("note: ")),
                                    kx_name="option kx")
            number_new_points(result.branches)  # HB points a stability pass located (as trace numbers them)
    except (SceneError, ValueError) as exc:
        base.update(status="error", reason=str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    except Exception as exc:  # noqa: BLE001 -- a crashing task is a result, never the end of a sweep
        # the reason names the innermost frame; the full traceback goes into the task file
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" ({Path(frame.filename).name}:{frame.lineno})"
        base.update(status="error", reason=f"{type(exc).__name__}: {exc}".splitlines()[0] + where,
                    traceback=traceback.format_exc())
        _log.debug("task %s crashed", key, exc_info=True)
    if result is not None:
        failed = [b for b in result.branches if b.status == "MX"]
        base.update(
            special_points=[_special_point(sp, b.id) for b in result.branches for sp in b.special_points],
            extra=dict(result.extra),
            branches=[branch_summary(b) for b in result.branches],
            notes=list(result.notes),
            parameters={**dict(params), **dict(result.parameters)},
        )
        if failed:
            base.update(status="MX", reason="; ".join(f"branch {b.id}: {b.message or 'MX'}" for b in failed))
    base["seconds"] = time.perf_counter() - t0
    doc = to_jsonable(base)
    if path is not None:
        _write_task_file(path, doc, scene_name, options, result)
    return doc


def _write_task_file(path: str, doc: Mapping[str, Any], scene_name: str, options: Mapping[str, Any],
                     result: Any) -> None:
    """Publish the task's HDF5 file atomically.

    The run (branches, special points, provenance) goes through :func:`contin.io.write` into
    ``PATH.part``; the compact result is added as the root attribute ``sweep_task`` (JSON) and
    the file is renamed to ``PATH`` only then, so ``PATH`` exists iff the task is finished.
    """
    from contin import io

    final = Path(path)
    part = final.with_name(final.name + ".part")
    meta: dict[str, Any] = {"scene": scene_name, "options": dict(options),
                            "command": f"contin sweep (task {doc['key']})"}
    if result is not None:
        meta.update(parameters=result.parameters, discretization=result.discretization, y=result.y,
                    profiles=result.profiles, notes=result.notes, extra=result.extra)
        branches = result.branches
    else:
        meta.update(parameters=doc["parameters"], notes=[doc["reason"]])
        branches = []

    def write(tmp: Path) -> None:
        # One in-memory image, written with plain writes (contin.io._publish): HDF5 editing a file
        # in place on a full disk crashed the worker.
        io.write(tmp, branches, attrs={"sweep_task": json_dumps(doc)}, **meta)

    publish(final, write, temporary=part)


def read_task_file(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The compact result stored in a finished task file, or None if the file is absent,
    unfinished or unreadable (then the task must be recomputed)."""
    p = Path(path)
    if not p.is_file():
        return None
    try:
        import h5py

        with h5py.File(p, "r") as f:
            if (not bool(f.attrs.get("complete", False)) or "sweep_task" not in f.attrs
                    or str(f.attrs.get("stopped", ""))):  # a run that stopped is not finished
                return None
            doc = json.loads(f.attrs["sweep_task"])
    except (OSError, ValueError, KeyError) as exc:
        _log.warning("task file %s is unreadable (%s); recomputing it", p, exc)
        return None
    if not (isinstance(doc, dict) and doc.get("key") == p.stem):
        return None
    # the whole file, as every command reads it: a task file whose branch 0 was lost was reused
    # as 'ok' with the results of its summary attribute, which the file no longer backs (qa15)
    from contin import io

    try:
        io.load(p)
    except (io.FileFormatError, OSError, ValueError, KeyError) as exc:
        _log.warning("task file %s is damaged (%s); recomputing it", p, str(exc).splitlines()[0] if str(exc) else exc)
        return None
    return doc


# --------------------------------------------------------------------------- the sweep

@dataclass
class TaskRecord:
    """Outcome of one task in a sweep.

    status : 'ok', 'MX', 'error' (the task ran and failed), 'lost' (its worker died or the
        executor failed: no task file, recomputed on resume) or 'pending' (sweep interrupted).
    cached : True if it was read from an existing task file instead of computed.
    result : the compact result of :func:`run_task` (empty for lost/pending tasks).
    """

    index: int
    key: str
    swept: dict[str, Any]
    status: str
    reason: str = ""
    cached: bool = False
    file: str = ""
    result: dict[str, Any] = field(default_factory=dict)

    @property
    def special_points(self) -> list[dict[str, Any]]:
        return list(self.result.get("special_points", []))

    @property
    def extra(self) -> dict[str, Any]:
        return dict(self.result.get("extra", {}))


@dataclass
class SweepSummary:
    """All task outcomes of a sweep, in grid order."""

    spec: SweepSpec
    outdir: Path
    records: list[TaskRecord]

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.records)

    @property
    def n_cached(self) -> int:
        return sum(r.cached for r in self.records)

    @property
    def n_computed(self) -> int:
        return sum(not r.cached and r.status in ("ok", "MX", "error") for r in self.records)

    @property
    def failed(self) -> list[TaskRecord]:
        return [r for r in self.records if r.status != "ok"]

    def counts(self) -> dict[str, int]:
        out = {s: self.count(s) for s in ("ok", "MX", "error", "lost", "pending")}
        return {"tasks": len(self.records), **out, "cached": self.n_cached, "computed": self.n_computed}

    def selected_points(self, record: TaskRecord) -> list[dict[str, Any]]:
        """The record's special points that the sweep asked to record."""
        wanted = self.spec.record
        if "special_points" in wanted:
            return record.special_points
        return [sp for sp in record.special_points if sp["type"] in wanted]

    def selected_extra(self, record: TaskRecord) -> dict[str, Any]:
        """The record's extra results that the sweep asked to record (missing ones as None)."""
        if "extra" in self.spec.record:
            return record.extra
        extra = record.extra
        return {r[6:]: extra.get(r[6:]) for r in self.spec.record if r.startswith("extra.")}

    def missing_extra(self) -> list[str]:
        """The ``extra.NAME`` entries of ``record`` that no task which ran (ok or MX) has in its
        extra results: a misspelled or unknown name, recorded as null in every task."""
        ran = [r for r in self.records if r.status in ("ok", "MX")]
        names = [r[6:] for r in self.spec.record if r.startswith("extra.")]
        return [n for n in names if ran and not any(n in r.extra for r in ran)]

    def to_dict(self) -> dict[str, Any]:
        """The JSON document written to ``summary.json`` (strict JSON)."""
        tasks = []
        for r in self.records:
            tasks.append({
                "index": r.index, "key": r.key, "params": r.swept, "status": r.status, "reason": r.reason,
                "cached": r.cached, "file": r.file, "seconds": r.result.get("seconds"),
                "special_points": self.selected_points(r), "extra": self.selected_extra(r),
                "branches": r.result.get("branches", []),
            })
        return to_jsonable({
            "format": SUMMARY_FORMAT, "format_version": SUMMARY_FORMAT_VERSION,
            "scene": self.spec.scene, "source": self.spec.source, "outdir": str(self.outdir),
            "sweep": self.spec.to_dict(), "counts": self.counts(), "tasks": tasks,
        })


def _format_progress(done: int, total: int, rec: TaskRecord) -> str:
    params = " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in rec.swept.items())
    width = len(str(total))
    if rec.status == "ok":
        types: dict[str, int] = {}
        for sp in rec.special_points:
            types[sp["type"]] = types.get(sp["type"], 0) + 1
        what = ", ".join(f"{n} {t}" for t, n in sorted(types.items())) or "no special points"
        tail = f"ok  {what}"
    else:
        tail = f"{rec.status}: {rec.reason}"
    secs = rec.result.get("seconds")
    timing = f"  ({secs:.1f} s)" if isinstance(secs, (int, float)) else ""
    return f"[{done:>{width}}/{total}] {params}  {tail}{timing}"


@contextlib.contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Pin BLAS/OpenMP to one thread in child processes started inside the block.

    The variables must be set before a worker imports numpy, so they go into the parent's
    environment (inherited at spawn) and are restored afterwards; a user's explicit setting wins.
    """
    saved = {v: os.environ.get(v) for v in _THREAD_VARS}
    for v in _THREAD_VARS:
        os.environ.setdefault(v, "1")
    try:
        yield
    finally:
        for v, old in saved.items():
            if old is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = old


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask, which containers and ``taskset`` set;
    ``os.cpu_count()`` counts the whole machine)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


def worker_count(jobs: int | None) -> tuple[int, str]:
    """Local workers for ``jobs`` and a note when it was capped.

    Every task is CPU-bound and single-threaded (BLAS pinned to one thread), so more workers
    than usable CPUs only oversubscribe them: the tasks time-share the cores, each is slower,
    and they all hold their memory at once.  ``-j 64`` on a 2-CPU machine therefore runs 2
    workers (a note says so) instead of being refused: the sweep gives the same results, and
    the user asked for "as parallel as possible", not for 64 processes.
    """
    cpus = usable_cpus()
    if jobs is None or jobs <= cpus:
        return (cpus if jobs is None else jobs), ""
    return cpus, (f"note: -j {jobs} capped at {cpus} worker(s), the CPUs this process may use "
                  f"(the tasks are CPU-bound: more workers would only oversubscribe them)")


def _lost(task: Task, reason: str) -> TaskRecord:
    return TaskRecord(task.index, task.key, task.swept, "lost", reason, file="")


def run_sweep(
    spec: SweepSpec,
    outdir: str | os.PathLike[str],
    executor: Executor | None = None,
    jobs: int | None = None,
    progress: Callable[[str], None] | None = None,
    retry_failed: bool = False,
) -> SweepSummary:
    """Run (or resume) a sweep and write its summary.

    Parameters
    ----------
    spec : the sweep (:func:`load_sweep`).
    outdir : output directory; task files go to ``outdir/tasks``.
    executor : any ``concurrent.futures.Executor`` (e.g. Dask's ``client.get_executor()``);
        None = a process pool of ``jobs`` workers (default: all usable CPUs; more are capped at
        that, :func:`worker_count`) created and shut down here.
    progress : called with one line per finished task (and one line about resumed tasks).
    retry_failed : recompute tasks whose file records a failure ('MX' or 'error').

    Returns
    -------
    SweepSummary
        Also written to ``outdir/summary.h5`` and ``outdir/summary.json`` (atomically).
        A failing task never stops the sweep; it is recorded with its reason.

    Raises
    ------
    SceneError, SweepError
        For an unknown scene or parameter, before any task runs.
    """
    scene = check_spec(spec)
    if jobs is not None and jobs < 1:
        raise SweepError(f"jobs must be >= 1, got {jobs}")
    out = Path(outdir).resolve()
    taskdir = out / "tasks"
    try:
        taskdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepError(f"cannot create the output directory {str(out)!r}: {exc.strerror or exc}") from None
    # One sweep per directory: a second one would delete the first one's partial files (below)
    # and race it for the summary (tasks were lost with raw FileNotFoundError/BlockingIOError).
    lock = OutputLock(out, directory=True).acquire()
    try:
        return _run_sweep_locked(spec, out, taskdir, executor, jobs, progress, retry_failed,
                                 task_settings(scene, spec.options))
    finally:
        lock.release()


def other_sweep(outdir: str | os.PathLike[str], spec: SweepSpec) -> str | None:
    """A sentence when ``outdir`` holds the summary of another sweep than ``spec`` (another scene,
    grid, fixed values or options), else None.  Its task files stay (tasks are keyed by their
    inputs, so the shared ones are reused), but the summary is replaced by this sweep's: said,
    not silent (qa15: it was replaced without a word)."""
    path = Path(outdir) / "summary.json"
    try:
        previous = json.loads(path.read_text()).get("sweep")
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(previous, dict) or previous == to_jsonable(spec.to_dict()):
        return None
    scene = previous.get("sweep", {}).get("scene", "?") if isinstance(previous.get("sweep"), dict) else "?"
    return (f"{path} is the summary of another sweep (scene {scene!r}); it is replaced by this one's (its task "
            f"files are kept: rerun that sweep with the same -o to rebuild its summary)")


def _die_with_parent(parent: int) -> None:
    """Worker initializer: end this worker when the sweep's parent process dies.

    Without it a killed ``contin sweep`` left its workers (and the resource tracker, which exits
    when they do) computing as orphans.  Linux: PR_SET_PDEATHSIG sends SIGKILL at once; elsewhere
    (and as a fallback) a watchdog thread checks every second whether the parent changed.
    """
    import signal
    import threading

    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(1.0)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="contin-parent-watch", daemon=True).start()


def _run_sweep_locked(spec: SweepSpec, out: Path, taskdir: Path, executor: Executor | None, jobs: int | None,
                      progress: Callable[[str], None] | None, retry_failed: bool,
                      settings: Mapping[str, Any]) -> SweepSummary:
    for stale in itertools.chain(taskdir.glob("*.h5.part"), taskdir.glob("*.tmp")):
        stale.unlink(missing_ok=True)  # left by a killed task; the single parent owns the directory (locked)

    def say(line: str) -> None:
        if progress is not None:
            progress(line)

    tasks = spec.tasks(settings)
    records: dict[int, TaskRecord] = {}
    todo: list[Task] = []
    for task in tasks:
        doc = read_task_file(out / task.file)
        if doc is not None and not (retry_failed and doc.get("status") != "ok"):
            records[task.index] = TaskRecord(task.index, task.key, task.swept, doc["status"], doc.get("reason", ""),
                                             cached=True, file=task.file, result=doc)
        else:
            todo.append(task)
    if records:
        say(f"resuming: {len(records)} of {len(tasks)} tasks already finished in {taskdir}")
    summary = SweepSummary(spec, out, [])

    def finish() -> SweepSummary:
        # A task whose worker finished its file but whose result was not collected yet (Ctrl-C)
        # is done: the summary must match the task files (it said ok = 1, pending = 7 with 4 files).
        for t in tasks:
            if t.index not in records:
                doc = read_task_file(out / t.file)
                if doc is not None:
                    records[t.index] = TaskRecord(t.index, t.key, t.swept, doc["status"], doc.get("reason", ""),
                                                  file=t.file, result=doc)
        summary.records = [records.get(t.index) or TaskRecord(t.index, t.key, t.swept, "pending", "sweep interrupted")
                           for t in tasks]
        write_summary(summary)
        return summary

    if not todo:
        return finish()
    own = executor is None
    env = _single_threaded_children() if own else contextlib.nullcontext()
    futures: dict[Future[dict[str, Any]], Task] = {}
    try:
        with env:
            if own:
                executor = ProcessPoolExecutor(max_workers=min(worker_count(jobs)[0], len(todo)),
                                               mp_context=multiprocessing.get_context("spawn"),
                                               initializer=_die_with_parent, initargs=(os.getpid(),))
            assert executor is not None
            for task in todo:
                futures[executor.submit(run_task, spec.scene, task.params, spec.options, str(out / task.file))] = task
            done = len(records)
            for fut in as_completed(futures):
                task = futures[fut]
                try:
                    doc = fut.result()
                    rec = TaskRecord(task.index, task.key, task.swept, doc["status"], doc["reason"],
                                     file=task.file, result=doc)
                except (Exception, CancelledError) as exc:  # worker died, executor broke, file not written
                    rec = _lost(task, f"{type(exc).__name__}: {exc}".splitlines()[0])
                records[task.index] = rec
                done += 1
                say(_format_progress(done, len(tasks), rec))
    except BaseException:
        for fut in futures:
            fut.cancel()
        if own and executor is not None:
            # Stop our workers before the summary is written: a task still running would publish
            # its file after it, and the summary would not match the task files.
            for proc in list(getattr(executor, "_processes", {}).values()):
                proc.terminate()
            executor.shutdown(wait=True, cancel_futures=True)
            executor = None
        finish()  # record what is done; unfinished tasks are 'pending' and rerun on resume
        raise
    finally:
        if own and executor is not None:
            executor.shutdown(wait=True, cancel_futures=True)
    return finish()


# --------------------------------------------------------------------------- summary files

def _publish(path: Path, write: Callable[[Path], None]) -> None:
    publish(path, write)


def _scalar_column(values: Sequence[Any]) -> Any:
    """A float column if every value is a number or None (None -> NaN: the reason column says why),
    else text (non-scalars as JSON)."""
    import numpy as np

    if all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) or v in ("inf", "-inf")
           for v in values):
        return np.array([math.nan if v is None else float(v) for v in values], dtype=float)
    return np.array([v if isinstance(v, str) else json.dumps(v) for v in values], dtype=object)


def write_summary(summary: SweepSummary) -> tuple[Path, Path]:
    """Write ``summary.h5`` and ``summary.json`` into ``summary.outdir`` (each atomically).

    ``summary.h5`` layout::

        /                 attrs: format='contin-sweep', format_version, contin_version, scene,
                                 sweep (JSON of the sweep file), counts (JSON), created_utc,
                                 libraries (JSON: versions of the numerical stack)
        /tasks/           one row per grid point, in grid order:
            key, status, reason, file (text); cached (bool); seconds (float)
            params/<name> swept parameter values
            n_<TYPE>      number of recorded special points of each type (int)
            extra/<name>  recorded scalar extras (float; text/JSON otherwise)
        /special_points/  one row per recorded special point:
            task (row in /tasks), key, type, label, branch, note (text); phi (float);
            converged (bool); params/<name> parameter values at the point
    """
    import h5py
    import numpy as np

    from contin import __version__
    from contin.io import library_versions

    s = summary
    text = h5py.string_dtype()
    recs = s.records
    points = [(i, sp) for i, r in enumerate(recs) for sp in s.selected_points(r)]
    extras = [s.selected_extra(r) for r in recs]
    extra_names: list[str] = []
    for e in extras:
        extra_names.extend(n for n in e if n not in extra_names)
    types = [t for t in POINT_TYPES if "special_points" in s.spec.record or t in s.spec.record]

    def fill(path: Path) -> None:
        with h5py.File(path, "w") as f:
            a = f.attrs
            a["format"] = SUMMARY_FORMAT
            a["format_version"] = SUMMARY_FORMAT_VERSION
            a["contin_version"] = __version__
            a["libraries"] = json.dumps(library_versions())
            a["scene"] = s.spec.scene
            a["sweep"] = json_dumps(s.spec.to_dict())
            a["counts"] = json.dumps(s.counts())
            a["created_utc"] = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
            g = f.create_group("tasks")
            for name in ("key", "status", "reason", "file"):
                g.create_dataset(name, data=np.array([getattr(r, name) for r in recs], dtype=object), dtype=text)
            g.create_dataset("cached", data=np.array([r.cached for r in recs], dtype=bool))
            g.create_dataset("seconds", data=_scalar_column([r.result.get("seconds") for r in recs]))
            pg = g.create_group("params", track_order=True)
            for name in s.spec.grid:
                col = _scalar_column([to_jsonable(r.swept[name]) for r in recs])
                pg.create_dataset(name.replace("/", "%2F"), data=col, dtype=text if col.dtype == object else None)
            for t in types:
                g.create_dataset(f"n_{t}", data=np.array(
                    [sum(sp["type"] == t for sp in r.special_points) for r in recs], dtype=np.int64))
            eg = g.create_group("extra", track_order=True)
            for name in extra_names:
                col = _scalar_column([e.get(name) for e in extras])
                eg.create_dataset(name.replace("/", "%2F"), data=col, dtype=text if col.dtype == object else None)
            sg = f.create_group("special_points")
            sg.create_dataset("task", data=np.array([i for i, _ in points], dtype=np.int64))
            sg.create_dataset("key", data=np.array([recs[i].key for i, _ in points], dtype=object), dtype=text)
            for name in ("type", "label", "branch", "note"):
                sg.create_dataset(name, data=np.array([sp[name] for _, sp in points], dtype=object), dtype=text)
            sg.create_dataset("phi", data=_scalar_column([sp["phi"] for _, sp in points]).astype(float))
            sg.create_dataset("converged", data=np.array([sp["converged"] for _, sp in points], dtype=bool))
            names: list[str] = []
            for _, sp in points:
                names.extend(n for n in sp["params"] if n not in names)
            spg = sg.create_group("params", track_order=True)
            for name in names:
                col = _scalar_column([sp["params"].get(name) for _, sp in points])
                spg.create_dataset(name.replace("/", "%2F"), data=col, dtype=text if col.dtype == object else None)

    h5 = s.outdir / "summary.h5"
    js = s.outdir / "summary.json"
    _publish(h5, fill)
    doc = json.dumps(s.to_dict(), indent=1, allow_nan=False)
    _publish(js, lambda p: p.write_text(doc + "\n"))
    return h5, js


# --------------------------------------------------------------------------- executors

DASK_HINT = "pip install -e '.[dask]'"


@contextlib.contextmanager
def open_executor(scheduler: str | None, jobs: int | None = None) -> Iterator[Executor | None]:
    """The executor for ``--scheduler``: None (the default process pool, made by
    :func:`run_sweep`), ``'local-dask'`` (a LocalCluster of ``jobs`` single-threaded workers) or a
    Dask scheduler address ``'tcp://host:port'`` (``Client(address).get_executor()``)."""
    if scheduler is None:
        yield None
        return
    if scheduler != "local-dask" and "://" not in scheduler:
        raise SweepError(f"unknown scheduler {scheduler!r}; use tcp://HOST:PORT or local-dask")
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise SweepError(f"--scheduler {scheduler} needs Dask distributed, which is not installed: {DASK_HINT}") from None
    with contextlib.ExitStack() as stack:
        if scheduler == "local-dask":
            cluster = stack.enter_context(LocalCluster(
                n_workers=worker_count(jobs)[0], threads_per_worker=1, processes=True,
                dashboard_address=None, silence_logs=logging.ERROR))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(scheduler, timeout="10s"))
            except (OSError, TimeoutError) as exc:
                raise SweepError(f"cannot reach the Dask scheduler at {scheduler}: {exc}".splitlines()[0]) from None
        # pure=False: every submit is a fresh computation (a retried task must really rerun)
        yield client.get_executor(pure=False)

