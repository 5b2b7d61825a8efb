"""Linear algebra of continuation: bordered matrices, one LU reused, determinant signs.

Every Newton iteration of the corrector factorizes the bordered (n+1) x (n+1) matrix

    A = [[J,   F_p],
         [c^T, c_p]]

once; the same factorization then gives the Newton update, the next tangent and the
branch-point test function.  Two back ends behind one interface (:class:`Factorization`):

- dense LAPACK ``getrf`` (partial pivoting, P A = L U) for n + 1 <= :data:`DENSE_LIMIT`.  The
  systems of continuation are small, and there the cost of a sparse LU is almost all call
  overhead and fill-in: on gPCF (Chebyshev blocks are dense, and the bordering row/column and
  the mass constraint are dense) dgetrf beats SuperLU 5x at n = 76, 6x at n = 148 and still
  1.3x at n = 772 (FD4, N = 256), CPU time, one BLAS thread;
- SuperLU (``scipy.sparse.linalg.splu``, P_r A P_c = L U) above it.

With unit-diagonal L the determinant's sign is

    sign det A = sign(prod diag U) * parity(P_r) [* parity(P_c)],

and log|det A| = sum log|U_ii| (the magnitude would over/underflow for large n).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import lapack
from scipy.sparse.csgraph import connected_components

from contin.problem import Array

_getrf, _getrs = lapack.dgetrf, lapack.dgetrs
# ufunc reductions called directly (ndarray.all & co. add a Python wrapper: at continuation
# sizes the wrapper costs more than the reduction)
_ALL, _SUM = np.logical_and.reduce, np.add.reduce


def as_csc(a: object) -> sp.csc_matrix:
    """``a`` as CSC (no copy when it already is one); dense input is accepted for tiny problems."""
    if sp.issparse(a):
        return a.tocsc()  # type: ignore[no-any-return,union-attr]
    return sp.csc_matrix(np.atleast_2d(np.asarray(a, dtype=float)))


def permutation_parity(perm: Array) -> int:
    """+1 for an even permutation, -1 for an odd one.

    parity = (-1)^(n - number of cycles); the cycles are the connected components of the graph
    i -> perm[i], counted in C by ``scipy.sparse.csgraph`` (no Python loop over n).
    """
    perm = np.asarray(perm, dtype=np.int64)
    n = perm.size
    if n == 0:
        return 1
    graph = sp.csr_matrix((np.ones(n), perm, np.arange(n + 1)), shape=(n, n))
    cycles, _ = connected_components(graph, directed=True, connection="weak")
    return 1 if (n - cycles) % 2 == 0 else -1


#: Largest matrix order factorized densely (LAPACK getrf) instead of by SuperLU.
DENSE_LIMIT = 800


class Factorization:
    """An LU factorization of a square matrix: solves, determinant sign and log-magnitude."""

    _det: tuple[float, float] | None = None

    @property
    def size(self) -> int:
        raise NotImplementedError

    def solve(self, rhs: Array, trans: str = "N") -> Array:
        """Solve A x = rhs (``trans='T'``: A^T x = rhs)."""
        raise NotImplementedError

    def det_sign_log(self) -> tuple[float, float]:
        """(sign det A, log |det A|) from the LU factors (see module docstring)."""
        if self._det is None:
            diag, parity = self._diag_parity()
            sign = float(np.prod(np.sign(diag))) * parity
            if _ALL(diag):  # no zero pivot (the dense LU guarantees it): no log(0) warning to silence
                logabs = float(_SUM(np.log(np.abs(diag))))
            else:
                with np.errstate(divide="ignore"):
                    logabs = float(_SUM(np.log(np.abs(diag))))
            self._det = (sign, logabs)
        return self._det

    def _diag_parity(self) -> tuple[Array, int]:
        raise NotImplementedError


class SparseLU(Factorization):
    """SuperLU factors P_r A P_c = L U."""

    def __init__(self, lu: spla.SuperLU) -> None:
        self.lu = lu

    @property
    def size(self) -> int:
        return int(self.lu.shape[0])

    def solve(self, rhs: Array, trans: str = "N") -> Array:
        return np.asarray(self.lu.solve(np.asarray(rhs, dtype=float), trans=trans))

    def _diag_parity(self) -> tuple[Array, int]:
        return self.lu.U.diagonal(), permutation_parity(self.lu.perm_r) * permutation_parity(self.lu.perm_c)


class DenseLU(Factorization):
    """LAPACK getrf factors P A = L U (``piv``: 0-based row interchanges, one per row)."""

    def __init__(self, lu: Array, piv: Array) -> None:
        self.lu = lu
        self.piv = piv

    @property
    def size(self) -> int:
        return int(self.lu.shape[0])

    def solve(self, rhs: Array, trans: str = "N") -> Array:
        x, _ = _getrs(self.lu, self.piv, np.asarray(rhs, dtype=float), trans=0 if trans == "N" else 1)
        return np.asarray(x)

    def _diag_parity(self) -> tuple[Array, int]:
        # Each entry with piv[i] != i is one transposition.
        swaps = int(np.count_nonzero(self.piv != _arange(self.piv.size)))
        return self.lu.diagonal(), -1 if swaps % 2 else 1


_ARANGE = np.arange(DENSE_LIMIT)


def _arange(n: int) -> Array:
    """0, ..., n-1 (a view of a cached range for the dense sizes)."""
    return _ARANGE[:n] if n <= DENSE_LIMIT else np.arange(n)


def factorize(a: object) -> Factorization | None:
    """LU of a square sparse or dense matrix; None if exactly singular (a zero pivot).

    Dense LAPACK for order <= :data:`DENSE_LIMIT` (see module docstring), SuperLU above.
    """
    n = a.shape[0]  # type: ignore[attr-defined]
    if n <= DENSE_LIMIT:
        return _dense_lu(a.toarray() if sp.issparse(a) else np.array(a, dtype=float, order="F"))  # type: ignore[attr-defined]
    try:
        return SparseLU(spla.splu(as_csc(a)))
    except RuntimeError:  # SuperLU: "Factor is exactly singular"
        return None


def _dense_lu(a: Array) -> DenseLU | None:
    """getrf of ``a`` in place; None on an exactly zero pivot (info > 0)."""
    lu, piv, info = _getrf(a, overwrite_a=True)
    if info != 0 or not _ALL(lu.diagonal()):
        return None
    return DenseLU(lu, piv)


def bordered(jac: sp.spmatrix, column: Array, row: Array) -> sp.csc_matrix:
    """[[J, column], [row[:n], row[n]]] as a sparse CSC matrix of size n + 1.

    ``row`` has n + 1 entries (its last entry is the corner).  Assembled directly from J's CSC
    arrays (each column of J gains one entry in row n; the new last column is dense), which
    is several times cheaper than ``scipy.sparse.bmat`` for the small-to-medium n of
    continuation; no dense n x n array is formed.
    """
    j = as_csc(jac)
    n = j.shape[0]
    col = np.asarray(column, dtype=float).ravel()
    r = np.asarray(row, dtype=float).ravel()
    ends = j.indptr[1:]
    indices = np.concatenate([np.insert(j.indices, ends, n), np.arange(n + 1)])
    data = np.concatenate([np.insert(j.data, ends, r[:n]), col, r[n:]])
    indptr = np.concatenate([j.indptr + np.arange(n + 1), [j.indptr[-1] + 2 * n + 1]])
    return sp.csc_matrix((data, indices.astype(np.int32 if indices.size < 2**31 else np.int64), indptr), shape=(n + 1, n + 1))


def bordered_dense(jac: object, column: Array, row: Array) -> Array:
    """[[J, column], [row[:n], row[n]]] as a dense (Fortran-ordered, for getrf) array."""
    n = jac.shape[0]  # type: ignore[attr-defined]
    a = np.empty((n + 1, n + 1), order="F")
    a[:n, :n] = jac.toarray() if sp.issparse(jac) else jac  # type: ignore[attr-defined]
    a[:n, n] = column
    a[n, :] = row
    return a


def factorize_bordered(jac: object, column: Array, row: Array) -> Factorization | None:
    """:func:`factorize` of the bordered matrix of :func:`bordered`, built densely when small.

    ``jac`` itself is not modified (the dense path factorizes a bordered copy).
    """
    n = jac.shape[0]  # type: ignore[attr-defined]
    if n + 1 <= DENSE_LIMIT:
        return _dense_lu(bordered_dense(jac, column, row))
    return factorize(bordered(jac, column, row))


def inf_norm(a: object) -> float:
    """||A||_inf = max row sum of |a_ij| for a sparse or dense matrix (0 for an empty one)."""
    if sp.issparse(a):
        m = sp.csr_matrix(a) if not isinstance(a, sp.csr_matrix) else a
        if m.nnz == 0:
            return 0.0
        if np.all(np.diff(m.indptr)):  # reduceat needs every row non-empty
            return float(np.add.reduceat(np.abs(m.data), m.indptr[:-1]).max())
        return float(np.asarray(abs(m).sum(axis=1)).max())
    d = np.asarray(a)
    return float(np.abs(d).sum(axis=1).max()) if d.size else 0.0


def inverse_iteration(fact: Factorization, *, trans: str = "N", iterations: int = 3, seed: int = 0) -> Array:
    """Unit vector of the (near-)null space of a nearly singular factorized matrix.

    Inverse iteration x <- A^{-1} x / |A^{-1} x|: the component along the smallest singular
    direction grows by sigma_2 / sigma_1 per sweep, so a few sweeps suffice next to a simple
    singular point.
    """
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(fact.size)
    x /= np.linalg.norm(x)
    for _ in range(iterations):
        x = fact.solve(x, trans=trans)
        norm = np.linalg.norm(x)
        if not math.isfinite(norm) or norm == 0.0:
            break
        x /= norm
    return x
