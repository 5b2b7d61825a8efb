"""Step-size control: the Newton-iteration law and the tangent-angle guard.

ds_{k+1} = clip(ds_k * clip(N_target / N_k, shrink, grow), ds_min, ds_max), N_k the number of
corrector iterations of the accepted step (Seydel, *Practical Bifurcation and Stability
Analysis*, 3rd ed. 2010, sec. 4.6).  A step is rejected (and ds halved) if the corrector
fails or the tangent turns by more than ``max_angle``.
"""

from __future__ import annotations

import math

from contin.extended import ExtendedSystem
from contin.options import StepOptions
from contin.problem import Array


def next_step(ds: float, iterations: int, options: StepOptions) -> float:
    factor = min(max(options.newton_target / max(iterations, 1), options.shrink), options.grow)
    return min(max(ds * factor, options.ds_min), options.ds_max)


def reduced_step(ds: float, options: StepOptions) -> float:
    return max(0.5 * ds, options.ds_min)


def angle(system: ExtendedSystem, t1: Array, t2: Array) -> float:
    """Angle between two unit tangents in the theta inner product."""
    return math.acos(min(max(system.dot(t1, t2), -1.0), 1.0))
