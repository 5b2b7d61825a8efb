"""Test functions whose sign changes mark special points along a branch.

- Fold (LP): the parameter component t_p of the oriented unit tangent.
- Branch point (BP): kappa = det [[J, F_p], [c^T]] / (c . t).  For any bordering row c with
  c . t != 0, det is linear in c and equals kappa (c . t) with kappa independent of c (the
  cofactor row of [J F_p] is kappa t^T), so the corrector's own factorization gives kappa for
  free, and kappa changes sign exactly where [J F_p] loses rank (Govaerts, *Numerical Methods
  for Bifurcations of Dynamical Equilibria*, SIAM 2000, sec. 3.3).  Sign and log|kappa| are
  kept separately because det over/underflows for large n.
- Symmetry-breaking BP: on a branch of S-invariant states (S an involution with
  F(S u) = S F(u)), J commutes with S and splits on the +-1 eigenspaces of S.  With Q an
  orthonormal basis of the -1 eigenspace, det(Q^T J Q) changes sign where an antisymmetric
  mode becomes critical; kappa / det(Q^T J Q) tracks the symmetric BPs.
"""

from __future__ import annotations

import functools
import logging
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.linalg import Factorization, as_csc, factorize, inverse_iteration
from contin.problem import Array, has

log = logging.getLogger("contin")

#: Largest n for which a general (not signed-permutation) symmetry is turned into a dense basis.
DENSE_SYMMETRY_LIMIT = 600
#: Largest n for which a sparse J is reduced to Q^T J Q densely (Antisymmetric.reduced).
DENSE_REDUCTION_LIMIT = 400

SignLog = tuple[float, float]


@dataclass(frozen=True)
class TestValues:
    """Test functions at one point: fold = t_p, bp = (sign, log|kappa|), anti = det(Q^T J Q);
    ``extra`` holds the values of the tracer's point tests (``contin.pointtests``) by name."""

    fold: float
    bp: SignLog
    anti: SignLog | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def symmetric_bp(self) -> SignLog:
        """kappa / det(Q^T J Q): changes sign at BPs inside the symmetric subspace."""
        if self.anti is None:
            return self.bp
        return (self.bp[0] * self.anti[0], self.bp[1] - self.anti[1])


def bp_value(fact: Factorization, row: Array, t: Array) -> SignLog:
    """(sign, log|kappa|) of kappa = det A / (c . t) from the factorization of A."""
    sign, logabs = fact.det_sign_log()
    ct = float(row @ t)
    return (sign * math.copysign(1.0, ct), logabs - math.log(abs(ct)) if ct != 0 else math.inf)


#: Bound on |log| of :func:`signed_value`: exp(+-700) is finite and nonzero in double precision.
LOG_CLAMP = 700.0


def signed_value(v: SignLog, reference: float) -> float:
    """sign * exp(log - reference): a continuous real version of a (sign, log) pair.

    The exponent is clamped to +-:data:`LOG_CLAMP`, so a value is zero only where the
    determinant itself is (sign 0 or log -inf): a locator must never mistake an underflow
    for a located zero (issue 14 sec. 3: at fd2 N = 1200 log|kappa| changes by more than
    745 across one step, exp underflowed to 0 at one end of the bracket, and that end was
    reported as a converged BP).
    """
    if v[0] == 0 or v[1] == -math.inf:
        return 0.0
    return v[0] * math.exp(min(max(v[1] - reference, -LOG_CLAMP), LOG_CLAMP))


def sign_change(a: Any, b: Any) -> bool | None:
    """Whether two values of one test function (floats, or (sign, log) pairs) have opposite,
    nonzero signs; None when either cannot be read (None, a NaN or infinite float, a NaN sign or
    log).  The one comparison of the tracer's detection (``_Tracer.detect``) and its retreat
    (``trace``): a value that is not finite is neither a sign change (no special point is made
    up from it) nor silently "no change" -- the caller says that the test function was not
    finite there.  Before session 15 the detection passed a NaN on to the locator (it made the
    comparison (nan > 0) == (vb > 0) false) while the retreat refused it."""
    def sign(v: Any) -> float:
        if v is None:
            return math.nan
        if isinstance(v, tuple):
            return float(v[0]) if math.isfinite(v[0]) and not math.isnan(v[1]) else math.nan
        v = float(v)
        return v if math.isfinite(v) else math.nan

    sa, sb = sign(a), sign(b)
    if math.isnan(sa) or math.isnan(sb):
        return None
    return sa != 0 and sb != 0 and (sa > 0) != (sb > 0)


