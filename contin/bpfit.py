"""The normal form of a stored pitchfork, fitted to the branches of a run file around it.

``contin fit FILE.h5 --at BP1`` (and :func:`fit_at_bp`): the file holds a branch through the
pitchfork ``BP1`` in the parameter lambda and branches near it at several fixed values of an
imperfection parameter mu (mu = 0 allowed; every branch with both columns, constant mu, and the
order-parameter observable is used).  The solution set is fitted as the graph
lambda - lambda_c = sum c[k, j] mu^j delta^(2k - 3j) (:func:`contin.fit.fit_graph`), which gives
the canonical unfolding (Golubitsky & Schaeffer 1985, ch. III)

    delta^3 - B(lambda) delta + alpha(mu) + beta(mu) delta^2 + q5 delta^5 = 0,
    B = b1 (lambda - lambda_c) + b2 (lambda - lambda_c)^2,  alpha = alpha1 mu,  beta = beta1 mu,

with delta = (observable) - (its value at the BP); the observable must be odd under the
symmetry that maps mu to -mu (else even terms of lower weight spoil the fit).  With the
problem rebuilt (the scene's ``problem_factory``) the same coefficients come from the
Lyapunov-Schmidt reduction at the BP (:func:`contin.normalform.pitchfork_unfolding`) in the
same coordinate: the observable's gradient l (central differences; exact for a linear
observable, and the observable is checked to be linear), at two stencil amplitudes (their
difference is the error estimate).  The file's folds at mu != 0 are compared with the
unfolding's prediction lambda_LP(mu), and the hysteresis point alpha = beta^3/27 is located.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.fit import fit_graph, fit_imperfections

#: canonical coefficients compared between the fit and Lyapunov-Schmidt
COMPARED = ("b1", "alpha1", "beta1", "b2", "q5")


def branches_for_fit(branches: Sequence[Branch], parameter: str, imperfection: str, delta: str) -> list[Branch]:
    """Branches with both columns, constant ``imperfection`` and the ``delta`` observable."""
    return [b for b in branches if parameter in b.params and imperfection in b.params and len(b) > 2
            and np.ptp(b.params[imperfection]) == 0 and delta in b.observables]


def guess_imperfection(branches: Sequence[Branch], parameter: str) -> str:
    """The one parameter that is constant along every branch but differs between branches."""
    names = set.intersection(*(set(b.params) for b in branches)) - {parameter} if branches else set()
    hits = sorted(n for n in names
                  if all(np.ptp(b.params[n]) == 0 for b in branches if len(b))
                  and len({float(b.params[n][0]) for b in branches if len(b)}) > 1)
    if len(hits) != 1:
        raise ValueError("cannot tell the imperfection parameter from the file "
                         f"({'candidates: ' + ', '.join(hits) if hits else 'no parameter is constant per branch and varies between branches'}); "
                         "give it with --imperfection NAME")
    return hits[0]


def observable_gradient(problem: Any, u: np.ndarray, p: Mapping[str, float], name: str,
                        step: float = 1e-6) -> np.ndarray:
    """d observable / du by central differences, and a check that the observable is linear.

    Raises ValueError if observable(u + v) - observable(u) differs from l.v by more than 1e-6
    relative for a deterministic test vector v (Lyapunov-Schmidt needs a linear coordinate).
    """
    def f(x: np.ndarray) -> float:
        return float(problem.observables(x, p)[name])

    u = np.asarray(u, float)
    scale = max(1.0, float(np.max(np.abs(u))))
    h = step * scale
    ell = np.empty(u.size)
    for j in range(u.size):
        e = np.zeros(u.size)
        e[j] = h
        ell[j] = (f(u + e) - f(u - e)) / (2 * h)
    v = 1e-2 * scale * np.cos(np.arange(u.size) + 0.5)
    lhs, rhs = f(u + v) - f(u), float(ell @ v)
    if abs(lhs - rhs) > 1e-6 * max(abs(lhs), abs(rhs), 1e-12 * scale):
        raise ValueError(f"observable {name!r} is not linear in the state ({lhs:.6g} vs {rhs:.6g}); "
                         "the Lyapunov-Schmidt comparison needs a linear coordinate")
    return ell


def fit_at_bp(
    branches: Sequence[Branch],
    bp: SpecialPoint,
    parameter: str,
    *,
    imperfection: str,
    delta: str,
    problem: Any = None,
    delta_at_bp: float = 0.0,
    window: float = 0.3,
    delta_max: float = 0.05,
    delta_min: float = 3e-3,
    order: int = 5,
) -> dict[str, Any]:
    """The fit, its errors, the comparison with Lyapunov-Schmidt (when ``problem`` is given),
    folds and hysteresis, as one JSON-able document (module docstring)."""
    from contin.normalform import pitchfork_unfolding

    if bp.type != "BP":
        raise ValueError(f"{bp.name} is a {bp.type}, not a branch point")
    use = branches_for_fit(branches, parameter, imperfection, delta)
    mu0 = float(bp.params[imperfection])
    if not any(float(b.params[imperfection][0]) != mu0 for b in use):
        raise ValueError(f"no branches at a constant {imperfection} != {mu0:g} with a {parameter} column and the "
                         f"observable {delta!r}")
    lc = float(bp.params[parameter])
    lam = [np.asarray(b.params[parameter]) - lc for b in use]
    dl = [np.asarray(b.observables[delta]) - delta_at_bp for b in use]
    mu = [float(b.params[imperfection][0]) - mu0 for b in use]
    fit = fit_graph(lam, dl, mu, critical_value=lc, order=order, window=window, delta_max=delta_max,
                    delta_min=delta_min)
    per_mu = fit_imperfections(lam, dl, mu, fit, window=window, delta_max=delta_max, delta_min=delta_min)
    fu, ferr = fit.unfolding, fit.errors()
    doc: dict[str, Any] = {
        "point": bp.name, "parameter": parameter, "imperfection": imperfection, "delta": delta,
        "critical_value": lc, "imperfection_at_bp": mu0, "delta_at_bp": delta_at_bp,
        "imperfection_values": sorted({m + mu0 for m in mu}), "branches": [b.id for b in use],
        "B": {"b1": fu.b1, "b1_err": ferr["b1"], "b2": fu.b2, "b2_err": ferr["b2"],
              "formula": "B = b1 (lambda - lambda_c) + b2 (lambda - lambda_c)^2"},
        "alpha": [{"mu": r.mu, "alpha": r.alpha, "alpha_err": r.alpha_err, "n_points": r.n_points} for r in per_mu],
        "beta": [{"mu": r.mu, "beta": r.beta, "beta_err": r.beta_err, "n_points": r.n_points} for r in per_mu],
        "fit": fit.as_dict(),
        "convention": ("delta = observable - its value at the BP, mu = imperfection - its value at the BP; "
                       "delta^3 - B delta + alpha1 mu + beta1 mu delta^2 + q5 delta^5 = 0"),
    }
    ref = fu
    if problem is not None:
        ell = observable_gradient(problem, np.asarray(bp.state, float), bp.params, delta)
        ls = pitchfork_unfolding(problem, bp.state, dict(bp.params), parameter, imperfection, ell,
                                 amplitude=1e-2, tol=1e-11, polish=1)
        ls_fine = pitchfork_unfolding(problem, bp.state, dict(bp.params), parameter, imperfection, ell,
                                      amplitude=5e-3, tol=1e-11, polish=1)
        lu, lf = ls.unfolding, ls_fine.unfolding
        ref = lf
        coeffs = {}
        for k in COMPARED:
            f_v, l_v = getattr(fu, k), getattr(lf, k)
            l_err = abs(l_v - getattr(lu, k))
            rel = abs(f_v - l_v) / abs(l_v) if l_v != 0 else float("inf") if f_v != 0 else 0.0
            coeffs[k] = {"fit": f_v, "fit_err": ferr[k], "fit_stat_err": fu.errors()[k],
                         "fit_truncation": fit.systematic[k], "lyapunov_schmidt": l_v, "lyapunov_schmidt_err": l_err,
                         "relative_difference": rel, "agree_5pct": bool(rel <= 0.05),
                         "within_errors": bool(abs(f_v - l_v) <= 3 * (ferr[k] + l_err))}
        doc["coefficients"] = coeffs
        doc["lyapunov_schmidt"] = {"unfolding": lf.as_dict(), "raw": ls_fine.coefficients,
                                   "stencil_residual": ls_fine.residual, "amplitudes": [ls.amplitude, ls_fine.amplitude]}
    else:
        doc["coefficients"] = {k: {"fit": getattr(fu, k), "fit_err": ferr[k]} for k in COMPARED}
    folds = []
    for b in use:
        for lp in b.fold_points:
            m = float(lp.params[imperfection]) - mu0
            if not lp.converged or m == 0:
                continue
            pred = fu.fold(m)[0]
            dh = float(lp.params[parameter]) - lc
            folds.append({"branch": b.id, "mu": m, "lambda_minus_lc": dh, "predicted": pred,
                          "predicted_leading": fu.fold(m, leading=True)[0], "rel_error": pred / dh - 1})
    doc["folds"] = folds
    hyst = ref.hysteresis() if ref.beta1 != 0 else None
    if ref.beta1 != 0:
        m_h = float(np.sqrt(abs(27 * ref.alpha1 / ref.beta1**3)))
        doc["hysteresis"] = {
            "exists": hyst is not None, "mu": m_h, "delta": abs(ref.beta1 * m_h / 3),
            "perturbative": bool(abs(ref.beta1 * m_h / 3) <= delta_max),
            "note": ("alpha1 beta1 < 0: the line (alpha1 mu, beta1 mu) meets alpha = beta^3/27 only at mu = 0; "
                     "mu and delta are where it would if beta1 changed sign" if hyst is None
                     else "hysteresis point of the cubic truncation")}
    else:
        doc["hysteresis"] = {"exists": False, "mu": None, "delta": None, "perturbative": False,
                             "note": "beta1 = 0: no hysteresis point"}
    return doc
