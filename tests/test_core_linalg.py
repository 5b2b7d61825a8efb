"""LU (dense and sparse back ends) determinant signs, permutation parity, bordered assembly, step-size law."""

import itertools
import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from contin.extended import ExtendedSystem
from contin.linalg import bordered, bordered_dense, factorize, factorize_bordered, inf_norm, inverse_iteration, permutation_parity
from contin.options import StepOptions
from contin.stepsize import next_step
from problems.demo import ImperfectPitchfork


def inversion_parity(perm):
    inv = sum(1 for i, j in itertools.combinations(range(len(perm)), 2) if perm[i] > perm[j])
    return -1 if inv % 2 else 1


def test_permutation_parity_matches_inversion_count():
    rng = np.random.default_rng(1)
    for n in (1, 2, 3, 5, 8, 13):
        for _ in range(20):
            perm = rng.permutation(n)
            assert permutation_parity(perm) == inversion_parity(list(perm))


@pytest.fixture(params=["dense", "sparse"])
def backend(request, monkeypatch):
    """Both LU back ends of contin.linalg.factorize (dense getrf below DENSE_LIMIT, SuperLU above)."""
    import contin.linalg

    if request.param == "sparse":
        monkeypatch.setattr(contin.linalg, "DENSE_LIMIT", 0)
    return request.param


@pytest.mark.parametrize("seed", range(25))
def test_lu_determinant_sign_equals_numpy(seed, backend):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 9))
    # A sparse matrix whose pivoting needs both row and column permutations: a random signed
    # permutation plus a sparse perturbation.
    perm = rng.permutation(n)
    base = np.zeros((n, n))
    base[np.arange(n), perm] = rng.choice([-1.0, 1.0], n) * rng.uniform(0.5, 2.0, n)
    a = base + sp.random(n, n, density=0.3, random_state=seed).toarray() * rng.choice([-1, 1])
    fact = factorize(sp.csr_matrix(a))
    sign, logabs = fact.det_sign_log()
    ref_sign, ref_log = np.linalg.slogdet(a)
    assert sign == ref_sign
    assert logabs == pytest.approx(ref_log, abs=1e-10)


def test_singular_matrix_gives_none_and_null_vector_by_inverse_iteration(backend):
    a = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    assert factorize(a) is None
    near = factorize(sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0 + 1e-9]])))
    v = inverse_iteration(near)
    assert abs(abs(v @ np.array([2.0, -1.0]) / np.sqrt(5)) - 1) < 1e-8


def test_bordered_assembly_equals_dense_block_matrix():
    j = sp.random(7, 7, density=0.3, random_state=3, format="csr")
    col, row = np.arange(7.0) + 1, np.arange(8.0) - 3
    dense = np.block([[j.toarray(), col[:, None]], [row[None, :]]])
    assert np.array_equal(bordered(j, col, row).toarray(), dense)
    assert np.array_equal(bordered(j.tocsc(), col, row).toarray(), dense)
    assert np.array_equal(bordered_dense(j, col, row), dense)
    assert np.array_equal(bordered_dense(j.toarray(), col, row), dense)


def test_bordered_factorization_solves_and_matches_determinant(backend):
    rng = np.random.default_rng(7)
    j = sp.random(9, 9, density=0.4, random_state=5, format="csr") + sp.eye(9)
    col, row = rng.standard_normal(9), rng.standard_normal(10)
    dense = np.block([[j.toarray(), col[:, None]], [row[None, :]]])
    fact = factorize_bordered(j, col, row)
    b = rng.standard_normal(10)
    assert np.allclose(dense @ fact.solve(b), b, atol=1e-12)
    assert np.allclose(dense.T @ fact.solve(b, trans="T"), b, atol=1e-12)
    sign, logabs = fact.det_sign_log()
    assert (sign, logabs) == pytest.approx(np.linalg.slogdet(dense), abs=1e-10)


