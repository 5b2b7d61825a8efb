"""A branch that ended at its step cap while crawling: incomplete, and said so.

A tracer that keeps halving its step next to a singular point (detectors that disagree, a
tangent that turns, Newton that fails) can spend the rest of ``max_steps`` within a tiny
stretch and end with ``EP maximum number of steps reached``, which reads like a normal end: the
Brusselator's fd2 trace (CI, session 19) crawled 200 steps through b = 5.09 ... 5.16 and stopped
short of its Hopf point at 5.296 with exit 0 and no warning.  :func:`stalled` reads the stored
steps (no audit line is added, so stored files are unchanged) and says when the last
:data:`WINDOW` steps were, by their median, :data:`RATIO` or less of the branch's largest step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: Steps at the end of the branch that are looked at.
WINDOW = 20
#: Median |ds| of the window over the largest |ds| of the branch at or below which it crawled.
RATIO = 1e-3
#: Largest |ds| of a whole branch, relative to its values (at least 1), at or below which it cannot move.
TINY = 1e-12
#: Words that start the message (the command line shows it as a ``warning:`` line).
STALLED = "ended at its step cap crawling"


def stalled(branch: Any) -> str | None:
    """The message for a branch that ended by ``max_steps`` with its last :data:`WINDOW` steps at
    a median of at most :data:`RATIO` times its largest step, else None."""
    message = str(getattr(branch, "message", "") or "")
    if not message.startswith("maximum number of steps"):
        return None
    raw = np.abs(np.asarray(getattr(branch, "ds", ()), dtype=float))
    steps = raw[1:][np.isfinite(raw[1:])]  # (the first point's ds is 0)
    name = getattr(branch, "parameter", None)
    if steps.size and name is not None and name in getattr(branch, "params", {}):
        # steps below the rounding of the values never move the branch: `contin trace bratu --ds-max
        # 1e-300` stored 61 points within lam = 0 .. 6e-299, exit 0 (qa19)
        p = np.asarray(branch.params[name], dtype=float)
        states = np.asarray(getattr(branch, "states", np.zeros((0,))), dtype=float)
        scale = max(1.0, float(np.nanmax(np.abs(p))) if p.size else 0.0,
                    float(np.nanmax(np.abs(states))) if states.size else 0.0)
        largest = float(np.max(steps))
        if largest <= TINY * scale:
            return (f"{STALLED}: its largest step was {largest:.3g}, at the rounding of its values (of size "
                    f"{scale:.3g}): {name} moved {float(np.max(p) - np.min(p)):.3g} in {steps.size} steps; give a larger "
                    f"step (--ds/--ds-max)")
    ds = raw[np.isfinite(raw) & (raw > 0)]
    if ds.size < 2 * WINDOW:
        return None
    tail, largest = float(np.median(ds[-WINDOW:])), float(np.max(ds))
    if tail > RATIO * largest:
        return None
    moved = ""
    if name is not None and name in getattr(branch, "params", {}):
        p = np.asarray(branch.params[name], dtype=float)[-WINDOW - 1:]
        moved = f"; {name} moved {float(np.max(p) - np.min(p)):.3g} over them, to {float(p[-1]):.10g}"
    return (f"{STALLED}: its last {WINDOW} steps had a median ds of {tail:.3g}, {largest / tail:.3g} times "
            f"below its largest ({largest:.3g}){moved}; what lies beyond was not traced (the audit lines "
            f"say why the steps were cut)")
