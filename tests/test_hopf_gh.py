"""Generalized Hopf (Bautin) points, label GH, on Hopf curves (``contin.hopfsystem.LyapunovTest``).

References computed independently in the tests:
- the Bautin normal form z' = (b1 + i) z + b2 z|z|^2 - z|z|^4 (Kuznetsov, *Elements of Applied
  Bifurcation Theory*, 3rd ed., sec. 8.3), with a slaved third variable: the Hopf curve is b1 = 0
  with omega = 1, l1 = 2 b2 in Kuznetsov's normalisation q^H q = 1 (z = sqrt(2) w for
  q = (1, -i)/sqrt(2): w' = i w + 2 b2 w|w|^2), GH at b2 = 0;
- AUTO-07p's demo ab (a CSTR, tests/hopf_models.AB): the GH of its Hopf curve in (D, B) at
  beta = 3 solves F = 0, tr J = 0, a = 0 with a the Guckenheimer-Holmes coefficient (eq. 3.4.11 of
  *Nonlinear Oscillations, Dynamical Systems, and Bifurcations of Vector Fields*) from the
  model's analytic second and third derivatives, solved by scipy.optimize.fsolve; its second
  Lyapunov coefficient l2 from the Poincare map of the ODE (scipy's DOP853; ``ab_l2_poincare``);
- the Bautin normal form at GH with s = +-1 under linear and nonlinear changes of coordinates,
  time scaling and a mass matrix (``WarpedBautin``): l2 = 4 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import fsolve

from contin.continuation import trace
from contin.hopfcurve import trace_hopf_curve
from contin.options import ContinuationOptions, StepOptions
from hopf_models import AB


class Bautin:
    """x, y: the Bautin normal form in real coordinates; s' = -s + x^2 (slaved, no feedback)."""

    parameter_names = ("b1", "b2")

    def residual(self, u, p):
        x, y, s = u
        r2 = x * x + y * y
        g = p["b1"] + p["b2"] * r2 - r2 * r2
        return np.array([g * x - y, x + g * y, -s + x * x])

    def jacobian(self, u, p):
        x, y, s = u
        r2 = x * x + y * y
        g = p["b1"] + p["b2"] * r2 - r2 * r2
        gr = p["b2"] - 2 * r2  # dg/d(r2)
        return sp.csr_matrix(np.array([[g + 2 * x * x * gr, -1 + 2 * x * y * gr, 0.0],
                                       [1 + 2 * x * y * gr, g + 2 * y * y * gr, 0.0],
                                       [2 * x, 0.0, -1.0]]))

    def dresidual_dp(self, u, p, name):
        x, y, _ = u
        r2 = x * x + y * y
        return np.array([x, y, 0.0]) * (1.0 if name == "b1" else r2)


