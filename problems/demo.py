"""Demo problems with known answers (they prove the continuation core).

- :class:`Bratu`: u'' + lam e^u = 0 on [0, 1], u(0) = u(1) = 0.  One fold at
  lam* = 3.513830719125162: the exact solutions are u = -2 ln[cosh((x - 1/2) theta/2) / cosh(theta/4)]
  with lam = theta^2 / (2 cosh^2(theta/4)), and lam* is the maximum over theta (Bratu 1914,
  Gel'fand 1963).
- :class:`KinkedBratu`: Bratu plus a step source lam^3 [x > 0.3]: a solution with a jump in u''
  (algebraically falling Chebyshev coefficients), for adaptive resolution's slow-decay paths.
- :class:`StretchedBratu`: Bratu on the stretched coordinate s = (e^{a x} - 1)/(e^a - 1), a second
  parameter a: fold curve lam = lam*/(1 + a), fold state Bratu's compressed into a layer of width
  ~ 1/a (the grid a tolerance needs grows along the curve: segment-wise regridding's test).
- :class:`AllenCahn`: u'' + lam (u - u^3) = 0 on [0, pi], Dirichlet.  Supercritical
  pitchforks off u = 0 at lam = k^2 (the Dirichlet eigenvalues of -d^2/dx^2 on [0, pi]);
  symmetry u -> -u (Chafee & Infante, Applicable Anal. 4, 1974).
- :class:`ImperfectPitchfork`: x^3 - lam x + alpha + beta x^2 = 0 (scalar); folds where also
  3x^2 + 2 beta x - lam = 0, i.e. alpha = 2x^3 + beta x^2, lam = 3x^2 + 2 beta x.
- :class:`Transcritical`: lam x - x^2 = 0 (scalar); branches x = 0 and x = lam cross at 0.
- :class:`Isola`: x^2 + (lam - c)^2 - r^2 = 0 (scalar); a closed curve with folds at lam = c +- r.
- :class:`COOxidation`: BifurcationKit's CO-oxidation model (two Hopf points, two folds in q2;
  BT points on its Hopf and fold curves in (q2, k)).
- :class:`Brusselator`: the 1-D Brusselator (Prigogine & Lefever 1968) as a two-field BVP with a
  mass matrix; its homogeneous state has a Hopf point at b_H = 1 + a^2 + (D1 + D2) lam_1 / L^2
  (lam_1 = pi^2, or the grid's smallest Dirichlet eigenvalue of -d^2/dx^2): the non-granular
  test problem of the two-grid check of Hopf points (``contin.specialcheck.hopf_point_error``).
- :class:`Lorenz`: the Lorenz (1963) system; its equilibria C+- = (+-sqrt(beta (rho - 1)), ..,
  rho - 1) lose stability at a subcritical Hopf point rho_H = sigma (sigma + beta + 3) /
  (sigma - beta - 1) (470/19 at sigma = 10, beta = 8/3) with omega^2 = beta (sigma + rho_H).

The BVPs use ``problems.discretization.make_grid`` on y in [-1/2, 1/2] with the physical
coordinate x = L (y + 1/2); boundary rows of the collocation system are replaced by the
Dirichlet conditions.  All Jacobians are analytic and sparse.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

from problems.discretization import (MIN_INTERVALS, Grid, chebyshev_coefficients, chebyshev_tail, chebyshev_tail_sum,
                                     make_grid)

Array = np.ndarray

EPS = float(np.finfo(float).eps)

#: The Bratu fold (Gel'fand 1963; e.g. Mohsen, Comput. Math. Appl. 2014, to 16 digits).
BRATU_FOLD = 3.513830719125162


def point_weights(grid: Grid, y0: float) -> Array:
    """w with w . f = interpolant of f at y0 (the grid's own interpolation, as a row vector)."""
    return grid.interpolate(np.eye(grid.size), np.array([y0]))[0]


class _DirichletBVP:
    """u'' / L^2 + g(u, p) = 0 on x in [0, L] with u = 0 at both ends."""

    parameter_names: tuple[str, ...] = ("lam",)
    length = 1.0

    def __init__(self, method: str = "cheb", intervals: int = 32) -> None:
        self.grid = make_grid(method, intervals)
        n = self.grid.size
        self.n = n
        self.interior = np.ones(n, dtype=bool)
        self.interior[[0, -1]] = False
        mask = sp.diags(self.interior.astype(float))
        self._d2 = sp.csr_matrix(mask @ self.grid.d2 / self.length**2)
        self._bc = sp.diags((~self.interior).astype(float), format="csr")
        self.x = self.length * (self.grid.y + 0.5)
        # Fixed sparsity pattern of J = D2 (interior rows) + I (boundary rows) + diag(g_u):
        # only the diagonal values change from one Jacobian to the next.
        base = sp.csr_matrix(self._d2 + self._bc + sp.identity(n, format="csr"))
        base.sort_indices()
        rows = np.repeat(np.arange(n), np.diff(base.indptr))
        self._diag_pos = np.flatnonzero(base.indices == rows)
        base.data[self._diag_pos] = (self._d2 + self._bc).diagonal()
        self._base = base

    def _g(self, u: Array, lam: float) -> Array:
        raise NotImplementedError

    def _g_u(self, u: Array, lam: float) -> Array:
        raise NotImplementedError

    def _g_lam(self, u: Array, lam: float) -> Array:
        raise NotImplementedError

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        lam = p["lam"]
        out = self._d2 @ u + np.where(self.interior, self._g(u, lam), 0.0)
        out[~self.interior] = u[~self.interior]
        return out

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        jac = self._base.copy()
        jac.data[self._diag_pos] += np.where(self.interior, self._g_u(u, p["lam"]), 0.0)
        return jac

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        if name != "lam":
            raise ValueError(f"unknown parameter {name!r}")
        return np.where(self.interior, self._g_lam(u, p["lam"]), 0.0)

    def integrate(self, f: Array) -> float:
        """Integral over x in [0, L]."""
        return float(self.length * self.grid.integrate(f))

    def validate(self, p: Mapping[str, float]) -> None:
        if not np.isfinite(p["lam"]):
            raise ValueError(f"lam must be finite, got {p['lam']}")

    def inner_product_weights(self, u: Array, p: Mapping[str, float]) -> Array:
        """The grid's quadrature weights over x in [0, L] (trapezoid-like of the scheme's order
        for FD, Clenshaw-Curtis for Chebyshev; all > 0, the walls included): sum w v^2 is the
        L2 norm^2 of a perturbation v, the norm in which contin normalises the eigenvectors of
        its normal forms (``contin.problem``), so that they converge with the grid."""
        return self.length * self.grid.weights

    # --- grid hooks (adaptive resolution, contin.adapt) ---------------------------------------
    @property
    def grid_size(self) -> int:
        """Number of grid intervals N."""
        return self.grid.intervals

    @property
    def convergence_order(self) -> float:
        """The grid's nominal order (fd2/fd4/fd6: 2, 4, 6; Chebyshev: inf): the contin hook that
        scales two-grid differences to the coarse grid's error (``contin.adapt.richardson``)."""
        return float(self.grid.order)

    def with_grid(self, intervals: int) -> _DirichletBVP:
        """The same problem on the grid of the same method with ``intervals`` intervals."""
        return type(self)(self.grid.method, int(intervals))

    def transfer(self, u: Array, other: _DirichletBVP) -> Array:
        """u carried onto ``other``'s nodes by this grid's interpolant (barycentric for Chebyshev,
        local Lagrange of the scheme's order for FD); linear in u, exact at shared nodes (the walls)."""
        return self.grid.interpolate(np.asarray(u, dtype=float), other.grid.y)

    def error_estimate(self, u: Array, p: Mapping[str, float]) -> float:
        """Estimated relative error of the discrete solution u.

        Chebyshev: the relative coefficient tail (``problems.discretization.chebyshev_tail``).
        FD of order q (fd2, fd4): the relative truncation error of the scheme at u, i.e.
        max |(D2_q - D2_{q+2}) u| / max |D2_q u| with the order-(q+2) operator on the same nodes
        as the reference (a defect estimate: the error of u is this defect carried through the
        smooth inverse operator, the same size for these BVPs away from the fold).  fd6 has no
        higher-order scheme here: ValueError.
        """
        return self.vector_error(u)

    def vector_error(self, v: Array) -> float:
        """The estimate of :meth:`error_estimate` for any grid function v (a tangent or null vector)."""
        v = np.asarray(v, dtype=float)
        g = self.grid
        if g.method == "cheb":
            return chebyshev_tail(v)
        if g.method not in ("fd2", "fd4"):
            raise ValueError(f"no error estimate for {g.method} (adaptive resolution supports cheb, fd2 and fd4)")
        higher = f"fd{int(g.order) + 2}"
        if g.intervals < MIN_INTERVALS[higher]:
            # too few intervals for the reference scheme (fd4 on 8: fd6 needs 12): no estimate, so
            # adaptive resolution does not coarsen to this grid (it stopped `contin trace bratu
            # --method fd4 --tol 1e-6` with "grid too small" at min_grid 8)
            return math.inf
        ref = make_grid(higher, g.intervals)
        d2u = g.d2 @ v
        scale = float(np.max(np.abs(d2u[1:-1]))) if v.size > 2 else 0.0
        return float(np.max(np.abs((g.d2 - ref.d2) @ v)[1:-1]) / scale) if scale > 0 else 0.0


    def suggest_vector_grid(self, v: Array, tol: float) -> float:
        """The grid at which :meth:`vector_error` of v is expected to meet tol / 10.  Chebyshev:
        from the geometric decay rate of the coefficient envelope (least squares on the log of
        the 4-blocks' maxima over the upper half of the spectrum; Boyd, *Chebyshev and Fourier
        Spectral Methods*, 2nd ed., sec. 2.12).  FD of order q: the defect falls like N^-q.
        At least 1.5 N, at most 8 N."""
        n = self.grid.intervals
        err = self.vector_error(v)
        target = tol / 10.0
        want = 1.5 * n
        if err > target:
            if self.grid.method == "cheb":
                a = np.abs(chebyshev_coefficients(np.asarray(v, dtype=float)))
                k = np.arange(n // 2, n - 2)
                if k.size >= 2:
                    env = np.maximum([a[j:j + 4].max() for j in k], 1e-300)
                    slope = float(np.polyfit(k, np.log(env), 1)[0])
                    if slope < -1e-3:
                        want = max(want, n + math.log(target / err) / slope)
            else:
                want = max(want, n * (err / target) ** (1.0 / self.grid.order))
        return min(want, 8.0 * n)


class Bratu(_DirichletBVP):
    """u'' + lam e^u = 0 on [0, 1], u(0) = u(1) = 0.

    Order parameter: u(1/2), the maximum of the (symmetric, positive) solution.
    Symmetry: the reflection x -> 1 - x (a permutation of the symmetric grid).
    """

    length = 1.0

    def __init__(self, method: str = "cheb", intervals: int = 32) -> None:
        super().__init__(method, intervals)
        self._mid = point_weights(self.grid, 0.0)

    def _g(self, u: Array, lam: float) -> Array:
        return lam * np.exp(u)

    def _g_u(self, u: Array, lam: float) -> Array:
        return lam * np.exp(u)

    def _g_lam(self, u: Array, lam: float) -> Array:
        return np.exp(u)

    def order_parameter(self, u: Array, p: Mapping[str, float]) -> float:
        return float(self._mid @ u)

    def observables(self, u: Array, p: Mapping[str, float]) -> dict[str, float]:
        return {"u_max": float(np.max(u)), "l2": float(np.sqrt(self.integrate(u * u)))}

    def symmetry(self, u: Array) -> Array:
        return np.asarray(u)[::-1].copy()

    def initial(self) -> Array:
        return np.zeros(self.n)


class StretchedBratu(Bratu):
    """Bratu mapped onto a stretched coordinate: v(x) = u(s(x)) with s = (e^{a x} - 1) / (e^a - 1),

        v'' - a v' + lam (1 + a) k(a)^2 e^{2 a x} e^v = 0 on [0, 1],   v(0) = v(1) = 0,
        k(a) = a / (e^a - 1)   (k(0) = 1: a = 0 is Bratu itself).

    u solves Bratu u'' + lam (1 + a) e^u = 0, so the folds are those of Bratu at
    lam (1 + a) = lam*: the fold curve in (lam, a) is lam = lam* / (1 + a) (a > -1), and the fold
    state is Bratu's fold solution u* compressed towards x = 1 (a > 0) or x = 0 (a < 0) into a
    layer of width ~ 1/|a|, so the grid a tolerance needs grows along the curve with |a|: the
    non-granular test problem of segment-wise regridding of fold curves
    (:class:`contin.foldcurve.SegmentRegrid`).  With the resolution guard ``under_resolved``
    (the Chebyshev tail of the state against tol) and ``suggest_grid``.
    """

    parameter_names = ("lam", "a")

    #: No reflection symmetry: the stretching breaks Bratu's x -> 1 - x for every a != 0.
    #: Inherited, it made every trace from u = 0 (which is reflection-invariant) an S-invariant
    #: branch of a problem that is not equivariant: at any a != 0 the first step failed at ds_min
    #: (`contin trace stretched-bratu -s a=0.5`: MX at lam = 2.4e-5) or ended MX after storing a
    #: point 0.47 off its solution (a = 4) (session 15).  ``contin.problem.has`` finds no callable hook.
    symmetry = None

    def __init__(self, method: str = "cheb", intervals: int = 32) -> None:
        super().__init__(method, intervals)
        mask = sp.diags(self.interior.astype(float))
        self._d1 = sp.csr_matrix(mask @ self.grid.d1 / self.length)

    @staticmethod
    def _k2(a: float) -> tuple[float, float]:
        """k(a)^2 and d ln k / da (series near a = 0)."""
        if abs(a) < 1e-4:
            k = 1.0 - a / 2.0 + a * a / 12.0
            return k * k, -0.5 + a / 12.0
        k = a / math.expm1(a)
        return k * k, 1.0 / a - 1.0 / (-math.expm1(-a))

    def _source(self, a: float, lam: float) -> Array:
        """lam (1 + a) k(a)^2 e^{2 a x} (interior rows; the walls are Dirichlet rows)."""
        k2, _ = self._k2(a)
        return lam * (1.0 + a) * k2 * np.exp(2.0 * a * self.x)

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        a = float(p["a"])
        out = self._d2 @ u - a * (self._d1 @ u) + np.where(self.interior, self._source(a, p["lam"]) * np.exp(u), 0.0)
        out[~self.interior] = u[~self.interior]
        return out

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        a = float(p["a"])
        diag = np.where(self.interior, self._source(a, p["lam"]) * np.exp(u), 0.0)
        return sp.csr_matrix(self._d2 + self._bc - a * self._d1 + sp.diags(diag))

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        a, lam = float(p["a"]), float(p["lam"])
        if name == "lam":
            return np.where(self.interior, self._source(a, 1.0) * np.exp(u), 0.0)
        if name == "a":
            _, dlnk = self._k2(a)
            ds = self._source(a, lam) * (1.0 / (1.0 + a) + 2.0 * dlnk + 2.0 * self.x)
            return np.where(self.interior, ds * np.exp(u) - self._d1 @ u, 0.0)
        raise ValueError(f"unknown parameter {name!r}")

    def mass_matrix(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        """The identity on the interior rows (dynamics v_t = v'' - a v' + ...), zero on the two
        Dirichlet rows (algebraic).  Without it the stability pass of the ``stretched-bratu`` scene
        (which has a problem_factory) solved with M = I and counted the boundary rows v_0 = 0,
        v_N = 0 as two unstable modes: the stable lower branch was stored as unstable (qa14)."""
        return sp.diags(self.interior.astype(float), format="csr")

    #: Largest a: the source k(a)^2 e^{2 a x} overflows double precision past a = 354 (e^{2a} at
    #: x = 1), and the layer of width ~1/a needs ~a Chebyshev intervals (a = 300: cheb 480 at the
    #: fold for tol 1e-10; max_grid is 512).  `-s a=1e6` printed "OverflowError: math range error".
    A_MAX = 350.0

    @classmethod
    def check_a(cls, a: float) -> None:
        """ValueError naming the valid range of a and why, for an a outside it."""
        if not (np.isfinite(a) and -1.0 < a <= cls.A_MAX):
            raise ValueError(f"a = {a:g} is out of range: it must be > -1 (the source lam (1 + a) k(a)^2 "
                             f"e^(2 a x) e^v changes sign at a = -1: Bratu at lam (1 + a) <= 0 has no fold) and <= {cls.A_MAX:g} (the source term k(a)^2 e^(2 a x) "
                             f"overflows double precision beyond a = 354, and its layer of width ~1/a needs ~a "
                             f"grid intervals)")

    def validate(self, p: Mapping[str, float]) -> None:
        super().validate(p)
        self.check_a(p["a"])

    def under_resolved(self, u: Array, p: Mapping[str, float], tol: float) -> str | None:
        """The resolution guard: None if the state's estimate (:meth:`error_estimate`) is <= tol."""
        err = self.error_estimate(u, p)
        if err <= tol:
            return None
        return f"estimated relative error {err:.2g} > {tol:.2g} on {self.grid.method} {self.grid.intervals}"

    def suggest_grid(self, u: Array, p: Mapping[str, float], tol: float) -> float:
        """The grid at which the state's estimate is expected to meet tol / 10
        (:meth:`suggest_vector_grid`)."""
        return self.suggest_vector_grid(u, tol)

    @staticmethod
    def fold_curve(a: Array | float) -> Array:
        """The exact fold curve: lam = lam* / (1 + a)."""
        return BRATU_FOLD / (1.0 + np.asarray(a, dtype=float))

    def fold_state(self, a: float) -> Array:
        """The exact fold state at a on this grid: u*(s(x)), u* = -2 ln[cosh((s - 1/2) theta*/2) /
        cosh(theta*/4)] with theta* the root of (theta/4) tanh(theta/4) = 1."""
        from scipy.optimize import brentq

        theta = 4.0 * brentq(lambda z: z * math.tanh(z) - 1.0, 0.5, 2.0)
        s = self.x if abs(a) < 1e-12 else np.expm1(a * self.x) / math.expm1(a)
        return -2.0 * np.log(np.cosh((s - 0.5) * theta / 2.0) / math.cosh(theta / 4.0))


class KinkedBratu(_DirichletBVP):
    """u'' + lam e^u + lam^3 s(x) = 0 on [0, 1], u(0) = u(1) = 0, with the step s = 1 for
    x > X0 = 0.3, else 0: a source with a jump, so u'' jumps by lam^3 at X0, u is only C^1,1 and
    its Chebyshev coefficients fall algebraically, |a_k| ~ k^-3 (Boyd, *Chebyshev and Fourier
    Spectral Methods*, 2nd ed., sec. 2.6), with a weight ~ lam^2 relative to the smooth part.
    The non-granular test problem of adaptive resolution's slow-decay paths (the tail sum of
    ``problems.discretization.chebyshev_tail_sum`` and the "resolution limit" end of
    ``contin.adapt``); no symmetry (X0 is off-centre).

    Estimate (Chebyshev): the relative coefficient tail or, where larger, the extrapolated sum of
    the omitted coefficients (what the last coefficients under-state when they fall slowly).
    """

    length = 1.0
    X0 = 0.3

    def __init__(self, method: str = "cheb", intervals: int = 32) -> None:
        super().__init__(method, intervals)
        self._step = (self.x > self.X0).astype(float)

    def _g(self, u: Array, lam: float) -> Array:
        return lam * np.exp(u) + lam**3 * self._step

    def _g_u(self, u: Array, lam: float) -> Array:
        return lam * np.exp(u)

    def _g_lam(self, u: Array, lam: float) -> Array:
        return np.exp(u) + 3.0 * lam**2 * self._step

    def order_parameter(self, u: Array, p: Mapping[str, float]) -> float:
        return float(np.max(u))

    def initial(self) -> Array:
        return np.zeros(self.n)

    def vector_error(self, v: Array) -> float:
        if self.grid.method != "cheb":
            return super().vector_error(v)
        a = np.abs(chebyshev_coefficients(np.asarray(v, dtype=float)))
        scale = float(np.max(a)) if a.size else 0.0
        if scale == 0:
            return 0.0
        return float(max(np.max(a[-4:]), chebyshev_tail_sum(a)[0]) / scale)


class AllenCahn(_DirichletBVP):
    """u'' + lam (u - u^3) = 0 on [0, pi], u(0) = u(pi) = 0.

    Order parameter: u(pi/5), a point where none of the modes sin(kx), k = 1..4, vanishes,
    so it separates the modes and the two signs of each.  Observable ``nodes``: interior sign
    changes of u (the mode number minus one).  Symmetry: u -> -u.
    """

    length = np.pi

    def __init__(self, method: str = "cheb", intervals: int = 32) -> None:
        super().__init__(method, intervals)
        self._probe = point_weights(self.grid, 0.2 - 0.5)

    def _g(self, u: Array, lam: float) -> Array:
        return lam * (u - u**3)

    def _g_u(self, u: Array, lam: float) -> Array:
        return lam * (1.0 - 3.0 * u**2)

    def _g_lam(self, u: Array, lam: float) -> Array:
        return u - u**3

    def order_parameter(self, u: Array, p: Mapping[str, float]) -> float:
        return float(self._probe @ u)

    def observables(self, u: Array, p: Mapping[str, float]) -> dict[str, float]:
        inner = u[1:-1]
        scale = max(float(np.max(np.abs(u))), 1e-300)
        significant = inner[np.abs(inner) > 1e-8 * scale]
        nodes = int(np.count_nonzero(np.diff(np.sign(significant)))) if scale > 1e-12 else 0
        return {"max_abs": float(np.max(np.abs(u))), "nodes": float(nodes)}

    def symmetry(self, u: Array) -> Array:
        return -np.asarray(u)

    def symmetry_matrix(self) -> sp.csr_matrix:
        return -sp.identity(self.n, format="csr")

    def initial(self) -> Array:
        return np.zeros(self.n)


class _Scalar:
    """Helpers for scalar problems: u is a length-1 array."""

    def order_parameter(self, u: Array, p: Mapping[str, float]) -> float:
        return float(u[0])

    @staticmethod
    def _j(value: float) -> sp.csr_matrix:
        return sp.csr_matrix(np.array([[float(value)]]))


class ImperfectPitchfork(_Scalar):
    """F(x) = x^3 - lam x + alpha + beta x^2 (parameters lam, alpha, beta)."""

    parameter_names = ("lam", "alpha", "beta")

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        x = u[0]
        return np.array([x**3 - p["lam"] * x + p["alpha"] + p["beta"] * x**2])

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        x = u[0]
        return self._j(3 * x**2 - p["lam"] + 2 * p["beta"] * x)

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        x = u[0]
        return np.array([{"lam": -x, "alpha": 1.0, "beta": x**2}[name]])

    @staticmethod
    def folds(alpha: float, beta: float) -> list[tuple[float, float]]:
        """Analytic folds (lam, x): real roots of 2x^3 + beta x^2 - alpha = 0, lam = 3x^2 + 2 beta x."""
        roots = np.roots([2.0, beta, 0.0, -alpha])
        xs = sorted(float(r.real) for r in roots if abs(r.imag) < 1e-12)
        return [(3 * x**2 + 2 * beta * x, x) for x in xs]


class Transcritical(_Scalar):
    """F(x) = lam x - x^2: the branches x = 0 and x = lam cross transcritically at lam = 0."""

    parameter_names = ("lam",)

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        return np.array([p["lam"] * u[0] - u[0] ** 2])

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        return self._j(p["lam"] - 2 * u[0])

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        return np.array([u[0]])


class Isola(_Scalar):
    """F(x) = x^2 + (lam - c)^2 - r^2: the circle of radius r about (x, lam) = (0, c).

    J = 2x vanishes only at the two folds (x, lam) = (0, c +- r); F_lam = 2 (lam - c) is
    nonzero there, so the curve is smooth and closed (an isola).
    """

    parameter_names = ("lam", "c", "r")

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        return np.array([u[0] ** 2 + (p["lam"] - p["c"]) ** 2 - p["r"] ** 2])

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        return self._j(2 * u[0])

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        d = {"lam": 2 * (p["lam"] - p["c"]), "c": -2 * (p["lam"] - p["c"]), "r": -2 * p["r"]}
        return np.array([d[name]])


class DetachedIsola(_Scalar):
    """F(x) = x ((x - 2)^2 + lam^2 - mu): the line x = 0 and the circle of radius sqrt(mu) about
    (lam, x) = (0, 2).

    For 0 < mu < 4 the two sets are disjoint and F's gradient vanishes on neither (on x = 0,
    F_x = 4 + lam^2 - mu > 0; on the circle F_x = 2x (x - 2), F_lam = 2 lam x, not both zero),
    so the circle is an isola with folds at lam = +-sqrt(mu), x = 2, unreachable from x = 0 by
    continuation or switching.  For mu > 4 the circle crosses x = 0 transversally at
    lam = +-sqrt(mu - 4) (two simple BPs of the line; at mu = 4 it touches it), so a homotopy in
    mu from a state of the circle switched there reaches the isola -- the route by which
    isolas of imperfect bifurcations are found (Golubitsky & Schaeffer, Singularities and
    Groups in Bifurcation Theory I, 1985, ch. III: the isola centre x^2 + lam^2 - mu).
    """

    parameter_names = ("lam", "mu")

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        x = u[0]
        return np.array([x * ((x - 2) ** 2 + p["lam"] ** 2 - p["mu"])])

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        x = u[0]
        return self._j((x - 2) ** 2 + p["lam"] ** 2 - p["mu"] + 2 * x * (x - 2))

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        x = u[0]
        return np.array([{"lam": 2 * p["lam"] * x, "mu": -x}[name]])


class Lorenz:
    """x' = sigma (y - x), y' = rho x - y - x z, z' = x y - beta z (parameters sigma, rho, beta)."""

    parameter_names = ("sigma", "rho", "beta")

    def mass_matrix(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        """An ODE: every row is dynamic (M = I)."""
        return sp.identity(3, format="csr")

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        x, y, z = u
        return np.array([p["sigma"] * (y - x), p["rho"] * x - y - x * z, x * y - p["beta"] * z])

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        x, y, z = u
        s, r, b = p["sigma"], p["rho"], p["beta"]
        return sp.csr_matrix(np.array([[-s, s, 0.0], [r - z, -1.0, -x], [y, x, -b]]))

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        x, y, z = u
        return {"sigma": np.array([y - x, 0.0, 0.0]), "rho": np.array([0.0, x, 0.0]),
                "beta": np.array([0.0, 0.0, -z])}[name]

    def order_parameter(self, u: Array, p: Mapping[str, float]) -> float:
        return float(u[2])  # z, AUTO's usual axis for Lorenz

    @staticmethod
    def equilibrium(p: Mapping[str, float]) -> Array:
        """C+ = (sqrt(beta (rho - 1)), sqrt(beta (rho - 1)), rho - 1) for rho > 1."""
        x = float(np.sqrt(p["beta"] * (p["rho"] - 1)))
        return np.array([x, x, p["rho"] - 1])


class AB:
    """AUTO-07p's demo ``ab`` (the A -> B reaction in a CSTR; AUTO's demos/ab/ab.f90, Doedel's
    tutorial): F1 = -u1 + D (1 - u1) e^{u2},  F2 = -u2 + D B (1 - u1) e^{u2} - beta u2
    (PAR(1..3) = D, B, beta).  u = 0 solves it at D = 0 for every B; continued in D (beta = 3,
    B = 14) it has two Hopf points, the lower subcritical and the upper supercritical, which its
    Hopf curve in (D, B) joins through a generalized Hopf point (GH)."""

    parameter_names = ("D", "B", "beta")

    def mass_matrix(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        """An ODE: every row is dynamic (M = I)."""
        return sp.identity(2, format="csr")

    def residual(self, u: Array, p: Mapping[str, float]) -> Array:
        u1, u2 = u
        h = p["D"] * (1 - u1) * np.exp(u2)
        return np.array([-u1 + h, -u2 + p["B"] * h - p["beta"] * u2])

    def jacobian(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        u1, u2 = u
        e, b = p["D"] * np.exp(u2), p["B"]
        return sp.csr_matrix(np.array([[-1 - e, (1 - u1) * e],
                                       [-b * e, -1 + b * (1 - u1) * e - p["beta"]]]))

    def dresidual_dp(self, u: Array, p: Mapping[str, float], name: str) -> Array:
        u1, u2 = u
        g = (1 - u1) * np.exp(u2)  # h / D
        return {"D": np.array([g, p["B"] * g]), "B": np.array([0.0, p["D"] * g]),
                "beta": np.array([0.0, -u2])}[name]

    def order_parameter(self, u: Array, p: Mapping[str, float]) -> float:
        return float(u[0])  # u1, AUTO's first solution measure in the demo


class COOxidation:
    """CO oxidation (Bykov-Yablonskii-Kim; BifurcationKit's tutorialCO), z = 1 - x - y - s:
    x' = 2 q1 z^2 - 2 q5 x^2 - q3 x y, y' = q2 z - q6 y - q3 x y, s' = q4 z - k q4 s.
    In q2 at the tutorial's parameters: two Hopf points and two folds near q2 = 1.04-1.05."""

    parameter_names = ("q1", "q2", "q3", "q4", "q5", "q6", "k")
    PARAMS = dict(q1=2.5, q2=0.6, q3=10.0, q4=0.0675, q5=1.0, q6=0.1, k=0.4)

    def mass_matrix(self, u: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        """An ODE: every row is dynamic (M = I)."""
        return sp.identity(3, format="csr")

    def residual(self, u, p):
        x, y, s = u
        z = 1 - x - y - s
        return np.array([2 * p["q1"] * z**2 - 2 * p["q5"] * x**2 - p["q3"] * x * y,
                         p["q2"] * z - p["q6"] * y - p["q3"] * x * y,
                         p["q4"] * z - p["k"] * p["q4"] * s])

    def jacobian(self, u, p):
        x, y, s = u
        z = 1 - x - y - s
        q1, q2, q3, q4, q5, q6, k = (p[n] for n in self.parameter_names)
        dz = -4 * q1 * z
        return np.array([  # dense: contin accepts a dense J for tiny problems (and it is faster)
            [dz - 4 * q5 * x - q3 * y, dz - q3 * x, dz],
            [-q2 - q3 * y, -q2 - q6 - q3 * x, -q2],
            [-q4, -q4, -q4 - k * q4]])

    def dresidual_dp(self, u, p, name):
        x, y, s = u
        z = 1 - x - y - s
        columns = {"q1": [2 * z * z, 0, 0], "q2": [0, z, 0], "q3": [-x * y, -x * y, 0],
                   "q4": [0, 0, z - p["k"] * s], "q5": [-2 * x * x, 0, 0], "q6": [0, -y, 0],
                   "k": [0, 0, -p["q4"] * s]}
        return np.array(columns[name], dtype=float)


class Brusselator(_DirichletBVP):
    """The 1-D Brusselator (Prigogine & Lefever 1968) as a two-field BVP on x in [0, 1]:

        u_t = (D1/L^2) u_xx + a - (b + 1) u + u^2 v,   v_t = (D2/L^2) v_xx + b u - u^2 v,
        u = a, v = b/a at both ends,

    state [u at the nodes, v at the nodes] (2 (N + 1) unknowns), parameters b, a, D1, D2, L; the
    mass matrix is the identity on the interior rows and zero on the boundary rows.  The
    homogeneous state (a, b/a) solves it for every b (exact on every grid).  Its linearisation
    on a Dirichlet eigenfunction of -d^2/dx^2 with eigenvalue lam_k (k^2 pi^2 in the continuum)
    has trace b - 1 - a^2 - (D1 + D2) lam_k / L^2 and determinant
    a^2 (1 + d1) + d2 (d1 + 1 - b) (d_i = D_i lam_k / L^2), so the first Hopf point (k = 1,
    where that determinant is > 0) is at

        b_H = 1 + a^2 + (D1 + D2) lam_1 / L^2,   omega_H^2 = a^2 (1 + d1 - d2) - d2^2

    (:meth:`hopf_point`); on a grid lam_1 is the smallest eigenvalue of the discrete -d^2/dx^2
    with Dirichlet ends (fd2: 4/h^2 sin^2(pi h / 2)), the same formula (the fields share the
    operator, so the pencil splits mode by mode exactly).  At the defaults (a = 2, D1 = 0.02,
    D2 = 0.01, L = 1) b_H = 5 + 0.03 pi^2 = 5.2961, omega_H = 2.094, the next Hopf point
    (k = 2) at b = 6.18 and the first Turing instability (a real eigenvalue through 0) at
    b = 14.7: the Hopf point is the first instability.
    """

    parameter_names = ("b", "a", "D1", "D2", "L")
    PARAMS = {"a": 2.0, "D1": 0.02, "D2": 0.01, "L": 1.0}
    #: A field's non-linear part at most this many ulps of the field is rounding (:meth:`_fields`).
    ROUNDING_ULPS = 1e3

    def __init__(self, method: str = "cheb", intervals: int = 32) -> None:
        super().__init__(method, intervals)
        self.nodes = self.n  # N + 1 per field
        self.n = 2 * self.nodes  # unknowns
        diag = np.tile(self.interior.astype(float), 2)
        self._mass = sp.diags(diag, format="csr")
        self._bc2 = sp.diags(1.0 - diag, format="csr")
        self._mid_weights: Array | None = None

    # --- the two fields -----------------------------------------------------------------------
    def split(self, x: Array) -> tuple[Array, Array]:
        x = np.asarray(x)
        return x[:self.nodes], x[self.nodes:]

    def residual(self, x: Array, p: Mapping[str, float]) -> Array:
        u, v = self.split(x)
        a, b, l2 = p["a"], p["b"], p["L"] ** 2
        inner = self.interior
        fu = p["D1"] / l2 * (self._d2 @ u) + np.where(inner, a - (b + 1.0) * u + u * u * v, 0.0)
        fv = p["D2"] / l2 * (self._d2 @ v) + np.where(inner, b * u - u * u * v, 0.0)
        fu[~inner] = u[~inner] - a
        fv[~inner] = v[~inner] - b / a
        return np.concatenate([fu, fv])

    def jacobian(self, x: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        u, v = self.split(x)
        b, l2 = p["b"], p["L"] ** 2
        inner = self.interior.astype(float)
        return sp.csr_matrix(sp.bmat([
            [p["D1"] / l2 * self._d2 + sp.diags(inner * (2.0 * u * v - (b + 1.0))), sp.diags(inner * u * u)],
            [sp.diags(inner * (b - 2.0 * u * v)), p["D2"] / l2 * self._d2 - sp.diags(inner * u * u)],
        ]) + self._bc2)

    def mass_matrix(self, x: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        """The identity on the interior rows (dynamics), zero on the boundary rows (algebraic)."""
        return self._mass

    def dresidual_dp(self, x: Array, p: Mapping[str, float], name: str) -> Array:
        u, v = self.split(x)
        inner = self.interior
        a, b, l2 = p["a"], p["b"], p["L"] ** 2
        zero = np.zeros_like(u, dtype=float)
        if name == "b":
            fu, fv = np.where(inner, -u, 0.0), np.where(inner, u, -1.0 / a)
        elif name == "a":
            fu, fv = np.where(inner, 1.0, -1.0), np.where(inner, 0.0, b / a**2)
        elif name == "D1":
            fu, fv = self._d2 @ u / l2, zero
        elif name == "D2":
            fu, fv = zero, self._d2 @ v / l2
        elif name == "L":
            fu, fv = -2.0 * p["D1"] / l2 / p["L"] * (self._d2 @ u), -2.0 * p["D2"] / l2 / p["L"] * (self._d2 @ v)
        else:
            raise ValueError(f"unknown parameter {name!r}")
        return np.concatenate([fu, fv])

    def validate(self, p: Mapping[str, float]) -> None:
        for name in self.parameter_names:
            if not np.isfinite(p[name]):
                raise ValueError(f"{name} must be finite, got {p[name]}")
        if p["a"] == 0 or p["L"] <= 0:
            raise ValueError(f"need a != 0 and L > 0, got a={p['a']}, L={p['L']}")

    def inner_product_weights(self, x: Array, p: Mapping[str, float]) -> Array:
        """The grid's quadrature weights for each field: sum w |q|^2 = int |q_u|^2 + |q_v|^2 dx
        (the L2 norm of the pair (u, v) on [0, 1]; l1 of the Hopf point converges with it)."""
        return np.tile(self.length * self.grid.weights, 2)

    def homogeneous(self, p: Mapping[str, float]) -> Array:
        """The homogeneous state (a, b/a)."""
        return np.concatenate([np.full(self.nodes, float(p["a"])), np.full(self.nodes, p["b"] / p["a"])])

    def order_parameter(self, x: Array, p: Mapping[str, float]) -> float:
        return float(self._mid @ self.split(x)[1])

    def observables(self, x: Array, p: Mapping[str, float]) -> dict[str, float]:
        u, v = self.split(x)
        return {"u_mid": float(self._mid @ u), "v_mid": float(self._mid @ v)}

    @property
    def _mid(self) -> Array:
        """Interpolation weights of x = 1/2 (computed once per grid)."""
        if self._mid_weights is None:
            self._mid_weights = point_weights(self.grid, 0.0)
        return self._mid_weights

    def dirichlet_eigenvalue(self) -> float:
        """The smallest eigenvalue of this grid's -d^2/dx^2 with Dirichlet ends (interior block)."""
        inner = self.grid.d2[1:-1, 1:-1]
        w = np.linalg.eigvals(-inner.toarray() if sp.issparse(inner) else -np.asarray(inner))
        return float(np.min(w.real))

    @staticmethod
    def hopf_point(p: Mapping[str, float], lam: float = math.pi**2) -> tuple[float, float]:
        """(b_H, omega_H) of the k = 1 Hopf point for the Dirichlet eigenvalue lam (class docstring)."""
        a, l2 = p["a"], p["L"] ** 2
        d1, d2 = p["D1"] * lam / l2, p["D2"] * lam / l2
        return 1.0 + a * a + d1 + d2, math.sqrt(a * a * (1.0 + d1 - d2) - d2 * d2)

    # --- grid hooks: the scalar grid's, field by field ---------------------------------------
    def transfer(self, x: Array, other: Brusselator) -> Array:
        """Each field carried by the grid's interpolant (linear, exact at the walls)."""
        x = np.asarray(x, dtype=float)
        cols = np.stack(self.split(x), axis=1)
        return np.asarray(self.grid.interpolate(cols, other.grid.y), dtype=float).T.ravel()

    def _fields(self, v: Array) -> tuple[Array, Array]:
        """The two fields of v as the scalar estimates see them: on FD grids less their linear
        part between the walls, which every scheme differentiates exactly, and a remainder at
        the field's rounding level (ROUNDING_ULPS) taken as 0: the defect estimate of the
        homogeneous state (a, b/a) is then 0, not rounding over rounding (fd4's D2 of a
        Newton-corrected constant is ~1e-13, and so is its defect: estimate 1.3); Chebyshev
        tails are relative to the whole field."""
        fields = self.split(np.asarray(v, dtype=float))
        if self.grid.method == "cheb":
            return fields
        s = self.grid.y + 0.5
        out = []
        for f in fields:
            g = f - (f[0] + (f[-1] - f[0]) * s)
            size = float(np.max(np.abs(f), initial=0.0))
            rounding = float(np.max(np.abs(g), initial=0.0)) <= self.ROUNDING_ULPS * EPS * size
            out.append(np.zeros_like(g) if rounding else g)
        return out[0], out[1]

    def vector_error(self, v: Array) -> float:
        """The larger of the two fields' estimates (:meth:`_DirichletBVP.vector_error`)."""
        return max(_DirichletBVP.vector_error(self, f) for f in self._fields(v))

    def suggest_vector_grid(self, v: Array, tol: float) -> float:
        return max(_field_suggestion(self, f, tol) for f in self._fields(v))

    def suggest_grid(self, x: Array, p: Mapping[str, float], tol: float) -> float:
        return self.suggest_vector_grid(x, tol)


def _field_suggestion(pb: _DirichletBVP, f: Array, tol: float) -> float:
    """:meth:`_DirichletBVP.suggest_vector_grid` of one field f of a multi-field problem (its
    ``vector_error`` is the fields', not f's)."""
    scalar = _DirichletBVP.__new__(_DirichletBVP)
    scalar.grid = pb.grid
    return _DirichletBVP.suggest_vector_grid(scalar, f, tol)
