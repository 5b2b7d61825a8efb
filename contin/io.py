"""HDF5 storage of continuation runs: one self-describing file per run, readable with h5py alone.

Layout (format "contin", format_version 2; version 1 files are read too)
-------------------------------------------------------------------------
::

    /                         attrs: format="contin", format_version=2, contin_version,
                                     git_commit, libraries (JSON: python, numpy, scipy, h5py
                                     and numba versions; bitwise results need the same ones),
                                     created_utc, command (exact argv), scene,
                                     parameters, discretization, options, notes, extra (JSON
                                     text), diagram_x, diagram_y, complete (bool),
                                     stopped (why an incomplete run stopped: "interrupted",
                                     "terminated by SIGTERM", "failed: <reason>"; "" otherwise)
    /grid/y                   (N,) wall-normal grid of the profiles (optional)
    /branches/<id>/           attrs: id, parameter, free, status, message, closed, kind,
                                     parent, position, param_names, observable_names,
                                     datasets (JSON: quantity name -> dataset name)
        <param>               (S,) one per parameter (fixed ones too), e.g. H, nu
        <observable>          (S,) one per observable, e.g. phi
        ds, newton_iterations (S,)
        states                (S, n)    or (M, n) with state_index (M,) when only every
                                        k-th state was kept (save_every)
        tangents              (S, n + len(free))
        grid                  (S,) int  only for adaptive runs (version 2): the grid size of
                                        each point (``Branch.grid``); the grid changes are
                                        where it changes
        sizes                 (S,) int  only when the points' state sizes differ (version 2):
                                        states/tangents rows are then left-aligned and
                                        NaN-padded to the widest (``Branch.sizes``)
        stable, n_unstable    (S,)      only when stability was computed (n_unstable = -1:
                                        the eigenproblem failed at that point)
        eigenvalues           (S, k)    complex, leading eigenvalues, only when computed
                                        (group attrs stability_kx, stability_kz: the
                                        wavenumbers of these columns)
        audit                 (A,)      text messages
        profile_index         (P,)      point indices along the branch of the stored profiles
        profiles/<name>       (P, N)    e.g. nu, u, T against /grid/y
    /special_points/          one row per special point, columns:
        branch, name, type, note (text); branch_position (row of the branch in write
        order), label, index, state_size, tangent_size (int);
        phi, bracket_lo, bracket_hi (float); converged (bool);
        params/<name>         one column per parameter name (attr param_names)
        params_present        (K, P) bool: which parameters each row has
        data/<name>           one float column per SpecialPoint.data name (attr data_names),
                              e.g. omega and l1 of HB rows, value of UZ rows
        data_present          (K, D) bool: which data each row has
        states                (K, n_max) located states (NaN-padded to state_size)
        tangents              (K, m_max) tangents (tangent_size = -1 when none)
        grid                  (K,) int  grid size the point was located on (-1: the
                                        problem's own grid; version 2)
        profiles/<name>       (K, N) profiles of the located states (optional)

Parameters, observables and dataset names are stored under the quantity's own name; a name
that clashes with a reserved dataset (``ds``, ``states``...) or contains ``/`` is stored under
an escaped name, and the ``datasets`` attribute maps quantity names to dataset names.

Crash safety
------------
A file is never modified in place.  Every publish writes the whole run to ``FILE.tmp``,
flushes and fsyncs it, then renames it over ``FILE`` (``os.replace`` is atomic on POSIX), so
``FILE`` is at every instant either absent or a complete, consistent file: a SIGKILL at any
moment leaves the last published version (attr ``complete=False`` while the run is still going)
and at worst a stale ``FILE.tmp``.  :class:`H5Writer` republishes after finished branches;
the runs are small (a few MB), so rewriting is cheap and far simpler than in-place appends.
Cheap is not free (a publish of the main job's seven branches takes ~60 ms, a whole run's
publishes grow with the square of its branch count), so a writer may be given a
``checkpoint_ratio`` c: a finished branch is then published at once only when the time since
the last publish ended is at least c times that publish's duration, else it waits for the next
branch, an interrupt or the final publish.  The work a SIGKILL can lose is then bounded by c
publishes' worth of computing time, and publishing takes at most 1/(1 + c) of the run.

Non-finite data
---------------
Nothing non-finite that must be finite reaches a file: before every publish each branch is
checked (:func:`check_finite`) and a violation raises :class:`NonFiniteError` (a ValueError,
so the CLI prints one ``Error:`` line) naming the branch, the quantity and the first bad row;
the previously published file is left untouched.  Must be finite: ``states``, ``tangents``,
``ds``, the free parameter columns, every observable column that has any finite value, and
the states and free-parameter values of the special points.  Allowed: ``inf`` (not NaN) in a
fixed parameter column or a special point's fixed parameter (``Fr = inf`` means no gravity), an observable that is NaN at every
point (the problem does not define it), and NaN ``phi``/``bracket`` of a special point (no
order parameter / no bracket).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import functools
import json
import logging
import math
import os
import shlex
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from contin.atomic import OutputLock, check_target, publish, write_bytes

from contin.branch import Branch, SpecialPoint, first_crossing, interleave_located
from contin.filecheck import (BadDataset, bad_parameter, check_branch, check_orbits, check_profile_grid, check_profile_widths, check_special_point,
                              first_bad_row)
from contin.jsonout import dumps as _json_dumps
from contin.options import AdaptOptions, ContinuationOptions, DetectionOptions, NewtonOptions, StepOptions

if TYPE_CHECKING:
    import h5py

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "FileFormatError",
    "H5Writer",
    "NonFiniteError",
    "check_finite",
    "git_commit",
    "library_versions",
    "load",
    "options_from_dict",
    "restart",
    "write",
]

FORMAT = "contin"
FORMAT_VERSION = 2
#: Versions :func:`load` reads.  Version 2 added the optional per-point ``grid`` and ``sizes``
#: branch datasets and the special-point ``grid`` column (adaptive resolution); a version-1
#: file is a version-2 file without them.
READABLE_VERSIONS = (1, 2)

_log = logging.getLogger("contin")

_RESERVED = frozenset({
    "ds", "newton_iterations", "states", "tangents", "stable", "n_unstable", "eigenvalues",
    "audit", "profiles", "profile_index", "state_index",
})


@functools.cache
def _str() -> Any:
    """h5py's variable-length UTF-8 string dtype.  h5py is imported on the first write or read,
    not with this module: a run computes its first branch before anything is published."""
    import h5py

    return h5py.string_dtype()


ProfileFn = Callable[[np.ndarray], Mapping[str, np.ndarray]]


_HAS_STATE_INDEX = "state_index" in {f.name for f in dataclasses.fields(Branch)}


class FileFormatError(ValueError):
    """A file that is not a readable contin HDF5 file (corrupt, truncated or foreign)."""


class NonFiniteError(ValueError):
    """A branch holds NaN or inf where a stored value must be finite (see the module docstring)."""


def check_finite(branch: Branch) -> None:
    """Raise :class:`NonFiniteError` if ``branch`` holds NaN/inf where a file needs finite data.

    Rules (module docstring, "Non-finite data"): states, tangents, ds, free parameters, partly
    defined observables and special-point states/free parameters must be finite; fixed
    parameters may be inf but not NaN.
    """
    free = set(branch.free) | {branch.parameter}

    def refuse(what: str, row: int) -> None:
        raise NonFiniteError(f"branch {branch.id}: {what} is not finite at point {row}; "
                             f"refusing to write non-finite data (the solver produced an invalid state)")

    states, tangents = branch.states, branch.tangents
    if branch.sizes is not None:  # NaN padding of states of several sizes is not a bad value
        states = [states[r, : int(branch.sizes[i])] for r, i in enumerate(branch.stored_points)]
        tangents = [tangents[i, : int(branch.sizes[i]) + branch.tangent_extra] for i in range(len(branch))]
    for what, values in (("the state", states), ("the tangent", tangents), ("the step ds", branch.ds)):
        row = (next((k for k, v in enumerate(values) if not np.all(np.isfinite(v))), None)
               if isinstance(values, list) else first_bad_row(values))
        if row is not None:
            refuse(what, row)
    for name, values in branch.params.items():
        row = first_bad_row(values, allow_inf=name not in free)
        if row is not None:
            refuse(f"parameter {name}", row)
    for name, values in branch.observables.items():
        arr = np.asarray(values)
        if arr.dtype.kind in "fc" and arr.size and np.isnan(arr).all():
            continue  # not defined by the problem
        row = first_bad_row(arr)
        if row is not None:
            refuse(f"observable {name}", row)
    for sp in branch.special_points:
        if sp.state is not None and first_bad_row(np.ravel(sp.state)) is not None:
            refuse(f"the located state of {sp.name}", sp.index)
        for name, v in sp.params.items():  # free: finite; fixed: not NaN (as the reader checks)
            if bad_parameter(name, v, free):
                refuse(f"parameter {name} of {sp.name}", sp.index)


# --------------------------------------------------------------------------- provenance

@functools.lru_cache(maxsize=None)
def git_commit(path: str | None = None) -> str:
    """Commit of the git tree holding ``path`` (default: the contin sources), else 'unknown'.

    A ``-dirty`` suffix marks uncommitted changes to tracked files.
    """
    where = path or str(Path(__file__).resolve().parent)
    try:
        sha = subprocess.run(["git", "-C", where, "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", where, "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (sha + "-dirty" if dirty else sha) or "unknown"


def library_versions() -> dict[str, str]:
    """Versions of the numerical stack a run used (Python, numpy, scipy, h5py, numba if loaded).

    A file regenerated with other versions agrees with the shipped one to rounding, not bitwise:
    results/pitchfork.h5 of numpy 2.4.6 / scipy 1.17.1 / numba 0.68.1 differs from the one
    written before in the last bits (H_c within 1e-11 relative), and a step-size sequence that
    depends on those bits moved n = 2's points by 8e-7.  Recording the versions says which.
    """
    import platform

    import scipy

    out = {"python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__}
    h5 = sys.modules.get("h5py")
    if h5 is not None:
        out["h5py"] = h5.__version__
    numba = sys.modules.get("numba")  # only when the compiled engine ran (importing it costs ~0.3 s)
    if numba is not None:
        out["numba"] = numba.__version__
    return out


def _contin_version() -> str:
    from contin import __version__

    return __version__


def _options_dict(options: ContinuationOptions | Mapping[str, Any] | None) -> dict[str, Any]:
    if options is None:
        return {}
    if dataclasses.is_dataclass(options) and not isinstance(options, type):
        out = dataclasses.asdict(options)
        # event functions are code, not data: the file records their names
        out["events"] = sorted(out.get("events", {}))
        return out
    return dict(options)


def options_from_dict(d: Mapping[str, Any]) -> ContinuationOptions:
    """Rebuild :class:`ContinuationOptions` from the ``options`` attribute of a file."""
    d = dict(d)
    kw: dict[str, Any] = {}
    for key, cls in (("newton", NewtonOptions), ("step", StepOptions), ("detection", DetectionOptions),
                     ("adapt", AdaptOptions)):
        if isinstance(d.get(key), Mapping):
            kw[key] = cls(**d.pop(key))
    if "bounds" in d:
        kw["bounds"] = {k: (float(lo), float(hi)) for k, (lo, hi) in d.pop("bounds").items()}
    d.pop("events", None)  # only their names are stored; the functions cannot be rebuilt
    return ContinuationOptions(**kw, **d)


def _jsonload(text: Any, default: Any) -> Any:
    if text is None:
        return default
    from contin.jsonout import from_json_value

    def fix(obj: Any) -> Any:  # 'inf' strings back to floats (see contin.jsonout)
        if isinstance(obj, dict):
            return {k: fix(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [fix(v) for v in obj]
        return from_json_value(obj) if obj in ("inf", "-inf") else obj

    return fix(json.loads(text))


# --------------------------------------------------------------------------- writing

def _escape(name: str, taken: set[str]) -> str:
    """A dataset name for quantity ``name``: itself unless reserved, used or containing '/'."""
    ds = name.replace("%", "%25").replace("/", "%2F")
    if ds in ("", ".") or ds in _RESERVED or ds in taken:
        ds = "q%" + ds
        while ds in _RESERVED or ds in taken:
            ds = "q%" + ds
    taken.add(ds)
    return ds


def _column(values: Any) -> np.ndarray:
    arr = np.asarray(values)
    if arr.dtype.kind in "USO":
        return np.asarray([str(v) for v in arr.ravel()], dtype=object).reshape(arr.shape)
    return arr


def _put(group: h5py.Group, name: str, values: Any) -> h5py.Dataset:
    arr = _column(values)
    if arr.dtype == object:
        return group.create_dataset(name, data=arr, dtype=_str())
    return group.create_dataset(name, data=arr)


def _sample_rows(n: int, max_rows: int, keep: Iterable[int] = ()) -> np.ndarray:
    """At most ~max_rows evenly spaced row indices in [0, n), plus the rows in ``keep``."""
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    rows = set(np.unique(np.linspace(0, n - 1, min(n, max_rows)).round().astype(int)).tolist())
    rows.update(i for i in keep if 0 <= i < n)
    return np.array(sorted(rows), dtype=np.int64)


def _write_branch(group: h5py.Group, branch: Branch, position: int,
                  profiles: Mapping[str, np.ndarray] | None, profile_index: np.ndarray | None) -> None:
    g = group.create_group(_escape(str(branch.id), set(group.keys())))
    a = g.attrs
    a["id"] = str(branch.id)
    a["parameter"] = branch.parameter
    a["free"] = np.asarray(list(branch.free), dtype=_str())
    a["status"] = branch.status
    a["message"] = branch.message
    a["closed"] = bool(branch.closed)
    a["kind"] = branch.kind
    a["parent"] = branch.parent
    a["position"] = position
    a["param_names"] = np.asarray(list(branch.params), dtype=_str())
    a["observable_names"] = np.asarray(list(branch.observables), dtype=_str())
    taken: set[str] = set()
    mapping: dict[str, dict[str, str]] = {"params": {}, "observables": {}}
    for kind, table in (("params", branch.params), ("observables", branch.observables)):
        for name, values in table.items():
            ds = _escape(name, taken)
            mapping[kind][name] = ds
            _put(g, ds, values)
    a["datasets"] = json.dumps(mapping)
    g.create_dataset("ds", data=np.asarray(branch.ds))
    g.create_dataset("newton_iterations", data=np.asarray(branch.newton_iterations))
    g.create_dataset("states", data=np.asarray(branch.states))
    g.create_dataset("tangents", data=np.asarray(branch.tangents))
    for name in ("stable", "n_unstable", "eigenvalues", "state_index", "grid", "sizes"):
        value = getattr(branch, name, None)
        if value is not None:
            g.create_dataset(name, data=np.asarray(value))
    if branch.stability_k is not None:
        a["stability_kx"], a["stability_kz"] = (float(k) for k in branch.stability_k)
    g.create_dataset("audit", data=np.asarray(list(branch.audit), dtype=object), dtype=_str())
    if profiles is not None and profile_index is not None:
        g.create_dataset("profile_index", data=profile_index)
        pg = g.create_group("profiles")
        for name, arr in profiles.items():
            pg.create_dataset(name.replace("/", "%2F"), data=np.asarray(arr, dtype=float))


def _write_special_points(f: h5py.File, branches: Sequence[Branch],
                          sp_profiles: Mapping[str, np.ndarray] | None) -> None:
    rows = [(b, sp) for b in branches for sp in b.special_points]
    positions = [pos for pos, b in enumerate(branches) for _ in b.special_points]
    g = f.create_group("special_points")
    k = len(rows)
    names: list[str] = []
    for _, sp in rows:
        names.extend(n for n in sp.params if n not in names)
    g.attrs["param_names"] = np.asarray(names, dtype=_str())
    g.attrs["n_rows"] = k

    def text(vals: list[str]) -> np.ndarray:
        return np.asarray(vals, dtype=object)

    g.create_dataset("branch", data=text([str(b.id) for b, _ in rows]), dtype=_str())
    g.create_dataset("name", data=text([sp.name for _, sp in rows]), dtype=_str())
    g.create_dataset("type", data=text([sp.type for _, sp in rows]), dtype=_str())
    g.create_dataset("note", data=text([sp.note for _, sp in rows]), dtype=_str())
    g.create_dataset("branch_position", data=np.asarray(positions, dtype=np.int64))
    g.create_dataset("label", data=np.asarray([sp.label for _, sp in rows], dtype=np.int64))
    g.create_dataset("index", data=np.asarray([sp.index for _, sp in rows], dtype=np.int64))
    g.create_dataset("phi", data=np.asarray([sp.order_parameter for _, sp in rows], dtype=float))
    g.create_dataset("bracket_lo", data=np.asarray([sp.bracket[0] for _, sp in rows], dtype=float))
    g.create_dataset("bracket_hi", data=np.asarray([sp.bracket[1] for _, sp in rows], dtype=float))
    g.create_dataset("converged", data=np.asarray([sp.converged for _, sp in rows], dtype=bool))
    pg = g.create_group("params")
    present = np.zeros((k, len(names)), dtype=bool)
    for j, name in enumerate(names):
        vals = []
        for i, (_, sp) in enumerate(rows):
            present[i, j] = name in sp.params
            vals.append(sp.params.get(name, np.nan))
        if any(isinstance(v, str) for v in vals):
            pg.create_dataset(name.replace("/", "%2F"), data=text([str(v) for v in vals]), dtype=_str())
        else:
            pg.create_dataset(name.replace("/", "%2F"), data=np.asarray(vals, dtype=float))
    g.create_dataset("params_present", data=present)
    _write_special_data(g, [sp for _, sp in rows])
    for col, get in (("states", lambda sp: sp.state), ("tangents", lambda sp: sp.tangent)):
        vecs = [None if get(sp) is None else np.asarray(get(sp)).ravel() for _, sp in rows]
        width = max([v.size for v in vecs if v is not None], default=0)
        dtype = np.result_type(float, *[v.dtype for v in vecs if v is not None])
        table = np.full((k, width), np.nan, dtype=dtype)
        sizes = np.full(k, -1, dtype=np.int64)
        for i, v in enumerate(vecs):
            if v is not None:
                table[i, : v.size] = v
                sizes[i] = v.size
        g.create_dataset(col, data=table)
        g.create_dataset(col[:-1] + "_size", data=sizes)
    g.create_dataset("grid", data=np.asarray([-1 if sp.grid is None else int(sp.grid) for _, sp in rows], dtype=np.int64))
    if sp_profiles:
        spg = g.create_group("profiles")
        for name, arr in sp_profiles.items():
            spg.create_dataset(name.replace("/", "%2F"), data=np.asarray(arr, dtype=float))


def _write_special_data(g: h5py.Group, sps: Sequence[SpecialPoint]) -> None:
    """SpecialPoint.data as float columns data/<name> and a presence table (HB omega, l1; UZ value)."""
    names: list[str] = []
    for sp in sps:
        names.extend(n for n in sp.data if n not in names)
    g.attrs["data_names"] = np.asarray(names, dtype=_str())
    dg = g.create_group("data")
    present = np.zeros((len(sps), len(names)), dtype=bool)
    for j, name in enumerate(names):
        present[:, j] = [name in sp.data for sp in sps]
        dg.create_dataset(name.replace("/", "%2F"), data=np.asarray([sp.data.get(name, np.nan) for sp in sps], dtype=float))
    g.create_dataset("data_present", data=present)


def _read_special_data(g: h5py.Group, k: int) -> list[dict[str, float]]:
    """The data dicts of k special-point rows (empty dicts for files written before data existed)."""
    if "data" not in g:
        return [{} for _ in range(k)]
    names = _attr_list(g.attrs["data_names"])
    cols = {n: g["data"][n.replace("/", "%2F")][()] for n in names}
    present = g["data_present"][()]
    return [{n: float(cols[n][i]) for j, n in enumerate(names) if present[i, j]} for i in range(k)]


def _publish(path: Path, fill: Callable[[h5py.File], None]) -> None:
    """Write a whole file through ``fill`` into PATH.tmp, fsync, and rename it onto PATH.

    The HDF5 image is built in memory and then written with plain ``write`` calls: HDF5 itself
    writing onto a full disk crashed the process (segmentation fault, hundreds of traceback
    lines, a stray PATH.tmp), while a failed ``write`` is an ordinary OSError that
    :func:`contin.atomic.publish` turns into one sentence.  Runs are a few MB.
    """
    import io as _io

    import h5py

    def write(tmp: Path) -> None:
        buf = _io.BytesIO()
        with h5py.File(buf, "w") as f:
            fill(f)
        write_bytes(tmp, buf.getvalue())

    publish(path, write)


def check_writable(path: str | os.PathLike[str]) -> Path:
    """Raise ``OSError`` with a clear message if ``path`` (an output file) cannot be written.

    Creates and removes a probe file beside PATH (a publish needs to create PATH.tmp there), so
    a bad ``-o`` fails before any computing.
    """
    p = check_target(path)  # a regular file or a new path, never a device or a symlink
    if not p.parent.is_dir():
        raise FileNotFoundError(f"cannot write {str(p)!r}: directory {str(p.parent)!r} does not exist")
    # A probe of our own (never PATH.tmp: another run publishing to PATH may be writing that)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.probe")
    try:
        write_bytes(tmp, b"")
        tmp.unlink()
    except OSError as exc:
        raise OSError(f"cannot write {str(p)!r}: {exc.strerror or exc}") from None
    if p.exists() and not os.access(p, os.W_OK) and not os.access(p.parent, os.W_OK):
        raise PermissionError(f"cannot write {str(p)!r}: permission denied")
    return p


class H5Writer:
    """Incremental, crash-safe writer of one run (see the module docstring for the design).

    Parameters
    ----------
    path : output file.
    scene, parameters, discretization, options, command : provenance (``command`` defaults to
        ``sys.argv``; ``options`` a :class:`ContinuationOptions` or a dict).
    y, profiles : wall-normal grid and state -> {name: profile} map; profiles are stored for
        at most ``max_profiles`` evenly spaced rows of each branch (plus its special points).
    branches : branches already finished (``--resume``); written with the first publish.
    notes, extra, diagram_x, diagram_y : stored as root attributes.

    Use as a context manager: :meth:`add_branch` after each finished branch (publishes at
    once, or with ``checkpoint_ratio = c > 0`` once the time since the last publish is at least
    c times its duration: see "Crash safety" above; :attr:`pending` says whether the published
    file lags behind); leaving the block normally publishes the final file with ``complete=True``; leaving
    it with an exception keeps the last published (``complete=False``) file.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        scene: str = "",
        parameters: Mapping[str, Any] | None = None,
        discretization: Mapping[str, Any] | None = None,
        options: ContinuationOptions | Mapping[str, Any] | None = None,
        command: Sequence[str] | str | None = None,
        y: np.ndarray | None = None,
        profiles: ProfileFn | None = None,
        branches: Iterable[Branch] = (),
        notes: Sequence[str] = (),
        extra: Mapping[str, Any] | None = None,
        diagram_x: str = "",
        diagram_y: str = "phi",
        max_profiles: int = 40,
        lock: bool = True,
        attrs: Mapping[str, str] | None = None,
        checkpoint_ratio: float = 0.0,
    ) -> None:
        if not (math.isfinite(checkpoint_ratio) and checkpoint_ratio >= 0):
            raise ValueError(f"checkpoint_ratio must be a finite number >= 0, got {checkpoint_ratio!r}")
        self.checkpoint_ratio = float(checkpoint_ratio)
        self.pending = False  # a branch was added after the last publish
        self._last_publish_end = -math.inf
        self._last_publish_duration = 0.0
        self.path = check_writable(path)
        # One writer per output, refused up front (two runs on one -o lost work silently).
        self._lock = OutputLock(self.path).acquire() if lock else None
        argv = sys.argv if command is None else command
        self.meta: dict[str, Any] = {
            "scene": scene,
            "parameters": dict(parameters or {}),
            "discretization": dict(discretization or {}),
            "options": _options_dict(options),
            "command": argv if isinstance(argv, str) else shlex.join(str(a) for a in argv),
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "notes": list(notes),
            "extra": dict(extra or {}),
            "diagram_x": diagram_x,
            "diagram_y": diagram_y,
            "stopped": "",
        }
        self.y = None if y is None else np.asarray(y, dtype=float)
        self.profiles = profiles
        self.max_profiles = max_profiles
        self.attrs = dict(attrs or {})  # extra root attributes (text), e.g. a sweep task's result
        self._branches: dict[str, Branch] = {}
        self._extra_branches: list[Branch] = []
        self._profile_cache: dict[int, tuple[Branch, tuple[np.ndarray, dict[str, np.ndarray]] | None]] = {}
        for b in branches:
            self._branches[str(b.id)] = b
        self.complete = False
        self.publishes = 0

    # -- context manager
    def __enter__(self) -> H5Writer:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.release()

    @property
    def branches(self) -> list[Branch]:
        return list(self._branches.values())

    def add_branch(self, branch: Branch) -> None:
        """Record a finished branch (replacing one with the same id) and publish the file
        (at once, or under ``checkpoint_ratio`` when enough time has passed since the last)."""
        self._branches[str(branch.id)] = branch
        self.pending = True
        since = time.monotonic() - self._last_publish_end
        if since >= self.checkpoint_ratio * self._last_publish_duration:
            self.publish()

    def update(self, **meta: Any) -> None:
        """Change provenance/notes before the final publish (e.g. the scene's full parameters,
        ``y`` and ``profiles`` from its SceneResult)."""
        if "y" in meta:
            y = meta.pop("y")
            self.y = None if y is None else np.asarray(y, dtype=float)
        if "profiles" in meta:
            self.profiles = meta.pop("profiles")
        unknown = set(meta) - set(self.meta)
        if unknown:
            raise TypeError(f"unknown metadata {sorted(unknown)}")
        for key, value in meta.items():
            self.meta[key] = value if key != "options" else _options_dict(value)
        self._profile_cache.clear()

    def set_branches(self, branches: Iterable[Branch]) -> None:
        """Replace the branch list (the scene's final, authoritative list)."""
        self._branches = {}
        self._extra_branches = []
        for b in branches:
            if str(b.id) in self._branches:
                _log.warning("two branches share the id %r; both are stored", b.id)
                self._extra_branches.append(b)
            else:
                self._branches[str(b.id)] = b

    def _all_branches(self) -> list[Branch]:
        return list(self._branches.values()) + self._extra_branches

    def _branch_profiles(self, b: Branch) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        if self.profiles is None or self.y is None:
            return None
        cached = self._profile_cache.get(id(b))
        if cached is not None and cached[0] is b:  # the entry keeps b alive, so id(b) is unique
            return cached[1]
        result: tuple[np.ndarray, dict[str, np.ndarray]] | None
        try:
            rows = _sample_rows(len(b.states), self.max_profiles)
            if b.sizes is not None:  # states of several grids: unpadded (profiles() maps them onto y)
                index = b.stored_points
                samples = [self.profiles(b.states[i, : int(b.sizes[index[i]])]) for i in rows]
            else:
                samples = [self.profiles(b.states[i]) for i in rows]
            names = list(samples[0]) if samples else []
            state_index = getattr(b, "state_index", None)
            points = rows if state_index is None else np.asarray(state_index)[rows]
            result = (points, {n: np.array([s[n] for s in samples]) for n in names})
        except Exception as exc:  # noqa: BLE001 -- a profile bug must not lose the run
            _log.warning("profiles of branch %s not stored: %s", b.id, exc)
            result = None
        self._profile_cache[id(b)] = (b, result)
        return result

    def _fill(self, f: h5py.File) -> None:
        a = f.attrs
        a["format"] = FORMAT
        a["format_version"] = FORMAT_VERSION
        a["contin_version"] = _contin_version()
        a["git_commit"] = git_commit()
        a["libraries"] = json.dumps(library_versions())
        a["complete"] = bool(self.complete)
        for key in ("created_utc", "command", "scene", "diagram_x", "diagram_y", "stopped"):
            a[key] = str(self.meta[key])
        for key in ("parameters", "discretization", "options", "notes", "extra"):
            a[key] = _json_dumps(self.meta[key])
        for key, value in self.attrs.items():
            a[key] = str(value)
        if self.y is not None:
            f.create_group("grid").create_dataset("y", data=self.y)
        bg = f.create_group("branches", track_order=True)
        branches = self._all_branches()
        for pos, b in enumerate(branches):
            prof = self._branch_profiles(b)
            _write_branch(bg, b, pos, None if prof is None else prof[1], None if prof is None else prof[0])
        sp_profiles = None
        sps = [sp for b in branches for sp in b.special_points]
        if self.profiles is not None and self.y is not None and sps:
            try:
                samples = [self.profiles(np.asarray(sp.state)) for sp in sps]
                sp_profiles = {n: np.array([s[n] for s in samples]) for n in samples[0]}
            except Exception as exc:  # noqa: BLE001
                _log.warning("profiles of special points not stored: %s", exc)
        _write_special_points(f, branches, sp_profiles)

    def publish(self) -> None:
        """Write the current state atomically to :attr:`path` (:class:`NonFiniteError` first
        if a branch holds non-finite data; the published file is then left as it was)."""
        for b in self._all_branches():
            check_finite(b)
        start = time.monotonic()
        _publish(self.path, self._fill)
        self._last_publish_end = time.monotonic()
        self._last_publish_duration = self._last_publish_end - start
        self.publishes += 1
        self.pending = False

    def close(self) -> None:
        """Final publish with ``complete=True``; releases the output lock."""
        self.complete = True
        try:
            self.publish()
        finally:
            self.release()

    def release(self) -> None:
        """Drop the output lock (also done by :meth:`close`; a dying process drops it anyway)."""
        lock, self._lock = self._lock, None  # (forgotten first: a Ctrl-C inside must not release it twice)
        if lock is not None:
            lock.release()


