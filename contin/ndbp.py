"""Branch switching at a branch point whose kernel has dimension d > 1 (reduced bifurcation
equations; BifurcationKit's "nd branch points", Govaerts 2000 sec. 3.5; Golubitsky & Schaeffer,
*Singularities and Groups in Bifurcation Theory* I, ch. VII).

At the BP x0 = (u0, p0) of a known branch with tangent t1 = (u', p'), let Z (n x d) span the
kernel of J and W (n x d) the left kernel, W^T Z = I.  Near x0 the solutions are
u = u0 + (u'/p') delta + Z a + w with the Lyapunov-Schmidt reduction

    f(a, delta) = delta M a + Q(a, a) / 2 + C(a) / 6 + ... = 0,     f : R^d x R -> R^d,

    M = W^T (dJ/dp along the branch) Z,     Q(a, a) = W^T B(Za, Za),
    C(a) = W^T [ F_uuu(Za, Za, Za) + 3 B(Za, w2(a)) ],   J w2 = -(I - Z W^T) B(Za, Za),

B = F_uu (differences of J).  Every branch through x0 other than the known one is tangent to a
nonzero root direction: if Q does not vanish (transcritical type) a = delta b with
M b + Q(b, b)/2 = 0, tangent (u'/p' + Z b, 1) ~ followed both ways; if Q vanishes identically
(the equivariant case, e.g. F odd) a = sqrt(|delta|) b with sigma M b + C(b)/6 = 0 for
sigma = sign(delta) = +-1, tangent (Z b, 0) into the side sigma.  The roots are found by Newton
from many starting points (deduplicated), each direction is traced like a simple BP's new
branch (``contin.switching``).  Dense linear algebra: n <= :data:`ND_DENSE_LIMIT`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.extended import ExtendedSystem
from contin.options import ContinuationOptions
from contin.problem import Array
from contin.switching import Departure, first_point

#: Largest n for which the kernels are computed by a dense SVD.
ND_DENSE_LIMIT = 2000
#: Relative size of the difference steps for second and third derivatives.
FD_STEP = 1e-4
#: Newton starts per reduced system and the tolerances of its roots.
STARTS = 400
ROOT_TOL = 1e-10


def kernels(jac: Array, d: int) -> tuple[Array, Array]:
    """Z, W: right and left singular vectors of the d smallest singular values, W^T Z = I."""
    import scipy.linalg as la  # lazy: the package is off the path to the first step (contin.lapack)

    u, s, vt = la.svd(jac)
    z = vt[-d:].T
    w = u[:, -d:]
    w = w @ np.linalg.inv(z.T @ w).T  # biorthogonal: W^T Z = I
    return z, w


class Reduced:
    """The reduced equations' coefficients at one BP (module docstring)."""

    def __init__(self, system: ExtendedSystem, x0: Array, t1: Array, d: int) -> None:
        self.system, self.x0, self.d = system, x0, d
        n = x0.size - 1
        self.n = n
        jac = _dense(system.jacobian(x0, dense=False)[0])
        self.J = jac
        self.Z, self.W = kernels(jac, d)
        h = FD_STEP * max(1.0, float(np.max(np.abs(x0))))
        # dJ/dp along the branch (theta-free: t1 scaled to dp = 1 when the branch is not vertical)
        tb = t1 / t1[-1] if abs(t1[-1]) > 1e-8 * np.linalg.norm(t1) else t1
        self.along = tb
        jp = _dense(system.jacobian(x0 + h * tb, dense=False)[0])
        jm = _dense(system.jacobian(x0 - h * tb, dense=False)[0])
        self.M = self.W.T @ ((jp - jm) / (2 * h)) @ self.Z
        self.h = h

    def _jac_u(self, v: Array) -> Array:
        x = self.x0.copy()
        x[:-1] += v
        return _dense(self.system.jacobian(x, dense=False)[0])

    def B(self, v: Array, w: Array) -> Array:
        h = self.h / max(float(np.max(np.abs(v))), 1e-300)
        return (self._jac_u(h * v) - self._jac_u(-h * v)) @ w / (2 * h)

    def Q(self, a: Array) -> Array:
        v = self.Z @ a
        return self.W.T @ self.B(v, v)

    def C(self, a: Array) -> Array:
        v = self.Z @ a
        h = (self.h ** 0.5) / max(float(np.max(np.abs(v))), 1e-300)  # third differences: larger step
        f3 = (self._jac_u(h * v) - 2 * self.J + self._jac_u(-h * v)) @ v / h**2
        b = self.B(v, v)
        rhs = -(b - self.Z @ (self.W.T @ b))
        w2 = np.linalg.lstsq(self.J, rhs, rcond=None)[0]
        w2 -= self.Z @ (self.W.T @ w2)  # the component in the kernel is a's, not w's
        return self.W.T @ (f3 + 3 * self.B(v, w2))


class Polynomial:
    """A homogeneous polynomial map R^d -> R^d of the given degree, fitted by least squares to
    samples of ``f`` (exact up to the samples' rounding: f is a polynomial of that degree), so
    that Newton on the reduced equations costs no Jacobian evaluations of the problem."""

    def __init__(self, f: Any, d: int, degree: int, seed: int = 2) -> None:
        from itertools import combinations_with_replacement

        self.terms = list(combinations_with_replacement(range(d), degree))
        rng = np.random.default_rng(seed)
        samples = rng.standard_normal((2 * len(self.terms) + 4, d))
        design = np.array([self._monomials(b) for b in samples])
        values = np.array([f(b) for b in samples])
        self.coef, *_ = np.linalg.lstsq(design, values, rcond=None)
        self.size = float(np.max(np.abs(values))) if values.size else 0.0

    def _monomials(self, b: Array) -> Array:
        return np.array([np.prod(b[list(t)]) for t in self.terms])

    def __call__(self, b: Array) -> Array:
        return self._monomials(b) @ self.coef


