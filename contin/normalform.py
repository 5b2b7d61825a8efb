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
derivative of Phi along phi (|phi| = |psi| = 1 Euclidean; without an ``order_parameter`` delta
is the amplitude along phi in the problem's ``inner_product_weights`` norm, kappa =
sqrt(sum w phi^2), or x itself without that hook), the equilibria satisfy (after division by
the cubic coefficient)

    delta^3 - B delta + alpha + beta delta^2 = 0,
    B = -(a1/a3)(lambda - lambda_c),  alpha = (a0/a3) mu,  beta = (a2/a3) mu,

with a3 = g_xxx/(6 kappa^3), a1 = g_lx/kappa, a0 = g_mu, a2 = g_xxmu/(2 kappa^2).  This is
the unfolding of the pitchfork x^3 - lambda x + alpha + beta x^2 (A13 slides; G&S ch. III).
The branch bends as lambda - lambda_c ~ a delta^2 with a = -a3/a1: the pitchfork is
supercritical when a > 0 and subcritical when a < 0, counting lambda increasing.

The mu delta^2 coefficient a2 depends on the coordinate x and on the normalisation of g
(contact equivalence): it is not a property of the solution set.  :func:`pitchfork_unfolding`
computes the unfolding to next order (all weight-5 terms) in the coordinate of a given
linear order parameter and returns its canonical form :class:`Unfolding`
(delta^3 - B(lambda) delta + alpha(mu) + beta(mu) delta^2 + q5 delta^5 = 0), whose beta1 is
unique and comparable with :func:`contin.fit.fit_graph`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from contin.problem import Array, inner_product_weights


@dataclass(frozen=True)
class NullVectors:
    """Right (phi) and left (psi) null vectors of a singular Jacobian, |phi| = |psi| = 1."""

    phi: Array
    psi: Array
    residual: float  # max(|J phi|, |J^T psi|): small when J really is singular


def borders(n: int, *, seed: int = 0) -> tuple[Array, Array]:
    """The random borders b, c of [[J, b], [c^T, 0]] (:func:`null_vectors`; one seed, so every
    bordering of the same J gives the same null vector)."""
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n), rng.standard_normal(n)


def null_vectors(jacobian: sp.spmatrix, *, seed: int = 0) -> NullVectors:
    """Null vectors of a (numerically) singular sparse matrix by bordering.

    Solves [[J, b], [c^T, 0]] [phi; s] = [0; 1] and its transpose with random b, c
    (Govaerts, *Numerical Methods for Bifurcations of Dynamical Equilibria*, SIAM 2000,
    sec. 3.2); the bordered matrix is regular at a simple singular point.
    """
    n = jacobian.shape[0]
    b, c = borders(n, seed=seed)
    border = sp.bmat([[sp.csc_matrix(jacobian), b[:, None]], [c[None, :], None]], format="csc")
    import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

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
    # Side condition c . w = 0 of the splitting u = u_c + x phi + w (default c = phi).  With
    # c = l, a linear order parameter l . u, and l . phi = 1, the amplitude x IS the
    # order-parameter deviation l . (u - u_c) exactly, at every order.
    constraint: Array | None = None

    def __call__(self, x: float, shifts: Mapping[str, float]) -> float:
        """Value of g at amplitude x and parameters params + shifts."""
        p = dict(self.params)
        for name, d in shifts.items():
            p[name] = p[name] + d
        phi, psi = self.nulls.phi, self.nulls.psi
        c = phi if self.constraint is None else self.constraint
        n = phi.size
        w = np.zeros(n)
        g = 0.0
        extra = self.polish
        for _ in range(self.max_iterations + self.polish):
            u = self.state + x * phi + w
            res = np.concatenate([self.problem.residual(u, p) - g * psi, [c @ w]])
            if np.max(np.abs(res)) < self.tol:
                if extra == 0:
                    break
                extra -= 1
            jac = sp.bmat(
                [[sp.csc_matrix(self.problem.jacobian(u, p)), -psi[:, None]], [c[None, :], None]], format="csc"
            )
            import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

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
    kappa : d Phi / d x along the null vector (converts amplitude x to delta = Phi - Phi_c);
        without an order parameter |phi|_W (delta the amplitude in the problem's
        ``inner_product_weights`` norm), or 1 without those either
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
    """d Phi(u + t phi)/dt at t = 0 by a central difference (Phi is a cheap scalar).  Without an
    ``order_parameter`` Phi is the amplitude along phi in the problem's norm: |phi|_W =
    sqrt(sum w phi^2) with its ``inner_product_weights`` w, else 1 (the Euclidean |phi| = 1)."""
    if not callable(getattr(problem, "order_parameter", None)):
        weights = inner_product_weights(problem, state, params)
        return 1.0 if weights is None else float(np.sqrt(weights @ (phi * phi)))
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
    Normalisation: |phi| = |psi| = 1 (Euclidean), so g = psi . F on the reduced solutions and
    x is the Euclidean amplitude.  The reported ratios (``bend``, ``unfolding``) do not depend
    on psi's scale, nor, through kappa, on phi's: delta = Phi - Phi_c with the problem's
    ``order_parameter`` Phi, else the amplitude along phi in its ``inner_product_weights`` norm,
    x sqrt(sum w phi^2) (a discretised PDE's L2 amplitude: the bend converges with the grid,
    where the Euclidean x, ~ sqrt(n) times it, made the bend fall like 1/n; kappa = 1 without
    either hook, as before it).  a3, a1, a0, a2 one by one carry psi's Euclidean,
    sign-arbitrary scale: only their ratios are grid-independent (measured on Allen-Cahn in
    ``tests/test_normalform.py``).

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


