"""Sparse linear algebra of continuation: bordered matrices, one LU reused, determinant signs.

Every Newton iteration of the corrector factorizes the bordered (n+1) x (n+1) matrix

    A = [[J,   F_p],
         [c^T, c_p]]

once with SuperLU (``scipy.sparse.linalg.splu``); the same factorization then gives the Newton
update, the next tangent and the branch-point test function.  The determinant's sign follows
from P_r A P_c = L U with unit-diagonal L:

    sign det A = sign(prod diag U) * parity(P_r) * parity(P_c),

and log|det A| = sum log|U_ii| (the magnitude would over/underflow for large n).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from contin.problem import Array


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


@dataclass
class Factorization:
    """A sparse LU of a square matrix with its determinant's sign and log-magnitude."""

    lu: spla.SuperLU
    _det: tuple[float, float] | None = field(default=None, repr=False)

    @property
    def size(self) -> int:
        return int(self.lu.shape[0])

    def solve(self, rhs: Array, trans: str = "N") -> Array:
        """Solve A x = rhs (``trans='T'``: A^T x = rhs)."""
        return np.asarray(self.lu.solve(np.asarray(rhs, dtype=float), trans=trans))

    def det_sign_log(self) -> tuple[float, float]:
        """(sign det A, log |det A|) from the LU factors (see module docstring)."""
        if self._det is None:
            diag = self.lu.U.diagonal()
            sign = float(np.prod(np.sign(diag)))
            sign *= permutation_parity(self.lu.perm_r) * permutation_parity(self.lu.perm_c)
            with np.errstate(divide="ignore"):
                logabs = float(np.sum(np.log(np.abs(diag))))
            self._det = (sign, logabs)
        return self._det


def factorize(a: sp.spmatrix) -> Factorization | None:
    """SuperLU factorization of ``a`` (converted to CSC); None if exactly singular."""
    try:
        return Factorization(spla.splu(as_csc(a)))
    except RuntimeError:  # SuperLU: "Factor is exactly singular"
        return None


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
