"""Parameters of granular plane Couette flow: names, defaults, Froude-number conversion, checks.

Continuation parameters (physics.md sections 2-3, Alam scaling):

======  =====================================================  =========================
name    meaning                                                 valid range
======  =====================================================  =========================
nu      mean volume fraction nu_bar                             1e-6 <= nu < packing limit
e       particle restitution coefficient                        0 < e <= 1
H       gap in particle diameters, H = H~ / d_p                 1e-50 <= H <= 1e50
G       gravity, G = Fr^-2 (Fr = U_w / sqrt(g d_p))             0 <= G <= 1e100 (Fr >= 1e-50, inf allowed)
phi_w   specularity phi' of Johnson-Jackson walls               0 <= phi_w <= 1
ew      particle-wall restitution e_w                           0 < ew <= 1
num     nu_m of chi (and nu_max of the wall terms)              0 < num < 1
======  =====================================================  =========================

The packing limit is ``num`` for the ``jj`` and ``ls`` radial distributions and 1 for ``cs``
(closures.packing_limit).  Users may give ``Fr`` instead of ``G``; it is converted.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from problems.couette.closures import CHI_MODELS, packing_limit

#: The largest gravity G = Fr^-2 (smallest Froude number FR_MIN): the scaled balances carry H^3 G, and
#: `contin trace gravity -s Fr=1e-150` (G = 1e300) ended in a bare OverflowError (qa19).  Fr < 1 is
#: already a wall speed below the free-fall speed over one particle diameter.
G_MAX = 1e100
FR_MIN = G_MAX ** -0.5

#: The most dilute mean volume fraction: uniform shear's temperature T0 = f2/f5 grows as nu^-2 and the
#: balances carry powers of it (`-s nu=1e-300`: non-finite states; 1e-50: an index error; 1e-100: an
#: OverflowError, qa19); at nu = 1e-6 the mean free path, ~ d_p / (6 sqrt(2) nu), is already 1e5
#: particle diameters, far outside a continuum model.
NU_MIN = 1e-6
#: The gap's range: the scaled balances carry 1/H^2 and H^3 G (G <= G_MAX).
H_RANGE = (1e-50, 1e50)

PARAMETER_NAMES: tuple[str, ...] = ("nu", "e", "H", "G", "phi_w", "ew", "num")

DEFAULTS: dict[str, float] = {
    "nu": 0.3,
    "e": 0.8,
    "H": 20.0,
    "G": 0.0,
    "phi_w": 0.5,
    "ew": 0.9,
    "num": 0.65,
}


def froude_to_gravity(fr: float) -> float:
    """G = Fr^-2 (G = 0 for Fr = inf).

    Raises
    ------
    ValueError
        If Fr is not a positive number.
    """
    fr = _as_float("Fr", fr)
    if not fr > 0:
        raise ValueError(f"parameter Fr = {fr} is out of range; the Froude number must be > 0 (inf allowed)")
    if fr < FR_MIN:
        raise ValueError(f"parameter Fr = {fr:g} is out of range; it must satisfy Fr >= {FR_MIN:g} "
                         f"(G = Fr^-2 <= {G_MAX:g}; inf allowed)")
    if math.isinf(fr):
        return 0.0
    # Fr**2 overflows above ~1.3e154 (`-s Fr=1e300` ended 'OverflowError: Numerical result out of
    # range'); there G = Fr^-2 rounds to 0 or a subnormal, which (1/Fr)^2 gives
    return 1.0 / fr**2 if fr < 1e150 else (1.0 / fr) ** 2


def gravity_to_froude(g: float) -> float:
    """Fr = G^-1/2 (inf for G = 0)."""
    return math.inf if g == 0 else 1.0 / math.sqrt(g)


def _as_float(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"parameter {name} = {value!r} is not a number") from None
    if math.isnan(v):
        raise ValueError(f"parameter {name} is NaN")
    return v


def build_params(values: Mapping[str, Any] | None = None, *, chi: str = "jj") -> dict[str, float]:
    """Full parameter dict from user values merged over :data:`DEFAULTS`, validated.

    Parameters
    ----------
    values : mapping of name -> value (numbers or numeric strings such as ``"inf"``).
        Accepts every name in :data:`PARAMETER_NAMES` and ``Fr`` (converted to G = Fr^-2;
        ``Fr`` and ``G`` together must agree).
    chi : radial distribution model ('jj', 'cs', 'ls'); sets the packing limit of ``nu``.

    Returns
    -------
    dict with exactly the keys of :data:`PARAMETER_NAMES`, float values.

    Raises
    ------
    ValueError
        One sentence naming the parameter and its allowed range, or the unknown name.
    """
    p = dict(DEFAULTS)
    values = dict(values or {})
    fr = values.pop("Fr", None)
    for name, value in values.items():
        if name not in DEFAULTS:
            raise ValueError(
                f"unknown parameter {name!r}; known parameters are {', '.join(PARAMETER_NAMES)} and Fr"
            )
        p[name] = _as_float(name, value)
    if fr is not None:
        g = froude_to_gravity(fr)
        if "G" in values and not math.isclose(p["G"], g, rel_tol=1e-12, abs_tol=0.0):
            raise ValueError(f"parameters Fr = {fr} and G = {p['G']} disagree; give only one of them (G = Fr^-2)")
        p["G"] = g
    validate_params(p, chi=chi)
    return p


def validate_params(p: Mapping[str, Any], *, chi: str = "jj") -> None:
    """Raise ``ValueError`` (one sentence) unless ``p`` is a complete, physical parameter set."""
    if chi not in CHI_MODELS:
        raise ValueError(f"unknown radial distribution chi = {chi!r}; choose one of {', '.join(CHI_MODELS)}")
    for name in PARAMETER_NAMES:
        if name not in p:
            raise ValueError(f"parameter {name} is missing")
    for name in p:
        if name not in DEFAULTS:
            raise ValueError(
                f"unknown parameter {name!r}; known parameters are {', '.join(PARAMETER_NAMES)}"
            )
    v = {name: _as_float(name, p[name]) for name in PARAMETER_NAMES}
    if not 0.0 < v["num"] < 1.0:
        raise ValueError(f"parameter num = {v['num']} is out of range; nu_m must satisfy 0 < num < 1")
    limit = packing_limit(chi, v["num"])
    checks = (
        ("nu", 0.0 < v["nu"] < limit, f"0 < nu < {limit:g} (packing limit of chi = {chi})"),
        ("nu", NU_MIN <= v["nu"], f"{NU_MIN:g} <= nu < {limit:g} (below {NU_MIN:g} the flow is far too dilute "
                                  f"for this continuum model)"),
        ("e", 0.0 < v["e"] <= 1.0, "0 < e <= 1"),
        ("H", 0.0 < v["H"] < math.inf, "0 < H < inf"),
        ("H", H_RANGE[0] <= v["H"] <= H_RANGE[1], f"{H_RANGE[0]:g} <= H <= {H_RANGE[1]:g} (gap in particle diameters)"),
        ("G", 0.0 <= v["G"] < math.inf, "0 <= G < inf (G = Fr^-2, Fr > 0)"),
        ("G", v["G"] <= G_MAX, f"0 <= G <= {G_MAX:g} (G = Fr^-2, Fr >= {FR_MIN:g})"),
        ("phi_w", 0.0 <= v["phi_w"] <= 1.0, "0 <= phi_w <= 1"),
        ("ew", 0.0 < v["ew"] <= 1.0, "0 < ew <= 1"),
    )
    for name, ok, allowed in checks:
        if not ok:
            raise ValueError(f"parameter {name} = {v[name]} is out of range; it must satisfy {allowed}")