def _dense(a: Any) -> Array:
    return a.toarray() if hasattr(a, "toarray") else np.asarray(a, dtype=float)


def _roots(f: Any, d: int, scale: float, seed: int = 0) -> list[Array]:
    """Distinct nonzero roots of f: R^d -> R^d by Newton (difference Jacobian) from random starts."""
    from itertools import product

    rng = np.random.default_rng(seed)
    found: list[Array] = []
    # the vertices of {-1, 0, 1}^d (the roots of decoupled equations) first, then random starts
    starts = [np.array(v, float) * scale for v in product((-1, 0, 1), repeat=d) if any(v)] if d <= 6 else []
    starts += [rng.standard_normal(d) * scale * rng.uniform(0.2, 3.0) for _ in range(STARTS)]
    for b in starts:
        for _ in range(60):
            r = f(b)
            if not np.all(np.isfinite(r)):
                break
            jac = np.empty((d, d))
            eps = 1e-7 * max(1.0, float(np.max(np.abs(b))))
            for j in range(d):
                e = np.zeros(d)
                e[j] = eps
                jac[:, j] = (f(b + e) - f(b - e)) / (2 * eps)
            try:
                step = np.linalg.solve(jac, -r)
            except np.linalg.LinAlgError:
                break
            b = b + step
            if np.linalg.norm(step) <= ROOT_TOL * max(1.0, np.linalg.norm(b)):
                break
        if not np.all(np.isfinite(b)) or np.linalg.norm(b) < 1e-6 * scale:
            continue
        if np.linalg.norm(f(b)) > 1e-8 * max(1.0, scale):
            continue
        if not any(np.linalg.norm(b - c) <= 1e-6 * max(1.0, np.linalg.norm(c)) for c in found):
            found.append(b)
    return found


def directions(red: Reduced) -> list[tuple[Array, str]]:
    """Unit tangents (u, p) of the new branches and a note naming the reduced root."""
    d, sys = red.d, red.system
    quad = Polynomial(red.Q, d, 2)
    qsize, msize = quad.size, float(np.linalg.norm(red.M))
    out: list[tuple[Array, str]] = []
    cub = None if qsize > 1e-6 * max(msize, 1e-300) else Polynomial(red.C, d, 3)
    csize = 0.0 if cub is None else cub.size
    if cub is None:
        qc = float(np.max(np.abs(quad.coef)))
        for b in _roots(lambda b: red.M @ b + 0.5 * quad(b), d, 2 * msize / max(qc, 1e-300)):
            tau = np.concatenate([red.along[:-1] + red.Z @ b, [red.along[-1]]])
            out += [(sys.unit(tau), f"a = delta ({', '.join(f'{v:.4g}' for v in b)})"),
                    (sys.unit(-tau), f"a = delta ({', '.join(f'{v:.4g}' for v in b)}), delta < 0")]
        return out
    if csize == 0:
        raise ValueError("the reduced equations are degenerate to cubic order (Q and C vanish); cannot switch")
    for sigma in (1.0, -1.0):
        cc = float(np.max(np.abs(cub.coef)))
        for b in _roots(lambda b, s=sigma: s * red.M @ b + cub(b) / 6.0, d, math.sqrt(6 * msize / cc)):
            tau = np.concatenate([red.Z @ b, [0.0]])
            out.append((sys.unit(tau), f"a = sqrt({'+' if sigma > 0 else '-'}delta) ({', '.join(f'{v:.4g}' for v in b)})"))
    return out


def nd_departures(problem: Any, branch: Branch, point: SpecialPoint, options: ContinuationOptions, dim: int, *,
                  ds: float | None = None) -> list[Departure | str]:
    """The first point along each root direction of the reduced equations at a BP of kernel
    dimension ``dim`` > 1 (module docstring); a root without an accepted first step gives its
    note (a str).  :func:`contin.continuation.switch` traces on from them.

    Raises ValueError with one clear sentence when the point is too large for the dense
    reduction or the reduced equations have no nonzero root.
    """
    param = branch.parameter
    u0 = np.asarray(point.state, dtype=float)
    if u0.size > ND_DENSE_LIMIT:
        raise ValueError(f"{point.name} has a kernel of dimension {dim}; switching there needs the reduced equations, "
                         f"which contin computes densely for n <= {ND_DENSE_LIMIT} only (n = {u0.size})")
    system = ExtendedSystem(problem, point.params, param, options.step.theta)
    system.n = u0.size
    x0 = system.pack(u0, point.params[param])
    t1 = system.unit(np.asarray(point.tangent, dtype=float))
    red = Reduced(system, x0, t1, dim)
    dirs = directions(red)
    if not dirs:
        raise ValueError(f"the reduced equations at {point.name} ({param} = {x0[-1]:.10g}, kernel dimension {dim}) "
                         "have no nonzero root: no branch to switch to")
    out: list[Departure | str] = []
    for tau, note in dirs:
        start, step, _ = first_point(system, x0, tau, abs(ds if ds is not None else options.step.ds), options)
        out.append(Departure(system, x0, start, tau, step, +1, note) if start is not None else note)
    return out
