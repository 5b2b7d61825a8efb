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
- above it the matrix's structure decides (:func:`factorize`): a banded matrix with a few dense
  rows and columns (finite differences: node-by-node bands plus integral constraints, global
  unknowns and the continuation border) by banded LAPACK LU with the border eliminated
  (``contin.banded``: 37x faster than dense LU at fd4 N = 256); a matrix with at least
  :data:`DENSE_FILL` of its entries nonzero (collocation) by dense LAPACK up to
  :data:`DENSE_MAX`; any other sparse matrix by SuperLU (``scipy.sparse.linalg.splu``,
  P_r A P_c = L U).

With unit-diagonal L the determinant's sign is

    sign det A = sign(prod diag U) * parity(P_r) [* parity(P_c)],

and log|det A| = sum log|U_ii| (the magnitude would over/underflow for large n).
"""

from __future__ import annotations

import math

import numpy as np
from typing import TYPE_CHECKING, Any

import scipy.sparse as sp

from contin.banded import BAND_FRACTION, MAX_BORDER, BandedStructure, factorize_banded, structure_of
from contin.lapack import flapack
from contin.problem import Array
from contin.sparsity import as_csc, canonical_csc, permutation_parity

if TYPE_CHECKING:
    import scipy.sparse.linalg as spla

__all__ = ["DENSE_FILL", "DENSE_LIMIT", "DENSE_MAX", "DenseLU", "Factorization", "SparseLU", "as_csc", "bordered",
           "bordered_dense", "factorize", "factorize_bordered", "inf_norm", "inverse_iteration", "permutation_parity",
           "structure"]

_getrf, _getrs = flapack().dgetrf, flapack().dgetrs  # scipy.linalg.lapack's, without scipy.linalg (contin.lapack)
# The ufunc reduction called directly (ndarray.sum adds a Python wrapper: at continuation
# sizes the wrapper costs more than the reduction); pairwise summation, as ndarray.sum
_SUM = np.add.reduce


#: Matrices below this order are factorized densely whatever their structure.
BANDED_MIN = 64
#: Matrices up to this order are factorized densely (LAPACK getrf) unless banded.
DENSE_LIMIT = 800
#: Above DENSE_LIMIT, a sparse matrix with at least this fraction of nonzeros is factorized
#: densely too (collocation matrices: SuperLU on a dense matrix is 6-7x slower than getrf) ...
DENSE_FILL = 0.1
#: ... up to this order (8 bytes n^2: 288 MB at 6000).
DENSE_MAX = 6000


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
            if np.count_nonzero(diag) == diag.size:  # no zero pivot (the dense LU guarantees it): no log(0) warning to silence
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
        # positional arguments: f2py's keyword parsing costs ~1 us of a ~3 us call at small n
        x, _ = _getrs(self.lu, self.piv, np.asarray(rhs, dtype=float), 0 if trans == "N" else 1)
        return x  # type: ignore[no-any-return]

    def _diag_parity(self) -> tuple[Array, int]:
        # Each entry with piv[i] != i is one transposition.
        swaps = int(np.count_nonzero(self.piv != _arange(self.piv.size)))
        return self.lu.diagonal(), -1 if swaps % 2 else 1


_ARANGE = np.arange(DENSE_LIMIT)


def _arange(n: int) -> Array:
    """0, ..., n-1 (a view of a cached range for the dense sizes)."""
    return _ARANGE[:n] if n <= DENSE_LIMIT else np.arange(n)


def structure(a: object) -> str:
    """How :func:`factorize` treats ``a``: 'dense', 'banded' or 'sparse' (module docstring).

    By structure, not size: a sparse matrix that is banded plus a small dense border
    (``contin.banded.analyze``) is 'banded' from :data:`BANDED_MIN` unknowns on, because its
    banded LU is O(n) where a dense one is O(n^3) (fd4 N = 256, n = 773: 0.5 ms against 27 ms);
    other matrices are 'dense' up to :data:`DENSE_LIMIT`, or up to :data:`DENSE_MAX` when at
    least :data:`DENSE_FILL` of their entries are nonzero (collocation), and 'sparse' above.
    """
    return _classify(a)[0]


def _classify(a: object) -> tuple[str, sp.csc_matrix | None, BandedStructure | None]:
    """(:func:`structure` of ``a``, ``a`` as canonical CSC, its banded structure) -- the CSC
    copy and the pattern analysis are done once and handed on to the factorization."""
    n = a.shape[0]  # type: ignore[attr-defined]
    if not sp.issparse(a) or n < BANDED_MIN:
        return "dense", None, None
    csc = canonical_csc(a)
    banded = structure_of(csc)
    if banded is not None:
        return "banded", csc, banded
    if n <= DENSE_LIMIT or (n <= DENSE_MAX and a.nnz >= DENSE_FILL * n * n):  # type: ignore[attr-defined]
        return "dense", csc, None
    return "sparse", csc, None


def dense_factorization(jac: object, bordered: bool = False) -> bool:
    """True when :func:`factorize` (``bordered``: :func:`factorize_bordered`) of a matrix with
    the structure of ``jac`` is a dense LU, i.e. when a problem's ``dense_jacobian`` hook saves
    building a sparse J only to copy it densely (``contin.problem``)."""
    if not sp.issparse(jac):
        return True
    if bordered:  # the border's dense row and column are part of what factorize sees
        jac = bordered_matrix_pattern(jac)
    return structure(jac) == "dense"


#: Orders up to which a problem's dense Jacobian (its ``dense_jacobian`` hook) is counted to decide
#: :func:`dense_by_count` before a sparse J is built for :func:`dense_factorization` (a dense J
#: of this order costs ~0.1 ms; a Chebyshev J on cheb 64, n = 326, is dense by its count).
DENSE_PROBE_MAX = 400


def dense_by_count(n: int, nnz: int) -> bool:
    """True when :func:`factorize` treats *every* n x n matrix with nnz nonzeros as dense,
    whatever their pattern: n below :data:`BANDED_MIN`, or more nonzeros than any
    banded-plus-border structure holds (``contin.banded.analyze``: at most n^2 / BAND_FRACTION in
    the band, 2 MAX_BORDER n in the border) with n within the dense sizes.  False: the pattern
    decides (:func:`structure`).  Lets a problem's dense J, counted, spare building a sparse J
    only to classify it (~0.6 ms for gPCF cheb 64, once per problem and per extended system)."""
    if n < BANDED_MIN:
        return True
    if nnz <= n * n / BAND_FRACTION + 2 * MAX_BORDER * n:
        return False
    return n <= DENSE_LIMIT or (n <= DENSE_MAX and nnz >= DENSE_FILL * n * n)


def counted_dense(dense_jacobian: Any, n: int, bordered: bool = False) -> Array | None:
    """``dense_jacobian()`` (a problem's dense J of order n) where its count decides that it is
    factorized densely (:func:`dense_by_count`; ``bordered``: as the bordered matrix of
    :func:`factorize_bordered`, J with a dense row and column of n + 1 more entries); None where
    n exceeds :data:`DENSE_PROBE_MAX` (not evaluated) or the pattern must decide."""
    if n > DENSE_PROBE_MAX:
        return None
    probe = np.asarray(dense_jacobian(), dtype=float)
    nnz = int(np.count_nonzero(probe))
    dense = dense_by_count(n + 1, nnz + 2 * n + 1) if bordered else dense_by_count(n, nnz)
    return probe if dense else None


def factorize(a: object) -> Factorization | None:
    """LU of a square sparse or dense matrix, chosen by its structure; None if exactly singular.

    Dense LAPACK up to :data:`DENSE_LIMIT` and for dense matrices (at least :data:`DENSE_FILL`
    nonzero) up to :data:`DENSE_MAX`; banded LAPACK with the dense border eliminated
    (``contin.banded``) for banded-plus-border matrices; SuperLU otherwise (also when the
    banded factorization's self-check fails).  All of them give the determinant's sign.
    """
    kind, csc, banded = _classify(a)
    if kind == "dense":
        return _dense_lu(a.toarray(order="F") if sp.issparse(a) else np.array(a, dtype=float, order="F"))  # type: ignore[attr-defined]
    assert csc is not None
    if banded is not None:
        fact = factorize_banded(csc, banded)
        if fact is not None:
            return fact  # type: ignore[return-value]
    import scipy.sparse.linalg as spla  # lazy: off the main path (start-up)

    try:
        return SparseLU(spla.splu(csc))
    except RuntimeError:  # SuperLU: "Factor is exactly singular"
        return None


def _dense_lu(a: Array) -> DenseLU | None:
    """getrf of ``a`` in place; None on an exactly zero pivot (info > 0)."""
    lu, piv, info = _getrf(a, 1)  # overwrite_a (positional: see DenseLU.solve)
    # count_nonzero is a C function; np.logical_and.reduce costs ~2 us more at small n
    if info != 0 or np.count_nonzero(lu.diagonal()) < lu.shape[0]:
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


def bordered_dense(jac: object, column: Array, row: Array, out: Array | None = None) -> Array:
    """[[J, column], [row[:n], row[n]]] as a dense (Fortran-ordered, for getrf) array.

    ``out``: an (n+1) x (n+1) Fortran-ordered array to assemble into (returned), e.g. the
    buffer of an earlier Newton iteration whose factorization is no longer needed.
    """
    n = jac.shape[0]  # type: ignore[attr-defined]
    if out is not None and out.shape == (n + 1, n + 1) and out.flags.f_contiguous and out.dtype == np.float64:
        a = out
    else:
        a = np.empty((n + 1, n + 1), order="F")
    a[:n, :n] = jac if type(jac) is np.ndarray or not sp.issparse(jac) else jac.toarray()  # type: ignore[attr-defined]
    a[:n, n] = column
    a[n, :] = row
    return a


def factorize_bordered(jac: object, column: Array, row: Array, out: Array | None = None) -> Factorization | None:
    """:func:`factorize` of the bordered matrix of :func:`bordered` (built densely when J is dense).

    ``jac`` itself is not modified (the dense path factorizes a bordered copy).  ``out`` (dense
    J only): an (n+1) x (n+1) Fortran-ordered buffer the bordered matrix is assembled into and
    factorized in place (LAPACK overwrite), instead of a new array: a Newton loop passes the
    buffer of its previous iteration, whose factorization it has discarded, and so saves one
    fresh (n+1)^2 allocation per iteration -- on a large grid its page faults cost as much as
    the copy itself (contin.corrector).  Any earlier factorization held in ``out`` is destroyed.
    """
    if type(jac) is np.ndarray or not sp.issparse(jac):  # the type test first: issparse is an ABC check
        return _dense_lu(bordered_dense(jac, column, row, out))
    n = jac.shape[0]  # type: ignore[attr-defined]
    if n + 1 >= BANDED_MIN:
        csc = canonical_csc(jac)
        s = structure_of(csc)
        if s is not None:  # J banded plus border: the continuation border joins J's border
            fact = factorize_banded(csc, s, border=(column, row))
            if fact is not None:
                return fact  # type: ignore[return-value]
    return factorize(bordered(jac, column, row))


def bordered_matrix_pattern(jac: object) -> sp.csc_matrix:
    """[[J, 1], [1^T, 1]]: the pattern :func:`factorize_bordered` factorizes (values of the border: 1)."""
    n = jac.shape[0]  # type: ignore[attr-defined]
    return bordered(jac, np.ones(n), np.ones(n + 1))


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
