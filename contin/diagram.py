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

import math

import logging
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint, relabel
from contin.continuation import switch, trace
from contin.jumps import restep, retrace_on_jumps, trace_both_ways
from contin.options import ContinuationOptions
from contin.overlap import (Coordinates, StateCoordinates, image_defect, is_invariant, lies_on, mirror_branch, near,
                            params_at)
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
    probe_steps = 0 : no probe (each direction is traced, then dropped if it lies on a known branch)
    start_direction : 0 = the start branch both ways (:func:`contin.jumps.trace_both_ways`),
        +1 / -1 = one way (:func:`contin.continuation.trace`; e.g. from a bound)
    retraces : a trace that jumped between branches is repeated with ds_max halved, at most this
        often (:func:`contin.jumps.retrace_on_jumps`): the start branch when a BP location did not
        converge, a switched branch when ``DiagramHooks.jumped`` says so
    """

    depth: int = 3
    max_branches: int = 200
    probe_steps: int = 4
    tol: float = 5e-3
    fraction: float = 0.9
    mirror: bool = True
    excursion: float = float("inf")
    unconverged: bool = True
    start_direction: int = 0
    retraces: int = 0

    def __post_init__(self) -> None:
        from contin.options import _check_field_types

        _check_field_types(self)  # depth = 2.5 ran as a depth (qa15)
        # each a clear error (qa15): max_branches 0 gave the start branch alone, tol = inf or
        # fraction 0 made every branch a duplicate of the first (one branch, silently), fraction 2
        # or NaN and excursion -1 or NaN were accepted
        if self.max_branches < 1:
            raise ValueError(f"max_branches must be >= 1, got {self.max_branches}")
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"tol must be a finite number > 0, got {self.tol}")
        if not 0 < self.fraction <= 1:
            raise ValueError(f"fraction must lie in (0, 1], got {self.fraction}")
        if not self.excursion > 0:
            raise ValueError(f"excursion must be > 0 (inf switches the jump repair off), got {self.excursion}")
        if self.depth < 1:
            raise ValueError(f"depth must be >= 1 (the start branch), got {self.depth}")
        if self.probe_steps < 0:
            raise ValueError(f"probe_steps must be >= 0, got {self.probe_steps}")
        if self.start_direction not in (-1, 0, 1):
            raise ValueError(f"start_direction must be -1, 0 or +1, got {self.start_direction}")
        if self.retraces < 0:
            raise ValueError(f"retraces must be >= 0, got {self.retraces}")


@dataclass(frozen=True)
class DiagramHooks:
    """What a problem family decides in :func:`bifurcation_diagram` (its physics); all optional.

    switch_at(branch, bp) -> prefix | None : the ids of the branches switched at ``bp`` are
        f"{prefix}.1" (direction +1) and f"{prefix}.2"; None = do not switch there (default:
        every BP, prefix f"{branch.id}.{bp.name}")
    mirror_id(branch_id) -> id : the id of a traced branch's image (default f"{branch_id}'"; a
        scene naming the two signs of a pitchfork 'n1.1' / 'n1.2' maps one onto the other)
    jumped(parent, child) -> reason | None : a switched branch that jumped (e.g. came back onto its
        parent) is re-traced with ds_max halved (``DiagramSettings.retraces``)
    finish(branch) : called on every traced branch before it is stored and mirrored (e.g. re-check
        its BPs on a finer grid: what it changes reaches the image)
    on_branch(branch, source) : every stored branch as soon as it is known, ``source`` the traced
        branch it mirrors or None (checkpointing, stability)
    completed : branches of an interrupted run by id, reused instead of traced (``--resume``)
    options(parent) -> ContinuationOptions : the options of the start branch (parent None) and of
        the branches switched off ``parent`` (default: the ``options`` argument for every branch)
    start_id : the id of the start branch
    """

    switch_at: Callable[[Branch, SpecialPoint], str | None] | None = None
    mirror_id: Callable[[str], str] | None = None
    jumped: Callable[[Branch, Branch], str | None] | None = None
    finish: Callable[[Branch], None] | None = None
    on_branch: Callable[[Branch, Branch | None], None] | None = None
    completed: Mapping[str, Branch] = field(default_factory=dict)
    options: Callable[[Branch | None], ContinuationOptions] | None = None
    start_id: str = "0"


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
                        seeds: Sequence[Seed] = (), progress: Callable[[str], None] | None = None,
                        hooks: DiagramHooks = DiagramHooks()) -> Diagram:
    """The bifurcation diagram from (u0, params) in ``parameter`` (module docstring).

    ``options`` are used for every branch (bounds included); ``coordinates`` decide when two
    branches are the same (default :class:`contin.overlap.StateCoordinates`: the parameter and
    random projections of the state); ``seeds`` are traced after the start branch, each unless
    it lies on a known branch; ``hooks`` carry the problem family's choices (:class:`DiagramHooks`).
    """
    coords = coordinates if coordinates is not None else StateCoordinates(parameter)
    say = progress or (lambda m: None)
    out = Diagram(branches=[])
    queue: deque[Branch] = deque()
    symmetric = settings.mirror and (callable(getattr(problem, "symmetry", None))
                                     or callable(getattr(problem, "symmetry_matrix", None)))
    mirror_id = hooks.mirror_id or (lambda i: f"{i}'")

    def on_known(u: Array, p: Mapping[str, float], exclude: Branch | None = None) -> Branch | None:
        return next((k for k in out.branches if k is not exclude and near(problem, u, p, k, coords, settings.tol)), None)

    def add(b: Branch, level: int) -> None:
        if hooks.finish is not None and b.id not in hooks.completed:
            hooks.finish(b)
        out.branches.append(b)
        relabel(out.branches)  # AUTO-style labels, stable for the branches found before
        out.level[b.id] = level
        queue.append(b)
        if hooks.on_branch is not None:
            hooks.on_branch(b, None)
        if symmetric and len(b) > 0 and not is_invariant(problem, b):
            mid = mirror_id(b.id)
            m = hooks.completed.get(mid) or mirror_branch(problem, b, params, mid)
            bad = None if mid in hooks.completed else image_defect(problem, b, m, params)
            if bad is not None:  # not a branch of solutions: not stored (and traced where a BP leads to it)
                out.skipped.append(f"{mid}: not stored as the image of {b.id}: {bad}")
                return
            twin = next((k for k in out.branches if lies_on(m, k, coords, settings.tol, settings.fraction)), None)
            if twin is None:
                out.branches.append(m)
                out.level[m.id] = level
                out.mirrors[m.id] = b.id
                relabel(out.branches)
                if hooks.on_branch is not None:
                    hooks.on_branch(m, b)

    def trace_from(u: Array, p: Mapping[str, float], bid: str, kind: str, parent: str,
                   direction: int = 0) -> Branch:
        if bid in hooks.completed:
            return hooks.completed[bid]

        def run(o: ContinuationOptions) -> Branch:
            if direction == 0:
                return trace_both_ways(problem, u, p, parameter, o, coordinates=coords, excursion=settings.excursion,
                                       restep="local", branch_id=bid, kind=kind, parent=parent, progress=progress)
            return trace(problem, u, dict(p), parameter, o, direction=direction, branch_id=bid, kind=kind,
                         parent=parent, progress=progress)

        opts = hooks.options(None) if hooks.options is not None else options
        if settings.retraces == 0:
            return run(opts)
        return retrace_on_jumps(run, opts, what="base branch" if bid == hooks.start_id else f"branch {bid}",
                                retraces=settings.retraces)

    say(f"diagram: start branch in {parameter}")
    add(trace_from(u0, params, hooks.start_id, "primary", "", settings.start_direction), 1)
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
            _switch_at(problem, b, bp, params, options, settings, coords, out, on_known, add, level, progress, hooks)
    return out


def _switch_at(problem: Any, b: Branch, bp: SpecialPoint, params: Mapping[str, float], options: ContinuationOptions,
               settings: DiagramSettings, coords: Coordinates, out: Diagram,
               on_known: Callable[..., Branch | None], add: Callable[[Branch, int], None], level: int,
               progress: Callable[[str], None] | None, hooks: DiagramHooks) -> None:
    """Both directions of the BP ``bp`` of ``b``: probed, traced when new, added at level + 1.

    At a BP of an S-invariant branch whose first direction gave a branch that is not S-invariant
    (a symmetry-breaking pitchfork), the second direction is that branch's image, already stored:
    it is neither probed nor traced."""
    where = f"{bp.name}@{b.id} ({b.parameter} = {bp.params[b.parameter]:.6g})"
    prefix = hooks.switch_at(b, bp) if hooks.switch_at is not None else f"{b.id}.{bp.name}"
    if prefix is None:
        out.skipped.append(f"{where}: not selected for switching")
        return
    if not bp.converged and not settings.unconverged:
        out.skipped.append(f"{where}: location not converged")
        return
    crossing = on_known(bp.state, bp.params, exclude=b)
    if crossing is not None:
        out.skipped.append(f"{where}: branch {crossing.id} passes through it (crossing already known)")
        return
    if hooks.options is not None:
        options = hooks.options(b)
    probe_opts = replace(options, max_steps=max(settings.probe_steps, 1))
    first: Branch | None = None
    for k, d in enumerate((+1, -1), start=1):
        bid = f"{prefix}.{k}"
        if first is not None and first.id in out.mirrors.values() and is_invariant(problem, b):
            image = next(m for m, t in out.mirrors.items() if t == first.id)
            out.skipped.append(f"{bid}: the image {image} of {first.id} (symmetry-breaking BP of an invariant branch)")
            continue
        if bid in hooks.completed:
            first = hooks.completed[bid]
            add(first, level + 1)
            continue
        if settings.probe_steps > 0:
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

        def run(o: ContinuationOptions, d: int = d, bid: str = bid) -> Branch:
            nb = switch(problem, b, bp, o, directions=(d,), branch_id_prefix=prefix)[0]
            nb.id = bid
            return nb

        try:
            if hooks.jumped is not None and settings.retraces > 0:
                nb = retrace_on_jumps(run, options, what=f"branch from {bp.name}", unconverged_bp=False,
                                      jumped=lambda nb: hooks.jumped(b, nb), retraces=settings.retraces)
            else:
                nb = run(options)
        except ValueError as exc:  # switch says why it found no branch (it never returns [])
            out.skipped.append(f"{bid}: switching found no start point ({exc})")
            continue
        if np.isfinite(settings.excursion):
            nb = restep(problem, nb, params, options, coords, excursion=settings.excursion, branch_id=bid,
                        kind=nb.kind, parent=nb.parent)
        twin = next((t for t in out.branches if lies_on(nb, t, coords, settings.tol, settings.fraction)), None)
        if twin is not None:
            out.skipped.append(f"{bid}: lies on branch {twin.id}")
            continue
        if progress is not None:
            progress(f"diagram: branch {bid} ({len(nb)} points, level {level + 1})")
        first = nb
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
