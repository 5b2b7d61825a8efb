"""A switched branch that runs back along its parent (contin.rejoin), on a closed-form problem.

F = (x (x^2 + (mu - 1)^2 - 1), y - x^2): the trivial branch x = y = 0 has pitchforks at mu = 0
and mu = 2, joined by the bifurcated branch x^2 + (mu - 1)^2 = 1, y = x^2 (a circle in (mu, x)).
Switched at mu = 0, the tracer crawls across mu = 2 (a cloud of LPs at the vertex, points
within 1e-8 of the trivial branch) and closes the circle: no jump, and none may be reported.
A branch that follows the circle to mu = 2 and then the trivial branch must be reported there.
"""

from __future__ import annotations

import dataclasses

import numpy as np

import contin
from contin.branch import relabel
from contin.continuation import switch, trace
from contin.options import ContinuationOptions, StepOptions
from contin.rejoin import REJOINED, on_parent


def circle_F(u, p):
    x, y = u
    return np.array([x * (x * x + (p["mu"] - 1) ** 2 - 1), y - x * x])


P = {"mu": -0.5}


def traced(mu_max):
    pb = contin.from_functions(circle_F, np.zeros(2), P)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"mu": (-0.5, mu_max)}, max_steps=500)
    base = trace(pb, np.zeros(2), P, "mu", opts)
    relabel([base])
    assert [round(b.params["mu"], 6) for b in base.branch_points] == [0.0, 2.0][: 1 + (mu_max > 2)]
    return pb, base, switch(pb, base, base.branch_points[0], opts)


def on_circle(b):
    mu, x = b.parameter_values, b.states[:, 0]
    return np.abs(x ** 2 + (mu - 1) ** 2 - 1) < 1e-8


def rejoined(kid):
    return [m for m in kid.audit if m.startswith(REJOINED)]


def test_a_switched_branch_crossing_its_parent_at_the_second_pitchfork_is_not_flagged():
    """The circle traced through mu = 2 (several points within 1e-7 of x = 0 there, all of them on
    the circle) and back to mu = 0: no REJOINED line; nor on the arcs bounded at mu = 1.9."""
    for mu_max in (3.0, 1.9):
        _, _, kids = traced(mu_max)
        for kid in kids:
            x = kid.states[:, 0]
            assert np.all(on_circle(kid)) and np.ptp(kid.parameter_values) > 1.8
            assert mu_max == 1.9 or np.sum(np.abs(x) < 1e-7) >= 3  # the vertex the detector must spare
            assert not rejoined(kid), rejoined(kid)


def spliced(kid, base):
    """The circle up to its first point at mu = 2, then the trivial branch from there to mu = 3."""
    i = int(np.flatnonzero(kid.parameter_values > 2 - 1e-9)[0])
    j = base.parameter_values > 2 + 1e-9
    cat = lambda a, b: np.concatenate([a[: i + 1], b[j]])  # noqa: E731
    return dataclasses.replace(
        kid, params={"mu": cat(kid.params["mu"], base.params["mu"])}, observables={},
        states=cat(kid.states, base.states), tangents=cat(kid.tangents, base.tangents), ds=cat(kid.ds, base.ds),
        newton_iterations=cat(kid.newton_iterations, base.newton_iterations), special_points=[], audit=[],
        closed=False), i


def test_a_branch_that_turns_onto_its_parent_at_the_second_pitchfork_is_flagged_there():
    """The spliced branch (circle, then x = 0 for mu in (2, 3]) is reported running along its
    parent from its junction with it at mu = 2 on; the circle alone is not."""
    pb, base, kids = traced(3.0)
    for kid in kids:
        jumped, i = spliced(kid, base)
        assert np.all(on_circle(jumped)[: i + 1]) and np.all(jumped.states[i + 1:, 0] == 0)
        msg = on_parent(pb, base, jumped, P)
        assert msg is not None and msg.startswith(REJOINED)
        first = int(msg.split("from point ")[1].split()[0])
        # the junction (x = 1e-5 there, not within tol of x = 0) or the first point after it
        assert i <= first <= i + 1 and -1e-8 < jumped.parameter_values[first] - 2 <= 0.1, (msg, i)
        assert on_parent(pb, base, kid, P) is None


def test_the_command_line_shows_the_rejoined_line_as_a_warning():
    """``contin.cli.trace.doubtful_points`` (the ``warning:`` lines, also with -q) takes the
    REJOINED audit line of the spliced branch, and nothing from the circle's own audit."""
    from contin.cli.trace import doubtful_points

    pb, base, kids = traced(3.0)
    jumped, _ = spliced(kids[0], base)
    jumped.audit = [on_parent(pb, base, jumped, P)]
    assert doubtful_points(jumped) == jumped.audit
    assert not any(m.startswith(REJOINED) for m in doubtful_points(kids[0]))


def test_a_parent_with_points_on_several_grids_is_compared_on_the_matching_grid():
    """An adaptive parent stores states of several sizes (``Branch.sizes``); the spliced branch's
    points are compared with the parent's points of their own size, and still flagged (before,
    a parent with mixed sizes was not compared at all)."""
    from contin.branch import pad_rows

    pb, base, kids = traced(3.0)
    jumped, i = spliced(kids[0], base)
    other = np.flatnonzero(base.parameter_values < 1.0)[:3]  # a stretch on another "grid"
    rows = [np.append(base.state(k), 0.0) if k in other else base.state(k) for k in range(len(base))]
    sizes = np.array([r.size for r in rows])
    mixed = dataclasses.replace(base, states=pad_rows(rows), sizes=sizes,
                                tangents=pad_rows([np.append(base.tangents[k], 0.0) if k in other else base.tangents[k]
                                                   for k in range(len(base))]))
    assert len(set(mixed.state(k).size for k in range(len(mixed)))) == 2
    msg = on_parent(pb, mixed, jumped, P)
    assert msg is not None and i <= int(msg.split("from point ")[1].split()[0]) <= i + 1


def test_a_branch_storing_every_other_state_is_still_checked():
    """With save_every = 2 (``state_index``) the stored points are consecutive among themselves:
    the spliced branch with every other state kept is still flagged at its junction (before, a
    streak needed indices i, i + 1 and never grew)."""
    pb, base, kids = traced(3.0)
    jumped, i = spliced(kids[0], base)
    keep = np.unique(np.append(np.arange(0, len(jumped), 2), len(jumped) - 1))
    sparse = dataclasses.replace(jumped, states=jumped.states[keep], state_index=keep)
    msg = on_parent(pb, base, sparse, P)
    assert msg is not None and i <= int(msg.split("from point ")[1].split()[0]) <= i + 2