def test_bautin_gh_at_the_origin_and_l1_is_2_b2():
    pb = Bautin()
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-0.5, 0.5)}, max_steps=100)
    br = trace(pb, np.zeros(3), {"b1": -0.3, "b2": -0.4}, "b1", opts)
    (hb,) = br.points("HB")
    assert abs(hb.params["b1"]) < 1e-12 and hb.data["l1"] == pytest.approx(-0.8, rel=1e-6)
    curve = trace_hopf_curve(pb, hb, "b1", ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1),
                                                               bounds={"b2": (-0.4, 0.3)}, max_steps=100),
                             parameter="b2")
    (gh,) = curve.points("GH")
    assert gh.converged and "generalized Hopf" in gh.note
    # l1 comes from central differences of J (contin.hopf.FD_STEP_C = 1e-4): the quintic term
    # leaves an h^2 truncation of ~1.2e-7 in l1 (the HB's l1 above is -0.80000012), so the zero of
    # l1 = 2 b2 sits ~6e-8 off b2 = 0
    assert abs(gh.params["b2"]) < 1e-7 and abs(gh.params["b1"]) < 1e-12
    # l1 at the located zero: within the rounding of the differences (eps / FD_STEP_C^2 ~ 2e-8)
    assert abs(gh.data["l1"]) < 1e-8 and gh.data["omega"] == pytest.approx(1.0, rel=1e-12)
    assert gh.data["l2"] == pytest.approx(-4.0, abs=1e-6)  # s = -1: l2 = 4 s (WarpedBautin below)
    assert not curve.points("BT")
    # l1 along the curve, recomputed by the test function at stored points, against 2 b2
    from contin.extended import ExtendedSystem
    from contin.hopfsystem import HopfCurveProblem, LyapunovTest

    aug = HopfCurveProblem(pb, "b1", np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    test = LyapunovTest(aug)
    system = ExtendedSystem(aug, {"b1": 0.0, "b2": 0.0}, "b2")
    for i in range(0, len(curve.params["b2"]), 7):
        b2 = curve.params["b2"][i]
        x = np.concatenate([curve.states[i], [b2]])
        l1, hopf = test.value(system, x)
        assert hopf and l1 == pytest.approx(2 * b2, abs=2e-7)  # the truncation above


class WarpedBautin:
    """The Bautin normal form at its GH (b1 = b2 = 0), z' = i z + s z|z|^4 in x1 = Re z, x2 = Im z,
    with x3' = -x3 + x1^2, written in coordinates y with x = T (y + N(y)): M y' = M k (I + N'(y))^-1
    T^T f(T (y + N(y))).  N (quadratic and cubic) gives the system quadratic, cubic and quartic
    terms (B, C, D and all the H's of l2 nonzero); T orthogonal keeps |q| = 1; k scales time
    (omega = k); M is a mass matrix.  l2 is invariant under all of them: 4 s (the class
    docstring of ``Bautin`` above: z = sqrt(2) w, w' = i w + 4 s w|w|^4).  Its Jacobian is the
    complex-step derivative of the residual (exact to rounding)."""

    parameter_names = ("b1", "b2")

    def __init__(self, s, t=np.eye(3), m=None, k=1.0, warp=0.3):
        self.s, self.t, self.m, self.k, self.warp = s, t, m, k, warp

    def _f(self, x, p):
        r2 = x[0] ** 2 + x[1] ** 2
        g = p["b1"] + p["b2"] * r2 + self.s * r2 * r2
        return np.array([g * x[0] - x[1], x[0] + g * x[1], -x[2] + x[0] ** 2])

    def _n(self, y):
        return self.warp * np.array([y[0] * y[2] + 0.7 * y[1] ** 2 - 0.4 * y[0] ** 3,
                                     y[0] ** 2 - 0.5 * y[0] * y[1] + 0.6 * y[1] ** 2 * y[2],
                                     y[0] * y[1] + y[1] ** 2 + 0.8 * y[0] ** 2 * y[1]])

    def _dn(self, y):
        return self.warp * np.array([[y[2] - 1.2 * y[0] ** 2, 1.4 * y[1], y[0]],
                                     [2 * y[0] - 0.5 * y[1], -0.5 * y[0] + 1.2 * y[1] * y[2], 0.6 * y[1] ** 2],
                                     [y[1] + 1.6 * y[0] * y[1], y[0] + 2 * y[1] + 0.8 * y[0] ** 2, 0 * y[0]]])

    def residual(self, y, p):
        g = self.k * np.linalg.solve(np.eye(3) + self._dn(y), self.t.T @ self._f(self.t @ (y + self._n(y)), p))
        return g if self.m is None else self.m @ g

    def jacobian(self, y, p):
        h = 1e-30
        return np.array([np.imag(self.residual(y + 1j * h * e, p)) / h for e in np.eye(3)]).T

    def mass_matrix(self, y, p):
        return np.eye(3) if self.m is None else self.m


def _rotation(a, b):
    c1, s1, c2, s2 = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    return np.array([[c1, -s1, 0], [s1, c1, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, c2, -s2], [0, s2, c2]])


@pytest.mark.parametrize("s", [1.0, -1.0])
def test_second_lyapunov_coefficient_of_the_bautin_normal_form(s):
    """l2 = 4 s (Kuznetsov's normalization q^H q = 1, l2 = Re c2 / omega), the same after a
    rotation, a near-identity nonlinear change of coordinates, a time scaling (omega = 2) and a
    mass matrix.  Tolerance 1e-6: D and E are third and fourth differences of J
    (Richardson-extrapolated, ~1e-7 here)."""
    from contin.codim2tests import second_lyapunov
    from contin.hopf import first_lyapunov

    origin, u = {"b1": 0.0, "b2": 0.0}, np.zeros(3)
    mass = np.array([[2.0, 0.3, 0.0], [0.1, 1.5, 0.2], [0.0, 0.4, 3.0]])
    cases = [({"warp": 0.0}, 1.0), ({}, 1.0), ({"t": _rotation(0.7, 0.4)}, 1.0),
             ({"t": _rotation(0.7, 0.4), "k": 2.0}, 2.0), ({"t": _rotation(0.7, 0.4), "k": 2.0, "m": mass}, 2.0)]
    for kw, omega in cases:
        pb = WarpedBautin(s, **kw)
        assert abs(first_lyapunov(pb, u, origin, omega)) < 1e-6  # a GH: l1 = 0
        assert second_lyapunov(pb, u, origin, omega) == pytest.approx(4 * s, abs=1e-6), kw


def test_gh_detection_off_and_forced():
    pb = Bautin()
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-0.5, 0.5)}, max_steps=100)
    (hb,) = trace(pb, np.zeros(3), {"b1": -0.3, "b2": -0.4}, "b1", opts).points("HB")
    copts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b2": (-0.4, 0.3)}, max_steps=100)
    off = trace_hopf_curve(pb, hb, "b1", copts, parameter="b2", generalized_hopf=False)
    assert not off.points("GH") and off.params["b2"].max() > 0.29  # crossed b2 = 0 without a GH


