"""A cloud of special points: one singular point reported several times.

Where a tracer crawls across a singular point with tiny steps (a pitchfork passed along the
branch that bifurcates there, whose vertex is also a fold of that branch; a jump attempt that
halves its step down to ds_min), a test function can change sign back and forth between
neighbouring points: the branch then lists several LPs or BPs at the same parameter and state
(AUTO demo enz: LP, BP, LP within 2e-8 in s0 at its second pitchfork; x (x^2 + (mu - 1)^2 - 1)
= 0: five LPs at mu = 2 for the circle's one fold).  No regular branch has three special points
that close: :func:`special_cloud` says where a branch has, and the tracer records it in the
audit (a ``warning:`` line on the command line, ``contin.cli.trace.doubtful_points``).
"""

from __future__ import annotations

import numpy as np

from contin.branch import Branch

#: Words that start the audit line of a cloud (read by ``contin.cli.trace.doubtful_points``).
CLOUD = "special points in a cloud"


def special_cloud(branch: Branch, *, count: int = 3, rtol: float = 1e-6, state_tol: float = 1e-3) -> str | None:
    """The first cluster of ``count`` or more LPs and BPs of ``branch`` that lie within
    ``rtol max(1, |p|)`` of each other in the continuation parameter and ``state_tol max(1,
    |u|)`` (max norm) in state, as one line; None if there is none."""
    par = branch.parameter
    sps = [s for s in branch.special_points if s.type in ("LP", "BP") and s.state is not None]
    for s in sps:
        p, u = float(s.params[par]), np.asarray(s.state, dtype=float).ravel()
        scale = max(1.0, float(np.max(np.abs(u)))) if u.size else 1.0
        near = [t for t in sps if abs(float(t.params[par]) - p) <= rtol * max(1.0, abs(p))
                and np.asarray(t.state).size == u.size
                and float(np.max(np.abs(np.asarray(t.state, dtype=float).ravel() - u), initial=0.0)) <= state_tol * scale]
        if len(near) >= count:
            kinds = ", ".join(f"{sum(t.type == k for t in near)} {k}" for k in ("LP", "BP") if any(t.type == k for t in near))
            return (f"{CLOUD}: {len(near)} ({kinds}) at {par} = {p:.10g}: one singular point reported several times "
                    f"(a crawl across it; their types and count are doubtful)")
    return None
