"""Test problems for branch points of every kernel dimension and for codim-2 curves.

- :class:`Diagonal`: BifurcationKit's branch-point detection test (``test/test_bif_detection.jl``):
  F(x, lam) = -x + lam L x - x^3 with L diagonal, entries 1/i repeated i times for i = 1..5, then
  1/6, 1/6.5, 1/6.75, 1/6.875.  On x = 0 the Jacobian is diag(-1 + lam L_ii), singular at
  lam = 1/L_ii: branch points at lam = 1, 2, 3, 4, 5, 6, 6.5, 6.75, 6.875 with kernel dimensions
  1, 2, 3, 4, 5, 1, 1, 1, 1 (n = 19).
- BifurcationKit's 1-D Swift-Hohenberg tutorial lives in :mod:`problems.swift_hohenberg`
  (:class:`~problems.swift_hohenberg.SwiftHohenberg`, with the closed-form BPs of u = 0).
- :class:`Cusp`: AUTO-07p's ``cusp`` demo normal form x' = mu + lam x - x^3 (scalar).  Folds lie on
  mu = -2 (lam/3)^{3/2} ... i.e. 27 mu^2 = 4 lam^3, which has its cusp at (lam, mu) = (0, 0).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

Array = np.ndarray

#: Branch points of :class:`Diagonal` on x = 0 and their kernel dimensions.
DIAGONAL_BPS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 6.5, 6.75, 6.875)
DIAGONAL_DIMS = (1, 2, 3, 4, 5, 1, 1, 1, 1)


class Diagonal:
    """F(x, lam) = -x + lam L x - x^3 (BifurcationKit test_bif_detection.jl)."""

    parameter_names: tuple[str, ...] = ("lam",)

    def __init__(self) -> None:
        diag = [1.0 / i for i in range(1, 6) for _ in range(i)] + [1 / 6.0, 1 / 6.5, 1 / 6.75, 1 / 6.875]
        self.L = np.array(diag)
        self.n = self.L.size

    def residual(self, x: Array, p: Mapping[str, float]) -> Array:
        return -x + p["lam"] * self.L * x - x**3

    def jacobian(self, x: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        return sp.diags(-1.0 + p["lam"] * self.L - 3 * x**2, format="csr")

    def dresidual_dp(self, x: Array, p: Mapping[str, float], name: str) -> Array:
        return self.L * x

    def order_parameter(self, x: Array, p: Mapping[str, float]) -> float:
        return float(np.linalg.norm(x))


class Cusp:
    """mu + lam x - x^3 = 0 (AUTO-07p demo ``cusp``'s normal form); cusp of the fold curve at (0, 0)."""

    parameter_names: tuple[str, ...] = ("lam", "mu")

    def residual(self, x: Array, p: Mapping[str, float]) -> Array:
        return np.array([p["mu"] + p["lam"] * x[0] - x[0] ** 3])

    def jacobian(self, x: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        return sp.csr_matrix([[p["lam"] - 3 * x[0] ** 2]])

    def dresidual_dp(self, x: Array, p: Mapping[str, float], name: str) -> Array:
        return np.array([x[0] if name == "lam" else 1.0])

    def order_parameter(self, x: Array, p: Mapping[str, float]) -> float:
        return float(x[0])
