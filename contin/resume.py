"""Resuming interrupted runs branch by branch.

A scene re-run with ``--resume`` gets the branches an interrupted run finished
(``SceneRequest.completed``, by id).  The README promises that a kill loses at most the branch
in progress, so a scene must reuse every finished branch individually: reusing the two halves
of a switched branch only as a pair retraced a finished half whenever the kill fell between
them (issue 16).  :func:`switch_reusing` is :func:`contin.continuation.switch` with that rule.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from contin.branch import Branch, SpecialPoint


def switch_reusing(completed: Mapping[str, Branch], problem: Any, branch: Branch, point: SpecialPoint,
                   options: Any, *, directions: tuple[int, ...] = (+1, -1), branch_id_prefix: str | None = None,
                   **kwargs: Any) -> list[Branch]:
    """The branches of ``switch(problem, branch, point, options, directions=...)``, reusing those in ``completed``.

    Ids are those of ``switch``: f"{prefix}.{k}" for the k-th direction (prefix default
    f"{branch.id}.{point.name}").  With nothing completed this is exactly one ``switch`` call;
    otherwise each missing direction is switched on its own and given its id.  A direction whose
    start fails is left out, as ``switch`` does.
    """
    from contin.continuation import switch

    prefix = branch_id_prefix if branch_id_prefix is not None else f"{branch.id}.{point.name}"
    ids = [f"{prefix}.{k}" for k in range(1, len(directions) + 1)]
    if not any(i in completed for i in ids):
        return switch(problem, branch, point, options, directions=directions, branch_id_prefix=prefix, **kwargs)
    out = []
    for bid, d in zip(ids, directions):
        if bid in completed:
            out.append(completed[bid])
            continue
        for new in switch(problem, branch, point, options, directions=(d,), branch_id_prefix=prefix, **kwargs):
            new.id = bid
            out.append(new)
    return out
