"""Fit the universal unfolding of the pitchfork to computed branches.

Near a pitchfork at lambda_c, equilibria of every branch traced at small imperfection mu
satisfy, to leading order (A13 slides; Golubitsky & Schaeffer 1985, ch. III),

    delta^3 - B delta + alpha + beta delta^2 = 0,
    B = b1 (lambda - lambda_c),  alpha = alpha1 mu,  beta = beta1 mu,

with delta = Phi - Phi_c the order-parameter deviation.  The relation is linear in
(b1, b1 lambda_c, alpha1, beta1), so ordinary least squares over all branch points inside
a window |delta| <= delta_max, |lambda - lambda_c| <= window gives the coefficients and,
from the residual variance, their standard errors.  The same coefficients follow from
:func:`contin.normalform.pitchfork_normal_form` as b1 = -a1/a3, alpha1 = a0/a3,
beta1 = a2/a3; agreement of the two is a check on both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


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
    """Fit delta^3 - b1 (lam - lam_c) delta + alpha1 mu + beta1 mu delta^2 = 0.

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