def detrended(va: SignLog, vb: SignLog, s_b: float) -> Callable[[SignLog, float], float]:
    """g(v, s) = sign * exp(log|v| - l(s)), l linear in s with l(0) = log|va|, l(s_b) = log|vb|.

    A determinant along a branch has log|det| = sum log|lambda_i|: a smooth trend from the
    many eigenvalues that do not cross (it grows like the number of unknowns: hundreds of
    e-folds per step on fine grids) plus log|lambda_c| of the one that crosses zero.  Taking
    the trend out linearly between the two ends of a step makes g = +-1 at the ends and keeps
    it of order one inside, so regula falsi sees the crossing eigenvalue and not an
    exponential that under- or overflows.  g is a fixed function of s (the trend does not
    move while the bracket shrinks), so the locator's samples stay comparable.
    """
    la, lb = va[1], vb[1]
    slope = (lb - la) / s_b if s_b != 0 and math.isfinite(la) and math.isfinite(lb) else 0.0

    def g(v: SignLog, s: float) -> float:
        return signed_value(v, la + slope * s if math.isfinite(la) else max(la, lb))

    return g


#: Antisymmetric.from_problem results per problem instance.
_ANTI_CACHE: weakref.WeakKeyDictionary[Any, tuple[tuple[int, int], Antisymmetric | None]] = weakref.WeakKeyDictionary()


#: sqrt(machine epsilon): the floor of the F_p scale in :meth:`Antisymmetric.equivariance_defect`
_SQRT_EPS = float(np.sqrt(np.finfo(float).eps))


