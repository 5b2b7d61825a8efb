"""Closures of the Dsouza-Nott non-local model and the closed-form plane-shear profile.

Units (docs/nonlocal.md): lengths in particle diameters d_p, velocities in the wall speed
u_w, stresses in the prefactor alpha of the critical-state pressure.  The model is rate
independent, so u_w and alpha drop out of the quasi-static equations; they enter only
through the inertial number of the mu(I) extension, I = U gammadot / sqrt(P) with the
dimensionless wall speed U = u_w / (d_p sqrt(alpha / rho_p)) and gammadot in u_w / d_p.

Critical-state pressure (Dsouza & Nott 2020, J. Fluid Mech. 888 R3; the form of the Nott
group, e.g. Mohan, Rao & Nott 2002, J. Fluid Mech. 457, with the exponent names n1, n2 of the
report's Fig. 5):

    Pi(phi) = (phi - phi_min)^n1 / (phi_max - phi)^n2       (times alpha)

It vanishes at the loosest packing phi_min and diverges at the densest phi_max.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CriticalState:
    """Pi(phi) = (phi - phi_min)^n1 / (phi_max - phi)^n2 and its first two derivatives."""

    phi_min: float = 0.5
    phi_max: float = 0.64
    n1: float = 2.0
    n2: float = 1.0

    def __post_init__(self) -> None:
        if not (0.0 <= self.phi_min < self.phi_max < 1.0):
            raise ValueError(f"need 0 <= phi_min < phi_max < 1, got phi_min={self.phi_min:g}, phi_max={self.phi_max:g}")
        if not (self.n1 > 0 and self.n2 >= 0):
            raise ValueError(f"need n1 > 0 and n2 >= 0, got n1={self.n1:g}, n2={self.n2:g}")

    def pi(self, phi):
        """(Pi, dPi/dphi, d2Pi/dphi2) at phi (works on complex input for the complex step)."""
        a = phi - self.phi_min
        b = self.phi_max - phi
        val = a**self.n1 / b**self.n2
        s = self.n1 / a + self.n2 / b  # d ln Pi / d phi
        ds = -self.n1 / a**2 + self.n2 / b**2
        return val, val * s, val * (s * s + ds)

    def inside(self, phi: np.ndarray) -> bool:
        return bool(np.all(phi > self.phi_min) and np.all(phi < self.phi_max))


def mu_of_I(I, mu_s: float, dmu: float, I0: float):
    """(mu, dmu/dI) of mu(I) = mu_s + (mu_2 - mu_s) / (I0 / I + 1), written as
    mu_s + dmu I / (I0 + I) so that I = 0 (the quasi-static limit) is regular."""
    return mu_s + dmu * I / (I0 + I), dmu * I0 / (I0 + I) ** 2


@dataclass(frozen=True)
class PlaneShearAnalytic:
    """Uniform-phi plane shear, wall y = 0 at rest, y = W moving at u_w = 1 (lengths in d_p).

    Integrating d sigma_yx / dy = 0 once with the wall friction sigma_yx = mu_w p gives
    ell^2 u''' = (1 - mu_w / mu) u' for u' > 0; with slip u(0) = K u'(0),
    u(W) = 1 - K u'(W) and the mid-plane condition u''(W/2) = 0 (equivalently
    u'(0) = u'(W)):

        u(y) = 1/2 + sinh(zeta (y - W/2)) / (2 beta),
        zeta = sqrt(1 - mu_w/mu) / ell,  beta = K zeta cosh(zeta W/2) + sinh(zeta W/2).

    The report prints sinh(zeta (W/2 - y)), i.e. the mirror image, which puts the wall at rest
    at u(0) = 1/2 + sinh(zeta W/2) / (2 beta) (0.93 at the defaults) and violates both slip
    conditions; :meth:`report_profile` keeps it for the test that shows this.
    """

    W: float
    K: float
    ell: float
    mu_w: float
    mu: float

    def __post_init__(self) -> None:
        check_plane(self.W, self.K, self.ell, self.mu_w, self.mu)

    @property
    def zeta(self) -> float:
        return math.sqrt(1.0 - self.mu_w / self.mu) / self.ell

    @property
    def beta(self) -> float:
        z = self.zeta
        return self.K * z * math.cosh(z * self.W / 2) + math.sinh(z * self.W / 2)

    def u(self, y: np.ndarray) -> np.ndarray:
        return 0.5 + np.sinh(self.zeta * (np.asarray(y) - self.W / 2)) / (2 * self.beta)

    def dudy(self, y: np.ndarray) -> np.ndarray:
        return self.zeta * np.cosh(self.zeta * (np.asarray(y) - self.W / 2)) / (2 * self.beta)

    def report_profile(self, y: np.ndarray) -> np.ndarray:
        """The report's printed formula, 1/2 + sinh(zeta (W/2 - y)) / (2 beta) (wrong sign)."""
        return 0.5 + np.sinh(self.zeta * (self.W / 2 - np.asarray(y))) / (2 * self.beta)

    @property
    def wall_layer(self) -> float:
        """Boundary-layer width: the e-folding length of the shear rate at the wall,
        u'(0) / |u''(0)| = 1 / (zeta tanh(zeta W / 2)) (-> 1/zeta for zeta W >> 1)."""
        z = self.zeta
        return 1.0 / (z * math.tanh(z * self.W / 2))


def check_plane(W: float, K: float, ell: float, mu_w: float, mu: float) -> None:
    """ValueError (one sentence) unless the plane-shear parameters are admissible."""
    if not all(math.isfinite(v) for v in (W, K, ell, mu_w, mu)):
        raise ValueError("W, K, ell, mu_w and mu must be finite numbers")
    if not ell > 0:
        raise ValueError(f"the non-local length ell must be > 0, got ell = {ell:g}")
    if not W > 0:
        raise ValueError(f"the gap W must be > 0, got W = {W:g}")
    if K < 0:
        raise ValueError(f"the slip coefficient K must be >= 0, got K = {K:g}")
    if not mu > 0:
        raise ValueError(f"the internal friction mu must be > 0, got mu = {mu:g}")
    if mu_w < 0:
        raise ValueError(f"the wall friction mu_w must be >= 0, got mu_w = {mu_w:g}")
    if not mu_w < mu:
        raise ValueError(f"the wall friction must be below the internal friction (mu_w < mu) for a sheared "
                         f"layer with wall boundary layers (zeta^2 = (1 - mu_w/mu)/ell^2 > 0), got mu_w = {mu_w:g}, mu = {mu:g}")
