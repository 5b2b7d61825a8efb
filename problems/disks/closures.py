"""Constitutive closures of two-dimensional granular disks (docs/disks.md).

Kinetic part: Jenkins & Richman (1985, Phys. Fluids 28, 3485) for smooth inelastic disks with
the constants of Saitoh et al. (Soft Matter 2015 ESI, Table 1; seeds/002 Eqs. 9-13).  In the
Alam-type f-notation of physics.md (section 1.2), lengths by the diameter d, mass density by
rho_p (mass per particle area), T = <C.C>/2 the 2-D granular temperature per unit mass:

    p  = rho_p f1 T,            f1 = nu [1 + (1+e) G]
    mu = rho_p d f2 sqrt(T),    f2 = c nu [a_eta G + b_eta / G + c_eta]        (shear viscosity)
    xi = rho_p d f3 sqrt(T),    f3 = c nu a_xi G                                (bulk viscosity)
    k  = rho_p d f4 sqrt(T),    f4 = c nu [a_kap G + b_kap / G + c_kap]        (conductivity)
    D  = (rho_p/d) f5 T^{3/2},  f5 = c nu a_chi G                               (dissipation)

with G = nu g(nu) (g the contact value of the pair correlation).  ``normalization='jr'``
(c = pi/4) is the physically consistent one: f1 is 2-D Enskog's n T [1 + (1+e) nu g], and
f2, f4, f5 reproduce Enskog's dilute viscosity (1/2d) sqrt(m T/pi), conductivity (2/d)
sqrt(T/(pi m)), Gass's dense viscosity eta_0 [1/g + 2 nu + (1 + 8/pi) nu^2 g] and the
collision integral of the dissipation, Gamma = sqrt(pi) (1 - e^2) g n^2 d T^{3/2} / sqrt(m).
``normalization='esi'`` (c = 1) is the ESI's dimensionless system taken literally
(p = [1 + (1+e)G] phi theta beside eta = [...] phi theta^{1/2}): the same transport
coefficients, but a pressure pi/4 smaller relative to them (the ESI scales stresses by
epsilon/upsilon with upsilon = d^2 while phi is the area fraction; see docs/disks.md).  The
uniform-shear temperature T0 = f2/f5 (ESI Eq. 31) is the same in both.

Pair correlation G(nu) (ESI Eqs. 24-26): ``cs`` Carnahan-Starling/Henderson
nu (16 - 7 nu) / (16 (1 - nu)^2); ``fv`` free volume [(1+e)(sqrt(phi_inf/nu) - 1)]^-1;
``gf`` Luding's global fit G_CS + (G_FV - G_CS) / (1 + exp(-(nu - phi_f)/m_f)).

Dense part (Savage 1998, JFM 377, 1; ESI Eqs. 14-23): a rate-independent contact pressure
p_con = a0 log((phi_inf - phi_c)/(phi_inf - nu)) for nu > phi_c (zero below: the model holds
for phi_c < nu < phi_inf), and every transport coefficient and the dissipation proportional to
the total pressure p = p_kin + p_con with the kinetic ratios: mu = p f2 / (f1 sqrt T),
k = p f4 / (f1 sqrt T), D = p f5 sqrt(T) / f1 (ESI f_eta = f1/f2, f_kappa = f1/f4,
f_chi = f1/f5).  In the Couette scaling (stresses by rho_p (gamma_dot d)^2) the parameter is
``a0`` in those units: a rate-independent p_con is a0 = a0_phys / (rho_p gamma_dot^2 d^2).

All functions accept complex arguments (complex-step derivatives); nu-derivatives are analytic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

SQRT_PI = math.sqrt(math.pi)
G_MODELS = ("cs", "fv", "gf")
NORMALIZATIONS = ("jr", "esi")


# ----------------------------------------------------------------------------- pair correlation
def pair_correlation(nu, model: str, e, phi_inf, phi_f=0.7, m_f=0.01):
    """G(nu) = nu g(nu) and dG/dnu for ``model`` in G_MODELS (ESI Eqs. 24-26, 38-40)."""
    if model not in G_MODELS:
        raise ValueError(f"unknown pair correlation G = {model!r}; choose one of {', '.join(G_MODELS)}")
    g_cs = nu * (16.0 - 7.0 * nu) / (16.0 * (1.0 - nu) ** 2)
    g_cs_nu = (1.0 + nu / 8.0) / (1.0 - nu) ** 3
    if model == "cs":
        return g_cs, g_cs_nu
    r = np.sqrt(phi_inf / nu)
    g_fv = 1.0 / ((1.0 + e) * (r - 1.0))
    g_fv_nu = r / (2.0 * (1.0 + e) * nu * (r - 1.0) ** 2)
    if model == "fv":
        return g_fv, g_fv_nu
    a = -(nu - phi_f) / m_f
    if np.any(np.real(a) > 350.0):
        # Far below phi_f in units of m_f (phi_f = 1e300, or m_f = 1e-300): x = exp(a) overflowed
        # and w_nu = inf/inf = nan made psi nan, so disks-pitchfork said 'no pitchfork' and exited 0.
        # There y = 1/x = exp(-a): w = y/(1 + y), and x/(1 + x)^2 = y/(1 + y)^2 is the same formula.
        # Elsewhere (every physical case) y = x and nothing changes.  Complex steps pass through.
        far = np.real(a) > 350.0
        y = np.exp(np.where(far, -a, a))
        w = np.where(far, y / (1.0 + y), 1.0 / (1.0 + y))
    else:
        y = np.exp(a)
        w = 1.0 / (1.0 + y)  # logistic weight of the free-volume branch
    w_nu = y / (m_f * (1.0 + y) ** 2)
    return g_cs + (g_fv - g_cs) * w, g_cs_nu + (g_fv_nu - g_cs_nu) * w + (g_fv - g_cs) * w_nu


# ----------------------------------------------------------------------------- kinetic constants
def table1(e) -> dict[str, Any]:
    """The constants of ESI Table 1 (Jenkins & Richman 1985 for disks) at restitution e."""
    sp_ = SQRT_PI
    return {
        "a_xi": 4.0 * (1.0 + e) / sp_**3,
        "a_eta": (1.0 + e) / sp_ * ((1.0 + e) * (3.0 * e - 1.0) / (4.0 * (7.0 - 3.0 * e)) + 2.0 / math.pi),
        "b_eta": 2.0 / (sp_ * (7.0 - 3.0 * e)),
        "c_eta": (1.0 + e) * (3.0 * e + 1.0) / (2.0 * sp_ * (7.0 - 3.0 * e)),
        "a_kap": (1.0 + e) / sp_ * (9.0 * (1.0 + e) ** 2 * (2.0 * e - 1.0) / (4.0 * (19.0 - 15.0 * e)) + 4.0 / math.pi),
        "b_kap": 16.0 / (sp_ * (1.0 + e) * (19.0 - 15.0 * e)),
        "c_kap": 6.0 * (2.0 * e**2 + e + 1.0) / (sp_ * (19.0 - 15.0 * e)),
        "a_chi": 16.0 * (1.0 - e**2) / sp_**3,
    }


class Kinetic(NamedTuple):
    """f1..f5 of the module docstring, their nu-derivatives, and G, G' (all arrays like nu)."""

    f1: Any
    f2: Any
    f3: Any
    f4: Any
    f5: Any
    f1_nu: Any
    f2_nu: Any
    f3_nu: Any
    f4_nu: Any
    f5_nu: Any
    G: Any
    G_nu: Any


