"""Gravity in the linearised operator (problems.couette.linear) and the long-wave limit.

Issue 5, "growth rate vs k_x": our bottom plug at nu = 0.3, e = 0.8, Fr = 1000, H = 25 is weakly
unstable to long travelling waves, unlike the slides.  These tests establish that this is the
model's behaviour and not an operator defect:

- an independent linearisation: the x-, z-dependent equations of physics.md sections 1-2
  (gravity -H G nu in the y-momentum) written in physical space on a (phase, y) grid and
  linearised by complex steps; it must reproduce linear_operator exactly on a uniform base and
  converge spectrally to it on the plug states (it discretises divergences in flux form,
  d1 @ flux, where linear_operator expands products, so the two differ at truncation level);
- k_x = 0 against the steady problem: the unconstrained operator annihilates d(base)/d nu_bar
  from CouetteProblem.jacobian (the mass mode), and at the fold in G of the steady problem the
  mass-constrained operator has an exact zero eigenvalue;
- the long-wave limit: the least-stable mode at small k_x is the mass mode, omega = i c k_x +
  w2 k_x^2 + O(k_x^3) with c = -dq/d nu_bar the kinematic-wave speed of the steady mass flux
  q = int nu u dy (computed from steady solutions only), and w2 > 0 (the instability);
- spanwise mass modes (k_x = 0, k_z > 0) decay diffusively;
- stronger gravity (Fr < 166 at H = 25) makes the bottom plug stable for all k_x, k_z;
- the same numbers from the command line: ``contin trace gravity ... -s H_max=25`` then
  ``contin stability FILE --branch ID --point EPn`` on the states at H = 25.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la

from contin.continuation import newton, trace
from contin.foldcurve import fold_start
from contin.options import NewtonOptions
from problems.couette.closures import coefficients, uniform_shear
from problems.couette.gravity import (
    GravitySettings,
    g_options,
    gravity_free_branches,
    gravity_problem,
    homotopy_in_G,
)
from problems.couette.linear import _density_constraints, linear_operator
from problems.discretization import make_grid

NU, E, H, FR = 0.3, 0.8, 25.0, 1000.0

# --------------------------------------------------------------------------- independent operator
NTH = 4  # phase nodes theta = k_x x + k_z z: Fourier modes 0 and +-1 are differentiated exactly
THETA = 2.0 * np.pi * np.arange(NTH) / NTH


def _dtheta() -> np.ndarray:
    k = np.fft.fftfreq(NTH, 1.0 / NTH)
    k[NTH // 2] = 0.0
    return np.real(np.fft.ifft(1j * k[:, None] * np.fft.fft(np.eye(NTH), axis=0), axis=0))


DTH = _dtheta()


def tendencies(q, d1, kx, kz, e, H, G):
    """Right-hand sides of physics.md section 2 on a (theta, y) grid, flux form.

    d nu/dt = R_nu, nu d(u, v, w)/dt = (R_u, R_v, R_w), (3/2) nu dT/dt = R_T with
    R_nu = -div(nu u), R_i = -nu (u.grad) u_i - (1/H^2) d_j P_ij - H G nu delta_iy,
    R_T = -(3/2) nu u.grad T + (1/H^2) div(kappa grad T) - P:grad u - f5 T^{3/2},
    P = (p - lambda div u) I - 2 mu S.  q = (nu, u, v, w, T), each (NTH, n).
    """
    nu, u, v, w, T = q
    D = (lambda f: kx * (DTH @ f), lambda f: f @ d1.T, lambda f: kz * (DTH @ f))
    c = coefficients(nu, e)
    sT = np.sqrt(T)
    p, mu, lam, kap, dis = c.f1 * T, c.f2 * sT, c.f3 * sT, c.f4 * sT, c.f5 * T * sT
    vel = (u, v, w)
    grad = [[D[j](vel[i]) for j in range(3)] for i in range(3)]  # d_j u_i
    div = grad[0][0] + grad[1][1] + grad[2][2]
    P = [[((p - lam * div) if i == j else 0.0) - 2.0 * mu * (0.5 * (grad[i][j] + grad[j][i]) - (div / 3.0 if i == j else 0.0))
          for j in range(3)] for i in range(3)]
    out = [-(D[0](nu * u) + D[1](nu * v) + D[2](nu * w))]
    for i in range(3):
        r = -nu * sum(vel[j] * grad[i][j] for j in range(3)) - sum(D[j](P[i][j]) for j in range(3)) / H**2
        out.append(r - H * G * nu if i == 1 else r)
    gT = [D[j](T) for j in range(3)]
    out.append(-1.5 * nu * sum(vel[j] * gT[j] for j in range(3)) + sum(D[j](kap * gT[j]) for j in range(3)) / H**2
               - sum(P[i][j] * grad[i][j] for i in range(3) for j in range(3)) - dis)
    return out


def independent_operator(grid, nu0, u0, T0, G, kx, kz, h=1e-30):
    """(A, B) by complex steps of :func:`tendencies`, wall rows u = v = w = 0 and the linearised
    kappa dT/dy = 0, and the density constraints of linear_operator (_density_constraints)."""
    n = grid.size
    d1 = grid.d1.toarray()
    zero = np.zeros(n)
    base = np.stack([np.broadcast_to(f, (NTH, n)) for f in (nu0, u0, zero, zero, T0)]).astype(complex)
    A = np.zeros((5 * n, 5 * n), complex)
    mode1 = np.exp(-1j * THETA) * 2.0 / NTH  # Fourier coefficient of exp(i theta)
    for j in range(5 * n):
        pert = np.zeros((5, NTH, n))
        pert[j // n, :, j % n] = np.cos(THETA)  # Re(e_j exp(i theta)); response Re(A e_j exp(i theta))
        A[:, j] = np.concatenate([mode1 @ (r.imag / h) for r in tendencies(base + 1j * h * pert, d1, kx, kz, E, H, G)])
    bdiag = np.concatenate([np.ones(n), nu0, nu0, nu0, 1.5 * nu0])
    for node in (0, n - 1):
        for f in (1, 2, 3):
            A[f * n + node] = 0.0
            A[f * n + node, f * n + node] = 1.0
            bdiag[f * n + node] = 0.0
        row = np.zeros(5 * n, complex)
        for m in range(n):
            step = 1j * h * (np.arange(n) == m)
            for f, (a, b) in ((0, (nu0 + step, T0)), (4, (nu0, T0 + step))):
                row[f * n + m] = (coefficients(a, E).f4 * np.sqrt(b) * (d1 @ b))[node].imag / h
        A[4 * n + node] = row
        bdiag[4 * n + node] = 0.0
    C, Gdir = _density_constraints(grid, kx == 0.0 and kz == 0.0)
    R = A[:n]
    R -= Gdir @ np.linalg.solve(C.T @ Gdir, C.T @ R)
    J = la.qr(C.T, pivoting=True, mode="r")[1][: C.shape[1]]
    R[J] = 0.0
    R[J, :n] = C.T
    bdiag[J] = 0.0
    return A, np.diag(bdiag)


def leading(A, B, m=5):
    w = la.eigvals(A, B)
    w = w[np.isfinite(w) & (np.abs(w) < 1e8)]
    return w[np.lexsort((-w.imag, -w.real))][:m]


def mismatch(a, b):
    """Largest distance from an eigenvalue of a to the nearest one of b."""
    return np.abs(a[:, None] - b[None, :]).min(axis=1).max()


def dense(A, B):
    return A.toarray().astype(complex), B.toarray()


# --------------------------------------------------------------------------- base states
@pytest.fixture(scope="module")
def plugs():
    """Bottom and floating plugs at nu = 0.3, e = 0.8, H = 25, Fr = 1000 (cheb 32), and G = 0 ones."""
    pb = gravity_problem("cheb", 32)
    p0 = pb.params({"nu": NU, "e": E})
    _, g0 = gravity_free_branches(pb, p0, GravitySettings(H_range=(1.0, H + 2.0), modes=1))
    p = {**p0, "H": H, "G": 0.0}
    out = {"problem": pb, "p0": p, "p": {**p, "G": FR**-2}}
    for b in g0:
        r = newton(pb, b.state(int(np.argmin(np.abs(b.params["H"] - H)))), p, NewtonOptions())
        assert r.converged
        key = "bottom" if r.u[pb.i_nu][0] > r.u[pb.i_nu][-1] else "floating"
        out[key + "0"] = r.u
        out[key] = homotopy_in_G(pb, r.u, p, FR**-2)
    return out


def profiles(pb, x):
    nu, u, T, _, _ = pb.unpack(x)
    return nu, u, T


def omega(pb, x, p, kx, kz=0.0, **kw):
    A, B = linear_operator(pb.grid, *profiles(pb, x), p, kx=kx, kz=kz, **kw)
    return leading(*dense(A, B), m=1)[0]


# --------------------------------------------------------------------------- (a) operator
@pytest.mark.parametrize("kx,kz", [(0.0, 0.0), (0.3, 0.0), (0.3, 0.2)])
def test_independent_linearisation_exact_on_uniform_base(kx, kz):
    """Uniform nu, T and u = y (not a steady state when G != 0; the linearisation does not need
    one): flux and expanded forms coincide, so the matrices agree to rounding, gravity term
    included (G = 1e-2, H G = 0.25 is O(1) here)."""
    g = make_grid("cheb", 16)
    nu0 = np.full(g.size, NU)
    T0 = np.full(g.size, float(uniform_shear(NU, E)[0]))
    G = 1e-2
    Ai, Bi = independent_operator(g, nu0, g.y.copy(), T0, G, kx, kz)
    A, B = dense(*linear_operator(g, nu0, g.y.copy(), T0, {"e": E, "H": H, "G": G}, kx=kx, kz=kz))
    scale = np.abs(A).max()
    assert np.abs(A - Ai).max() < 1e-12 * scale
    assert np.array_equal(B, Bi)
    assert mismatch(leading(A, B, 8), leading(Ai, Bi, 12)) < 1e-9
    assert mismatch(leading(Ai, Bi, 8), leading(A, B, 12)) < 1e-9
    # the check is not blind to gravity: dropping it changes the v rows by H G nu = 0.25 nu
    A0 = linear_operator(g, nu0, g.y.copy(), T0, {"e": E, "H": H, "G": 0.0}, kx=kx, kz=kz)[0].toarray()
    n = g.size
    assert np.allclose((A0 - A)[2 * n + 1: 3 * n - 1, 1: n - 1], H * G * np.eye(n - 2), atol=1e-12 * scale)


@pytest.mark.parametrize("kx,kz,G", [(0.0, 0.0, FR**-2), (0.01, 0.0, FR**-2), (0.3, 0.2, 1e-2)])
def test_independent_linearisation_converges_on_plug(plugs, kx, kz, G):
    """On the bottom plug (interpolated from cheb 32) the two discretisations of the same
    equations differ only by truncation: leading eigenvalues differ by ~1e-4 at N = 16 and by
    < 1e-8 at N = 48 (measured: 4e-5 / 5e-4 / 0.9 at N = 16, 4e-11 / 5e-11 / 3e-9 at N = 48)."""
    pb = plugs["problem"]
    nu, u, T = profiles(pb, plugs["bottom"])
    diffs = {}
    for N in (16, 48):
        g = make_grid("cheb", N)
        base = [pb.grid.interpolate(f, g.y) for f in (nu, u, T)]
        A, B = dense(*linear_operator(g, *base, {**plugs["p"], "G": G}, kx=kx, kz=kz))
        w, wi = leading(A, B, 1)[0], leading(*independent_operator(g, *base, G, kx, kz), 1)[0]
        diffs[N] = abs(w - wi) / max(1.0, abs(w))
    assert diffs[48] < 1e-8
    assert diffs[16] > 1e3 * diffs[48]  # spectral convergence, not an algebraic difference


# --------------------------------------------------------------------------- (b) k_x = 0 vs steady problem
@pytest.mark.parametrize("side", ["bottom", "floating"])
def test_mass_mode_is_derivative_of_base_state(plugs, side):
    """Without the mass constraint the k_x = 0 operator annihilates d(nu, u, T)/d nu_bar of the
    steady problem (J dx = -dF/d nu_bar, CouetteProblem.jacobian): gravity enters both through
    d(f1 T)/dy = -H^3 G nu consistently.  The steady energy equation linearises D1(k(nu, T)) where
    the operator uses the product rule, so the residual is a truncation error: measured (max
    row / (|A| |X|)) 5e-8, 2e-9, 6e-13 at N = 24, 32, 48; asserted at N = 48 (state re-solved
    there).  With the constraint this mode is excluded."""
    pb32 = plugs["problem"]
    pb = gravity_problem("cheb", 48)
    p = plugs["p"]
    nu, u, T = (pb32.grid.interpolate(f, pb.grid.y) for f in profiles(pb32, plugs[side]))
    r = newton(pb, pb.pack(nu, u, T, pb32.unpack(plugs[side])[3]), p, NewtonOptions())
    assert r.converged
    x = r.u
    dF = np.zeros(pb.size)
    dF[pb.i_P] = -1.0  # F_P = w . nu - nu_bar
    dx = la.solve(pb.jacobian(x, p).toarray(), -dF)
    n = pb.n
    X = np.concatenate([dx[pb.i_nu], dx[pb.i_u], np.zeros(2 * n), dx[pb.i_T]])
    A, B = linear_operator(pb.grid, *profiles(pb, x), p, conserve_mass=False)
    scale = abs(A).max() * np.abs(X).max()
    assert np.abs(A @ X).max() < 1e-11 * scale
    assert np.abs((A @ X)[2 * n: 3 * n]).max() < 1e-13 * scale  # y-momentum, where gravity enters
    assert np.abs(leading(*dense(A, B), 1)[0]) < 1e-10
    w_con = omega(pb, x, p, 0.0)
    assert -3e-3 < w_con.real < -1e-3  # the least-stable constrained mode (-1.89e-3 / -1.68e-3)


def test_fold_in_G_is_neutral_at_kx0(plugs):
    """The floating plug at H = 25 dies at a fold in G (Fr* = 288.76 at cheb 32); on the fold
    system's solution the mass-constrained k_x = 0 operator has an exact zero eigenvalue."""
    pb, p = plugs["problem"], plugs["p0"]
    br = trace(pb, plugs["floating0"], p, "G", g_options(250.0**-2, 300), symmetric=False, branch_id="h")
    lp = br.fold_points[0]
    fold, U0 = fold_start(pb, lp, "G")
    r = newton(fold, U0, lp.params, NewtonOptions(tol=1e-11))
    assert r.converged
    x, G = r.u[: pb.size], r.u[2 * pb.size]
    assert G**-0.5 == pytest.approx(288.76, abs=0.05)
    w = omega(pb, x, {**p, "G": G}, 0.0)
    assert abs(w) < 1e-9
    # on the stable (lower) sheet just before the fold the same eigenvalue is negative
    assert omega(pb, plugs["floating"], plugs["p"], 0.0).real < -1e-3


