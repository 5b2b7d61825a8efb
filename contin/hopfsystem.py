"""The Hopf defining system as a contin Problem: the augmented system of
``contin.hopfcurve`` (two-parameter continuation of Hopf points) and of the two-grid check of a
located Hopf point (``contin.specialcheck.hopf_point_error``).

A Hopf point of M u' = F(u, p) has a real two-dimensional invariant subspace of the pencil
(J, M) on which it acts with eigenvalues +-i omega; with kappa = omega^2 it solves the standard
augmented system (Govaerts, *Numerical Methods for Bifurcations of Dynamical Equilibria*, SIAM
2000, sec. 4.4.2; the "J^2 + kappa I" formulation of Roose & Hlavacek, SIAM J. Appl. Math. 45,
1985; Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed., sec. 10.2)

    F(u, p) = 0,   J v - M w = 0,   J w + kappa M v = 0,   c . v - 1 = 0,   d . v = 0,

unknowns (u, v, w, kappa, p) (the real form of J q = i omega M q, c^H q = 1: v = Re q,
w = -omega Im q up to a scale and phase, which the rows c . v = 1 and d . v = 0 fix).  M is
taken as constant; the second derivatives are central differences of the problem's Jacobian
along v and w.  Kept apart from ``contin.hopfcurve`` (which imports the tracer) so that the
tracer's special-point checks can use it without an import circle.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.branch import SpecialPoint
from contin.pointtests import Crossing
from contin.problem import Array, has
from contin.testfunctions import sign_change

#: Relative step of the central differences of J and F_p along v, w.
FD_EPS = 1e-6
#: Augmented systems with at most this many unknowns get a dense Jacobian.
DENSE_AUGMENTED = 300


def _mass(problem: Any, u: Array, q: Mapping[str, float], n: int) -> sp.csr_matrix:
    if has(problem, "mass_matrix"):
        return sp.csr_matrix(problem.mass_matrix(u, q), dtype=float)
    return sp.identity(n, format="csr")


class HopfCurveProblem:
    """The augmented Hopf system as a contin Problem (state U = [u, v, w, kappa, p2])."""

    def __init__(self, problem: Any, second: str, normalisation: Array, phase: Array, eps: float = FD_EPS,
                 generalized_hopf: bool = False) -> None:
        self.problem = problem
        self.generalized_hopf = generalized_hopf  # point_tests: GH (l1 = 0) besides BT
        self.zero_hopf = False  # point_tests: ZH (det J / kappa changes sign)
        self.base_hopf: Any = None  # the base problem's HopfTest: HH (a second pair crosses)
        self.second = second
        self.parameter_names = tuple(problem.parameter_names)
        self.c = np.asarray(normalisation, float)
        self.d = np.asarray(phase, float)
        self.n = self.c.size
        self.eps = eps
        self._m: sp.csr_matrix | None = None

    def split(self, state: Array, p: Mapping[str, float]) -> tuple[Array, Array, Array, float, dict[str, float]]:
        n = self.n
        q = dict(p)
        q[self.second] = float(state[3 * n + 1])
        return state[:n], state[n:2 * n], state[2 * n:3 * n], float(state[3 * n]), q

    def mass(self, u: Array, q: Mapping[str, float]) -> sp.csr_matrix:
        if self._m is None:
            self._m = _mass(self.problem, u, q, self.n)
        return self._m

    def residual(self, state: Array, p: Mapping[str, float]) -> Array:
        u, v, w, kappa, q = self.split(state, p)
        jac = self.problem.jacobian(u, q)
        m = self.mass(u, q)
        return np.concatenate([self.problem.residual(u, q), jac @ v - m @ w, jac @ w + kappa * (m @ v),
                               [self.c @ v - 1.0, self.d @ v]])

    def _step(self, u: Array, d: Array) -> float:
        return self.eps * max(1.0, float(np.max(np.abs(u)))) / max(float(np.max(np.abs(d))), 1e-300)

    def _hessian(self, u: Array, d: Array, q: Mapping[str, float]) -> Any:
        """d/du (J d) by a central difference of J along d (sparse or dense as J comes)."""
        h = self._step(u, d)
        plus, minus = self.problem.jacobian(u + h * d, q), self.problem.jacobian(u - h * d, q)
        if sp.issparse(plus) or sp.issparse(minus):
            return (sp.csr_matrix(plus) - sp.csr_matrix(minus)) / (2 * h)
        return (np.asarray(plus) - np.asarray(minus)) / (2 * h)

    def _mixed(self, u: Array, d: Array, q: Mapping[str, float], name: str) -> Array:
        """d/dp (J d) = d/du(F_p) d, by a central difference along d."""
        h = self._step(u, d)
        fp = self.problem.dresidual_dp
        return (fp(u + h * d, q, name) - fp(u - h * d, q, name)) / (2 * h)

    def jacobian(self, state: Array, p: Mapping[str, float]) -> sp.csr_matrix | Array:
        """The augmented Jacobian: dense below :data:`DENSE_AUGMENTED` unknowns (assembling
        scipy.sparse blocks costs far more than the dense arithmetic there), else sparse."""
        u, v, w, kappa, q = self.split(state, p)
        if 3 * self.n + 2 <= DENSE_AUGMENTED:
            return self._dense_jacobian(u, v, w, kappa, q)
        jac = sp.csr_matrix(self.problem.jacobian(u, q))
        m = self.mass(u, q)
        col = lambda a: sp.csr_matrix(np.asarray(a, float)[:, None])  # noqa: E731
        row = sp.csr_matrix(self.c[None, :])
        row_d = sp.csr_matrix(self.d[None, :])
        blocks = [
            [jac, None, None, None, col(self.problem.dresidual_dp(u, q, self.second))],
            [self._hessian(u, v, q), jac, -m, None, col(self._mixed(u, v, q, self.second))],
            [self._hessian(u, w, q), kappa * m, jac, col(m @ v), col(self._mixed(u, w, q, self.second))],
            [None, row, None, None, None],
            [None, row_d, None, None, None],
        ]
        return sp.bmat(blocks, format="csr")

    def _dense_jacobian(self, u: Array, v: Array, w: Array, kappa: float, q: Mapping[str, float]) -> Array:
        n = self.n

        def dense(a: Any) -> Array:
            return a.toarray() if sp.issparse(a) else np.asarray(a, dtype=float)

        jac = dense(self.problem.jacobian(u, q))
        m = dense(self.mass(u, q))
        out = np.zeros((3 * n + 2, 3 * n + 2))
        out[:n, :n] = jac
        out[:n, -1] = self.problem.dresidual_dp(u, q, self.second)
        out[n:2 * n, :n] = dense(self._hessian(u, v, q))
        out[n:2 * n, n:2 * n] = jac
        out[n:2 * n, 2 * n:3 * n] = -m
        out[n:2 * n, -1] = self._mixed(u, v, q, self.second)
        out[2 * n:3 * n, :n] = dense(self._hessian(u, w, q))
        out[2 * n:3 * n, n:2 * n] = kappa * m
        out[2 * n:3 * n, 2 * n:3 * n] = jac
        out[2 * n:3 * n, 3 * n] = m @ v
        out[2 * n:3 * n, -1] = self._mixed(u, w, q, self.second)
        out[3 * n, n:2 * n] = self.c
        out[3 * n + 1, n:2 * n] = self.d
        return out

    def dresidual_dp(self, state: Array, p: Mapping[str, float], name: str) -> Array:
        u, v, w, _, q = self.split(state, p)
        return np.concatenate([self.problem.dresidual_dp(u, q, name), self._mixed(u, v, q, name),
                               self._mixed(u, w, q, name), [0.0, 0.0]])

    def order_parameter(self, state: Array, p: Mapping[str, float]) -> float:
        u, _, _, _, q = self.split(state, p)
        if has(self.problem, "order_parameter"):
            return float(self.problem.order_parameter(u, q))
        return float(np.linalg.norm(u))

    def observables(self, state: Array, p: Mapping[str, float]) -> dict[str, float]:
        u, _, _, kappa, q = self.split(state, p)
        out = dict(self.problem.observables(u, q)) if has(self.problem, "observables") else {}
        out[self.second] = float(state[3 * self.n + 1])
        out["kappa"] = kappa  # omega^2 on Hopf points, -lambda^2 on neutral saddles (finite: HDF5-safe)
        return out

    def admissible(self, state: Array, p: Mapping[str, float]) -> str | None:
        u, _, _, _, q = self.split(state, p)
        return self.problem.admissible(u, q) if has(self.problem, "admissible") else None

    def under_resolved(self, state: Array, p: Mapping[str, float], tol: float) -> str | None:
        if not has(self.problem, "under_resolved"):
            return None
        u, _, _, _, q = self.split(state, p)
        reason = self.problem.under_resolved(u, q, tol)
        return None if reason is None else f"{reason} (at {self.second} = {q[self.second]:.6g})"

    def base(self, state: Array, p: Mapping[str, float]) -> tuple[Array, dict[str, float]]:
        """The base state u and the base parameters (p2 in place) of an augmented state."""
        u, _, _, _, q = self.split(state, p)
        return u, q

    def point_tests(self) -> list[Any]:
        """BT: the sign change of kappa (module docstring); GH: the sign change of l1 on the Hopf
        part (kappa > 0), when ``generalized_hopf``; ZH (a real eigenvalue through 0) when
        ``zero_hopf``; HH (a second pair through the imaginary axis) when ``base_hopf`` is set
        (``contin.codim2tests``)."""
        from contin.codim2tests import BaseEigenTest, ZeroHopfTest

        tests: list[Any] = [KappaTest(self.n)]
        if self.generalized_hopf:
            tests.append(LyapunovTest(self))
        if self.zero_hopf:
            tests.append(ZeroHopfTest(self.problem, self.base, 3 * self.n))
        if self.base_hopf is not None:
            tests.append(BaseEigenTest(self.base_hopf, self.base, "hh", "HH",
                                       "double Hopf (a second pair crosses the imaginary axis)", own_kappa=3 * self.n))
        return tests


@dataclass(frozen=True)
class KappaTest:
    """Point test of a Hopf curve: kappa = omega^2 changes sign at a Bogdanov-Takens point."""

    n: int
    name: str = "bt"
    kind: str = "BT"

    def value(self, system: Any, x: Array) -> float:
        return float(x[3 * self.n])

    def crossings(self, va: float, vb: float) -> list[Crossing]:
        return [("Bogdanov-Takens (kappa = omega^2 = 0)", float)] if sign_change(va, vb) else []

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        """kappa (~0) and the BT normal-form coefficients a, b (``contin.codim2tests``)."""
        from contin.codim2tests import bogdanov_takens_coefficients

        data = {**sp_.data, "kappa": float(x[3 * self.n])}
        curve = system.problem
        if isinstance(curve, HopfCurveProblem) and not has(curve.problem, "eigenproblem"):
            u, _, _, _, q = curve.split(x[:-1], system.params_at(x[-1]))
            data.update(bogdanov_takens_coefficients(curve.problem, u, q))
        return replace(sp_, data=data)


@dataclass(frozen=True)
class LyapunovTest:
    """Point test of a Hopf curve: the first Lyapunov coefficient l1 changes sign at a
    generalized Hopf (Bautin) point, label GH (AUTO-07p's GH, BifurcationKit's ``:gh``).

    The value at a point is (l1, True) on the Hopf part of the curve (kappa = omega^2 > 0; l1
    by :func:`contin.hopf.first_lyapunov` at the base state with omega = sqrt(kappa): Kuznetsov,
    *Elements of Applied Bifurcation Theory*, 3rd ed., eq. (3.20)), and (0, False) where l1 is
    not defined (neutral saddles, kappa <= 0) or cannot be computed there (the reason is
    logged): no GH is bracketed by such a point.  The zero is located like every point test,
    by re-correcting onto the curve (``contin.locate``), so its accuracy is that of l1 (central
    differences of J: relative ~1e-8 on smooth problems) over |dl1/ds|.  A located GH carries
    the second Lyapunov coefficient l2, its normal-form coefficient (``data['l2']``).
    """

    curve: Any
    name: str = "gh"
    kind: str = "GH"
    #: {'m': the multiplier of l1's difference steps}, chosen at the curve's first Hopf point
    _steps: dict[str, float] = field(default_factory=dict, compare=False, hash=False, repr=False)

    def step_scale(self, u: Array, q: Mapping[str, float], omega: float) -> float:
        """The multiplier of l1's difference steps along the curve: :func:`contin.hopf.step_ladder`
        at its first Hopf point, then kept (one step size all along: a sign change of l1 is not
        one of its steps).  The default steps resolve a nonlinearity on the scale max(1, |u|)
        only: the Bautin system scaled by 1e-4 had no GH, scaled by 1e4 its GH at b2 = 0.021
        (exact 0), 'converged' (session 16 audit)."""
        if "m" not in self._steps:
            from contin.hopf import first_lyapunov_ladder

            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                l1, _, m = first_lyapunov_ladder(self.curve.problem, np.asarray(u, float), dict(q), omega)
            if not math.isfinite(l1):
                return 1.0  # not at this point (a singular J): chosen at the next
            self._steps["m"] = m
        return self._steps["m"]

    def value(self, system: Any, x: Array) -> tuple[float, bool]:
        from contin.hopf import first_lyapunov

        u, _, _, kappa, q = self.curve.split(x[:-1], system.params_at(x[-1]))
        if not kappa > 0:
            return (0.0, False)
        try:
            m = self.step_scale(u, q, math.sqrt(kappa))
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # a singular J (a ZH): l1 NaN, no bracket
                l1 = first_lyapunov(self.curve.problem, np.asarray(u, float), q, math.sqrt(kappa), step_scale=m)
        except (np.linalg.LinAlgError, RuntimeError, ValueError) as exc:
            import logging

            logging.getLogger("contin").warning("GH test: l1 failed at %s=%g: %s", system.parameter, x[-1], exc)
            return (0.0, False)
        return (l1, True) if math.isfinite(l1) else (0.0, False)

    def crossings(self, va: tuple[float, bool], vb: tuple[float, bool]) -> list[Crossing]:
        if not (va[1] and vb[1] and sign_change(va[0], vb[0])):
            return []
        return [("generalized Hopf (l1 = 0)", _l1_or_nan)]

    def value_error(self, system: Any, x: Array) -> float:
        """|l1(m) - l1(2 m)| at x (m the curve's step multiplier): the error of the test value
        that located a GH (:func:`contin.hopf.two_step_estimate`).  From a difference Jacobian
        (``from_functions``' default) it is ~1e-5: AUTO's pp3 had its GHs 1e-6 off, 'converged'."""
        from contin.hopf import first_lyapunov, two_step_estimate

        u, _, _, kappa, q = self.curve.split(x[:-1], system.params_at(x[-1]))
        if not kappa > 0:
            return math.nan
        m = self.step_scale(u, q, math.sqrt(kappa))
        estimate = two_step_estimate(lambda k: first_lyapunov(self.curve.problem, np.asarray(u, float), q,
                                                              math.sqrt(kappa), step_scale=k))
        try:
            return estimate(m)[1]
        except (np.linalg.LinAlgError, RuntimeError, ValueError):
            return math.nan

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        """l1 (~0), omega, kappa and the second Lyapunov coefficient l2 of the GH
        (:func:`contin.codim2tests.second_lyapunov_estimate`; NaN where it cannot be computed,
        the reason logged) with its estimated absolute error ``l2_error`` (a warning and the note
        'l2 doubtful' above L2_DOUBTFUL |l2|): its sign tells the GH's two unfoldings apart (l2 < 0: the fold curve of cycles
        that starts at the GH bounds a region with a stable and an unstable cycle; Kuznetsov
        sec. 8.3)."""
        import logging

        from contin.codim2tests import L2_DOUBTFUL, second_lyapunov_estimate

        l1, hopf = self.value(system, x)
        kappa = float(x[3 * self.curve.n])
        omega = math.sqrt(kappa) if kappa > 0 else math.nan
        l2, l2_err = math.nan, math.nan
        note = sp_.note
        if hopf:
            u, _, _, _, q = self.curve.split(x[:-1], system.params_at(x[-1]))
            try:
                l2, l2_err = second_lyapunov_estimate(self.curve.problem, np.asarray(u, float), q, omega)
            except (np.linalg.LinAlgError, RuntimeError, ValueError) as exc:
                logging.getLogger("contin").warning("GH: l2 failed at %s=%g: %s", system.parameter, x[-1], exc)
            if math.isfinite(l2) and not l2_err <= L2_DOUBTFUL * abs(l2):
                # the differences of J found no step that resolves F's fourth and fifth derivatives
                msg = f"l2 doubtful (estimated relative error {l2_err / abs(l2) if l2 else math.inf:.1e})"
                logging.getLogger("contin").warning("GH at %s=%g: %s", system.parameter, x[-1], msg)
                note = f"{note}; {msg}" if note else msg
        if not math.isfinite(l2):
            l2, l2_err = math.nan, math.nan
        return replace(sp_, note=note, data={**sp_.data, "l1": l1 if hopf else math.nan, "l2": l2, "l2_error": l2_err,
                                             "omega": omega, "kappa": kappa})


def _l1_or_nan(v: tuple[float, bool]) -> float:
    """The GH test function: l1 where it is defined, NaN (a failed trial of the locator) elsewhere."""
    return v[0] if v[1] else math.nan


def hopf_basis(problem: Any, u: Array, params: Mapping[str, float], omega: float,
               q: Array | None = None) -> tuple[Array, Array, Array]:
    """(v, w, d) of the augmented system at a Hopf point (u, p) with frequency omega: J v = M w,
    J w = -omega^2 M v, |v| = 1, v . w = 0, and the phase row d = Im q / |Im q| (d . v = 0).
    From the critical eigenvector q (J q = i omega M q; computed by
    :func:`contin.hopf.hopf_vectors` when not given) rotated by a phase so that Re q is
    orthogonal to Im q: v = Re q / |Re q| (J v = -omega M Im q / |Re q|, so
    w = -omega Im q / |Re q|).  (The Hopf curve's start, :func:`contin.hopfcurve.hopf_curve_start`, and the
    two-grid check of a located HB, :func:`contin.specialcheck.hopf_point_error`.)"""
    if q is None:
        from contin.hopf import hopf_vectors

        u = np.asarray(u, float)
        q, _ = hopf_vectors(problem.jacobian(u, params), _mass(problem, u, params, u.size), omega)
    # phase with Re q . Im q = 0: q e^{i t}, tan 2t = 2 a.b / (|a|^2 - |b|^2) ... solved numerically
    a, b = q.real, q.imag
    t = 0.5 * math.atan2(-2 * float(a @ b), float(a @ a - b @ b))
    q = q * complex(math.cos(t), math.sin(t))
    scale = math.sqrt(float(q.real @ q.real))
    return q.real / scale, -omega * q.imag / scale, q.imag / np.linalg.norm(q.imag)