class Transport(NamedTuple):
    """Pressure p, viscosity mu, conductivity k, dissipation D and their nu-, T-partials."""

    p: Any
    p_nu: Any
    p_T: Any
    mu: Any
    mu_nu: Any
    mu_T: Any
    k: Any
    k_nu: Any
    k_T: Any
    D: Any
    D_nu: Any
    D_T: Any


@dataclass(frozen=True)
class DiskClosure:
    """The choice of closure: pair correlation, normalization, Savage contact part on/off.

    Parameter values (e, phi_inf, phi_f, m_f, phi_c, a0) come with each call in a mapping, so that
    they can be continuation parameters and carry complex steps.
    """

    G: str = "cs"
    contact: bool = False
    normalization: str = "jr"

    def __post_init__(self) -> None:
        if self.G not in G_MODELS:
            raise ValueError(f"unknown pair correlation G = {self.G!r}; choose one of {', '.join(G_MODELS)}")
        if self.normalization not in NORMALIZATIONS:
            raise ValueError(f"unknown normalization {self.normalization!r}; choose one of {', '.join(NORMALIZATIONS)}")

    @property
    def scale(self) -> float:
        """c of the module docstring: pi/4 ('jr') or 1 ('esi')."""
        return math.pi / 4.0 if self.normalization == "jr" else 1.0

    def kinetic(self, nu, p) -> Kinetic:
        """f1..f5 and their nu-derivatives at area fraction nu (parameters e, phi_inf, phi_f, m_f from p)."""
        e = p["e"]
        G, G_nu = pair_correlation(nu, self.G, e, p["phi_inf"], p.get("phi_f", 0.7), p.get("m_f", 0.01))
        t = table1(e)
        c = self.scale
        iG, iG_nu = 1.0 / G, -G_nu / G**2

        def poly(a, b, cc):
            val = a * G + b * iG + cc
            return c * nu * val, c * (val + nu * (a * G_nu + b * iG_nu))

        f2, f2_nu = poly(t["a_eta"], t["b_eta"], t["c_eta"])
        f4, f4_nu = poly(t["a_kap"], t["b_kap"], t["c_kap"])
        f3, f3_nu = c * t["a_xi"] * nu * G, c * t["a_xi"] * (G + nu * G_nu)
        f5, f5_nu = c * t["a_chi"] * nu * G, c * t["a_chi"] * (G + nu * G_nu)
        f1 = nu * (1.0 + (1.0 + e) * G)
        f1_nu = 1.0 + (1.0 + e) * (G + nu * G_nu)
        return Kinetic(f1, f2, f3, f4, f5, f1_nu, f2_nu, f3_nu, f4_nu, f5_nu, G, G_nu)

    def contact_pressure(self, nu, p):
        """(p_con, dp_con/dnu): a0 log((phi_inf - phi_c)/(phi_inf - nu)) above phi_c, else 0 (ESI Eq. 15)."""
        if not self.contact:
            return 0.0 * nu, 0.0 * nu
        inf, pc, a0 = p["phi_inf"], p["phi_c"], p["a0"]
        on = np.real(nu) > np.real(pc)
        val = a0 * np.log((inf - pc) / (inf - nu))
        return np.where(on, val, 0.0 * val), np.where(on, a0 / (inf - nu), 0.0 * val)

    def transport(self, nu, T, p) -> Transport:
        """p, mu, k, D and their partials at (nu, T); Savage's form when ``contact`` is on."""
        f = self.kinetic(nu, p)
        sT = np.sqrt(T)
        pc, pc_nu = self.contact_pressure(nu, p)
        pr, pr_nu, pr_T = f.f1 * T + pc, f.f1_nu * T + pc_nu, f.f1
        out = [pr, pr_nu, pr_T]
        # X = f sqrt(T) (1 + pc / (f1 T)) = f sqrt(T) + pc (f/f1) T^-1/2 for X = mu, k; D likewise with T^{1/2}
        for fx, fx_nu, power in ((f.f2, f.f2_nu, 0.5), (f.f4, f.f4_nu, 0.5), (f.f5, f.f5_nu, 1.5)):
            kin = fx * T**power
            kin_nu, kin_T = fx_nu * T**power, power * fx * T ** (power - 1.0)
            if self.contact:
                ratio = fx / f.f1
                ratio_nu = (fx_nu * f.f1 - fx * f.f1_nu) / f.f1**2
                tp = T ** (power - 1.0)
                kin = kin + pc * ratio * tp
                kin_nu = kin_nu + (pc_nu * ratio + pc * ratio_nu) * tp
                kin_T = kin_T + (power - 1.0) * pc * ratio * T ** (power - 2.0)
            out += [kin, kin_nu, kin_T]
        return Transport(*out)

    def packing_limit(self, p) -> float:
        """The area fraction where the closure ends: phi_inf (G_FV, G_GF and p_con diverge there;
        for G_CS, which diverges only at 1, phi_inf is kept as the closure's maximum packing)."""
        return float(np.real(p["phi_inf"]))


