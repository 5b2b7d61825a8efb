"""Normal forms of zero-Hopf (ZH) and double-Hopf (HH) points (``contin.codim2tests``:
``zero_hopf_coefficients``, ``double_hopf_coefficients``), against references computed here:

- systems written in Kuznetsov's normal forms (*Elements of Applied Bifurcation Theory*, 3rd
  ed., secs. 8.5 and 8.6) in real coordinates x = (xi, Re Z, Im Z, ...), whose coefficients are
  read off: with q1 = (e1 - i e2) / sqrt(2) (|q1| = 1, contin's normalization) Z = sqrt(2) z,
  |Z|^2 = 2 |z|^2, so a term c |Z|^2 is 2 c |z|^2 and a term Z |Z|^2 h is 2 h z |z|^2;
- the same after a rotation, a near-identity nonlinear change of coordinates x = T (y + N(y))
  (it gives the system quadratic, cubic and quartic terms: every center-manifold coefficient of
  the projection formulas becomes nonzero), a time scaling (t -> t / k: coefficients times k,
  theta, delta, s unchanged) and a mass matrix: the normal-form coefficients are invariant;
- the fixture systems of tests/test_zero_double_hopf.py, whose restriction to the center
  manifold is their own (closed form below), at their located ZH and HH.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from contin.codim2tests import double_hopf_coefficients, zero_hopf_coefficients


def _rotation(n, angles):
    """An orthogonal n x n matrix: a product of plane rotations (i, i + 1) by the angles."""
    t = np.eye(n)
    for i, a in enumerate(angles):
        g = np.eye(n)
        c, s = math.cos(a), math.sin(a)
        g[i, i], g[i, i + 1], g[i + 1, i], g[i + 1, i + 1] = c, -s, s, c
        t = t @ g
    return t


class Warped:
    """M y' = M k (I + N'(y))^-1 T^T f(T (y + N(y))): the system x' = f(x) in coordinates y with
    x = T (y + N(y)), time scaled by k, with a mass matrix M.  N is quadratic plus cubic with
    fixed coefficients.  The Jacobian is the complex-step derivative (exact to rounding)."""

    parameter_names = ("p",)

    def __init__(self, f, n, t=None, m=None, k=1.0, warp=0.3, seed=3):
        rng = np.random.default_rng(seed)
        self.f, self.n, self.k, self.warp, self.m = f, n, k, warp, m
        self.t = np.eye(n) if t is None else t
        self.quad = rng.uniform(-1, 1, (n, n, n))
        self.cub = rng.uniform(-0.5, 0.5, (n, n, n, n))

    def _n(self, y):
        return self.warp * (np.einsum("ijk,j,k->i", self.quad, y, y) + np.einsum("ijkl,j,k,l->i", self.cub, y, y, y))

    def _dn(self, y):
        q = np.einsum("ijk,k->ij", self.quad, y) + np.einsum("ikj,k->ij", self.quad, y)
        c = (np.einsum("ijkl,k,l->ij", self.cub, y, y) + np.einsum("ikjl,k,l->ij", self.cub, y, y)
             + np.einsum("iklj,k,l->ij", self.cub, y, y))
        return self.warp * (q + c)

    def residual(self, y, p):
        g = self.k * np.linalg.solve(np.eye(self.n) + self._dn(y), self.t.T @ self.f(self.t @ (y + self._n(y))))
        return g if self.m is None else self.m @ g

    def jacobian(self, y, p):
        h = 1e-30
        return np.array([np.imag(self.residual(y + 1j * h * e, p)) / h for e in np.eye(self.n)]).T

    def mass_matrix(self, y, p):
        return np.eye(self.n) if self.m is None else self.m


def _zero_hopf_field(b, c, d, e, g=0.0, h=0j):
    """xi' = b xi^2 + c |Z|^2 + g xi |Z|^2, Z' = (i + d xi + e xi^2 + h |Z|^2) Z, and a slaved
    s' = -s + xi^2 + v w + xi s / 2 (no feedback), in x = (xi, v, w, s), Z = v + i w; real
    arithmetic throughout (complex steps)."""

    def f(x):
        xi, v, w, s = x
        r2 = v * v + w * w
        ar = d.real * xi + e.real * xi * xi + h.real * r2
        ai = 1.0 + d.imag * xi + e.imag * xi * xi + h.imag * r2
        return np.array([b * xi * xi + c * r2 + g * xi * r2, ar * v - ai * w, ai * v + ar * w,
                         -s + xi * xi + v * w + 0.5 * xi * s])

    return f


def _zero_hopf_reference(b, c, d, e, g=0.0, h=0j, k=1.0):
    """(B, C, E, s, theta) of _zero_hopf_field: in z = Z / sqrt(2) its Taylor coefficients are
    g200 = b, g011 = 2 c, g110 = d, g300 = 0, g111 = 2 g, g210 = e, g021 = 2 h, and Kuznetsov's
    (sec. 8.5) B = g200, C = g011, theta = Re g110 / g200,
    E = Re[g210 + g110 (Re g021 / g011 - 3 g300 / (2 g200) + g111 / (2 g011)) - g021 g200 / g011]
    (E = Re e when g = h = 0: the field is then in the normal form itself); with q0 -> -q0 where
    b < 0 (contin's B >= 0): B, C change sign.  Time scaling by k multiplies B, C, E by k.

    E derived here, independently of the code and the book: in r = |z| the field is
    xi' = b xi^2 + C r^2 + G3 xi^3 + G1 xi r^2, r' = r (dr xi + er xi^2 + hr r^2) (dr = Re d,
    er = Re e, hr = Re g021, C = g011, G3 = g300, G1 = g111).  xi = eta + gamma r^2 with
    gamma = -hr / dr removes r^3 from r' and turns G1 into G1 + 2 gamma (b - dr); the time
    t -> (1 + alpha eta) t and eta = mu + beta mu^2 remove mu^3 and mu r^2 from mu'
    (alpha = -G3 / b, beta = (G1 + 2 gamma (b - dr) + alpha C) / (2 C)) and leave
    r' = r (dr mu + (er + dr (alpha + beta)) mu^2), so E = er + dr (alpha + beta)
    = er + dr (hr / C - 3 G3 / (2 b) + G1 / (2 C)) - hr b / C: the formula above."""
    g011, g111, g021 = 2 * c, 2 * g, 2 * h
    e_ref = (e + d * (g021.real / g011 + g111 / (2 * g011)) - g021 * b / g011).real
    sign = 1.0 if b > 0 else -1.0
    return {"B": k * sign * b, "C": k * sign * g011, "E": k * e_ref, "s": float(np.sign(b * c)), "theta": d.real / b}


ZH_CASES = [(-1.0, 0.5, 1.0 + 0.3j, 0.7 - 0.2j), (0.8, 0.6, -0.5 + 0.4j, -1.1 + 0.3j), (1.2, -0.4, 0.9 - 0.6j, 0.4)]


@pytest.mark.parametrize("coeffs", ZH_CASES)
def test_zero_hopf_normal_form_of_the_normal_form_and_its_transforms(coeffs):
    """B, C, E, s, theta of a system in ZH normal form (s = -1 and theta < 0; s = +1 and theta
    < 0; s = -1 and theta > 0) and of its transforms.  Tolerance 1e-6 relative: E uses third
    derivatives of F (central differences of J, relative ~1e-8) through the h's."""
    b, c, d, e = coeffs
    mass = np.array([[2.0, 0.3, 0.0, 0.1], [0.1, 1.5, 0.2, 0.0], [0.0, 0.4, 3.0, 0.2], [0.3, 0.0, 0.1, 1.0]])
    rot = _rotation(4, [0.7, 0.4, -0.9])
    f = _zero_hopf_field(*coeffs)
    cases = [({"warp": 0.0}, 1.0), ({}, 1.0), ({"t": rot}, 1.0), ({"t": rot, "k": 2.0}, 2.0),
             ({"t": rot, "k": 2.0, "m": mass}, 2.0)]
    for kw, k in cases:
        got = zero_hopf_coefficients(Warped(f, 4, **kw), np.zeros(4), {"p": 0.0}, k)
        ref = _zero_hopf_reference(*coeffs, k=k)
        assert got == pytest.approx(ref, rel=1e-6, abs=1e-9), kw


def test_zero_hopf_normal_form_with_cubic_terms_the_formula_removes():
    """The field with xi |Z|^2 and Z |Z|^2 terms (not yet in normal form): E from Kuznetsov's
    formula on its hand-read Taylor coefficients, the same after the transforms."""
    coeffs = dict(b=-1.0, c=0.5, d=1.0 + 0.3j, e=0.7 - 0.2j, g=0.4, h=-0.6 + 0.5j)
    ref = _zero_hopf_reference(**coeffs)
    assert ref["E"] == pytest.approx(0.7 + 1.0 * (-1.2 + 0.4) - 1.2)  # -1.3 by hand
    rot = _rotation(4, [0.2, -0.5, 1.1])
    for kw in ({"warp": 0.0}, {}, {"t": rot, "seed": 5}):
        got = zero_hopf_coefficients(Warped(_zero_hopf_field(**coeffs), 4, **kw), np.zeros(4), {"p": 0.0}, 1.0)
        assert got == pytest.approx(ref, rel=1e-6, abs=1e-9), kw


def _double_hopf_field(w1, w2, p):
    """Z1' = (i w1 + P11 |Z1|^2 + P12 |Z2|^2) Z1, Z2' = (i w2 + P21 |Z1|^2 + P22 |Z2|^2) Z2 (P
    complex, 2 x 2) and a slaved s' = -s + v1 w2 + v1^2 (no feedback), in x = (v1, w1, v2, w2, s)."""

    def f(x):
        v1, x1, v2, x2, s = x
        r1, r2 = v1 * v1 + x1 * x1, v2 * v2 + x2 * x2
        a1r, a1i = p[0][0].real * r1 + p[0][1].real * r2, w1 + p[0][0].imag * r1 + p[0][1].imag * r2
        a2r, a2i = p[1][0].real * r1 + p[1][1].real * r2, w2 + p[1][0].imag * r1 + p[1][1].imag * r2
        return np.array([a1r * v1 - a1i * x1, a1i * v1 + a1r * x1, a2r * v2 - a2i * x2, a2i * v2 + a2r * x2,
                         -s + v1 * x2 + v1 * v1])

    return f


HH_CASES = [((-1.0 + 0.2j, 0.5 - 0.3j), (-0.7 + 0.1j, -0.4 + 0.6j)),  # simple (p11 p22 > 0)
            ((1.0 - 0.5j, -2.0 + 0.3j), (0.6 + 0.2j, -0.5 - 0.1j))]  # difficult (p11 p22 < 0)


@pytest.mark.parametrize("p", HH_CASES)
def test_double_hopf_normal_form_of_the_normal_form_and_its_transforms(p):
    """p_ij = 2 Re P_ij (|Z_j|^2 = 2 |z_j|^2), theta = p12 / p22, delta = p21 / p11, for the
    frequencies 1 and 1.7 (no resonance of order <= 5 among the h's), and after the transforms;
    swapping the pairs swaps p11 <-> p22, p12 <-> p21, theta <-> delta."""
    w1, w2 = 1.0, 1.7
    f = _double_hopf_field(w1, w2, p)
    pij = {"p11": 2 * p[0][0].real, "p12": 2 * p[0][1].real, "p21": 2 * p[1][0].real, "p22": 2 * p[1][1].real}
    mass = np.diag([2.0, 1.5, 3.0, 1.0, 0.5]) + 0.2 * np.eye(5, k=1) + 0.1 * np.eye(5, k=-2)
    rot = _rotation(5, [0.7, 0.4, -0.9, 0.3])
    for kw, k in [({"warp": 0.0}, 1.0), ({}, 1.0), ({"t": rot}, 1.0), ({"t": rot, "k": 2.0}, 2.0),
                  ({"t": rot, "k": 2.0, "m": mass}, 2.0)]:
        pb = Warped(f, 5, **kw)
        ref = {key: k * v for key, v in pij.items()}
        ref.update(theta=pij["p12"] / pij["p22"], delta=pij["p21"] / pij["p11"])
        got = double_hopf_coefficients(pb, np.zeros(5), {"p": 0.0}, k * w1, k * w2)
        assert got == pytest.approx(ref, rel=1e-6, abs=1e-9), kw
        swapped = double_hopf_coefficients(pb, np.zeros(5), {"p": 0.0}, k * w2, k * w1)
        assert swapped == pytest.approx({"p11": ref["p22"], "p12": ref["p21"], "p21": ref["p12"], "p22": ref["p11"],
                                         "theta": ref["delta"], "delta": ref["theta"]}, rel=1e-6, abs=1e-9), kw


class Unfolded(Warped):
    """Warped with a field f(x, p) of the parameters (a, b); dF/dp by complex steps too."""

    parameter_names = ("a", "b")

    def residual(self, y, p):
        g = self.k * np.linalg.solve(np.eye(self.n) + self._dn(y), self.t.T @ self.f(self.t @ (y + self._n(y)), p))
        return g if self.m is None else self.m @ g

    def dresidual_dp(self, y, p, name):
        q = dict(p)
        q[name] = q[name] + 1e-30j
        return np.imag(self.residual(y, q)) / 1e-30


def test_located_double_hopf_carries_its_normal_form():
    """The HH normal form (the difficult case of HH_CASES) unfolded, Z1' = (a + i + ...) Z1,
    Z2' = (b + 1.7 i + ...) Z2, in warped coordinates with a mass matrix: the branch in a at
    b = -0.5 has its HB at a = 0, the Hopf curve a = 0 its HH at b = 0, where the stored normal
    form is p_ij = 2 Re P_ij (1e-6) and omega = 1, omega2 = 1.7; the curve of the other pair
    switched from it starts with the pairs swapped."""
    from contin.continuation import trace
    from contin.hopfcurve import trace_hopf_curve
    from contin.options import ContinuationOptions, StepOptions
    from contin.twoparam import continue_point

    p = HH_CASES[1]
    normal = _double_hopf_field(1.0, 1.7, p)

    def f(x, q):
        out = normal(x)
        v1, x1, v2, x2 = x[:4]
        return out + np.array([q["a"] * v1, q["a"] * x1, q["b"] * v2, q["b"] * x2, 0.0])

    mass = np.diag([2.0, 1.5, 3.0, 1.0, 0.5]) + 0.2 * np.eye(5, k=1)
    pb = Unfolded(f, 5, t=_rotation(5, [0.7, 0.4, -0.9, 0.3]), m=mass)
    step = StepOptions(ds=0.05, ds_max=0.1)
    br = trace(pb, np.zeros(5), {"a": -0.5, "b": -0.5}, "a",
               ContinuationOptions(step=step, bounds={"a": (-0.5, 0.5)}, max_steps=100))
    (hb,) = br.points("HB")
    opts = ContinuationOptions(step=step, bounds={"a": (-1, 1), "b": (-0.5, 0.5)}, max_steps=100)
    curve = trace_hopf_curve(pb, hb, "b", opts, parameter="a")
    (hh,) = curve.points("HH")
    assert abs(hh.params["b"]) < 1e-10 and abs(hh.params["a"]) < 1e-10
    assert hh.data["omega"] == pytest.approx(1.0, rel=1e-10) and hh.data["omega2"] == pytest.approx(1.7, rel=1e-10)
    pij = {"p11": 2 * p[0][0].real, "p12": 2 * p[0][1].real, "p21": 2 * p[1][0].real, "p22": 2 * p[1][1].real}
    ref = {**pij, "theta": pij["p12"] / pij["p22"], "delta": pij["p21"] / pij["p11"]}
    assert {k: hh.data[k] for k in ref} == pytest.approx(ref, rel=1e-6)
    assert ref["p11"] * ref["p22"] < 0  # the difficult case
    other = continue_point(pb, curve, hh, "b", opts)
    (start,) = other.points("HH")
    assert start.data["omega"] == pytest.approx(1.7, rel=1e-10)
    swapped = {"p11": ref["p22"], "p12": ref["p21"], "p21": ref["p12"], "p22": ref["p11"], "theta": ref["delta"],
               "delta": ref["theta"]}
    assert {k: start.data[k] for k in swapped} == pytest.approx(swapped, rel=1e-6)


def test_located_zero_hopf_carries_its_normal_form():
    """The ZH normal form (ZH_CASES[0]) unfolded, xi' = a + b/2 - xi^2 + c |Z|^2, Z' = (b + i + d xi
    + e xi^2) Z, in warped coordinates with a mass matrix: equilibria xi = +-sqrt(a + b/2) (Z = 0),
    the fold curve a = -b/2 and the Hopf curve b = -xi - 0.7 xi^2 meet at the ZH a = b = 0; located
    on both curves it stores _zero_hopf_reference's B, C, E, s, theta (1e-6).  (With xi' = a - xi^2
    the fold curve a = 0 cannot be parametrized by a: its start correction at fixed a is singular.)"""
    from scipy.optimize import fsolve

    from contin.continuation import trace_both
    from contin.foldcurve import trace_fold_curve
    from contin.hopfcurve import trace_hopf_curve
    from contin.options import ContinuationOptions, StepOptions

    coeffs = ZH_CASES[0]
    normal = _zero_hopf_field(*coeffs)

    def f(x, q):
        out = normal(x)
        xi, v, w = x[:3]
        return out + np.array([q["a"] + q["b"] / 2, q["b"] * v, q["b"] * w, 0.0])

    mass = np.array([[2.0, 0.3, 0.0, 0.1], [0.1, 1.5, 0.2, 0.0], [0.0, 0.4, 3.0, 0.2], [0.3, 0.0, 0.1, 1.0]])
    pb = Unfolded(f, 4, t=_rotation(4, [0.7, 0.4, -0.9]), m=mass, warp=0.2)
    xi = 0.2  # the equilibrium xi = sqrt(a + b/2) at a = 0.29, b = -0.5, with the slaved s = xi^2 / (1 - xi / 2)
    x0 = np.array([xi, 0.0, 0.0, xi * xi / (1 - xi / 2)])
    y0 = fsolve(lambda y: pb.t @ (y + pb._n(y)) - x0, pb.t.T @ x0, xtol=1e-13)
    start = {"a": xi * xi + 0.25, "b": -0.5}
    assert np.max(np.abs(pb.residual(y0, start))) < 1e-12
    step = StepOptions(ds=0.02, ds_max=0.05)
    br = trace_both(pb, y0, start, "a", ContinuationOptions(step=step, bounds={"a": (0.2, 0.6)}, max_steps=200))
    (lp,) = br.points("LP")
    (hb,) = br.points("HB")
    assert lp.params["a"] == pytest.approx(0.25, abs=1e-10)
    assert hb.params["a"] == pytest.approx(0.25 + ((math.sqrt(2.4) - 1) / 1.4) ** 2, rel=1e-8)
    opts = ContinuationOptions(step=step, bounds={"a": (-1, 1), "b": (-0.6, 0.5)}, max_steps=200)
    ref = _zero_hopf_reference(*coeffs)
    fold = trace_fold_curve(pb, lp, "b", opts, parameter="a")
    hopf = trace_hopf_curve(pb, hb, "b", opts, parameter="a")
    for curve in (fold, hopf):
        (zh,) = curve.points("ZH")
        assert abs(zh.params["a"]) < 1e-9 and abs(zh.params["b"]) < 1e-9
        assert {k: zh.data[k] for k in ref} == pytest.approx(ref, rel=1e-6, abs=1e-9), curve.kind