@pytest.mark.parametrize("n", [5, 40, 200])
def test_bordered_factorization_in_place_equals_a_fresh_one_and_scipy(n):
    # the corrector assembles each iteration's bordered matrix into the previous iteration's
    # buffer and factorizes it there: the same LU bit for bit as into a fresh array, scipy's
    # lu_factor of the same matrix, and the determinant sign of numpy's slogdet
    from scipy.linalg import lu_factor, lu_solve

    rng = np.random.default_rng(n)
    buffer = None
    for _ in range(3):  # the buffer reused across "iterations" with different matrices
        j = rng.standard_normal((n, n))
        col, row = rng.standard_normal(n), rng.standard_normal(n + 1)
        dense = np.block([[j, col[:, None]], [row[None, :]]])
        j_before = j.copy()
        fresh = factorize_bordered(j, col, row)
        fact = factorize_bordered(j, col, row, buffer)
        if buffer is not None:
            assert fact.lu is buffer  # assembled and factorized in place
        buffer = fact.lu
        lu, piv = lu_factor(dense)
        assert np.array_equal(fact.lu, fresh.lu) and np.array_equal(fact.piv, fresh.piv)
        assert np.array_equal(fact.lu, lu) and np.array_equal(fact.piv, piv)
        b = rng.standard_normal(n + 1)
        assert np.array_equal(fact.solve(b), lu_solve((lu, piv), b))
        assert np.linalg.norm(dense @ fact.solve(b) - b) < 1e-10 * np.linalg.norm(dense, 1) * np.linalg.norm(fact.solve(b))
        sign, logabs = fact.det_sign_log()
        ref_sign, ref_log = np.linalg.slogdet(dense)
        assert sign == ref_sign and logabs == pytest.approx(ref_log, rel=1e-12)
        assert np.array_equal(j, j_before)  # J itself untouched
    # a buffer of the wrong shape is not used
    other = factorize_bordered(j, col, row, np.empty((n, n), order="F"))
    assert np.array_equal(other.lu, lu)


def test_inf_norm_sparse_and_dense():
    a = np.array([[1.0, -2.0, 0.0], [0.0, 0.0, 0.0], [-4.0, 0.5, 0.25]])
    assert inf_norm(a) == 4.75
    assert inf_norm(sp.csr_matrix(a)) == 4.75  # an empty row in between
    assert inf_norm(sp.csc_matrix(a)) == 4.75


def test_theta_weighted_row_reproduces_inner_product():
    system = ExtendedSystem(ImperfectPitchfork(), {"lam": 0, "alpha": 0, "beta": 0}, "lam", theta=0.3)
    a, b = np.array([1.0, 2.0]), np.array([3.0, -1.0])
    assert system.dot(a, b) == pytest.approx(3.0 - 0.3 * 2.0)
    assert system.row(a) @ b == pytest.approx(system.dot(a, b))


def test_step_size_law():
    opts = StepOptions(ds=0.1, ds_max=0.5, newton_target=4, grow=1.5, shrink=0.5)
    assert next_step(0.1, 2, opts) == pytest.approx(0.15)  # grow capped at 1.5
    assert next_step(0.1, 4, opts) == pytest.approx(0.1)
    assert next_step(0.1, 5, opts) == pytest.approx(0.08)
    assert next_step(0.1, 12, opts) == pytest.approx(0.05)  # shrink floor 0.5
    assert next_step(0.4, 1, opts) == pytest.approx(0.5)  # ds_max


@pytest.mark.parametrize("n", [7, 10])
def test_antisymmetric_reduction_dense_gather_equals_sparse_product_bitwise(n):
    """Antisymmetric.reduced gathers rows and columns for a signed-permutation S; each entry is
    the same one- or two-term sum as in the sparse product (Q^T J) Q, so the numbers (and the
    determinant and null vectors) are bitwise those of the sparse product."""
    from contin.linalg import as_csc
    from contin.testfunctions import Antisymmetric, _antisymmetric_basis

    rng = np.random.default_rng(n)
    perm = np.arange(n)[::-1].copy()  # a reflection with signs: S e_i = s_i e_perm(i)
    signs = np.ones(n)
    signs[[0, n - 1]] = -1.0  # S S = identity: s_i s_perm(i) = 1
    s = sp.csc_matrix((signs, (perm, np.arange(n))), shape=(n, n))
    anti = Antisymmetric(s, _antisymmetric_basis(s))
    assert anti._pairs is not None
    jac = rng.standard_normal((n, n))
    ref = as_csc(anti.q.T @ as_csc(jac) @ anti.q).toarray()
    for j in (jac, sp.csr_matrix(jac)):
        red = anti.reduced(j)
        assert isinstance(red, np.ndarray)
        np.testing.assert_array_equal(red, ref)
    assert anti.det(jac) == factorize(as_csc(ref)).det_sign_log()