# ----------------------------------------------------------------------------- parameter checks
def check_closure_parameters(p, closure: DiskClosure) -> None:
    """One-sentence ValueError for parameters outside the closure's validity (issue 17)."""
    e = float(np.real(p["e"]))
    if not 0.0 < e <= 1.0:
        raise ValueError(f"restitution coefficient e = {e:g} is outside (0, 1]")
    inf = float(np.real(p["phi_inf"]))
    if not 0.0 < inf < 1.0:
        raise ValueError(f"maximum area fraction phi_inf = {inf:g} must lie in (0, 1)")
    nu = float(np.real(p["nu"]))
    if not nu > 0.0:
        raise ValueError(f"mean area fraction nu = {nu:g} must be > 0")
    if nu >= inf:
        raise ValueError(f"mean area fraction nu = {nu:g} >= phi_inf = {inf:g}: the closure diverges there "
                         "(G_FV and the contact pressure are infinite at phi_inf)")
    if closure.G == "gf" and not float(np.real(p["m_f"])) > 0:
        raise ValueError(f"the width m_f = {float(np.real(p['m_f'])):g} of the global fit must be > 0")
    if closure.G == "gf" and not 0.0 < float(np.real(p["phi_f"])) < inf:
        raise ValueError(f"the freezing area fraction phi_f = {float(np.real(p['phi_f'])):g} of the global fit must lie "
                         f"in (0, phi_inf = {inf:g}), where it switches from G_CS to G_FV")
    if closure.contact:
        pc = float(np.real(p["phi_c"]))
        if not 0.0 < pc < inf:
            raise ValueError(f"critical area fraction phi_c = {pc:g} must lie in (0, phi_inf = {inf:g})")
        if not float(np.real(p["a0"])) >= 0:
            raise ValueError(f"contact pressure scale a0 = {float(np.real(p['a0'])):g} must be >= 0")


