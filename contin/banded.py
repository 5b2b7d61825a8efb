"""Banded LU with a dense border, for the sparse matrices of finite-difference discretizations.

A finite-difference Jacobian is banded once its unknowns are ordered node by node, except for
a few dense rows and columns: integral constraints (a mass constraint), global unknowns (a
pressure), and the border of pseudo-arclength continuation ([J, F_p; c^T]).  Permuted,

    P_r A P_c = [[B, C],
                 [R, D]]      B: (m - k) x (m - k) banded, C, R: k dense columns / rows, D: k x k,

and factorized by block elimination (Govaerts, *Numerical Methods for Bifurcations of
Dynamical Equilibria*, SIAM 2000, ch. 3):

    B = P L U         LAPACK gbtrf, partial pivoting, O(m kl (kl + ku)) flops
    S = D - R B^-1 C  Schur complement (k banded solves), dense getrf

    det A = parity(P_r) parity(P_c) det B det S.

The banded order of B is the reverse Cuthill-McKee ordering of its symmetrized pattern
(``scipy.sparse.csgraph.reverse_cuthill_mckee``), which recovers the node-by-node order of a
field-by-field layout without the problem having to declare it.  Block elimination is unstable
when B alone is ill conditioned although A is not (Govaerts, section 3.4), so every solve is
followed by one step of iterative refinement against A itself (the "BEM" variant), and the
factorization checks itself once on a random right-hand side: if that solve does not reach
:data:`CHECK_TOL`, :func:`factorize_banded` returns None and the caller falls back to SuperLU.

The analysis (border, ordering, bandwidths, where each nonzero of A goes) depends only on the
sparsity pattern; it is cached per pattern, so a Newton loop pays it once.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from contin.lapack import flapack
from contin.problem import Array
from contin.sparsity import canonical_csc, permutation_parity

_lapack = flapack()  # scipy.linalg.lapack's routines, without importing scipy.linalg (contin.lapack)
_gbtrf, _gbtrs = _lapack.dgbtrf, _lapack.dgbtrs
_getrf, _getrs = _lapack.dgetrf, _lapack.dgetrs

#: Largest border (dense rows = dense columns) eliminated by the Schur complement.
MAX_BORDER = 16
#: A matrix is treated as banded when, after ordering, kl + ku + 1 <= m / BAND_FRACTION.
BAND_FRACTION = 8
#: Backward error ||b - A x|| / (||A|| ||x|| + ||b||) (inf-norms) a checked solve must reach,
#: else the caller falls back to SuperLU.  A backward-stable solve gives a small multiple of eps.
CHECK_TOL = 1e-12
#: Patterns whose analysis is cached (a run has one or two: J and the bordered matrix).
_CACHE_SIZE = 8


def _dense_cut(n: int) -> int:
    """Rows / columns with more nonzeros than this are border (dense), not band."""
    return max(32, n // 32)


@dataclass(frozen=True)
class BandedStructure:
    """Where each nonzero of a CSC matrix with this pattern goes (see module docstring)."""

    n: int
    m: int  # order of the banded block B
    kl: int
    ku: int
    row_order: Array  # original row of permuted row i
    col_order: Array  # original column of permuted column j
    parity: int  # parity(P_r) * parity(P_c)
    band_src: Array  # positions in A.data of the entries of B ...
    band_dst: Array  # ... and their flat positions in the (2 kl + ku + 1, m) Fortran band array
    c_src: Array
    c_dst: Array  # flat positions in C (m, k), Fortran order
    r_src: Array
    r_dst: Array  # flat positions in R (k, m), Fortran order
    d_src: Array
    d_dst: Array  # flat positions in D (k, k), Fortran order

    @property
    def k(self) -> int:
        return self.n - self.m

    @property
    def ldab(self) -> int:
        return 2 * self.kl + self.ku + 1


def analyze(a: sp.csc_matrix) -> BandedStructure | None:
    """The banded-plus-border structure of ``a`` (canonical CSC), or None when it has none:
    unequal numbers of dense rows and columns, a border larger than :data:`MAX_BORDER`, or a
    bandwidth after ordering above 1/:data:`BAND_FRACTION` of the order."""
    n = a.shape[0]
    cut = _dense_cut(n)
    col_count = np.diff(a.indptr)
    row_count = np.bincount(a.indices, minlength=n)
    dense_rows = np.flatnonzero(row_count > cut)
    dense_cols = np.flatnonzero(col_count > cut)
    k = dense_rows.size
    if k != dense_cols.size or k > MAX_BORDER or k >= n:
        return None
    core_rows = np.setdiff1d(np.arange(n), dense_rows, assume_unique=True)
    core_cols = np.setdiff1d(np.arange(n), dense_cols, assume_unique=True)
    m = n - k
    # core row i is paired with core column i; their symmetrized pattern orders both
    rowpos = np.full(n, -1, dtype=np.int64)
    colpos = np.full(n, -1, dtype=np.int64)
    rowpos[core_rows] = np.arange(m)
    colpos[core_cols] = np.arange(m)
    cols_of = np.repeat(np.arange(n), col_count)
    r, c = rowpos[a.indices], colpos[cols_of]
    inner = (r >= 0) & (c >= 0)
    pattern = sp.csr_matrix((np.ones(int(inner.sum())), (r[inner], c[inner])), shape=(m, m))
    pattern = (pattern + pattern.T).tocsr()
    from scipy.sparse.csgraph import reverse_cuthill_mckee  # here: csgraph only where a band is looked for

    perm = np.asarray(reverse_cuthill_mckee(pattern, symmetric_mode=True), dtype=np.int64)
    inv = np.empty(m, dtype=np.int64)
    inv[perm] = np.arange(m)
    # final positions: band rows/cols 0..m-1 in RCM order, then the border in original order
    rpos = np.empty(n, dtype=np.int64)
    cpos = np.empty(n, dtype=np.int64)
    rpos[core_rows] = inv
    cpos[core_cols] = inv
    rpos[dense_rows] = m + np.arange(k)
    cpos[dense_cols] = m + np.arange(k)
    i, j = rpos[a.indices], cpos[cols_of]
    band = (i < m) & (j < m)
    kl = int(max(np.max(i[band] - j[band], initial=0), 0))
    ku = int(max(np.max(j[band] - i[band], initial=0), 0))
    if (kl + ku + 1) * BAND_FRACTION > m:
        return None
    ldab = 2 * kl + ku + 1
    src = np.arange(a.indices.size)
    cb = (i < m) & (j >= m)
    rb = (i >= m) & (j < m)
    db = (i >= m) & (j >= m)
    row_order = np.empty(n, dtype=np.int64)
    col_order = np.empty(n, dtype=np.int64)
    row_order[rpos] = np.arange(n)
    col_order[cpos] = np.arange(n)
    return BandedStructure(
        n=n, m=m, kl=kl, ku=ku, row_order=row_order, col_order=col_order,
        parity=permutation_parity(row_order) * permutation_parity(col_order),
        band_src=src[band], band_dst=(kl + ku + i[band] - j[band]) + j[band] * ldab,
        c_src=src[cb], c_dst=i[cb] + (j[cb] - m) * m,
        r_src=src[rb], r_dst=(i[rb] - m) + j[rb] * k,
        d_src=src[db], d_dst=(i[db] - m) + (j[db] - m) * k,
    )


_cache: dict[tuple, BandedStructure | None] = {}


def structure_of(a: sp.csc_matrix) -> BandedStructure | None:
    """:func:`analyze`, cached by the sparsity pattern (shape, indptr, indices)."""
    key = (a.shape, a.indptr.tobytes(), a.indices.tobytes())
    try:
        return _cache[key]
    except KeyError:
        pass
    found = analyze(a)
    if len(_cache) >= _CACHE_SIZE:
        _cache.pop(next(iter(_cache)))
    _cache[key] = found
    return found


class BandedBorderedLU:
    """Block-elimination LU of a banded-plus-border matrix (module docstring).  Same interface
    as the factorizations of ``contin.linalg`` (solve, size, det_sign_log)."""

    def __init__(self, matvec: Callable[[Array, str], Array], s: BandedStructure, row_order: Array, col_order: Array,
                 lu: Array, ipiv: Array, r: Array, binv_c: Array, schur: tuple[Array, Array] | None) -> None:
        self.matvec = matvec  # x, trans -> A x or A^T x (for refinement and the self-check)
        self.s, self.row_order, self.col_order = s, row_order, col_order
        self.lu, self.ipiv, self.r, self.binv_c, self.schur = lu, ipiv, r, binv_c, schur
        self.refine = True
        self._det: tuple[float, float] | None = None

    @property
    def size(self) -> int:
        return int(self.row_order.size)

    def _band_solve(self, rhs: Array, trans: int) -> Array:
        x, info = _gbtrs(self.lu, self.s.kl, self.s.ku, rhs, self.ipiv, trans=trans)
        return np.asarray(x)

    def _solve_once(self, rhs: Array, trans: str) -> Array:
        m = self.s.m
        k = self.size - m
        b = np.asarray(rhs, dtype=float)
        one = b.ndim == 1
        b2 = b[:, None] if one else b
        out = np.empty_like(b2)
        if trans == "N":
            bp = b2[self.row_order]
            y = self._band_solve(np.asfortranarray(bp[:m]), 0)
            if k:
                x2, _ = _getrs(self.schur[0], self.schur[1], bp[m:] - self.r @ y, trans=0)  # type: ignore[index]
                out[self.col_order] = np.vstack([y - self.binv_c @ x2, x2])
            else:
                out[self.col_order] = y
        else:
            bp = b2[self.col_order]
            if k:
                z2, _ = _getrs(self.schur[0], self.schur[1], bp[m:] - self.binv_c.T @ bp[:m], trans=1)  # type: ignore[index]
                z1 = self._band_solve(np.asfortranarray(bp[:m] - self.r.T @ z2), 1)
                out[self.row_order] = np.vstack([z1, z2])
            else:
                out[self.row_order] = self._band_solve(np.asfortranarray(bp[:m]), 1)
        return out[:, 0] if one else out

    def solve(self, rhs: Array, trans: str = "N") -> Array:
        """Solve A x = rhs (``trans='T'``: A^T x = rhs), with one step of iterative refinement
        where the self-check found block elimination alone not backward stable."""
        x = self._solve_once(rhs, trans)
        if not self.refine:
            return x
        return x + self._solve_once(np.asarray(rhs, dtype=float) - self.matvec(x, trans), trans)

    def det_sign_log(self) -> tuple[float, float]:
        """(sign det A, log |det A|): det B from the band LU's diagonal and row interchanges,
        det S from its dense LU, times the parity of the two orderings."""
        if self._det is None:
            s = self.s
            diag = self.lu[s.kl + s.ku, :]
            swaps = int(np.count_nonzero(self.ipiv != np.arange(s.m)))
            sign = float(np.prod(np.sign(diag))) * (-1 if swaps % 2 else 1) * s.parity
            with np.errstate(divide="ignore"):
                logabs = float(np.sum(np.log(np.abs(diag))))
            if self.schur is not None:
                sd = self.schur[0].diagonal()
                swaps = int(np.count_nonzero(self.schur[1] != np.arange(sd.size)))
                sign *= float(np.prod(np.sign(sd))) * (-1 if swaps % 2 else 1)
                with np.errstate(divide="ignore"):
                    logabs += float(np.sum(np.log(np.abs(sd))))
            self._det = (sign, logabs)
        return self._det


def factorize_banded(a: object, structure: BandedStructure | None = None,
                     border: tuple[Array, Array] | None = None) -> BandedBorderedLU | None:
    """Banded-plus-border LU of the square sparse matrix ``a`` or, with ``border = (column,
    row)``, of the bordered matrix [[a, column], [row[:n], row[n]]] (the continuation border
    joins the dense border of ``a``; its pattern need not be analysed again).  None when ``a``
    has no such structure, B or S is exactly singular, or the checked solve misses
    :data:`CHECK_TOL` even with refinement (the caller then uses a general sparse LU)."""
    a = canonical_csc(a)
    s = structure if structure is not None else structure_of(a)
    if s is None:
        return None
    data = a.data
    ab = np.zeros(s.ldab * s.m)
    ab[s.band_dst] = data[s.band_src]
    ab = ab.reshape((s.ldab, s.m), order="F")
    lu, ipiv, info = _gbtrf(ab, s.kl, s.ku, overwrite_ab=1)
    if info != 0:
        return None
    m, k = s.m, s.k
    c = np.zeros(m * k)
    c[s.c_dst] = data[s.c_src]
    c = c.reshape((m, k), order="F")
    r = np.zeros(k * m)
    r[s.r_dst] = data[s.r_src]
    r = r.reshape((k, m), order="F")
    d = np.zeros(k * k)
    d[s.d_dst] = data[s.d_src]
    d = d.reshape((k, k), order="F")
    row_order, col_order = s.row_order, s.col_order
    if border is None:
        def matvec(x: Array, trans: str) -> Array:
            return a @ x if trans == "N" else a.T @ x  # type: ignore[no-any-return]

        norm_rows = np.bincount(a.indices, weights=np.abs(data), minlength=s.n)
    else:
        column = np.asarray(border[0], dtype=float)
        row = np.asarray(border[1], dtype=float)
        n = s.n
        c = np.column_stack([c, column[row_order[:m]]])
        r = np.vstack([r, row[col_order[:m]]])
        d = np.block([[d, column[row_order[m:]][:, None]], [row[col_order[m:]][None, :], row[n:]]])
        row_order = np.append(row_order, n)  # the border is a fixed point: parity unchanged
        col_order = np.append(col_order, n)

        def matvec(x: Array, trans: str) -> Array:
            if trans == "N":
                return np.append(a @ x[:n] + column * x[n], row @ x)
            return np.append(a.T @ x[:n] + row[:n] * x[n], column @ x[:n] + row[n] * x[n])

        norm_rows = np.append(np.bincount(a.indices, weights=np.abs(data), minlength=n) + np.abs(column),
                              np.abs(row).sum())
    schur: tuple[Array, Array] | None = None
    binv_c = np.zeros((m, 0))
    if c.shape[1]:
        binv_c, _ = _gbtrs(lu, s.kl, s.ku, np.asfortranarray(c), ipiv)
        slu, spiv, sinfo = _getrf(np.asfortranarray(d - r @ binv_c), overwrite_a=1)
        if sinfo != 0:
            return None
        schur = (slu, spiv)
    fact = BandedBorderedLU(matvec, s, row_order, col_order, lu, ipiv, r, binv_c, schur)
    # Self-check on one random right-hand side: block elimination loses backward stability
    # where B alone is ill conditioned; one refinement step then restores it (else: None).
    rhs = np.random.default_rng(12345).standard_normal(fact.size)
    norm_a = float(np.max(norm_rows, initial=0.0))
    for refine in (False, True):
        fact.refine = refine
        x = fact.solve(rhs)
        backward = np.max(np.abs(rhs - matvec(x, "N"))) / (norm_a * np.max(np.abs(x)) + np.max(np.abs(rhs)))
        if math.isfinite(backward) and backward <= CHECK_TOL:
            return fact
    return None
