"""Linearised granular Couette flow: A X = omega B X about any steady base state.

Implements physics.md section 5 (Alam scaling).  Base state nu0(y), U(y), T0(y) on the nodes
of a :class:`problems.discretization.Grid`; perturbation X(y) exp(i k_x x + i k_z z + omega t)
with X = (nu_hat, u_hat, v_hat, w_hat, T_hat), D = d/dy, sigma = omega + i k_x U,
Delta = i k_x u + D v + i k_z w, k^2 = k_x^2 + k_z^2:

    sigma nu + D(nu0 v) + nu0 (i k_x u + i k_z w) = 0
    nu0 (sigma u + U' v)  = -(1/H^2) [i k_x P_xx + D P_xy + i k_z P_xz]
    nu0 sigma v           = -(1/H^2) [i k_x P_xy + D P_yy + i k_z P_yz] - H G nu
    nu0 sigma w           = -(1/H^2) [i k_x P_xz + D P_yz + i k_z P_zz]
    (3/2) nu0 (sigma T + T0' v) = (1/H^2) [D(kappa0 D T + kappa_hat T0') - k^2 kappa0 T]
                                  - p0 Delta + 2 mu0 U' (D u + i k_x v) + mu_hat U'^2 - D_hat
    P_xx = p_hat - lam0 Delta - 2 mu0 (i k_x u - Delta/3),  P_yy, P_zz alike,
    P_xy = -mu0 (D u + i k_x v) - mu_hat U',  P_xz = -mu0 (i k_z u + i k_x w),
    P_yz = -mu0 (D w + i k_z v),
    p = f1 T, mu = f2 sqrt(T), lam = f3 sqrt(T), kappa = f4 sqrt(T), D = f5 T^{3/2}
    (hats: linearisations in nu and T), G = Fr^{-2}.

With ``dufour=True`` the heat flux gains -kappa_h grad(nu), kappa_h = f_h T^{3/2}, in the bulk
and in the wall conditions.

Discretisation
    Collocation at the grid nodes.  Every term D(a D f) is expanded as a D2 f + a' D f (a' =
    D1 a of the base profile), never D1 diag(a) D1, because on finite-difference grids the
    product of two centred first-derivative stencils has a checkerboard null space.  The
    mass flux D(nu0 v) alone is kept in conservative form D1 diag(nu0), so that the
    Chebyshev quadrature sums the continuity rows exactly to nu0 v at the walls (= 0).

Boundary conditions (rows of u, v, w, T at y = -1/2 and y = +1/2; those rows of B are 0)
    ``walls='noslip'``: u = v = w = 0 and zero linearised heat flux; with kappa_h = 0 and a
    base state with T0' = 0 at the wall this is D T = 0 (physics.md section 5).
    ``walls='jj'``: v = 0 and the linearised Johnson-Jackson conditions of physics.md
    section 3(b), with n = +1 at the bottom and -1 at the top, u_w = -n/2 the wall speed:
        S_x = n H s_w (u - u_w),   S_z = n H s_w w,   Q = n [H s_w (u - u_w)^2 - d_w / H],
    S_x = -P_xy, S_z = -P_yz the tangential stresses, Q = -(1/H^2)(kappa dT/dy + kappa_h dnu/dy)
    the wall-normal heat flux, s_w = phi_w pi nu chi sqrt(T) / (2 sqrt(3) nu_m),
    d_w = sqrt(3) pi nu chi (1 - e_w^2) T^{3/2} / (4 nu_m).  The spanwise condition is the
    w-component of the vector slip law (traction parallel to the slip velocity).

The mass-conservation neutral mode (k_x = k_z = 0)
    With k_x = k_z = 0 and v = 0 at both walls, continuity conserves int nu dy, so the
    unconstrained problem has an exact eigenvalue omega = 0: the derivative of the base state
    with respect to the mean density nu_bar (a uniform-ish density shift with matching
    pressure and temperature changes).  Walls at fixed positions fix the mass, so this
    perturbation is not admissible.  Every eigenvector with omega != 0 already has
    int nu_hat dy = 0, so we restrict to that subspace: the continuity rows R are replaced by
    their projection (I - 1 w^T) R onto zero-mean tendencies (w = quadrature weights,
    sum w = 1), and then one continuity row (the node of largest weight; it is implied by the
    others once the mean is fixed) is replaced by the constraint w . nu_hat = 0 with a zero
    row in B.  For Chebyshev grids the projection acts only on the wall values of v, which
    the boundary rows set to zero, so the spectrum is exactly the unconstrained one minus the
    neutral mode; for finite differences the projection also removes the O(h^p) mass leak of
    the discrete flux.  Deflating instead (shifting the zero eigenvalue away) would leave the
    physically inadmissible mode in the eigenvector space.  With k_x or k_z nonzero the mean
    over x or z of exp(i k.x) vanishes, there is no constraint, and none is applied.

    The spurious pressure mode.  The y-momentum equation is replaced by v = 0 at the walls,
    so D p_hat = 0 is enforced only at interior nodes, whose null space is spanned by the
    constants and one grid mode q (T_N on Chebyshev grids, the checkerboard for fd2): with
    v_hat = 0 this gives an exact, purely numerical omega = 0 eigenvalue at k_x = k_z = 0.
    It is removed the same way: the continuity tendency is projected along q onto the null
    space of a functional c that vanishes on smooth profiles (the T_N coefficient for
    Chebyshev, i.e. continuity is truncated to degree N - 1; an O(h^(order+2)) central
    difference for FD), and c . nu_hat = 0 replaces a second continuity row.  For smooth
    eigenfunctions this changes eigenvalues at truncation level only (the uniform-shear
    modes are reproduced to rounding).  Finite-difference grids nevertheless carry a branch
    of weakly damped near-Nyquist density modes (see :func:`to_chebyshev`); use Chebyshev
    grids for spectra, especially at k_x != 0.

    The long-wave limit.  The mass mode is excluded only at k_x = k_z = 0 exactly; the
    eigenvalue is continuous in k (the unconstrained k = 0 spectrum is the constrained one plus
    omega = 0).  For small k_x it is the least-stable mode, a kinematic wave of the mean density
    in x: omega = i c k_x + w2 k_x^2 + O(k_x^3) with c = -dq/d nu_bar, q = int nu U dy the
    steady mass flux (A13 sign convention), and w2 set mainly by its coupling to the slowest
    k = 0 mode (second-order perturbation theory).  So max Re omega(k_x) is discontinuous at
    k_x = 0 whenever the constrained k = 0 spectrum is stable; for spanwise waves (k_z) there is
    no advection and the mode decays like -k_z^2.  Checked in tests/test_linear_gravity.py,
    together with an independent complex-step linearisation of the x-, z-dependent equations
    (gravity included) and the k = 0 links to CouetteProblem.jacobian (d base/d nu_bar is the
    unconstrained null vector; folds of the steady problem are zeros of the constrained one).

    Other neutral modes: with JJ walls and phi_w = 0 (frictionless walls) uniform u_hat or
    w_hat is neutral (momentum conservation); the base state is then unsheared and the case
    is rejected.  No other zero eigenvalues exist for no-slip or phi_w > 0 JJ walls
    (checked in tests/test_couette_linear.py).

References
----------
physics.md sections 3-5; M. Alam, P. R. Nott, J. Fluid Mech. 377 (1998) 99 (Chebyshev
collocation for this stability problem); P. C. Johnson, R. Jackson, J. Fluid Mech. 176
(1987) 67 (wall conditions).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any
from dataclasses import dataclass
from functools import lru_cache
from math import comb

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from numpy.typing import NDArray

from contin.stability import eigenpairs, eigenvalues
from problems.couette.closures import coefficients, packing_limit
from problems.discretization import Grid

FIELDS = ("nu", "u", "v", "w", "T")
NU, UX, VY, WZ, TT = range(5)
WALLS = ("noslip", "jj")

Array = NDArray[np.float64]


# --------------------------------------------------------------------------------------------
# Small symbolic helper: linear expressions  sum_terms a(y) D^m X_var  with product-rule D.

class _Expr:
    """A linear expression sum a(y) D^m X_var (m = 0, 1, 2) on the grid nodes."""

    def __init__(self, n: int, terms: dict[tuple[int, int], NDArray] | None = None):
        self.n = n
        self.terms: dict[tuple[int, int], NDArray] = dict(terms or {})

    @classmethod
    def var(cls, n: int, var: int, m: int = 0, coef=1.0) -> _Expr:
        coef = np.asarray(coef)  # real at k_x = k_z = 0 (then the whole operator is assembled in reals)
        return cls(n, {(var, m): np.broadcast_to(coef.astype(np.result_type(coef, float)), (n,)).copy()})

    def __add__(self, other: _Expr) -> _Expr:
        out = dict(self.terms)
        for key, a in other.terms.items():
            out[key] = out[key] + a if key in out else a
        return _Expr(self.n, out)

    def __sub__(self, other: _Expr) -> _Expr:
        return self + other * -1.0

    def __mul__(self, c) -> _Expr:
        c = np.asarray(c)
        return _Expr(self.n, {key: a * c for key, a in self.terms.items()})

    __rmul__ = __mul__

    def d(self, d1: NDArray) -> _Expr:
        """D(expr) by the product rule, D(a D^m f) = a' D^m f + a D^{m+1} f."""
        out = _Expr(self.n)
        for (var, m), a in self.terms.items():
            out = out + _Expr(self.n, {(var, m): d1 @ a, (var, m + 1): a})
        return out

    def add_to(self, out: NDArray, ops: Sequence[NDArray], scale: complex = 1.0) -> None:
        """out[:, var block] += scale * a D^m for every term; out is (n, 5n), ``ops[m]`` the
        dense matrix of D^m (``ops[0]`` unused: the identity is added on the diagonal)."""
        n = self.n
        diag = np.arange(n)
        for (var, m), a in self.terms.items():
            if m >= 3:
                raise AssertionError("third derivatives do not occur in this model")
            block = out[:, var * n:(var + 1) * n]
            if m == 0:
                block[diag, diag] += scale * a
            else:
                block += (scale * a)[:, None] * ops[m]

    def row(self, node: int, ops: Sequence[NDArray]) -> NDArray:
        """The (5n,) row of this expression at one node."""
        n = self.n
        out = np.zeros(5 * n, dtype=np.result_type(*self.terms.values()))
        for (var, m), a in self.terms.items():
            if m == 0:
                out[var * n + node] += a[node]
            else:
                out[var * n:(var + 1) * n] += a[node] * ops[m][node]
        return out


# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class BaseCoefficients:
    """Transport coefficients of the base state and their linearisations (physics.md s. 4-5)."""

    p0: Array
    p_nu: Array
    p_T: Array
    mu0: Array
    mu_nu: Array
    mu_T: Array
    lam0: Array
    kap0: Array
    kap_nu: Array
    kap_T: Array
    D_nu: Array
    D_T: Array
    kh0: Array
    kh_nu: Array
    kh_T: Array
    chi: Array
    chi_nu: Array


def base_coefficients(nu0, T0, e: float, chi: str = "jj", nu_max: float = 0.65, dufour: bool = False) -> BaseCoefficients:
    """p, mu, lambda, kappa, D, kappa_h and their derivatives in nu and T at (nu0, T0)."""
    c = coefficients(nu0, e, chi, nu_max, dufour=dufour)
    s = np.sqrt(T0)
    t32 = T0 * s
    if dufour:
        h = 1e-30  # complex step: d f_h / d nu exact to rounding (closures has no analytic form)
        fh_nu = coefficients(nu0 + 1j * h, e, chi, nu_max, dufour=True).fh.imag / h
    else:
        fh_nu = 0.0 * nu0
    return BaseCoefficients(
        p0=c.f1 * T0, p_nu=c.f1_nu * T0, p_T=c.f1,
        mu0=c.f2 * s, mu_nu=c.f2_nu * s, mu_T=c.f2 / (2 * s),
        lam0=c.f3 * s,
        kap0=c.f4 * s, kap_nu=c.f4_nu * s, kap_T=c.f4 / (2 * s),
        D_nu=c.f5_nu * t32, D_T=1.5 * c.f5 * s,
        kh0=c.fh * t32, kh_nu=fh_nu * t32, kh_T=1.5 * c.fh * s,
        chi=c.chi, chi_nu=c.chi_nu,
    )