# ----------------------------------------------------------------------------- uniform shear
def uniform_temperature(nu, p, closure: DiskClosure):
    """T0 = f2/f5 of uniform shear (u' = 1): mu u'^2 = D; with Savage's contact part both sides
    carry the same factor p/(f1 T), so T0 is the kinetic one (ESI Eq. 31)."""
    if float(np.real(p["e"])) >= 1.0:
        raise ValueError("e = 1 has no steady uniform shear (no collisional dissipation balances the shear "
                         "heating, T0 = f2/f5 is infinite); use e < 1")
    f = closure.kinetic(nu, p)
    return f.f2 / f.f5


def uniform_shear(nu, p, closure: DiskClosure) -> tuple[Any, Any, Any]:
    """(T0, S0, p0) of uniform shear: temperature, shear stress mu(nu, T0), pressure p(nu, T0)."""
    t0 = uniform_temperature(nu, p, closure)
    tr = closure.transport(nu, t0, p)
    return t0, tr.mu, tr.p


def critical_gap_factor(nu, p, closure: DiskClosure):
    """psi with H_n^c = n pi psi for uniform shear between no-slip adiabatic walls (docs/disks.md).

    The k_x = 0 mode (nu, T) ~ cos n pi (y + 1/2), u ~ sin n pi (y + 1/2) of the steady equations
    (p(nu,T) = P, (mu u')' = 0, (k T')'/H^2 + mu u'^2 - D = 0) is neutral when

        psi^2 = k r / [(mu_nu + D_nu) - (mu_T + D_T) r],   r = p_nu / p_T,

    all at (nu, T0).  For the kinetic closure this is physics.md's
    (f4/f5) / [(f1/f1')(f2'/f2 + f5'/f5) - 2] with the disk f's.  nan where the bracket is not
    positive (no shear-banding pitchfork at any gap).
    """
    t0 = uniform_temperature(nu, p, closure)
    tr = closure.transport(nu, t0, p)
    r = tr.p_nu / tr.p_T
    bracket = (tr.mu_nu + tr.D_nu) - (tr.mu_T + tr.D_T) * r
    with np.errstate(invalid="ignore", divide="ignore"):
        psi2 = tr.k * r / bracket
    return np.where(np.real(bracket) > 0, np.sqrt(np.abs(psi2)), np.nan)


