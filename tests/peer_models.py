"""Peer problems: equilibria of AUTO-07p's demos and BifurcationKit's tutorials, written from their
published equations through the public API (``contin.from_functions``), each with its exact
Jacobian for the independent references of tests/test_peer_*.py (the core never sees it: it
builds its own by grouped differences from F alone, as a user's problem would).

- AUTO ``enz`` (demos/enz/enz.f90; two cells, one substrate, Doedel's tutorial):
  F1 = (s0 - s1) + (s2 - s1) - rho R(s1),  F2 = (s0 + mu - s2) + (s1 - s2) - rho R(s2),
  R(s) = s / (1 + s + kappa s^2); PAR = (s0, mu, rho, kappa) = (0, 0, 100, 1), u = 0.  For mu = 0
  the cells may be swapped (s1 <-> s2): on the symmetric branch s1 = s2 = s, s0 = s + rho R(s),
  J has the eigenvalues -1 - rho R'(s) (symmetric: folds) and -3 - rho R'(s) (antisymmetric:
  symmetry-breaking pitchforks).
- AUTO ``pp2`` (demos/pp2/pp2.f90; fish and sharks with a harvesting quota):
  F1 = r x (1 - x) - x y - q (1 - e^{-c x}),  F2 = -y + e x y; PAR = (q, r, c, e) = (0, 3, 5, 3).
  The trivial branch x = y = 0 has a BP at q = r / c; the shark-free branch y = 0 a BP at x = 1/e
  and a fold; the coexistence branch x = 1/e, y = r (1 - x) - q (1 - e^{-c x}) / x a Hopf point
  where dF1/dx = 0.
- AUTO ``abc`` (demos/abc/abc.f90; A -> B -> C in a CSTR, Doedel & Heinemann 1983):
  F1 = -x1 + D (1 - x1) E,  F2 = -x2 + D E (1 - x1 - s x2),
  F3 = -x3 - beta x3 + D B E (1 - x1 + alpha s x2),  E = e^{x3};
  PAR = (D, alpha, beta, B, s) = (0, 1, 1.55, 8, 0.04), u = 0.
- BifurcationKit's neural mass tutorial (Tsodyks-Markram rate model, tutorials/ode/tutorialsBasic1,
  after Cortes et al. 2013): tau E' = -E + g(J u x E + E0), x' = (1 - x)/tau_D - u x E,
  u' = (U0 - u)/tau_F + U0 (1 - u) E, g(y) = alpha log(1 + e^{y/alpha}); (alpha, tau, J, E0,
  tau_D, U0, tau_F) = (1.5, 0.013, 3.07, -2, 0.2, 0.3, 1.5), continued in E0 within [-4, -0.9]
  and its Hopf curve in (E0, alpha).
- AUTO ``pp3`` (demos/pp3/pp3.f90): x' = x (1 - x) - p4 x y, y' = -p2 y + p4 x y - p5 y z
  - p1 (1 - e^{-p6 y}), z' = -p3 z + p5 y z; its branches in p1 (BPs where a species appears)
  and the Hopf locus in (p1, p4) of the three-species branch (a closed curve).
- The Brusselator (Prigogine & Lefever 1968; the kinetics of AUTO's demo ``brc`` and of
  BifurcationKit's Brusselator PDE tutorials): x' = a - (b + 1) x + x^2 y, y' = b x - x^2 y; the
  equilibrium (a, b / a) has tr J = b - 1 - a^2, det J = a^2: a supercritical Hopf point at b = 1 + a^2, omega = a.
- AUTO ``plp`` (demos/plp/plp.f90; one cell, two substrates): F1 = (s0 - s) - rho R,
  F2 = alpha (a0 - a) - rho R, R = s a / (1 + s + kappa s^2); PAR = (s0, a0, alpha, rho, kappa) =
  (110, 500, 0.2, 2.021628, 0.1) at its start (s, a) = (45.55974, 177.7987), continued in rho: two
  subcritical Hopf points joined by a branch of cycles with two folds (LPC).
- pacopy's Bratu1d (:func:`pacopy_bratu`).
- BifurcationKit's ``chan`` example (examples/chan.jl; Chan's temperature problem): n = 101 points,
  x_1 = x_n = beta, (x_{i-1} - 2 x_i + x_{i+1}) (n - 1)^2 + alpha N(x_i) = 0 inside,
  N(x) = 1 + (x + a x^2) / (1 + beta x^2), a = 0.5; (alpha, beta) = (3.3, 0.01), its folds in alpha
  and the fold curve in (alpha, beta).
"""

from __future__ import annotations

import numpy as np

import contin

ENZ = dict(s0=0.0, mu=0.0, rho=100.0, kappa=1.0)
PP2 = dict(q=0.0, r=3.0, c=5.0, e=3.0)
ABC = dict(D=0.0, alpha=1.0, beta=1.55, B=8.0, s=0.04)


def enz_rate(s, kappa):
    return s / (1 + s + kappa * s * s)


def enz_rate_ds(s, kappa):
    return (1 - kappa * s * s) / (1 + s + kappa * s * s) ** 2