# ----------------------------------------------------------------------------- unfolding to next order
#: Weighted orders of the unfolding: delta ~ eps, lambda - lambda_c ~ eps^2, mu ~ eps^3.  The
#: solution set near the pitchfork is the graph lambda(delta, mu) = sum c[k, j] mu^j delta^(2k - 3j)
#: (k = 1, 2, ...; j = 0..k; weight 2k), unique once the order-parameter coordinate is fixed.
GRAPH_TERMS: tuple[tuple[int, int], ...] = ((1, 0), (1, 1), (2, 0), (2, 1), (2, 2))


@dataclass(frozen=True)
class Unfolding:
    """Pitchfork unfolding to next order, in the form the A13 slides write it,

        delta^3 - B(lambda) delta + alpha(mu) + beta(mu) delta^2 + q5 delta^5 = 0,
        B = b1 l + b2 l^2,  alpha = alpha1 mu,  beta = beta1 mu,  l = lambda - lambda_c,

    with B depending on lambda only and alpha, beta on mu only (the canonical representative:
    the terms mu l, l delta^3 and l^2 delta that a raw reduction also produces are removed by
    the multipliers 1 + n l and 1 + m delta^2 of contact equivalence and by B's l^2 term;
    Golubitsky & Schaeffer 1985, ch. II-III).  Valid when delta is an order parameter odd under
    the symmetry that maps mu to -mu, so no even-weight terms appear.

    Equivalent data: the graph lambda(delta, mu) of the solution set, to weight 4,
        l = c10 delta^2 + c11 mu/delta + c20 delta^4 + c21 mu delta + c22 mu^2/delta^2,
    c10 = 1/b1, c11 = alpha1/b1, c20 = q5/b1 - b2/b1^3, c21 = beta1/b1 - 2 b2 alpha1/b1^3,
    c22 = -b2 alpha1^2/b1^3 (substitute B = delta^2 + alpha/delta + beta delta + q5 delta^4
    and invert B(l)).  ``cov`` is the covariance of (b1, b2, alpha1, beta1, q5) when known.
    """

    critical_value: float
    b1: float
    b2: float
    alpha1: float
    beta1: float
    q5: float
    cov: NDArray[np.float64] | None = None

    NAMES = ("b1", "b2", "alpha1", "beta1", "q5")

    @classmethod
    def from_graph(cls, critical_value: float, c: Mapping[tuple[int, int], float],
                   cov: NDArray[np.float64] | None = None) -> Unfolding:
        """From graph coefficients c[(k, j)] (GRAPH_TERMS), with their covariance propagated
        to (b1, b2, alpha1, beta1, q5) by the Jacobian of the (smooth) map."""
        vec = np.array([c[t] for t in GRAPH_TERMS], float)
        out = _canonical(vec)
        if cov is not None:
            jac = np.empty((5, 5))
            for i in range(5):
                h = 1e-6 * max(abs(vec[i]), 1e-300)
                dp, dm = vec.copy(), vec.copy()
                dp[i] += h
                dm[i] -= h
                jac[:, i] = (_canonical(dp) - _canonical(dm)) / (2 * h)
            cov = jac @ np.asarray(cov, float) @ jac.T
        return cls(float(critical_value), *map(float, out), cov=cov)

    def graph(self) -> dict[tuple[int, int], float]:
        b1, b2, a1, be, q5 = self.b1, self.b2, self.alpha1, self.beta1, self.q5
        return {(1, 0): 1 / b1, (1, 1): a1 / b1, (2, 0): q5 / b1 - b2 / b1**3,
                (2, 1): be / b1 - 2 * b2 * a1 / b1**3, (2, 2): -b2 * a1**2 / b1**3}

    def errors(self) -> dict[str, float]:
        """One-sigma errors from ``cov`` (NaN when unknown)."""
        if self.cov is None:
            return {k: float("nan") for k in self.NAMES}
        return {k: float(np.sqrt(max(self.cov[i, i], 0.0))) for i, k in enumerate(self.NAMES)}

    def lam(self, delta: NDArray[np.float64] | float, mu: float) -> NDArray[np.float64] | float:
        """lambda - lambda_c on the solution set at (delta, mu) (the weight-4 graph)."""
        d = np.asarray(delta, float)
        return sum(v * mu**j * d ** (2 * k - 3 * j) for (k, j), v in self.graph().items())

    def fold(self, mu: float, *, leading: bool = False) -> tuple[float, float]:
        """(lambda_LP - lambda_c, delta_LP) of the fold on the graph at imperfection mu.

        Leading order: d lambda/d delta = 0 gives delta^3 = alpha1 mu / 2 and
        lambda - lambda_c = (3/b1)(alpha1 mu/2)^(2/3); to next order
        lambda - lambda_c = 3 d^2/b1 + (c20 + 2 c21/alpha1 + 4 c22/alpha1^2) d^4 with
        d = (alpha1 mu/2)^(1/3) (first-order perturbation of a stationary value).
        ``leading=False`` returns the stationary point of the whole weight-4 graph (Newton
        from d), which agrees with the expansion to O(d^6).
        """
        d0 = float(np.cbrt(self.alpha1 * mu / 2.0))
        c = self.graph()
        if leading:
            return 3 * d0**2 / self.b1, d0
        d = d0
        for _ in range(50):
            # d lambda/d delta and its derivative for the five graph terms
            f = sum(v * mu**j * (2 * k - 3 * j) * d ** (2 * k - 3 * j - 1) for (k, j), v in c.items())
            fp = sum(v * mu**j * (2 * k - 3 * j) * (2 * k - 3 * j - 1) * d ** (2 * k - 3 * j - 2) for (k, j), v in c.items())
            step = f / fp
            d -= step
            if abs(step) <= 1e-15 * abs(d):
                break
        return float(self.lam(d, mu)), float(d)

    def fold_expansion(self, mu: float) -> float:
        """lambda_LP - lambda_c = 3 d^2/b1 + C4 d^4, d = (alpha1 mu/2)^(1/3) (see :meth:`fold`)."""
        c = self.graph()
        d = float(np.cbrt(self.alpha1 * mu / 2.0))
        c4 = c[(2, 0)] + 2 * c[(2, 1)] / self.alpha1 + 4 * c[(2, 2)] / self.alpha1**2
        return 3 * d**2 / self.b1 + c4 * d**4

    def hysteresis(self) -> dict[str, float] | None:
        """The hysteresis point alpha = beta^3/27, B = -beta^2/3 of the cubic truncation along
        alpha = alpha1 mu, beta = beta1 mu: mu^2 = 27 alpha1/beta1^3.  None when alpha1 beta1^3 < 0
        (the line (alpha1 mu, beta1 mu) meets the hysteresis variety only at mu = 0)."""
        m2 = 27.0 * self.alpha1 / self.beta1**3
        if not m2 > 0:
            return None
        mu = float(np.sqrt(m2))
        beta = self.beta1 * mu
        return {"mu": mu, "lam": -beta**2 / 3.0 / self.b1, "delta": -beta / 3.0}

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {k: getattr(self, k) for k in ("critical_value", *self.NAMES)}
        out["errors"] = self.errors()
        out["graph"] = {f"c{k}{j}": v for (k, j), v in self.graph().items()}
        if self.cov is not None:
            out["covariance"] = {"order": list(self.NAMES), "matrix": np.asarray(self.cov).tolist()}
        return out


