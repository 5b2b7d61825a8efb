"""Invariants a contin run file must satisfy when it is read (``contin.io.load``).

The writer refuses non-finite data (``contin.io.check_finite``) and writes every per-point
column with one row per branch point; a file that breaks either was damaged or edited after it
was written, and reading it on would give silent wrong answers (``contin info`` reported "7
points" for a 4-row column; NaN states drew T < 0).  :func:`check_branch` and
:func:`check_special_points` raise :class:`BadDataset` naming the dataset; ``contin.io.load``
turns it into a ``FileFormatError``.

Checked per branch (S = len(ds) points): every parameter, observable, ``newton_iterations``,
``stable``, ``n_unstable`` column and the rows of ``tangents`` and ``eigenvalues`` have S rows;
``states`` has S rows, or one per ``state_index`` entry (each in [0, S)); ``profile_index``
entries lie in [0, S) and each profile has one row per entry.  Finite as the writer requires:
states, tangents, ds, free parameters, observables that are not NaN everywhere, profiles;
fixed parameters may be inf, not NaN.  Special points: index in [0, S) of their branch, free
parameters and located states (up to ``state_size``) finite.  The per-point ``grid`` column of an
adaptive run lies in 1..MAX_GRID, and ``grid/y`` (the profiles' abscissa) is finite.  A fold or
Hopf curve has two free parameters and states of its augmented size.  Periodic orbits: see
:func:`check_orbits`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.limits import MAX_GRID


class BadDataset(ValueError):
    """A dataset that breaks an invariant of the format (message names it)."""


def first_bad_row(values: Any, allow_inf: bool = False) -> int | None:
    """Index of the first row of ``values`` holding NaN (or, unless ``allow_inf``, inf), or None;
    non-float data and empty arrays have none.  Also the writer's check (``contin.io.check_finite``)."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "fc" or arr.size == 0:
        return None
    bad = np.isnan(arr) if allow_inf else ~np.isfinite(arr)
    if arr.ndim > 1:
        bad = bad.reshape(arr.shape[0], -1).any(axis=1)
    hits = np.flatnonzero(bad)
    return int(hits[0]) if hits.size else None


def _check_curve(group: str, branch: Any) -> None:
    """A fold or Hopf curve (``kind`` in ``contin.branch.CURVE_BLOCKS``) has two free parameters,
    the first its ``parameter``, and states of its augmented size (an edited ``free`` or ``kind``
    ended `contin stability` and `contin continue` with "too many values to unpack", qa16)."""
    from contin.branch import CURVE_BLOCKS, base_state_size

    if branch.kind not in CURVE_BLOCKS:
        return
    free = tuple(branch.free)
    if len(free) != 2 or free[0] != branch.parameter:
        raise BadDataset(f"branch group {group} is a {branch.kind} but its free parameters (attribute free) are "
                         f"{', '.join(free) or 'none'}, not {branch.parameter!r} and a second one")
    sizes = getattr(branch, "sizes", None)
    widths = {int(v) for v in sizes} if sizes is not None else ({int(branch.states.shape[1])} if len(branch) else set())
    bad = sorted(w for w in widths if base_state_size(branch.kind, w) is None)
    if bad:
        raise BadDataset(f"dataset {group}/states has rows of {bad[0]} entries, which is no {branch.kind} state "
                         f"(the branch's kind attribute and its states disagree)")


def bad_parameter(name: str, value: Any, free: set[str]) -> bool:
    """Whether a special point's parameter value is one the files never hold: a free parameter
    not finite, a fixed one NaN (inf, no gravity, is allowed there, as on the branch's columns).
    The writer refuses such a value (``contin.io.check_finite``), the reader calls it damage."""
    return not isinstance(value, str) and (bool(np.isnan(value)) or (name in free and not np.isfinite(value)))


