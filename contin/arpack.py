"""ARPACK's start vector, the same in every call (shift-invert eigenvalues in contin.stability,
contin.hopf and contin.bpdetect).

ARPACK's own start vector comes from a seed that advances with every call in the process, so the
same matrix gave different results from one run to the next, depending on what ran before:
which copies of a multiple eigenvalue were found (the Brusselator's boundary eigenvalue 1, four
times, came back three or four times; ``contin.bpdetect.without_fixed``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: Seed of the start vector.
SEED = 20261204


def start_vector(n: int, dtype: Any = float) -> np.ndarray:
    """ARPACK's start vector for n unknowns: pseudo-random, so that no symmetry of a problem makes
    it orthogonal to an eigenvector, and the same in every call."""
    return np.random.default_rng(SEED).standard_normal(n).astype(dtype)