def _gh_coefficient(u, p):
    """Guckenheimer-Holmes' a at a Hopf point of the planar AB model (sign of l1; zero at GH)."""
    u1, u2 = u
    d, b, beta = p["D"], p["B"], p["beta"]
    e = d * math.exp(u2)
    # h = (1 - u1) D e^{u2}: F = (-u1 + h, -(1 + beta) u2 + B h); derivatives of order >= 2 are c_k h_ij...
    h1, h2 = -e, (1 - u1) * e
    c = np.array([1.0, b])
    h2t = np.array([[0.0, -e], [-e, (1 - u1) * e]])
    h3t = np.zeros((2, 2, 2))
    h3t[0, 1, 1] = h3t[1, 0, 1] = h3t[1, 1, 0] = -e
    h3t[1, 1, 1] = (1 - u1) * e
    jac = np.array([[-1 + h1, h2], [b * h1, -(1 + beta) + b * h2]])
    # J's trace-free part [[a, b], [c, -a]] (J itself where tr J = 0): q = (b, i omega - a) with
    # omega^2 = -a^2 - b c is the eigenvector of i omega, and P = [Im q, Re q] gives
    # J P = P [[0, -omega], [omega, 0]], G-H's linear part (a smooth extension off tr J = 0)
    a, bb, cc = 0.5 * (jac[0, 0] - jac[1, 1]), jac[0, 1], jac[1, 0]
    omega = math.sqrt(-a * a - bb * cc)
    pmat = np.array([[0.0, bb], [omega, -a]])
    pinv = np.linalg.inv(pmat)
    c2 = np.einsum("k,ij->kij", c, h2t)
    c3 = np.einsum("k,ijl->kijl", c, h3t)
    f2 = np.einsum("mk,kij,ia,jb->mab", pinv, c2, pmat, pmat)
    f3 = np.einsum("mk,kijl,ia,jb,lc->mabc", pinv, c3, pmat, pmat, pmat)
    fxx, fxy, fyy = f2[0, 0, 0], f2[0, 0, 1], f2[0, 1, 1]
    gxx, gxy, gyy = f2[1, 0, 0], f2[1, 0, 1], f2[1, 1, 1]
    third = f3[0, 0, 0, 0] + f3[0, 0, 1, 1] + f3[1, 0, 0, 1] + f3[1, 1, 1, 1]
    return third / 16 + (fxy * (fxx + fyy) - gxy * (gxx + gyy) - fxx * gxx + fyy * gyy) / (16 * omega)