def _param(params: Mapping[str, float], name: str, default: float | None = None) -> float:
    if name in params:
        return float(params[name])
    if default is None:
        raise ValueError(f"parameter {name!r} is required by the linear operator but missing from params")
    return default


def _check_base(grid: Grid, nu0, u0, T0, nu_max: float, chi: str) -> tuple[Array, Array, Array]:
    arrays = []
    for name, f in (("nu0", nu0), ("u0", u0), ("T0", T0)):
        f = np.asarray(f, dtype=float)
        if f.shape != (grid.size,):
            raise ValueError(f"base profile {name} has shape {f.shape}, expected ({grid.size},) on this grid")
        if not np.all(np.isfinite(f)):
            raise ValueError(f"base profile {name} contains NaN or inf")
        arrays.append(f)
    nu0, u0, T0 = arrays
    limit = packing_limit(chi, nu_max)
    if np.any(nu0 <= 0) or np.any(nu0 >= limit):
        raise ValueError(f"base density must lie in (0, {limit}), got range [{nu0.min():.6g}, {nu0.max():.6g}]")
    if np.any(T0 <= 0):
        raise ValueError(f"base temperature must be positive, got min {T0.min():.6g}")
    return nu0, u0, T0


def linear_operator(
    grid: Grid,
    nu0,
    u0,
    T0,
    params: Mapping[str, float],
    *,
    walls: str = "noslip",
    kx: float = 0.0,
    kz: float = 0.0,
    chi: str = "jj",
    dufour: bool = False,
    gravity: bool = True,
    conserve_mass: bool | None = None,
    dense: bool = False,
) -> tuple[Any, Any]:
    """The generalized eigenproblem A X = omega B X of physics.md section 5 (module docstring).

    Parameters
    ----------
    grid : Grid
        Discretisation of [-1/2, 1/2] (``problems.discretization.make_grid``).
    nu0, u0, T0 : (N+1,) arrays
        Base density, streamwise velocity and granular temperature at the grid nodes.
    params : mapping
        ``e``, ``H`` required; ``G`` (= Fr^-2, default 0), ``num`` (nu_max, default 0.65);
        for JJ walls ``phi_w`` and ``ew``.  ``nu`` (the mean density) is not used.
    walls : 'noslip' or 'jj'
    kx, kz : float
        Streamwise and spanwise wavenumbers (scaled with the gap H~).
    chi : radial distribution model of :mod:`problems.couette.closures`.
    dufour : include the kappa_h grad(nu) heat flux.
    gravity : include the -H G nu_hat body force (G from params).
    conserve_mass : restrict to int nu_hat = 0; default: exactly when kx = kz = 0.
    dense : return dense ndarrays instead of CSR matrices (what the eigensolvers use).

    Returns
    -------
    A, B : (5(N+1), 5(N+1)) CSR matrices (ndarrays with ``dense=True``), unknowns ordered
        (nu, u, v, w, T) node by node within each field block; complex when kx or kz is nonzero.

    Assembly is dense, with the grid's dense D1, D2 and the density-constraint projector
    cached per grid (:func:`_dense_ops`, :func:`_constraint_rows`): the matrices are small
    (325 x 325 at N = 64) and mostly dense in their D-blocks, so thousands of small sparse
    products cost far more than the arithmetic (the former sparse assembly is kept in
    ``tests/linear_sparse_reference.py``; the two agree to rounding).

    Raises
    ------
    ValueError
        Unknown wall type, missing parameters, profiles of the wrong size or outside the
        physical range.
    """
    A, bdiag = _assemble(grid, nu0, u0, T0, params, walls=walls, kx=kx, kz=kz, chi=chi, dufour=dufour,
                         gravity=gravity, conserve_mass=conserve_mass, replace_constraints=True)
    if dense:
        return A, np.diag(bdiag)
    return sp.csr_matrix(A), sp.diags(bdiag, format="csr")


@lru_cache(maxsize=64)
def _dense_ops(grid: Grid) -> tuple[NDArray, NDArray]:
    """Dense (D1, D2) of a grid, read-only (cached: the stability pass reuses them per state)."""
    d1 = grid.d1.toarray() if sp.issparse(grid.d1) else np.array(grid.d1, dtype=float)
    d2 = grid.d2.toarray() if sp.issparse(grid.d2) else np.array(grid.d2, dtype=float)
    d1.flags.writeable = False
    d2.flags.writeable = False
    return d1, d2


