"""Small sparse-matrix utilities shared by the factorizations (``contin.linalg``, ``contin.banded``)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

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
    from scipy.sparse.csgraph import connected_components  # here: only the sparse LUs need a parity

    graph = sp.csr_matrix((np.ones(n), perm, np.arange(n + 1)), shape=(n, n))
    cycles, _ = connected_components(graph, directed=True, connection="weak")
    return 1 if (n - cycles) % 2 == 0 else -1


def canonical_csc(a: object) -> sp.csc_matrix:
    """``a`` as CSC with sorted indices and no duplicates (a copy only when needed)."""
    m = as_csc(a)
    if not m.has_canonical_format:
        m = m.copy()
        m.sum_duplicates()
    return m
