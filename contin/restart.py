"""Restarting from a labelled point of a stored run (AUTO's ``IRS``).

AUTO restarts a computation from a label of a stored run (``run(s='1', IRS='LP1', ICP=[...])``);
here a run file written by :func:`contin.io.write` (or ``contin trace -o``) holds the located
special points with their states and tangents, and:

- :func:`find_point` picks a special point by label (``'BP2'``; case-insensitive), on one
  branch or in the whole run (an ambiguous label names the branches that carry it);
- :func:`rebuild_problem` rebuilds the problem of a file through its scene's
  ``problem_factory(parameters, discretization)`` (:mod:`contin.scene`), or says in one
  sentence what is missing;
- :class:`Restart` is what one needs to call the tracer again from that point;
  :func:`contin.io.restart` reads a file and returns it in one call.

This module knows no concrete problem and does not read HDF5 itself (``contin.io`` does).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.problem import Array


@dataclass(frozen=True)
class Restart:
    """A labelled point of a stored run, ready for :func:`contin.continuation.trace`.

    u : the located state; params : every parameter there (the file's parameters updated with
    the point's own); tangent : unit tangent (u, p) in the branch's parameter (None if not
    stored); parameter : the branch's continuation parameter; point, branch : the special
    point and the branch that carries it.

    ``trace_kwargs()`` gives the arguments of ``trace(problem, **r.trace_kwargs(), options=...)``.
    """

    u: Array
    params: dict[str, float]
    tangent: Array | None
    parameter: str
    point: SpecialPoint
    branch: Branch

    def __iter__(self):  # (u, p, tangent) = restart(...)
        return iter((self.u, self.params, self.tangent))

    def trace_kwargs(self) -> dict[str, Any]:
        """``u0``, ``params``, ``parameter`` and ``tangent`` for :func:`contin.continuation.trace`."""
        return {"u0": self.u, "params": dict(self.params), "parameter": self.parameter, "tangent": self.tangent}


def _numeric(values: Mapping[str, Any]) -> dict[str, float]:
    return {k: float(v) for k, v in values.items()
            if isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool)}


def find_point(branches: Sequence[Branch], label: str, branch_id: str | None = None,
               where: str = "the run") -> tuple[Branch, SpecialPoint]:
    """The special point called ``label`` (e.g. 'LP1'), on branch ``branch_id`` or anywhere.

    Raises ValueError (one sentence naming the labels there are) if there is no such point, or
    if the label occurs on several branches and ``branch_id`` is not given.
    """
    if not isinstance(label, str):  # io.restart(f, 5) ended "AttributeError: 'int' object has no attribute 'strip'"
        raise TypeError(f"label must be a special-point label such as 'LP1' or 'BP2', got {label!r} "
                        f"({type(label).__name__})")
    want = label.strip().upper()
    pool = list(branches)
    if branch_id is not None:
        pool = [b for b in branches if b.id == branch_id]
        if not pool:
            raise ValueError(f"no branch {branch_id!r} in {where}; branches: {', '.join(b.id for b in branches) or 'none'}")
    hits = [(b, sp) for b in pool for sp in b.special_points if sp.name.upper() == want]
    if not hits:
        names = sorted({sp.name for b in pool for sp in b.special_points})
        on = f"branch {branch_id!r} of {where}" if branch_id is not None else where
        raise ValueError(f"no point {label!r} on {on}; its labels are {', '.join(names) or 'none'}")
    if len(hits) > 1:
        raise ValueError(f"label {label!r} occurs on branches {', '.join(b.id for b, _ in hits)} of {where}; "
                         "choose one with --branch (or call contin.branch.relabel on the run)")
    return hits[0]


def restart_from(branches: Sequence[Branch], meta: Mapping[str, Any], label: str,
                 branch_id: str | None = None) -> Restart:
    """:class:`Restart` at ``label`` of a loaded run (``contin.io.load`` output)."""
    where = repr(meta.get("path", "the run"))
    branch, sp = find_point(branches, label, branch_id, where)
    if sp.state is None or np.asarray(sp.state).size == 0 or not np.all(np.isfinite(sp.state)):
        raise ValueError(f"special point {sp.name} of branch {branch.id} in {where} has no stored state")
    params = {**_numeric(dict(meta.get("parameters", {}))), **_numeric(dict(sp.params))}
    tangent = None if sp.tangent is None or not np.all(np.isfinite(sp.tangent)) else np.asarray(sp.tangent, float)
    return Restart(np.asarray(sp.state, float), params, tangent, branch.parameter, sp, branch)


def rebuild_problem(meta: Mapping[str, Any]) -> Any:
    """The problem of a stored run, from its scene's ``problem_factory``.

    Raises ValueError saying what is missing: a file without a scene name (written by
    ``contin.io.write`` without ``scene=``), an unknown scene, a scene without a factory, or the
    factory's own ValueError (e.g. a file whose branches come from several problems), prefixed
    with the file.
    """
    from contin.scene import get_scene

    where = repr(meta.get("path", "the file"))
    name = str(meta.get("scene") or "")
    if not name:
        raise ValueError(f"{where} names no scene, so its problem cannot be rebuilt; in Python pass the problem "
                         "yourself (contin.io.restart gives the state), or write the file with "
                         "scene=<a registered scene with a problem_factory>")
    try:
        scene = get_scene(name)
    except ValueError as exc:
        raise ValueError(f"cannot rebuild the problem of {where}: {exc}") from None
    if scene.problem_factory is None:
        raise ValueError(f"cannot rebuild the problem of {where}: scene {name!r} has no problem_factory")
    try:
        return scene.problem_factory(dict(meta.get("parameters", {})), dict(meta.get("discretization", {})))
    except ValueError as exc:  # the factory's one sentence (bad parameters, a file of several problems)
        raise ValueError(f"cannot rebuild the problem of {where}: {exc}") from None
    except KeyError as exc:  # 'Error: num': a file whose scene attribute names another scene
        raise ValueError(f"cannot rebuild the problem of {where}: its parameters have no {exc.args[0]!r}, which "
                         f"scene {name!r} needs (is it a file of another scene?)") from None
