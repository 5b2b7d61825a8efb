"""Zero-Hopf (ZH) and double-Hopf (HH) points on fold and Hopf curves (codimension two).

Labels as AUTO-07p's and BifurcationKit's (``:zh``, ``:hh``; Kuznetsov, *Elements of Applied
Bifurcation Theory*, 3rd ed., secs. 8.5 and 8.6):

- on a fold curve (J has a simple zero eigenvalue), a complex pair of the pencil (J, M) at the
  base state crossing the imaginary axis is a zero-Hopf point (fold-Hopf; ZH): the fold curve
  meets a Hopf curve.  :class:`BaseEigenTest` with the Hopf test of the base problem
  (``contin.hopf``: Re mu of the crossing eigenvalue, mutual-nearest pairing);
- on a Hopf curve (a pair +-i omega, kappa = omega^2), a real eigenvalue through zero is also a
  ZH: :class:`ZeroHopfTest`, the sign of det J / kappa (det J is kappa times the product of the
  other eigenvalues of (J, M) and a constant: the pair's own product kappa is divided out, so a
  Bogdanov-Takens point, where kappa changes sign, is not counted);
- on a Hopf curve, a second pair crossing the imaginary axis is a double-Hopf point (HH):
  :class:`BaseEigenTest` with the curve's own pair (the eigenvalue nearest i omega) removed.
Both Hopf-curve tests are off on its neutral-saddle part (kappa <= 0, past a BT): there is no
Hopf pair, and a crossing there is neither a ZH nor an HH.

Each is a point test (``contin.pointtests``) of the augmented problem, evaluated at the base
state of each point, located by re-correcting onto the curve like every point test.  The
eigenvalue tests cost one eigen-solve of the base pencil per point (dense QZ up to the Hopf
test's ``dense_max``, shift-invert ARPACK above) and are on where HB detection would be on for
the base problem (``contin.hopf.hopf_test``: ``DetectionOptions.detect_hopf``); the determinant
test costs one LU.  Located ZH and HH points carry their normal-form coefficients
(:func:`zero_hopf_coefficients`, :func:`double_hopf_coefficients`, in ``finish``), BT points
theirs (:func:`bogdanov_takens_coefficients`), and GH points of Hopf curves the second Lyapunov
coefficient (:func:`second_lyapunov`, stored by ``contin.hopfsystem.LyapunovTest``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.branch import SpecialPoint
from contin.pointtests import Crossing
from contin.problem import Array, has
from contin.testfunctions import sign_log_crossing

#: (augmented state, parameters) -> (base state u, base parameters q with p2 in place)
Split = Callable[[Array, Mapping[str, float]], tuple[Array, dict[str, float]]]


@dataclass(frozen=True)
class BaseEigenTest:
    """Complex eigenvalues of the base pencil at an augmented curve's base state (ZH on fold
    curves, HH on Hopf curves: the module docstring).

    ``hopf``: the base problem's :class:`contin.hopf.HopfTest` (its dense_max and k);
    ``split``: the base state and parameters of an augmented state; ``own_kappa``: the index of
    kappa in the augmented state (Hopf curves), whose pair i sqrt(kappa) is left out."""

    hopf: Any
    split: Split
    name: str
    kind: str
    note: str
    own_kappa: int | None = None

    def value(self, system: Any, x: Array) -> Array:
        u, q = self.split(x[:-1], system.params_at(x[-1]))
        w = self.hopf.eigenvalues(u, q, f"{system.parameter}={x[-1]:g}", self.kind)
        if self.own_kappa is not None and w.size:
            kappa = float(x[self.own_kappa])
            if not kappa > 0:  # a neutral saddle (past a BT): a pair crossing there is no double Hopf
                return np.zeros(0, dtype=complex)
            # the curve's own pair, on the axis by construction
            w = np.delete(w, int(np.argmin(np.abs(w - 1j * math.sqrt(kappa)))))
        return w

    def crossings(self, va: Array, vb: Array) -> list[Crossing]:
        return [(self.note, g) for _, g in self.hopf.crossings(va, vb)]

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        w = self.value(system, x)
        data = dict(sp_.data)
        if w.size:
            mu = complex(w[int(np.argmin(np.abs(w.real)))])
            data["omega2" if self.own_kappa is not None else "omega"] = mu.imag
        if self.own_kappa is not None:
            kappa = float(x[self.own_kappa])
            data["omega"] = math.sqrt(kappa) if kappa > 0 else math.nan
        problem = self.hopf.problem
        if has(problem, "eigenproblem"):  # its own M is not the steady one (as for BT): no normal form
            return replace(sp_, data=data)
        u, q = self.split(x[:-1], system.params_at(x[-1]))
        if self.own_kappa is None:  # ZH of a fold curve
            omega = abs(float(data.get("omega", math.nan)))
            data.update(zero_hopf_coefficients(problem, u, q, omega) if omega > 0 else _zh_nan())
        else:
            w1, w2 = float(data["omega"]), abs(float(data.get("omega2", math.nan)))
            ok = w1 > 0 and w2 > 0
            data.update(double_hopf_coefficients(problem, u, q, w1, w2) if ok else
                        {k: math.nan for k in DOUBLE_HOPF_KEYS})
        return replace(sp_, data=data)


@dataclass(frozen=True)
class ZeroHopfTest:
    """det J / kappa on a Hopf curve as (sign, log|.|): changes sign where a real eigenvalue
    passes through zero (ZH; module docstring)."""

    problem: Any
    split: Split
    kappa_index: int
    name: str = "zh"
    kind: str = "ZH"

    def value(self, system: Any, x: Array) -> tuple[float, float]:
        from contin.linalg import factorize

        u, q = self.split(x[:-1], system.params_at(x[-1]))
        kappa = float(x[self.kappa_index])
        if not kappa > 0:  # a neutral saddle (past a BT): a real eigenvalue through 0 there is no zero-Hopf
            return (0.0, -math.inf)
        fact = factorize(self.problem.jacobian(u, q))
        if fact is None:
            return (0.0, -math.inf)
        sign, logabs = fact.det_sign_log()
        return (sign * math.copysign(1.0, kappa), logabs - math.log(abs(kappa)))

    def crossings(self, va: tuple[float, float], vb: tuple[float, float]) -> list[Crossing]:
        return sign_log_crossing(va, vb, "zero-Hopf (a real eigenvalue through 0 on the Hopf curve)")

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        kappa = float(x[self.kappa_index])
        omega = math.sqrt(kappa) if kappa > 0 else math.nan
        data = {**sp_.data, "omega": omega}
        if not has(self.problem, "eigenproblem"):  # as for BT: its own M is not the steady one
            u, q = self.split(x[:-1], system.params_at(x[-1]))
            data.update(zero_hopf_coefficients(self.problem, u, q, omega) if omega > 0 else _zh_nan())
        return replace(sp_, data=data)


def generalized_null_vector(jac: Any, mass: Any, q0: Array, p1: Array) -> Array:
    """q1 with J q1 = M q0 and q0 . q1 = 0 at a Bogdanov-Takens point (J q0 = 0, p1^T J = 0, M q0
    in J's range): the bordered solve [[J, p1], [q0^T, 0]] [q1; s] = [M q0; 0], regular at a BT
    (p1 is not in J's range, q0 not orthogonal to its kernel); s = 0 there.  The start of a Hopf
    curve at a BT (``contin.hopfcurve.hopf_curve_start_at_bt``) and the BT normal form below."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    border = sp.bmat([[jac, p1[:, None]], [q0[None, :], None]], format="csc")
    return spla.splu(border).solve(np.concatenate([np.asarray(mass @ q0, float), [0.0]]))[:jac.shape[0]]


def bogdanov_takens_coefficients(problem: Any, u: Array, params: Mapping[str, float]) -> dict[str, float]:
    """Normal-form coefficients (a, b) of a Bogdanov-Takens point (u, p) of M u' = F(u, p):
    w0' = w1, w1' = a w0^2 + b w0 w1 + ... (Kuznetsov, *Elements of Applied Bifurcation Theory*,
    3rd ed., sec. 8.7, the projection method generalized to M: with f = M^-1 F it reads)

        J q0 = 0, J q1 = M q0, J^T p1 = 0, J^T p0 = M^T p1,
        p0^T M q0 = p1^T M q1 = 1, p1^T M q0 = p0^T M q1 = 0,
        a = p1^T B(q0, q0) / 2,   b = p0^T B(q0, q0) + p1^T B(q0, q1),

    B the second derivative of F (central differences of J, as for l1).  q0 -> c q0 scales a and
    b by c; q0 is normalized to 1 in the problem's ``inner_product_weights`` norm (Euclidean
    without the hook) and its sign chosen so that a >= 0, so sign(b) = sign(ab), the invariant
    that separates the two BT unfoldings (ab < 0: a stable cycle born at the Hopf curve ends in a
    homoclinic orbit; Kuznetsov Fig. 8.8).  NaN for both when the vectors cannot be computed."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from contin.hopf import _Forms, _mass
    from contin.normalform import null_vectors
    from contin.problem import inner_product_weights

    u = np.asarray(u, float)
    q = dict(params)
    nan = {"a": math.nan, "b": math.nan}
    try:
        jac = sp.csc_matrix(problem.jacobian(u, q), dtype=float)
        n = jac.shape[0]
        m = _mass(problem, u, q, n)
        nulls = null_vectors(jac)
        q0, p1 = nulls.phi, nulls.psi
        weights = inner_product_weights(problem, u, q)
        norm = math.sqrt(float(q0 @ (q0 if weights is None else weights * q0)))
        q0 = q0 / norm
        q1 = generalized_null_vector(jac, m, q0, p1)
        left = sp.bmat([[jac.T, q0[:, None]], [p1[None, :], None]], format="csc")
        p1 = p1 / float(p1 @ (m @ q1))  # p1^T M q1 = 1 (then p0^T M q0 = (M^T p1)^T q1 = 1 too)
        p0 = spla.splu(left).solve(np.concatenate([m.T @ p1, [0.0]]))[:n]
        p0 = p0 - float(p0 @ (m @ q1)) * p1  # p0^T M q1 = 0 (p1^T M q1 = 1)
        forms = _Forms(problem, u, q)
        b00 = np.real(forms.B(q0.astype(complex), q0.astype(complex)))
        b01 = np.real(forms.B(q0.astype(complex), q1.astype(complex)))
    except (np.linalg.LinAlgError, RuntimeError, ValueError, ZeroDivisionError):
        return nan
    a = 0.5 * float(p1 @ b00)
    b = float(p0 @ b00) + float(p1 @ b01)
    if not (math.isfinite(a) and math.isfinite(b)):
        return nan
    if a < 0:  # q0 -> -q0 flips both
        a, b = -a, -b
    return {"a": a, "b": b}


#: Relative steps of the central differences of J for the fourth and fifth derivatives of F
#: (third and fourth mixed differences of J): error ~ h^2 (truncation) + eps / h^3 (resp. h^4)
#: (rounding), balanced near eps^(1/5) and eps^(1/6).
FD_STEP_D = 1e-3
FD_STEP_E = 3e-3


def _mixed_difference(problem: Any, u: Array, params: Mapping[str, float], dirs: list[Array], y: Any,
                      step: float) -> Any:
    """d^k/dt_1..dt_k J(u + sum t_i a_i) y at t = 0 for real directions a_i (k = len(dirs)): the
    central mixed difference sum over sign vectors s of (prod s_i) J(u + sum s_i h_i a_i) y /
    (2^k prod h_i), h_i = step * max(1, |u|_inf) / |a_i|_inf; exact for J polynomial of degree
    k + 1, else O(h^2)."""
    import itertools

    sizes = [float(np.max(np.abs(a), initial=0.0)) for a in dirs]
    if any(s == 0 for s in sizes):
        return np.zeros_like(y)
    scale = max(1.0, float(np.max(np.abs(u), initial=0.0)))
    hs = [step * scale / s for s in sizes]
    out = np.zeros_like(y)
    for signs in itertools.product((1.0, -1.0), repeat=len(dirs)):
        du = sum(s * h * a for s, h, a in zip(signs, hs, dirs))
        out = out + float(np.prod(signs)) * np.asarray(problem.jacobian(u + du, dict(params)) @ y)
    return out / (2 ** len(dirs) * float(np.prod(hs)))


def _complex_form(problem: Any, u: Array, params: Mapping[str, float], args: tuple[Any, ...], y: Any,
                  step: float) -> Any:
    """The symmetric multilinear form of order len(args) + 1 of F (the len(args)-th derivative of
    J along args, applied to y), for complex args: multilinear in each, so the sum over the real
    and imaginary parts (2^k real mixed differences, each 2^k Jacobians); Richardson-extrapolated
    from the steps h and 2 h ((4 f(h) - f(2 h)) / 3: the h^2 truncation cancels)."""
    fine = _complex_form_at(problem, u, params, args, y, step)
    coarse = _complex_form_at(problem, u, params, args, y, 2 * step)
    return (4 * fine - coarse) / 3


def _complex_form_at(problem: Any, u: Array, params: Mapping[str, float], args: tuple[Any, ...], y: Any,
                     step: float) -> Any:
    """:func:`_complex_form` at one step."""
    import itertools

    parts = [((np.real(a).astype(float), 1.0), (np.imag(a).astype(float), 1j)) for a in args]
    out = np.zeros(np.shape(y), dtype=complex)
    for choice in itertools.product(*parts):
        if any(not np.any(d) for d, _ in choice):
            continue
        factor = complex(np.prod([f for _, f in choice]))
        out = out + factor * _mixed_difference(problem, u, params, [d for d, _ in choice], np.asarray(y, complex), step)
    return out


#: Relative error of l2 accepted at the first step scale (the difference of l2 at the steps h and 2 h)
L2_ACCEPT = 1e-6
#: Relative error estimate of l2 above which a GH's l2 is reported doubtful (warning, note)
L2_DOUBTFUL = 1e-3
#: Decades either side of the default steps tried for l2 (multipliers 10^-k .. 10^k of all the
#: difference steps, B, C, D and E): the steps are relative to max(1, |u|_inf), which says
#: nothing about the length scale of F's nonlinearity (a problem whose state is scaled by 1e-4
#: needs steps 1e-4 times smaller, one scaled by 1e4 larger)
L2_STEP_DECADES = 6


def second_lyapunov_estimate(problem: Any, u: Array, params: Mapping[str, float],
                             omega: float) -> tuple[float, float]:
    """(l2, its estimated absolute error): :func:`second_lyapunov` with all its difference steps
    multiplied by m and by 2 m, the difference of the two the error estimate (the l2 returned is
    the one at m).  m = 1 first; unless its estimate is below L2_ACCEPT |l2|, m walks down by
    decades while the estimate improves, then up, up to L2_STEP_DECADES each way, and the best is
    kept.  At the default steps the differences resolve a nonlinearity on the scale max(1, |u|):
    a state scaled by 1e-4 (or 1e4) gave l2 wrong by a factor 1e15 (1e8) with no sign of it."""

    from contin.hopf import step_ladder, two_step_estimate

    at = two_step_estimate(lambda m: second_lyapunov(problem, u, params, omega, step_scale=m))
    return step_ladder(at, L2_ACCEPT, L2_STEP_DECADES)[:2]


def second_lyapunov(problem: Any, u: Array, params: Mapping[str, float], omega: float,
                    step_scale: float = 1.0) -> float:
    """Second Lyapunov coefficient l2 at a generalized Hopf (Bautin) point (u, p) of M u' = F(u, p)
    with frequency omega (where l1 = 0): the multilinear formula of Kuznetsov, SIAM J. Numer.
    Anal. 36, 1104-1124, 1999, sec. 7 (the normal form of *Elements of Applied Bifurcation
    Theory*, 3rd ed., sec. 8.3), generalized to M as :func:`contin.hopf.first_lyapunov` (f = M^-1 F):

        J q = i omega M q, p^H J = i omega p^H M, p^H M q = 1, q^H W q = 1 (W the problem's
        ``inner_product_weights`` or I: the normalization of l1),
        H20 = (2 i omega M - J)^-1 B(q, q),   H11 = -J^-1 B(q, qb),
        H30 = (3 i omega M - J)^-1 [C(q, q, q) + 3 B(q, H20)],
        h21 = C(q, q, qb) + B(qb, H20) + 2 B(q, H11),   G21 = p^H h21 (l1 = Re G21 / (2 omega)),
        (i omega M - J) H21 = h21 - G21 M q,   p^H M H21 = 0 (bordered solve),
        H31 = (2 i omega M - J)^-1 [D(q, q, q, qb) + 3 C(q, q, H11) + 3 C(q, qb, H20) + 3 B(H20, H11)
                                    + B(qb, H30) + 3 B(q, H21) - 3 G21 M H20],
        H22 = -J^-1 [D(q, q, qb, qb) + 4 C(q, qb, H11) + C(qb, qb, H20) + C(q, q, H20b)
                     + 2 B(H11, H11) + 2 B(q, H21b) + 2 B(qb, H21) + B(H20b, H20) - 4 Re(G21) M H11],
        G32 = p^H [E(q, q, q, qb, qb) + D(q, q, q, H20b) + 3 D(q, qb, qb, H20) + 6 D(q, q, qb, H11)
                   + C(qb, qb, H30) + 3 C(q, q, H21b) + 6 C(q, qb, H21) + 3 C(q, H20b, H20)
                   + 6 C(q, H11, H11) + 6 C(qb, H20, H11) + 2 B(qb, H31) + 3 B(q, H22)
                   + B(H20b, H30) + 3 B(H21b, H20) + 6 B(H11, H21)],
        l2 = Re G32 / (12 omega),

    the normal form w' = i omega w + (G21 / 2) w|w|^2 + (G32 / 12) w|w|^4 on the center manifold
    u = u0 + 2 Re(w q) + ...; l2 = Re c2 / omega as l1 = Re c1 / omega (MatCont and
    BifurcationKit report omega l2).  B, C: central differences of J as for l1; D, E: third and
    fourth mixed differences of J (steps FD_STEP_D, FD_STEP_E; relative accuracy ~1e-6; all steps,
    those of B and C too, times ``step_scale``: :func:`second_lyapunov_estimate`).  For the
    Bautin normal form z' = (b1 + i) z + b2 z|z|^2 + s z|z|^4 in x = Re z, y = Im z (q = (1, -i) /
    sqrt(2), z = sqrt(2) w): l1 = 2 b2 and, at b2 = 0, l2 = 4 s."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from contin.hopf import _Forms, _mass, hopf_vectors
    from contin.problem import inner_product_weights

    u = np.asarray(u, float)
    q_ = dict(params)
    jac = sp.csc_matrix(problem.jacobian(u, q_), dtype=float)
    n = jac.shape[0]
    mass = _mass(problem, u, q_, n)
    q, p = hopf_vectors(jac, mass, omega, weights=inner_product_weights(problem, u, q_))
    qb = np.conj(q)
    forms = _Forms(problem, u, q_)
    forms.scale *= step_scale
    B, C = forms.B, forms.C

    def D(a, b, c, y):
        return _complex_form(problem, u, q_, (a, b, c), y, FD_STEP_D * step_scale)

    def E(a, b, c, d, y):
        return _complex_form(problem, u, q_, (a, b, c, d), y, FD_STEP_E * step_scale)

    jc = sp.csc_matrix(jac, dtype=complex)
    mc = sp.csc_matrix(mass, dtype=complex)
    zero = spla.splu(jc)
    two = spla.splu(sp.csc_matrix(2j * omega * mc - jc))
    three = spla.splu(sp.csc_matrix(3j * omega * mc - jc))
    mq = np.asarray(mc @ q)
    row = np.conj(np.asarray(mc.T @ p))  # p^H M (M real)
    border = sp.bmat([[sp.csc_matrix(1j * omega * mc - jc), sp.csc_matrix(mq[:, None])],
                      [sp.csc_matrix(row[None, :]), None]], format="csc")
    one = spla.splu(border)

    h20 = two.solve(B(q, q))
    h11 = -zero.solve(B(q, qb))
    h30 = three.solve(C(q, q, q) + 3 * B(q, h20))
    r21 = C(q, q, qb) + B(qb, h20) + 2 * B(q, h11)
    g21 = complex(np.vdot(p, r21))
    h21 = one.solve(np.concatenate([r21 - g21 * mq, [0.0]]))[:n]
    h20b, h21b = np.conj(h20), np.conj(h21)
    r31 = (D(q, q, q, qb) + 3 * C(q, q, h11) + 3 * C(q, qb, h20) + 3 * B(h20, h11) + B(qb, h30) + 3 * B(q, h21)
           - 3 * g21 * np.asarray(mc @ h20))
    h31 = two.solve(r31)
    r22 = (D(q, q, qb, qb) + 4 * C(q, qb, h11) + C(qb, qb, h20) + C(q, q, h20b) + 2 * B(h11, h11) + 2 * B(q, h21b)
           + 2 * B(qb, h21) + B(h20b, h20) - 4 * g21.real * np.asarray(mc @ h11))
    h22 = -zero.solve(r22)
    r32 = (E(q, q, q, qb, qb) + D(q, q, q, h20b) + 3 * D(q, qb, qb, h20) + 6 * D(q, q, qb, h11)
           + C(qb, qb, h30) + 3 * C(q, q, h21b) + 6 * C(q, qb, h21) + 3 * C(q, h20b, h20) + 6 * C(q, h11, h11)
           + 6 * C(qb, h20, h11) + 2 * B(qb, h31) + 3 * B(q, h22) + B(h20b, h30) + 3 * B(h21b, h20) + 6 * B(h11, h21))
    return float(complex(np.vdot(p, r32)).real / (12 * omega))


def _zh_nan() -> dict[str, float]:
    return {k: math.nan for k in ZERO_HOPF_KEYS}


#: The normal-form data of a zero-Hopf point (:func:`zero_hopf_coefficients`)
ZERO_HOPF_KEYS = ("B", "C", "E", "s", "theta")


def zero_hopf_coefficients(problem: Any, u: Array, params: Mapping[str, float], omega: float) -> dict[str, float]:
    """Normal-form coefficients of a zero-Hopf (fold-Hopf) point (u, p) of M u' = F(u, p) with
    the pair +-i omega: Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed., sec. 8.5
    (Lemma 8.9 and eq. (8.81)), by the projection method of Kuznetsov, SIAM J. Numer. Anal. 36
    (1999) generalized to M (f = M^-1 F).  On the center manifold u = u0 + xi q0 + z q1 + zb qb1
    + ... the restricted system in Taylor coefficients reads

        xi' = g200 xi^2 + g011 |z|^2 + g300 xi^3 + g111 xi |z|^2 + ...,
        z'  = i omega z + g110 xi z + g210 xi^2 z + g021 z |z|^2 + ...,

    with J q0 = 0, J^T p0 = 0, p0^T M q0 = 1, J q1 = i omega M q1, p1^H J = i omega p1^H M,
    p1^H M q1 = 1 and (B, C the second and third derivatives of F)

        g200 = p0^T B(q0, q0) / 2,   g011 = p0^T B(q1, qb1),   g110 = p1^H B(q0, q1),
        J h200 = 2 g200 M q0 - B(q0, q0),  -J h011 = B(q1, qb1) - g011 M q0   (p0^T M h = 0),
        (i omega M - J) h110 = B(q0, q1) - g110 M q1  (p1^H M h110 = 0),
        h020 = (2 i omega M - J)^-1 B(q1, q1)   (bordered solves as in :func:`second_lyapunov`;
        the orthogonality conditions remove the M h terms of the cubic equations),
        g300 = p0^T [C(q0, q0, q0) + 3 B(q0, h200)] / 6,
        g111 = p0^T [C(q0, q1, qb1) + B(q0, h011) + B(q1, hb110) + B(qb1, h110)],
        g210 = p1^H [C(q0, q0, q1) + B(q1, h200) + 2 B(q0, h110)] / 2,
        g021 = p1^H [C(q1, q1, qb1) + 2 B(q1, h011) + B(qb1, h020)] / 2;

    the normal form xi' = beta1 + B xi^2 + C |z|^2, z' = (beta2 + i omega1) z + D xi z
    + E xi^2 z (+ O(4)) has

        B = g200,  C = g011,  theta = Re D / B = Re g110 / g200,
        E = Re[g210 + g110 (Re g021 / g011 - 3 g300 / (2 g200) + g111 / (2 g011)) - g021 g200 / g011],

    and s = sign(B C) = +-1 (0 for a degenerate C = 0, where E is NaN): with theta they select
    Guckenheimer-Holmes' four unfoldings (Kuznetsov sec. 8.5.2); in the amplitude equations
    xi' = beta1 + B xi^2 + C r^2, r' = r (beta2 + Re D xi + E xi^2) the cycle born at the Hopf
    curve has a Neimark-Sacker bifurcation (a torus) only for s theta < 0, where E enters its
    stability.
    Normalization (the choice, as for BT and l1): q0 unit and q1 with q1^H W q1 = 1 (W the
    problem's ``inner_product_weights``, else I), q0's sign such that B >= 0; then B ~ |q0|,
    C ~ |q1|^2 / |q0|, E ~ |q0|^2, while s, theta and the sign of E do not depend on it.  B, C,
    E scale with time (t -> t / k multiplies them by k).  NaN for all when the vectors or solves
    fail (e.g. at a BT, where p0^T M q0 = 0)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from contin.hopf import _Forms, _mass, hopf_vectors
    from contin.normalform import null_vectors
    from contin.problem import inner_product_weights

    u = np.asarray(u, float)
    q_ = dict(params)
    omega = abs(float(omega))
    try:
        jac = sp.csc_matrix(problem.jacobian(u, q_), dtype=float)
        n = jac.shape[0]
        mass = sp.csc_matrix(_mass(problem, u, q_, n), dtype=float)
        weights = inner_product_weights(problem, u, q_)
        nulls = null_vectors(jac)
        q0, p0 = np.asarray(nulls.phi, float), np.asarray(nulls.psi, float)
        q0 = q0 / math.sqrt(float(q0 @ (q0 if weights is None else weights * q0)))
        mq0 = np.asarray(mass @ q0)
        p0 = p0 / float(p0 @ mq0)
        q1, p1 = hopf_vectors(jac, mass, omega, weights=weights)
        forms = _Forms(problem, u, q_)
        B, C = forms.B, forms.C
        q0c, qb1 = q0.astype(complex), np.conj(q1)
        jc, mc = sp.csc_matrix(jac, dtype=complex), sp.csc_matrix(mass, dtype=complex)
        mq1 = np.asarray(mc @ q1)
        b00 = np.real(B(q0c, q0c))
        b11 = np.real(B(q1, qb1))
        b01 = B(q0c, q1)
        g200p = float(p0 @ b00)  # 2 g200
        g011 = float(p0 @ b11)
        g110 = complex(np.vdot(p1, b01))
        zero = spla.splu(sp.bmat([[jac, mq0[:, None]], [np.asarray(mass.T @ p0)[None, :], None]], format="csc"))
        h200 = zero.solve(np.concatenate([g200p * mq0 - b00, [0.0]]))[:n]
        h011 = zero.solve(np.concatenate([g011 * mq0 - b11, [0.0]]))[:n]
        one = spla.splu(sp.bmat([[sp.csc_matrix(1j * omega * mc - jc), sp.csc_matrix(mq1[:, None])],
                                 [sp.csc_matrix(np.conj(np.asarray(mc.T @ p1))[None, :]), None]], format="csc"))
        h110 = one.solve(np.concatenate([b01 - g110 * mq1, [0.0]]))[:n]
        h020 = _solve_shifted(2j * omega * mc - jc, B(q1, q1))
        h200c, h011c = h200.astype(complex), h011.astype(complex)
        g300 = float(np.real(p0 @ (C(q0c, q0c, q0c) + 3 * B(q0c, h200c)))) / 6
        g111 = float(np.real(p0 @ (C(q0c, q1, qb1) + B(q0c, h011c) + B(q1, np.conj(h110)) + B(qb1, h110))))
        g210 = complex(np.vdot(p1, C(q0c, q0c, q1) + B(q1, h200c) + 2 * B(q0c, h110))) / 2
        g021 = complex(np.vdot(p1, C(q1, q1, qb1) + 2 * B(q1, h011c) + B(qb1, h020))) / 2
    except (np.linalg.LinAlgError, RuntimeError, ValueError, ZeroDivisionError):
        return _zh_nan()
    g200 = g200p / 2
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # g200 or g011 = 0 (degenerate): NaN
        b_, c_ = np.float64(g200), np.float64(g011)
        e = (g210.real + g110.real * (g021.real / c_ - 3 * g300 / (2 * b_) + g111 / (2 * c_))
             - g021.real * b_ / c_)
        theta = g110.real / b_
    if g200 < 0:  # q0 -> -q0: B, C change sign; E, theta do not
        g200, g011 = -g200, -g011
    out = {"B": g200, "C": g011, "E": float(e), "s": float(np.sign(g200 * g011)), "theta": float(theta)}
    return {k: (v if math.isfinite(v) else math.nan) for k, v in out.items()}


def _solve_shifted(matrix: Any, rhs: Any) -> Any:
    """matrix^-1 rhs for a shifted pencil i k M - J of a center-manifold coefficient; a zero right
    side (a system without the quadratic term, e.g. odd) gives zero without a solve, so that a
    resonant shift (i k an eigenvalue: HH with omega2 = 2 omega) does not fail where the term is
    absent.  A singular matrix with a nonzero right side raises RuntimeError (splu)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    rhs = np.asarray(rhs, complex)
    if not np.any(rhs):
        return np.zeros_like(rhs)
    return spla.splu(sp.csc_matrix(matrix, dtype=complex)).solve(rhs)


#: The normal-form data of a double-Hopf point (:func:`double_hopf_coefficients`)
DOUBLE_HOPF_KEYS = ("p11", "p12", "p21", "p22", "theta", "delta")


def double_hopf_coefficients(problem: Any, u: Array, params: Mapping[str, float], omega1: float,
                             omega2: float) -> dict[str, float]:
    """Normal-form coefficients of a double-Hopf (Hopf-Hopf) point (u, p) of M u' = F(u, p) with
    the pairs +-i omega1 (the Hopf curve's own pair, data ``omega``) and +-i omega2 (the pair that
    crosses, data ``omega2``): Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed.,
    sec. 8.6, by the projection method (Kuznetsov, SIAM J. Numer. Anal. 36, 1999) generalized to
    M as :func:`contin.hopf.first_lyapunov`.  On the center manifold u = u0 + z1 q1 + z2 q2 + cc
    + ... the restricted system reads, in Taylor coefficients,

        z1' = i omega1 z1 + g2100 z1 |z1|^2 + g1011 z1 |z2|^2 + ...,
        z2' = i omega2 z2 + g1110 z2 |z1|^2 + g0021 z2 |z2|^2 + ...,

    with J q_k = i omega_k M q_k, p_k^H J = i omega_k p_k^H M, p_k^H M q_k = 1, q_k^H W q_k = 1
    (W the problem's ``inner_product_weights``, else I: the normalization of l1) and

        h1100 = -J^-1 B(q1, qb1),  h0011 = -J^-1 B(q2, qb2),  h2000 = (2 i omega1 M - J)^-1 B(q1, q1),
        h0020 = (2 i omega2 M - J)^-1 B(q2, q2),  h1010 = (i (omega1 + omega2) M - J)^-1 B(q1, q2),
        h1001 = (i (omega1 - omega2) M - J)^-1 B(q1, qb2),
        g2100 = p1^H [C(q1, q1, qb1) + B(qb1, h2000) + 2 B(q1, h1100)] / 2,
        g1011 = p1^H [C(q1, q2, qb2) + B(q1, h0011) + B(q2, h1001) + B(qb2, h1010)],
        g1110 = p2^H [C(q1, qb1, q2) + B(q1, hb1001) + B(qb1, h1010) + B(q2, h1100)],
        g0021 = p2^H [C(q2, q2, qb2) + B(qb2, h0020) + 2 B(q2, h0011)] / 2;

    p11 = Re g2100, p12 = Re g1011, p21 = Re g1110, p22 = Re g0021 (the amplitude equations
    r1' = r1 (mu1 + p11 r1^2 + p12 r2^2), r2' = r2 (mu2 + p21 r1^2 + p22 r2^2)), theta = p12 / p22,
    delta = p21 / p11: p11 p22 > 0 is the "simple" case, p11 p22 < 0 the "difficult" one (with
    tori and possibly chaos; Kuznetsov sec. 8.6.2).  p11 = omega1 l1 of the first pair and p22 =
    omega2 l1 of the second (l1 in contin's normalization).  p_ij scale with |q_j|^2 and with time
    (t -> t / k multiplies them by k); theta, delta and the signs do not.  Swapping the pairs swaps
    p11 <-> p22, p12 <-> p21, theta <-> delta.  NaN for all when a solve fails (e.g. a
    resonance omega2 = 2 omega1 with a quadratic term; an absent quadratic term is solved as zero)."""
    import scipy.sparse as sp

    from contin.hopf import _Forms, _mass, hopf_vectors
    from contin.problem import inner_product_weights

    u = np.asarray(u, float)
    q_ = dict(params)
    w1, w2 = abs(float(omega1)), abs(float(omega2))
    nan = {k: math.nan for k in DOUBLE_HOPF_KEYS}
    try:
        jac = sp.csc_matrix(problem.jacobian(u, q_), dtype=float)
        n = jac.shape[0]
        mass = sp.csc_matrix(_mass(problem, u, q_, n), dtype=float)
        weights = inner_product_weights(problem, u, q_)
        q1, p1 = hopf_vectors(jac, mass, w1, weights=weights)
        q2, p2 = hopf_vectors(jac, mass, w2, weights=weights)
        forms = _Forms(problem, u, q_)
        B, C = forms.B, forms.C
        qb1, qb2 = np.conj(q1), np.conj(q2)
        jc, mc = sp.csc_matrix(jac, dtype=complex), sp.csc_matrix(mass, dtype=complex)

        def shifted(k: float, rhs: Any) -> Any:
            return _solve_shifted(1j * k * mc - jc, rhs)

        h1100 = shifted(0.0, B(q1, qb1))
        h0011 = shifted(0.0, B(q2, qb2))
        h2000 = shifted(2 * w1, B(q1, q1))
        h0020 = shifted(2 * w2, B(q2, q2))
        h1010 = shifted(w1 + w2, B(q1, q2))
        h1001 = shifted(w1 - w2, B(q1, qb2))
        g2100 = complex(np.vdot(p1, C(q1, q1, qb1) + B(qb1, h2000) + 2 * B(q1, h1100))) / 2
        g1011 = complex(np.vdot(p1, C(q1, q2, qb2) + B(q1, h0011) + B(q2, h1001) + B(qb2, h1010)))
        g1110 = complex(np.vdot(p2, C(q1, qb1, q2) + B(q1, np.conj(h1001)) + B(qb1, h1010) + B(q2, h1100)))
        g0021 = complex(np.vdot(p2, C(q2, q2, qb2) + B(qb2, h0020) + 2 * B(q2, h0011))) / 2
    except (np.linalg.LinAlgError, RuntimeError, ValueError, ZeroDivisionError):
        return nan
    p11, p12, p21, p22 = g2100.real, g1011.real, g1110.real, g0021.real
    out = {"p11": p11, "p12": p12, "p21": p21, "p22": p22,
           "theta": p12 / p22 if p22 != 0 else math.nan, "delta": p21 / p11 if p11 != 0 else math.nan}
    return {k: (float(v) if math.isfinite(v) else math.nan) for k, v in out.items()}
