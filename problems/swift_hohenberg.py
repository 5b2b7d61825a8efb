"""1-D Swift-Hohenberg equation, the automatic-bifurcation-diagram tutorial of BifurcationKit.

    -(I + Delta)^2 u + lam u + nu u^3 - u^5 = 0

on x_j = -l + 2 l j / N, j = 0..N-1 (N = 200, l = 6), Delta the 3-point Laplacian with u = 0
outside the grid (BifurcationKit's ``spdiagm(0 => -2, 1 => 1, -1 => 1) / h^2``, h = 2l/N),
nu = 2 (BifurcationKit tutorial "1d Swift-Hohenberg equation (Automatic)", after pde2path).

Trivial branch u = 0: J = -(I + Delta)^2 + lam I with eigenvalues lam - (1 - m_k)^2,
m_k = (4/h^2) sin^2(k pi / (2(N + 1))) the eigenvalues of -Delta, so BPs at
lam_k = (1 - m_k)^2 (:meth:`SwiftHohenberg.trivial_branch_points`).  The equation is odd in u:
S u = -u is a symmetry (F(-u) = -F(u)), and every branch off u = 0 comes with its negative.
The Jacobian is exact and sparse (pentadiagonal).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

Array = np.ndarray


class SwiftHohenberg:
    """F(u; lam, nu) = -(I + Delta)^2 u + lam u + nu u^3 - u^5 (module docstring)."""

    parameter_names = ("lam", "nu")

    def __init__(self, N: int = 200, l: float = 6.0) -> None:
        if N < 5:
            raise ValueError(f"Swift-Hohenberg needs N >= 5 grid points, got {N}")
        self.N = N
        self.l = l
        self.x = -l + 2 * l / N * np.arange(N)
        self.h = 2 * l / N
        lap = sp.diags([np.ones(N - 1), -2 * np.ones(N), np.ones(N - 1)], [-1, 0, 1], format="csr") / self.h**2
        op = sp.identity(N, format="csr") + lap
        self.L1 = sp.csr_matrix(-(op @ op))
        self.L1.sort_indices()
        rows = np.repeat(np.arange(N), np.diff(self.L1.indptr))
        self._diag = np.flatnonzero(self.L1.indices == rows)

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        return self.L1 @ u + p["lam"] * u + p["nu"] * u**3 - u**5

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        jac = self.L1.copy()
        jac.data[self._diag] += p["lam"] + 3 * p["nu"] * u**2 - 5 * u**4
        return jac

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        if name == "lam":
            return np.array(u, dtype=float)
        if name == "nu":
            return u**3
        raise ValueError(f"unknown parameter {name!r}")

    def mass_matrix(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        """The identity: every row is an equation u_t = F (the walls are in the stencil, there are
        no algebraic rows).  Declared so that the stability pass does not warn that M = I may
        count boundary rows as unstable (printed on every ``contin trace swift-hohenberg``)."""
        return sp.identity(self.N, format="csr")

    def order_parameter(self, u: Array, p: Mapping[str, float] | None = None) -> float:
        """||u||_2 (BifurcationKit's ``n2 = norm(x)``)."""
        return float(np.linalg.norm(u))

    def observables(self, u: Array, p: Mapping[str, float]) -> dict[str, float]:
        return {"u0": float(u[self.N // 2]), "umax": float(np.max(u)), "umin": float(np.min(u))}

    def symmetry(self, u: Array) -> Array:
        """S u = -u (F is odd in u)."""
        return -np.asarray(u)

    def symmetry_matrix(self) -> sp.csr_matrix:
        return sp.csr_matrix(-sp.identity(self.N))

    def trivial_branch_points(self, lo: float = -np.inf, hi: float = np.inf) -> Array:
        """lam_k = (1 - m_k)^2 inside (lo, hi), sorted: the BPs of u = 0 (module docstring)."""
        k = np.arange(1, self.N + 1)
        m = 4 / self.h**2 * np.sin(k * np.pi / (2 * (self.N + 1))) ** 2
        lam = (1 - m) ** 2
        return np.sort(lam[(lam > lo) & (lam < hi)])

    def validate(self, p: Mapping[str, float]) -> None:
        for name in self.parameter_names:
            if not np.isfinite(p[name]):
                raise ValueError(f"{name} must be finite, got {p[name]}")
