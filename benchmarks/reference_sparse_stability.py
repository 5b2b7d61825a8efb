"""The k_x = 0 stability path of the pitchfork scene as it was before the dense assembly: the sparse
assembly of ``problems.couette.linear.linear_operator`` (kept verbatim) and the Schur elimination of
``problems.couette.pitchfork.finite_eigenvalues`` on it.

The reference path of tests/test_couette_linear_dense.py and of ``python -m benchmarks.stability``
(old against new time per state)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from numpy.typing import NDArray

from problems.couette.linear import NU, TT, UX, VY, WALLS, WZ, _check_base, _density_constraints, _param, base_coefficients
from problems.discretization import Grid


# --------------------------------------------------------------------------------------------
# Small symbolic helper: linear expressions  sum_terms a(y) D^m X_var  with product-rule D.

class _Expr:
    """A linear expression sum a(y) D^m X_var (m = 0, 1, 2) on the grid nodes."""

    def __init__(self, n: int, terms: dict[tuple[int, int], NDArray] | None = None):
        self.n = n
        self.terms: dict[tuple[int, int], NDArray] = dict(terms or {})

    @classmethod
    def var(cls, n: int, var: int, m: int = 0, coef=1.0) -> _Expr:
        return cls(n, {(var, m): np.broadcast_to(np.asarray(coef, dtype=complex), (n,)).copy()})

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

    def d(self, d1: sp.csr_matrix) -> _Expr:
        """D(expr) by the product rule, D(a D^m f) = a' D^m f + a D^{m+1} f."""
        out = _Expr(self.n)
        for (var, m), a in self.terms.items():
            out = out + _Expr(self.n, {(var, m): d1 @ a, (var, m + 1): a})
        return out

    def blocks(self, ops: Sequence[sp.spmatrix]) -> list[sp.spmatrix | None]:
        """The 5 (n x n) blocks of this row; ``ops[m]`` is the matrix of D^m."""
        out: list[sp.spmatrix | None] = [None] * 5
        for (var, m), a in self.terms.items():
            if m >= len(ops):
                raise AssertionError("third derivatives do not occur in this model")
            term = sp.diags(a) @ ops[m]
            out[var] = term if out[var] is None else out[var] + term
        return out


def sparse_linear_operator(
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
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
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

    Returns
    -------
    A, B : (5(N+1), 5(N+1)) CSR matrices, unknowns ordered (nu, u, v, w, T) node by node
        within each field block; complex when kx or kz is nonzero.

    Raises
    ------
    ValueError
        Unknown wall type, missing parameters, profiles of the wrong size or outside the
        physical range.
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
    d1 = sp.csr_matrix(grid.d1)
    ident = sp.identity(n, format="csr")
    ops = [ident, d1, sp.csr_matrix(grid.d2)]
    c = base_coefficients(nu0, T0, e, chi, nu_max, dufour)
    dU = d1 @ u0
    dT0 = d1 @ T0
    dnu0 = d1 @ nu0
    ikx, ikz = 1j * kx, 1j * kz
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

    # Continuity, with the mass flux D(nu0 v) in conservative form.
    cont = [sp.diags(-adv), sp.diags(-ikx * nu0), -(d1 @ sp.diags(nu0)), sp.diags(-ikz * nu0), None]
    rows = [cont] + [expr.blocks(ops) for expr in (mom_x, mom_y, mom_z, energy)]
    dtype = complex if (kx != 0.0 or kz != 0.0) else float
    zero = sp.csr_matrix((n, n))
    A = sp.bmat([[blk if blk is not None else zero for blk in row] for row in rows], format="csr").astype(complex)

    # Boundary rows.
    bc_rows: dict[int, list[tuple[int, _Expr]]] = {}
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
            bc_rows.setdefault(var, []).append((node, expr))
    # Replace the boundary rows: A <- (I - S S^T) A + S R_bc, S selecting the rows.
    rows_idx, rows_mat = [], []
    for var, items in bc_rows.items():
        for node, expr in items:
            rows_idx.append(var * n + node)
            rows_mat.append(sp.hstack([sp.csr_matrix(blk)[node, :] if blk is not None else sp.csr_matrix((1, n))
                                       for blk in expr.blocks(ops)]))
    keep = np.ones(5 * n)
    keep[rows_idx] = 0.0
    select = sp.csr_matrix((np.ones(len(rows_idx)), (rows_idx, np.arange(len(rows_idx)))),
                           shape=(5 * n, len(rows_idx)))
    A = sp.diags(keep) @ A + select @ sp.vstack(rows_mat)

    bdiag = np.concatenate([np.ones(n), nu0, nu0, nu0, 1.5 * nu0])
    bdiag[rows_idx] = 0.0

    if conserve_mass is None:
        conserve_mass = kx == 0.0 and kz == 0.0
    C, Gdir = _density_constraints(grid, conserve_mass)
    # Continuity rows: project the tendency onto the constrained subspace along Gdir, then
    # replace m rows (chosen by pivoted QR so that C[J] is well conditioned) by C^T nu = 0.
    R = A[:n, :].toarray()
    R -= Gdir @ np.linalg.solve(C.T @ Gdir, C.T @ R)
    m = C.shape[1]
    J = la.qr(C.T, pivoting=True, mode="r")[1][:m]
    R[J, :] = 0.0
    R[J, :n] = C.T
    bdiag[J] = 0.0
    A = sp.vstack([sp.csr_matrix(R), A[n:, :]], format="csr")
    if dtype is float:
        if A.nnz and np.max(np.abs(A.data.imag)) > 0:
            raise AssertionError("imaginary entries at kx = kz = 0")
        A = sp.csr_matrix(A.real)
    B = sp.diags(bdiag, format="csr")
    return A, B


def reference_k0_eigenvalues(grid: Grid, nu0, u0, T0, params: Mapping[str, float], *, walls: str = "noslip",
                             chi: str = "jj", dufour: bool = False) -> NDArray[np.complex128]:
    """All finite k_x = 0 eigenvalues, w block dropped, by the former path (pitchfork.StabilityOperator
    + finite_eigenvalues): sparse assembly, the constraint rows J replaced, then the zero-B rows
    eliminated by a Schur complement (dense QZ if that block is singular)."""
    from contin.stability import eigenvalues

    A, B = sparse_linear_operator(grid, nu0, u0, T0, params, walls=walls, chi=chi, dufour=dufour, gravity=False)
    n = grid.size
    keep = np.r_[0:3 * n, 4 * n:5 * n]
    A = sp.csr_matrix(A)[keep][:, keep]
    B = sp.csr_matrix(B)[keep][:, keep]
    a = A.toarray()
    d = B.diagonal()
    z = np.flatnonzero(d == 0)
    k = np.flatnonzero(d != 0)
    azz = a[np.ix_(z, z)]
    if np.linalg.cond(azz) < 1e12:
        schur = a[np.ix_(k, k)] - a[np.ix_(k, z)] @ np.linalg.solve(azz, a[np.ix_(z, k)])
        w = la.eigvals(schur / d[k][:, None])
        return w[np.lexsort((-w.imag, -w.real))]
    return eigenvalues(A, B)