def enz_F(u, p):
    s1, s2 = u
    rho, kappa = p["rho"], p["kappa"]
    return np.array([(p["s0"] - s1) + (s2 - s1) - rho * enz_rate(s1, kappa),
                     (p["s0"] + p["mu"] - s2) + (s1 - s2) - rho * enz_rate(s2, kappa)])


def enz_J(u, p):
    d = [-2 - p["rho"] * enz_rate_ds(s, p["kappa"]) for s in u]
    return np.array([[d[0], 1.0], [1.0, d[1]]])


def enz():
    """The demo as a user writes it: F, the start point and the swap of the two cells."""
    return contin.from_functions(enz_F, np.zeros(2), ENZ, mass_matrix=np.eye(2), symmetry=lambda u: u[::-1].copy())


def pp2_F(u, p):
    x, y = u
    return np.array([p["r"] * x * (1 - x) - x * y - p["q"] * (1 - np.exp(-p["c"] * x)), -y + p["e"] * x * y])


def pp2_J(u, p):
    x, y = u
    return np.array([[p["r"] * (1 - 2 * x) - y - p["q"] * p["c"] * np.exp(-p["c"] * x), -x],
                     [p["e"] * y, -1 + p["e"] * x]])


def pp2():
    return contin.from_functions(pp2_F, np.zeros(2), PP2, mass_matrix=np.eye(2))


def abc_F(u, p):
    x1, x2, x3 = u
    e, d = np.exp(x3), p["D"]
    return np.array([-x1 + d * (1 - x1) * e,
                     -x2 + d * e * (1 - x1 - p["s"] * x2),
                     -x3 - p["beta"] * x3 + d * p["B"] * e * (1 - x1 + p["alpha"] * p["s"] * x2)])


def abc_J(u, p):
    x1, x2, x3 = u
    e, d, s, b, al = np.exp(x3), p["D"], p["s"], p["B"], p["alpha"]
    return np.array([[-1 - d * e, 0.0, d * (1 - x1) * e],
                     [-d * e, -1 - d * e * s, d * e * (1 - x1 - s * x2)],
                     [-d * b * e, d * b * e * al * s, -1 - p["beta"] + d * b * e * (1 - x1 + al * s * x2)]])


def abc():
    return contin.from_functions(abc_F, np.zeros(3), ABC, mass_matrix=np.eye(3))


TM = dict(alpha=1.5, tau=0.013, J=3.07, E0=-2.0, tauD=0.2, U0=0.3, tauF=1.5)
TM_GUESS = (0.238616, 0.982747, 0.367876)  # the tutorial's z0 (an equilibrium at E0 = -2 to 1e-6)


def tm_F(z, p):
    e, x, u = z
    s = p["J"] * u * x * e + p["E0"]
    return np.array([(-e + p["alpha"] * np.log(1 + np.exp(s / p["alpha"]))) / p["tau"],
                     (1 - x) / p["tauD"] - u * x * e,
                     (p["U0"] - u) / p["tauF"] + p["U0"] * (1 - u) * e])


def tm_J(z, p):
    e, x, u = z
    j, tau = p["J"], p["tau"]
    sig = 1 / (1 + np.exp(-(j * u * x * e + p["E0"]) / p["alpha"]))  # g'
    return np.array([[(-1 + sig * j * u * x) / tau, sig * j * u * e / tau, sig * j * x * e / tau],
                     [-u * x, -1 / p["tauD"] - u * e, -x * e],
                     [p["U0"] * (1 - u), 0 * e, -1 / p["tauF"] - p["U0"] * e]])


def tm(z0):
    """The tutorial's problem; the complex step (method='cs'): its rows scale with 1/tau = 77, and
    central differences leave the augmented Hopf system a residual floor of ~1e-9, above
    the corrector's 1e-10 (the Hopf curve's first point did not converge)."""
    return contin.from_functions(tm_F, z0, TM, mass_matrix=np.eye(3), method="cs")


PP3 = dict(p1=0.0, p2=0.25, p3=0.5, p4=4.0, p5=3.0, p6=5.0)


def pp3_F(u, p):
    """AUTO ``pp3`` (demos/pp3/pp3.f90; a predator-prey food chain with harvesting of the middle
    species): start (1, 0, 0), PAR(1..6) = (0, 0.25, 0.5, 4, 3, 5)."""
    x, y, z = u
    return np.array([x * (1 - x) - p["p4"] * x * y,
                     -p["p2"] * y + p["p4"] * x * y - p["p5"] * y * z - p["p1"] * (1 - np.exp(-p["p6"] * y)),
                     -p["p3"] * z + p["p5"] * y * z])


def pp3_J(u, p):
    x, y, z = u
    return np.array([[1 - 2 * x - p["p4"] * y, -p["p4"] * x, 0 * x],
                     [p["p4"] * y, -p["p2"] + p["p4"] * x - p["p5"] * z - p["p1"] * p["p6"] * np.exp(-p["p6"] * y),
                      -p["p5"] * y],
                     [0 * x, p["p5"] * z, -p["p3"] + p["p5"] * y]])


