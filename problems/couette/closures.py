"""Kinetic-theory constitutive functions f1..f5 of Lun, Savage, Jeffrey & Chepurniy (1984).

In Alam's notation (physics.md section 1.2; expanded from MFIX ``GT_PDE_LUN``):
p = rho_p f1 T, mu = rho_p d f2 sqrt(T), zeta = rho_p d f3 sqrt(T), kappa = rho_p d f4 sqrt(T),
D = (rho_p / d) f5 T^{3/2}, and the Dufour-like kappa_h = rho_p d f_h T^{3/2}.  With
eta = (1 + e) / 2 and chi = chi(nu):

    f1 = nu [1 + 4 eta nu chi]
    f2 = (5 sqrt(pi) / 96) [1/(eta(2-eta)chi) + (8/5)(3eta-1)nu/(2-eta)
                            + (64/25) eta ((3eta-2)/(2-eta) + 12/pi) nu^2 chi]
    f3 = (8 / (3 sqrt(pi))) eta nu^2 chi
    f4 = (25 sqrt(pi) / 16) [1/(eta(41-33eta)chi) + (12/5)(1 + eta(4eta-3)) nu/(41-33eta)
                             + (16/25) eta (9eta(4eta-3)/(41-33eta) + 4/pi) nu^2 chi]
    f5 = (12 / sqrt(pi)) (1 - e^2) nu^2 chi
    f_h = (15 sqrt(pi)/4) (eta-1)(2eta-1)(1 + (12/5) eta nu chi)(2chi + nu chi') / ((41-33eta) chi)

Radial distribution functions chi(nu) (physics.md section 1.3):
``jj`` 1/(1 - (nu/nu_m)^{1/3}) (Johnson & Jackson 1987; default, nu_m = 0.65),
``cs`` (1 - nu/2)/(1 - nu)^3 (Carnahan & Starling 1969; diverges at nu = 1),
``ls`` (1 - nu/nu_m)^{-2.5 nu_m} (Lun & Savage 1986).

All functions accept complex ``nu`` and ``e`` so that complex-step derivatives work through
them; derivatives with respect to nu are analytic.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

SQRT_PI = np.sqrt(np.pi)
_FLOATS = (float, np.float64)  # scalar types of e whose constants are cached (see coefficients)
CHI_MODELS = ("jj", "cs", "ls")


def radial_distribution(nu, model: str = "jj", nu_max: float = 0.65):
    """chi(nu) and dchi/dnu for ``model`` in ('jj', 'cs', 'ls')."""
    if model == "jj":
        s = (nu / nu_max) ** (1.0 / 3.0)
        chi = 1.0 / (1.0 - s)
        return chi, chi**2 * s / (3.0 * nu)
    if model == "cs":
        chi = (1.0 - nu / 2.0) / (1.0 - nu) ** 3
        return chi, (2.5 - nu) / (1.0 - nu) ** 4
    if model == "ls":
        chi = (1.0 - nu / nu_max) ** (-2.5 * nu_max)
        return chi, 2.5 * chi / (1.0 - nu / nu_max)
    raise ValueError(f"unknown radial distribution {model!r}; choose one of {', '.join(CHI_MODELS)}")


def packing_limit(model: str, nu_max: float) -> float:
    """The volume fraction at which chi diverges (nu_max for jj/ls, 1 for cs)."""
    return 1.0 if model == "cs" else nu_max


class Coefficients(NamedTuple):
    """f1..f5, f_h and their nu-derivatives (suffix ``_nu``) at given (nu, e).

    A NamedTuple rather than a frozen dataclass: it is built at every residual evaluation,
    and a 13-field frozen dataclass costs ~3 us to construct, a tuple ~1 us.
    """

    f1: np.ndarray
    f2: np.ndarray
    f3: np.ndarray
    f4: np.ndarray
    f5: np.ndarray
    fh: np.ndarray
    f1_nu: np.ndarray
    f2_nu: np.ndarray
    f3_nu: np.ndarray
    f4_nu: np.ndarray
    f5_nu: np.ndarray
    chi: np.ndarray
    chi_nu: np.ndarray


def coefficients(nu, e, model: str = "jj", nu_max: float = 0.65, dufour: bool = False) -> Coefficients:
    """Evaluate the LSJC functions and their nu-derivatives (physics.md section 1.2).

    ``fh`` is zero unless ``dufour`` is True; its nu-derivative is not needed by the
    steady problem with fh = 0 and is not provided.
    """
    chi, chi1 = radial_distribution(nu, model, nu_max)
    # Shared pieces: q = nu^2 chi and its nu-derivative, 1/chi and its nu-derivative.
    g = nu * chi
    q = nu * g
    q_nu = 2.0 * g + nu * nu * chi1
    ic = 1.0 / chi
    ic_nu = -chi1 * ic * ic

    cached = type(e) in _FLOATS
    if (cached or np.ndim(e) == 0) and getattr(nu, "ndim", 0) == 1:  # nu: an array or a scalar
        # Stacked rows: one numpy call per operation instead of one per function (the arrays
        # are short in continuation, so the number of calls is the cost); the e-dependent
        # constants as column arrays, cached per value of e (a float: e is not complex here).
        b_, c_, d_, k_ = _stacked_constants(e) if cached else _columns(_constants(e))
        f24 = b_ * ic + c_ * nu + d_ * q
        f24_nu = b_ * ic_nu + (c_ + d_ * q_nu)
        q135 = k_ * q
        q135_nu = k_ * q_nu
    else:
        b24, c24, d24, k135 = _constants(e)
        f24 = [b * ic + c * nu + d * q for b, c, d in zip(b24, c24, d24)]
        f24_nu = [b * ic_nu + (c + d * q_nu) for b, c, d in zip(b24, c24, d24)]
        q135 = [k * q for k in k135]
        q135_nu = [k * q_nu for k in k135]
    f1 = nu + q135[0]
    f1_nu = 1.0 + q135_nu[0]
    f2, f4, f2_nu, f4_nu = f24[0], f24[1], f24_nu[0], f24_nu[1]
    f3, f5, f3_nu, f5_nu = q135[1], q135[2], q135_nu[1], q135_nu[2]

    if dufour:
        eta = (1.0 + e) / 2.0
        g4 = 41.0 - 33.0 * eta
        fh = (15.0 * SQRT_PI / 4.0) * (eta - 1.0) * (2.0 * eta - 1.0) * (1.0 + 2.4 * eta * nu * chi) \
            * (2.0 * chi + nu * chi1) / (g4 * chi)
    else:
        fh = 0.0 * nu
    return Coefficients(f1, f2, f3, f4, f5, fh, f1_nu, f2_nu, f3_nu, f4_nu, f5_nu, chi, chi1)


def real_coefficients(nu: np.ndarray, e: float, model: str = "jj", nu_max: float = 0.65) -> Coefficients:
    """:func:`coefficients` for a real 1-D float64 ``nu``, a float ``e`` and no Dufour flux (fh = 0).

    The hot path of the gPCF residual (one call per Newton iterate).  Every f_i is
    (c0 b0 + c1 b1) + c2 b2 in the basis (1/chi, nu, nu^2 chi), and every f_i_nu is
    (c0 b0 + c1 b1) + c2 b2 in ((nu^2 chi)', 1, (1/chi)') -- the association and order of the
    operations of :func:`coefficients` (adding the exact 0 of a missing term changes nothing), so
    the result is bitwise the same (tested) -- with all twelve rows (fh = 0 the last) from one
    broadcast product and two sums: 4 numpy calls instead of 15 on continuation-sized arrays.
    """
    chi, chi1 = radial_distribution(nu, model, nu_max)
    basis = np.empty((3, 2, 1, nu.size))  # (term, values/derivatives, 1, node)
    b = basis[:, :, 0]
    b[1, 0] = nu
    b[1, 1] = 1.0
    g = nu * chi
    np.multiply(nu, g, out=b[2, 0])  # q = nu^2 chi
    np.add(2.0 * g, nu * nu * chi1, out=b[0, 1])  # q_nu
    ic = np.divide(1.0, chi, out=b[0, 0])
    np.multiply(-chi1 * ic, ic, out=b[2, 1])  # (1/chi)_nu
    terms = _basis_matrix(e) * basis
    rows = terms[0] + terms[1]
    rows += terms[2]
    (f1, f2, f3, f4, f5, fh), (f1_nu, f2_nu, f3_nu, f4_nu, f5_nu, _) = rows
    return Coefficients(f1, f2, f3, f4, f5, fh, f1_nu, f2_nu, f3_nu, f4_nu, f5_nu, chi, chi1)


@lru_cache(maxsize=64)
def _basis_matrix(e: float) -> np.ndarray:
    """(term, values/derivatives, row f1..f5 fh, 1) coefficients of :func:`real_coefficients`.  Read-only."""
    (b2, b4), (c2, c4), (d2, d4), (k1, k3, k5) = _constants(e)
    m = np.zeros((3, 2, 6, 1))
    # f1 = nu + k1 q; f2, f4 = (b / chi + c nu) + d q; f3, f5 = k q
    m[:, 0, :5, 0] = np.array([[0.0, 1.0, k1], [b2, c2, d2], [0.0, 0.0, k3], [b4, c4, d4], [0.0, 0.0, k5]]).T
    # f1_nu = 1 + k1 q_nu; f2_nu, f4_nu = b (1/chi)_nu + (c + d q_nu); f3_nu, f5_nu = k q_nu
    m[:, 1, :5, 0] = np.array([[k1, 1.0, 0.0], [d2, c2, b2], [k3, 0.0, 0.0], [d4, c4, b4], [k5, 0.0, 0.0]]).T
    m.flags.writeable = False
    return m


def _constants(e):
    """(b24, c24, d24, k135): f2, f4 = b / chi + c nu + d nu^2 chi; f1 - nu, f3, f5 = k nu^2 chi."""
    eta = (1.0 + e) / 2.0
    a2 = 5.0 * SQRT_PI / 96.0
    a4 = 25.0 * SQRT_PI / 16.0
    g4 = 41.0 - 33.0 * eta
    b24 = (a2 / (eta * (2.0 - eta)), a4 / (eta * g4))
    c24 = (a2 * 1.6 * (3.0 * eta - 1.0) / (2.0 - eta), a4 * 2.4 * (1.0 + eta * (4.0 * eta - 3.0)) / g4)
    d24 = (a2 * 2.56 * eta * ((3.0 * eta - 2.0) / (2.0 - eta) + 12.0 / np.pi),
           a4 * 0.64 * eta * (9.0 * eta * (4.0 * eta - 3.0) / g4 + 4.0 / np.pi))
    k135 = (4.0 * eta, 8.0 / (3.0 * SQRT_PI) * eta, 12.0 / SQRT_PI * (1.0 - e * e))
    return b24, c24, d24, k135


def _columns(constants):
    col = (slice(None), None)
    return tuple(np.array(c)[col] for c in constants)


@lru_cache(maxsize=64)
def _stacked_constants(e: float):
    """:func:`_constants` as column arrays (cached: e is fixed along most runs).  Read-only."""
    out = _columns(_constants(e))
    for a in out:
        a.flags.writeable = False
    return out


def wall_prefactors(phi_w, ew, nu_max):
    """(c_s, c_d) of the Johnson-Jackson wall terms (physics.md section 3b), s_w = c_s nu chi sqrt(T)
    and d_w = c_d nu chi T^{3/2}: c_s = phi_w pi / (2 sqrt(3) nu_m), c_d = sqrt(3) pi (1 - e_w^2) / (4 nu_m).
    Accepts complex values (complex-step derivatives)."""
    sqrt3 = np.sqrt(3.0)
    return phi_w * np.pi / (2.0 * sqrt3 * nu_max), sqrt3 * np.pi * (1.0 - ew**2) / (4.0 * nu_max)


def uniform_shear(nu, e, model: str = "jj", nu_max: float = 0.65):
    """Uniform shear state (physics.md section 4): T0 = f2/f5, S0 = f2 sqrt(T0), p0 = f1 T0.

    Raises ValueError for e = 1 (f5 = 0: no collisional dissipation balances viscous heating,
    so there is no steady uniform temperature).
    """
    if np.any(np.real(np.asarray(e)) >= 1.0):
        raise ValueError("e = 1 has no steady uniform shear (no collisional dissipation, T0 = f2/f5 is infinite); use e < 1")
    c = coefficients(nu, e, model, nu_max)
    t0 = c.f2 / c.f5
    return t0, c.f2 * np.sqrt(t0), c.f1 * t0


def critical_gap_factor(nu, e, model: str = "jj", nu_max: float = 0.65, dufour: bool = False):
    """psi(nu, e) with H_n^c = n pi psi (physics.md section 4, no-slip/adiabatic walls).

    psi^2 = (f4/f5) / [(f1/f1')(f2'/f2 + f5'/f5) - 2]; returns nan where the bracket is not
    positive (no shear-banding instability: "bifurcation from infinity").  With the Dufour flux
    (``dufour``, heat flux -kappa_h nu') f4 is replaced by f4 - f_h f1/f1' (physics.md section 4).
    """
    c = coefficients(nu, e, model, nu_max, dufour=dufour)
    bracket = (c.f1 / c.f1_nu) * (c.f2_nu / c.f2 + c.f5_nu / c.f5) - 2.0
    f4 = c.f4 - c.fh * c.f1 / c.f1_nu if dufour else c.f4
    with np.errstate(invalid="ignore", divide="ignore"):
        psi2 = (f4 / c.f5) / bracket
    return np.where(np.real(bracket) > 0, np.sqrt(np.abs(psi2)), np.nan)
