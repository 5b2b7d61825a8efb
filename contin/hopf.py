"""Hopf points (label HB): a complex pair of J x = mu M x crossing the imaginary axis.

Detection and location
    At every point of a branch the point test (``contin.pointtests``) computes the finite
    eigenvalues of the pencil (J, M) -- M = I when the problem has no ``mass_matrix`` -- with
    positive imaginary part: all of them by QZ for n <= ``hopf_dense_max``, else the
    ``hopf_eigs`` nearest 0 by shift-invert ARPACK (``contin.stability.eigenvalues``).  Between
    two points, eigenvalues are paired by mutual nearest neighbours; a pair whose real part
    changes sign brackets a Hopf point.  Its test function is

        psi(x) = Re mu(x),   mu(x) the eigenvalue at x nearest the segment [mu_a, mu_b],

    evaluated at points re-corrected onto the branch (not interpolated), so the tracer's
    locator (Anderson-Bjorck regula falsi in arclength, ``contin.locate``) finds its zero to
    ``locate_tol`` like a fold.  Unlike the bialternate product det(2 J (.) I), psi does not
    vanish at neutral saddles (real pairs +-lambda), and it costs one eigen-solve, not an
    n(n-1)/2 determinant (Govaerts, *Numerical Methods for Bifurcations of Dynamical
    Equilibria*, SIAM 2000, ch. 4, on the choice of Hopf test functions).

Reported numbers
    omega = Im mu at the located point, and the first Lyapunov coefficient (Kuznetsov,
    *Elements of Applied Bifurcation Theory*, 3rd ed., eq. (3.20)), generalized to M u' = F:

        l1 = 1/(2 omega) Re[ p^H C(q, q, conj q)
                             - 2 p^H B(q, J^{-1} B(q, conj q))
                             + p^H B(conj q, (2 i omega M - J)^{-1} B(q, q)) ],

    J q = i omega M q, J^T p = -i omega M^T p, q^H W q = 1, p^H M q = 1, with B and C the second
    and third derivatives of F in u (multilinear forms).  B and C are directional derivatives of
    the problem's Jacobian by central differences, B(a, y) = [J(u + h a) - J(u - h a)] y / 2h
    and C(a, b, y) = d^2/dh_a dh_b J y, extended to complex arguments by multilinearity.
    l1 < 0: supercritical (stable cycles born); l1 > 0: subcritical.  For M = I this is
    Kuznetsov's formula exactly (f = M^{-1} F otherwise).  Problems with their own
    ``eigenproblem`` get omega from it and no l1 (their nonlinearity is not J's).

Norm of q
    W = diag(w) is the problem's ``inner_product_weights(u, p)`` (quadrature weights, so that
    q^H W q approximates the L2 norm of the continuous eigenfunction); W = I without the hook
    (q^H q = 1, Kuznetsov's normalisation, bitwise as before the hook).  Under q -> c q (and
    p -> p / conj c) l1 scales by |c|^2, so l1 is a number only together with the norm of q:
    with the Euclidean norm the nodal values of a discretised PDE's q are O(1/sqrt(n)) and l1
    falls like 1/n under refinement (right sign, grid-dependent size); with the weights it
    converges at the scheme's order (fd2 Brusselator: ``tests/test_hopf_norm.py``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.branch import SpecialPoint
from contin.options import HOPF_AUTO_MAX, DetectionOptions
from contin.pointtests import Crossing
from contin.problem import Array, has, inner_product_weights

CArray = np.ndarray
log = logging.getLogger("contin")

#: Relative imaginary part below which an eigenvalue counts as real.
REAL_TOL = 1e-10
#: Relative step of the central differences of J in the multilinear forms (error ~ h^2).
FD_STEP_B = 1e-5
FD_STEP_C = 1e-4
#: Relative error estimate of an HB's l1 accepted at the default steps (session 16 audit)
L1_ACCEPT = 1e-5
#: Relative error estimate of an HB's l1 above which it is reported doubtful (warning, note)
L1_DOUBTFUL = 1e-3


def step_ladder(at: Any, accept: float, decades: int = 6) -> tuple[float, float, float]:
    """(value, estimated absolute error, the multiplier m used) of a coefficient computed by differences of J whose
    steps are all multiplied by m: ``at(m)`` returns (value at m, its difference from the value at
    2 m).  m = 1 first; unless its estimate is below ``accept`` |value|, m walks down by decades
    while the estimate improves, then up, up to ``decades`` each way; the best is kept.  The
    steps are relative to max(1, |u|_inf), which says nothing about the length scale of F's
    nonlinearity: a state scaled by 1e-4 needs steps 1e-4 times smaller, one scaled by 1e4
    larger (l1 and l2 of such a Bautin system were wrong by factors up to 1e15, silently)."""

    def good(v: tuple[float, float, float]) -> bool:
        return v[1] <= accept * abs(v[0])

    first = best = (*at(1.0), 1.0)
    for factor in (0.1, 10.0):
        last, m = first, 1.0
        for _ in range(decades):
            if good(best):
                break
            m *= factor
            v = (*at(m), m)
            best = min(best, v, key=lambda w: w[1])
            if not v[1] < last[1]:
                break  # past the best of this direction
            last = v
    return best


def hopf_test(problem: Any, detection: DetectionOptions, n: int) -> HopfTest | None:
    """The HB point test for a problem with n unknowns, or None when detection is off."""
    on = detection.detect_hopf
    dense_max = detection.hopf_dense_max
    if on is None:  # augmented systems (fold / Hopf curves: ``point_tests``) are not dynamics
        # every n for problems that state their dynamics (``mass_matrix``; M = I is assumed
        # only up to HOPF_AUTO_MAX unknowns: a large discretization without a mass matrix has
        # algebraic rows (boundary conditions) that M = I counts as dynamics -- disks-steady,
        # n ~ 150..400, got a spurious HB with omega = 1e-5 and 29 -> 40 s); dense QZ up to
        # HOPF_AUTO_MAX unknowns, the hopf_eigs eigenvalues nearest 0 by shift-invert above
        # (Brusselator n = 400: 0.8 s instead of 17.5 s dense, the same two HBs)
        on = (not has(problem, "eigenproblem") and not has(problem, "point_tests")
              and (n <= HOPF_AUTO_MAX or has(problem, "mass_matrix")))
        dense_max = min(dense_max, HOPF_AUTO_MAX)
    if not on:
        return None
    return HopfTest(problem, dense_max, detection.hopf_eigs)


def pencil(problem: Any, u: Array, params: dict[str, float]) -> tuple[Any, Any]:
    """(J, M) of the problem at (u, p): ``eigenproblem(kx=0, kz=0)`` if it has one."""
    from contin.stability import operator_pair

    return operator_pair(problem, u, params)


def complex_eigenvalues(a: Any, b: Any, dense_max: int, k: int) -> CArray:
    """Finite eigenvalues of a x = mu b x with Im mu > 0 (one per conjugate pair)."""
    from contin.stability import eigenvalues

    n = a.shape[0]
    w = eigenvalues(a, b, k=None if n <= dense_max else min(k, n - 2), dense_max=dense_max)
    return w[w.imag > REAL_TOL * np.maximum(1.0, np.abs(w))]


def _nearest(v: CArray, target: complex) -> int:
    return int(np.argmin(np.abs(v - target)))


def crossing_pairs(va: CArray, vb: CArray) -> list[tuple[complex, complex]]:
    """Eigenvalues (Im > 0) at two points paired by mutual nearest neighbours whose real parts
    have opposite signs: the complex pairs that cross the imaginary axis in between.  A pair
    that is not mutual (the step too long to track it) is not reported."""
    out: list[tuple[complex, complex]] = []
    if va.size == 0 or vb.size == 0:
        return out
    for i, mu_a in enumerate(va):
        mu_b = vb[_nearest(vb, mu_a)]
        if _nearest(va, mu_b) != i:
            continue
        if mu_a.real == 0 or mu_b.real == 0 or (mu_a.real > 0) == (mu_b.real > 0):
            continue
        out.append((complex(mu_a), complex(mu_b)))
    return out


def distance_to_segment(v: CArray, a: complex, b: complex) -> CArray:
    """Distances of the points v from the segment [a, b] of the complex plane."""
    d = b - a
    if d == 0:
        return np.abs(v - a)
    t = np.clip(((v - a) * np.conj(d)).real / abs(d) ** 2, 0.0, 1.0)
    return np.abs(v - (a + t * d))


@dataclass
class HopfTest:
    """Point test for Hopf points (module docstring)."""

    problem: Any
    dense_max: int = 400
    k: int = 12
    name: str = "hopf"
    kind: str = "HB"

    def value(self, system: Any, x: Array) -> CArray:
        return self.eigenvalues(x[:-1], system.params_at(x[-1]), f"{system.parameter}={x[-1]:g}")

    def eigenvalues(self, u: Array, params: dict[str, float], where: str, test: str = "Hopf") -> CArray:
        """The pencil's eigenvalues with Im > 0 at (u, params); none (logged, not hidden) where the
        eigen-solve fails: no crossing can then be bracketed by this point.  Also the ZH/HH tests'
        (``contin.codim2tests``) at the base states of fold and Hopf curves."""
        a, b = pencil(self.problem, u, params)
        try:
            return complex_eigenvalues(a, b, self.dense_max, self.k)
        except (np.linalg.LinAlgError, RuntimeError, ValueError) as exc:  # RuntimeError includes ArpackError
            log.warning("%s test: eigenvalues failed at %s: %s", test, where, exc)
            return np.zeros(0, dtype=complex)

    def crossings(self, va: CArray, vb: CArray) -> list[Crossing]:
        out: list[Crossing] = []
        for mu_a, mu_b in crossing_pairs(va, vb):

            def g(v: CArray, a: complex = complex(mu_a), b: complex = complex(mu_b)) -> float:
                if v.size == 0:
                    return math.nan
                return float(v[int(np.argmin(distance_to_segment(v, a, b)))].real)

            out.append(("", g))
        return out

    def finish(self, system: Any, sp: SpecialPoint, x: Array) -> SpecialPoint:
        u, q = x[:-1], system.params_at(x[-1])
        data = hopf_numbers(self.problem, u, q, self.dense_max, self.k)
        l1 = data["l1"]
        kind = "" if not math.isfinite(l1) else ("subcritical" if l1 > 0 else "supercritical")
        doubt = ""
        if "l1_error" in data:
            doubt = f"l1 doubtful (estimated relative error {data['l1_error'] / abs(l1) if l1 else math.inf:.1e})"
            log.warning("HB at %s=%g: %s", system.parameter, x[-1], doubt)
        note = "; ".join(t for t in (kind, doubt, sp.note) if t)
        return replace(sp, data={**sp.data, **data}, note=note)


def hopf_numbers(problem: Any, u: Array, params: dict[str, float], dense_max: int = 400, k: int = 12) -> dict[str, float]:
    """``{'omega': ..., 'l1': ...}`` at a Hopf point (u, p): the critical eigenvalue is the one
    with positive imaginary part nearest the imaginary axis."""
    a, b = pencil(problem, u, params)
    w = complex_eigenvalues(a, b, dense_max, k)
    if w.size == 0:
        return {"omega": math.nan, "l1": math.nan}
    mu = complex(w[int(np.argmin(np.abs(w.real)))])
    omega = mu.imag
    if has(problem, "eigenproblem"):
        return {"omega": omega, "l1": math.nan}
    try:
        l1, err = first_lyapunov_estimate(problem, u, params, omega)
    except (np.linalg.LinAlgError, RuntimeError, ValueError):
        l1, err = math.nan, math.nan
    if math.isfinite(l1) and not err <= L1_DOUBTFUL * abs(l1):
        # no step of the differences resolves F's second and third derivatives (or l1 ~ 0): the
        # estimate is kept (and named by the HB's note), the sign may be wrong
        return {"omega": omega, "l1": l1, "l1_error": err}
    return {"omega": omega, "l1": l1}


def _mass(problem: Any, u: Array, params: dict[str, float], n: int) -> sp.csc_matrix:
    if has(problem, "mass_matrix"):
        return sp.csc_matrix(problem.mass_matrix(u, params), dtype=float)
    return sp.identity(n, format="csc")


def hopf_vectors(jac: Any, mass: Any, omega: float, seed: int = 0,
                 weights: Array | None = None) -> tuple[CArray, CArray]:
    """q, p with J q = i omega M q, J^T p = -i omega M^T p, q^H W q = 1, p^H M q = 1
    (W = diag(weights), the identity when None).

    Inverse iteration with one sparse LU of J - i omega M (shifted by a rounding-level amount
    so that it is not exactly singular): three solves give the null vectors to rounding.
    """
    n = jac.shape[0]
    scale = max(1.0, abs(omega))
    a = sp.csc_matrix(jac, dtype=complex) - 1j * (omega * (1 + 1e-13) + 1e-13 * scale) * sp.csc_matrix(mass, dtype=complex)
    import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

    lu = spla.splu(sp.csc_matrix(a))
    rng = np.random.default_rng(seed)
    q = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    r = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    for _ in range(3):
        q = lu.solve(q)
        q /= np.linalg.norm(q)
        r = lu.solve(r, trans="T")  # A^T r = ., r = conj(p) with J^T conj(p) = i omega M^T conj(p)
        r /= np.linalg.norm(r)
    if weights is not None:
        q = q / math.sqrt(float(np.vdot(q, weights * q).real))
    p = np.conj(r)
    pmq = np.vdot(p, np.asarray(mass @ q))
    if pmq == 0:
        raise np.linalg.LinAlgError("left and right Hopf eigenvectors are M-orthogonal (not a simple Hopf point)")
    p = p / np.conj(pmq)
    return q, p


class _Forms:
    """Second and third derivatives of F in u as multilinear forms, from J by central differences."""

    def __init__(self, problem: Any, u: Array, params: dict[str, float], step_scale: float = 1.0) -> None:
        self.problem, self.u, self.params = problem, u, params
        self.scale = max(1.0, float(np.max(np.abs(u), initial=0.0))) * step_scale

    def _jac(self, du: Array) -> Any:
        return self.problem.jacobian(self.u + du, self.params)

    def _b_real(self, a: Array, y: CArray) -> CArray:
        na = float(np.max(np.abs(a), initial=0.0))
        if na == 0:
            return np.zeros_like(y)
        h = FD_STEP_B * self.scale / na
        return np.asarray((self._jac(h * a) @ y) - (self._jac(-h * a) @ y)) / (2 * h)

    def B(self, x: CArray, y: CArray) -> CArray:
        return self._b_real(x.real.copy(), y) + 1j * self._b_real(x.imag.copy(), y)

    def _c_real(self, a: Array, b: Array, y: CArray) -> CArray:
        na = float(np.max(np.abs(a), initial=0.0))
        nb = float(np.max(np.abs(b), initial=0.0))
        if na == 0 or nb == 0:
            return np.zeros_like(y)
        ha, hb = FD_STEP_C * self.scale / na, FD_STEP_C * self.scale / nb
        pp = self._jac(ha * a + hb * b) @ y
        pm = self._jac(ha * a - hb * b) @ y
        mp = self._jac(-ha * a + hb * b) @ y
        mm = self._jac(-ha * a - hb * b) @ y
        return np.asarray(pp - pm - mp + mm) / (4 * ha * hb)

    def C(self, x: CArray, y: CArray, z: CArray) -> CArray:
        xr, xi, yr, yi = x.real.copy(), x.imag.copy(), y.real.copy(), y.imag.copy()
        return (self._c_real(xr, yr, z) - self._c_real(xi, yi, z)
                + 1j * (self._c_real(xr, yi, z) + self._c_real(xi, yr, z)))


def first_lyapunov_estimate(problem: Any, u: Array, params: dict[str, float], omega: float) -> tuple[float, float]:
    """(l1, its estimated absolute error): :func:`first_lyapunov` with its steps times m and 2 m
    along :func:`step_ladder` (accepted below L1_ACCEPT |l1|)."""
    return first_lyapunov_ladder(problem, u, params, omega)[:2]


def first_lyapunov_ladder(problem: Any, u: Array, params: dict[str, float], omega: float) -> tuple[float, float, float]:
    """:func:`first_lyapunov_estimate` and the step multiplier m it chose (the GH test of a Hopf
    curve uses the m of its first point all along: ``contin.hopfsystem.LyapunovTest``)."""

    return step_ladder(two_step_estimate(lambda m: first_lyapunov(problem, u, params, omega, step_scale=m)), L1_ACCEPT)


def two_step_estimate(value: Callable[[float], float]) -> Callable[[float], tuple[float, float]]:
    """m -> (value(m), |value(m) - value(2 m)|): a difference-step quantity at step multiplier m and
    its error estimate from the step doubled ((nan, inf) where either is not finite), for
    :func:`step_ladder`."""

    def at(m: float) -> tuple[float, float]:
        with np.errstate(all="ignore"):
            a, b = value(m), value(2 * m)
        err = abs(a - b)
        return (a, err) if math.isfinite(a) and math.isfinite(err) else (math.nan, math.inf)

    return at


def first_lyapunov(problem: Any, u: Array, params: dict[str, float], omega: float, step_scale: float = 1.0) -> float:
    """First Lyapunov coefficient l1 at the Hopf point (u, p) with frequency omega (module
    docstring: Kuznetsov's eq. (3.20) with q^H W q = 1, W the problem's
    ``inner_product_weights`` or I, generalized to a mass matrix); the difference steps of B and
    C times ``step_scale`` (:func:`first_lyapunov_estimate`)."""
    jac = problem.jacobian(u, params)
    n = jac.shape[0]
    mass = _mass(problem, u, params, n)
    q, p = hopf_vectors(jac, mass, omega, weights=inner_product_weights(problem, u, params))
    forms = _Forms(problem, u, params, step_scale)
    qb = np.conj(q)
    jc = sp.csc_matrix(jac, dtype=complex)
    mc = sp.csc_matrix(mass, dtype=complex)
    import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

    a_inv_b = spla.splu(jc).solve(forms.B(q, qb).astype(complex))
    r2 = spla.splu(sp.csc_matrix(2j * omega * mc - jc)).solve(forms.B(q, q).astype(complex))
    total = np.vdot(p, forms.C(q, q, qb)) - 2 * np.vdot(p, forms.B(q, a_inv_b)) + np.vdot(p, forms.B(qb, r2))
    return float(total.real / (2 * omega))