class Antisymmetric:
    """Orthonormal basis Q (sparse n x m) of the -1 eigenspace of a linear involution S."""

    def __init__(self, s: sp.csc_matrix, q: sp.csc_matrix) -> None:
        self.s = s
        self.q = q

    @property
    def dimension(self) -> int:
        return int(self.q.shape[1])

    @classmethod
    def from_problem(cls, problem: Any, n: int, seed: int = 0) -> Antisymmetric | None:
        """Build S and Q from ``symmetry_matrix()`` or by probing ``symmetry(u)``; None if unavailable.

        The result depends on the problem instance and n only (neither method takes parameters),
        so it is cached per instance (weakly: the cache does not keep problems alive).
        """
        try:
            cached = _ANTI_CACHE.get(problem)
        except TypeError:  # unhashable or not weak-referenceable problem: no cache
            return cls._build(problem, n, seed)
        if cached is not None and cached[0] == (n, seed):
            return cached[1]
        anti = cls._build(problem, n, seed)
        _ANTI_CACHE[problem] = ((n, seed), anti)
        return anti

    @classmethod
    def _build(cls, problem: Any, n: int, seed: int) -> Antisymmetric | None:
        if has(problem, "symmetry_matrix"):
            s = as_csc(problem.symmetry_matrix())
        elif has(problem, "symmetry"):
            s = _probe_signed_permutation(problem.symmetry, n, seed)
            if s is None:
                if n > DENSE_SYMMETRY_LIMIT:
                    log.warning("symmetry is not a signed permutation and n=%d is too large for a dense basis", n)
                    return None
                s = as_csc(np.column_stack([problem.symmetry(e) for e in np.eye(n)]))
        else:
            return None
        if abs(s @ (s @ np.arange(1.0, n + 1.0)) - np.arange(1.0, n + 1.0)).max() > 1e-9 * n:
            raise ValueError("the problem's symmetry is not an involution (S S != identity)")
        return cls(s, _antisymmetric_basis(s))

    def apply(self, u: Array) -> Array:
        return np.asarray(self.s @ u)

    def equivariance_defect(self, jac: Any, fp: Array) -> float:
        """How far F is from equivariant at an S-invariant state: the larger of
        max|S J S - J| / max|J| and max|S F_p - F_p| / max|F_p| (0 for an equivariant F up to
        rounding).  A problem's ``symmetry`` can be one only at some parameters (stretched
        Bratu's reflection only at a = 0): there the branch must not be treated as S-invariant."""
        s = self.s
        if sp.issparse(jac):
            j = sp.csr_matrix(jac)
            diff = sp.csr_matrix(s @ j @ s) - j  # S J S (S is its own inverse)
            worst, scale_j = float(np.max(np.abs(diff.data), initial=0.0)), float(np.max(np.abs(j.data), initial=0.0))
        else:
            j = np.asarray(jac, dtype=float)
            sjs = np.asarray(s.T @ np.asarray(s @ j).T).T  # (S J) S = ((S^T) (S J)^T)^T
            worst, scale_j = float(np.max(np.abs(sjs - j), initial=0.0)), float(np.max(np.abs(j), initial=0.0))
        out = worst / scale_j if scale_j > 0 else 0.0
        fp = np.asarray(fp, dtype=float)
        # F_p at rounding level is F_p = 0 (uniform shear solves F at every H: dF/dH ~ 1e-15,
        # whose "defect" relative to itself was 1 and switched the symmetry off for the savage
        # band's H branch, whose BPs were then missed): F_p is measured against sqrt(eps) |J| too
        scale_p = max(float(np.max(np.abs(fp), initial=0.0)), _SQRT_EPS * scale_j)
        if scale_p > 0:
            out = max(out, float(np.max(np.abs(np.asarray(s @ fp) - fp))) / scale_p)
        return out

    def is_invariant(self, u: Array, tol: float = 1e-8) -> bool:
        return float(np.max(np.abs(self.apply(u) - u), initial=0.0)) <= tol * max(1.0, float(np.max(np.abs(u), initial=0.0)))

    def symmetrize(self, u: Array) -> Array:
        return 0.5 * (u + self.apply(u))

    def reduced(self, jac: sp.spmatrix | Array) -> sp.csc_matrix | Array:
        """Q^T J Q: dense for a dense J or a small one (n <= :data:`DENSE_REDUCTION_LIMIT`),
        else sparse.

        The dense form gathers rows and columns (:attr:`_pairs`, a signed-permutation S: each
        column of Q has one or two entries) instead of two sparse products, which cost ~0.2 ms
        at continuation sizes (called at every point of an S-invariant branch).  Every entry is
        the same one- or two-term sum as in the sparse product (Q^T J) Q, so bitwise the same.
        """
        pairs = self._pairs
        n = jac.shape[0]
        if pairs is None or (sp.issparse(jac) and n > DENSE_REDUCTION_LIMIT):
            return as_csc(self.q.T @ as_csc(jac) @ self.q)
        a = jac.toarray() if sp.issparse(jac) else np.asarray(jac, dtype=float)
        i1, v1, i2, v2 = pairs
        qtj = v1[:, None] * a[i1] + v2[:, None] * a[i2]  # (Q^T J)_jk = v1_j J_i1(j),k + v2_j J_i2(j),k
        return qtj[:, i1] * v1 + qtj[:, i2] * v2

    def reduces_densely(self, n: int) -> bool:
        """True when :meth:`reduced` of an n x n J takes the dense gather whether J is sparse or
        dense, so a dense J with the same entries gives the same Q^T J Q bit for bit (nonzero
        entries; an exact zero may change sign, which no LU pivot or determinant sees)."""
        return self._pairs is not None and n <= DENSE_REDUCTION_LIMIT

    @functools.cached_property
    def _pairs(self) -> tuple[Array, Array, Array, Array] | None:
        """(i1, v1, i2, v2): the one or two entries of each column of Q (v2 = 0 for one), or None
        if some column has more (a general basis)."""
        q = sp.csc_matrix(self.q)
        q.sort_indices()
        counts = np.diff(q.indptr)
        out = None
        if counts.size and np.all((counts >= 1) & (counts <= 2)):
            first = q.indptr[:-1]
            second = np.where(counts == 2, first + 1, first)
            v2 = np.where(counts == 2, q.data[second], 0.0)
            out = (q.indices[first].astype(np.int64), q.data[first].astype(float),
                   q.indices[second].astype(np.int64), v2.astype(float))
        return out

    def det(self, jac: sp.spmatrix) -> SignLog:
        fact = factorize(self.reduced(jac))
        return (0.0, -math.inf) if fact is None else fact.det_sign_log()

    def null_vectors(self, jac: sp.spmatrix) -> tuple[Array, Array]:
        """Right and left antisymmetric (near-)null vectors of J, lifted to R^n (unit 2-norm)."""
        red = self.reduced(jac)
        fact = factorize(red)
        if fact is None:  # exactly singular: shift by a rounding-level amount
            shift = 1e-14 * max(1.0, abs(red).max())
            eye = sp.identity(red.shape[0], format="csc") if sp.issparse(red) else np.eye(red.shape[0])
            fact = factorize(red + shift * eye)
        assert fact is not None
        right = np.asarray(self.q @ inverse_iteration(fact))
        left = np.asarray(self.q @ inverse_iteration(fact, trans="T"))
        return right / np.linalg.norm(right), left / np.linalg.norm(left)