def ab_gh_reference() -> np.ndarray:
    """(u1, u2, D, B) of ab's GH at beta = 3: F = 0, tr J = 0, a = 0 by fsolve from a rough guess."""
    model = AB()

    def defining(z):
        u, p = z[:2], {"D": z[2], "B": z[3], "beta": 3.0}
        jac = model.jacobian(u, p).toarray()
        return np.concatenate([model.residual(u, p), [np.trace(jac), _gh_coefficient(u, p)]])

    z, _, ok, msg = fsolve(defining, np.array([0.6, 1.6, 0.28, 11.0]), xtol=1e-14, full_output=True)
    assert ok == 1 or (ok == 3 and np.max(np.abs(defining(z))) < 1e-12), msg
    jac = model.jacobian(z[:2], {"D": z[2], "B": z[3], "beta": 3.0}).toarray()
    omega = math.sqrt(np.linalg.det(jac))
    pmat = np.array([[0.0, jac[0, 1]], [omega, -jac[0, 0]]])
    assert np.allclose(np.linalg.solve(pmat, jac @ pmat), [[0, -omega], [omega, 0]], atol=1e-12)
    return z


def ab_l2_poincare(z: np.ndarray) -> float:
    """Kuznetsov's l2 of ab at the GH z = (u1, u2, D, B) (beta = 3) from its Poincare map,
    without normal forms: on the ray x0 + rho v (v = Re q / |Re q|, q numpy's unit eigenvector of
    i omega) one turn of the orbit moves rho by d(rho) = 2 pi l2 rho^5 / a^4 + O(rho^6) with
    a = 2 |Re q| (on the center manifold x - x0 = 2 Re(w q) + O(|w|^2), and one turn of
    w' = i omega w + c2 w|w|^4 changes |w| by 2 pi (Re c2 / omega) |w|^5; l1 = 0 at z).  The orbit
    is integrated in x - x0 (DOP853, rtol 1e-13) from 17 rho in [0.04, 0.2]; d / rho^5 is fitted
    by a polynomial of degree 6 in rho and taken at rho = 0 (degrees 4 to 7 agree within 5e-5
    relative)."""
    from scipy.integrate import solve_ivp

    model = AB()
    x0, p = z[:2], {"D": z[2], "B": z[3], "beta": 3.0}
    w, vecs = np.linalg.eig(model.jacobian(x0, p).toarray())
    k = int(np.argmax(w.imag))
    omega, q = float(w[k].imag), vecs[:, k] / np.linalg.norm(vecs[:, k])
    a = 2 * float(np.linalg.norm(q.real))
    v = q.real / np.linalg.norm(q.real)
    normal = np.array([-v[1], v[0]])

    def section(t, y):
        return float(y @ normal)

    rhos = np.linspace(0.04, 0.2, 17)
    ratios = []
    for rho in rhos:
        sol = solve_ivp(lambda t, y: model.residual(x0 + y, p), (0.0, 3 * math.pi / omega), rho * v, method="DOP853",
                        rtol=1e-13, atol=1e-18, events=section)
        back = next(y for t, y in zip(sol.t_events[0], sol.y_events[0]) if y @ v > 0 and t > math.pi / omega)
        ratios.append((float(back @ v) - rho) / rho**5)
    return float(np.polyfit(rhos, ratios, 6)[-1]) * a**4 / (2 * math.pi)


def test_auto_ab_hopf_curve_gh_against_the_defining_system():
    """AUTO's ab at beta = 3: from the lower HB at B = 14 (subcritical) the Hopf curve in (D, B)
    passes a BT at B = 64/3 one way and a GH the other way, then the upper (supercritical) HB."""
    model = AB()
    first = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.2), bounds={"B": (0.0, 100.0)},
                                user_zeros={"B": (14.0,)}, stop_at=("UZ1",))
    (uz,) = trace(model, np.zeros(2), {"D": 0.0, "B": 0.0, "beta": 3.0}, "B", first).points("UZ")
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"D": (0.0, 0.5)}, max_steps=2000)
    hb = trace(model, uz.state, uz.params, "D", opts).points("HB")
    assert len(hb) == 2
    for point in hb:  # the reference coefficient has l1's sign
        assert math.copysign(1.0, _gh_coefficient(point.state, point.params)) == math.copysign(1.0, point.data["l1"])
    copts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"D": (0.0, 0.5), "B": (0.0, 40.0)},
                                max_steps=300)
    curve = trace_hopf_curve(model, hb[0], "B", copts, parameter="D")
    (gh,) = curve.points("GH")
    (bt,) = curve.points("BT")
    assert bt.params["B"] == pytest.approx(64 / 3, rel=1e-9)  # BT of ab: tr J = det J = 0

    z = ab_gh_reference()
    assert gh.converged and abs(gh.data["l1"]) < 1e-8
    assert gh.params["D"] == pytest.approx(z[2], rel=1e-8)
    assert gh.params["B"] == pytest.approx(z[3], rel=1e-8)
    assert np.allclose(gh.state[:2], z[:2], rtol=1e-8, atol=0)
    # l2 of the GH (-0.44258) against its Poincare map (the reference's own spread: 5e-5)
    from contin.codim2tests import second_lyapunov

    reference = ab_l2_poincare(z)
    assert gh.data["l2"] == pytest.approx(reference, rel=1e-4)
    omega = math.sqrt(np.linalg.det(model.jacobian(z[:2], {"D": z[2], "B": z[3], "beta": 3.0}).toarray()))
    assert second_lyapunov(model, z[:2], {"D": z[2], "B": z[3], "beta": 3.0}, omega) == pytest.approx(reference, rel=1e-4)