@lru_cache(maxsize=64)
def _constraint_rows(grid: Grid, conserve_mass: bool) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """(C, Gdir, K, J) of the density constraints (module docstring), cached per grid.

    C (n x m) the functionals, Gdir (n x m) the directions removed, K = (C^T Gdir)^-1 C^T so that
    the projected tendency is R - Gdir (K R), J the m continuity rows replaced by C^T nu = 0
    (pivoted QR of C^T: C[J] well conditioned).
    """
    C, Gdir = _density_constraints(grid, conserve_mass)
    K = np.linalg.solve(C.T @ Gdir, C.T)
    J = la.qr(C.T, pivoting=True, mode="r")[1][: C.shape[1]]
    for arr in (C, Gdir, K, J):
        arr.flags.writeable = False
    return C, Gdir, K, J


def _assemble(grid: Grid, nu0, u0, T0, params: Mapping[str, float], *, walls: str, kx: float, kz: float, chi: str,
              dufour: bool, gravity: bool, conserve_mass: bool | None,
              replace_constraints: bool) -> tuple[NDArray, NDArray]:
    """Dense A (real at k_x = k_z = 0) and the diagonal of B of :func:`linear_operator`.

    ``replace_constraints=False`` leaves the projected continuity rows in place (no rows J
    replaced by the constraints): the pencil then has the constrained spectrum plus m exact
    zero eigenvalues, whose subspace :func:`k0_spectrum` removes by restriction instead.
    """
    if walls not in WALLS:
        raise ValueError(f"unknown wall type {walls!r}; choose one of {', '.join(WALLS)}")
    e = _param(params, "e")
    H = _param(params, "H")
    nu_max = _param(params, "num", 0.65)
    G = _param(params, "G", 0.0) if gravity else 0.0
    if H <= 0:
        raise ValueError(f"H must be positive, got {H}")
    nu0, u0, T0 = _check_base(grid, nu0, u0, T0, nu_max, chi)
    n = grid.size
    d1, d2 = _dense_ops(grid)
    ops = (None, d1, d2)
    c = base_coefficients(nu0, T0, e, chi, nu_max, dufour)
    dU = d1 @ u0
    dT0 = d1 @ T0
    dnu0 = d1 @ nu0
    real = kx == 0.0 and kz == 0.0
    ikx, ikz = (0.0, 0.0) if real else (1j * kx, 1j * kz)
    k2 = kx * kx + kz * kz
    ih2 = 1.0 / (H * H)

    def V(var: int, m: int = 0, coef=1.0) -> _Expr:
        return _Expr.var(n, var, m, coef)

    delta = V(UX, 0, ikx) + V(VY, 1) + V(WZ, 0, ikz)
    p_hat = V(NU, 0, c.p_nu) + V(TT, 0, c.p_T)
    mu_hat = V(NU, 0, c.mu_nu) + V(TT, 0, c.mu_T)
    kap_hat = V(NU, 0, c.kap_nu) + V(TT, 0, c.kap_T)
    kh_hat = V(NU, 0, c.kh_nu) + V(TT, 0, c.kh_T)
    iso = p_hat - delta * (c.lam0 - 2.0 * c.mu0 / 3.0)
    Pxx = iso - V(UX, 0, 2.0 * c.mu0 * ikx)
    Pyy = iso - V(VY, 1, 2.0 * c.mu0)
    Pzz = iso - V(WZ, 0, 2.0 * c.mu0 * ikz)
    Pxy = (V(UX, 1) + V(VY, 0, ikx)) * (-c.mu0) - mu_hat * dU
    Pxz = (V(UX, 0, ikz) + V(WZ, 0, ikx)) * (-c.mu0)
    Pyz = (V(WZ, 1) + V(VY, 0, ikz)) * (-c.mu0)
    # kappa dT/dy + kappa_h dnu/dy, linearised (= -H^2 Q_hat)
    flux = V(TT, 1, c.kap0) + kap_hat * dT0 + V(NU, 1, c.kh0) + kh_hat * dnu0

    adv = ikx * u0  # i k_x U
    mom_x = V(UX, 0, -adv * nu0) - V(VY, 0, nu0 * dU) - (Pxx * ikx + Pxy.d(d1) + Pxz * ikz) * ih2
    mom_y = V(VY, 0, -adv * nu0) - (Pxy * ikx + Pyy.d(d1) + Pyz * ikz) * ih2 - V(NU, 0, H * G)
    mom_z = V(WZ, 0, -adv * nu0) - (Pxz * ikx + Pyz.d(d1) + Pzz * ikz) * ih2
    energy = (V(TT, 0, -1.5 * nu0 * adv) - V(VY, 0, 1.5 * nu0 * dT0)
              + (flux.d(d1) - V(TT, 0, k2 * c.kap0) - V(NU, 0, k2 * c.kh0)) * ih2
              - delta * c.p0 + (V(UX, 1) + V(VY, 0, ikx)) * (2.0 * c.mu0 * dU) + mu_hat * dU**2
              - V(NU, 0, c.D_nu) - V(TT, 0, c.D_T))

    A = np.zeros((5 * n, 5 * n), dtype=float if real else complex)
    # Continuity, with the mass flux D(nu0 v) in conservative form.
    diag = np.arange(n)
    A[diag, NU * n + diag] = -adv
    A[diag, UX * n + diag] = -ikx * nu0
    A[:n, VY * n:(VY + 1) * n] = -(d1 * nu0[None, :])
    A[diag, WZ * n + diag] = -ikz * nu0
    for var, expr in ((UX, mom_x), (VY, mom_y), (WZ, mom_z), (TT, energy)):
        expr.add_to(A[var * n:(var + 1) * n], ops)

    # Boundary rows.
    rows_idx: list[int] = []
    for node, nsign in ((0, 1.0), (n - 1, -1.0)):
        uw = -0.5 * nsign  # wall speed: -1/2 at the bottom, +1/2 at the top
        if walls == "noslip":
            conds = [(UX, V(UX)), (VY, V(VY)), (WZ, V(WZ)), (TT, flux)]
        else:
            phi_w = _param(params, "phi_w")
            ew = _param(params, "ew")
            if phi_w <= 0:
                raise ValueError(f"JJ walls need specularity phi_w > 0 (got {phi_w}); frictionless walls cannot shear")
            cs = phi_w * np.pi / (2.0 * np.sqrt(3.0) * nu_max)
            cd = np.sqrt(3.0) * np.pi * (1.0 - ew * ew) / (4.0 * nu_max)
            nchi = nu0 * c.chi
            nchi_nu = c.chi + nu0 * c.chi_nu
            sw = cs * nchi * np.sqrt(T0)
            sw_hat = V(NU, 0, cs * nchi_nu * np.sqrt(T0)) + V(TT, 0, cs * nchi / (2 * np.sqrt(T0)))
            dw_hat = V(NU, 0, cd * nchi_nu * T0**1.5) + V(TT, 0, cd * nchi * 1.5 * np.sqrt(T0))
            slip = u0 - uw
            shear_x = Pxy * -1.0 - (sw_hat * slip + V(UX, 0, sw)) * (nsign * H)
            shear_z = Pyz * -1.0 - V(WZ, 0, nsign * H * sw)
            heat = flux * -ih2 - (sw_hat * (H * slip**2) + V(UX, 0, 2 * H * sw * slip) - dw_hat * (1.0 / H)) * nsign
            conds = [(UX, shear_x), (VY, V(VY)), (WZ, shear_z), (TT, heat)]
        for var, expr in conds:
            rows_idx.append(var * n + node)
            A[var * n + node] = expr.row(node, ops)

    bdiag = np.concatenate([np.ones(n), nu0, nu0, nu0, 1.5 * nu0])
    bdiag[rows_idx] = 0.0

    if conserve_mass is None:
        conserve_mass = kx == 0.0 and kz == 0.0
    C, Gdir, K, J = _constraint_rows(grid, bool(conserve_mass))
    # Continuity rows: project the tendency onto the constrained subspace along Gdir, then
    # replace m rows J by C^T nu = 0.
    R = A[:n]
    R -= Gdir @ (K @ R)
    if replace_constraints:
        R[J, :] = 0.0
        R[J, :n] = C.T
        bdiag[J] = 0.0
    return A, bdiag