# --------------------------------------------------------------------------- long waves
@pytest.mark.parametrize("side,sign", [("bottom", 1.0), ("floating", -1.0)])
def test_long_wave_mode_is_kinematic_wave(plugs, side, sign):
    """omega(k_x) = i c k_x + w2 k_x^2 + O(k_x^3): c = -dq/d nu_bar from steady solutions only
    (q = int nu u dy, the mass flux; the dense plug moves with its wall, so c ~ +-0.5 is the
    wall-speed kinematic wave), Re omega ~ k_x^2 (ratio 4 when k_x doubles) with w2 > 0."""
    pb, p, x = plugs["problem"], plugs["p"], plugs[side]

    def flux(nu_bar):
        r = newton(pb, x, {**p, "nu": nu_bar}, NewtonOptions())
        assert r.converged
        nu, u, _ = profiles(pb, r.u)
        return pb.grid.weights @ (nu * u)

    d = 1e-5
    c_kin = -(flux(NU + d) - flux(NU - d)) / (2 * d)
    w1, w2 = omega(pb, x, p, 1e-5), omega(pb, x, p, 2e-5)
    assert sign * c_kin == pytest.approx(0.53, abs=0.02)
    assert w1.imag / 1e-5 == pytest.approx(c_kin, rel=1e-4)
    assert w2.real / w1.real == pytest.approx(4.0, rel=1e-3)
    assert w1.real / 1e-10 > 10.0  # measured 20.17 (bottom), 27.84 (floating)


