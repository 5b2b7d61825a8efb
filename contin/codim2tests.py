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
test costs one LU.  Normal-form coefficients of ZH and HH points are not computed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.branch import SpecialPoint
from contin.pointtests import Crossing
from contin.problem import Array
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
        return replace(sp_, data={**sp_.data, "omega": math.sqrt(kappa) if kappa > 0 else math.nan})


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
