"""Jumps between nearby sheets: detection on a traced branch, and tracing that repairs them.

The core tracer already refuses a single step that jumps where a BP test function changes
sign without a BP (``contin.continuation._jump_retry``).  What it cannot see from one step is
a jump between two sheets that are close but carry no test-function sign change (e.g. the
O(epsilon)-separated sheets of an imperfect bifurcation): the run then goes round a loop it
does not close, meets the same fold twice, or comes back along its own earlier part.  This
module recognises those signs on the finished branch (:func:`jumped`, :func:`trim_self_overlap`)
and repeats the run with a smaller largest step:

- :func:`trace_both_ways` -- both directions from a start point, a loop closed by either half
  returned once, open halves cut where they retrace themselves, and a jumped run traced
  again with ds_max halved (``restep="whole"``) or re-stepped from the last good point
  (``restep="local"``: only the part after the jump is traced again);
- :func:`retrace_on_jumps` -- any run repeated with ds_max halved while a caller's test says
  it jumped.

The step-length reasoning (a long step can land on a neighbouring sheet; the predictor's error
falls like ds^2) is that of Keller's pseudo-arclength method; repairing with a shorter step is
what AUTO-07p and BifurcationKit do on a failed step.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from contin.branch import Branch
from contin.continuation import join, trace
from contin.options import ContinuationOptions
from contin.overlap import Coordinates, params_at, segment_distances, slice_branch

log = logging.getLogger("contin")
Array = np.ndarray

#: Halvings of ds_max of :func:`retrace_on_jumps`.
RETRACES = 4

#: Words of the message of a branch cut by :func:`trim_self_overlap` (read by :func:`jumped`).
SELF_OVERLAP = "own earlier part"


def repeated_fold(branch: Branch, rtol: float = 1e-6, atol: float = 1e-6) -> bool:
    """True when the same fold (parameter within rtol, order parameter within atol) is met twice."""
    par = branch.parameter
    f = np.array([(lp.params[par], lp.order_parameter) for lp in branch.fold_points]).reshape(-1, 2)
    for i in range(len(f)):
        for j in range(i + 1, len(f)):
            if abs(f[i, 0] - f[j, 0]) <= rtol * abs(f[i, 0]) and abs(f[i, 1] - f[j, 1]) <= atol:
                return True
    return False


def jumped(branch: Branch) -> bool:
    """Signs of a jump between sheets: a half-run cut by :func:`trim_self_overlap`, or the same
    fold met twice (both halves, or one half going round a loop it did not close)."""
    return SELF_OVERLAP in branch.message or repeated_fold(branch)


def trim_self_overlap(branch: Branch, coordinates: Coordinates, tol: float = 2e-3, skip: int = 20, run: int = 5,
                      excursion: float = 5.0) -> Branch:
    """The branch up to where it starts running along its own earlier part.

    An open half-run that comes back onto points it has already traced has gone round a loop
    after a jump between two nearby sheets (a closed loop would have been detected).  The
    branch is cut before the first of ``run`` consecutive points that lie within ``tol`` (in
    ``coordinates``) of a segment more than ``skip`` steps earlier such that the branch
    between that segment and the point spans more than ``excursion`` in the continuation
    parameter.  The last condition spares folds: just past a fold the branch runs close to its
    part before the fold, but only after an excursion of the fold's width.
    """
    n = len(branch)
    if branch.closed or n <= skip + run or branch.state_index is not None:
        return branch
    pts = coordinates.branch(branch)
    P = branch.params[branch.parameter]
    near = np.zeros(n, bool)
    for i0 in range(skip + 1, n, 200):
        idx = np.arange(i0, min(i0 + 200, n))
        d = segment_distances(pts[idx], pts[: int(idx[-1]) - skip + 1])  # (points, segments)
        d[np.arange(d.shape[1])[None, :] >= (idx[:, None] - skip)] = np.inf
        for r, c in zip(*np.nonzero(d < tol)):
            i = int(idx[r])
            if not near[i] and np.ptp(P[int(c): i + 1]) > excursion:
                near[i] = True
    hits = np.convolve(near.astype(int), np.ones(run, int), "valid") == run
    if not hits.any():
        return branch
    cut = int(np.argmax(hits))
    if cut < 2:
        return branch
    out = slice_branch(branch, 0, cut - 1)
    out.message = (f"{branch.message}; cut at {branch.parameter} = {P[cut]:.6g}, where the run comes back "
                   f"along its {SELF_OVERLAP} (a jump between nearby sheets)")
    return out


def halved(options: ContinuationOptions, factor: float = 0.5, steps: float = 2.0) -> ContinuationOptions:
    """``options`` with ds_max (and ds, ds_min if larger) times ``factor`` and max_steps times ``steps``."""
    s = options.step
    top = factor * s.ds_max
    step = replace(s, ds_max=top, ds=math.copysign(min(abs(s.ds), top), s.ds), ds_min=min(s.ds_min, top))
    return replace(options, step=step, max_steps=int(round(steps * options.max_steps)))


def concat(first: Branch, second: Branch) -> Branch:
    """One branch from ``first`` followed by ``second``, which starts at ``first``'s last point."""
    out = join(first.reversed(), second)
    out.message = second.message
    return out


