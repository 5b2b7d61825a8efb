"""Steady granular plane Couette flow of disks (d = 2) as a continuation problem (docs/disks.md).

The steady, fully developed equations are those of the 3-D problem (problems.couette.model,
physics.md section 3) with a general closure (problems.disks.closures.DiskClosure) in place of
f1..f5 T^k: with p(nu, T), mu(nu, T), k(nu, T), D(nu, T),

    (mu u')' = 0                                    x-momentum
    (1/H^2) (k T')' + mu u'^2 - D = 0               energy (the d/2 of the time derivative drops out)
    p(nu, T) - P + H^3 G M = 0                      y-momentum, integrated (gravity G = Fr^-2)
    integral of nu dy = nu_bar,   M' = nu           mass constraint, centred cumulative mass

on y in [-1/2, 1/2], walls moving with u = -+1/2, Alam scaling (T by (gamma_dot d)^2).
Unknowns x = [nu (N+1), u (N+1), T (N+1), P (1)] (+ [M (N+1)] with ``gravity=True``; the rows of
M are those of problems.couette.model, reused).

Walls (sigma = -1 bottom, +1 top, u_w = sigma/2, slip = u - u_w):

- ``noslip``: u = u_w and zero heat flux, sigma T' = 0.
- ``bumpy`` (seed 000, "Boundary Conditions": -n.P.t = (pi/4) phi Omega |u_sl|,
  n.q = -u_sl.P.n - Gamma): the Johnson-Jackson structure of problems.couette with the
  2-D Maxwellian wall fluxes of a disk gas at contact density G = nu g,
      -sigma S = H s_w slip,  sigma k T'/H^2 - H s_w slip^2 + d_w/H = 0,
      s_w = phi_w G sqrt(T) / sqrt(2 pi),  d_w = (1 - ew^2) G T^{3/2} / sqrt(2 pi)
  (tangential momentum phi_w rho_p nu g sqrt(T/2pi) u_sl and energy loss
  (1 - ew^2) rho_p nu g T^{3/2}/sqrt(2pi) per unit wall length; phi_w plays the bumpiness).

Symmetry: (nu, T)(y) -> (nu, T)(-y), u(y) -> -u(-y), P -> P, M(y) -> -M(-y) for G = 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.problem import complex_step_dp
from problems.couette.model import _mass_rows, reflected
from problems.discretization import cell_integration_matrix, make_grid
from problems.disks.closures import DiskClosure, check_closure_parameters, uniform_temperature
from problems.gridhooks import ResolutionHooks

WALLS = ("noslip", "bumpy")
PARAMETER_NAMES = ("nu", "e", "H", "G", "phi_w", "ew", "phi_inf", "phi_f", "m_f", "phi_c", "a0")
DEFAULTS: dict[str, float] = {
    "nu": 0.5, "e": 0.8, "H": 20.0, "G": 0.0, "phi_w": 0.5, "ew": 0.9,
    "phi_inf": 0.9, "phi_f": 0.7, "m_f": 0.01, "phi_c": 0.8, "a0": 0.0,
}
_SQRT_2PI = np.sqrt(2.0 * np.pi)


class DiskCouetteProblem(ResolutionHooks):
    """Steady Couette flow of disks, F(x, p) = 0 (module docstring).

    Parameters
    ----------
    method, N : discretization (problems.discretization: 'cheb', 'fd2', 'fd4', 'fd6'; N intervals)
    walls : 'noslip' or 'bumpy'
    closure : DiskClosure (pair correlation, normalization, Savage contact part)
    gravity : carry the cumulative mass M (needed for G != 0)
    """

    parameter_names = PARAMETER_NAMES
    symmetry_breaking_parameters = ("G",)
    #: rounding = rounding_factor eps N^2 phi_inf / (phi_inf - max nu) in the resolution estimate
    #: (problems.couette.resolution): measured against longdouble-residual solutions of the G_CS
    #: n = 1 band near phi_inf (gap 1e-7, 1.3e-8; cheb 48, 80, 128) the error of nu relative to the
    #: distance to phi_inf is 1.3 .. 3.1 times eps N^2 phi_inf / gap (gPCF: 0.014 .. 0.15, factor 0.2)
    rounding_factor = 4.0
    #: no default eigenvalue-count BP detector: J of the steady residual has algebraic rows
    #: whose eigenvalues cross zero in pairs, and the count re-stepped and bisected on them
    #: (steady band, cheb 32, H = 1 .. 40: 7.9 s -> 18.3 s; contin.problem, bp_eigen_auto)
    bp_eigen_auto = False

    def __init__(self, method: str = "cheb", N: int = 48, *, walls: str = "noslip",
                 closure: DiskClosure | None = None, gravity: bool = False) -> None:
        if walls not in WALLS:
            raise ValueError(f"unknown wall model walls = {walls!r}; choose one of {', '.join(WALLS)}")
        self.closure = closure or DiskClosure()
        self.grid = make_grid(method, int(N))
        self.method, self.N, self.walls, self.gravity = method, int(N), walls, bool(gravity)
        n = self.n = self.grid.size
        self.size = 3 * n + 1 + (n if self.gravity else 0)
        self.i_nu, self.i_u, self.i_T, self.i_P = slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n), 3 * n
        self.i_M = slice(3 * n + 1, 4 * n + 1) if self.gravity else None
        self._d1 = sp.csr_matrix(self.grid.d1)
        self._d2 = sp.csr_matrix(self.grid.d2)
        self._sigma = np.array([-1.0, 1.0])
        self._w = np.array([0, n - 1])
        self._interior = sp.diags(np.r_[0.0, np.ones(n - 2), 0.0])
        if self.gravity:
            self._mass_M, self._mass_nu = _mass_rows(cell_integration_matrix(self.grid))

    def __repr__(self) -> str:
        return (f"DiskCouetteProblem(method={self.method!r}, N={self.N}, walls={self.walls!r}, "
                f"closure={self.closure!r}, gravity={self.gravity})")

    @property
    def options(self) -> dict[str, Any]:
        c = self.closure
        return {"method": self.method, "N": self.N, "walls": self.walls, "G": c.G, "contact": c.contact,
                "normalization": c.normalization, "gravity": self.gravity}

    # ------------------------------------------------------------------ parameters
    def params(self, values: Mapping[str, Any] | None = None) -> dict[str, float]:
        """DEFAULTS merged with ``values``, validated."""
        p = {**DEFAULTS, **{k: float(v) for k, v in dict(values or {}).items()}}
        unknown = set(p) - set(PARAMETER_NAMES)
        if unknown:
            raise ValueError(f"unknown parameter(s) {', '.join(sorted(unknown))}; the parameters are {', '.join(PARAMETER_NAMES)}")
        self.validate(p)
        return p

    def validate(self, p: Mapping[str, Any]) -> None:
        """One-sentence ValueError for invalid parameters (closure limits, gap, gravity, walls)."""
        check_closure_parameters(p, self.closure)
        if not float(np.real(p["H"])) > 0:
            raise ValueError(f"gap H = {p['H']} must be > 0")
        if not self.gravity and p["G"] != 0:
            raise ValueError(f"gravity G = {p['G']} needs a problem built with gravity=True")
        if self.walls == "bumpy":
            if not 0.0 <= float(np.real(p["phi_w"])) <= 1.0:
                raise ValueError(f"wall bumpiness phi_w = {p['phi_w']} must lie in [0, 1]")
            if not 0.0 < float(np.real(p["ew"])) <= 1.0:
                raise ValueError(f"wall restitution ew = {p['ew']} is outside (0, 1]")

    # ------------------------------------------------------------------ state
    def unpack(self, x):
        m = x[self.i_M] if self.gravity else None
        return x[self.i_nu], x[self.i_u], x[self.i_T], x[self.i_P], m

    def pack(self, nu, u, T, P, M=None):
        parts = [np.asarray(nu), np.asarray(u), np.asarray(T), np.atleast_1d(P)]
        if self.gravity:
            parts.append(self.cumulative_mass(nu) if M is None else np.asarray(M))
        return np.concatenate(parts)

    def cumulative_mass(self, nu):
        cells = cell_integration_matrix(self.grid)
        cum = np.concatenate([[0.0], np.cumsum(cells @ nu)])
        return cum - 0.5 * cum[-1]

    def uniform_state(self, p: Mapping[str, Any]) -> np.ndarray:
        """Uniform shear nu = nu_bar, u = y, T = T0, P = p(nu_bar, T0) (exact for no-slip walls, G = 0)."""
        self.validate(p)
        nu = np.full(self.n, float(p["nu"]))
        t0 = float(uniform_temperature(np.float64(p["nu"]), p, self.closure))
        P = float(self.closure.transport(nu[:1], np.array([t0]), p).p[0])
        return self.pack(nu, self.grid.y.copy(), np.full(self.n, t0), P)

    def initial_guess(self, p: Mapping[str, Any]) -> np.ndarray:
        """Uniform shear (no-slip) or, for bumpy walls, a uniform state with the slip-reduced shear
        rate gamma and temperature from the integrated energy and wall balances."""
        x = self.uniform_state(p)
        if self.walls == "noslip":
            return x
        nu0, H = float(p["nu"]), float(p["H"])
        f = self.closure.kinetic(np.array([nu0]), p)
        G0 = float(f.G[0])
        t0 = float(f.f2[0] / f.f5[0])
        gamma = 1.0
        with np.errstate(all="ignore"):  # extreme parameters give a non-finite guess: Newton says so
            for _ in range(50):  # fixed point: S = f2 sqrt(T) gamma = H s_w slip, slip = (1 - gamma)/2
                sw = p["phi_w"] * G0 * np.sqrt(t0) / _SQRT_2PI
                gamma = H * sw / (float(f.f2[0]) * np.sqrt(t0) + H * sw)
                cs, cd = p["phi_w"] * G0 / _SQRT_2PI, (1 - p["ew"] ** 2) * G0 / _SQRT_2PI
                slip = 0.5 * (1.0 - gamma)
                t0 = (float(f.f2[0]) * gamma**2 + 2.0 * H * cs * slip**2) / (float(f.f5[0]) + 2.0 * cd / H)
        tr = self.closure.transport(np.array([nu0]), np.array([t0]), p)
        return self.pack(np.full(self.n, nu0), gamma * self.grid.y, np.full(self.n, t0), float(tr.p[0]))

    # ------------------------------------------------------------------ residual
    def _fields(self, x, p):
        nu, u, T, P, M = self.unpack(x)
        tr = self.closure.transport(nu, T, p)
        d1, d2 = self._d1, self._d2
        # Differentiate after removing what D1, D2 map to 0 or 1 exactly (constants, u = y): the same
        # operators in exact arithmetic, but Chebyshev D2 has entries ~N^4 whose rounding would leave
        # ~1e-12 in the residual of uniform shear.
        du, dT = u - self.grid.y, T - T[0]
        up = d1 @ du + 1.0
        return (nu, u, T, P, M, tr, up, d2 @ du, d1 @ dT, d2 @ dT, d1 @ (tr.mu - tr.mu[0]),
                d1 @ (tr.k - tr.k[0]))

    def _wall_terms(self, nu, T, p):
        """(s_w, d_w, s_w_nu, s_w_T, d_w_nu, d_w_T) at both walls (bumpy walls)."""
        f = self.closure.kinetic(nu, p)
        sT = np.sqrt(T)
        cs, cd = p["phi_w"] / _SQRT_2PI, (1.0 - p["ew"] ** 2) / _SQRT_2PI
        sw, dw = cs * f.G * sT, cd * f.G * T * sT
        return sw, dw, cs * f.G_nu * sT, sw / (2.0 * T), cd * f.G_nu * T * sT, 1.5 * cd * f.G * sT

    def residual(self, x, p):
        nu, u, T, P, M, tr, up, upp, Tp, Tpp, mup, kp = self._fields(x, p)
        H = p["H"]
        dtype = np.result_type(x, *(np.asarray(p[k]) for k in PARAMETER_NAMES if k in p))
        F = np.empty(self.size, dtype=dtype)
        ry = tr.p - P
        if self.gravity:
            ry = ry + H**3 * p["G"] * M
        F[self.i_nu] = ry
        ru = tr.mu * upp + mup * up
        rT = (tr.k * Tpp + kp * Tp) / H**2 + tr.mu * up**2 - tr.D
        w, sig = self._w, self._sigma
        if self.walls == "noslip":
            ru[w] = u[w] - 0.5 * sig
            rT[w] = sig * Tp[w]
        else:
            sw, dw = self._wall_terms(nu[w], T[w], p)[:2]
            slip = u[w] - 0.5 * sig
            ru[w] = -sig * tr.mu[w] * up[w] - H * sw * slip
            rT[w] = sig * tr.k[w] * Tp[w] / H**2 - H * sw * slip**2 + dw / H
        F[self.i_u] = ru
        F[self.i_T] = rT
        F[self.i_P] = self.grid.weights @ nu - p["nu"]
        if self.gravity:
            F[self.i_M] = self._mass_M @ M - self._mass_nu @ nu
        return F

    def dresidual_dp(self, x, p, name):
        return complex_step_dp(self, np.asarray(x, dtype=float), p, name)

    # ------------------------------------------------------------------ Jacobian
    def jacobian(self, x, p) -> sp.csr_matrix:
        """Exact dF/dx, assembled from diagonal and differentiation matrices (docs/disks.md)."""
        x = np.asarray(x, dtype=float)
        nu, u, T, P, M, tr, up, upp, Tp, Tpp, mup, kp = self._fields(x, p)
        H, n = p["H"], self.n
        h2 = 1.0 / H**2
        D1, D2, Ii = self._d1, self._d2, self._interior
        dg = sp.diags
        # x-momentum (interior): d(mu u'' + mu' u') = (u'' + u' D1) dmu + (mu D2 + mu' D1) du
        ju_nu = Ii @ (dg(upp * tr.mu_nu) + dg(up) @ D1 @ dg(tr.mu_nu))
        ju_T = Ii @ (dg(upp * tr.mu_T) + dg(up) @ D1 @ dg(tr.mu_T))
        ju_u = Ii @ (dg(tr.mu) @ D2 + dg(mup) @ D1)
        # energy (interior): ((T'' + T' D1) dk + (k D2 + k' D1) dT)/H^2 + u'^2 dmu + 2 mu u' D1 du - dD
        jt_nu = Ii @ (h2 * (dg(Tpp * tr.k_nu) + dg(Tp) @ D1 @ dg(tr.k_nu)) + dg(up**2 * tr.mu_nu - tr.D_nu))
        jt_T = Ii @ (h2 * (dg(Tpp * tr.k_T) + dg(Tp) @ D1 @ dg(tr.k_T) + dg(tr.k) @ D2 + dg(kp) @ D1)
                     + dg(up**2 * tr.mu_T - tr.D_T))
        jt_u = Ii @ (dg(2.0 * tr.mu * up) @ D1)
        # wall rows
        w, sig = self._w, self._sigma
        rows_w = sp.csr_matrix((np.ones(2), (w, np.arange(2))), shape=(n, 2))  # scatter 2 wall rows into n
        D1w = sp.csr_matrix(D1[w])
        e_w = sp.csr_matrix((np.ones(2), (np.arange(2), w)), shape=(2, n))  # pick wall nodes
        if self.walls == "noslip":
            ju_u = ju_u + rows_w @ e_w
            jt_T = jt_T + rows_w @ dg(sig) @ D1w
        else:
            sw, dw, sw_nu, sw_T, dw_nu, dw_T = self._wall_terms(nu[w], T[w], p)
            slip = u[w] - 0.5 * sig
            muw, upw, kw, Tpw = tr.mu[w], up[w], tr.k[w], Tp[w]
            ju_u = ju_u + rows_w @ (dg(-sig * muw) @ D1w + dg(-H * sw) @ e_w)
            ju_nu = ju_nu + rows_w @ dg(-sig * tr.mu_nu[w] * upw - H * sw_nu * slip) @ e_w
            ju_T = ju_T + rows_w @ dg(-sig * tr.mu_T[w] * upw - H * sw_T * slip) @ e_w
            jt_T = jt_T + rows_w @ (dg(sig * kw * h2) @ D1w
                                    + dg(sig * tr.k_T[w] * Tpw * h2 - H * sw_T * slip**2 + dw_T / H) @ e_w)
            jt_nu = jt_nu + rows_w @ dg(sig * tr.k_nu[w] * Tpw * h2 - H * sw_nu * slip**2 + dw_nu / H) @ e_w
            jt_u = jt_u + rows_w @ dg(-2.0 * H * sw * slip) @ e_w
        jy_nu, jy_T = dg(tr.p_nu), dg(tr.p_T)
        ones = sp.csr_matrix(-np.ones((n, 1)))
        wts = sp.csr_matrix(self.grid.weights[None, :])
        blocks = [
            [jy_nu, None, jy_T, ones],
            [ju_nu, ju_u, ju_T, None],
            [jt_nu, jt_u, jt_T, None],
            [wts, None, None, sp.csr_matrix((1, 1))],
        ]
        if self.gravity:
            for row in blocks:
                row.append(None)
            blocks[0][4] = dg(np.full(n, H**3 * p["G"]))
            blocks.append([-self._mass_nu, None, None, None, self._mass_M])
        return sp.csr_matrix(sp.bmat(blocks, format="csr"))

    # ------------------------------------------------------------------ diagnostics
    def admissible(self, x, p) -> str | None:
        nu, _, T, _, _ = self.unpack(np.asarray(x))
        if not np.all(np.isfinite(x)):
            return "state has non-finite entries"
        if np.min(T) <= 0:
            return f"temperature not positive (min T = {np.min(T):.3g})"
        if np.min(nu) <= 0:
            return f"area fraction not positive (min nu = {np.min(nu):.3g})"
        limit = self.packing_limit(p)
        if np.max(nu) >= limit:
            return f"area fraction reached phi_inf = {limit:g} (max nu = {np.max(nu):.6g})"
        return None

    def packing_limit(self, p) -> float:
        """The area fraction where the closure ends (phi_inf)."""
        return self.closure.packing_limit(p)

    # ------------------------------------------------------------------ grid hooks (contin.adapt)
    # The estimates, transfer and the guard are gPCF's (problems.gridhooks.ResolutionHooks: the
    # shared resolution measure -- Chebyshev tails, nu's against the distance to phi_inf, plus the
    # rounding term that sets the precision limit next to packing), so disks scenes run
    # adaptively like gPCF.
    def with_grid(self, N: int) -> DiskCouetteProblem:
        """The same model (method, walls, closure, gravity) on N intervals."""
        return DiskCouetteProblem(self.method, int(N), walls=self.walls, closure=self.closure, gravity=self.gravity)

    def state_on(self, x) -> np.ndarray:
        """A state of any grid of this model (its size tells the grid) carried onto this grid."""
        from contin.adapt import on_grid

        x = np.asarray(x, dtype=float)
        if x.size == self.size:
            return x
        fields = 4 if self.gravity else 3
        return on_grid(self, (x.size - 1) // fields - 1).transfer(x, self)

    def order_parameter(self, x, p=None) -> float:
        """Phi = nu(y = 1/2), the area fraction at the top wall."""
        return float(np.real(x[self.i_nu][-1]))

    def observables(self, x, p) -> dict[str, float]:
        x = np.asarray(x, dtype=float)
        nu, u, T, P, M, tr, up, *_ = self._fields(x, p)
        return {"phi": float(nu[-1]), "delta": float(nu[-1] - p["nu"]), "shear_stress": float(tr.mu[-1] * up[-1]),
                "pressure": float(tr.p[0]), "nu_bottom": float(nu[0]), "nu_top": float(nu[-1]),
                "nu_max": float(np.max(nu)), "T_bottom": float(T[0]), "T_top": float(T[-1]),
                "slip_top": float(0.5 - u[-1])}

    def shear_stress(self, x, p):
        nu, u, T, P, M, tr, up, *_ = self._fields(np.asarray(x, dtype=float), p)
        return tr.mu * up

    def profiles(self, x) -> dict[str, np.ndarray]:
        nu, u, T, _, M = self.unpack(np.asarray(x))
        out = {"nu": nu.copy(), "u": u.copy(), "T": T.copy()}
        if M is not None:
            out["M"] = M.copy()
        return out

    # ------------------------------------------------------------------ symmetry
    def symmetric(self, p) -> bool:
        return p["G"] == 0

    def symmetry(self, x):
        return reflected(self, x)