def _canonical(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """(b1, b2, alpha1, beta1, q5) from the graph coefficients (c10, c11, c20, c21, c22)."""
    c10, c11, c20, c21, c22 = c
    b1 = 1.0 / c10
    a1 = c11 * b1
    b2 = -c22 * b1**3 / a1**2
    beta = b1 * c21 + 2 * b2 * a1 / b1**2
    q5 = b1 * (c20 + b2 / b1**3)
    return np.array([b1, b2, a1, beta, q5])


@dataclass(frozen=True)
class ReducedUnfolding:
    """Taylor coefficients of the Lyapunov-Schmidt function g(delta, l, mu) / g_delta^3 up to
    weight 5 (delta ~ eps, l ~ eps^2, mu ~ eps^3):

        delta^3 - b1 l delta + alpha1 mu + beta_raw mu delta^2 + c mu l
              + q5 delta^5 + q3 l delta^3 + q1 l^2 delta = 0,

    ``unfolding`` the canonical form (:class:`Unfolding`) of the same solution set:
    beta1 = beta_raw - c/b1 + q3 alpha1/b1 (the raw mu delta^2 coefficient alone depends on
    the multiplier of g and is not comparable with a fit).  ``residual`` is the rms misfit
    of the stencil polynomial relative to max |g|.
    """

    coefficients: dict[str, float]
    unfolding: Unfolding
    residual: float
    amplitude: float


def _monomials(weight: int) -> list[tuple[int, int, int]]:
    return [(i, j, m) for m in range(weight // 3 + 1) for j in range((weight - 3 * m) // 2 + 1)
            for i in range(weight - 3 * m - 2 * j + 1)]


def pitchfork_unfolding(
    problem: object,
    state: Array,
    params: Mapping[str, float],
    parameter: str,
    imperfection: str,
    coordinate: Array,
    *,
    amplitude: float = 1e-2,
    tol: float | None = None,
    polish: int = 0,
) -> ReducedUnfolding:
    """Unfolding of a Z2 pitchfork to next order by Lyapunov-Schmidt reduction.

    The splitting u = u_c + delta phi + w uses the side condition l . w = 0 with l =
    ``coordinate`` (a linear order parameter, odd under the symmetry; phi scaled to l . phi = 1),
    so the reduced amplitude is the order-parameter deviation delta = l . (u - u_c) exactly.
    g is evaluated on the tensor stencil delta in h{0, +-1, .., +-4}, l in k{0, +-1, +-2},
    mu in m{0, +-1, +-2} with h = ``amplitude``, k = h^2 |a3/a1|, m = h^3 |a3/a0| (the natural
    scales of the unfolding) and every monomial delta^i l^j mu^n of weight i + 2j + 3n <= 7 is
    fitted by least squares in the scaled variables; the weight-3 and weight-5 coefficients
    are kept.  The truncation error of the weight-5 coefficients is O(h^2) relative (the next
    odd weight is 7, fitted; 9 is not): compare two amplitudes to estimate it.
    """
    state = np.asarray(state, float)
    ell = np.asarray(coordinate, float)
    jac = sp.csc_matrix(problem.jacobian(state, params))  # type: ignore[attr-defined]
    nv = null_vectors(jac)
    s = float(ell @ nv.phi)
    if abs(s) < 1e-8 * np.linalg.norm(ell):
        raise ValueError("the coordinate functional vanishes on the null vector; it cannot measure the amplitude")
    nulls = NullVectors(nv.phi / s, nv.psi, nv.residual)
    g = ReducedFunction(problem, state, dict(params), nulls, polish=int(polish), constraint=ell,
                        **({} if tol is None else {"tol": float(tol)}))
    h = amplitude
    k0 = 1e-4 * max(1.0, abs(params[parameter]))
    line = {j: g(j * h, {}) for j in (-3, -2, -1, 1, 2, 3)}
    a3 = (-line[3] + 8 * line[2] - 13 * line[1] + 13 * line[-1] - 8 * line[-2] + line[-3]) / (8 * h**3) / 6

    def slope(shift: dict[str, float]) -> float:
        return (-g(2 * h, shift) + 8 * g(h, shift) - 8 * g(-h, shift) + g(-2 * h, shift)) / (12 * h)

    a1 = (slope({parameter: k0}) - slope({parameter: -k0})) / (2 * k0)
    m0 = 1e-6
    a0 = (g(0.0, {imperfection: m0}) - g(0.0, {imperfection: -m0})) / (2 * m0)
    if a0 == 0 or a1 == 0:
        raise ValueError(f"{imperfection!r} or {parameter!r} does not unfold this branch point at first order")
    k = h**2 * abs(a3 / a1)
    m = h**3 * abs(a3 / a0)
    pts = [(i, j, n) for i in range(-4, 5) for j in range(-2, 3) for n in range(-2, 3)]
    vals = np.array([g(i * h, {parameter: j * k, imperfection: n * m}) for i, j, n in pts])
    mons = _monomials(7)
    P = np.array(pts, float)
    A = np.column_stack([P[:, 0] ** i * P[:, 1] ** j * P[:, 2] ** n for i, j, n in mons])
    coef, *_ = np.linalg.lstsq(A, vals, rcond=None)
    resid = float(np.sqrt(np.mean((vals - A @ coef) ** 2)) / np.max(np.abs(vals)))
    # back to unscaled variables
    raw = {mon: c / (h ** mon[0] * k ** mon[1] * m ** mon[2]) for mon, c in zip(mons, coef)}
    c3 = raw[(3, 0, 0)]
    co = {
        "b1": -raw[(1, 1, 0)] / c3,
        "alpha1": raw[(0, 0, 1)] / c3,
        "beta_raw": raw[(2, 0, 1)] / c3,
        "c": raw[(0, 1, 1)] / c3,
        "q5": raw[(5, 0, 0)] / c3,
        "q3": raw[(3, 1, 0)] / c3,
        "q1": raw[(1, 2, 0)] / c3,
        "a3": c3,
    }
    b1, a1_, be, c_, q5, q3, q1 = (co[x] for x in ("b1", "alpha1", "beta_raw", "c", "q5", "q3", "q1"))
    graph = {
        (1, 0): 1 / b1,
        (1, 1): a1_ / b1,
        (2, 0): q5 / b1 + q3 / b1**2 + q1 / b1**3,
        (2, 1): (be + c_ / b1 + q3 * a1_ / b1 + 2 * q1 * a1_ / b1**2) / b1,
        (2, 2): c_ * a1_ / b1**2 + q1 * a1_**2 / b1**3,
    }
    unf = Unfolding.from_graph(float(params[parameter]), graph)
    return ReducedUnfolding(coefficients=co, unfolding=unf, residual=resid, amplitude=h)
