"""Automatic bifurcation diagrams: trace, switch at every BP to a given depth, keep each branch once.

BifurcationKit's ``bifurcationdiagram`` (Veltz, https://hal.archives-ouvertes.fr/hal-02902346)
recursively switches at every branch point of every branch up to a level.  Written by hand,
that recursion traces every solution set several times: both halves of a symmetry-breaking
pitchfork (one is the mirror image of the other), every branch again from each BP it passes
through (a branch joining two BPs of its parent is met from both ends, and at a BP where a child
crosses its parent the recursion switches back onto the parent and retraces it and its whole
subtree).  :func:`bifurcation_diagram` does the same recursion but

- skips a BP through which another known branch passes (its crossing is already explored:
  a simple BP has exactly two branches through it);
- probes each direction of a BP with a few steps (``DiagramSettings.probe_steps``) and traces it
  only if the probe lies on no known branch;
- stores the image of every traced branch under the problem's involution S (``symmetry`` or
  ``symmetry_matrix``; F(S u, p) = S F(u, p)) by reflection instead of tracing it, and does not
  recurse into images (their children are the images of the children);
- drops a traced branch lying on a known one (:func:`contin.overlap.lies_on`);
- repairs jumps between nearby sheets (a run coming back along itself) by re-stepping after
  the jump (:func:`contin.jumps.restep`), not by retracing the branch, when
  ``DiagramSettings.excursion`` is finite (it is in units of the parameter, so problem-specific);
- traces extra seeds (:mod:`contin.seeds`: homotopies in a second parameter, fold-curve
  crossings), so that isolas are discovered, not only closed (a closed loop is returned once).

Branch ids: '0' the start branch, 's<k>' the k-th seed, f"{parent}.{BP label}.{1|2}" a switched
branch (direction +1 / -1), f"{id}'" the mirror image of branch ``id``.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint, relabel
from contin.continuation import switch
from contin.jumps import restep, trace_both_ways
from contin.options import ContinuationOptions
from contin.overlap import Coordinates, StateCoordinates, is_invariant, lies_on, mirror_branch, near, params_at
from contin.seeds import Seed

log = logging.getLogger("contin")
Array = np.ndarray


@dataclass(frozen=True)
class DiagramSettings:
    """Settings of :func:`bifurcation_diagram`.

    depth : BifurcationKit's ``level``: 1 = the start branch (and seeds) only, 2 = also the
        branches switched at their BPs, 3 = also those switched on these, ...
    max_branches : stop switching once this many branches (images included) are known
    probe_steps : continuation steps of the probe of each BP direction
    tol : distance (in the coordinates) below which a point lies on a known branch
    fraction : share of a traced branch's points within ``tol`` of a known branch that makes it
        a duplicate
    mirror : store images under the problem's symmetry instead of tracing them
    excursion : parameter span that a run must cover before it can come back along itself
        (:func:`contin.jumps.trim_self_overlap`); inf switches the jump repair off
    unconverged : also switch at BPs whose location did not converge (the switching start is
        then slightly off the BP; the probe and the duplicate test keep the result honest)
    """

    depth: int = 3
    max_branches: int = 200
    probe_steps: int = 4
    tol: float = 5e-3
    fraction: float = 0.9
    mirror: bool = True
    excursion: float = float("inf")
    unconverged: bool = True

    def __post_init__(self) -> None:
        if self.depth < 1:
            raise ValueError(f"depth must be >= 1 (the start branch), got {self.depth}")
        if self.probe_steps < 1:
            raise ValueError(f"probe_steps must be >= 1, got {self.probe_steps}")
        if not self.tol > 0:
            raise ValueError(f"tol must be > 0, got {self.tol}")


@dataclass
class Diagram:
    """Branches of an automatic bifurcation diagram.

    branches : every branch, traced or mirrored, in the order found
    level : branch id -> recursion level (1 = start branch and seeds)
    mirrors : image id -> id of the traced branch it reflects
    skipped : one line per BP direction not traced, with the reason (known crossing, probe on a
        known branch, duplicate, switching failed)
    """

    branches: list[Branch]
    level: dict[str, int] = field(default_factory=dict)
    mirrors: dict[str, str] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)

    @property
    def traced(self) -> list[Branch]:
        """The branches that were traced (not mirrored)."""
        return [b for b in self.branches if b.id not in self.mirrors]

    def branch(self, branch_id: str) -> Branch:
        return next(b for b in self.branches if b.id == branch_id)


def bifurcation_diagram(problem: Any, u0: Array, params: Mapping[str, float], parameter: str,
                        options: ContinuationOptions = ContinuationOptions(),
                        settings: DiagramSettings = DiagramSettings(), *, coordinates: Coordinates | None = None,
                        seeds: Sequence[Seed] = (), progress: Callable[[str], None] | None = None) -> Diagram:
    """The bifurcation diagram from (u0, params) in ``parameter`` (module docstring).

    ``options`` are used for every branch (bounds included); ``coordinates`` decide when two
    branches are the same (default :class:`contin.overlap.StateCoordinates`: the parameter and
    random projections of the state); ``seeds`` are traced after the start branch, each unless
    it lies on a known branch.
    """
    coords = coordinates if coordinates is not None else StateCoordinates(parameter)
    say = progress or (lambda m: None)
    out = Diagram(branches=[])
    queue: deque[Branch] = deque()
    symmetric = settings.mirror and (callable(getattr(problem, "symmetry", None))
                                     or callable(getattr(problem, "symmetry_matrix", None)))

    def on_known(u: Array, p: Mapping[str, float], exclude: Branch | None = None) -> Branch | None:
        return next((k for k in out.branches if k is not exclude and near(problem, u, p, k, coords, settings.tol)), None)

    def add(b: Branch, level: int) -> None:
        out.branches.append(b)
        relabel(out.branches)  # AUTO-style labels, stable for the branches found before
        out.level[b.id] = level
        queue.append(b)
        if symmetric and len(b) > 0 and not is_invariant(problem, b):
            m = mirror_branch(problem, b, params, f"{b.id}'")
            twin = next((k for k in out.branches if lies_on(m, k, coords, settings.tol, settings.fraction)), None)
            if twin is None:
                out.branches.append(m)
                out.level[m.id] = level
                out.mirrors[m.id] = b.id
                relabel(out.branches)

    def trace_from(u: Array, p: Mapping[str, float], bid: str, kind: str, parent: str) -> Branch:
        return trace_both_ways(problem, u, p, parameter, options, coordinates=coords, excursion=settings.excursion,
                               restep="local", branch_id=bid, kind=kind, parent=parent, progress=progress)

    say(f"diagram: start branch in {parameter}")
    add(trace_from(u0, params, "0", "primary", ""), 1)
    for k, seed in enumerate(seeds):
        twin = on_known(seed.state, seed.params)
        if twin is not None:
            out.skipped.append(f"seed {seed.label}: on known branch {twin.id}")
            continue
        say(f"diagram: seed {k} ({seed.label})")
        b = trace_from(seed.state, seed.params, f"s{k}", "seeded", seed.label)
        twin = next((t for t in out.branches if lies_on(b, t, coords, settings.tol, settings.fraction)), None)
        if twin is not None:
            out.skipped.append(f"seed {seed.label}: its branch lies on {twin.id}")
            continue
        add(b, 1)
    while queue:
        b = queue.popleft()
        level = out.level[b.id]
        if level >= settings.depth:
            continue
        for bp in b.branch_points:
            if len(out.branches) >= settings.max_branches:
                out.skipped.append(f"{bp.name}@{b.id}: max_branches = {settings.max_branches} reached")
                break
            _switch_at(problem, b, bp, params, options, settings, coords, out, on_known, add, level, progress)
    return out


def _switch_at(problem: Any, b: Branch, bp: SpecialPoint, params: Mapping[str, float], options: ContinuationOptions,
               settings: DiagramSettings, coords: Coordinates, out: Diagram,
               on_known: Callable[..., Branch | None], add: Callable[[Branch, int], None], level: int,
               progress: Callable[[str], None] | None) -> None:
    """Both directions of the BP ``bp`` of ``b``: probed, traced when new, added at level + 1."""
    where = f"{bp.name}@{b.id} ({b.parameter} = {bp.params[b.parameter]:.6g})"
    if not bp.converged and not settings.unconverged:
        out.skipped.append(f"{where}: location not converged")
        return
    crossing = on_known(bp.state, bp.params, exclude=b)
    if crossing is not None:
        out.skipped.append(f"{where}: branch {crossing.id} passes through it (crossing already known)")
        return
    probe_opts = replace(options, max_steps=settings.probe_steps)
    for k, d in enumerate((+1, -1), start=1):
        bid = f"{b.id}.{bp.name}.{k}"
        try:
            probe = switch(problem, b, bp, probe_opts, directions=(d,), branch_id_prefix="probe")
        except ValueError as exc:  # not a simple BP, or no start point in this direction: say why
            out.skipped.append(f"{bid}: cannot switch ({exc})")
            continue
        if not probe or len(probe[0]) < 2:
            out.skipped.append(f"{bid}: switching found no start point")
            continue
        pr = probe[0]
        i = len(pr) - 1
        twin = on_known(pr.state(i), params_at(pr, i))
        if twin is not None:
            out.skipped.append(f"{bid}: probe lies on branch {twin.id}")
            continue
        try:
            new = switch(problem, b, bp, options, directions=(d,), branch_id_prefix=f"{b.id}.{bp.name}")
        except ValueError as exc:  # switch says why it found no branch (it never returns [])
            out.skipped.append(f"{bid}: switching found no start point ({exc})")
            continue
        nb = new[0]
        nb.id = bid
        if np.isfinite(settings.excursion):
            nb = restep(problem, nb, params, options, coords, excursion=settings.excursion, branch_id=bid,
                        kind=nb.kind, parent=nb.parent)
        twin = next((t for t in out.branches if lies_on(nb, t, coords, settings.tol, settings.fraction)), None)
        if twin is not None:
            out.skipped.append(f"{bid}: lies on branch {twin.id}")
            continue
        if progress is not None:
            progress(f"diagram: branch {bid} ({len(nb)} points, level {level + 1})")
        add(nb, level + 1)


def explore(start: Any, request: Any, *, depth: int | None = None, max_branches: int | None = None) -> Any:
    """A scene's automatic diagram: :func:`bifurcation_diagram` from ``start`` (a
    :class:`contin.scene.DiagramStart`) as a :class:`contin.scene.SceneResult`
    (``contin trace SCENE --depth D``).

    ``depth`` / ``max_branches`` replace the start's settings.  Every branch (mirror images
    included) gets the stability pass the request asks for and is handed to
    ``request.finished``; the notes list the BP directions not traced and why (known crossing,
    probe on a known branch, duplicate), then the scene's own notes on the diagram.
    """
    from contin.scene import SceneResult

    settings = start.settings if start.settings is not None else DiagramSettings()
    if depth is not None:
        settings = replace(settings, depth=depth)
    if max_branches is not None:
        settings = replace(settings, max_branches=max_branches)
    request.report(f"diagram to depth {settings.depth} in {start.parameter}")
    d = bifurcation_diagram(start.problem, np.asarray(start.state, dtype=float), start.params, start.parameter,
                            start.options, settings, coordinates=start.coordinates, seeds=start.seeds,
                            progress=request.report)
    notes = []
    for b in d.branches:
        source = d.mirrors.get(b.id)
        if source is not None:
            b.message = f"mirror image of branch {source} under the problem's symmetry"
        for m in request.run_stability(start.problem, b, start.params):
            notes.append(f"stability audit, branch {b.id}: {m}")
        request.finished(b)
    levels = ", ".join(f"{n} at level {lv}" for lv, n in sorted(
        {lv: sum(1 for v in d.level.values() if v == lv) for lv in set(d.level.values())}.items()))
    notes.insert(0, f"diagram to depth {settings.depth}: {len(d.branches)} branches ({levels}), "
                    f"{len(d.mirrors)} of them mirror images")
    notes += [f"not traced: {s}" for s in d.skipped]
    if start.notes is not None:
        notes += start.notes(d)
    return SceneResult(branches=d.branches, parameters=dict(start.parameters), discretization=dict(start.discretization),
                       y=start.y, profiles=start.profiles, notes=notes,
                       extra={"diagram": {"depth": settings.depth, "level": dict(d.level), "mirrors": dict(d.mirrors),
                                          "skipped": list(d.skipped)}})
