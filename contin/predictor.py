"""Predictors of pseudo-arclength continuation: the tangent and the secant.

Tangent (Keller 1977): the unit solution t of [[J, F_p], [c^T]] t = (0, ..., 0, 1) for a
bordering row c with c . t != 0, normalised in the theta-norm.  The factorization is the one
the corrector left behind, so the tangent costs one back-substitution.  Secant: the unit chord
(x_k - x_{k-1}) / |x_k - x_{k-1}|_theta.
"""

from __future__ import annotations

import numpy as np

from contin.extended import ExtendedSystem
from contin.linalg import Factorization
from contin.problem import Array


def tangent(system: ExtendedSystem, fact: Factorization, orient: Array) -> Array:
    """Unit tangent from a factorized bordered matrix, oriented so that <t, orient>_theta > 0."""
    e = np.zeros(fact.size)
    e[-1] = 1.0
    t = system.unit(fact.solve(e))
    return -t if system.dot(t, orient) < 0 else t


def secant(system: ExtendedSystem, x_prev: Array, x: Array) -> Array:
    """Unit chord from x_prev to x."""
    return system.unit(x - x_prev)