#: the root attributes H5Writer sets itself; any other one is a caller's (``attrs=``)
_OWN_ROOT_ATTRS = frozenset({"format", "format_version", "contin_version", "git_commit", "libraries", "complete",
                             "created_utc", "command", "scene", "diagram_x", "diagram_y", "stopped", "parameters",
                             "discretization", "options", "notes", "extra"})


def write(path: str | os.PathLike[str], branches: Iterable[Branch], *, stopped: str = "", **meta: Any) -> Path:
    """Write a complete run file atomically; ``meta`` as for :class:`H5Writer`.

    Without ``parameters=`` the file records the problem's parameters as the branches carry
    them: every parameter column of the first branch at its first point (the values a
    restart or a rebuilt problem starts from).  ``stopped`` (e.g. ``"interrupted"``,
    :data:`contin.cancel.STOPPED`) writes a partial result: ``complete=False`` and the reason, as a
    run's writer leaves a stopped run (``contin info`` says it is incomplete).
    """
    if isinstance(branches, Branch):  # io.write(path, branch) met "'Branch' object is not iterable"
        branches = [branches]
    if isinstance(branches, str | bytes) or not hasattr(branches, "__iter__"):
        raise TypeError(f"branches must be a list of Branch objects, got {type(branches).__name__}")
    branches = list(branches)
    strays = [b for b in branches if not isinstance(b, Branch)]
    if strays:
        raise TypeError(f"branches must be a list of Branch objects, got a {type(strays[0]).__name__} among them")
    if not meta.get("parameters"):
        first = next((b for b in branches if len(b)), None)
        meta["parameters"] = {} if first is None else {k: float(v[0]) for k, v in first.params.items()}
    meta.setdefault("lock", False)  # one publish, atomic by itself; no run to protect
    w = H5Writer(path, **meta)
    w.set_branches(branches)
    if not stopped:
        w.close()
        return w.path
    w.update(stopped=stopped)
    try:
        w.publish()  # complete stays False
    finally:
        w.release()
    return w.path


