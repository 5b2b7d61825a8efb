"""The extended system of one-parameter continuation: x = (u, p), G(x) = F(u, p).

Holds the problem, the fixed parameters and the name of the free one, and defines the weighted
inner product of pseudo-arclength continuation (Keller 1977; AUTO-07p, BifurcationKit ``DotTheta``)

    <a, b>_theta = (a_u . b_u) / n + theta * a_p * b_p,

which makes step sizes independent of the grid size n.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.linalg import counted_dense, dense_factorization
from contin.problem import Array, has


#: Jacobians an ExtendedSystem remembers (ExtendedSystem.state_jacobian).
JACOBIAN_MEMO = 3


def l2_norm(u: Array) -> float:
    """The default order parameter: the discrete L2 norm ||u||_2 / sqrt(n).

    AUTO-07p plots the L2 norm of the solution when the user names no other measure; for a
    state sampled on n points of a unit interval ||u||_2 / sqrt(n) approximates the integral
    norm (for n = 1 it is |u|).
    """
    u = np.asarray(u, dtype=float)
    return float(np.linalg.norm(u) / math.sqrt(max(u.size, 1)))


def _takes_out(fn: Any) -> bool:
    """True when ``fn`` accepts an ``out`` keyword (an optional extension of a problem hook)."""
    import inspect

    try:
        return "out" in inspect.signature(fn).parameters
    except (TypeError, ValueError):  # builtins without a signature
        return False


def validate_params(problem: Any, params: Mapping[str, float], parameter: str | None = None) -> dict[str, float]:
    """A full, float-valued copy of ``params``; ValueError naming any unknown or missing name."""
    names = tuple(problem.parameter_names)
    if not isinstance(params, Mapping):  # a list of values met str.join: 'sequence item 0: expected str'
        raise TypeError(f"params must be a mapping {{name: value}} of the problem's parameters ({', '.join(names)}), "
                        f"got {type(params).__name__}")
    unknown = sorted(set(params) - set(names), key=str)
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}; the problem has {', '.join(names)}")
    missing = [k for k in names if k not in params]
    if missing:
        raise ValueError(f"missing value(s) for parameter(s) {', '.join(missing)}")
    if parameter is not None and parameter not in names:
        raise ValueError(f"unknown continuation parameter {parameter!r}; the problem has {', '.join(names)}")
    out: dict[str, float] = {}
    from contin.options import real_number

    for k in names:
        # a str ('0.5', 'abc') or None is refused by name: float('0.5') passed silently and 'abc'
        # gave "could not convert string to float" without saying which parameter (session 14)
        v = real_number(params[k], f"parameter {k!r}")
        if math.isnan(v):
            raise ValueError(f"parameter {k} is NaN")
        out[k] = v
    if has(problem, "validate"):
        problem.validate(out)
    return out


class ExtendedSystem:
    """G(x) = F(u, p) with x = concat(u, [p]) for the free parameter ``parameter``."""

    def __init__(self, problem: Any, params: Mapping[str, float], parameter: str, theta: float = 1.0, n: int = 0) -> None:
        self.problem = problem
        self.parameter = parameter
        self.params = validate_params(problem, params, parameter)
        self.theta = float(theta)
        self.n = int(n)
        # Optional hooks looked up once (they are called at every Newton iteration).
        self._admissible = problem.admissible if has(problem, "admissible") else None
        self._dense_jacobian = problem.dense_jacobian if has(problem, "dense_jacobian") else None
        self._dense_decided = self._dense_jacobian is None  # decided at the first Jacobian
        # The hook may take out= (an earlier J to overwrite): then scratch=True Jacobians reuse one array.
        self._dense_out = self._dense_jacobian is not None and _takes_out(self._dense_jacobian)
        self._scratch: Array | None = None
        self._jacobians: dict[bytes, Any] = {}  # state_jacobian's memo (sparse and dense J by x)

    # --- packing ------------------------------------------------------------------------
    def pack(self, u: Array, p: float) -> Array:
        return np.concatenate([np.asarray(u, dtype=float).ravel(), [float(p)]])

    def params_at(self, p: float) -> dict[str, float]:
        q = dict(self.params)
        q[self.parameter] = float(p)
        return q

    # --- evaluations --------------------------------------------------------------------
    def residual(self, x: Array) -> Array:
        return np.asarray(self.problem.residual(x[:-1], self.params_at(x[-1])), dtype=float)

    def jacobian(self, x: Array, dense: bool = True, scratch: bool = False) -> tuple[sp.spmatrix | Array, Array]:
        """(J = dF/du, F_p = dF/dp) at x.

        J is dense when it will be factorized densely (``contin.linalg.dense_factorization`` of
        the first sparse J decides, by its structure) and the problem has the optional
        ``dense_jacobian`` hook (``dense=False`` declines it); otherwise as the problem's
        ``jacobian`` returns it (sparse, or dense for tiny problems).

        ``scratch=True`` (the corrector's Newton loop): a dense J may be written into the array
        of the previous scratch call (when the hook takes ``out``), so it is valid only until
        the next scratch call.  Saves one fresh n^2 array per iteration, whose page faults cost
        ~10 % of an iteration on large Chebyshev grids.
        """
        q = self.params_at(x[-1])
        u = x[:-1]
        if not self._dense_decided:
            self._dense_decided = True
            # a small problem's dense J, counted as the bordered matrix, may decide without a sparse J
            probe = counted_dense(lambda: self._dense_jacobian(u, q), u.size, bordered=True) if dense else None  # type: ignore[misc]
            if probe is not None:
                if scratch and self._dense_out:
                    self._scratch = probe  # as a scratch J: the next scratch call writes into it
                fp = np.asarray(self.problem.dresidual_dp(u, q, self.parameter), dtype=float).ravel()
                return probe, fp
            if not dense_factorization(self.state_jacobian(x, q), bordered=True):
                self._dense_jacobian = None
        if dense and self._dense_jacobian is not None:
            if scratch and self._dense_out:
                jac = np.asarray(self._dense_jacobian(u, q, out=self._scratch), dtype=float)
                self._scratch = jac  # overwritten by the next scratch call
            else:
                jac = np.asarray(self._dense_jacobian(u, q), dtype=float)
        else:
            jac = self.state_jacobian(x, q)
        fp = np.asarray(self.problem.dresidual_dp(u, q, self.parameter), dtype=float).ravel()
        return jac, fp

    def state_jacobian(self, x: Array, q: Mapping[str, float] | None = None,
                       dense_ok: bool = False) -> sp.spmatrix | Array:
        """J = dF/du at x (no F_p); sparse as the problem returns it, dense input as a 2-D array.

        The last JACOBIAN_MEMO Jacobians (by the bytes of x) are remembered: a point's J is asked
        for by its test functions (the symmetry-breaking determinant) and again by adaptive
        resolution's kernel estimates at the same point (``contin.adapt``).  Read-only for
        callers (every consumer copies before factorizing).

        ``dense_ok=True``: the caller uses J only through its entries' values (e.g. a dense
        gather, :meth:`contin.testfunctions.Antisymmetric.reduced`), so when the problem's
        ``dense_jacobian`` hook is in use (see :meth:`jacobian`) J comes from it (memoized
        apart from the sparse J): the same entries (the hook's contract), without building a
        sparse matrix only to copy it densely again (~1 ms per point of gPCF's main job, most
        of it scipy.sparse's constructor)."""
        if q is not None:
            jac = self.problem.jacobian(x[:-1], q)
            return jac if sp.issparse(jac) else np.atleast_2d(np.asarray(jac, dtype=float))
        key = np.asarray(x, dtype=float).tobytes()
        dense = dense_ok and self._dense_decided and self._dense_jacobian is not None
        if dense:
            key += b"dense"
        jac = self._jacobians.get(key)
        if jac is None:
            if dense:
                jac = np.asarray(self._dense_jacobian(x[:-1], self.params_at(x[-1])), dtype=float)
            else:
                jac = self.problem.jacobian(x[:-1], self.params_at(x[-1]))
                jac = jac if sp.issparse(jac) else np.atleast_2d(np.asarray(jac, dtype=float))
            if len(self._jacobians) >= JACOBIAN_MEMO:
                self._jacobians.pop(next(iter(self._jacobians)))
            self._jacobians[key] = jac
        return jac

    def admissible(self, x: Array) -> str | None:
        """None, or the problem's reason why x is outside its physical domain."""
        if self._admissible is not None:
            return self._admissible(x[:-1], self.params_at(x[-1]))  # type: ignore[no-any-return]
        return None

    def record(self, x: Array) -> dict[str, float]:
        """Observables at x: problem.observables plus 'phi' = problem.order_parameter."""
        q = self.params_at(x[-1])
        out: dict[str, float] = {}
        if has(self.problem, "observables"):
            out.update({k: float(v) for k, v in self.problem.observables(x[:-1], q).items()})
        out["phi"] = self.order_parameter(x)
        return out

    def order_parameter(self, x: Array) -> float:
        """The problem's ``order_parameter``, else the L2 norm :func:`l2_norm` (AUTO's default)."""
        if has(self.problem, "order_parameter"):
            return float(self.problem.order_parameter(x[:-1], self.params_at(x[-1])))
        return l2_norm(x[:-1])

    # --- weighted geometry -----------------------------------------------------------------
    def dot(self, a: Array, b: Array) -> float:
        n = a.size - 1
        return float(a[:-1] @ b[:-1]) / n + self.theta * float(a[-1] * b[-1])

    def norm(self, a: Array) -> float:
        return math.sqrt(max(self.dot(a, a), 0.0))

    def row(self, t: Array) -> Array:
        """The row vector c with c . x = <t, x>_theta (the bordering row of the corrector)."""
        c = np.array(t, dtype=float)
        c[:-1] /= c.size - 1
        c[-1] *= self.theta
        return c

    def unit(self, t: Array) -> Array:
        return t / self.norm(t)