def test_ab_scene_hopf_curve_gh_from_the_cli(tmp_path):
    """`contin trace ab` then `contin continue FILE --from HB1 --free B`: the GH row, stored, drawn."""
    import json

    from click.testing import CliRunner

    from contin import io
    from contin.cli import main

    def run(*args):
        return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)

    first, curve = tmp_path / "ab.h5", tmp_path / "hopf.h5"
    res = run("trace", "ab", "-o", first, "--json")
    assert res.exit_code == 0, res.output
    hb = [sp for sp in json.loads(res.stdout)["special_points"] if sp["type"] == "HB"]
    assert [sp["data"]["l1"] > 0 for sp in hb] == [True, False]  # subcritical, then supercritical
    res = run("continue", first, "--from", "HB1", "--free", "B", "--bounds", "B=0:40", "-o", curve, "--json")
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)["special_points"]
    (gh,) = [sp for sp in rows if sp["type"] == "GH"]
    (bt,) = [sp for sp in rows if sp["type"] == "BT"]
    z = ab_gh_reference()
    assert gh["params"]["D"] == pytest.approx(z[2], rel=1e-8) and gh["params"]["B"] == pytest.approx(z[3], rel=1e-8)
    assert bt["params"]["B"] == pytest.approx(64 / 3, rel=1e-9)
    assert "generalized Hopf" in gh["note"]
    (branch,), _ = io.load(curve)
    assert [sp.type for sp in branch.special_points if sp.type in ("BT", "GH")] == ["BT", "GH"]
    assert run("diagram", curve, "-o", tmp_path / "d.png").exit_code == 0
    assert "GH" in run("info", curve).output
    # from the BT of the Hopf curve, the fold curve through it (same parameters)
    fold = tmp_path / "fold.h5"
    res = run("continue", curve, "--from", "BT2", "--free", "B", "--bounds", "B=0:40", "-o", fold, "--json")
    assert res.exit_code == 0, res.output
    assert "fold curve from BT2" in res.stderr
    (branch,), _ = io.load(fold)
    assert branch.kind == "fold-curve"
    model, n = AB(), 2
    for i in range(0, len(branch), 10):  # every stored state is a fold of ab: F = 0, det J = 0
        p = {"D": branch.params["D"][i], "B": branch.params["B"][i], "beta": 3.0}
        u = branch.state(i)[:n]
        assert np.max(np.abs(model.residual(u, p))) < 1e-10
        assert abs(np.linalg.det(model.jacobian(u, p).toarray())) < 1e-8
    (start,) = branch.points("BT")
    assert start.params["B"] == pytest.approx(64 / 3, rel=1e-12) and "start: BT2" in start.note
    # the classical cusp of this reactor: B = 4 (1 + beta), u2 = 2, D = e^-2 (Uppal, Ray & Poore 1974)
    (cp,) = branch.points("CP")
    assert cp.params["B"] == pytest.approx(16.0, rel=1e-9) and cp.params["D"] == pytest.approx(math.exp(-2), rel=1e-9)
    res = run("continue", curve, "--from", "BT2", "--free", "beta")
    assert res.exit_code != 0 and "--free B" in res.output and "Traceback" not in res.output


