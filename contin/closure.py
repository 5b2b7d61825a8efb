"""Recognising a branch that returns to its start (isolas, loops).

After a step to x_k with unit tangent t_k, the start point x_0 lies ahead on the branch within
the next step when, in the theta-norm,

    0 < sigma = <t_k, x_0 - x_k> <= reach,   |x_0 - x_k| <= 1.1 sigma,   <t_k, t_0> > 0,

and the branch has already travelled more than twice |x_0 - x_k| (so the first steps, which
leave x_0 behind, never trigger it).  The tracer then takes one final step of length sigma,
which lands on x_0 itself, checks the segment for special points and stops without storing
x_0 a second time.
"""

from __future__ import annotations

from contin.extended import ExtendedSystem
from contin.problem import Array

#: How close (theta-norm, relative to max(1, |x_0|)) the closing step must land to x_0.
LANDING_TOL = 1e-6


def closing_distance(
    system: ExtendedSystem, x0: Array, t0: Array, x: Array, t: Array, reach: float, travelled: float
) -> float | None:
    """sigma if the start point x0 is within ``reach`` ahead of (x, t), else None."""
    d = x0 - x
    dist = system.norm(d)
    sigma = system.dot(t, d)
    if travelled <= 2.0 * dist or system.dot(t, t0) <= 0.0:
        return None
    if 0.0 < sigma <= reach and dist <= 1.1 * sigma:
        return sigma
    return None


def landed(system: ExtendedSystem, x0: Array, x: Array) -> bool:
    """True if x is the start point x0 (up to the corrector's accuracy)."""
    return system.norm(x - x0) <= LANDING_TOL * max(1.0, system.norm(x0))