def _whole(value: Any, lo: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= lo


def check_orbits(branches: Any, extra: Any) -> None:
    """Branches of periodic orbits (kind 'periodic-orbits', written by ``contin continue --cycles``, or
    'lpc-curve')
    against the run's ``extra['cycles']`` entry: n >= 1 and NCOL >= 1 whole numbers (NTST >= 2
    where given), and every stored orbit -- [node values (NTST NCOL n), T, interior mesh points] --
    of that layout with T > 0 and the mesh increasing inside (0, 1).  A file without the entry is
    left to the commands that need it (they say so).  An edited entry ended `contin continue --from
    PD1 --cycles` with 'internal error (AttributeError ...)', `profiles` and `export` with 'invalid
    literal for int()' (qa19); a damaged mesh drew nothing ('mesh points must be ...') or an orbit
    was taken at face value.  An LPC curve (kind 'lpc-curve', ``contin.lpccurve``) stores its orbits
    in the same layout and is checked the same way (an edited period there was drawn as
    'period T = -1', qa19b)."""
    orbits = [b for b in branches if getattr(b, "kind", "") in ("periodic-orbits", "lpc-curve")]
    if not orbits or not isinstance(extra, Mapping) or "cycles" not in extra:
        return
    cycles = extra["cycles"]
    if not isinstance(cycles, Mapping):
        raise BadDataset(f"attribute extra holds a 'cycles' entry of type {type(cycles).__name__}, not the mapping "
                         f"(n, ntst, ncol) of the orbits' collocation")
    n, ncol, ntst = cycles.get("n"), cycles.get("ncol"), cycles.get("ntst", 2)
    if not (_whole(n, 1) and _whole(ncol, 1) and _whole(ntst, 2)):
        raise BadDataset(f"attribute extra: the orbits' collocation 'cycles' needs whole numbers n >= 1, "
                         f"ncol >= 1 and ntst >= 2, got n = {n!r}, ncol = {ncol!r}, ntst = {ntst!r}")
    for b in orbits:
        rows = [(f"branches/{b.id}/states", k, b.states[k]) for k in range(len(b.states))]
        rows += [("special_points/states", sp.name, sp.state) for sp in b.special_points if sp.state is not None]
        for where, row, state in rows:
            state = np.asarray(state, dtype=float)
            steps, rest = divmod(state.size, n * ncol + 1)  # n NTST NCOL + 1 + (NTST - 1) = NTST (n NCOL + 1)
            size = n * steps * ncol + 1
            if steps < 2 or rest:
                raise BadDataset(f"dataset {where} (row {row}) holds {state.size} entries, which is no orbit of "
                                 f"n = {n}, NCOL = {ncol} (NTST (n NCOL + 1) entries, NTST >= 2)")
            mesh = np.concatenate([[0.0], state[size:], [1.0]])
            if not (state[size - 1] > 0 and np.all(np.diff(mesh) > 0)):
                raise BadDataset(f"dataset {where} (row {row}) is no orbit: its period must be > 0 and its mesh "
                                 f"increase from 0 to 1 (period {state[size - 1]:g})")


def _rows(where: str, values: Any, n: int, what: str) -> None:
    got = int(np.shape(values)[0]) if np.ndim(values) else -1
    if got != n:
        raise BadDataset(f"dataset {where} has {got} rows, {what} has {n}")


def _finite(where: str, values: Any, *, allow_inf: bool = False) -> None:
    row = first_bad_row(values, allow_inf)
    if row is not None:
        kind = "NaN" if allow_inf else "a non-finite value"
        raise BadDataset(f"dataset {where} holds {kind} at row {row} (the writer stores only finite values there)")


def check_branch(group: str, branch: Any, datasets: Mapping[str, Mapping[str, str]],
                 profiles: Mapping[str, np.ndarray] | None = None) -> None:
    """Raise :class:`BadDataset` if the branch read from ``group`` breaks an invariant (module docstring)."""
    s = len(branch)
    what = f"branch {branch.id!r} ({s} points by its ds column)"
    free = set(branch.free) | {branch.parameter}
    missing = sorted(free - set(branch.params))
    if missing:  # `contin info` ended with "Error: foo" (a KeyError) for parameter = 'foo'
        raise BadDataset(f"branch group {group} names the free parameter {missing[0]!r} (attributes parameter/free) "
                         f"but holds no such column; its parameters are {', '.join(branch.params)}")
    _finite(f"{group}/ds", branch.ds)
    _check_curve(group, branch)
    for kind, table in (("params", branch.params), ("observables", branch.observables)):
        for name, values in table.items():
            where = f"{group}/{datasets[kind][name]}"
            _rows(where, values, s, what)
            if kind == "params":
                _finite(where, values, allow_inf=name not in free)
            elif not (np.asarray(values).dtype.kind in "fc" and np.isnan(values).all()):
                _finite(where, values)
    for name in ("newton_iterations", "tangents", "stable", "n_unstable", "eigenvalues"):
        value = getattr(branch, name, None)
        if value is not None:
            _rows(f"{group}/{name}", value, s, what)
    sizes = getattr(branch, "sizes", None)
    if sizes is None:
        _finite(f"{group}/tangents", branch.tangents)
    else:  # adaptive runs: rows NaN-padded beyond each point's size (the writer's layout)
        _rows(f"{group}/sizes", sizes, s, what)
        if s and not (0 < int(np.min(sizes)) and int(np.max(sizes)) <= branch.states.shape[1]):
            raise BadDataset(f"dataset {group}/sizes holds a size outside 1..{branch.states.shape[1]}")
        for i in range(s):
            if first_bad_row(branch.tangent(i)) is not None:
                raise BadDataset(f"dataset {group}/tangents holds a non-finite value at row {i} "
                                 f"(the writer stores only finite values there)")
    grid = getattr(branch, "grid", None)
    if grid is not None:
        _rows(f"{group}/grid", grid, s, what)
        if s and not (1 <= int(np.min(grid)) and int(np.max(grid)) <= MAX_GRID):
            # a grid of 0 made 'contin verify' say 'grid too small: cheb needs at least 4 intervals, got 0'
            raise BadDataset(f"dataset {group}/grid holds a grid size outside 1..{MAX_GRID}")
    index = getattr(branch, "state_index", None)
    if index is None:
        _rows(f"{group}/states", branch.states, s, what)
    else:
        _rows(f"{group}/states", branch.states, len(index), f"dataset {group}/state_index")
        if len(index) and not (0 <= int(np.min(index)) and int(np.max(index)) < s):
            raise BadDataset(f"dataset {group}/state_index points outside the branch's {s} points")
    if sizes is None:
        _finite(f"{group}/states", branch.states)
    else:
        rows = range(s) if index is None else [int(i) for i in index]
        for k, i in enumerate(rows):
            if first_bad_row(branch.states[k, : int(sizes[i])]) is not None:
                raise BadDataset(f"dataset {group}/states holds a non-finite value at row {k} "
                                 f"(the writer stores only finite values there)")
    if profiles:
        idx = np.asarray(profiles["index"])
        if idx.size and not (0 <= int(idx.min()) and int(idx.max()) < s):
            raise BadDataset(f"dataset {group}/profile_index points outside the branch's {s} points")
        for name, arr in profiles.items():
            if name != "index":
                _rows(f"{group}/profiles/{name}", arr, idx.size, f"dataset {group}/profile_index")
                _finite(f"{group}/profiles/{name}", arr)


def check_profile_widths(where: str, profiles: Mapping[str, Any], y: Any) -> None:
    """Raise :class:`BadDataset` if a profile (rows of values on ``grid/y``) is not len(y) wide:
    `contin profiles` ended with numpy's "setting an array element with a sequence. The requested
    array has an inhomogeneous shape ..." for a profiles dataset of 5 columns against 33 nodes."""
    if y is None:
        return
    n = np.asarray(y).size
    for name, arr in profiles.items():
        a = np.asarray(arr)
        if name != "index" and a.ndim == 2 and a.shape[1] != n:
            raise BadDataset(f"dataset {where}/{name} has {a.shape[1]} columns, grid/y (the profiles' abscissa) "
                             f"has {n} nodes")


def check_profile_grid(y: Any) -> None:
    """Raise :class:`BadDataset` if ``grid/y`` (the abscissa of every stored profile) is not finite."""
    if y is not None and first_bad_row(np.ravel(y)) is not None:
        raise BadDataset(f"dataset grid/y holds a non-finite value at row {first_bad_row(np.ravel(y))} "
                         f"(the writer stores only finite values there)")


def check_special_point(row: int, branch: Any, sp: Any) -> None:
    """Raise :class:`BadDataset` if special-point row ``row`` (of ``branch``) breaks an invariant."""
    if not 0 <= sp.index < max(len(branch), 1):
        raise BadDataset(f"dataset special_points/index row {row} is {sp.index}, outside branch "
                         f"{branch.id!r} ({len(branch)} points)")
    free = set(branch.free) | {branch.parameter}
    for name, v in sp.params.items():
        # as on the branch's own columns: a free parameter finite, the others not NaN (a NaN fixed
        # parameter of an LPC, taken as the LPC curve's second parameter, ended "internal error
        # (RuntimeError: Factor is exactly singular)", qa19b)
        if bad_parameter(name, v, free):
            kind = "a non-finite value" if name in free else "NaN"
            raise BadDataset(f"dataset special_points/params/{name} holds {kind} at row {row} "
                             f"(the writer stores only finite values there)")
    if sp.state is not None and first_bad_row(np.ravel(sp.state)) is not None:
        raise BadDataset(f"dataset special_points/states holds a non-finite value at row {row} "
                         f"(the writer stores only finite values there)")
