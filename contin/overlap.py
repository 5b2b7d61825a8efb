"""Which traced branches are the same solution set: coordinates, distances, de-duplication.

A branch is compared with another as a polyline in a low-dimensional coordinate space (the
continuation parameter, scaled, and a few scalar functionals of the state).  Two branches are
the same solution set when (almost) every point of one lies within ``tol`` of the other's
polyline (:func:`lies_on`); a seed state lies on a branch when its coordinates do
(:func:`near`).  This is the bookkeeping of BifurcationKit's ``bifurcationdiagram`` and of
deflated continuation (Farrell, Birkisson & Funke, SIAM J. Sci. Comput. 37, 2015: a solution
already found is not returned again), done on stored branches instead of by deflation.

Coordinates are supplied by the caller (:class:`Coordinates`); the default
:class:`StateCoordinates` uses the parameter and random projections of the state, so that it
needs nothing from the problem and tells S u from u.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from contin.branch import Branch

Array = np.ndarray


class Coordinates(Protocol):
    """Maps branches and single states to rows of comparison coordinates.

    ``branch(b)`` -> (len(b), k); ``point(problem, u, p)`` -> (k',) with k' <= k: the first k'
    columns of ``branch`` (a seed state may be compared on fewer coordinates).
    """

    def branch(self, b: Branch) -> Array: ...

    def point(self, problem: Any, u: Array, p: Mapping[str, float]) -> Array: ...


@dataclass(frozen=True)
class StateCoordinates:
    """(p / parameter_scale, P_1 u, ..., P_k u): the continuation parameter and ``projections``
    fixed Gaussian projections of the state scaled by 1/sqrt(n), so each has the size of the
    root-mean-square of u (the state part of contin's arclength norm, ``ExtendedSystem.dot``).

    Needs fully stored branches (``save_every = 1``).  Generic: u and S u (or any two
    different states) differ in at least one projection with probability one.
    """

    parameter: str
    parameter_scale: float = 1.0
    projections: int = 4
    seed: int = 0

    def _project(self, states: Array) -> Array:
        n = states.shape[-1]
        r = np.random.default_rng(self.seed).standard_normal((n, self.projections)) / np.sqrt(n)
        return states @ r

    def branch(self, b: Branch) -> Array:
        if b.state_index is not None:
            raise ValueError(f"branch {b.id}: comparing branches needs every state (save_every = 1)")
        return np.column_stack([b.params[self.parameter] / self.parameter_scale, self._project(b.states)])

    def point(self, problem: Any, u: Array, p: Mapping[str, float]) -> Array:
        return np.concatenate([[p[self.parameter] / self.parameter_scale], self._project(np.asarray(u, float))])


def segment_distances(points: Array, line: Array) -> Array:
    """(points, segments) distances of every point to every segment of the polyline ``line``."""
    a, b = line[:-1], line[1:]
    d = b - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    t = np.clip(np.einsum("pk,sk->ps", points, d) - np.einsum("sk,sk->s", a, d)[None, :], 0.0, None) / dd[None, :]
    t = np.minimum(t, 1.0)
    proj = a[None, :, :] + t[:, :, None] * d[None, :, :]
    return np.linalg.norm(points[:, None, :] - proj, axis=2)


def distance_to_polyline(points: Array, line: Array) -> Array:
    """Distance of every point (rows) to the polyline through ``line`` (rows are vertices)."""
    if len(line) == 1:
        return np.linalg.norm(points - line[0], axis=1)
    out = np.empty(len(points))
    for i0 in range(0, len(points), 256):  # bounded memory: (256, segments, k) at a time
        out[i0: i0 + 256] = np.min(segment_distances(points[i0: i0 + 256], line), axis=1)
    return out


def lies_on(a: Branch, b: Branch, coordinates: Coordinates, tol: float = 5e-3, fraction: float = 0.9) -> bool:
    """True when at least ``fraction`` of the points of ``a`` lie within ``tol`` of ``b``'s
    polyline in ``coordinates``: ``a`` is (part of) ``b``."""
    if len(a) == 0 or len(b) == 0:
        return False
    dist = distance_to_polyline(coordinates.branch(a), coordinates.branch(b))
    return bool(np.mean(dist <= tol) >= fraction)


def near(problem: Any, u: Array, p: Mapping[str, float], branch: Branch, coordinates: Coordinates,
         tol: float = 2e-3) -> bool:
    """True when the state (u, p) lies within ``tol`` of ``branch`` in ``coordinates``."""
    if len(branch) == 0:
        return False
    pt = np.atleast_2d(coordinates.point(problem, u, p))
    line = coordinates.branch(branch)[:, : pt.shape[1]]
    return bool(np.min(distance_to_polyline(pt, line)) < tol)


def arclength(b: Branch) -> float:
    return float(np.sum(b.ds))


def deduplicate(branches: Sequence[Branch], coordinates: Coordinates,
                tol: float = 5e-3) -> tuple[list[Branch], list[tuple[str, str]]]:
    """One branch per solution set: a branch lying on another (:func:`lies_on`) is dropped in
    favour of the closed or longer one.  Returns (kept in input order, [(dropped id, kept id)])."""
    order = sorted(branches, key=lambda b: (not b.closed, -arclength(b)))
    kept: list[Branch] = []
    dropped: list[tuple[str, str]] = []
    for b in order:
        twin = next((k for k in kept if lies_on(b, k, coordinates, tol)), None)
        if twin is None:
            kept.append(b)
        else:
            dropped.append((b.id, twin.id))
    ids = [b.id for b in branches]
    kept.sort(key=lambda b: ids.index(b.id))
    return kept, dropped


def params_at(branch: Branch, i: int) -> dict[str, float]:
    """Every parameter of the branch at point i."""
    return {k: float(v[i]) for k, v in branch.params.items()}


def slice_branch(branch: Branch, i0: int, i1: int) -> Branch:
    """Points i0..i1 (inclusive) of a branch, with the special points and stored states inside
    (a branch that saved every k-th state keeps its ``state_index``, shifted)."""
    keep = slice(i0, i1 + 1)
    if branch.state_index is None:
        states, state_index = branch.states[keep].copy(), None
    else:
        inside = (branch.state_index >= i0) & (branch.state_index <= i1)
        states, state_index = branch.states[inside].copy(), branch.state_index[inside] - i0
    sps = [replace(s, index=s.index - i0) for s in branch.special_points if i0 <= s.index < i1 or
           (s.type in ("EP", "MX") and i0 <= s.index <= i1)]
    return replace(
        branch, params={k: v[keep].copy() for k, v in branch.params.items()},
        observables={k: v[keep].copy() for k, v in branch.observables.items()},
        states=states, tangents=branch.tangents[keep].copy(),
        ds=np.concatenate([[0.0], branch.ds[i0 + 1: i1 + 1]]), newton_iterations=branch.newton_iterations[keep].copy(),
        special_points=sps, closed=branch.closed and i0 == 0 and i1 == len(branch) - 1, state_index=state_index,
        stable=None, n_unstable=None, eigenvalues=None,
        grid=None if branch.grid is None else branch.grid[keep].copy(),
        sizes=None if branch.sizes is None else branch.sizes[keep].copy())


def _nearest_row(branch: Branch, seed: Array) -> int | None:
    """The point of ``branch`` nearest to ``seed`` among its states of the seed's size (an adaptive
    branch's rows are NaN-padded to its largest grid: `contin trace gravity -s Fr=1e20` ended
    'operands could not be broadcast together with shapes (616,901) (1,261)', qa19); None if the
    branch has no state of that size (it left the seed's grid at once: nothing to compare)."""
    states = branch.states
    width = seed.shape[0]
    if branch.sizes is None:
        return int(np.argmin(np.linalg.norm(states - seed[None, :], axis=1))) if states.shape[1] == width else None
    same = np.flatnonzero(np.asarray(branch.sizes) == width)
    if same.size == 0:
        return None
    return int(same[np.argmin(np.linalg.norm(states[same, :width] - seed[None, :], axis=1))])


def trim_to_new(branch: Branch, seed: Array, known: Sequence[Branch], coordinates: Coordinates,
                tol: float = 2e-3, columns: int | None = None) -> Branch:
    """The part of ``branch`` around the seed state that does not run along a ``known`` branch.

    When two branches pass close to each other a step may land on the neighbour; the run then
    retraces a branch already known.  The contiguous stretch through the point nearest to
    ``seed`` whose points are off every known branch is kept (one point of overlap at each
    end).  ``columns``: compare on the first ``columns`` coordinates only.
    """
    if not known or len(branch) < 3 or branch.state_index is not None:
        return branch
    pts = coordinates.branch(branch)[:, :columns]
    on = np.zeros(len(branch), bool)
    for k in known:
        on |= distance_to_polyline(pts, coordinates.branch(k)[:, :columns]) < tol
    if not on.any():
        return branch
    i = _nearest_row(branch, np.asarray(seed, dtype=float))
    if i is None:
        return branch
    lo = i
    while lo > 0 and not on[lo - 1]:
        lo -= 1
    hi = i
    while hi < len(branch) - 1 and not on[hi + 1]:
        hi += 1
    lo, hi = max(lo - 1, 0), min(hi + 1, len(branch) - 1)
    out = slice_branch(branch, lo, hi)
    out.message = f"{branch.message}; trimmed to points {lo}..{hi} (the rest runs along known branches)"
    return out


def _symmetry_of(problem: Any) -> Any:
    """A callable u -> S u from ``symmetry_matrix`` (preferred) or ``symmetry``; None if neither."""
    if callable(getattr(problem, "symmetry_matrix", None)):
        s = problem.symmetry_matrix()
        return lambda u: np.asarray(s @ u)
    if callable(getattr(problem, "symmetry", None)):
        return problem.symmetry
    return None


def is_invariant(problem: Any, branch: Branch, tol: float = 1e-6) -> bool:
    """True when the middle stored state of the branch is S-invariant (the branch maps to itself);
    a point of an adaptive run is reflected on its own grid (``contin.adapt.point_problem``)."""
    i = len(branch.states) // 2
    if branch.sizes is not None:
        from contin.adapt import point_problem

        problem = point_problem(problem, branch, i)
        x = branch.state(i)
    else:
        x = branch.states[i]
    s = _symmetry_of(problem)
    if s is None:
        return True
    return float(np.max(np.abs(s(x) - x))) <= tol * max(1.0, float(np.max(np.abs(x))))


def mirror_branch(problem: Any, branch: Branch, params: Mapping[str, float], branch_id: str) -> Branch:
    """The image of ``branch`` under the problem's involution S (``symmetry_matrix`` or
    ``symmetry``): F(S u, p) = S F(u, p) makes S maps solutions onto solutions, so the image is
    a branch without tracing it.  Observables and the order parameter are recomputed; stability
    columns are copied (S maps the linearisation at u onto that at S u).
    """
    s = _symmetry_of(problem)
    if s is None:
        raise ValueError("mirror_branch needs a problem with symmetry or symmetry_matrix")
    if branch.state_index is not None:
        raise ValueError("mirror_branch needs every state of the branch (save_every = 1)")
    if branch.sizes is not None:  # points on several grids (adaptive runs)
        return _mirror_regridded(problem, branch, params, branch_id)
    states = np.array([s(x) for x in branch.states])
    has_obs = callable(getattr(problem, "observables", None))
    has_op = callable(getattr(problem, "order_parameter", None))
    obs: dict[str, list[float]] = {}
    for i, x in enumerate(states):
        p = {**params, **params_at(branch, i)}
        row: dict[str, float] = {k: float(v) for k, v in problem.observables(x, p).items()} if has_obs else {}
        if has_op:
            row["phi"] = float(problem.order_parameter(x, p))
        for k, v in row.items():
            obs.setdefault(k, []).append(v)
    m = branch.tangents.shape[1] - states.shape[1]
    tang = branch.tangents.copy()
    tang[:, :-m] = np.array([s(t) for t in branch.tangents[:, :-m]])

    def image(sp_: Any) -> Any:
        p = {**params, **sp_.params}
        u = s(sp_.state)
        return replace(sp_, state=u, order_parameter=float(problem.order_parameter(u, p)) if has_op else sp_.order_parameter,
                       tangent=None if sp_.tangent is None else np.concatenate([s(sp_.tangent[:-m]), sp_.tangent[-m:]]))

    return dataclasses.replace(
        branch, observables={k: np.array(v) for k, v in obs.items()} if obs else dict(branch.observables),
        states=states, tangents=tang, special_points=[image(sp_) for sp_ in branch.special_points], id=branch_id,
        kind=branch.kind, audit=list(branch.audit), message=f"mirror image of branch {branch.id}",
        stable=None if branch.stable is None else branch.stable.copy(),
        n_unstable=None if branch.n_unstable is None else branch.n_unstable.copy(),
        eigenvalues=None if branch.eigenvalues is None else branch.eigenvalues.copy())


def image_defect(problem: Any, branch: Branch, image: Branch, params: Mapping[str, float]) -> str | None:
    """Why the image of ``branch`` under the problem's symmetry is no branch of solutions (None if
    its states at the first, middle and last point solve F as well as the originals do).  A
    ``symmetry`` that is one of F only at some parameters made :func:`contin.diagram.explore`
    store non-solutions as a branch, exit 0 (qa15); the tracer's own guard is
    ``contin.continuation.EQUIVARIANCE_TOL``."""
    from contin.adapt import point_problem
    from contin.newton import max_norm

    n = len(branch)
    for i in sorted({0, n // 2, n - 1}) if n else []:
        pb = point_problem(problem, branch, i) if branch.sizes is not None else problem
        p = {**params, **params_at(branch, i)}
        with np.errstate(all="ignore"):
            r0 = max_norm(np.asarray(pb.residual(branch.state(i), p), dtype=float))
            r1 = max_norm(np.asarray(pb.residual(image.state(i), p), dtype=float))
        if not r1 <= max(100.0 * r0, 1e-8):
            return (f"the problem's symmetry is not one of F on branch {branch.id} (residual {r1:.2g} of the "
                    f"reflected state at point {i}, {r0:.2g} of the state)")
    return None


def _mirror_regridded(problem: Any, branch: Branch, params: Mapping[str, float], branch_id: str) -> Branch:
    """:func:`mirror_branch` for a branch whose points lie on several grids (adaptive runs): each
    point reflected by the problem on its own grid (``contin.adapt.point_problem``)."""
    from contin.adapt import on_grid, point_problem
    from contin.branch import pad_rows

    states, tangents, obs = [], [], {}
    for i in range(len(branch)):
        pb = point_problem(problem, branch, i)
        s = _symmetry_of(pb)
        x = s(branch.state(i))
        t = branch.tangent(i)
        states.append(x)
        m = t.size - x.size
        tangents.append(np.concatenate([s(t[:-m]), t[-m:]]))
        p = {**params, **params_at(branch, i)}
        row = {k: float(v) for k, v in pb.observables(x, p).items()} if callable(getattr(pb, "observables", None)) else {}
        if callable(getattr(pb, "order_parameter", None)):
            row.setdefault("phi", float(pb.order_parameter(x, p)))
        for k, v in row.items():
            obs.setdefault(k, []).append(v)

    def image(sp_: Any) -> Any:
        pb = on_grid(problem, sp_.grid)
        s = _symmetry_of(pb)
        x = s(sp_.state)
        m = None if sp_.tangent is None else sp_.tangent.size - x.size
        return replace(sp_, state=x, order_parameter=float(pb.order_parameter(x, {**params, **sp_.params})),
                       tangent=None if sp_.tangent is None else np.concatenate([s(sp_.tangent[:-m]), sp_.tangent[-m:]]))

    return dataclasses.replace(
        branch, observables={k: np.array(v) for k, v in obs.items()} if obs else dict(branch.observables),
        states=pad_rows(states, branch.states.shape[1]), tangents=pad_rows(tangents, branch.tangents.shape[1]),
        special_points=[image(sp_) for sp_ in branch.special_points], id=branch_id, kind=branch.kind,
        audit=list(branch.audit), message=f"mirror image of branch {branch.id}",
        stable=None if branch.stable is None else branch.stable.copy(),
        n_unstable=None if branch.n_unstable is None else branch.n_unstable.copy(),
        eigenvalues=None if branch.eigenvalues is None else branch.eigenvalues.copy())