def pp3():
    return contin.from_functions(pp3_F, np.array([1.0, 0.0, 0.0]), PP3, mass_matrix=np.eye(3))


CHAN = dict(alpha=3.3, beta=0.01)
CHAN_N = 101


def chan_N(x, b, a=0.5):
    return 1 + (x + a * x * x) / (1 + b * x * x)


def chan_F(x, p):
    n = x.size
    f = np.empty_like(x)
    f[0], f[-1] = x[0] - p["beta"], x[-1] - p["beta"]
    f[1:-1] = (x[:-2] - 2 * x[1:-1] + x[2:]) * (n - 1) ** 2 + p["alpha"] * chan_N(x[1:-1], p["beta"])
    return f


def chan_J(x, p, a=0.5):
    n, b = x.size, p["beta"]
    xi = x[1:-1]
    jac = np.zeros((n, n))
    jac[0, 0] = jac[-1, -1] = 1.0
    k = np.arange(1, n - 1)
    jac[k, k - 1] = jac[k, k + 1] = (n - 1) ** 2
    jac[k, k] = -2 * (n - 1) ** 2 + p["alpha"] * (1 - b * xi**2 + 2 * a * xi) / (1 + b * xi**2) ** 2
    return jac


def chan_start():
    """The example's guess (i - 1)(n - i)/n^2 + 0.1 (1-based i), solved at (3.3, 0.01)."""
    from scipy.optimize import fsolve

    i = np.arange(1, CHAN_N + 1)
    return fsolve(chan_F, (i - 1) * (CHAN_N - i) / CHAN_N**2 + 0.1, args=(CHAN,), fprime=lambda x, p: chan_J(x, p),
                  xtol=1e-13)


def chan(u0):
    """The example's problem; the complex step (method='cs'): its interior rows scale with
    (n - 1)^2 = 1e4, and the fold curve's system (second derivatives of F by differences of J)
    with central differences stops at its first point (residual 6e-8 > 1e-10)."""
    return contin.from_functions(chan_F, u0, CHAN, method="cs")


def pacopy_bratu(n=51):
    """pacopy's Bratu1d (test/test_bratu1d.py): -u'' = lambda e^u on [0, 1] by second differences on
    n points (rows 0 and n-1: u = 0), its exact sparse Jacobian and dF/dlambda, and the trapezoid
    weights H of its inner product; start u = 0, lambda = 0."""
    import scipy.sparse as sp

    h = 1.0 / (n - 1)
    a = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n), format="lil") / h**2
    a[0, :2], a[n - 1, n - 2:] = [[1.0, 0.0]], [[0.0, 1.0]]
    a = sp.csr_matrix(a)
    inner = np.ones(n)
    inner[0] = inner[-1] = 0.0  # boundary rows of F are u itself, not the equation

    def F(u, p):
        return a @ u - inner * p["lmbda"] * np.exp(u)

    def jac(u, p):
        return a - sp.diags(inner * p["lmbda"] * np.exp(u))

    def dF_dp(u, p, name):
        return -inner * np.exp(u)

    weights = np.full(n, h)
    weights[0] = weights[-1] = h / 2
    return contin.from_functions(F, np.zeros(n), {"lmbda": 0.0}, jacobian=jac, dF_dp=dF_dp, debug=True,
                                 inner_product_weights=weights), F, jac


BRUSSELATOR = dict(a=1.5, b=2.5)


def brusselator_F(u, p):
    x, y = u
    return np.array([p["a"] - (p["b"] + 1) * x + x * x * y, p["b"] * x - x * x * y])


def brusselator_J(u, p):
    x, y = u
    return np.array([[-(p["b"] + 1) + 2 * x * y, x * x], [p["b"] - 2 * x * y, -x * x]])


def brusselator():
    """F alone (contin differences it), the equilibrium (a, b / a) as the start."""
    a, b = BRUSSELATOR["a"], BRUSSELATOR["b"]
    return contin.from_functions(brusselator_F, np.array([a, b / a]), BRUSSELATOR, mass_matrix=np.eye(2))


PLP = dict(s0=110.0, a0=500.0, alpha=0.2, rho=2.021628, kappa=0.1)
PLP_START = (4.555974e01, 1.777987e02)  # the demo's STPNT (an equilibrium to ~1e-6)


def plp_F(u, p):
    s, a = u
    r = s * a / (1 + s + p["kappa"] * s * s)
    return np.array([(p["s0"] - s) - p["rho"] * r, p["alpha"] * (p["a0"] - a) - p["rho"] * r])


def plp_J(u, p):
    s, a = u
    d = 1 + s + p["kappa"] * s * s
    drds, drda = (a * d - s * a * (1 + 2 * p["kappa"] * s)) / d**2, s / d
    return np.array([[-1 - p["rho"] * drds, -p["rho"] * drda], [-p["rho"] * drds, -p["alpha"] - p["rho"] * drda]])


def plp():
    """F alone (contin differences it), from the demo's start."""
    return contin.from_functions(plp_F, np.array(PLP_START), PLP, mass_matrix=np.eye(2))