def kinetic_gap_factor(nu, p, closure: DiskClosure):
    """physics.md's explicit psi^2 = (f4/f5) / [(f1/f1')(f2'/f2 + f5'/f5) - 2] with the disk f's
    (the kinetic closure only; a cross-check of :func:`critical_gap_factor`)."""
    f = closure.kinetic(nu, p)
    bracket = (f.f1 / f.f1_nu) * (f.f2_nu / f.f2 + f.f5_nu / f.f5) - 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        psi2 = (f.f4 / f.f5) / bracket
    return np.where(np.real(bracket) > 0, np.sqrt(np.abs(psi2)), np.nan)


def critical_gaps(p, closure: DiskClosure, modes: int = 3) -> list[float]:
    """[H_1^c, ..., H_modes^c] = n pi psi(nu_bar) (nan where psi is not finite)."""
    psi = float(critical_gap_factor(np.float64(p["nu"]), p, closure))
    return [n * math.pi * psi for n in range(1, modes + 1)]


# ----------------------------------------------------------------------------- Savage rheology (ESI units)
def savage_contact_stresses(phi0, p, closure: DiskClosure) -> tuple[Any, Any]:
    """(p_con, sigma_con) of homogeneous simple shear, ESI Eqs. 15 and 28:

        p_con = a0 log((phi_inf - phi_c)/(phi_inf - phi0)),
        sigma_con = a0 log(...) / sqrt(f_eta f_chi),  f_eta = f1/f2, f_chi = f1/f5.

    Rate-independent.  Raises ValueError below phi_c, where the dense closure has no contact part
    (the model holds for phi_c < phi0 < phi_inf, ESI Sec. 1.3).
    """
    phi0 = np.asarray(phi0, dtype=float)
    if np.any(phi0 <= p["phi_c"]):
        raise ValueError(f"contact stresses asked at phi0 = {float(np.min(phi0)):g} <= phi_c = {p['phi_c']:g}: "
                         "Savage's dense closure has no contact part there (valid for phi_c < phi0 < phi_inf)")
    if np.any(phi0 >= p["phi_inf"]):
        raise ValueError(f"phi0 = {float(np.max(phi0)):g} >= phi_inf = {p['phi_inf']:g}: the contact pressure diverges")
    f = closure.kinetic(phi0, p)
    pcon = p["a0"] * np.log((p["phi_inf"] - p["phi_c"]) / (p["phi_inf"] - phi0))
    return pcon, pcon / np.sqrt((f.f1 / f.f2) * (f.f1 / f.f5))


def homogeneous_stresses(phi0, s, p, closure: DiskClosure) -> tuple[Any, Any, Any]:
    """(theta0, p, sigma) of homogeneous simple shear at shear rate s (ESI Sec. 1.5, Eqs. 27-31):

    theta0 = s^2 f_chi/f_eta = s^2 f2/f5, p = f1 theta0 + p_con, sigma = s p / (f_eta sqrt(theta0)).
    With the contact part sigma = sigma_kin (prop. to s^2, Bagnold) + sigma_con (Eq. 28).
    """
    f = closure.kinetic(phi0, p)
    theta0 = s**2 * f.f2 / f.f5
    pc, _ = closure.contact_pressure(phi0, p)
    pressure = f.f1 * theta0 + pc
    return theta0, pressure, s * pressure * f.f2 / (f.f1 * np.sqrt(theta0))


def kn_in_time_units(e: float) -> float:
    """k_n t_m^2 / m of the linear spring-dashpot f_n = k_n xi - eta_n xi' (ESI Eq. 91) with restitution e.

    Two equal particles (reduced mass m/2): e = exp(-pi z / sqrt(1 - z^2)), z = eta_n / (2 sqrt(k_n m/2)),
    and t_m = eta_n / k_n give k_n t_m^2 / m = eta_n^2 / (k_n m) = 2 z^2.  Converts a0 = 3.25e-2 k_n
    into the ESI's units m / t_m^2 (used for the flow curves; ESI Table 2 gives a0 / k_n only).
    """
    if not 0.0 < e < 1.0:
        raise ValueError(f"restitution coefficient e = {e:g} must lie in (0, 1) for a dashpot")
    q = -math.log(e) / math.pi  # z / sqrt(1 - z^2)
    z2 = q * q / (1.0 + q * q)
    return 2.0 * z2
