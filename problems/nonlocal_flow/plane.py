"""Plane shear of the Dsouza-Nott non-local model without gravity (docs/nonlocal.md §2).

Wall y = 0 at rest, y = W moving at u_w = 1; lengths in d_p, stresses in alpha.  The balances
d sigma_yy/dy = d sigma_yx/dy = 0 (report Eq. 3.1-3.2) become, with the wall friction
sigma_yx = mu_w P used to fix the constant of the second and P the uniform normal stress,

    p_c = Pi(phi) - ell^2 Pi'(phi) phi'' = P                   (phi boundary layers)
    ell^2 Pi(phi) gamma'' = P (1 - mu_w / mu(I)) gamma         (gamma = du/dy > 0)

with phi = phi_w at both walls, the mean (1/W) int phi dy = phi_bar (P is its Lagrange
multiplier: an extra unknown), slip int_0^W gamma dy = 1 - K (gamma(0) + gamma(W)) and the
mid-plane condition gamma(0) = gamma(W) (equivalent to u''(W/2) = 0: without it the
quasi-static problem has a one-parameter family u = a + b sinh + c cosh, the kinematic
indeterminacy of rigid-plastic flow).  u = K gamma(0) + int_0^y gamma.

mu(I) extension (report §Future work): mu(I) = mu + dmu I / (I0 + I), I = U gamma / sqrt(P)
(U = 0: the quasi-static model).  ``phi_model='phiI'`` replaces the phi equation by the local
phi(I) rheology phi = phi0 - A I (report Fig. 4, phi0 = phi_max) and Pi by the uniform P in
the gamma equation (a local pressure), the comparison branch of the ``nonlocal-muI`` scene.

State x = (phi_0..phi_N, g_0..g_N, P) on the grid s in [-1/2, 1/2] (y = W (s + 1/2)) with
g = W gamma = du/ds, O(1).  Rows: the phi equation (interior nodes) and phi = phi_w (walls);
the g equation divided by P (interior), the slip integral (first row), g_0 - g_N (last row);
the mean constraint.  The Jacobian is analytic and sparse (scipy.sparse.bmat of the blocks).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

from problems.discretization import cell_integration_matrix, make_grid
from problems.nonlocal_flow.closures import CriticalState, check_plane, mu_of_I
from problems.nonlocal_flow.grids import NonlocalGridHooks, profile_tails

Array = np.ndarray

PARAMETERS = ("W", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w", "U", "dmu", "I0", "A_phi")

#: Defaults: W = 40 d_p and the mean phi_bar = 0.585 of the report's Figs. 2-3, the first
#: (K, mu_w) pair (1.65, 0.33), mu = mu_s = 0.3618 of the report's mu(I) fit (so that the
#: mu(I) scene at I -> 0 is this model), ell = 3 d_p (with which the report's printed sign puts
#: the wall at rest at 0.93 u_w, the figure the issue quotes), phi_w = 0.56 (dilated walls).
DEFAULTS = {"W": 40.0, "ell": 3.0, "K": 1.65, "mu_w": 0.33, "mu": 0.3618, "phi_bar": 0.585, "phi_w": 0.56,
            "U": 0.0, "dmu": 0.3367, "I0": 0.1005, "A_phi": 1.0}


#: Relative size below which a negative shear rate counts as discretization noise (admissible).
NOISE = 1e-6

class PlaneShear(NonlocalGridHooks):
    """F(x, p) = 0 for plane shear; see the module docstring."""

    parameter_names = PARAMETERS

    def __init__(self, method: str = "cheb", intervals: int = 48, cs: CriticalState = CriticalState(),
                 phi_model: str = "nonlocal") -> None:
        if phi_model not in ("nonlocal", "phiI"):
            raise ValueError(f"phi_model must be 'nonlocal' or 'phiI', got {phi_model!r}")
        self.grid = make_grid(method, intervals)
        self.cs = cs
        self.phi_model = phi_model
        n = self.grid.size
        self.n = n
        self.size = 2 * n + 1
        self.d2 = self.grid.d2.toarray()
        self.wq = self.grid.weights
        self.cells = cell_integration_matrix(self.grid)
        self.interior = np.ones(n, dtype=bool)
        self.interior[[0, -1]] = False

    # ------------------------------------------------------------------ pieces
    def split(self, x: Array) -> tuple[Array, Array, float]:
        n = self.n
        return x[:n], x[n:2 * n], x[2 * n]

    def y(self, p: Mapping[str, float]) -> Array:
        """Wall-normal coordinate in d_p, 0 at the wall at rest."""
        return p["W"] * (self.grid.y + 0.5)

    def inertial_number(self, x: Array, p: Mapping[str, float]) -> Array:
        _, g, P = self.split(x)
        return p["U"] * g / (p["W"] * np.sqrt(P))

    def velocity(self, x: Array, p: Mapping[str, float]) -> Array:
        """u(y) = K gamma(0) + int_0^y gamma dy (u_w = 1)."""
        _, g, _ = self.split(x)
        g = np.real(g)
        cum = np.concatenate([[0.0], np.cumsum(self.cells @ g)])
        return p["K"] * g[0] / p["W"] + cum

    # ------------------------------------------------------------------ residual
    def residual(self, x: Array, p: Mapping[str, float]) -> Array:
        phi, g, P = self.split(x)
        W = p["W"]
        c = (p["ell"] / W) ** 2
        if self.phi_model == "nonlocal":
            pi, dpi, _ = self.cs.pi(phi)
            rphi = pi - c * dpi * (self.d2 @ phi) - P
            rphi[0] = phi[0] - p["phi_w"]
            rphi[-1] = phi[-1] - p["phi_w"]
            ratio = pi / P
        else:
            I = p["U"] * g / (W * np.sqrt(P))
            rphi = phi - self.cs.phi_max + p["A_phi"] * I
            ratio = np.ones_like(phi)
        I = p["U"] * g / (W * np.sqrt(P))
        mu, _ = mu_of_I(I, p["mu"], p["dmu"], p["I0"])
        rg = c * ratio * (self.d2 @ g) - (1.0 - p["mu_w"] / mu) * g
        rg[0] = self.wq @ g + p["K"] / W * (g[0] + g[-1]) - 1.0
        rg[-1] = g[0] - g[-1]
        rP = self.wq @ phi - p["phi_bar"]
        return np.concatenate([rphi, rg, [rP]])

    def jacobian(self, x: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        phi, g, P = self.split(x)
        n = self.n
        W = p["W"]
        c = (p["ell"] / W) ** 2
        d2 = self.d2
        inner = self.interior
        I = p["U"] * g / (W * np.sqrt(P))
        mu, dmu_dI = mu_of_I(I, p["mu"], p["dmu"], p["I0"])
        gfun = 1.0 - p["mu_w"] / mu
        g_I = p["mu_w"] * dmu_dI / mu**2
        d2g = d2 @ g
        if self.phi_model == "nonlocal":
            pi, dpi, d2pi = self.cs.pi(phi)
            d2phi = d2 @ phi
            a = -c * dpi[:, None] * d2
            a[np.diag_indices(n)] += dpi - c * d2pi * d2phi
            a[~inner] = 0.0
            a[0, 0] = a[-1, -1] = 1.0
            a_g = np.zeros((n, n))
            a_P = np.where(inner, -1.0, 0.0)
            ratio = pi / P
            b_phi = np.diag(np.where(inner, c * dpi / P * d2g, 0.0))
            dratio_dP = -pi / P**2
        else:
            a = np.eye(n)
            a_g = np.diag(p["A_phi"] * p["U"] / (W * np.sqrt(P)) * np.ones(n))
            a_P = -p["A_phi"] * I / (2 * P)
            ratio = np.ones(n)
            b_phi = np.zeros((n, n))
            dratio_dP = np.zeros(n)
        # g rows: c ratio D2 g - gfun(I) g; dI/dg = I/g = U/(W sqrt P), dI/dP = -I/(2P)
        dI_dg = p["U"] / (W * np.sqrt(P))
        b = c * ratio[:, None] * d2
        b[np.diag_indices(n)] -= gfun + g * g_I * dI_dg
        b_P = c * dratio_dP * d2g + g * g_I * I / (2 * P)
        b[0] = self.wq
        b[0, 0] += p["K"] / W
        b[0, -1] += p["K"] / W
        b[-1] = 0.0
        b[-1, 0], b[-1, -1] = 1.0, -1.0
        b_P[[0, -1]] = 0.0
        b_phi[[0, -1]] = 0.0
        jac = sp.bmat([[sp.csr_matrix(a), sp.csr_matrix(a_g), sp.csr_matrix(a_P.reshape(-1, 1))],
                       [sp.csr_matrix(b_phi), sp.csr_matrix(b), sp.csr_matrix(b_P.reshape(-1, 1))],
                       [sp.csr_matrix(self.wq.reshape(1, -1)), None, None]], format="csr")
        return jac

    def dresidual_dp(self, x: Array, p: Mapping[str, float], name: str) -> Array:
        """Complex step (exact to rounding; contin.problem.complex_step_dp)."""
        from contin.problem import complex_step_dp

        return complex_step_dp(self, x, p, name)

    # ------------------------------------------------------------------ hooks
    def with_grid(self, N: int) -> PlaneShear:
        """The same model (method, critical state, phi model) on N intervals (grid hooks:
        :class:`problems.nonlocal_flow.grids.NonlocalGridHooks`)."""
        return PlaneShear(self.grid.method, int(N), self.cs, phi_model=self.phi_model)

    def validate(self, p: Mapping[str, float]) -> None:
        check_plane(p["W"], p["K"], p["ell"], p["mu_w"], p["mu"])
        check_mean(p["phi_bar"], self.cs)
        if self.phi_model == "nonlocal" and not self.cs.phi_min < p["phi_w"] < self.cs.phi_max:
            raise ValueError(f"the wall volume fraction phi_w = {p['phi_w']:g} must lie in (phi_min, phi_max) = "
                             f"({self.cs.phi_min:g}, {self.cs.phi_max:g})")
        if p["U"] < 0 or p["dmu"] < 0 or not p["I0"] > 0:
            raise ValueError("need U >= 0, dmu >= 0 and I0 > 0 for mu(I)")

    def admissible(self, x: Array, p: Mapping[str, float]) -> str | None:
        phi, g, P = self.split(x)
        if not P > 0:
            return f"normal stress P = {P:.3g} <= 0"
        # phi(I) branch: Pi is not used, phi only has to stay a volume fraction below phi0 = phi_max
        lo = self.cs.phi_min if self.phi_model == "nonlocal" else 0.0
        if not (np.all(phi > lo) and np.all(phi < self.cs.phi_max)):
            return f"phi leaves ({lo:g}, phi_max): range [{phi.min():.4g}, {phi.max():.4g}]"
        # The core of a strongly localized flow shears at ~1/cosh(zeta W/2) of the wall rate;
        # values below NOISE of the maximum are at the discretization error and may take
        # either sign (pair 2 at W = 60, ell = 1: 3e-8 exact, -3e-11 on cheb 48).
        if not np.all(g > -NOISE * np.max(np.abs(g))):
            return ("the shear rate changes sign (a rigid zone, outside the flowing branch the model describes, "
                    "or a wall layer of ~exp(-zeta W/2) the grid does not resolve)")
        return None

    def under_resolved(self, x: Array, p: Mapping[str, float], tol: float) -> str | None:
        """contin's resolution hook: on Chebyshev grids the tail of the Chebyshev coefficients of
        gamma relative to its maximum and of phi relative to its variation must stay below tol;
        on every grid the state's two-grid error too (:meth:`NonlocalGridHooks.under_resolved`:
        FD grids were not checked at all, ``--method fd2 --grid 32`` stored states 0.16 off)."""
        if self.grid.method != "cheb":
            return super().under_resolved(x, p, tol)
        phi, g, _ = self.split(x)
        ephi, eg = profile_tails(phi, g)
        worst = max(eg, ephi)
        if worst > tol:
            name = "gamma" if eg >= ephi else "phi"
            zeta_inv = p["ell"] / np.sqrt(max(1 - p["mu_w"] / p["mu"], 1e-300))
            return (f"Chebyshev tail of {name} is {worst:.1e} of its scale (> {tol:.1e}): the wall layers "
                    f"(ell = {p['ell']:.3g}, 1/zeta = {zeta_inv:.3g} d_p in W = {p['W']:.4g} d_p) need a finer "
                    f"--grid than {self.grid.intervals}")
        return super().under_resolved(x, p, tol)

    def order_parameter(self, x: Array, p: Mapping[str, float]) -> float:
        """Slip velocity at the wall at rest, u(0) / u_w."""
        _, g, _ = self.split(x)
        return float(p["K"] * g[0] / p["W"])

    def observables(self, x: Array, p: Mapping[str, float]) -> dict[str, float]:
        phi, g, P = self.split(x)
        W = p["W"]
        dg = self.grid.d1 @ g
        u = self.velocity(x, p)
        ref = self.grid.reflection()
        mid = float(self.grid.interpolate(g, np.array([0.0]))[0])
        I = self.inertial_number(x, p)
        return {
            "P": float(P),
            "ell_over_W": p["ell"] / W,
            "mu_w_over_mu": p["mu_w"] / p["mu"],
            "u_slip": float(u[0]),
            "u_top": float(u[-1]),
            # e-folding length of the shear rate at the wall, gamma / |gamma'| (in d_p)
            "delta": float(W * g[0] / abs(dg[0])) if dg[0] != 0 else float("inf"),
            "zeta_inv": float(p["ell"] / np.sqrt(1.0 - p["mu_w"] / p["mu"])),
            "localization": float(g[0] / mid),
            "phi_wall": float(phi[0]),
            "phi_mid": float(self.grid.interpolate(phi, np.array([0.0]))[0]),
            "I_max": float(np.max(I)),
            # invariants of the reflection y -> W - y: phi even, gamma even (u - 1/2 odd)
            "asym_phi": float(np.max(np.abs(phi - phi[ref]))),
            "asym_u": float(np.max(np.abs(u + u[ref] - 1.0))),
        }

    def profiles(self, x: Array) -> dict[str, Array]:
        phi, g, _ = self.split(x)
        return {"phi": np.asarray(phi), "gamma_W": np.asarray(g)}

    def initial(self, p: Mapping[str, float]) -> Array:
        """phi = phi_bar, P = Pi(phi_bar) (or the phi(I) value), gamma = 1 / W."""
        n = self.n
        if self.phi_model == "nonlocal":
            P0 = float(self.cs.pi(p["phi_bar"])[0])
        else:
            # phi = phi_max - A U g / (W sqrt P) with g = 1: mean phi_bar
            P0 = (p["A_phi"] * p["U"] / (p["W"] * (self.cs.phi_max - p["phi_bar"]))) ** 2
        return np.concatenate([np.full(n, p["phi_bar"]), np.ones(n), [P0]])


def check_mean(phi_bar: float, cs: CriticalState) -> None:
    if not cs.phi_min < phi_bar < cs.phi_max:
        raise ValueError(f"the mean volume fraction phi_bar = {phi_bar:g} must lie strictly between "
                         f"phi_min = {cs.phi_min:g} and phi_max = {cs.phi_max:g} (Pi diverges at phi_max)")