def restep(problem: Any, branch: Branch, params: Mapping[str, float], options: ContinuationOptions,
           coordinates: Coordinates, *, excursion: float = 5.0, min_ds_max: float = 0.0, back: int = 4,
           **kw: Any) -> Branch:
    """A one-direction run repaired where it comes back along itself: cut there
    (:func:`trim_self_overlap`), then re-stepped from ``back`` points before the cut with half
    the largest step (only the part after the jump is traced again; the part before was traced
    on its sheet).  Unchanged when there is no such overlap; the cut branch when ds_max <=
    ``min_ds_max`` or the re-stepped run closes a loop.  ``kw`` goes to
    :func:`contin.continuation.trace` (branch_id, kind, parent, symmetric...)."""
    cut = trim_self_overlap(branch, coordinates, excursion=excursion)
    if cut is branch or not options.step.ds_max > min_ds_max:
        return cut
    par = branch.parameter
    k = max(len(cut) - back, 1)
    head = slice_branch(branch, 0, k)
    finer = halved(options)
    tail = trace(problem, branch.state(k), {**params, **params_at(branch, k)}, par, finer, direction=1,
                 tangent=branch.tangents[k], **kw)
    if tail.closed:
        return cut
    # the re-stepped part may still come back along the part kept before it: cut the whole
    out = trim_self_overlap(concat(head, tail), coordinates, excursion=excursion)
    out.message += f" (re-stepped from {par} = {branch.params[par][k]:.6g} with ds_max = {finer.step.ds_max:g})"
    return out


def _half(problem: Any, state: Array, params: Mapping[str, float], parameter: str, options: ContinuationOptions,
          direction: int, coordinates: Coordinates | None, excursion: float, mode: str, min_ds_max: float,
          kw: dict[str, Any]) -> Branch:
    b = trace(problem, state, dict(params), parameter, options, direction=direction, **kw)
    if b.closed or coordinates is None:
        return b
    if mode == "local":
        return restep(problem, b, params, options, coordinates, excursion=excursion, min_ds_max=min_ds_max, **kw)
    return trim_self_overlap(b, coordinates, excursion=excursion)


def trace_both_ways(problem: Any, state: Array, params: Mapping[str, float], parameter: str,
                    options: ContinuationOptions, *, coordinates: Coordinates | None = None, excursion: float = 5.0,
                    restep: str = "whole", min_ds_max: float = 0.0, **kw: Any) -> Branch:
    """Both directions in ``parameter`` from ``state``; a closed loop is returned once, closed.

    Like :func:`contin.continuation.trace_both`, except that a loop closed by the *backward*
    half is also returned as is (the forward half can miss its closing point, e.g. when a step
    near the start is rejected, and would then run round the loop until max_steps), open halves
    are cut where they come back along themselves (:func:`trim_self_overlap`, with
    ``coordinates``; ``excursion`` in units of the parameter), and a run showing a jump
    (:func:`jumped`) is repaired: ``restep="whole"`` traces it once more with half the largest
    step (kept when that one closes or shows no jump); ``restep="local"`` re-steps each cut half
    from just before the cut with half the largest step.  No repair when ds_max <= ``min_ds_max``.
    Other keyword arguments go to :func:`contin.continuation.trace` (not ``direction``).
    """
    if restep not in ("whole", "local"):
        raise ValueError(f"restep must be 'whole' or 'local', got {restep!r}")

    def once(opts: ContinuationOptions, mode: str) -> Branch:
        forward = _half(problem, state, params, parameter, opts, +1, coordinates, excursion, mode, min_ds_max, kw)
        if forward.closed or len(forward) == 0:
            return forward
        backward = _half(problem, state, params, parameter, opts, -1, coordinates, excursion, mode, min_ds_max, kw)
        if backward.closed:
            return backward
        return join(backward, forward)

    b = once(options, restep)
    if restep == "whole" and not b.closed and jumped(b) and options.step.ds_max > min_ds_max:
        finer = halved(options)
        again = once(finer, "whole")
        if again.closed or not jumped(again):
            again.message += (f" (retraced with ds_max = {finer.step.ds_max:g} after a jump at "
                              f"ds_max = {options.step.ds_max:g})")
            return again
    return b


def retrace_on_jumps(run: Callable[[ContinuationOptions], Branch], options: ContinuationOptions, *, what: str,
                     jumped: Callable[[Branch], str | None] | None = None, unconverged_bp: bool = True,
                     retraces: int = RETRACES) -> Branch:
    """``run(options)``, repeated with ds_max halved (at most ``retraces`` times) while it jumped.

    A jump is a BP whose location did not converge (if ``unconverged_bp``: a step that landed
    on another branch flips the tangent orientation, the BP test function changes sign and the
    location finds no zero), or whatever ``jumped(branch)`` reports (a reason, or None; e.g. a
    switched branch that comes back onto its parent).  The retrace is recorded in
    ``branch.audit`` ("<what> re-traced with ds_max = ...").
    """
    opts = options
    retraced: list[str] = []
    for attempt in range(retraces + 1):
        branch = run(opts)
        bad = [b for b in branch.branch_points if not b.converged] if unconverged_bp else []
        par = branch.parameter
        reason = f"BP location did not converge at {par} = {', '.join(format(b.params[par], '.6g') for b in bad)}" \
            if bad else (jumped(branch) if jumped is not None else None)
        if reason is None or attempt == retraces:
            break
        retraced.append(f"ds_max = {opts.step.ds_max:.4g} ({reason})")
        opts = halved(opts, steps=1.0)
        log.info("%s re-traced with ds_max = %g: a step jumped between branches", what, opts.step.ds_max)
    if retraced:
        branch.audit = [*branch.audit, f"{what} re-traced with ds_max = {opts.step.ds_max:.4g}: the traces with "
                        + "; ".join(retraced) + " jumped between branches"]
    return branch
