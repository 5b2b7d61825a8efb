"""Normal form of a simple branch point by numerical Lyapunov-Schmidt reduction.

At a simple singular point (u_c, lambda_c) of F(u, lambda, mu) = 0 with right and left null
vectors phi, psi of J = F_u, every nearby solution is u = u_c + x phi + w with phi.w = 0, and
(w, g) solve the bordered system (Golubitsky & Schaeffer 1985, ch. I.3; Kuznetsov,
*Elements of Applied Bifurcation Theory*, 3rd ed., sec. 10.2)

    F(u_c + x phi + w, lambda, mu) - g psi = 0,      phi . w = 0.

The reduced bifurcation function g(x, lambda, mu) vanishes exactly on solutions.  Its Taylor
coefficients at the origin are the normal-form coefficients.  We evaluate g on a small
stencil (one bordered Newton solve per stencil point) and take central differences:

    g ~ g_lx (lambda - lambda_c) x + g_xxx x^3 / 6 + g_mu mu + g_xxmu mu x^2 / 2 + ...

Re-expressed in the order-parameter deviation delta = Phi - Phi_c ~ kappa x with kappa the
derivative of Phi along phi, the equilibria satisfy (after division by the cubic coefficient)

    delta^3 - B delta + alpha + beta delta^2 = 0,
    B = -(a1/a3)(lambda - lambda_c),  alpha = (a0/a3) mu,  beta = (a2/a3) mu,

with a3 = g_xxx/(6 kappa^3), a1 = g_lx/kappa, a0 = g_mu, a2 = g_xxmu/(2 kappa^2).  This is
the unfolding of the pitchfork x^3 - lambda x + alpha + beta x^2 (A13 slides; G&S ch. III).
The branch bends as lambda - lambda_c ~ a delta^2 with a = -a3/a1: the pitchfork is
supercritical when a > 0 and subcritical when a < 0, counting lambda increasing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from contin.problem import Array


@dataclass(frozen=True)
class NullVectors:
    """Right (phi) and left (psi) null vectors of a singular Jacobian, |phi| = |psi| = 1."""

    phi: Array
    psi: Array
    residual: float  # max(|J phi|, |J^T psi|): small when J really is singular


def null_vectors(jacobian: sp.spmatrix, *, seed: int = 0) -> NullVectors:
    """Null vectors of a (numerically) singular sparse matrix by bordering.

    Solves [[J, b], [c^T, 0]] [phi; s] = [0; 1] and its transpose with random b, c
    (Govaerts, *Numerical Methods for Bifurcations of Dynamical Equilibria*, SIAM 2000,
    sec. 3.2); the bordered matrix is regular at a simple singular point.
    """
    n = jacobian.shape[0]
    rng = np.random.default_rng(seed)
    b = rng.standard_normal(n)
    c = rng.standard_normal(n)
    border = sp.bmat([[sp.csc_matrix(jacobian), b[:, None]], [c[None, :], None]], format="csc")
    lu = spla.splu(border)
    rhs = np.zeros(n + 1)
    rhs[-1] = 1.0
    phi = lu.solve(rhs)[:n]
    psi = lu.solve(rhs, trans="T")[:n]
    phi /= np.linalg.norm(phi)
    psi /= np.linalg.norm(psi)
    res = max(np.abs(jacobian @ phi).max(), np.abs(jacobian.T @ psi).max())
    return NullVectors(phi, psi, float(res))


@dataclass(frozen=True)
class ReducedFunction:
    """g(x, lambda, mu) of the Lyapunov-Schmidt reduction about a singular point."""

    problem: object
    state: Array
    params: Mapping[str, float]
    nulls: NullVectors
    tol: float = 1e-13
    max_iterations: int = 20
    # Extra Newton steps once the residual test passes: with tol set at a rounding floor
    # (eps ||J|| ||u||, often far above the residual actually reachable) the first iterate
    # that passes can still be far less accurate than the quadratic convergence allows.
    polish: int = 0

    def __call__(self, x: float, shifts: Mapping[str, float]) -> float:
        """Value of g at amplitude x and parameters params + shifts."""
        p = dict(self.params)
        for name, d in shifts.items():
            p[name] = p[name] + d
        phi, psi = self.nulls.phi, self.nulls.psi
        n = phi.size
        w = np.zeros(n)
        g = 0.0
        extra = self.polish
        for _ in range(self.max_iterations + self.polish):
            u = self.state + x * phi + w
            res = np.concatenate([self.problem.residual(u, p) - g * psi, [phi @ w]])
            if np.max(np.abs(res)) < self.tol:
                if extra == 0:
                    break
                extra -= 1
            jac = sp.bmat(
                [[sp.csc_matrix(self.problem.jacobian(u, p)), -psi[:, None]], [phi[None, :], None]], format="csc"
            )
            step = spla.spsolve(jac, -res)
            w += step[:n]
            g += step[n]
        else:
            raise RuntimeError("Lyapunov-Schmidt corrector did not converge; use a smaller stencil")
        return float(g)


@dataclass(frozen=True)
class PitchforkNormalForm:
    """Coefficients of g(delta) = a3 delta^3 + a1 (lambda - lambda_c) delta + sum_mu (a0 mu + a2 mu delta^2).

    Attributes
    ----------
    parameter : the bifurcation parameter lambda
    critical_value : lambda_c
    a3, a1 : cubic and (lambda - lambda_c) delta coefficients
    a0, a2 : per unfolding parameter mu, the imperfection coefficients of mu and mu delta^2
    a_quadratic : the delta^2 coefficient at mu = 0 (zero for a symmetric pitchfork)
    kappa : d Phi / d x along the null vector (converts amplitude x to delta = Phi - Phi_c)
    """

    parameter: str
    critical_value: float
    a3: float
    a1: float
    a_quadratic: float
    kappa: float
    a0: dict[str, float] = field(default_factory=dict)
    a2: dict[str, float] = field(default_factory=dict)

    @property
    def bend(self) -> float:
        """a in lambda - lambda_c ~ a delta^2 (> 0 supercritical, < 0 subcritical)."""
        return -self.a3 / self.a1

    @property
    def criticality(self) -> str:
        return "supercritical" if self.bend > 0 else "subcritical"

    def unfolding(self, lam: float, mu: Mapping[str, float]) -> tuple[float, float, float]:
        """(B, alpha, beta) of delta^3 - B delta + alpha + beta delta^2 = 0 at (lambda, mu)."""
        b = -(self.a1 / self.a3) * (lam - self.critical_value)
        alpha = sum(self.a0[k] * v for k, v in mu.items()) / self.a3
        beta = (sum(self.a2[k] * v for k, v in mu.items()) + self.a_quadratic) / self.a3
        return b, alpha, beta

    def as_dict(self) -> dict[str, object]:
        return {
            "parameter": self.parameter,
            "critical_value": self.critical_value,
            "a3": self.a3,
            "a1": self.a1,
            "a_quadratic": self.a_quadratic,
            "kappa": self.kappa,
            "a0": dict(self.a0),
            "a2": dict(self.a2),
            "bend": self.bend,
            "criticality": self.criticality,
        }


def _order_parameter_slope(problem: object, state: Array, params: Mapping[str, float], phi: Array) -> float:
    """d Phi(u + t phi)/dt at t = 0 by a central difference (Phi is a cheap scalar)."""
    if not callable(getattr(problem, "order_parameter", None)):
        return 1.0
    h = 1e-6
    plus = problem.order_parameter(state + h * phi, params)
    minus = problem.order_parameter(state - h * phi, params)
    return float((plus - minus) / (2 * h))


def pitchfork_normal_form(
    problem: object,
    state: Array,
    params: Mapping[str, float],
    parameter: str,
    *,
    unfolding: tuple[str, ...] = (),
    amplitude: float = 1e-2,
    parameter_step: float | None = None,
    unfolding_steps: Mapping[str, float] | None = None,
    tol: float | None = None,
    polish: int = 0,
) -> PitchforkNormalForm:
    """Normal-form coefficients at a located simple branch point.

    Parameters
    ----------
    problem : a contin Problem
    state, params : the located branch point (``SpecialPoint.state`` and ``.params``)
    parameter : the bifurcation parameter lambda
    unfolding : further parameters mu whose imperfection coefficients are wanted
        (e.g. ('G',) for gravity, G = Fr^-2, in granular Couette flow)
    amplitude : stencil step in the null-vector amplitude x (|phi| = 1); the differences
        are fourth order, so the error of g_xxx is O(amplitude^4).
    parameter_step, unfolding_steps : stencil steps in lambda and mu (default 1e-4 of
        max(1, |value|) for lambda and 1e-6 for mu).
    tol : residual max-norm of the Lyapunov-Schmidt corrector (default 1e-13); raise it to
        the problem's rounding floor (~ eps ||J|| ||u||) on fine grids where 1e-13 is out of reach.
    polish : extra corrector steps after the residual passes ``tol`` (use 1 with a floor tol).

    Notes
    -----
    Central differences of g on the stencil, with h = amplitude, k = parameter_step:
    g_xxx = [-g(3h) + 8g(2h) - 13g(h) + 13g(-h) - 8g(-2h) + g(-3h)] / (8h^3)   (O(h^4)),
    g_lx = [g_x(k) - g_x(-k)] / (2k), g_x = [-g(2h) + 8g(h) - 8g(-h) + g(-2h)] / (12h),
    g_mu = [g(0, mu) - g(0, -mu)] / (2 mu),
    g_xxmu = [g(h, mu) - 2g(0, mu) + g(-h, mu) - (same at -mu)] / (2 mu h^2).
    """
    jac = sp.csc_matrix(problem.jacobian(state, params))
    nulls = null_vectors(jac)
    g = ReducedFunction(problem, np.asarray(state, float), dict(params), nulls,
                        polish=int(polish), **({} if tol is None else {"tol": float(tol)}))
    h = amplitude
    k = parameter_step if parameter_step is not None else 1e-4 * max(1.0, abs(params[parameter]))
    line = {j: g(j * h, {}) for j in (-3, -2, -1, 0, 1, 2, 3)}
    g_xxx = (-line[3] + 8 * line[2] - 13 * line[1] + 13 * line[-1] - 8 * line[-2] + line[-3]) / (8 * h**3)
    g_xx = (-line[2] + 16 * line[1] - 30 * line[0] + 16 * line[-1] - line[-2]) / (12 * h**2)

    def slope(shift: dict[str, float]) -> float:
        return (-g(2 * h, shift) + 8 * g(h, shift) - 8 * g(-h, shift) + g(-2 * h, shift)) / (12 * h)

    g_lx = (slope({parameter: k}) - slope({parameter: -k})) / (2 * k)
    kappa = _order_parameter_slope(problem, state, params, nulls.phi)
    a0: dict[str, float] = {}
    a2: dict[str, float] = {}
    steps = dict(unfolding_steps or {})
    for name in unfolding:
        m = steps.get(name, 1e-6)
        plus0, minus0 = g(0.0, {name: m}), g(0.0, {name: -m})
        a0[name] = (plus0 - minus0) / (2 * m)
        curv_plus = g(h, {name: m}) - 2 * plus0 + g(-h, {name: m})
        curv_minus = g(h, {name: -m}) - 2 * minus0 + g(-h, {name: -m})
        a2[name] = (curv_plus - curv_minus) / (2 * m * h**2) / (2 * kappa**2)
    return PitchforkNormalForm(
        parameter=parameter,
        critical_value=float(params[parameter]),
        a3=g_xxx / (6 * kappa**3),
        a1=g_lx / kappa,
        a_quadratic=g_xx / (2 * kappa**2),
        kappa=kappa,
        a0=a0,
        a2=a2,
    )


def hysteresis_alpha(beta: NDArray[np.float64] | float) -> NDArray[np.float64] | float:
    """Hysteresis variety of delta^3 - B delta + alpha + beta delta^2: alpha = beta^3 / 27.

    Golubitsky & Schaeffer (1985), ch. III; re-derived: the cubic has a triple root when
    B = -beta^2/3 and alpha = beta^3/27.
    """
    return np.asarray(beta) ** 3 / 27.0