# --------------------------------------------------------------------------------------------
# k_x = k_z = 0 spectrum: Schur elimination of the boundary rows, restriction to the constraint
# subspace, and the reflection split on symmetric base states.

#: reflection parity of the perturbation fields under S: (nu, T)(y) -> (nu, T)(-y),
#: (u, v, w)(y) -> -(u, v, w)(-y)  (physics.md section 3, Symmetry)
PARITY = {NU: 1.0, UX: -1.0, VY: -1.0, WZ: -1.0, TT: 1.0}
#: relative tolerance of the commutation test ||S M S - M|| <= SYMMETRY_TOL ||M|| of the split
SYMMETRY_TOL = 1e-11


def _orbits(fields: Sequence[int], nodes: Sequence[NDArray], n: int, parity: int) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Basis of the S-even (parity +1) or S-odd (-1) subspace of the unknowns ``fields`` x ``nodes``.

    Returns (a, b, s, w): basis vector k is w_k (e_{a_k} + s_k e_{b_k}) in positions of the
    concatenated unknown list (a_k = b_k, w_k = 1/2 for a node fixed by the reflection).
    """
    pos: dict[tuple[int, int], int] = {}
    for f, nd in zip(fields, nodes):
        for j in nd:
            pos[(f, int(j))] = len(pos)
    a, b, sg, w = [], [], [], []
    for (f, j), i in pos.items():
        jm = n - 1 - j
        k = pos[(f, jm)]
        if k < i:
            continue
        sign = parity * PARITY[f]
        if k == i:
            if sign < 0:  # e_i is in the other subspace
                continue
            a.append(i), b.append(i), sg.append(1.0), w.append(0.5)
        else:
            a.append(i), b.append(k), sg.append(sign), w.append(np.sqrt(0.5))
    return np.array(a, dtype=int), np.array(b, dtype=int), np.array(sg), np.array(w)


def _fold(M: NDArray, basis_r: tuple, basis_c: tuple) -> NDArray:
    """basis_r^T M basis_c for bases given as (a, b, s, w) (see :func:`_orbits`)."""
    a, b, s, w = basis_c
    cols = (M[:, a] + M[:, b] * s) * w
    a, b, s, w = basis_r
    return (cols[a] + cols[b] * s[:, None]) * w[:, None]


def _restrict(M: NDArray, m: int, W: NDArray) -> NDArray:
    """Q^T M Q with Q = W on the leading ``m`` coordinates and the identity on the others (W
    orthonormal columns): M restricted to an M-invariant subspace that constrains only those
    coordinates."""
    k = W.shape[1]
    out = np.empty((M.shape[0] - m + k, M.shape[1] - m + k), dtype=M.dtype)
    top = W.T @ M[:m]
    out[:k, :k] = top[:, :m] @ W
    out[:k, k:] = top[:, m:]
    out[k:, :k] = M[m:, :m] @ W
    out[k:, k:] = M[m:, m:]
    return out


def _constraint_basis(Ct: NDArray, scale: float) -> NDArray | None:
    """Orthonormal basis of the null space of the functionals Ct (m x k); None if Ct ~ 0."""
    if np.max(np.abs(Ct), initial=0.0) <= 1e-13 * scale:
        return None
    return la.null_space(Ct, rcond=1e-12)


@lru_cache(maxsize=16)
def _k0_layout(n: int) -> tuple[NDArray, ...]:
    """Index sets of :func:`k0_spectrum` for n nodes: the boundary rows (u, v, T at both walls),
    the kept unknowns (nu everywhere, u, v, T inside), the S-even and S-odd bases on them
    (:func:`_orbits`) and the reflection as a signed permutation (refl, sign)."""
    fields = (NU, UX, VY, TT)
    inner = np.arange(1, n - 1)
    nodes = [np.arange(n), inner, inner, inner]  # the wall rows of u, v, T are boundary conditions
    walls_idx = np.array([f * n + j for f in (UX, VY, TT) for j in (0, n - 1)])
    keep = np.concatenate([f * n + nd for f, nd in zip(fields, nodes)])
    even = _orbits(fields, nodes, n, +1)
    odd = _orbits(fields, nodes, n, -1)
    refl = np.empty(keep.size, dtype=int)
    for a, b, _, _ in (even, odd):
        refl[a], refl[b] = b, a
    sign = np.concatenate([np.full(nd.size, PARITY[f]) for f, nd in zip(fields, nodes)])
    return walls_idx, keep, even, odd, refl, sign


@lru_cache(maxsize=16)
def _k0_constraint_bases(grid: Grid) -> tuple[NDArray, NDArray | None, NDArray | None]:
    """Orthonormal bases of {C^T nu = 0} (the density constraints, :func:`_constraint_rows`) in
    the nodal nu coordinates and in the nu coordinates of the S-even and S-odd bases of
    :func:`_k0_layout` (those come first there); None for a half the constraints do not touch."""
    C = _constraint_rows(grid, True)[0]
    scale = float(np.max(np.abs(C)))
    out: list[NDArray | None] = [la.null_space(C.T, rcond=1e-12)]
    m_total = 0
    for a, b, s, w in _k0_layout(grid.size)[2:4]:
        nu_pos = np.flatnonzero(a < grid.size)  # basis vectors on nu nodes
        if not np.array_equal(nu_pos, np.arange(nu_pos.size)):
            raise AssertionError("the nu basis vectors must come first")
        Cb = (C[a[nu_pos]] + C[b[nu_pos]] * s[nu_pos, None]) * w[nu_pos, None]
        W = _constraint_basis(Cb.T, scale)
        if W is not None:
            m_total += nu_pos.size - W.shape[1]
        out.append(W)
    if m_total != C.shape[1]:
        raise AssertionError(f"constraints split into {m_total} != {C.shape[1]} conditions")
    return out[0], out[1], out[2]


def k0_spectrum(grid: Grid, nu0, u0, T0, params: Mapping[str, float], *, walls: str = "noslip", chi: str = "jj",
                dufour: bool = False, gravity: bool = True, split: bool | None = None) -> NDArray[np.complex128] | None:
    """All finite eigenvalues at k_x = k_z = 0 without the decoupled w block, real part descending.

    The same spectrum as dense QZ on :func:`linear_operator`'s pencil with the w rows and columns
    dropped, computed on smaller standard eigenproblems:

    1. the pencil is assembled with the projected continuity rows left in place (no rows
       replaced by the constraints C^T nu = 0: it then has m extra exact zero eigenvalues, and
       the subspace {C^T nu = 0} is invariant because every projected row satisfies C^T R = 0);
    2. the boundary rows Z (zero rows of B) are eliminated with the unknowns of the same index:
       M = B_KK^-1 (A_KK - A_KZ A_ZZ^-1 A_ZK), whose eigenvalues are the finite ones;
    3. M is restricted to {C^T nu = 0} with an orthonormal basis of that subspace, which removes
       exactly the m zero eigenvalues;
    4. ``split`` (default: when it holds) on a reflection-symmetric base state (S: y -> -y,
       physics.md section 3), M commutes with the signed reflection of the unknowns and is
       block diagonal in the S-even / S-odd basis: two problems of half the size, about 4x
       cheaper than one.  The commutation is checked on M itself (relative SYMMETRY_TOL), so
       gravity or an asymmetric state simply takes the unsplit path.

    Returns None when A_ZZ is numerically singular (condition > 1e12); use dense QZ then.
    """
    nu0, u0, T0 = (np.asarray(f, dtype=float) for f in (nu0, u0, T0))
    A, bdiag = _assemble(grid, nu0, u0, T0, params, walls=walls, kx=0.0, kz=0.0, chi=chi, dufour=dufour,
                         gravity=gravity, conserve_mass=True, replace_constraints=False)
    n = grid.size
    walls_idx, keep, even, odd, refl, sign = _k0_layout(n)
    if np.any(bdiag[walls_idx] != 0.0) or np.any(bdiag[keep] == 0.0):
        raise AssertionError("unexpected zero pattern of B")
    azz = A[np.ix_(walls_idx, walls_idx)]
    if np.linalg.cond(azz) > 1e12:
        return None
    M = A[np.ix_(keep, keep)] - A[np.ix_(keep, walls_idx)] @ np.linalg.solve(azz, A[np.ix_(walls_idx, keep)])
    M /= bdiag[keep][:, None]
    blocks: list[NDArray] = []
    if split is not False:
        # cheap pre-test on the profiles, then the commutation S M S = M itself
        symmetric = max(np.max(np.abs(nu0 - nu0[::-1])), np.max(np.abs(T0 - T0[::-1])),
                        np.max(np.abs(u0 + u0[::-1]))) < 1e-6
        if symmetric:
            mirrored = M[np.ix_(refl, refl)] * sign[:, None] * sign[None, :]
            symmetric = np.max(np.abs(mirrored - M)) <= SYMMETRY_TOL * np.max(np.abs(M))
        if split and not symmetric:
            raise ValueError("split=True but the base state is not reflection-symmetric")
        if symmetric:
            for basis, W in zip((even, odd), _k0_constraint_bases(grid)[1:]):
                Mb = _fold(M, basis, basis)
                blocks.append(Mb if W is None else _restrict(Mb, W.shape[0], W))
    if not blocks:
        blocks.append(_restrict(M, n, _k0_constraint_bases(grid)[0]))
    w = np.concatenate([la.eigvals(b, check_finite=False) for b in blocks]).astype(complex)
    return w[np.lexsort((-w.imag, -w.real))]


@lru_cache(maxsize=64)
def _spurious_direction(grid: Grid) -> tuple[NDArray, NDArray]:
    """(q, c): the spurious pressure direction q and a functional c detecting it.

    q spans, with the constants, the null space of the interior rows of D1 (the y-momentum
    equation is not collocated at the walls, so D1 p = 0 there only).  Chebyshev: q = T_N at
    the nodes and c its discrete Chebyshev coefficient (c . f = 0 for every polynomial of
    degree < N).  Finite differences: q from an SVD (the checkerboard for fd2) and c the
    m-th central difference at the middle node(s), m = order + 2, which is O(h^m) on smooth
    vectors.  Both are reflection-equivariant with the parity of q.
    """
    n = grid.size
    N = grid.intervals
    if grid.method == "cheb":
        q = (-1.0) ** np.arange(n)
        c = q / N
        c[[0, -1]] *= 0.5
        return q, c
    d1i = sp.csr_matrix(grid.d1)[1:-1, :].toarray()
    null = la.null_space(d1i)
    if null.shape[1] != 2:
        raise AssertionError(f"interior D1 of {grid.method} has a {null.shape[1]}-dimensional null space, expected 2")
    q = null @ la.null_space((np.ones(n) @ null)[None, :])[:, 0]  # the member orthogonal to constants
    q /= np.max(np.abs(q))
    mdiff = int(grid.order) + 2
    stencil = np.array([(-1.0) ** k * comb(mdiff, k) for k in range(mdiff + 1)])
    c = np.zeros(n)
    parity = 1.0 if np.allclose(q[::-1], q) else -1.0
    for centre, sgn in ((N // 2, 1.0), (N - N // 2, parity)):
        c[centre - mdiff // 2: centre + mdiff // 2 + 1] += sgn * stencil
    return q, c


def _density_constraints(grid: Grid, conserve_mass: bool) -> tuple[NDArray, NDArray]:
    """Constraint functionals C (n x m) on nu_hat and the directions G removed with them."""
    q, c = _spurious_direction(grid)
    cols_c, cols_g = [c], [q]
    if conserve_mass:
        cols_c.append(np.asarray(grid.weights, dtype=float))
        cols_g.append(np.ones(grid.size))
    return np.column_stack(cols_c), np.column_stack(cols_g)


def to_chebyshev(grid: Grid, nu0, u0, T0, intervals: int | None = None) -> tuple[Grid, Array, Array, Array]:
    """Resample base profiles onto a Chebyshev grid (``grid.interpolate``) for the eigenproblem.

    Collocated finite-difference grids give the density/pressure coupling a spurious
    branch: centred first-derivative stencils nearly annihilate near-Nyquist density
    perturbations, whose decay rates then tend to 0 like (pi/2N)^2 instead of staying at the
    O(1) compressive damping; at k_x != 0 these weakly damped spurious modes (omega ~
    -i k_x U(y_j)) dominate max Re omega and do not converge with N.  Chebyshev collocation
    has no such branch (its exact spurious pressure mode T_N is removed, module docstring),
    so stability of FD base states should be computed after this resampling.
    ``intervals`` defaults to the grid's own N for Chebyshev grids (returned unchanged) and to
    min(N, 80) for finite differences.
    """
    from problems.discretization import make_grid

    if grid.method == "cheb" and (intervals is None or intervals == grid.intervals):
        return grid, np.asarray(nu0, float), np.asarray(u0, float), np.asarray(T0, float)
    target = make_grid("cheb", int(intervals if intervals is not None else min(grid.intervals, 80)))
    return (target, *(grid.interpolate(np.asarray(f, dtype=float), target.y) for f in (nu0, u0, T0)))


# --------------------------------------------------------------------------------------------
# Uniform shear, k_x = k_z = 0: the exact 4 x 4 amplitude system (physics.md section 4).

def uniform_shear_matrix(nu: float, e: float, H: float, n: int, *, chi: str = "jj", nu_max: float = 0.65,
                         advection: bool = True) -> tuple[NDArray, NDArray]:
    """(A4, B4) for mode n of uniform shear with no-slip, adiabatic walls, k_x = k_z = 0.

    With k = n pi, [nu, T] = [N, Theta] cos k(y + 1/2), [u, v] = [U, V] sin k(y + 1/2):

        omega N           = -nu k V
        nu omega U        = -nu V - (1/H^2) [mu0 k^2 U + k (mu_nu N + mu_T Theta)]
        nu omega V        =  (1/H^2) [k (p_nu N + p_T Theta) - (lam0 + 4 mu0 / 3) k^2 V]
        (3/2) nu omega Th = -(k^2/H^2) kap0 Th - p0 k V + 2 mu0 k U + (mu_nu - D_nu) N
                            + (mu_T - D_T) Th

    The term -nu V (advection of the base shear U' = 1 by v_hat, nu0 U' v_hat in the
    x-momentum equation of section 5) is missing from physics.md section 4 as printed;
    ``advection=False`` reproduces that printed system (and its quoted growth rates), which
    has the same neutral curve H_n^c (V = 0 when omega = 0) but different growth rates.
    """
    co = coefficients(nu, e, chi, nu_max)
    T0 = co.f2 / co.f5
    b = base_coefficients(np.array([nu]), np.array([T0]), e, chi, nu_max)
    g = {name: float(getattr(b, name)[0]) for name in ("p0", "p_nu", "p_T", "mu0", "mu_nu", "mu_T", "lam0",
                                                     "kap0", "D_nu", "D_T")}
    k = n * np.pi
    ih2 = 1.0 / (H * H)
    A4 = np.array([
        [0.0, 0.0, -nu * k, 0.0],
        [-k * g["mu_nu"] * ih2, -g["mu0"] * k * k * ih2, -nu if advection else 0.0, -k * g["mu_T"] * ih2],
        [k * g["p_nu"] * ih2, 0.0, -(g["lam0"] + 4.0 * g["mu0"] / 3.0) * k * k * ih2, k * g["p_T"] * ih2],
        [g["mu_nu"] - g["D_nu"], 2.0 * g["mu0"] * k, -g["p0"] * k,
         -k * k * g["kap0"] * ih2 + g["mu_T"] - g["D_T"]],
    ])
    B4 = np.diag([1.0, nu, nu, 1.5 * nu])
    return A4, B4


def uniform_shear_modes(nu: float, e: float, H: float, n: int, *, chi: str = "jj", nu_max: float = 0.65,
                        advection: bool = True) -> NDArray[np.complex128]:
    """Eigenvalues of :func:`uniform_shear_matrix`, real part descending."""
    A4, B4 = uniform_shear_matrix(nu, e, H, n, chi=chi, nu_max=nu_max, advection=advection)
    w = la.eigvals(A4, B4)
    return w[np.lexsort((-w.imag, -w.real))]


# --------------------------------------------------------------------------------------------
# Dispersion curves and eigenfunctions.

@dataclass(frozen=True)
class Mode:
    """An eigenvalue and its eigenfunction profiles on the grid nodes.

    The eigenvector is scaled so that its largest component (over all fields and nodes) is
    1 (real, positive).
    """

    omega: complex
    kx: float
    kz: float
    y: Array
    nu: NDArray[np.complex128]
    u: NDArray[np.complex128]
    v: NDArray[np.complex128]
    w: NDArray[np.complex128]
    T: NDArray[np.complex128]

    @property
    def phase_speed(self) -> float:
        """c = omega_i / sqrt(kx^2 + kz^2) (physics.md section 5), nan at k = 0."""
        k = np.hypot(self.kx, self.kz)
        return float(self.omega.imag / k) if k > 0 else float("nan")

    def profiles(self) -> dict[str, NDArray[np.complex128]]:
        return {name: getattr(self, name) for name in FIELDS}


def least_stable_mode(grid: Grid, nu0, u0, T0, params: Mapping[str, float], *, kx: float = 0.0, kz: float = 0.0,
                      walls: str = "noslip", chi: str = "jj", dufour: bool = False, gravity: bool = True) -> Mode:
    """The eigenvalue of largest real part and its eigenfunction (dense QZ)."""
    A, B = linear_operator(grid, nu0, u0, T0, params, walls=walls, kx=kx, kz=kz, chi=chi, dufour=dufour,
                           gravity=gravity)
    w, v = eigenpairs(A, B, k=1, dense_max=A.shape[0])
    x = v[:, 0]
    x = x / x[np.argmax(np.abs(x))]
    f = x.reshape(5, grid.size)
    return Mode(complex(w[0]), float(kx), float(kz), grid.y.copy(), *f)


def growth_rate_curve(grid: Grid, nu0, u0, T0, params: Mapping[str, float], kx_values, *, kz: float = 0.0,
                      walls: str = "noslip", chi: str = "jj", dufour: bool = False,
                      gravity: bool = True) -> tuple[Array, Array, Array]:
    """max Re omega and the phase speed of the least-stable mode against k_x.

    Returns
    -------
    kx : (K,) the wavenumbers
    growth : (K,) max Re omega (dense QZ, all finite eigenvalues)
    phase_speed : (K,) omega_i / sqrt(kx^2 + kz^2) of that mode (nan where k = 0)
    """
    kx_values = np.atleast_1d(np.asarray(kx_values, dtype=float))
    growth = np.empty(kx_values.size)
    speed = np.empty(kx_values.size)
    for i, kx in enumerate(kx_values):
        A, B = linear_operator(grid, nu0, u0, T0, params, walls=walls, kx=kx, kz=kz, chi=chi, dufour=dufour,
                               gravity=gravity)
        w = eigenvalues(A, B, k=1, dense_max=A.shape[0])
        growth[i] = w[0].real
        k = np.hypot(kx, kz)
        speed[i] = w[0].imag / k if k > 0 else np.nan
    return kx_values, growth, speed