# --------------------------------------------------------------------------- reading

def _text(ds: h5py.Dataset) -> list[str]:
    return [str(x) for x in ds.asstr()[()]] if ds.shape != () else [str(ds.asstr()[()])]


def _read_column(ds: h5py.Dataset) -> np.ndarray:
    import h5py

    if h5py.check_string_dtype(ds.dtype) is not None:
        return np.asarray(_text(ds), dtype=str)
    return ds[()]


def _attr_list(value: Any) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(value)] if np.size(value) else []


def _read_branch(g: h5py.Group) -> Branch:
    a = g.attrs
    mapping = json.loads(a["datasets"])
    params = {n: _read_column(g[ds]) for n, ds in mapping["params"].items()}
    observables = {n: _read_column(g[ds]) for n, ds in mapping["observables"].items()}
    return Branch(
        parameter=str(a["parameter"]),
        free=tuple(_attr_list(a["free"])),
        params=params,
        observables=observables,
        states=g["states"][()],
        tangents=g["tangents"][()],
        ds=g["ds"][()],
        newton_iterations=g["newton_iterations"][()],
        special_points=[],
        status=str(a["status"]),
        message=str(a["message"]),
        closed=bool(a["closed"]),
        stable=g["stable"][()] if "stable" in g else None,
        n_unstable=g["n_unstable"][()] if "n_unstable" in g else None,
        eigenvalues=g["eigenvalues"][()] if "eigenvalues" in g else None,
        kind=str(a["kind"]),
        parent=str(a["parent"]),
        id=str(a["id"]),
        audit=_text(g["audit"]) if g["audit"].size else [],
        stability_k=(float(a["stability_kx"]), float(a["stability_kz"])) if "stability_kx" in a else None,
        **({"state_index": g["state_index"][()] if "state_index" in g else None} if _HAS_STATE_INDEX else {}),
        grid=g["grid"][()] if "grid" in g else None,
        sizes=g["sizes"][()] if "sizes" in g else None,
    )