def _probe_signed_permutation(symmetry: Any, n: int, seed: int) -> sp.csc_matrix | None:
    """S as a sparse signed permutation, if (S v)_i = s_i v_{pi(i)}; detected from two probes."""
    v = np.arange(1.0, n + 1.0)
    w = np.asarray(symmetry(v), dtype=float)
    idx = np.rint(np.abs(w)).astype(np.int64) - 1
    if np.any(np.abs(np.abs(w) - (idx + 1)) > 1e-9) or np.any(idx < 0) or np.any(idx >= n):
        return None
    if np.unique(idx).size != n:
        return None
    sign = np.sign(w)
    r = np.random.default_rng(seed).standard_normal(n)
    if np.max(np.abs(np.asarray(symmetry(r)) - sign * r[idx])) > 1e-12 * max(1.0, np.max(np.abs(r))):
        return None
    return sp.csc_matrix((sign, (np.arange(n), idx)), shape=(n, n))


def _antisymmetric_basis(s: sp.csc_matrix) -> sp.csc_matrix:
    """Orthonormal basis of {v : S v = -v}.

    For a signed permutation (S e_i = s_j e_j with j = pi(i)) the basis is sparse: e_i for
    fixed points with s_i = -1 and (e_i - s_j e_j)/sqrt(2) for each 2-cycle i < j.  Otherwise
    the range of the projector (I - S)/2 from a dense SVD (small n only).
    """
    n = s.shape[0]
    coo = s.tocoo()
    pi = np.empty(n, dtype=np.int64)
    sg = np.empty(n)
    seen = np.zeros(n, dtype=bool)
    seen[coo.col] = True
    if coo.nnz == n and seen.all() and np.allclose(np.abs(coo.data), 1.0):
        pi[coo.col] = coo.row  # S e_col = data e_row
        sg[coo.col] = coo.data
        i = np.arange(n)
        cols_f = i[(pi == i) & (sg < 0)]
        cols_p = i[pi > i]
        m_f, m_p = cols_f.size, cols_p.size
        # CSC directly (the columns' rows are ascending: i < pi(i) in a pair); the same
        # matrix a COO (rows, cols, vals) assembly gives, without its conversion (~0.2 ms, paid
        # on every grid of an adaptive run)
        r = 1 / math.sqrt(2)
        indptr = np.concatenate([np.arange(m_f + 1), m_f + 2 * np.arange(1, m_p + 1)])
        indices = np.concatenate([cols_f, np.column_stack([cols_p, pi[cols_p]]).ravel()])
        data = np.concatenate([np.ones(m_f), np.column_stack([np.full(m_p, r), -sg[cols_p] * r]).ravel()])
        return sp.csc_matrix((data, indices.astype(np.int32), indptr.astype(np.int32)), shape=(n, m_f + m_p))
    proj = 0.5 * (np.eye(n) - s.toarray())
    u, sv, _ = np.linalg.svd(proj)
    return sp.csc_matrix(u[:, sv > 0.5])
