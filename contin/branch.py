"""Result objects: a columnar :class:`Branch` with named :class:`SpecialPoint` s.

Vocabulary follows AUTO-07p: ``BP`` branch point, ``LP`` limit point (fold), ``EP`` end
point (normal stop: bound, max steps, closed loop), ``MX`` failure (Newton or step-size
underflow), ``UZ`` user point (a parameter value or a user event g(u, p) = 0), ``HB`` Hopf point.  For
a two-parameter fold curve, extrema of a parameter along the curve are ``XT`` (isola
birth/death) and cusps are ``CP``; ``BT`` is a Bogdanov-Takens point on a fold or Hopf curve.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal, TypeVar

import numpy as np
from numpy.typing import NDArray

T = TypeVar("T")

#: Rejected-step diagnostics (and other audit lines) kept in Branch.audit by the tracer.
MAX_AUDIT = 200

PointType = Literal["BP", "LP", "EP", "MX", "UZ", "XT", "CP", "HB", "BT", "GH", "ZH", "HH"]
Status = Literal["running", "EP", "MX"]


@dataclass(frozen=True)
class SpecialPoint:
    """A labelled point on a branch.

    Attributes
    ----------
    type : str
        AUTO code ('BP', 'LP', 'EP', 'MX', 'UZ', 'XT', 'CP', 'HB', 'BT', 'GH', 'ZH', 'HH').
    index : int
        Index of the last regular branch point before (or at) this special point.
    params : dict
        All parameter values at the located point.
    order_parameter : float
        Order parameter (e.g. Phi) at the located point (nan if the problem has none).
    state : ndarray
        Located solution u.
    tangent : ndarray or None
        Unit tangent (u, p) at the point (for switching at a BP).
    bracket : (float, float)
        Values of the continuation parameter at the two branch points bracketing it.
    converged : bool
        Whether the location converged to the requested tolerance.
    label : int
        Running AUTO-style label, unique within a run.
    note : str
        Free text (e.g. the stop reason for EP/MX, 'closed loop', 'symmetry-breaking').
    grid : int or None
        Grid size the point was located on (adaptive runs, ``contin.adapt``; None: the
        problem's own grid).
    data : dict[str, float]
        Named numbers of the point's type: ``omega`` (imaginary part of the critical
        eigenvalue) and ``l1`` (first Lyapunov coefficient) of an HB; ``value`` (the
        parameter value or event name's target) of a UZ.  Stored as special-point columns.
    """

    type: str
    index: int
    params: dict[str, float]
    order_parameter: float
    state: NDArray[np.float64]
    tangent: NDArray[np.float64] | None = None
    bracket: tuple[float, float] = (np.nan, np.nan)
    converged: bool = True
    label: int = 0
    note: str = ""
    grid: int | None = None
    data: dict[str, float] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """e.g. 'LP3'."""
        return f"{self.type}{self.label}"


@dataclass
class Branch:
    """A traced branch, one array per quantity (columnar, like BifurcationKit's ContResult).

    Attributes
    ----------
    parameter : str
        Name of the continuation parameter (the first free parameter).
    free : tuple of str
        Names of all free parameters (one for ordinary continuation, two for fold curves).
    params : dict[str, ndarray]
        Every parameter (fixed ones too) along the branch, shape (S,).
    observables : dict[str, ndarray]
        Named observables along the branch, shape (S,); 'phi' is the order parameter.
    states : ndarray, shape (S, n) or (M, n)
        Solutions at every point, or at the points listed in ``state_index`` when the run
        saved only every k-th state (``ContinuationOptions.save_every``); use ``state(i)``.
    tangents : ndarray, shape (S, n + len(free))
        Unit tangents.
    ds : ndarray, shape (S,)
        Arclength step that produced each point (0 for the first).
    newton_iterations : ndarray of int, shape (S,)
    special_points : list of SpecialPoint
    status : 'running', 'EP' or 'MX'
    message : str
        Why the run stopped.
    closed : bool
        True if the branch is a closed loop (isola or periodic return to its start).
    stable, n_unstable, eigenvalues : optional stability columns
        Filled by the stability pass (``contin.stability``); eigenvalues has shape (S, k).
    stability_k : (kx, kz) or None
        Wavenumbers of the perturbations the stability columns refer to (set by the pass).
    kind : str
        Free label ('primary', 'isola', 'bifurcated', 'fold-curve', ...).
    parent : str
        Where this branch came from (e.g. 'BP2@0').
    id : str
        Identifier inside a run / HDF5 file.
    audit : list of str
        Diagnostics of the run (rejected steps and why).
    state_index : ndarray of int or None
        Point indices of the rows of ``states`` (None: every point is stored).
    grid : ndarray of int, shape (S,), or None
        Grid size in force at each point (adaptive resolution, ``contin.adapt``); None: every
        point is on the problem's own grid.  The grid changes are where this column changes.
    sizes : ndarray of int, shape (S,), or None
        State size n_i of each point when they differ (adaptive runs).  ``states`` and
        ``tangents`` rows are then left-aligned and NaN-padded to the largest size
        (:func:`pad_rows`); ``state(i)`` and ``tangent(i)`` return the unpadded vectors.
    """

    parameter: str
    free: tuple[str, ...]
    params: dict[str, NDArray[np.float64]]
    observables: dict[str, NDArray[np.float64]]
    states: NDArray[np.float64]
    tangents: NDArray[np.float64]
    ds: NDArray[np.float64]
    newton_iterations: NDArray[np.int64]
    special_points: list[SpecialPoint] = field(default_factory=list)
    status: str = "running"
    message: str = ""
    closed: bool = False
    stable: NDArray[np.bool_] | None = None
    n_unstable: NDArray[np.int64] | None = None
    eigenvalues: NDArray[np.complex128] | None = None
    kind: str = "primary"
    parent: str = ""
    id: str = "0"
    audit: list[str] = field(default_factory=list)
    state_index: NDArray[np.int64] | None = None
    stability_k: tuple[float, float] | None = None
    grid: NDArray[np.int64] | None = None
    sizes: NDArray[np.int64] | None = None

    def __len__(self) -> int:
        return int(self.ds.shape[0])

    def state(self, i: int) -> NDArray[np.float64]:
        """The solution at point ``i`` (KeyError if ``save_every`` dropped it)."""
        i = range(len(self))[i]
        if self.state_index is None:
            row = self.states[i]
        else:
            hit = np.flatnonzero(self.state_index == i)
            if hit.size == 0:
                raise KeyError(f"state of point {i} was not saved (save_every > 1)")
            row = self.states[int(hit[0])]
        return row if self.sizes is None else row[: int(self.sizes[i])]

    @property
    def stored_points(self) -> NDArray[np.int64]:
        """Indices of the points whose states are stored, one per row of ``states`` (every point
        unless ``save_every`` dropped some: then ``state_index``)."""
        return np.arange(len(self)) if self.state_index is None else np.asarray(self.state_index)

    def tangent(self, i: int) -> NDArray[np.float64]:
        """The unit tangent at point ``i`` (unpadded)."""
        i = range(len(self))[i]
        row = self.tangents[i]
        return row if self.sizes is None else row[: int(self.sizes[i]) + self.tangent_extra]

    @property
    def tangent_extra(self) -> int:
        """Entries a tangent has beyond its state: the free parameters outside the state (one
        for a branch, and for a fold curve, whose state carries the second parameter)."""
        if self.states.ndim == 2 and self.tangents.ndim == 2 and self.states.shape[1] and self.tangents.shape[1]:
            return int(self.tangents.shape[1] - self.states.shape[1])
        return len(self.free)

    def grid_at(self, i: int) -> int | None:
        """The grid size of point ``i`` (None: the problem's own grid)."""
        return None if self.grid is None else int(self.grid[range(len(self))[i]])

    @property
    def grid_changes(self) -> list[tuple[int, int, int]]:
        """(i, old, new) for every point i where the grid differs from point i - 1."""
        if self.grid is None:
            return []
        g = np.asarray(self.grid)
        return [(int(i), int(g[i - 1]), int(g[i])) for i in np.flatnonzero(np.diff(g)) + 1]

    @property
    def success(self) -> bool:
        """True unless the run ended on a failure (MX)."""
        return self.status == "EP"

    @property
    def parameter_values(self) -> NDArray[np.float64]:
        """The continuation parameter along the branch."""
        return self.params[self.parameter]

    @property
    def order_parameter(self) -> NDArray[np.float64]:
        return self.observables.get("phi", np.full(len(self), np.nan))

    def points(self, type: str) -> list[SpecialPoint]:
        """Special points of one AUTO type, e.g. ``branch.points('LP')``."""
        return [s for s in self.special_points if s.type == type]

    @property
    def fold_points(self) -> list[SpecialPoint]:
        return self.points("LP")

    @property
    def branch_points(self) -> list[SpecialPoint]:
        return self.points("BP")

    def reversed(self) -> Branch:
        """The same branch traversed in the opposite direction.

        Point j of the result is point S-1-j of this branch.  Per-step columns (ds, Newton
        iterations) describe the step *into* a point, so they move with the step: the step
        into reversed point j is the original step into point S-j.  A special point between
        original points i and i+1 (LP/BP, index i) lies between reversed points S-2-i and
        S-1-i, so its index becomes S-2-i; points sitting on a branch point (EP, MX) map
        to S-1-i.  Tangents change sign.
        """
        s = len(self)

        def step_column(a: NDArray) -> NDArray:
            return np.concatenate([np.zeros(1, dtype=a.dtype), a[:0:-1]]) if s else a.copy()

        sps = [
            replace(
                sp,
                index=s - 1 - sp.index if sp.type in ("EP", "MX") else max(s - 2 - sp.index, 0),
                tangent=None if sp.tangent is None else -sp.tangent,
            )
            for sp in reversed(self.special_points)
        ]
        if self.state_index is None:
            states, state_index = self.states[::-1].copy(), None
        else:
            states, state_index = self.states[::-1].copy(), (s - 1 - self.state_index[::-1]).copy()
        return Branch(
            parameter=self.parameter,
            free=self.free,
            params={k: v[::-1].copy() for k, v in self.params.items()},
            observables={k: v[::-1].copy() for k, v in self.observables.items()},
            states=states,
            tangents=-self.tangents[::-1].copy(),
            grid=None if self.grid is None else self.grid[::-1].copy(),
            sizes=None if self.sizes is None else self.sizes[::-1].copy(),
            ds=step_column(self.ds),
            newton_iterations=step_column(self.newton_iterations),
            special_points=sps,
            status=self.status,
            message=self.message,
            closed=self.closed,
            stable=None if self.stable is None else self.stable[::-1].copy(),
            n_unstable=None if self.n_unstable is None else self.n_unstable[::-1].copy(),
            eigenvalues=None if self.eigenvalues is None else self.eigenvalues[::-1].copy(),
            kind=self.kind,
            parent=self.parent,
            id=self.id,
            audit=list(self.audit),
            state_index=state_index,
            stability_k=self.stability_k,
        )


def pad_rows(rows: list[NDArray[np.float64]] | NDArray[np.float64], width: int | None = None) -> NDArray[np.float64]:
    """Rows of different lengths as one array, left-aligned and NaN-padded to ``width``
    (default: the longest row).  The storage of states of different grids (``Branch.sizes``)."""
    rows = [np.asarray(r, dtype=float).ravel() for r in rows]
    w = max((r.size for r in rows), default=0) if width is None else int(width)
    out = np.full((len(rows), w), np.nan)
    for k, r in enumerate(rows):
        out[k, : r.size] = r
    return out


def interleave_located(stored: Sequence[int], located: Sequence[tuple[int, T]], points: int) -> list[tuple[int, T | None]]:
    """The stored points of a branch of ``points`` points, in order, as (index, None), each followed
    by the ``located`` items (index i: located between points i and i + 1) that lie between it and
    the next stored point, as (index, item); none past the branch's last point.  The sequence in
    which a value is searched along a branch, located points included (``contin.io.profiles_at``,
    ``contin.orbitprofile``: a value between a fold and its stored neighbours was 'not reached')."""
    out: list[tuple[int, T | None]] = []
    stored = [int(i) for i in stored]
    for r, i in enumerate(stored):
        out.append((i, None))
        following = stored[r + 1] if r + 1 < len(stored) else points
        out.extend((index, item) for index, item in located if i <= index < following and index < points - 1)
    return out


def first_crossing(values: np.ndarray, value: float) -> tuple[int, int, float, int] | None:
    """Where ``values`` (a column along a branch) first reaches ``value``.

    Returns (i, j, w, count): ``value`` lies at (1 - w) values[i] + w values[j] with j = i + 1
    (j = i when only the last point equals it), and ``count`` is the number of crossings along
    the whole column (more than one past a fold); None if the column never reaches ``value``.
    """
    d = np.asarray(values, dtype=float) - value
    # signs, not the product: d[:-1] * d[1:] overflowed (a RuntimeWarning line before 'Error: ... does not
    # reach H = 1e+300') and underflowed to -0.0 (a crossing between 1e-200 and -1e-200 was missed)
    hits = np.flatnonzero((d[:-1] == 0) | (np.sign(d[:-1]) * np.sign(d[1:]) < 0))
    if d.size and d[-1] == 0 and not hits.size:
        hits = np.array([d.size - 1])
    if not hits.size:
        return None
    i = int(hits[0])
    j = min(i + 1, d.size - 1)
    w = 0.0 if d[i] == 0 or i == j else float(d[i] / (d[i] - d[j]))
    return i, j, w, int(hits.size)


#: Blocks of the augmented states of two-parameter curves: fold curves and BP curves [u, phi, p2],
#: Hopf curves [u, v, w, kappa, p2] (``contin.foldcurve``, ``contin.bpcurve``, ``contin.hopfsystem``).
#: (Without 'bp-curve' here `contin export --auto` wrote a BP curve's whole [u, phi, p2] as its
#: solution: NDIM 2n + 1, an L2-NORM of u, phi and p2 together; qa16.)
CURVE_BLOCKS = {"fold-curve": 2, "hopf-curve": 3, "bp-curve": 2}


def base_state_size(kind: str, size: int) -> int | None:
    """The base problem's n in an augmented state of ``size`` entries of a ``kind`` curve (None
    for other kinds, or a size that is no such state)."""
    blocks = CURVE_BLOCKS.get(kind)
    if blocks is None or size < 2 * blocks - 1 or (size - (blocks - 1)) % blocks:
        return None
    return (size - (blocks - 1)) // blocks


def relabel(branches: list[Branch]) -> None:
    """Number the special points of a run 1, 2, 3, ... in branch order (AUTO-style labels).

    Within a branch, points are numbered in the order of their index along the branch.
    SpecialPoint is frozen, so each is rebuilt with ``dataclasses.replace``.
    """
    label = 0
    for branch in branches:
        ordered = sorted(branch.special_points, key=lambda sp: sp.index)
        new = []
        for sp in ordered:
            label += 1
            new.append(replace(sp, label=label))
        branch.special_points = new
