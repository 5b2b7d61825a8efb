"""Fit the universal unfolding of the pitchfork to computed branches.

Near a pitchfork at lambda_c, equilibria of every branch traced at small imperfection mu
satisfy (A13 slides; Golubitsky & Schaeffer 1985, ch. III)

    delta^3 - B delta + alpha + beta delta^2 = 0,
    B = b1 (lambda - lambda_c),  alpha = alpha1 mu,  beta = beta1 mu,

with delta the order-parameter deviation.  Two fits:

:func:`fit_graph` (use this one) fits the solution set as the graph
lambda - lambda_c = sum c[k, j] mu^j delta^(2k - 3j) (weights 2k with delta ~ eps,
lambda ~ eps^2, mu ~ eps^3) and returns the canonical unfolding
(:class:`contin.normalform.Unfolding`: B = b1 l + b2 l^2, alpha = alpha1 mu, beta = beta1 mu,
plus q5 delta^5).  beta mu delta^2 is a weight-5 term, the same order as mu l, l delta^3,
l^2 delta and delta^5; an implicit polynomial fit cannot separate them (the multipliers of
contact equivalence move weight between them), while the graph is unique, so every
coefficient is identifiable.  delta must be odd under the symmetry that maps mu to -mu,
else even terms of LOWER weight appear.  :func:`fit_imperfections` gives alpha(mu), beta(mu)
at each mu separately.  Compare with :func:`contin.normalform.pitchfork_unfolding` in the
same coordinate.

:func:`fit_unfolding` is the leading-order implicit fit (linear in b1, b1 lambda_c, alpha1,
beta1): b1 and alpha1 to O(eps^2), but its beta1 is not identifiable (see above) and is
not comparable with a Lyapunov-Schmidt value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from contin.normalform import GRAPH_TERMS, Unfolding


@dataclass(frozen=True)
class UnfoldingFit:
    """Least-squares unfolding coefficients with one-sigma standard errors."""

    b1: float
    critical_value: float
    alpha1: float
    beta1: float
    b1_err: float
    critical_value_err: float
    alpha1_err: float
    beta1_err: float
    n_points: int
    rms_residual: float

    def as_dict(self) -> dict[str, float | int]:
        return dict(self.__dict__)


def fit_unfolding(
    lam: Sequence[NDArray[np.float64]],
    delta: Sequence[NDArray[np.float64]],
    mu: Sequence[float],
    *,
    critical_value: float | None = None,
    delta_max: float = np.inf,
    window: float = np.inf,
    center: float | None = None,
) -> UnfoldingFit:
    """Fit delta^3 - b1 (lam - lam_c) delta + alpha1 mu + beta1 mu delta^2 = 0 (leading order;
    beta1 is not identifiable from this form -- use :func:`fit_graph`).

    Parameters
    ----------
    lam, delta : per branch, the bifurcation parameter and the order-parameter deviation
    mu : per branch, the imperfection parameter (e.g. G = Fr^-2)
    critical_value : lambda_c if known (then it is not fitted)
    delta_max, window : keep points with |delta| <= delta_max and |lam - center| <= window
    center : centre of the window (default: critical_value, else the mean of lam)
    """
    rows, rhs = [], []
    c = critical_value if center is None else center
    if c is None:
        c = float(np.mean(np.concatenate([np.asarray(v) for v in lam])))
    for lam_b, d_b, m in zip(lam, delta, mu):
        lam_b = np.asarray(lam_b, float)
        d_b = np.asarray(d_b, float)
        keep = (np.abs(d_b) <= delta_max) & (np.abs(lam_b - c) <= window)
        lam_b, d_b = lam_b[keep], d_b[keep]
        if critical_value is None:
            # unknowns: b1, b1*lam_c, alpha1, beta1
            rows.append(np.column_stack([lam_b * d_b, -d_b, -m * np.ones_like(d_b), -m * d_b**2]))
            rhs.append(d_b**3)
        else:
            rows.append(np.column_stack([(lam_b - critical_value) * d_b, -m * np.ones_like(d_b), -m * d_b**2]))
            rhs.append(d_b**3)
    a = np.vstack(rows)
    y = np.concatenate(rhs)
    if a.shape[0] <= a.shape[1]:
        raise ValueError(f"only {a.shape[0]} points inside the fit window; widen delta_max or window")
    # Columns differ by many orders of magnitude (mu ~ 1e-8 against delta ~ 1e-2): solve and
    # form the covariance in unit-norm columns, where (A^T A)^-1 is well conditioned, and scale
    # back; a pseudo-inverse of the raw normal matrix truncates and reports tiny errors.
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    q, r = np.linalg.qr(a / scale)
    coef = np.linalg.solve(r, q.T @ y) / scale
    res = y - a @ coef
    dof = a.shape[0] - a.shape[1]
    sigma2 = float(res @ res) / dof
    r_inv = np.linalg.inv(r)
    cov = sigma2 * (r_inv @ r_inv.T) / np.outer(scale, scale)
    err = np.sqrt(np.abs(np.diag(cov)))
    if critical_value is None:
        b1, b1lc, alpha1, beta1 = coef
        lam_c = b1lc / b1
        # first-order error propagation for lam_c = (b1 lam_c) / b1
        grad = np.array([-b1lc / b1**2, 1.0 / b1, 0.0, 0.0])
        lam_c_err = float(np.sqrt(grad @ cov @ grad))
        b1_err, alpha1_err, beta1_err = err[0], err[2], err[3]
    else:
        b1, alpha1, beta1 = coef
        lam_c, lam_c_err = critical_value, 0.0
        b1_err, alpha1_err, beta1_err = err
    return UnfoldingFit(
        b1=float(b1),
        critical_value=float(lam_c),
        alpha1=float(alpha1),
        beta1=float(beta1),
        b1_err=float(b1_err),
        critical_value_err=lam_c_err,
        alpha1_err=float(alpha1_err),
        beta1_err=float(beta1_err),
        n_points=int(a.shape[0]),
        rms_residual=float(np.sqrt(np.mean(res**2))),
    )


# ----------------------------------------------------------------------------- graph fit (next order)
@dataclass(frozen=True)
class GraphFit:
    """Least-squares fit of the solution set as a graph lambda - lambda_c = sum c[k, j] mu^j delta^(2k-3j).

    coefficients : c[(k, j)] for k = 1..order, j = 0..k (weight 2k; delta ~ eps, lambda ~ eps^2,
        mu ~ eps^3)
    cov : their covariance, sigma^2 (A^T A)^-1 from the residual variance sigma^2 (full rank;
        no singular value is dropped -- ``condition`` is the 2-norm condition number of the
        column-scaled design matrix, so a near-degenerate design is visible)
    unfolding : the canonical unfolding (contin.normalform.Unfolding) from the weight-2 and
        weight-4 coefficients, with ``cov`` propagated
    systematic : per canonical coefficient, the larger of |value(order) - value(order -+ 1)|:
        the change when the highest weight is dropped or the next one added, an estimate of the
        truncation error that the residual-based covariance does not contain (the residuals are
        truncation, not noise).  One neighbour alone is not enough: the sequence in the order
        is not monotone, and two neighbouring orders can agree by accident.
    """

    coefficients: dict[tuple[int, int], float]
    cov: NDArray[np.float64]
    order: int
    critical_value: float
    n_points: int
    rms_residual: float
    condition: float
    unfolding: Unfolding
    systematic: dict[str, float]

    def errors(self) -> dict[str, float]:
        """Total one-sigma error per canonical coefficient: sqrt(statistical^2 + systematic^2)."""
        stat = self.unfolding.errors()
        return {k: float(np.hypot(stat[k], self.systematic.get(k, 0.0))) for k in stat}

    def as_dict(self) -> dict[str, object]:
        terms = list(self.coefficients)
        return {
            "order": self.order, "critical_value": self.critical_value, "n_points": self.n_points,
            "rms_residual": self.rms_residual, "condition": self.condition,
            "graph": {f"c{k}{j}": v for (k, j), v in self.coefficients.items()},
            "graph_errors": {f"c{k}{j}": float(np.sqrt(self.cov[i, i])) for i, (k, j) in enumerate(terms)},
            "unfolding": self.unfolding.as_dict(),
            "systematic": dict(self.systematic),
            "errors": self.errors(),
        }


def graph_terms(order: int) -> list[tuple[int, int]]:
    """(k, j) of the monomials mu^j delta^(2k - 3j), k = 1..order, j = 0..k."""
    return [(k, j) for k in range(1, order + 1) for j in range(k + 1)]


def _select(lam, delta, mu, delta_min, delta_max, window):
    L, D, M = [], [], []
    for lb, db, m in zip(lam, delta, mu):
        lb, db = np.asarray(lb, float), np.asarray(db, float)
        keep = (np.abs(db) >= delta_min) & (np.abs(db) <= delta_max) & (np.abs(lb) <= window)
        L.append(lb[keep])
        D.append(db[keep])
        M.append(np.full(int(keep.sum()), float(m)))
    return np.concatenate(L), np.concatenate(D), np.concatenate(M)


def _lstsq(a: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray, float]:
    """Coefficients, covariance, residuals and condition number of min |a c - y| (QR in
    unit-norm columns; every column kept)."""
    if a.shape[0] <= a.shape[1]:
        raise ValueError(f"only {a.shape[0]} points inside the fit window for {a.shape[1]} coefficients; "
                         "widen delta_max or window")
    scale = np.linalg.norm(a, axis=0)
    if np.any(scale == 0):
        raise ValueError("a fit term vanishes on every point (e.g. only mu = 0 data for a mu term)")
    q, r = np.linalg.qr(a / scale)
    cond = float(np.linalg.cond(r))
    if not cond < 1e12:
        raise ValueError(f"the fit design is singular (condition number {cond:.1e}); add branches at other mu")
    coef = np.linalg.solve(r, q.T @ y) / scale
    res = y - a @ coef
    sigma2 = float(res @ res) / (a.shape[0] - a.shape[1])
    r_inv = np.linalg.inv(r)
    cov = sigma2 * (r_inv @ r_inv.T) / np.outer(scale, scale)
    return coef, cov, res, cond


def _graph_lstsq(lam, delta, mu, order):
    terms = graph_terms(order)
    a = np.column_stack([mu**j * delta ** (2 * k - 3 * j) for k, j in terms])
    coef, cov, res, cond = _lstsq(a, lam)
    return terms, coef, cov, res, cond


def fit_graph(
    lam: Sequence[NDArray[np.float64]],
    delta: Sequence[NDArray[np.float64]],
    mu: Sequence[float],
    *,
    critical_value: float,
    order: int = 4,
    delta_min: float = 3e-3,
    delta_max: float = 0.05,
    window: float = 0.3,
) -> GraphFit:
    """Fit the pitchfork unfolding to next order as the graph of its solution set.

    Near a Z2 pitchfork unfolded by mu (odd under the symmetry, as is the order parameter
    deviation delta), every solution satisfies, with l = lambda - lambda_c,

        l = c10 delta^2 + c11 mu/delta + c20 delta^4 + c21 mu delta + c22 mu^2/delta^2 + (weight 6, ...),

    the Laurent expansion of the unique graph l(delta, mu) of delta^3 - B(l) delta + alpha +
    beta delta^2 + ... = 0 (contin.normalform.Unfolding).  Unlike an implicit fit of the
    unfolding polynomial (:func:`fit_unfolding`), the graph has no multiplier freedom, so
    every coefficient is identifiable; terms up to weight 2 ``order`` are fitted (the
    weights above 4 absorb the truncation) and the canonical (b1, b2, alpha1, beta1, q5)
    follow from the weight-2 and -4 ones.  Points with |delta| < delta_min (the G = 0
    symmetric branch, where l is undetermined), |delta| > delta_max or |l| > window are
    left out; branches at mu = 0 are welcome (they fix the mu-independent terms).

    ``lam`` are the values of lambda - lambda_c (not lambda).
    """
    if order < 2:
        raise ValueError(f"order must be >= 2 (weight 4 holds beta), got {order}")
    L, D, M = _select(lam, delta, mu, delta_min, delta_max, window)
    if not np.any(M != 0):
        raise ValueError("no branch with mu != 0 inside the window: alpha and beta cannot be fitted")

    def canonical(order_: int):
        terms, coef, cov, res, cond = _graph_lstsq(L, D, M, order_)
        c = dict(zip(terms, coef))
        idx = [terms.index(t) for t in GRAPH_TERMS]
        unf = Unfolding.from_graph(critical_value, c, cov[np.ix_(idx, idx)])
        return c, cov, res, cond, unf

    c, cov, res, cond, unf = canonical(order)
    neighbours = [canonical(order - 1)[4]]
    try:
        neighbours.append(canonical(order + 1)[4])
    except ValueError:  # too few points or a singular design one order up: the lower one only
        pass
    systematic = {k: max(abs(getattr(unf, k) - getattr(o, k)) for o in neighbours) for k in unf.NAMES}
    return GraphFit(coefficients={k: float(v) for k, v in c.items()}, cov=cov, order=order,
                    critical_value=float(critical_value), n_points=int(L.size),
                    rms_residual=float(np.sqrt(np.mean(res**2))), condition=cond, unfolding=unf,
                    systematic=systematic)


@dataclass(frozen=True)
class Imperfection:
    """alpha(mu), beta(mu) of the canonical unfolding at one imperfection mu, one-sigma errors."""

    mu: float
    alpha: float
    alpha_err: float
    beta: float
    beta_err: float
    n_points: int

    def as_dict(self) -> dict[str, float | int]:
        return dict(self.__dict__)


def fit_imperfections(
    lam: Sequence[NDArray[np.float64]],
    delta: Sequence[NDArray[np.float64]],
    mu: Sequence[float],
    base: GraphFit,
    *,
    delta_min: float = 3e-3,
    delta_max: float = 0.05,
    window: float = 0.3,
    expansion: float = 0.1,
    min_points: int = 12,
) -> list[Imperfection]:
    """alpha(mu) and beta(mu) separately at every distinct mu, without assuming they are linear.

    At fixed mu the graph is l - sum_k c[k, 0] delta^(2k) (mu-independent part, from ``base``)
    = A/delta + Bq delta + C/delta^2 + D delta^3 + E + F/delta^3 (the powers 2k - 3j, j >= 1,
    of weights up to 6); then alpha(mu) = b1 A and beta(mu) = b1 Bq + 2 b2 alpha(mu)/b1^2 with
    b1, b2 from ``base`` (Unfolding: c11 = alpha/b1, c21 = beta/b1 - 2 b2 alpha/b1^3).

    The successive mu-powers of the graph grow like (c22 mu)/(c11 delta): only points with
    |c22 mu / (c11 delta)| <= ``expansion`` are used (at larger mu/delta the truncated powers
    dominate and the per-mu fit is biased while its residual error looks small).  A mu with
    fewer than ``min_points`` such points is left out of the result.  Errors: the per-mu
    covariance and the errors of b1, b2 (first-order propagation), combined with the change
    when the weight-6 powers are dropped (truncation estimate).  At mu = 0 both must vanish;
    alpha(-mu) = -alpha(mu), beta(-mu) = -beta(mu) when the problem has the symmetry.
    """
    L, D, M = _select(lam, delta, mu, delta_min, delta_max, window)
    unf = base.unfolding
    b1, b2 = unf.b1, unf.b2
    e = base.errors()
    ratio = abs(base.coefficients[(2, 2)] / base.coefficients[(1, 1)])
    shared = sum(base.coefficients[(k, 0)] * D ** (2 * k) for k in range(1, base.order + 1))
    out = []
    for m in sorted(set(M.tolist())):
        sel = (M == m) & (ratio * abs(m) <= expansion * np.abs(D))
        if sel.sum() < min_points:
            continue
        d, y = D[sel], (L - shared)[sel]
        values = []
        for powers in ((-1, 1, -2, 3, 0, -3), (-1, 1, -2, 3, 0, -3, 5, 2, -4)):
            coef, cov, _, _ = _lstsq(np.column_stack([d**p for p in powers]), y)
            A, Bq = coef[0], coef[1]
            alpha = b1 * A
            beta = b1 * Bq + 2 * b2 * A / b1
            values.append((alpha, beta, A, Bq, cov[:2, :2]))
        alpha, beta, A, Bq, cAB = values[0]
        # alpha = b1 A, beta = b1 Bq + 2 b2 A / b1: gradients in (A, Bq), then b1 and b2
        ga = np.array([b1, 0.0])
        gb = np.array([2 * b2 / b1, b1])
        var_a = ga @ cAB @ ga + (A * e["b1"]) ** 2 + (alpha - values[1][0]) ** 2
        var_b = (gb @ cAB @ gb + ((Bq - 2 * b2 * A / b1**2) * e["b1"]) ** 2 + (2 * A / b1 * e["b2"]) ** 2
                 + (beta - values[1][1]) ** 2)
        out.append(Imperfection(mu=float(m), alpha=float(alpha), alpha_err=float(np.sqrt(var_a)), beta=float(beta),
                                beta_err=float(np.sqrt(var_b)), n_points=int(sel.sum())))
    return out