def _read_special_points(g: h5py.Group) -> list[tuple[int, str, SpecialPoint]]:
    k = int(g.attrs["n_rows"])
    if k == 0:
        return []
    for name in ("branch", "name", "type", "note", "label", "index", "branch_position", "phi", "bracket_lo",
                 "bracket_hi", "converged", "params_present", "states", "state_size", "tangents", "tangent_size"):
        if name in g and g[name].shape[:1] != (k,):
            raise BadDataset(f"dataset special_points/{name} has {g[name].shape[0] if g[name].shape else 0} rows, "
                             f"the table has {k} (attribute n_rows)")
    for name, ds in g["params"].items():
        if ds.shape[:1] != (k,):
            raise BadDataset(f"dataset special_points/params/{name} has {ds.shape[0] if ds.shape else 0} rows, "
                             f"the table has {k} (attribute n_rows)")
    names = _attr_list(g.attrs["param_names"])
    cols = {n: _read_column(g["params"][n.replace("/", "%2F")]) for n in names}
    present = g["params_present"][()]
    branch, type_, note = _text(g["branch"]), _text(g["type"]), _text(g["note"])
    label, index, position = g["label"][()], g["index"][()], g["branch_position"][()]
    phi, lo, hi, conv = g["phi"][()], g["bracket_lo"][()], g["bracket_hi"][()], g["converged"][()]
    states, state_size = g["states"][()], g["state_size"][()]
    tangents, tangent_size = g["tangents"][()], g["tangent_size"][()]
    grid = g["grid"][()] if "grid" in g else np.full(k, -1, dtype=np.int64)
    data = _read_special_data(g, k)
    out = []
    for i in range(k):
        params = {}
        for j, n in enumerate(names):
            if present[i, j]:
                v = cols[n][i]
                params[n] = str(v) if isinstance(v, str | np.str_) else float(v)
        out.append((int(position[i]), branch[i], SpecialPoint(
            type=type_[i],
            index=int(index[i]),
            params=params,
            order_parameter=float(phi[i]),
            state=states[i, : state_size[i]].copy(),
            tangent=None if tangent_size[i] < 0 else tangents[i, : tangent_size[i]].copy(),
            bracket=(float(lo[i]), float(hi[i])),
            converged=bool(conv[i]),
            label=int(label[i]),
            note=note[i],
            grid=None if grid[i] < 0 else int(grid[i]),
            data=data[i],
        )))
    return out


