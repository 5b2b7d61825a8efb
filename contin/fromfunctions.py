"""A continuation problem from plain functions: :func:`from_functions` (also ``contin.from_functions``).

For a user who has F(u, p) and nothing else.  The Jacobian is built by finite differences
with column grouping (Curtis, Powell & Reid, J. Inst. Math. Appl. 13, 1974): columns that share
no row are perturbed together, so a banded J costs (bandwidth) residual calls instead of n.
The groups are a greedy colouring of the column-intersection graph of the sparsity pattern
(scipy.optimize._numdiff.group_columns, in the natural and the reverse Cuthill-McKee order,
whichever needs fewer groups: 3 for a tridiagonal pattern).  The pattern is given
(``sparsity=``) or detected once from dense differences at u0 and at a perturbed u0 (the union
of their nonzeros, so an entry that vanishes by accident at u0 is kept).  ``method='cs'``
uses the complex step Im F(u + i h e_j) / h (Squire & Trapp, SIAM Rev. 40, 1998; exact to
rounding, F must accept complex input); the default central differences are accurate to
~1e-10 relative.  dF/dp likewise (one parameter at a time).  An exact ``jacobian`` (and
``dF_dp``) may be given instead; with ``debug=True`` it is compared once with differences
(:func:`contin.problem.check_jacobian`) and a mismatch is an error naming the worst entry.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.problem import Array, Params, check_jacobian

Residual = Callable[[Array, Params], Array]

#: relative step of the central differences (error ~ eps^(2/3) ~ 1e-11 relative for smooth F)
FD_STEP = 6e-6
#: relative step of the complex step (any small value works: no cancellation)
CS_STEP = 1e-20
#: largest relative error of an exact Jacobian against differences in debug mode
DEBUG_TOL = 1e-6


def column_groups(pattern: Any) -> np.ndarray:
    """Group index of each column: columns of one group share no nonzero row.

    Greedy colouring of the column-intersection graph in the natural and in the reverse
    Cuthill-McKee order; the one with fewer groups.  A tridiagonal pattern gives 3 groups.
    """
    from scipy.optimize._numdiff import group_columns
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    a = sp.csc_matrix(pattern, dtype=float)
    a.data[:] = 1.0
    n = a.shape[1]
    best = group_columns(a, order=np.arange(n))
    inter = sp.csr_matrix(a.T @ a)
    rcm = reverse_cuthill_mckee(inter, symmetric_mode=True)
    other = group_columns(a, order=np.asarray(rcm))
    return other if other.max() < best.max() else best


def detect_sparsity(F: Residual, u0: Array, params: Params, *, step: float = FD_STEP) -> sp.csc_matrix:
    """Pattern of dF/du: nonzeros of dense differences at (u0, params) and at a perturbed u0 with
    perturbed parameters (their union).  The parameters are perturbed too because a start value
    often switches couplings off: AUTO's ``abc`` starts at D = 0, where J is diagonal, and a
    pattern detected there dropped every D-dependent entry (Newton converged linearly with that
    Jacobian, ds shrank to 1e-4 and the run found none of its folds and Hopf points).  Where F
    cannot be evaluated at the perturbed parameters, the second pattern is taken at params."""
    u0 = np.asarray(u0, float)
    n = u0.size
    shift = 1e-3 * (1.0 + np.abs(u0)) * np.cos(np.arange(n) + 0.3)
    moved = {k: v + 1e-3 * (1.0 + abs(v)) * math.cos(i + 0.7) for i, (k, v) in enumerate(params.items())}
    try:  # a probe: whatever F raises at parameters the user never gave, the pattern falls back to params
        with np.errstate(all="ignore"):
            usable = bool(np.all(np.isfinite(np.asarray(F(u0 + shift, moved), float))))
    except Exception:
        usable = False
    rows, cols = [], []
    for base, p in ((u0, params), (u0 + shift, moved if usable else params)):
        for j in range(n):
            h = step * max(1.0, abs(base[j]))
            up, um = base.copy(), base.copy()
            up[j] += h
            um[j] -= h
            col = np.asarray(F(up, p), float) - np.asarray(F(um, p), float)
            nz = np.nonzero(col)[0]
            rows.append(nz)
            cols.append(np.full(nz.size, j))
    r, c = np.concatenate(rows), np.concatenate(cols)
    pattern = sp.csc_matrix((np.ones(r.size), (r, c)), shape=(n, n))
    pattern.data[:] = 1.0
    return pattern


class FunctionProblem:
    """A :class:`contin.problem.Problem` from F(u, p) (see :func:`from_functions`)."""

    def __init__(self, F: Residual, u0: Array, params: Mapping[str, float], *, jacobian: Callable | None = None,
                 dF_dp: Callable | None = None, sparsity: Any = None, method: str = "fd",
                 order_parameter: Callable | None = None, observables: Callable | None = None,
                 mass_matrix: Any = None, symmetry: Callable | None = None, debug: bool = False,
                 inner_product_weights: Any = None) -> None:
        if method not in ("fd", "cs"):
            raise ValueError(f"method must be 'fd' (central differences) or 'cs' (complex step), got {method!r}")
        from contin.options import real_number

        self.F = F
        self.u0 = np.asarray(u0, float).ravel()
        if self.u0.size == 0:  # it ended in scipy's "need at least one array to concatenate"
            raise ValueError("u0 has no entries: F must map R^n to R^n with n >= 1")
        if not isinstance(params, Mapping) or not params:
            raise ValueError(f"params must be a dict with a value for every parameter, got {params!r}")
        # the parameter named ({'lam': 'x'} said "could not convert string to float: 'x'")
        self.params0 = {str(k): real_number(v, f"params[{k!r}]") for k, v in params.items()}
        self.parameter_names = tuple(self.params0)
        self.method = method
        self.size = self.u0.size
        raw = np.asarray(F(self.u0, self.params0))
        if np.iscomplexobj(raw) and method == "fd":
            # cast with a ComplexWarning per call, the imaginary part dropped (qa15)
            raise ValueError(f"F(u0, params) returned complex values ({raw.dtype}); F must be real for real u "
                             f"(method='cs' evaluates it at complex u itself)")
        f0 = np.asarray(raw, float)
        if f0.shape != self.u0.shape:
            raise ValueError(f"F(u0, params) has shape {f0.shape}, but u0 has {self.u0.size} entries: F must map R^n to R^n")
        self._exact = jacobian
        self._dF_dp = dF_dp
        self._checked = not debug
        if jacobian is None:
            self.pattern = (sp.csc_matrix(sparsity, dtype=float) if sparsity is not None
                            else detect_sparsity(F, self.u0, self.params0))
            if self.pattern.shape != (self.size, self.size):
                raise ValueError(f"sparsity has shape {self.pattern.shape}, expected ({self.size}, {self.size})")
            self.pattern.data[:] = 1.0
            self.groups = column_groups(self.pattern)
        if order_parameter is not None:
            self.order_parameter = order_parameter
        if observables is not None:
            self.observables = observables
        if symmetry is not None:
            self.symmetry = symmetry
        if mass_matrix is not None:
            m = mass_matrix
            self.mass_matrix = m if callable(m) else (lambda u, p, _m=sp.csc_matrix(m): _m)
        if inner_product_weights is not None:
            w = inner_product_weights
            self.inner_product_weights = w if callable(w) else (lambda u, p, _w=np.asarray(w, float): _w)

    @property
    def central_differences(self) -> bool:
        """Whether J comes from central differences (method 'fd', no exact ``jacobian``): accurate
        to ~1e-10 relative, so a system that differentiates J again (fold and Hopf curves) has a
        residual floor ~1e-5 |J| its corrector may not get below."""
        return self._exact is None and self.method == "fd"

    def initial(self) -> Array:
        """The u0 given to :func:`from_functions`."""
        return self.u0.copy()

    def residual(self, u: Array, p: Params) -> Array:
        return np.asarray(self.F(u, p))

    def jacobian(self, u: Array, p: Params) -> sp.csc_matrix:
        if self._exact is not None:
            jac = sp.csc_matrix(self._exact(u, p))
            if not self._checked:
                self._checked = True
                self._check(u, p)
            return jac
        return self._grouped(np.asarray(u, float), p)

    def _grouped(self, u: Array, p: Params) -> sp.csc_matrix:
        """Compressed differences: one (or two) residual calls per column group."""
        n = u.size
        pat = self.pattern.tocoo()
        vals = np.empty(pat.nnz)
        for g in range(int(self.groups.max()) + 1 if n else 0):
            cols = np.nonzero(self.groups == g)[0]
            h = np.zeros(n)
            if self.method == "cs":
                h[cols] = CS_STEP * np.maximum(1.0, np.abs(u[cols]))
                d = np.asarray(self.F(u + 1j * h, p)).imag
            else:
                h[cols] = FD_STEP * np.maximum(1.0, np.abs(u[cols]))
                d = (np.asarray(self.F(u + h, p), float) - np.asarray(self.F(u - h, p), float)) / 2.0
            sel = np.isin(pat.col, cols)
            vals[sel] = d[pat.row[sel]] / h[pat.col[sel]]
        return sp.csc_matrix((vals, (pat.row, pat.col)), shape=(n, n))

    def dresidual_dp(self, u: Array, p: Params, name: str) -> Array:
        if self._dF_dp is not None:
            return np.asarray(self._dF_dp(u, p, name), float)
        q = dict(p)
        if self.method == "cs":
            h = CS_STEP * max(1.0, abs(p[name]))
            q[name] = complex(p[name], h)
            return np.asarray(self.F(np.asarray(u, complex), q)).imag / h
        h = FD_STEP * max(1.0, abs(p[name]))
        q[name] = p[name] + h
        fp = np.asarray(self.F(u, q), float)
        q[name] = p[name] - h
        return (fp - np.asarray(self.F(u, q), float)) / (2 * h)

    def _check(self, u: Array, p: Params) -> None:
        res = check_jacobian(self, u, p, parameters=self.parameter_names if self._dF_dp is not None else None)
        if res.relative_error > DEBUG_TOL:
            raise ValueError(f"the given jacobian differs from finite differences by {res.jacobian_error:.3g} "
                             f"(relative {res.relative_error:.3g} > {DEBUG_TOL:g}); check it with "
                             "contin.problem.check_jacobian")
        for name, err in res.dp_errors.items():
            scale = max(1.0, float(np.max(np.abs(self.dresidual_dp(u, p, name)))))
            if err > DEBUG_TOL * scale:
                raise ValueError(f"the given dF_dp for {name!r} differs from finite differences by {err:.3g}")


def from_functions(F: Residual, u0: Array, params: Mapping[str, float], **kwargs: Any) -> FunctionProblem:
    """A problem from F(u, p) alone (module docstring), ready for :func:`contin.continuation.trace`.

    Parameters
    ----------
    F : callable (u, p) -> (n,) array, p a dict of every parameter
    u0 : (n,) array -- a state (its size fixes n; the sparsity is detected around it)
    params : dict -- every parameter with a value (their names and order)
    jacobian : optional (u, p) -> (n, n) sparse or dense; exact dF/du instead of differences
    dF_dp : optional (u, p, name) -> (n,) array
    sparsity : optional (n, n) pattern of dF/du (sparse or dense; nonzeros matter)
    method : 'fd' (central differences, default) or 'cs' (complex step; F must accept complex u, p)
    order_parameter, observables, symmetry : optional (u, p) -> float / dict / (u) -> S u
    mass_matrix : optional (n, n) matrix or (u, p) -> matrix (M du/dt = F) for stability
    inner_product_weights : optional (n,) positive array or (u, p) -> array: quadrature weights of
        a discretised PDE (``contin.problem``), the norm of l1's Hopf vector
    debug : compare a given jacobian (and dF_dp) once with differences; raise on a mismatch
    """
    return FunctionProblem(F, u0, params, **kwargs)