@pytest.mark.parametrize("case", ["random", "exactly singular", "zero column", "tiny pivot", "nan"])
def test_dense_lu_equals_scipy_on_random_and_singular_ish_matrices(case):
    # contin's dense LU calls LAPACK getrf/getrs directly (positional arguments, zero pivots by
    # count_nonzero): the same LU, pivots, solves and determinant sign as scipy.linalg
    # lu_factor / lu_solve and numpy's slogdet, and None exactly where a pivot is exactly 0
    from scipy.linalg import lu_factor, lu_solve

    rng = np.random.default_rng(11)
    n = 30
    a = rng.standard_normal((n, n))
    if case == "exactly singular":
        a[7] = 2.0 * a[3]  # rows in exact ratio 2: elimination leaves an exact zero pivot
    elif case == "zero column":
        a[:, 5] = 0.0
    elif case == "tiny pivot":
        a[:, 4] = a[:, 2] + 1e-300 * rng.standard_normal(n)
    elif case == "nan":
        a[3, 3] = np.nan
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's LinAlgWarning on an exactly zero pivot
        lu, piv = lu_factor(a, check_finite=False)
    fact = factorize(a)
    zero_pivot = np.count_nonzero(np.diag(lu)) < n
    assert zero_pivot == (case in ("exactly singular", "zero column"))
    if zero_pivot:
        assert fact is None
        return
    assert np.array_equal(fact.lu, lu, equal_nan=True) and np.array_equal(fact.piv, piv)
    b = rng.standard_normal(n)
    for trans, t in (("N", 0), ("T", 1)):
        assert np.array_equal(fact.solve(b, trans=trans), lu_solve((lu, piv), b, trans=t, check_finite=False),
                              equal_nan=True)
    if case == "nan":
        return
    sign, logabs = fact.det_sign_log()
    ref_sign, ref_log = np.linalg.slogdet(a)
    assert sign == ref_sign and logabs == pytest.approx(ref_log, rel=1e-12)


def test_dense_by_count_never_overrules_the_pattern():
    """dense_by_count(n, nnz) is True only where structure() says 'dense' for every pattern with
    that count: a banded-plus-border matrix with the largest border contin.banded accepts (n = 200:
    16 dense rows and columns, a band of 15 diagonals; a wider one makes its rows count as border
    too) has fewer nonzeros than the bound and is left to the pattern ('banded'); random patterns
    of every fill agree; a full Chebyshev-like matrix is dense by its count."""
    import scipy.sparse as sp

    from contin.linalg import dense_by_count, structure

    n, k = 200, 16
    m = n - k
    rows, cols = [], []
    for i in range(m):
        for j in range(max(0, i - 7), min(m, i + 8)):
            rows.append(i)
            cols.append(j)
    for b in range(m, n):  # the border: full rows and columns
        rows += [b] * n + list(range(n))
        cols += list(range(n)) + [b] * n
    a = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    a.sum_duplicates()
    assert structure(a) == "banded"
    assert not dense_by_count(n, a.nnz)
    rng = np.random.default_rng(1)
    for fill in (0.01, 0.05, 0.1, 0.2, 0.3, 0.5, 0.9):
        for size in (40, 70, 150, 400):
            r = sp.random(size, size, density=fill, random_state=rng, format="csr") + sp.identity(size, format="csr")
            if dense_by_count(size, r.nnz):
                assert structure(r) == "dense", (fill, size)
    assert dense_by_count(326, int(0.65 * 326**2))  # gPCF cheb 64's J