def check_parameters(parameters: Any) -> None:
    """BadDataset when the run's ``parameters`` attribute holds a NaN: no scene writes one (the
    command line refuses NaN settings), so it is damage, and a problem rebuilt from it
    (``contin continue``, ``verify``, ``stability``) would compute with it."""
    if not isinstance(parameters, Mapping):
        return
    for name, value in parameters.items():
        if isinstance(value, float) and math.isnan(value):
            raise BadDataset(f"attribute parameters holds NaN for {name!r}")


def load(path: str | os.PathLike[str]) -> tuple[list[Branch], dict[str, Any]]:
    """Read a run file: ``(branches, metadata)``.

    Branches come back in the order they were written, with their special points.
    ``metadata`` holds the root attributes (``parameters``, ``discretization``, ``options``,
    ``notes``, ``extra`` decoded from JSON), ``complete``, ``y`` (or None) and ``profiles``:
    ``{branch_id: {"index": rows, name: (M, N) array}}``; ``attrs`` the other root attributes,
    as text (those a caller gave the writer's ``attrs=``, e.g. a sweep task's ``sweep_task``).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    FileFormatError
        If the file is not HDF5, is truncated or corrupt, or is not a contin file.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no such file: {str(p)!r}")
    import h5py

    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        reason = str(exc).split("(", 1)[-1].rstrip(")") if "(" in str(exc) else str(exc)
        raise FileFormatError(f"{str(p)!r} is not a readable HDF5 file ({reason.strip()})") from None
    try:
        with f:
            a = f.attrs
            if a.get("format") != FORMAT:
                raise FileFormatError(f"{str(p)!r} is an HDF5 file but not a contin run file (no format='contin' attribute)")
            version = int(a.get("format_version", -1))
            if version not in READABLE_VERSIONS:
                raise FileFormatError(f"{str(p)!r} has contin format version {version}; this contin reads versions "
                                      f"{', '.join(map(str, READABLE_VERSIONS))}")
            meta: dict[str, Any] = {
                "path": str(p),
                "format": FORMAT,
                "format_version": version,
                "complete": bool(a.get("complete", False)),
            }
            for key in ("contin_version", "git_commit", "created_utc", "command", "scene", "diagram_x", "diagram_y",
                        "stopped"):
                meta[key] = str(a.get(key, ""))
            meta["libraries"] = _jsonload(a.get("libraries"), {})  # written since session 18
            # root attributes of others (a sweep task's result, `sweep_task`): a writer over this
            # file (trace --resume) passes them on (H5Writer attrs=); they were dropped (qa19)
            meta["attrs"] = {k: (v.decode() if isinstance(v, bytes) else str(v)) for k, v in a.items()
                             if k not in _OWN_ROOT_ATTRS}
            for key, default in (("parameters", {}), ("discretization", {}), ("options", {}), ("notes", []), ("extra", {})):
                meta[key] = _jsonload(a.get(key), default)
            check_parameters(meta["parameters"])  # a NaN there was shown by info and rebuilt into problems
            meta["y"] = f["grid/y"][()] if "grid/y" in f else None
            check_profile_grid(meta["y"])  # NaN there drew profiles with gaps, exit 0
            groups = sorted(f["branches"].values(), key=lambda g: int(g.attrs["position"]))
            branches = [_read_branch(g) for g in groups]
            profiles = {}
            for g, b in zip(groups, branches):
                prof: dict[str, np.ndarray] | None = None
                if "profile_index" in g:
                    prof = {"index": g["profile_index"][()]}
                    for name, ds in g["profiles"].items():
                        prof[name.replace("%2F", "/")] = ds[()]
                    profiles[b.id] = prof
                check_branch(g.name.lstrip("/"), b, json.loads(g.attrs["datasets"]), prof)
                if prof:
                    check_profile_widths(f"{g.name.lstrip('/')}/profiles", prof, meta["y"])
            meta["profiles"] = profiles
            sp_group = f["special_points"]
            if "profiles" in sp_group:
                meta["special_point_profiles"] = {n.replace("%2F", "/"): d[()] for n, d in sp_group["profiles"].items()}
                check_profile_widths("special_points/profiles", meta["special_point_profiles"], meta["y"])
            for row, (pos, bid, sp) in enumerate(_read_special_points(sp_group)):
                if not 0 <= pos < len(branches) or branches[pos].id != bid:
                    raise FileFormatError(f"{str(p)!r} is damaged: special point {sp.name} names a missing branch {bid!r}")
                check_special_point(row, branches[pos], sp)
                branches[pos].special_points.append(sp)
            check_orbits(branches, meta["extra"])
            return branches, meta
    except FileFormatError:
        raise
    except BadDataset as exc:
        raise FileFormatError(f"{str(p)!r} is damaged: {exc}") from None
    except (KeyError, ValueError, TypeError, OSError, RuntimeError, IndexError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"{str(p)!r} is damaged or truncated ({msg})") from None


def profiles_at(
    branches: Sequence[Branch], meta: Mapping[str, Any], name: str, value: float,
) -> list[tuple[Branch, str, dict[str, np.ndarray]]]:
    """Stored solution profiles of each branch where parameter ``name`` equals ``value``.

    Uses, in this order, a special point of the branch located at ``name = value`` (exact,
    e.g. a UZ point) or linear interpolation between the two stored profiles (``profile_index``)
    that bracket the first crossing of ``value`` along the branch.  Branches that never reach
    ``value`` are left out.  Returns ``(branch, how, {profile name: (N,) array})``.
    """
    out: list[tuple[Branch, str, dict[str, np.ndarray]]] = []
    sp_prof = meta.get("special_point_profiles") or {}
    row = 0
    tol = 1e-9 * max(1.0, abs(value))
    for b in branches:
        found = None
        located: list[tuple[Any, int]] = []  # (special point, its row of special_point_profiles)
        for sp in b.special_points:
            if sp_prof and found is None and name in sp.params and abs(float(sp.params[name]) - value) <= tol:
                found = (b, f"at {sp.name}", {k: v[row] for k, v in sp_prof.items()})
            if sp_prof and sp.type not in ("EP", "MX") and name in sp.params:
                located.append((sp, row))
            row += 1
        prof = meta.get("profiles", {}).get(b.id)
        count = 0  # crossings of the value along the branch
        if prof is not None and name in b.params:
            idx = np.asarray(prof["index"])
            names = [k for k in prof if k != "index"]
            # the stored profiles in branch order, each located point (index i: between points i and
            # i + 1) after the stored ones up to i: `contin profiles br.h5 --at lam=3.5135` between
            # Bratu's fold (3.51383) and the stored profiles next to it said 'no stored branch
            # reaches lam=3.5135' (qa19)
            seq: list[tuple[float, str, dict[str, np.ndarray]]] = []
            params = np.asarray(b.params[name], dtype=float)
            rows = {int(i): r for r, i in enumerate(idx)}
            between = [(sp.index, (sp, sp_row)) for sp, sp_row in located if all(k in sp_prof for k in names)]
            for i, item in interleave_located(idx, between, len(b)):
                if item is None:
                    seq.append((float(params[i]), f"point {i}", {k: prof[k][rows[i]] for k in names}))
                else:
                    sp, sp_row = item
                    seq.append((float(sp.params[name]), sp.name, {k: sp_prof[k][sp_row] for k in names}))
            crossing = first_crossing(np.array([v for v, _, _ in seq]), value)
            if crossing is not None:
                i, j, w, count = crossing
                if found is None:
                    (_, what_i, prof_i), (_, what_j, prof_j) = seq[i], seq[j]
                    if w == 0.0:
                        how = f"at stored {what_i}" if what_i.startswith("point") else f"at {what_i}"
                    elif what_i.startswith("point") and what_j.startswith("point"):
                        how = f"interpolated between points {what_i.split()[1]} and {what_j.split()[1]}"
                    else:
                        how = f"interpolated between {what_i} and {what_j}"
                    found = (b, how, {k: (1 - w) * prof_i[k] + w * prof_j[k] for k in names})
        if found is not None:
            at_fold = found[1].startswith("at LP")  # both crossings next to a fold are that one point
            if count > 1 and not at_fold:  # a branch through a fold reaches the value again: say that only one is drawn
                found = (found[0], f"{found[1]} (the first of {count} crossings of {name}={value:g} along the branch; "
                                   f"the others are not drawn)", found[2])
            out.append(found)
    return out


def restart(path: str | os.PathLike[str], label: str, branch: str | None = None) -> Any:
    """The labelled point ``label`` (e.g. 'BP2') of the run file ``path``, ready for a restart.

    Returns a :class:`contin.restart.Restart`: unpacks as ``u, p, tangent = io.restart(f, 'BP2')``;
    ``trace(problem, **r.trace_kwargs())`` continues from it in the branch's parameter.
    ``branch`` picks the branch when the label occurs on several.  Raises ValueError (one
    sentence) for an unknown or ambiguous label or a point without a stored state.
    """
    from contin.restart import restart_from

    branches, meta = load(path)
    return restart_from(branches, meta, label, branch)
