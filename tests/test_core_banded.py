"""Linear algebra chosen by structure: banded LU with a dense border (contin.banded), dense
LAPACK for dense matrices at any size, SuperLU otherwise (contin.linalg.structure).

References are numpy's dense solve and slogdet of the same matrices."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from contin import banded, linalg


def field_layout_matrix(n_nodes: int, fields: int = 3, border: int = 2, seed: int = 0, shift: float = 4.0) -> sp.csc_matrix:
    """A finite-difference-like Jacobian in field-by-field layout: every field couples to every
    field through a pentadiagonal block, plus ``border`` dense rows and columns (integral
    constraints, global unknowns, the continuation border)."""
    rng = np.random.default_rng(seed)
    blocks = [[sp.diags([rng.standard_normal(n_nodes - abs(k)) + (shift if k == 0 and a == b else 0.0)
                         for k in (-2, -1, 0, 1, 2)], [-2, -1, 0, 1, 2])
               for b in range(fields)] for a in range(fields)]
    core = sp.bmat(blocks)
    m = core.shape[0]
    cols = rng.standard_normal((m, border))
    rows = rng.standard_normal((border, m))
    corner = rng.standard_normal((border, border))
    return sp.bmat([[core, cols], [rows, corner]]).tocsc()


def test_banded_structure_found_and_small():
    a = field_layout_matrix(200)
    s = banded.analyze(a)
    assert s is not None
    assert (s.n, s.m, s.k) == (602, 600, 2)
    # node-by-node order of three coupled pentadiagonal fields: at most 3 * 3 - 1 = 8 off the diagonal
    assert s.kl <= 8 and s.ku <= 8
    assert linalg.structure(a) == "banded"


@pytest.mark.parametrize("border", [0, 1, 2, 5])
def test_banded_solves_and_determinant(border):
    a = field_layout_matrix(150, border=border, seed=border)
    fact = banded.factorize_banded(a)
    assert fact is not None
    dense = a.toarray()
    rng = np.random.default_rng(1)
    b = rng.standard_normal(a.shape[0])
    x_ref = np.linalg.solve(dense, b)
    assert np.max(np.abs(fact.solve(b) - x_ref)) <= 1e-11 * np.max(np.abs(x_ref))
    xt_ref = np.linalg.solve(dense.T, b)
    assert np.max(np.abs(fact.solve(b, trans="T") - xt_ref)) <= 1e-11 * np.max(np.abs(xt_ref))
    many = rng.standard_normal((a.shape[0], 3))
    assert np.allclose(fact.solve(many), np.linalg.solve(dense, many), rtol=0, atol=1e-11 * np.abs(np.linalg.solve(dense, many)).max())
    sign, logabs = np.linalg.slogdet(dense)
    got_sign, got_log = fact.det_sign_log()
    assert got_sign == sign
    assert got_log == pytest.approx(logabs, rel=1e-12)


def test_determinant_sign_follows_a_crossing_eigenvalue():
    """The BP test function is the sign of det: shifting the matrix through an eigenvalue of the
    banded block flips it exactly where the dense determinant flips."""
    a0 = field_layout_matrix(100, border=2, seed=3, shift=0.0)
    eye = sp.identity(a0.shape[0], format="csc")
    signs_banded, signs_dense = [], []
    for shift in np.linspace(-0.3, 0.3, 13):
        a = (a0 + shift * eye).tocsc()
        fact = linalg.factorize(a)
        assert isinstance(fact, banded.BandedBorderedLU)
        signs_banded.append(fact.det_sign_log()[0])
        signs_dense.append(np.linalg.slogdet(a.toarray())[0])
    assert signs_banded == signs_dense
    assert len(set(signs_dense)) == 2  # the scan does cross eigenvalues


def test_singular_band_block_falls_back_to_superlu():
    """A banded block B that is exactly singular while A is not: block elimination cannot be
    used; factorize still returns a correct LU (SuperLU)."""
    n = 300
    core = sp.diags([np.ones(n - 1), np.r_[np.zeros(1), 2 * np.ones(n - 1)], np.ones(n - 1)], [-1, 0, 1]).tolil()
    core[0, :] = 0.0  # row 0 of B is empty: B singular
    rng = np.random.default_rng(4)
    a = sp.bmat([[core.tocsr(), rng.standard_normal((n, 1))],
                 [rng.standard_normal((1, n)), np.ones((1, 1))]]).tocsc()
    assert banded.structure_of(a) is not None
    assert banded.factorize_banded(a) is None
    fact = linalg.factorize(a)
    assert isinstance(fact, linalg.SparseLU)
    b = np.arange(n + 1, dtype=float)
    assert np.allclose(a @ fact.solve(b), b, atol=1e-10)
    assert fact.det_sign_log()[0] == np.linalg.slogdet(a.toarray())[0]


def test_structure_choice():
    # FD-like: banded as soon as the band is narrow against the order (180 unknowns, band 17)
    assert linalg.structure(field_layout_matrix(60)) == "banded"
    # ... not when the band is as wide as an eighth of the order (dense LU then)
    assert linalg.structure(field_layout_matrix(30)) == "dense"
    # tiny: dense
    assert linalg.structure(field_layout_matrix(5)) == "dense"
    # dense matrix stored sparse, above DENSE_LIMIT: dense LAPACK, not SuperLU
    rng = np.random.default_rng(0)
    big_dense = sp.csc_matrix(rng.standard_normal((900, 900)) + 30 * np.eye(900))
    assert linalg.structure(big_dense) == "dense"
    fact = linalg.factorize(big_dense)
    assert isinstance(fact, linalg.DenseLU)
    # random sparse without band structure above DENSE_LIMIT: SuperLU
    rnd = (sp.random(2000, 2000, density=2e-3, random_state=1) + 10 * sp.identity(2000)).tocsc()
    assert linalg.structure(rnd) == "sparse"
    assert isinstance(linalg.factorize(rnd), linalg.SparseLU)
    # a dense ndarray is always factorized densely
    assert linalg.structure(np.eye(3)) == "dense"


def test_dense_factorization_decides_the_dense_jacobian_hook():
    """Where J is banded, a problem's dense_jacobian hook is not used (it would force an O(n^3) LU)."""
    assert not linalg.dense_factorization(field_layout_matrix(100, border=1), bordered=True)
    assert linalg.dense_factorization(sp.csc_matrix(np.random.default_rng(0).standard_normal((50, 50))), bordered=True)


def test_bordered_factorization_banded_matches_dense():
    j = field_layout_matrix(120, border=1, seed=7)
    n = j.shape[0]
    rng = np.random.default_rng(2)
    column, row = rng.standard_normal(n), rng.standard_normal(n + 1)
    fact = linalg.factorize_bordered(j, column, row)
    assert isinstance(fact, banded.BandedBorderedLU)
    dense = linalg.bordered_dense(j.toarray(), column, row)
    b = rng.standard_normal(n + 1)
    assert np.allclose(fact.solve(b), np.linalg.solve(dense, b), rtol=0, atol=1e-11 * np.abs(np.linalg.solve(dense, b)).max())
    assert fact.det_sign_log()[0] == np.linalg.slogdet(dense)[0]


def test_banded_lu_cost_is_linear():
    """Structural, not timed: the band array of the factorization grows linearly with n."""
    small = banded.structure_of(field_layout_matrix(200))
    large = banded.structure_of(field_layout_matrix(4000))
    assert small is not None and large is not None
    assert (large.kl, large.ku) == (small.kl, small.ku)
    assert large.ldab * large.m == pytest.approx(20 * small.ldab * small.m, rel=0.01)