def _co_l1(u, p):
    """Kuznetsov's l1 (eq. 3.20) of CO oxidation from its exact Hessian (the model is quadratic:
    C = 0), with numpy's eigenvectors; a smooth function of (u, p) near a Hopf point."""
    from hopf_models import CO

    q1, q3, q5 = p["q1"], p["q3"], p["q5"]
    dz = -np.ones(3)
    hess = np.zeros((3, 3, 3))
    hess[0] = 4 * q1 * np.outer(dz, dz)
    hess[0, 0, 0] -= 4 * q5
    hess[0, 0, 1] -= q3
    hess[0, 1, 0] -= q3
    hess[1, 0, 1] -= q3
    hess[1, 1, 0] -= q3

    def b(x, y):
        return np.einsum("kij,i,j->k", hess, x, y)

    a = np.asarray(CO().jacobian(u, p), float)
    mu, right = np.linalg.eig(a)
    k = int(np.argmax(mu.imag))
    omega, q = mu[k].imag, right[:, k] / np.linalg.norm(right[:, k])
    mu_l, left = np.linalg.eig(a.T)
    pl = left[:, int(np.argmin(np.abs(mu_l - np.conj(mu[k]))))]  # A^T p = conj(mu) p
    pl = pl / np.conj(np.vdot(pl, q))  # <p, q> = p^H q = 1
    qb = np.conj(q)
    total = (-2 * np.vdot(pl, b(q, np.linalg.solve(a, b(q, qb))))
             + np.vdot(pl, b(qb, np.linalg.solve(2j * omega * np.eye(3) - a, b(q, q)))))
    return float(total.real / (2 * omega))


def test_co_oxidation_hopf_curve_two_gh_against_the_defining_system():
    """BifurcationKit's tutorialCO, Hopf curve in (q2, k): each GH solves F = 0, a1 a2 = a3
    (Routh-Hurwitz: a pair +-i sqrt(a2)), l1 = 0 with l1 from the exact Hessian (fsolve)."""
    from hopf_models import CO

    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.01), bounds={"q2": (0.5, 1.9)}, max_steps=3000)
    branch = trace(CO(), np.array([0.2, 0.05, 0.5]), CO.PARAMS, "q2", opts)
    copts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"q2": (0.5, 2.2), "k": (0.0, 1.0)},
                                max_steps=600)
    curve = trace_hopf_curve(CO(), branch.points("HB")[0], "k", copts, parameter="q2")
    ghs = curve.points("GH")
    assert len(ghs) == 2

    def defining(z):
        u, p = z[:3], {**CO.PARAMS, "q2": z[3], "k": z[4]}
        j = np.asarray(CO().jacobian(u, p))
        a1 = -np.trace(j)
        a2 = sum(np.linalg.det(j[np.ix_(ix, ix)]) for ix in ([0, 1], [0, 2], [1, 2]))
        a3 = -np.linalg.det(j)
        return np.concatenate([CO().residual(u, p), [a1 * a2 - a3, _co_l1(u, p)]])

    for gh in ghs:
        guess = np.round(np.concatenate([gh.state[:3], [gh.params["q2"], gh.params["k"]]]), 2)
        z, _, ok, msg = fsolve(defining, guess, xtol=1e-14, full_output=True)
        assert ok == 1 or (ok == 3 and np.max(np.abs(defining(z))) < 1e-12), msg
        assert gh.converged
        assert gh.params["q2"] == pytest.approx(z[3], rel=1e-8)
        assert gh.params["k"] == pytest.approx(z[4], rel=1e-8)
        # l1 at the zero: the differences' rounding (~2e-8) relative to l1's size on the curve
        assert abs(gh.data["l1"]) < 1e-8 * abs(branch.points("HB")[0].data["l1"])


def test_ab_scene_range_of_b_and_beta():
    """`contin trace ab -s B=1e300` ended MX with a raw overflow warning: now one Error line."""
    from click.testing import CliRunner

    from contin.cli import main

    for setting, expect in (("B=1e300", "|B| / (1 + beta) <= 700"), ("beta=-1", "beta > -1"), ("B=inf", "must be finite")):
        res = CliRunner().invoke(main, ["trace", "ab", "-s", setting], catch_exceptions=False)
        assert res.exit_code != 0 and expect in res.output, res.output
        assert [ln for ln in res.output.splitlines() if ln.strip()] == [res.output.strip()]  # one line
        assert "Traceback" not in res.output and "RuntimeWarning" not in res.output
