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
#: Words that start the message (the command line shows it as a ``warning:`` line).
STALLED = "ended at its step cap crawling"


def stalled(branch: Any) -> str | None:
    """The message for a branch that ended by ``max_steps`` with its last :data:`WINDOW` steps at
    a median of at most :data:`RATIO` times its largest step, else None."""
    message = str(getattr(branch, "message", "") or "")
    if not message.startswith("maximum number of steps"):
        return None
    ds = np.abs(np.asarray(getattr(branch, "ds", ()), dtype=float))
    ds = ds[np.isfinite(ds) & (ds > 0)]
    if ds.size < 2 * WINDOW:
        return None
    tail, largest = float(np.median(ds[-WINDOW:])), float(np.max(ds))
    if tail > RATIO * largest:
        return None
    name = getattr(branch, "parameter", None)
    moved = ""
    if name is not None and name in getattr(branch, "params", {}):
        p = np.asarray(branch.params[name], dtype=float)[-WINDOW - 1:]
        moved = f"; {name} moved {float(np.max(p) - np.min(p)):.3g} over them, to {float(p[-1]):.10g}"
    return (f"{STALLED}: its last {WINDOW} steps had a median ds of {tail:.3g}, {largest / tail:.3g} times "
            f"below its largest ({largest:.3g}){moved}; what lies beyond was not traced (the audit lines "
            f"say why the steps were cut)")
