"""A switched branch that runs back along its parent: a jump at a BP it should have passed.

A branch switched at a BP of its parent leaves the parent there; it can meet the parent again
only at another BP, where the two curves cross (transversally: one common point).  If further
on several consecutive points of the switched branch are solutions on the parent's own curve,
a step has landed on the parent and the tracer went on along it: the rest of the stored branch
is the parent's, not the switched one's.  This happens where a bifurcated branch rejoins its
parent at a second pitchfork and the tracer turns onto the parent instead of passing through
(AUTO-07p demo ``enz``: the asymmetric branch meets the symmetric one at s0 = 22.18 and was
stored on along the symmetric branch with exit status EP, no BP and no warning).

:func:`on_parent` recognises it generically: point i of the switched branch lies on the parent
when Newton at fixed parameters (point i's), started from the parent's nearest stored point,
lands within ``tol`` of it; ``run`` such points in a row that reach farther than the BP's
neighbourhood (:data:`LEAVES`) are the sign.  Only points close to the parent's polyline (within its local step length)
are solved for, so the check costs little where the branches are apart.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.adapt import point_problem
from contin.branch import Branch
from contin.newton import newton

#: Words of the audit line of a switched branch found running along its parent (the command
#: line shows such lines as warnings, ``contin.cli.trace.doubtful_points``).
REJOINED = "runs along its parent"

#: How far (relative, max norm) a run of points on the parent must reach to count.  Next to a
#: BP where the branch crosses its parent at an angle theta, its points lie within tol of the
#: parent only inside a ball of radius tol / sin(theta) around the BP; a tracer crawling across
#: the BP with tiny steps leaves many such points (a cloud of LPs at a pitchfork's vertex), which
#: are no jump.  A run reaching farther than 1e-3 is one, unless theta < tol / 1e-3 = 1e-3 rad.
LEAVES = 1e-3


def _span(branch: Branch, idx: list[int]) -> float:
    """Max-norm distance (state and parameter) from the first to the last of the points ``idx``
    (the parameter alone when their states lie on different grids)."""
    a, b = branch.state(idx[0]), branch.state(idx[-1])
    dp = abs(branch.parameter_values[idx[-1]] - branch.parameter_values[idx[0]])
    return float(max(np.max(np.abs(b - a)), dp)) if a.size == b.size else float(dp)


def _groups(branch: Branch) -> dict[int, tuple[list[int], np.ndarray, np.ndarray]]:
    """Per state size (grid of an adaptive run): the stored points' indices, their rows (state,
    parameter) and their reach, twice the larger of the steps to their neighbours (max norm)."""
    by_size: dict[int, list[int]] = {}
    for i in map(int, branch.stored_points):
        by_size.setdefault(branch.state(i).size, []).append(i)
    out = {}
    for m, idx in by_size.items():
        if len(idx) < 2:
            continue
        rows = np.column_stack([np.array([branch.state(i) for i in idx]), branch.parameter_values[idx]])
        step = np.max(np.abs(np.diff(rows, axis=0)), axis=1)
        out[m] = (idx, rows, 2.0 * np.maximum(np.append(step, step[-1]), np.insert(step, 0, step[0])))
    return out


def on_parent(problem: Any, parent: Branch, branch: Branch, params: Mapping[str, float], *, start: int = 1,
              run: int = 3, tol: float = 1e-6) -> str | None:
    """Where ``branch`` (switched at a BP of ``parent``) runs along ``parent``, or None.

    Point i (from ``start`` on) lies on the parent when it is within twice the parent's local
    step length (max norm over state and parameter) of a stored parent point j and Newton on
    ``problem`` at point i's parameters, started from point j's state, converges to within
    ``tol max(1, |u_i|)`` of u_i.  ``run`` consecutive such points reaching farther than
    ``LEAVES max(1, |u|)`` from the first of them make the answer: that first point and its
    parameter.  Points of an adaptive run are compared with the parent's points on the same
    grid (same state size) only.
    """
    groups = _groups(parent)
    par, streak, prev = branch.parameter, [], -1
    for i in map(int, branch.stored_points):
        if i < start:
            continue
        # consecutive among the stored points (save_every > 1 stores every k-th state)
        last, prev = prev, i
        u = branch.state(i)
        hit = False
        if u.size in groups:
            pidx, rows, reach = groups[u.size]
            d = np.max(np.abs(rows - np.append(u, branch.parameter_values[i])), axis=1)
            j = int(np.argmin(d))
            if d[j] <= reach[j]:
                p = {**params, **{k: float(v[i]) for k, v in branch.params.items()}}
                res = newton(point_problem(problem, parent, pidx[j]), parent.state(pidx[j]), p)
                hit = res.converged and float(np.max(np.abs(res.u - u))) <= tol * max(1.0, float(np.max(np.abs(u))))
        streak = [*streak, i] if hit and (not streak or streak[-1] == last) else ([i] if hit else [])
        if len(streak) >= run and _span(branch, streak) > LEAVES * max(1.0, float(np.max(np.abs(u)))):
            return (f"{REJOINED} {parent.id} from point {streak[0]} ({par} = {branch.parameter_values[streak[0]]:.10g}) "
                    f"on: a step landed on the parent branch and the points after it are the parent's, not "
                    f"this branch's (a BP passed without being crossed?)")
    return None