def test_gravity_stabilises_the_bottom_plug_long_waves(plugs):
    """At G = 0 the two banded states are mirror images: same w2 (23.54), opposite c.  Gravity
    lowers w2 of the bottom plug and raises that of the floating plug."""
    pb = plugs["problem"]
    coef = {}
    for key, pk in (("bottom0", "p0"), ("floating0", "p0"), ("bottom", "p"), ("floating", "p")):
        w = omega(pb, plugs[key], plugs[pk], 1e-4)
        coef[key] = (w.real / 1e-8, w.imag / 1e-4)
    assert coef["bottom0"][0] == pytest.approx(coef["floating0"][0], rel=1e-5)
    assert coef["bottom0"][1] == pytest.approx(-coef["floating0"][1], rel=1e-8)
    assert coef["bottom"][0] < coef["bottom0"][0] < coef["floating"][0]


def test_spanwise_mass_mode_decays(plugs):
    """k_x = 0, k_z > 0: no advection, the mass mode decays, Re omega ~ -0.155 k_z^2 (ratio 4)."""
    pb, p, x = plugs["problem"], plugs["p"], plugs["bottom"]
    a, b = omega(pb, x, p, 0.0, kz=1e-3), omega(pb, x, p, 0.0, kz=2e-3)
    assert a.real < 0 and b.real / a.real == pytest.approx(4.0, rel=1e-3)
    assert a.real / 1e-6 == pytest.approx(-0.155, abs=0.01)


