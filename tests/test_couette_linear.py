"""Linearised granular Couette operator (problems.couette.linear, physics.md sections 4-5)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from contin.stability import eigenvalues
from problems.couette.closures import coefficients, critical_gap_factor, uniform_shear
from problems.couette.linear import (
    growth_rate_curve,
    least_stable_mode,
    linear_operator,
    to_chebyshev,
    uniform_shear_modes,
)
from problems.discretization import make_grid

NU, E = 0.3, 0.8
T_US = float(uniform_shear(NU, E)[0])
JJ = dict(phi_w=0.5, ew=0.9)


def uniform(grid, nu=NU):
    return np.full(grid.size, nu), grid.y.copy(), np.full(grid.size, float(uniform_shear(nu, E)[0]))


def skewed(y):
    """A smooth, non-uniform, reflection-asymmetric base state (not a steady solution)."""
    return NU - 0.1 * np.sin(np.pi * y), y + 0.1 * (y * y - 0.25), T_US * (1 + 0.3 * np.sin(np.pi * y) + 0.1 * y * y)


def symmetric(y):
    """Invariant under (nu, u, T)(y) -> (nu(-y), -u(-y), T(-y))."""
    return NU + 0.08 * np.cos(2 * np.pi * y), y + 0.05 * np.sin(2 * np.pi * y), T_US * (1 + 0.2 * np.cos(2 * np.pi * y))


def mirror(grid, base):
    r = grid.reflection()
    nu0, u0, T0 = base
    return nu0[r], -u0[r], T0[r]


def spectrum(grid, base, params, **kw):
    A, B = linear_operator(grid, *base, params, **kw)
    return eigenvalues(A, B)


def match(a, b, tol):
    """Every eigenvalue of a has one of b within tol (and vice versa)."""
    d = np.abs(a[:, None] - b[None, :])
    return max(d.min(axis=1).max(), d.min(axis=0).max()) < tol


# ------------------------------------------------------------------ uniform shear, k = 0

@pytest.mark.parametrize("nu,H", [(0.3, 13.2), (0.3, 25.0), (0.5, 40.0), (0.2, 60.0)])
def test_spectrum_contains_amplitude_system(nu, H):
    g = make_grid("cheb", 48)
    w = spectrum(g, uniform(g, nu), dict(nu=nu, e=E, H=H))
    for n in (1, 2, 3):
        for lam in uniform_shear_modes(nu, E, H, n):
            assert np.min(np.abs(w - lam)) < 1e-8, (n, lam)


def test_printed_amplitude_system_regression_and_corrected_rates():
    # physics.md section 4 quotes omega(H) of its printed 4x4 system (which lacks nu0 U' v in
    # the x-momentum equation).  Quoted H have 4 digits: allow |d omega/dH| * 0.005 plus
    # half a unit in the last quoted digit.
    for H, quoted, unit in ((12.94, -1.04e-4, 1e-6), (13.20, 9.7e-5, 1e-6), (25.0, 1.18e-3, 1e-5)):
        w = uniform_shear_modes(NU, E, H, 1, advection=False)[0]
        slope = (uniform_shear_modes(NU, E, H + 1e-3, 1, advection=False)[0].real - w.real) / 1e-3
        assert w.imag == 0.0
        assert abs(w.real - quoted) <= abs(slope) * 0.005 + 0.5 * unit
    # The complete system (the one the section 5 operator contains): same neutral point,
    # smaller rates.
    got = [uniform_shear_modes(NU, E, H, 1)[0].real for H in (12.94, 13.20, 25.0)]
    np.testing.assert_allclose(got, [-6.02499e-5, 5.77745e-5, 6.49921e-4], rtol=1e-5)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_neutral_gap_is_critical_gap(n):
    hc = n * np.pi * float(critical_gap_factor(NU, E))
    assert hc / n == pytest.approx(13.0685, abs=1e-4)
    root = brentq(lambda H: uniform_shear_modes(NU, E, H, n)[0].real, 0.9 * hc, 1.1 * hc, xtol=1e-12)
    assert root == pytest.approx(hc, rel=1e-9)
    if n == 1:  # the full operator: leading eigenvalue crosses zero at H_1^c
        g = make_grid("cheb", 32)
        lead = [spectrum(g, uniform(g), dict(nu=NU, e=E, H=H))[0] for H in (hc * 0.999, hc, hc * 1.001)]
        assert lead[0].real < -1e-7 and abs(lead[1]) < 1e-10 and lead[2].real > 1e-7
        assert all(x.imag == 0 for x in lead)


def test_subcritical_density_threshold_no_instability():
    # nu = 0.15 lies below the shear-banding threshold (~0.156): uniform shear is stable at any H
    assert np.isnan(critical_gap_factor(0.15, E))
    g = make_grid("cheb", 32)
    for H in (50.0, 500.0):
        assert spectrum(g, uniform(g, 0.15), dict(nu=0.15, e=E, H=H))[0].real < 0


# ------------------------------------------------------------------ neutral and spurious modes

@pytest.mark.parametrize("method,N", [("cheb", 32), ("fd2", 40), ("fd4", 40), ("fd6", 48)])
@pytest.mark.parametrize("walls", ["noslip", "jj"])
def test_no_spurious_zero_modes_at_k0(method, N, walls):
    g = make_grid(method, N)
    prm = dict(nu=NU, e=E, H=25.0, **JJ)
    base = skewed(g.y)
    A, B = linear_operator(g, *base, prm, walls=walls)
    w = eigenvalues(A, B)
    n = g.size
    assert w.size == 5 * n - 8 - 2  # 8 boundary rows, mass and spurious-pressure constraints
    assert np.min(np.abs(w)) > 1e-5
    # without the mass constraint the neutral mass mode is back, exactly
    A0, B0 = linear_operator(g, *base, prm, walls=walls, conserve_mass=False)
    w0 = eigenvalues(A0, B0)
    assert w0.size == w.size + 1 and np.min(np.abs(w0)) < 1e-9
    if method == "cheb":  # the constraint removes exactly that mode
        assert match(w, w0[np.abs(w0) > 1e-9], 1e-9)


def test_mass_mode_is_density_derivative_of_base_state():
    # the removed omega = 0 eigenvector of uniform shear is the uniform state's d/d nu_bar:
    # nu_hat = 1, T_hat = dT0/dnu, u_hat = v_hat = w_hat = 0
    g = make_grid("cheb", 16)
    A0, B0 = linear_operator(g, *uniform(g), dict(nu=NU, e=E, H=25.0), conserve_mass=False)
    x = np.zeros(5 * g.size)
    x[: g.size] = 1.0
    c = coefficients(NU, E)
    x[4 * g.size:] = (c.f2_nu / c.f2 - c.f5_nu / c.f5) * T_US
    np.testing.assert_allclose(A0 @ x, 0.0, atol=1e-12)


# ------------------------------------------------------------------ symmetry

@pytest.mark.parametrize("walls", ["noslip", "jj"])
@pytest.mark.parametrize("method,N", [("cheb", 32), ("fd4", 48)])
def test_reflection_invariance(walls, method, N):
    g = make_grid(method, N)
    prm = dict(nu=NU, e=E, H=25.0, **JJ)
    b = skewed(g.y)
    rb = mirror(g, b)
    assert match(spectrum(g, b, prm, walls=walls), spectrum(g, rb, prm, walls=walls), 1e-9)
    # k_x != 0: the mirror image (x, y) -> (-x, -y) maps k_x to -k_x, i.e. to the conjugate spectrum
    w = spectrum(g, b, prm, walls=walls, kx=0.7, kz=0.4)
    wr = spectrum(g, rb, prm, walls=walls, kx=0.7, kz=0.4)
    assert match(w, np.conj(wr), 1e-8)
    assert not match(w, np.conj(w), 1e-3)  # the asymmetric base state really is asymmetric
    # a symmetric base state has a conjugation-closed spectrum (standing patterns or pairs)
    ws = spectrum(g, symmetric(g.y), prm, walls=walls, kx=0.7, kz=0.4)
    assert match(ws, np.conj(ws), 1e-8)


def test_gravity_reverses_under_reflection():
    g = make_grid("cheb", 32)
    b = skewed(g.y)
    up = spectrum(g, b, dict(nu=NU, e=E, H=25.0, G=1e-5))
    down = spectrum(g, mirror(g, b), dict(nu=NU, e=E, H=25.0, G=-1e-5))
    flat = spectrum(g, b, dict(nu=NU, e=E, H=25.0, G=0.0))
    assert match(up, down, 1e-9) and not match(up, flat, 1e-6)
    off = spectrum(g, b, dict(nu=NU, e=E, H=25.0, G=1e-5), gravity=False)
    assert match(off, flat, 1e-12)


# ------------------------------------------------------------------ convergence, dispersion

@pytest.mark.parametrize("walls", ["noslip", "jj"])
@pytest.mark.parametrize("kx,kz", [(0.0, 0.0), (0.5, 0.0), (2.0, 0.3)])
def test_leading_eigenvalue_converges(walls, kx, kz):
    prm = dict(nu=NU, e=E, H=25.0, **JJ)
    lead = []
    for N in (32, 48):
        g = make_grid("cheb", N)
        lead.append(spectrum(g, skewed(g.y), prm, walls=walls, kx=kx, kz=kz)[0])
    assert abs(lead[0] - lead[1]) < 1e-6


def test_fd_agrees_with_chebyshev_at_k0():
    prm = dict(nu=NU, e=E, H=25.0)
    gc = make_grid("cheb", 32)
    ref = spectrum(gc, skewed(gc.y), prm)[0]
    errs = []
    for N in (40, 80):
        g = make_grid("fd4", N)
        errs.append(abs(spectrum(g, skewed(g.y), prm)[0] - ref))
    assert errs[1] < 1e-7
    assert np.log2(errs[0] / errs[1]) > 3.5  # fourth order


def test_to_chebyshev_resamples_fd_base():
    g = make_grid("fd6", 60)
    gc, *base = to_chebyshev(g, *skewed(g.y), intervals=32)
    assert gc.method == "cheb" and gc.intervals == 32
    ref = skewed(gc.y)
    for f, r in zip(base, ref):
        np.testing.assert_allclose(f, r, atol=1e-8)
    same = to_chebyshev(gc, *ref)
    assert same[0] is gc


def test_growth_rate_curve_is_continuous():
    g = make_grid("cheb", 32)
    prm = dict(nu=NU, e=E, H=25.0)
    base = skewed(g.y)
    k, growth, c = growth_rate_curve(g, *base, prm, np.linspace(0.0, 3.0, 25))
    _, fine, _ = growth_rate_curve(g, *base, prm, np.linspace(0.0, 3.0, 49))
    np.testing.assert_allclose(fine[::2], growth, atol=1e-14)
    jump, jump_fine = np.max(np.abs(np.diff(growth))), np.max(np.abs(np.diff(fine)))
    assert jump_fine < 0.6 * jump  # jumps would not shrink with the sampling step
    assert np.isnan(c[0]) and np.all(np.isfinite(c[1:]))
    assert growth[0] == pytest.approx(spectrum(g, base, prm)[0].real, abs=1e-14)


def test_least_stable_mode_uniform_shear_eigenfunction():
    g = make_grid("cheb", 32)
    m = least_stable_mode(g, *uniform(g), dict(nu=NU, e=E, H=25.0))
    assert m.omega == pytest.approx(uniform_shear_modes(NU, E, 25.0, 1)[0], abs=1e-10)
    shape = np.cos(np.pi * (g.y + 0.5))
    for f in (m.nu, m.T):
        coef = (f @ shape) / (shape @ shape)
        np.testing.assert_allclose(f, coef * shape, atol=1e-9)
    np.testing.assert_allclose(m.w, 0.0, atol=1e-12)
    assert np.isnan(m.phase_speed)
    mk = least_stable_mode(g, *skewed(g.y), dict(nu=NU, e=E, H=25.0), kx=1.0)
    assert mk.phase_speed == pytest.approx(mk.omega.imag, abs=1e-15)
    assert max(np.max(np.abs(v)) for v in mk.profiles().values()) == pytest.approx(1.0)


# ------------------------------------------------------------------ linearisation check

def _d_fourier(f, k, axis):
    m = f.shape[axis]
    kk = k * np.fft.fftfreq(m, 1.0 / m)
    shape = [1, 1, 1]
    shape[axis] = m
    return np.real(np.fft.ifft(1j * kk.reshape(shape) * np.fft.fft(f, axis=axis), axis=axis))


def _nonlinear(g, fields, prm, kx, kz, walls):
    """The full 3-D equations of physics.md section 2 (Alam scaling) on an (x, z, y) grid.

    Returns the right-hand sides (d nu/dt, nu du/dt, nu dv/dt, nu dw/dt, (3/2) nu dT/dt) and
    the wall-condition residuals, for fields shaped (Mx, Mz, n).
    """
    nu, u, v, w, T = fields
    H, G, e, num = prm["H"], prm["G"], prm["e"], 0.65
    d1 = g.d1.toarray()

    def dx(f):
        return _d_fourier(f, kx, 0)

    def dz(f):
        return _d_fourier(f, kz, 1)

    def dy(f):
        return f @ d1.T

    c = coefficients(nu, e, "jj", num, dufour=True)
    s = np.sqrt(T)
    vel = (u, v, w)
    grad = [[dx(q), dy(q), dz(q)] for q in vel]  # grad[i][j] = d_j u_i
    div = grad[0][0] + grad[1][1] + grad[2][2]
    P = [[(c.f1 * T - c.f3 * s * div) * (i == j) - c.f2 * s * (grad[i][j] + grad[j][i] - (2 / 3) * div * (i == j))
          for j in range(3)] for i in range(3)]
    dj = (dx, dy, dz)
    adv = lambda q: u * dx(q) + v * dy(q) + w * dz(q)  # noqa: E731
    r_nu = -(dx(nu * u) + dy(nu * v) + dz(nu * w))
    r_mom = [-nu * adv(vel[i]) - sum(dj[j](P[j][i]) for j in range(3)) / H**2 for i in range(3)]
    r_mom[1] = r_mom[1] - H * G * nu
    kap, kh = c.f4 * s, c.fh * T * s
    heat = sum(dj[j](kap * dj[j](T) + kh * dj[j](nu)) for j in range(3)) / H**2
    r_T = -1.5 * nu * adv(T) + heat - sum(P[i][j] * grad[i][j] for i in range(3) for j in range(3)) - c.f5 * T * s
    flux = kap * dy(T) + kh * dy(nu)  # = -H^2 Q
    walls_res = {}
    for node, nsign in ((0, 1.0), (-1, -1.0)):
        if walls == "noslip":
            walls_res[node] = (u[..., node], v[..., node], w[..., node], flux[..., node])
            continue
        cs = prm["phi_w"] * np.pi / (2 * np.sqrt(3) * num)
        cd = np.sqrt(3) * np.pi * (1 - prm["ew"] ** 2) / (4 * num)
        sw = cs * nu * c.chi * s
        dw = cd * nu * c.chi * T * s
        slip = u + 0.5 * nsign
        sx = -P[0][1] - nsign * H * sw * slip
        sz = -P[2][1] - nsign * H * sw * w
        q = -flux / H**2 - nsign * (H * sw * (slip**2 + w**2) - dw / H)
        walls_res[node] = tuple(f[..., node] for f in (sx, v, sz, q))
    return (r_nu, *r_mom, r_T), walls_res


@pytest.mark.parametrize("walls", ["noslip", "jj"])
def test_operator_is_linearisation_of_full_equations(walls):
    g = make_grid("cheb", 24)
    kx, kz = 0.8, 0.5
    prm = dict(nu=NU, e=E, H=7.0, G=2e-3, **JJ)
    y = g.y
    base = skewed(y)
    A, B = linear_operator(g, *base, prm, walls=walls, kx=kx, kz=kz, dufour=True)
    A = A.toarray()
    xhat = np.concatenate([
        (0.02 + 0.01j) * np.exp(1j * y) * (1 + y), 0.03 * np.cos(2 * y) + 0.01j * y, (0.02 - 0.01j) * (1 + y * y),
        0.01 * np.exp(-y) + 0.02j, (0.05 + 0.02j) * np.sin(3 * y + 0.4)])
    n, M = g.size, 8
    xg = np.arange(M) * 2 * np.pi / (kx * M)
    zg = np.arange(M) * 2 * np.pi / (kz * M)
    phase = np.exp(1j * (kx * xg[:, None, None] + kz * zg[None, :, None]))
    pert = [np.real(xhat[i * n:(i + 1) * n][None, None, :] * phase) for i in range(5)]
    b3 = [np.broadcast_to(f, (M, M, n)) for f in (base[0], base[1], 0 * y, 0 * y, base[2])]
    eps = 1e-5
    rp, wp = _nonlinear(g, [b + eps * p for b, p in zip(b3, pert)], prm, kx, kz, walls)
    rm, wm = _nonlinear(g, [b - eps * p for b, p in zip(b3, pert)], prm, kx, kz, walls)

    def mode(f):  # complex amplitude of exp(i kx x + i kz z)
        return 2 * np.fft.fft2(f, axes=(0, 1))[1, 1] / M**2

    lin = np.concatenate([mode((a - b) / (2 * eps)) for a, b in zip(rp, rm)])
    ax = A @ xhat
    bulk = B.diagonal() != 0  # bulk rows (boundary and constraint rows have zero B)
    scale = np.max(np.abs(lin))
    assert np.max(np.abs(ax[bulk] - lin[bulk])) < 1e-6 * scale
    for node in (0, -1):
        got = [ax[var * n + (node % n)] for var in (1, 2, 3, 4)]
        ref = [mode((a - b) / (2 * eps)) for a, b in zip(wp[node], wm[node])]
        for gv, rv in zip(got, ref):
            assert abs(gv - rv) < 1e-6 * max(1.0, abs(rv))


def test_input_errors():
    g = make_grid("cheb", 16)
    base = uniform(g)
    with pytest.raises(ValueError, match="wall type"):
        linear_operator(g, *base, dict(e=E, H=10.0), walls="sticky")
    with pytest.raises(ValueError, match="shape"):
        linear_operator(g, base[0][:-1], base[1], base[2], dict(e=E, H=10.0))
    with pytest.raises(ValueError, match="'H'"):
        linear_operator(g, *base, dict(e=E))
    with pytest.raises(ValueError, match="phi_w"):
        linear_operator(g, *base, dict(e=E, H=10.0), walls="jj")
    with pytest.raises(ValueError, match="density"):
        linear_operator(g, np.full(g.size, 0.7), base[1], base[2], dict(e=E, H=10.0))
    with pytest.raises(ValueError, match="temperature"):
        linear_operator(g, base[0], base[1], -base[2], dict(e=E, H=10.0))


# ------------------------------------------------------------------ through the steady problem

def test_unstable_count_of_uniform_shear_via_model():
    # every mode n with H > H_n^c = n H_1^c contributes one real unstable eigenvalue
    from contin.stability import stability_of_state
    from problems.couette.model import CouetteProblem

    prob = CouetteProblem("cheb", 32)
    hc = np.pi * float(critical_gap_factor(NU, E))
    for H in (10.0, 20.0, 30.0, 40.0, 60.0):
        p = prob.params(dict(nu=NU, e=E, H=H))
        res = stability_of_state(prob, prob.uniform_state(p), p, n_eigs=3)
        assert res.n_unstable == int(H // hc)
        assert res.leading.real == pytest.approx(max(uniform_shear_modes(NU, E, H, n)[0].real for n in range(1, 6)),
                                                 abs=1e-10)


@pytest.mark.parametrize("walls", ["noslip", "jj"])
def test_leading_eigenvalue_converges_fine_grids(walls):
    prm = dict(nu=NU, e=E, H=25.0, **JJ)
    lead = []
    for N in (64, 96):
        g = make_grid("cheb", N)
        lead.append(spectrum(g, skewed(g.y), prm, walls=walls, kx=3.0, kz=1.0)[0])
    assert abs(lead[0] - lead[1]) < 1e-9
