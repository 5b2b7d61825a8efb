"""Orthogonal collocation of the periodic boundary-value problem (Doedel's scheme, as in AUTO).

A periodic orbit of M u' = F(u, p) with period T is, in the scaled time t in [0, 1],

    M u'(t) = T F(u(t), p),     u(0) = u(1),     int_0^1 <u(t), u_ref'(t)> dt = 0,

the last (AUTO's integral phase condition) fixing the time shift against a reference orbit
u_ref.  The interval [0, 1] is cut by the mesh 0 = t_0 < ... < t_NTST = 1; on each mesh interval
u is a polynomial of degree NCOL, represented by its values at the NCOL + 1 equally spaced nodes
t_j + k h_j / NCOL (k = 0..NCOL; AUTO's representation), neighbouring intervals sharing their
end node.  Periodicity is imposed by identifying the last node (t = 1) with the first, so the
unknowns are the NTST * NCOL node values (n each) and T.  The differential equation is collocated
at the NCOL Gauss-Legendre points of each interval (multiplied by h_j):

    M sum_k l_k'(z_i) u_{j,k} - h_j T F(sum_k l_k(z_i) u_{j,k}, p) = 0.

Error (de Boor & Swartz 1973; Doedel, Keller & Kernevez 1991): O(h^NCOL) uniformly and
O(h^{2 NCOL}) at the mesh points (superconvergence).  The Jacobian is exact: blocks of the
problem's Jacobian J at the collocation points.  M is the problem's ``mass_matrix`` taken as
constant (evaluated once); absent, M = I.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from contin.problem import Array

#: Default number of mesh intervals and of collocation points per interval (AUTO's NTST, NCOL).
NTST = 20
NCOL = 4


def lagrange_tables(ncol: int) -> tuple[Array, Array, Array, Array]:
    """(z, w, L, D): the Gauss-Legendre points z_i and weights w_i on [0, 1] (sum w = 1), and
    L[i, k] = l_k(z_i), D[i, k] = l_k'(z_i) for the Lagrange basis on the nodes s_k = k / ncol."""
    if ncol < 1:
        raise ValueError(f"NCOL must be >= 1, got {ncol}")
    x, wx = np.polynomial.legendre.leggauss(ncol)
    z, w = (x + 1) / 2, wx / 2
    s = np.arange(ncol + 1) / ncol
    m = ncol + 1
    L = np.empty((ncol, m))
    D = np.empty((ncol, m))
    for k in range(m):
        others = np.delete(s, k)
        den = np.prod(s[k] - others)
        L[:, k] = np.prod(z[:, None] - others[None, :], axis=1) / den
        # l_k'(z) = sum_r prod_{q != r} (z - s_q) / den
        D[:, k] = sum(np.prod(z[:, None] - np.delete(others, r)[None, :], axis=1) for r in range(ncol)) / den
    return z, w, L, D


def lagrange_at(ncol: int, s: Array) -> Array:
    """B[i, k] = l_k(s_i) for the nodes k / ncol (interpolation inside one mesh interval)."""
    nodes = np.arange(ncol + 1) / ncol
    s = np.atleast_1d(np.asarray(s, dtype=float))
    out = np.ones((s.size, ncol + 1))
    for k in range(ncol + 1):
        for q in range(ncol + 1):
            if q != k:
                out[:, k] *= (s - nodes[q]) / (nodes[k] - nodes[q])
    return out