def test_bottom_plug_is_stable_for_all_k_at_low_Fr(plugs):
    """Stronger gravity removes the long-wave instability of the bottom plug (the surviving
    attractor): w2 = Re omega / k_x^2 changes sign at Fr = 166.2 (cheb 48; cheb 64 agrees to 3
    digits: w2 = +1.08 at Fr = 200, -0.36 at 150), and at Fr = 120 max Re omega < 0 for every
    k_x in [1e-4, 3] and k_z in {0, 0.1, 1} (the mass mode is neutral only at k = 0)."""
    pb32 = plugs["problem"]
    pb = gravity_problem("cheb", 48)
    p = plugs["p0"]
    nu, u, T = (pb32.grid.interpolate(f, pb.grid.y) for f in profiles(pb32, plugs["bottom0"]))
    r = newton(pb, pb.pack(nu, u, T, pb32.unpack(plugs["bottom0"])[3]), p, NewtonOptions())
    assert r.converged
    w2 = {}
    x = r.u
    G_prev = 0.0
    for fr in (200.0, 150.0, 120.0):
        x = homotopy_in_G(pb, x, {**p, "G": G_prev}, fr**-2, max_steps=300)
        G_prev = fr**-2
        q = {**p, "G": G_prev}
        w2[fr] = omega(pb, x, q, 1e-4).real / 1e-8
    assert w2[200.0] == pytest.approx(1.079, abs=0.01)
    assert w2[150.0] == pytest.approx(-0.365, abs=0.01)
    assert pb.unpack(x)[0][0] < 0.65  # still a bottom plug below packing
    growth = [omega(pb, x, q, kx, kz).real for kz in (0.0, 0.1, 1.0) for kx in np.logspace(-4, 0.5, 12)]
    assert max(growth) < 0.0


