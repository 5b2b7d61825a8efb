"""Cylindrical Couette flow of the Dsouza-Nott non-local model (report §3.3, docs/nonlocal.md §3).

Inner cylinder r = r_i moving at u_w = 1, outer r = r_o = r_i + W fixed; lengths in d_p,
stresses in alpha.  The radius ratio ``ratio`` = r_o / r_i sets r_i = W / (ratio - 1).

Balances (report Eqs. 3.2-3.5): d sigma_rr/dr = 0 and d(r^2 sigma_r theta)/dr = 0, i.e.

    Pi(phi) - ell^2 Pi'(phi) (phi'' + phi'/r) = P                           (3.3)
    ell^2 Pi(phi) L[u] = P (1 - (mu_w/mu) (r_i/r)^2) gamma,  gamma = u' - u/r < 0   (3.4, 3.5)

where the second is r^2 sigma_r theta = const integrated once with the inner-wall friction
|sigma_r theta / sigma_rr| = mu_w (sigma_r theta has the sign of gamma), and
L[u] = 2 (lap D')_r theta = u''' + a u'/r^2 + b u/r^3.  The tensor Laplacian of D' gives
(a, b) = (-3, 3) (``operator='derived'``, default): then L[u] = gamma'' + gamma'/r - 4 gamma/r^2,
which vanishes for the harmonic field u = 1/r as it must.  The report prints (a, b) = (1, -1)
(``operator='report'``), which does not (L[1/r] = -8/r^4).  Boundary conditions (report §3.3.2):
slip u - 1 = K (u' + s u/r) at r_i with s = -1 (slip proportional to the wall shear rate, zero
for rigid rotation; the report prints s = +1, taken with ``operator='report'``); u = 0 and u' = 0
at r_o; phi = phi_w at both walls; the area mean
int phi r dr / int r dr = phi_bar with P its multiplier.

State (phi_0..phi_N, u_0..u_N, P) on s in [-1/2, 1/2], r = r_i + W (s + 1/2).  The third-order
u equation is collocated at nodes 1..N-2; node N-1 carries u'(r_o) = 0 (row replacement).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

from problems.discretization import make_grid

from .closures import CriticalState, check_plane
from .grids import NonlocalGridHooks

Array = np.ndarray

PARAMETERS = ("W", "ratio", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w")

#: Defaults: the report's fitted wall parameters mu_w/mu = 0.99 and K = 0.63 (its Fig. 5), with
#: mu = 0.3618 as in plane shear; gap W = 20 d_p, radius ratio 2, ell = 3 d_p, phi as in plane shear.
DEFAULTS = {"W": 20.0, "ratio": 2.0, "ell": 3.0, "K": 0.63, "mu_w": 0.99 * 0.3618, "mu": 0.3618,
            "phi_bar": 0.585, "phi_w": 0.56}

OPERATORS = {"derived": (-3.0, 3.0, -1.0), "report": (1.0, -1.0, 1.0)}


class CylindricalCouette(NonlocalGridHooks):
    """F(x, p) = 0 for cylindrical Couette flow; see the module docstring."""

    parameter_names = PARAMETERS

    def __init__(self, method: str = "cheb", intervals: int = 48, cs: CriticalState = CriticalState(),
                 operator: str = "derived") -> None:
        if operator not in OPERATORS:
            raise ValueError(f"operator must be one of {', '.join(OPERATORS)}, got {operator!r}")
        self.a, self.b, self.s_slip = OPERATORS[operator]
        self.operator = operator
        self.grid = make_grid(method, intervals)
        self.cs = cs
        n = self.grid.size
        self.n = n
        self.size = 2 * n + 1
        self.d1 = self.grid.d1.toarray()
        self.d2 = self.grid.d2.toarray()
        self.d3 = self.d1 @ self.d2
        self.wq = self.grid.weights
        self.inner = np.ones(n, dtype=bool)
        self.inner[[0, -1]] = False
        self.u_rows = np.zeros(n, dtype=bool)
        self.u_rows[1:n - 2] = True

    def split(self, x: Array) -> tuple[Array, Array, float]:
        n = self.n
        return x[:n], x[n:2 * n], x[2 * n]

    def radii(self, p: Mapping[str, float]) -> tuple[float, Array]:
        ri = p["W"] / (p["ratio"] - 1.0)
        return ri, ri + p["W"] * (self.grid.y + 0.5)

    def residual(self, x: Array, p: Mapping[str, float]) -> Array:
        phi, u, P = self.split(x)
        W, ell, K = p["W"], p["ell"], p["K"]
        ri, r = self.radii(p)
        pi, dpi, _ = self.cs.pi(phi)
        lap = (self.d2 @ phi) / W**2 + (self.d1 @ phi) / (W * r)
        rphi = pi - ell**2 * dpi * lap - P
        rphi[0] = phi[0] - p["phi_w"]
        rphi[-1] = phi[-1] - p["phi_w"]
        du = (self.d1 @ u) / W
        gam = du - u / r
        L = (self.d3 @ u) / W**3 + self.a * du / r**2 + self.b * u / r**3
        # times W: O(1) rows in the grid variable s, (ell/W)^2 (Pi/P) u_sss + ... - coef du/ds + ...
        ru = ell**2 * (pi / P) * L * W - (1.0 - p["mu_w"] / p["mu"] * (ri / r) ** 2) * gam * W
        ru = np.where(self.u_rows, ru, 0.0 * ru)
        ru[0] = u[0] - 1.0 - K * (du[0] + self.s_slip * u[0] / r[0])
        ru[-2] = du[-1] * W
        ru[-1] = u[-1]
        rP = (self.wq @ (phi * r)) / (self.wq @ r) - p["phi_bar"]
        return np.concatenate([rphi, ru, [rP]])

    def jacobian(self, x: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        phi, u, P = self.split(x)
        n = self.n
        W, ell, K = p["W"], p["ell"], p["K"]
        ri, r = self.radii(p)
        pi, dpi, d2pi = self.cs.pi(phi)
        lapm = self.d2 / W**2 + self.d1 / (W * r[:, None])
        lap = lapm @ phi
        a = -ell**2 * dpi[:, None] * lapm
        a[np.diag_indices(n)] += dpi - ell**2 * d2pi * lap
        a[[0, -1]] = 0.0
        a[0, 0] = a[-1, -1] = 1.0
        a_P = np.where(self.inner, -1.0, 0.0)
        d1u = self.d1 / W
        gm = d1u - np.diag(1.0 / r)
        Lm = self.d3 / W**3 + self.a * d1u / r[:, None] ** 2 + np.diag(self.b / r**3)
        L = Lm @ u
        coef = (1.0 - p["mu_w"] / p["mu"] * (ri / r) ** 2)
        b = ell**2 * (pi / P)[:, None] * Lm * W - coef[:, None] * gm * W
        b_phi = np.diag(ell**2 * dpi / P * L * W)
        b_P = -ell**2 * pi / P**2 * L * W
        off = ~self.u_rows
        b[off] = 0.0
        b_phi[off] = 0.0
        b_P[off] = 0.0
        b[0] = -K * (d1u[0])
        b[0, 0] += 1.0 - K * self.s_slip / r[0]
        b[-2] = d1u[-1] * W
        b[-1, -1] = 1.0
        mean = (self.wq * r) / (self.wq @ r)
        return sp.bmat([[sp.csr_matrix(a), None, sp.csr_matrix(a_P.reshape(-1, 1))],
                        [sp.csr_matrix(b_phi), sp.csr_matrix(b), sp.csr_matrix(b_P.reshape(-1, 1))],
                        [sp.csr_matrix(mean.reshape(1, -1)), None, None]], format="csr")

    def dresidual_dp(self, x: Array, p: Mapping[str, float], name: str) -> Array:
        from contin.problem import complex_step_dp

        return complex_step_dp(self, x, p, name)

    def with_grid(self, N: int) -> CylindricalCouette:
        """The same model (method, critical state, operator) on N intervals (grid hooks:
        :class:`problems.nonlocal_flow.grids.NonlocalGridHooks`)."""
        return CylindricalCouette(self.grid.method, int(N), self.cs, operator=self.operator)

    def validate(self, p: Mapping[str, float]) -> None:
        check_plane(p["W"], p["K"], p["ell"], p["mu_w"], p["mu"])
        if not p["ratio"] > 1.0:
            raise ValueError(f"the radius ratio r_o/r_i must be > 1, got ratio = {p['ratio']:g}")
        for name in ("phi_bar", "phi_w"):
            if not self.cs.phi_min < p[name] < self.cs.phi_max:
                raise ValueError(f"{name} = {p[name]:g} must lie strictly between phi_min = {self.cs.phi_min:g} "
                                 f"and phi_max = {self.cs.phi_max:g} (Pi diverges at phi_max)")

    def admissible(self, x: Array, p: Mapping[str, float]) -> str | None:
        phi, u, P = self.split(x)
        if not P > 0:
            return f"normal stress P = {P:.3g} <= 0"
        if not self.cs.inside(phi):
            return f"phi leaves (phi_min, phi_max): range [{phi.min():.4g}, {phi.max():.4g}]"
        return None

    def shear_rate(self, x: Array, p: Mapping[str, float]) -> Array:
        _, u, _ = self.split(x)
        _, r = self.radii(p)
        return (self.d1 @ u) / p["W"] - u / r

    def order_parameter(self, x: Array, p: Mapping[str, float]) -> float:
        """Slip at the moving inner wall, 1 - u(r_i)."""
        return float(1.0 - x[self.n])

    def observables(self, x: Array, p: Mapping[str, float]) -> dict[str, float]:
        phi, u, P = self.split(x)
        ri, r = self.radii(p)
        gam = self.shear_rate(x, p)
        mid = float(self.grid.interpolate(u, np.array([0.0]))[0])
        return {"P": float(P), "r_i": ri, "u_inner": float(u[0]), "u_mid": mid,
                "gamma_inner": float(gam[0]), "phi_inner": float(phi[0]),
                "phi_mid": float(self.grid.interpolate(phi, np.array([0.0]))[0]),
                "phi_max_profile": float(np.max(phi)),
                "gamma_sign_changes": float(np.count_nonzero(np.diff(np.sign(gam[1:-1][np.abs(gam[1:-1]) > 1e-10]))))}

    def initial(self, p: Mapping[str, float]) -> Array:
        """phi = phi_bar, P = Pi(phi_bar), u linear from 1 to 0 (quadratic near r_o)."""
        n = self.n
        s = self.grid.y + 0.5
        return np.concatenate([np.full(n, p["phi_bar"]), (1 - s) ** 2, [float(self.cs.pi(p["phi_bar"])[0])]])