@dataclass(frozen=True)
class Mesh:
    """The collocation mesh of n-dimensional periodic orbits: NTST intervals (uniform unless
    ``points`` are given), NCOL Gauss points each."""

    n: int
    ntst: int = NTST
    ncol: int = NCOL
    points: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.ntst < 2 or self.ncol < 1 or self.n < 1:
            raise ValueError(f"collocation needs NTST >= 2 and NCOL >= 1 (got NTST = {self.ntst}, NCOL = {self.ncol})")
        if self.points is not None:
            t = np.asarray(self.points, dtype=float)
            if t.shape != (self.ntst + 1,) or t[0] != 0 or t[-1] != 1 or not np.all(np.diff(t) > 0):
                raise ValueError("mesh points must be NTST + 1 increasing values from 0 to 1")

    @cached_property
    def t(self) -> Array:
        """Mesh points t_0 = 0 < ... < t_NTST = 1."""
        if self.points is None:
            return np.linspace(0.0, 1.0, self.ntst + 1)
        return np.asarray(self.points, dtype=float)

    @property
    def h(self) -> Array:
        return np.diff(self.t)

    @property
    def nodes(self) -> int:
        """Number of distinct nodes (t = 1 is t = 0)."""
        return self.ntst * self.ncol

    @property
    def size(self) -> int:
        """Unknowns of the periodic BVP: the node values and T."""
        return self.n * self.nodes + 1

    @cached_property
    def tables(self) -> tuple[Array, Array, Array, Array]:
        return lagrange_tables(self.ncol)

    @cached_property
    def node_times(self) -> Array:
        """Times of the NTST * NCOL nodes (without t = 1)."""
        s = np.arange(self.ncol) / self.ncol
        return (self.t[:-1, None] + self.h[:, None] * s[None, :]).ravel()

    @cached_property
    def gauss_times(self) -> Array:
        """Times of the collocation points, shape (NTST, NCOL)."""
        z = self.tables[0]
        return self.t[:-1, None] + self.h[:, None] * z[None, :]

    @cached_property
    def interval_nodes(self) -> Array:
        """g[j, k]: the node index of node k of interval j (the last wraps to 0)."""
        j = np.arange(self.ntst)[:, None] * self.ncol + np.arange(self.ncol + 1)[None, :]
        return j % self.nodes

    def split(self, x: Array) -> tuple[Array, float]:
        """(U, T): the node values, shape (NTST * NCOL, n), and the period."""
        return np.asarray(x[:-1]).reshape(self.nodes, self.n), float(x[-1])

    def pack(self, nodes: Array, period: float) -> Array:
        return np.concatenate([np.asarray(nodes, dtype=float).ravel(), [float(period)]])

    def blocks(self, nodes: Array) -> Array:
        """The node values interval by interval, shape (NTST, NCOL + 1, n)."""
        return nodes[self.interval_nodes]

    def at_gauss(self, nodes: Array) -> Array:
        """u at the collocation points, shape (NTST, NCOL, n)."""
        return np.einsum("ik,jkn->jin", self.tables[2], self.blocks(nodes))

    def derivative_at_gauss(self, nodes: Array) -> Array:
        """du/dt at the collocation points, shape (NTST, NCOL, n)."""
        return np.einsum("ik,jkn->jin", self.tables[3], self.blocks(nodes)) / self.h[:, None, None]

    def integrate(self, values: Array) -> float:
        """int_0^1 v dt of values v given at the collocation points (shape (NTST, NCOL, ...)),
        by Gauss-Legendre quadrature on each interval (exact for degree 2 NCOL - 1)."""
        w = self.tables[1]
        return float(np.einsum("j,i,ji...->", self.h, w, values))

    def l2_norm(self, nodes: Array) -> float:
        """sqrt(int_0^1 |u|^2 dt) (AUTO's L2-NORM of an orbit)."""
        u = self.at_gauss(nodes)
        return math.sqrt(max(self.integrate(np.sum(u * u, axis=-1)), 0.0))

    def evaluate(self, nodes: Array, times: Array) -> Array:
        """u(t) at the given times in [0, 1] (periodic), shape (len(times), n)."""
        tt = np.mod(np.asarray(times, dtype=float), 1.0)
        j = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, self.ntst - 1)
        s = (tt - self.t[j]) / self.h[j]
        out = np.empty((tt.size, self.n))
        blocks = self.blocks(nodes)
        for r in range(tt.size):
            out[r] = lagrange_at(self.ncol, s[r])[0] @ blocks[j[r]]
        return out

    def phase_row(self, reference: Array) -> Array:
        """The row c with c . U = int_0^1 <u(t), u_ref'(t)> dt (reference node values)."""
        _, w, L, _ = self.tables
        dref = self.derivative_at_gauss(reference) * self.h[:, None, None]  # (NTST, NCOL, n), times h
        # coefficient of node (j, k): sum_i w_i L[i, k] dref[j, i] (the h of dt cancels the 1/h of u_ref')
        coef = np.einsum("i,ik,jin->jkn", w, L, dref)
        row = np.zeros((self.nodes, self.n))
        np.add.at(row, self.interval_nodes, coef)
        return row.ravel()

    def highest_derivative(self, nodes: Array) -> Array:
        """u^(NCOL) on each interval (constant there: the NCOL-th difference of its equally spaced
        node values over (h / NCOL)^NCOL), shape (NTST, n)."""
        blocks = self.blocks(nodes)
        diff = np.diff(blocks, n=self.ncol, axis=1)[:, 0, :]
        return diff / (self.h[:, None] / self.ncol) ** self.ncol

    def adapted(self, nodes: Array, floor: float = 0.05) -> Mesh:
        """A mesh that equidistributes the collocation error estimate of the orbit ``nodes``
        (AUTO's mesh adaptation, Russell & Christiansen 1978): the error of interval j is about
        h_j^(NCOL+1) |u^(NCOL+1)|, so the new mesh equidistributes int |u^(NCOL+1)|^(1/(NCOL+1)) dt,
        with u^(NCOL+1) from the jumps of u^(NCOL) between neighbouring intervals (periodically).
        ``floor`` (a fraction of the mean monitor added everywhere) keeps intervals where the
        orbit is nearly a straight line from growing without bound."""
        m = self.ncol
        d = self.highest_derivative(nodes)
        jump = np.max(np.abs(np.roll(d, -1, axis=0) - d), axis=1)  # at t_{j+1}, between j and j + 1
        h = self.h
        at_points = 2 * jump / (h + np.roll(h, -1))  # |u^(m+1)| at the mesh points t_1 .. t_N (t_N = t_0)
        per_interval = 0.5 * (at_points + np.roll(at_points, 1)) ** (1.0 / (m + 1))
        mean = float(np.sum(per_interval * h))
        if not (math.isfinite(mean) and mean > 0):
            return self
        monitor = per_interval + floor * mean
        cumulative = np.concatenate([[0.0], np.cumsum(monitor * h)])
        targets = np.linspace(0.0, cumulative[-1], self.ntst + 1)
        points = np.interp(targets, cumulative, self.t)
        points[0], points[-1] = 0.0, 1.0
        return Mesh(self.n, self.ntst, self.ncol, tuple(float(v) for v in points))

    def resample(self, other: Mesh, nodes: Array) -> Array:
        """The node values of an orbit carried onto the nodes of ``other`` (interpolation)."""
        return self.evaluate(nodes, other.node_times)

    def remeshed(self, nodes: Array, ntst: int, ncol: int, adapt: bool = True) -> Mesh:
        """The mesh of ``ntst`` intervals and ``ncol`` points for the orbit ``nodes`` of this mesh:
        uniform, then (``adapt``) adapted to the orbit twice (:meth:`adapted`)."""
        target = Mesh(self.n, ntst, ncol)
        if adapt:
            for _ in range(2):
                target = target.adapted(self.resample(target, nodes))
        return target