# --------------------------------------------------------------------------- command line (issue 5)
def _cli(*args):
    import json

    from click.testing import CliRunner

    from contin.cli import main

    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout) if "--json" in args else r


def _ends_at_H(path, H):
    """{(branch id, label): phi} of the EP points of the stored branches at gap H."""
    from contin import io

    branches, _ = io.load(str(path))
    return {(b.id, sp.name): float(sp.order_parameter) for b in branches for sp in b.special_points
            if sp.name.startswith("EP") and sp.params["H"] == pytest.approx(H, abs=1e-9)}


def test_cli_stability_of_both_plugs_at_H25(tmp_path):
    """``contin trace gravity -s nu=0.3 -s e=0.8 -s Fr=1000 -s H_max=25 -s modes=1`` ends the
    primary (bottom plug, Phi = 0.126) and both sheets of the floating-plug branch (Phi = 0.615 and
    the middle sheet 0.308) at H = 25; ``contin stability FILE --branch ID --point EPn --json``
    gives the curves of results/gravity/growth_H25.png (cheb 32 here; cheb 48 / 64 agree to 4
    digits): both plugs stable at k_x = 0, unstable long waves with Re omega / k_x^2 = 20.13 /
    27.78 and c = +0.5289 / -0.5384 at k_x = 1e-4, +1.05e-4 / +1.13e-4 at k_x = 0.01, stable at
    0.1 and 1; the middle sheet is unstable already at k_x = 0 (+6.48e-4)."""
    h5 = tmp_path / "g25.h5"
    _cli("trace", "gravity", "-s", "nu=0.3", "-s", "e=0.8", "-s", "Fr=1000", "-s", "H_max=25", "-s", "modes=1",
         "--grid", 32, "--no-stability", "-q", "-o", h5)
    ends = _ends_at_H(h5, 25.0)
    assert len(ends) == 3 and {b for b, _ in ends} == {"0", "1"}
    by_phi = sorted(ends, key=ends.get)  # bottom plug, middle sheet, floating plug
    assert [ends[k] for k in by_phi] == pytest.approx([0.1255, 0.3077, 0.6146], abs=2e-4)
    assert by_phi[0][0] == "0" and by_phi[1][0] == by_phi[2][0] == "1"
    doc = {}
    for name, (bid, label) in zip(("bottom", "middle", "floating"), by_phi):
        doc[name] = _cli("stability", h5, "--branch", bid, "--point", label, "--kx", "0,1e-4,0.01,0.1,1", "--json")
        assert doc[name]["params"]["H"] == 25.0 and doc[name]["params"]["G"] == pytest.approx(1e-6, rel=1e-12)
    for name, w2, c, g01 in (("bottom", 20.13, 0.5289, 1.051e-4), ("floating", 27.78, -0.5384, 1.132e-4)):
        g, s = doc[name]["growth_rate"], doc[name]["phase_speed"]
        assert -2e-3 < g[0] < -1.5e-3
        assert g[1] / 1e-8 == pytest.approx(w2, abs=0.02)
        assert s[1] == pytest.approx(c, abs=2e-4)
        assert g[2] == pytest.approx(g01, rel=2e-3)
        assert g[3] < -1e-3 and g[4] < -1e-2
        assert doc[name]["n_unstable"] == [0, 1, 1, 0, 0]
    assert doc["middle"]["growth_rate"][0] == pytest.approx(6.48e-4, rel=1e-3)
    assert doc["middle"]["n_unstable"][0] == 1


