"""Why our third-pitchfork isola dies at Fr = 783.97 and the slides' (A13) at ~922: closure
variants of the death Fr (results/gravity/isola_death/isola_death.md; nu = 0.3, e = 0.8, no-slip walls).

Two facts the notes rely on:

- Exact closure scaling: with f_i -> a_i f_i (i = 1, 2, 4, 5) the steady no-slip/zero-flux problem
  at (H, G) is the original one at (H / h, G / g), T scaled by a2 / a5, h = sqrt(a4 / a5),
  g = a1 a2 sqrt(a5) / a4^(3/2).  Every critical Fr scales by g^(-1/2) and every critical gap by h,
  so the ratio death Fr / Fr* (= 3.0850) cannot change.  f4 x 1.24138 is the single-factor change
  that moves the death to 922 -- a constructed fit, not an identified cause.
- The threshold density below which uniform shear has no pitchfork (physics.md section 4) must
  lie between the slides' nu = 0.15 ("bifurcation from infinity") and 0.16 (subcritical); the
  closest natural variant for the death Fr (elastic transport coefficients: 908.5) fails it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

from problems.couette import closures, model
from problems.couette.gravity import phase_diagram
from problems.couette.model import CouetteProblem

# Baseline (chi_JJ, nu_m = 0.65, no Dufour), cheb 48 = 64 = 96 to 7 digits (test_couette_gravity.py).
FR_STAR = 254.12038
FR_DEATH = 783.97295
H_STAR, H_DEATH = 19.10882, 47.75352
F4_FACTOR = (922.0 / FR_DEATH) ** (4.0 / 3.0)  # 1.24138: g = F4_FACTOR^(-3/2), Fr x F4_FACTOR^(3/4)


def _with(c, **fields):
    """Copy of closures.Coefficients with some fields replaced (NamedTuple or dataclass)."""
    return c._replace(**fields) if hasattr(c, "_replace") else dataclasses.replace(c, **fields)


def _deaths(pb: CouetteProblem) -> tuple[float, dict[str, dict]]:
    params = pb.params({"nu": 0.3, "e": 0.8, "num": 0.65})
    d = phase_diagram(pb, params, H_range=(1.0, 70.0))
    rows = {r["curve"]: r for r in d.extrema if r["event"] == "death"}
    return d.fr_min_floating_plug, rows


def _threshold(f2_f4_elastic: bool) -> float:
    """Density where (f1/f1')(f2'/f2 + f5'/f5) - 2 changes sign (psi of physics.md s. 4)."""

    def bracket(nu: float) -> float:
        c = closures.coefficients(np.float64(nu), 0.8)
        f2, f2_nu = c.f2, c.f2_nu
        if f2_f4_elastic:
            el = closures.coefficients(np.float64(nu), 1.0)
            f2, f2_nu = el.f2, el.f2_nu
        return float((c.f1 / c.f1_nu) * (f2_nu / f2 + c.f5_nu / c.f5) - 2.0)

    return brentq(bracket, 0.05, 0.3, xtol=1e-10)


def test_threshold_density_excludes_elastic_transport():
    """LSJC (eta-dependent f2, f4): no pitchfork below nu = 0.15614, between the slides' 0.15 and
    0.16 cases.  f2, f4 at e = 1 (elastic Chapman-Enskog transport, dissipation only in f5):
    0.12742, which would give nu = 0.15 a finite-H pitchfork, against the slides."""
    assert _threshold(False) == pytest.approx(0.15614, abs=1e-5)
    assert _threshold(True) == pytest.approx(0.12742, abs=1e-5)


@pytest.mark.slow
def test_f4_factor_scales_every_critical_Fr_exactly(monkeypatch):
    """f4 -> 1.24138 f4: Fr* and the third-pitchfork isola's death both move by 1.24138^(3/4)
    = 1.17606 (to 298.861 and 922.000), the gaps by sqrt(1.24138) (H_1^c 13.0685 -> 14.5606)."""
    original = closures.coefficients

    def scaled(nu, e, chi="jj", nu_max=0.65, dufour=False):
        c = original(nu, e, chi, nu_max, dufour)
        return _with(c, f4=F4_FACTOR * c.f4, f4_nu=F4_FACTOR * c.f4_nu)

    original_real = closures.real_coefficients

    def scaled_real(nu, e, chi="jj", nu_max=0.65):  # the residual's fast path for real states
        c = original_real(nu, e, chi, nu_max)
        return _with(c, f4=F4_FACTOR * c.f4, f4_nu=F4_FACTOR * c.f4_nu)

    monkeypatch.setattr(model, "coefficients", scaled)
    monkeypatch.setattr(model, "real_coefficients", scaled_real)
    fr_star, deaths = _deaths(CouetteProblem("cheb", 48, gravity=True))
    s, h = F4_FACTOR**0.75, F4_FACTOR**0.5
    assert fr_star == pytest.approx(FR_STAR * s, rel=1e-6)
    assert deaths["fold0"]["H"] == pytest.approx(H_STAR * h, abs=1e-3)
    assert deaths["fold1"]["Fr"] == pytest.approx(922.0, rel=1e-6)
    assert deaths["fold1"]["H"] == pytest.approx(H_DEATH * h, abs=1e-3)


@pytest.mark.slow
def test_dufour_term_moves_death_and_fr_star_together():
    """The Dufour-like flux k_h nu' (physics.md 1.2, off by default) raises Fr* to 262.349 and the
    third-pitchfork isola's death to 809.403 (+3.2 % each): the ratio stays 3.085, and the death
    stays 12 % below the slides' 922."""
    fr_star, deaths = _deaths(CouetteProblem("cheb", 48, gravity=True, dufour=True))
    assert fr_star == pytest.approx(262.3486, rel=1e-5)
    assert deaths["fold1"]["Fr"] == pytest.approx(809.4031, rel=1e-5)
    assert deaths["fold1"]["Fr"] / fr_star == pytest.approx(FR_DEATH / FR_STAR, abs=2e-3)
