"""Small non-granular models with Hopf points, written from their published equations.

- Lorenz (1963): sigma (y - x), rho x - y - x z, x y - beta z.
- AUTO-07p demo ``ab`` (the A -> B reaction in a CSTR; demos/ab/ab.f90):
  F1 = -u1 + D (1 - u1) e^{u2},  F2 = -u2 + D B (1 - u1) e^{u2} - beta u2  (PAR(1..3) = D, B, beta).
- CO oxidation (Bykov-Yablonskii-Kim; BifurcationKit's tutorialCO): with z = 1 - x - y - s,
  x' = 2 q1 z^2 - 2 q5 x^2 - q3 x y,  y' = q2 z - q6 y - q3 x y,  s' = q4 z - k q4 s.
- 1-D Brusselator of BifurcationKit's tutorial (Lust 1997): n points, h = 1/n, Dirichlet values
  (alpha, beta/alpha), c_i = D_i / (l^2 h^2).
- The Hopf normal form x' = mu x - y + a x r^2, y' = x + mu y + a y r^2 (Kuznetsov's l1 = 2 a).

And :class:`Hidden`: a problem with some of its optional hooks hidden.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from contin.problem import complex_step_dp
from problems.demo import AB as ABDemo
from problems.demo import COOxidation


class Lorenz:
    parameter_names = ("sigma", "rho", "beta")

    def residual(self, u, p):
        x, y, z = u
        return np.array([p["sigma"] * (y - x), p["rho"] * x - y - x * z, x * y - p["beta"] * z])

    def jacobian(self, u, p):
        x, y, z = u
        s, r, b = p["sigma"], p["rho"], p["beta"]
        return sp.csc_matrix(np.array([[-s, s, 0.0], [r - z, -1.0, -x], [y, x, -b]]))

    def dresidual_dp(self, u, p, name):
        x, y, z = u
        return {"sigma": np.array([y - x, 0.0, 0.0]), "rho": np.array([0.0, x, 0.0]),
                "beta": np.array([0.0, 0.0, -z])}[name]


AB = ABDemo  # the demo problem (problems/demo.py), AUTO-07p's demos/ab equations
CO = COOxidation  # the demo problem (problems/demo.py), BifurcationKit's tutorialCO equations


class Brusselator1D:
    """BifurcationKit's Fbru / Jbru_sp (tutorials3.md) with n points per species."""

    parameter_names = ("alpha", "beta", "D1", "D2", "l")
    PARAMS = dict(alpha=2.0, beta=5.45, D1=0.008, D2=0.004, l=0.3)

    def __init__(self, n: int) -> None:
        self.n = n
        self.lap = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc")

    def residual(self, x, p):
        n, a, b = self.n, p["alpha"], p["beta"]
        h2 = 1.0 / n**2
        c1, c2 = p["D1"] / p["l"] ** 2 / h2, p["D2"] / p["l"] ** 2 / h2
        u, v = x[:n], x[n:]
        dt = np.result_type(x.dtype, type(a), type(b))
        bu = np.zeros(n, dtype=dt)
        bv = np.zeros(n, dtype=dt)
        bu[0] = bu[-1] = a
        bv[0] = bv[-1] = b / a
        fu = c1 * (self.lap @ u + bu) + a - (b + 1) * u + u * u * v
        fv = c2 * (self.lap @ v + bv) + b * u - u * u * v
        return np.concatenate([fu, fv])

    def jacobian(self, x, p):
        n, b = self.n, p["beta"]
        h2 = 1.0 / n**2
        c1, c2 = p["D1"] / p["l"] ** 2 / h2, p["D2"] / p["l"] ** 2 / h2
        u, v = x[:n], x[n:]
        return sp.bmat([[c1 * self.lap + sp.diags(-(b + 1) + 2 * u * v), sp.diags(u * u)],
                        [sp.diags(b - 2 * u * v), c2 * self.lap + sp.diags(-u * u)]], format="csc")

    def dresidual_dp(self, x, p, name):
        return complex_step_dp(self, x, p, name)

    def trivial(self, p):
        return np.concatenate([np.full(self.n, p["alpha"]), np.full(self.n, p["beta"] / p["alpha"])])


class BTNormalForm:
    """Bogdanov-Takens normal form x' = y, y' = b1 + b2 x + x^2 - x y (Kuznetsov, eq. 8.49, s = -1).

    Equilibria y = 0, x^2 + b2 x + b1 = 0; J = [[0, 1], [b2 + 2x, -x]].  Folds: b1 = b2^2 / 4;
    Hopf points: x = 0, i.e. b1 = 0 with b2 < 0 and omega^2 = -b2; both curves end at the BT
    point (b1, b2) = (0, 0), where the Hopf curve continues as neutral saddles (b2 > 0).
    """

    parameter_names = ("b1", "b2")

    def residual(self, u, p):
        x, y = u
        return np.array([y, p["b1"] + p["b2"] * x + x * x - x * y])

    def jacobian(self, u, p):
        x, y = u
        return np.array([[0.0, 1.0], [p["b2"] + 2 * x - y, -x]])

    def dresidual_dp(self, u, p, name):
        return np.array([0.0, 1.0]) if name == "b1" else np.array([0.0, u[0]])


class HopfNormalForm:
    """x' = mu x - y + a x r^2, y' = x + mu y + a y r^2: l1 = 2 a with q^H q = 1
    (tests/test_hopf.py); with ``inner_product_weights`` = c (all components) when c is given."""

    parameter_names = ("mu", "a")

    def __init__(self, c: float | None = None):
        if c is not None:
            self.inner_product_weights = lambda u, p: np.full(2, c)

    def residual(self, u, p):
        x, y = u
        r2 = x * x + y * y
        return np.array([p["mu"] * x - y + p["a"] * x * r2, x + p["mu"] * y + p["a"] * y * r2])

    def jacobian(self, u, p):
        x, y = u
        a, mu = p["a"], p["mu"]
        return np.array([[mu + a * (3 * x * x + y * y), -1 + 2 * a * x * y],
                         [1 + 2 * a * x * y, mu + a * (x * x + 3 * y * y)]])

    def dresidual_dp(self, u, p, name):
        return np.array([u[0], u[1]]) if name == "mu" else np.array([u[0], u[1]]) * (u @ u)


class Hidden:
    """``problem`` with only the hooks named in ``keep`` forwarded besides residual, jacobian and
    dresidual_dp (e.g. keep=("mass_matrix",) hides ``inner_product_weights`` and
    ``order_parameter``)."""

    def __init__(self, problem, keep=()):
        self.problem = problem
        self.parameter_names = problem.parameter_names
        for name in keep:
            setattr(self, name, getattr(problem, name))

    def residual(self, u, p):
        return self.problem.residual(u, p)

    def jacobian(self, u, p):
        return self.problem.jacobian(u, p)

    def dresidual_dp(self, u, p, name):
        return self.problem.dresidual_dp(u, p, name)