def test_cli_bottom_plug_stable_for_all_kx_at_Fr120(tmp_path):
    """At Fr = 120 (< Fr* = 254.12: no floating plug exists) the run (first pitchfork's seeds)
    finds only the primary branch, which at H = 25 is the bottom plug (the surviving attractor,
    Phi = 0.0817, nu(-1/2) = 0.6493; cheb 48 resolves it): ``contin stability`` finds it stable for
    every k_x, with the long-wave coefficient w2 = -0.730 (test_bottom_plug_is_stable_for_all_k_at_low_Fr)."""
    h5 = tmp_path / "g120.h5"
    _cli("trace", "gravity", "-s", "nu=0.3", "-s", "e=0.8", "-s", "Fr=120", "-s", "H_max=25", "-s", "modes=1",
         "--grid", 48, "--no-stability", "-q", "-o", h5)
    ends = _ends_at_H(h5, 25.0)
    assert list(ends) == [("0", "EP2")] and ends["0", "EP2"] == pytest.approx(0.08174, abs=1e-4)
    doc = _cli("stability", h5, "--branch", "0", "--point", "EP2", "--kx", "0:3:13", "--json")
    kx_small = _cli("stability", h5, "--branch", "0", "--point", "EP2", "--kx", "1e-4,1e-3,1e-2", "--json")
    growth = doc["growth_rate"] + kx_small["growth_rate"]
    assert max(growth) < 0.0 and not any(doc["n_unstable"] + kx_small["n_unstable"])
    assert kx_small["growth_rate"][0] / 1e-8 == pytest.approx(-0.730, abs=0.005)