class Collocation:
    """Residual and exact Jacobian of the periodic BVP (module docstring) for a problem.

    ``f(u, p)`` and ``jac(u, p)`` are the problem's residual and Jacobian, ``mass`` the constant
    M (None: identity), ``reference`` the node values of the phase reference u_ref.
    """

    def __init__(self, problem: object, mesh: Mesh, reference: Array, mass: Array | None = None) -> None:
        self.problem = problem
        self.mesh = mesh
        self.mass = None if mass is None else np.asarray(mass, dtype=float)
        self.set_reference(reference)
        m = mesh
        rows = np.arange(m.nodes).reshape(m.ntst, m.ncol)  # equation block (j, i)
        # sparsity: block (j, i) x node g[j, k]
        self._r = np.repeat(rows[:, :, None], m.ncol + 1, axis=2)
        self._c = np.repeat(m.interval_nodes[:, None, :], m.ncol, axis=1)

    def set_reference(self, reference: Array) -> None:
        self.reference = np.asarray(reference, dtype=float).reshape(self.mesh.nodes, self.mesh.n).copy()
        self.phase = self.mesh.phase_row(self.reference)

    def _f(self, ug: Array, p: dict[str, float]) -> Array:
        return np.array([self.problem.residual(v, p) for v in ug.reshape(-1, self.mesh.n)]).reshape(ug.shape)

    def residual(self, x: Array, p: dict[str, float]) -> Array:
        m = self.mesh
        nodes, period = m.split(x)
        _, _, _, D = m.tables
        blocks = m.blocks(nodes)
        du = np.einsum("ik,jkn->jin", D, blocks)  # h u'
        if self.mass is not None:
            du = du @ self.mass.T
        f = self._f(m.at_gauss(nodes), p)
        res = du - (m.h[:, None, None] * period) * f
        return np.concatenate([res.ravel(), [self.phase @ x[:-1]]])

    def interval_blocks(self, x: Array, p: dict[str, float]) -> Array:
        """The derivative of the collocation equations (j, i) in the node values (j, k):
        E[j, i, k] = D[i, k] M - h_j T L[i, k] J(u(z_ji)), shape (NTST, NCOL, NCOL + 1, n, n)."""
        m = self.mesh
        n = m.n
        nodes, period = m.split(x)
        _, _, L, D = m.tables
        ug = m.at_gauss(nodes).reshape(-1, n)
        jacs = np.array([dense_matrix(self.problem.jacobian(v, p)) for v in ug]).reshape(m.ntst, m.ncol, n, n)
        mass = np.eye(n) if self.mass is None else self.mass
        return (D[None, :, :, None, None] * mass[None, None, None]
                - (m.h[:, None, None, None, None] * period) * L[None, :, :, None, None] * jacs[:, :, None])

    def jacobian(self, x: Array, p: dict[str, float]) -> sp.csc_matrix:
        m = self.mesh
        n = m.n
        blk = self.interval_blocks(x, p)
        ug = m.at_gauss(m.split(x)[0]).reshape(-1, n)
        rr = self._r[..., None, None] * n + np.arange(n)[:, None]
        cc = self._c[..., None, None] * n + np.arange(n)[None, :]
        rr, cc = np.broadcast_to(rr, blk.shape).ravel(), np.broadcast_to(cc, blk.shape).ravel()
        f = self._f(ug, p).ravel()
        tcol = -np.repeat(m.h, m.ncol * n) * f
        N = m.size
        body = sp.coo_matrix((blk.ravel(), (rr, cc)), shape=(N, N))
        tpart = sp.coo_matrix((tcol, (np.arange(N - 1), np.full(N - 1, N - 1))), shape=(N, N))
        phase = sp.coo_matrix((self.phase, (np.full(N - 1, N - 1), np.arange(N - 1))), shape=(N, N))
        return (body + tpart + phase).tocsc()

    def dresidual_dp(self, x: Array, p: dict[str, float], name: str) -> Array:
        m = self.mesh
        nodes, period = m.split(x)
        ug = m.at_gauss(nodes).reshape(-1, m.n)
        fp = np.array([self.problem.dresidual_dp(v, p, name) for v in ug]).reshape(m.ntst, m.ncol, m.n)
        return np.concatenate([(-(m.h[:, None, None] * period) * fp).ravel(), [0.0]])


def dense_matrix(a: object) -> Array:
    """A scipy.sparse matrix or array-like as a dense float array (problems may give either)."""
    return a.toarray() if sp.issparse(a) else np.asarray(a, dtype=float)
