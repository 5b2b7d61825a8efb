"""Finite-difference grids of problems/discretization.py: exact weights, exact row sums and parity,
truncation orders of D1, D2 and the quadrature on smooth functions (interior and wall rows
separately), and the global order of a Neumann model BVP.

Numbers: the classical weights (Fornberg 1988, table 1), O(h^p) for p = 2, 4, 6 within +-0.2.
"""

from __future__ import annotations

import math
from fractions import Fraction as Fr

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.discretization import (
    extended_grid,
    fornberg_weights,
    make_grid,
    to_longdouble,
    uniform_cell_weights,
    uniform_stencil,
)

EPS = np.finfo(float).eps


def f(y):
    return np.exp(np.sin(2 * y + 0.3))


def f1(y):
    return 2 * np.cos(2 * y + 0.3) * f(y)


def f2(y):
    return (4 * np.cos(2 * y + 0.3) ** 2 - 4 * np.sin(2 * y + 0.3)) * f(y)


F_INTEGRAL = 1.4431550646209823  # int_{-1/2}^{1/2} exp(sin(2y + 0.3)) dy: Clenshaw-Curtis N = 48, 64, 96 and Gauss-Legendre 30, 60 agree


def slope(Ns, errs):
    return -np.polyfit(np.log(Ns), np.log(errs), 1)[0]


def test_exact_classical_stencils():
    assert uniform_stencil((-1, 0, 1), 2) == (1, -2, 1)
    assert uniform_stencil((-2, -1, 0, 1, 2), 2) == (Fr(-1, 12), Fr(4, 3), Fr(-5, 2), Fr(4, 3), Fr(-1, 12))
    assert uniform_stencil((-3, -2, -1, 0, 1, 2, 3), 1) == (
        Fr(-1, 60), Fr(3, 20), Fr(-3, 4), 0, Fr(3, 4), Fr(-3, 20), Fr(1, 60))
    assert uniform_stencil((0, 1, 2), 1) == (Fr(-3, 2), 2, Fr(-1, 2))
    assert uniform_stencil((0, 1, 2, 3), 2) == (2, -5, 4, -1)
    assert uniform_cell_weights((0, 1)) == (Fr(1, 2), Fr(1, 2))  # trapezoid
    assert uniform_cell_weights((-1, 0, 1, 2)) == (Fr(-1, 24), Fr(13, 24), Fr(13, 24), Fr(-1, 24))
    # the float recursion agrees with the exact one
    c = fornberg_weights(0.0, np.arange(-3.0, 4.0), 2)[:, 2]
    assert np.allclose(c, [float(v) for v in uniform_stencil(tuple(range(-3, 4)), 2)], rtol=0, atol=1e-14)


@pytest.mark.parametrize("method", ["fd2", "fd4", "fd6"])
@pytest.mark.parametrize("N", [16, 100, 256])
def test_entries_rounded_once_rows_sum_to_zero_exact_parity(method, N):
    g = make_grid(method, N)
    flip = np.arange(N, -1, -1)
    for deriv, d in ((1, g.d1.toarray()), (2, g.d2.toarray())):
        i = 3  # a wall-affected row for fd6, interior otherwise: off-diagonals are the rounded exact weights
        p = int(g.order)
        idx = np.arange(0, p + deriv) if i < p // 2 else np.arange(i - p // 2, i + p // 2 + 1)
        exact = uniform_stencil(tuple(int(j) - i for j in idx), deriv)
        for j, c in zip(idx, exact):
            if j != i:
                assert d[i, j] == float(c * Fr(N) ** deriv)
        # image of a constant: one rounding of the diagonal at most
        rowsum = np.array([math.fsum(row) for row in d])
        assert np.all(np.abs(rowsum) <= EPS * np.abs(np.diag(d)))
        # exact parity under y -> -y
        sign = -1.0 if deriv == 1 else 1.0
        assert np.array_equal(d, sign * d[np.ix_(flip, flip)])
    assert np.array_equal(g.y, -g.y[::-1]) and g.y[0] == -0.5 and g.y[-1] == 0.5
    assert np.array_equal(g.weights, g.weights[::-1])
    assert abs(math.fsum(g.weights) - 1.0) <= 2 * N * EPS


def test_wall_row_sums_far_below_the_floating_point_recursion():
    """The old construction (float Fornberg on linspace nodes) left ~30 eps N^2 in the row sum of the
    one-sided fd6 D2 wall row (6.8e-10 at N = 256); now it is one rounding of the diagonal (1.5e-11)."""
    N = 256
    y = np.linspace(-0.5, 0.5, N + 1)
    old = abs(math.fsum(fornberg_weights(y[0], y[:8], 2)[:, 2]))
    new = abs(math.fsum(make_grid("fd6", N).d2.toarray()[0]))
    assert old > 20 * new and new <= EPS * N**2 * 469 / 90  # |D_00| = (469/90) N^2


@pytest.mark.parametrize("method", ["fd2", "fd4", "fd6"])
def test_quadrature_is_exact_for_polynomials_below_the_order(method):
    p = int(method[2:])
    g = make_grid(method, 40)
    for k in range(p):
        exact = ((0.5) ** (k + 1) - (-0.5) ** (k + 1)) / (k + 1)
        assert g.integrate(g.y**k) == pytest.approx(exact, abs=1e-15)


# Grids chosen so that the errors lie well above the rounding of the matrix-vector product
# (~eps N^2 |f| for D2) and the observed pairwise orders are within 0.1 of their limit.
# fd6 beyond N ~ 100 reaches that rounding in D2 (pairwise 5.37 from 96 to 128).
ORDER_GRIDS = {"fd2": (128, 256, 512, 1024), "fd4": (32, 64, 128, 256), "fd6": (48, 64, 96)}


@pytest.mark.parametrize("method", ["fd2", "fd4", "fd6"])
def test_truncation_orders_of_d1_d2_and_weights(method):
    """Interior rows and the quadrature are O(h^p) on a smooth function; the one-sided wall rows are
    at least O(h^p) (fd6 D2 wall rows show 7.5 on this f: the h^6 coefficient is small there)."""
    p = int(method[2:])
    Ns = ORDER_GRIDS[method]
    k = p // 2 + 1  # first row with a centred stencil for both D1 and D2
    err = {name: [] for name in ("d1 interior", "d1 wall", "d2 interior", "d2 wall", "quadrature")}
    for N in Ns:
        g = make_grid(method, N)
        r1, r2 = g.d1 @ f(g.y) - f1(g.y), g.d2 @ f(g.y) - f2(g.y)
        err["d1 interior"].append(np.abs(r1[k:-k]).max())
        err["d1 wall"].append(np.abs(r1[[0, -1]]).max())
        err["d2 interior"].append(np.abs(r2[k:-k]).max())
        err["d2 wall"].append(np.abs(r2[: p // 2]).max())
        err["quadrature"].append(abs(g.integrate(f(g.y)) - F_INTEGRAL))
    for name, e in err.items():
        if "wall" in name:
            assert slope(Ns, e) > p - 0.2, (name, slope(Ns, e))
        else:
            assert abs(slope(Ns, e) - p) < 0.2, (name, slope(Ns, e))
    # one-sided wall rows: same order, larger constant (the source of the odd powers h^(p+1))
    assert err["d1 wall"][-1] > err["d1 interior"][-1]  # ratio 1.3, 4.9, 19 for fd2, fd4, fd6


def neumann_bvp_error(method, N):
    """-(k T')' + T = s on [-1/2, 1/2], T' given at both walls (D1 wall rows); max error and error of int T."""
    g = make_grid(method, N)
    y = g.y
    k, kp = 1 + 0.5 * np.sin(3 * y + 1), 1.5 * np.cos(3 * y + 1)
    T, Tp, Tpp = f(y) + np.cos(5 * y), f1(y) - 5 * np.sin(5 * y), f2(y) - 25 * np.cos(5 * y)
    A = (-sp.diags(k) @ g.d2 - sp.diags(kp) @ g.d1 + sp.eye(N + 1)).tolil()
    rhs = -(k * Tpp + kp * Tp) + T
    A[0], A[N] = g.d1[0].toarray(), g.d1[N].toarray()
    rhs[0], rhs[N] = Tp[0], Tp[N]
    t = spla.spsolve(A.tocsc(), rhs)
    return np.abs(t - T).max(), abs(g.integrate(t - T))


BVP_GRIDS = {"fd2": (128, 256, 512), "fd4": (64, 128, 256), "fd6": (48, 64, 96, 128)}


@pytest.mark.parametrize("method", ["fd2", "fd4", "fd6"])
def test_global_order_of_a_neumann_model_bvp(method):
    """Wall rows with one-sided D1 (flux conditions) keep the global order p of the interior."""
    p = int(method[2:])
    Ns = BVP_GRIDS[method]
    errs = np.array([neumann_bvp_error(method, N) for N in Ns])
    for col in errs.T:
        assert abs(slope(Ns, col) - p) < 0.2, slope(Ns, col)


# ----------------------------------------------------------------------------- extended precision
LD = np.longdouble
LD_EPS = float(np.finfo(LD).eps)


def exact(v) -> Fr:
    return Fr(*v.as_integer_ratio())


@pytest.mark.parametrize("q", [Fr(1, 3), Fr(-49, 18) * 448**2, Fr(2**64 - 1), Fr(2**65 + 3, 7), Fr(1, 10**30),
                               Fr(-180778091922353605829, 1152921504606846976)])
def test_to_longdouble_rounds_to_nearest(q):
    v = to_longdouble(q)
    assert v.dtype == LD
    for w in (np.nextafter(v, LD("inf")), np.nextafter(v, LD("-inf"))):
        assert abs(exact(v) - q) <= abs(exact(w) - q)


@pytest.mark.parametrize("method", ["fd2", "fd4", "fd6"])
@pytest.mark.parametrize("N", [16, 100, 256])
def test_extended_grid_rows_sum_to_exactly_zero_and_match_the_double_grid(method, N):
    """Extended-precision operators: the exact rationals to 2^-63 of the row's sum of |weights|,
    row sums exactly zero (problems.discretization._zero_sum_row), exact parity, and the double
    grid's entries within one double rounding."""
    g, gd = extended_grid(method, N), make_grid(method, N)
    assert g.y.dtype == g.weights.dtype == g.d1.dtype == g.d2.dtype == LD
    flip = np.arange(N, -1, -1)
    for deriv, d, dd in ((1, g.d1.toarray(), gd.d1.toarray()), (2, g.d2.toarray(), gd.d2.toarray())):
        i = 3
        p = int(g.order)
        idx = np.arange(0, p + deriv) if i < p // 2 else np.arange(i - p // 2, i + p // 2 + 1)
        weights = [c * Fr(N) ** deriv for c in uniform_stencil(tuple(int(j) - i for j in idx), deriv)]
        total = sum(abs(c) for c in weights)
        for j, c in zip(idx, weights):  # the diagonal carries the off-diagonals' quantization
            assert abs(exact(d[i, j]) - c) <= (len(idx) if j == i else 1) * total * Fr(2) ** -63
        assert all(sum(exact(v) for v in row) == 0 for row in d)
        sign = -1 if deriv == 1 else 1
        assert np.array_equal(d, sign * d[np.ix_(flip, flip)])
        assert np.all(np.abs(d - dd) <= EPS * np.abs(dd).max(axis=1)[:, None])
    assert all(exact(y) == Fr(2 * j - N, 2 * N) or abs(exact(y) - Fr(2 * j - N, 2 * N)) <= Fr(2) ** -64
               for j, y in enumerate(g.y))
    assert np.array_equal(g.y, -g.y[::-1]) and np.array_equal(g.weights, g.weights[::-1])
    assert abs(float(g.weights.sum() - 1)) <= 2 * N * LD_EPS
    assert np.all(np.abs(g.weights - gd.weights) <= EPS * gd.weights)


def test_extended_chebyshev_grid_matches_the_double_one():
    """Same formulas in longdouble (pi in extended precision): the double grid within its rounding."""
    for N in (16, 64):
        g, gd = extended_grid("cheb", N), make_grid("cheb", N)
        d, flip = g.d1.toarray(), np.arange(N, -1, -1)
        assert np.array_equal(d, -d[np.ix_(flip, flip)]) and np.array_equal(g.y, -g.y[::-1])
        assert float(np.abs(d - gd.d1.toarray()).max()) < 1e3 * EPS * N**2
        assert float(np.abs(g.y - gd.y).max()) < 4 * EPS and abs(float(g.weights.sum() - 1)) < 10 * LD_EPS
        assert float(np.abs(g.d1 @ g.y - 1).max()) < 10 * LD_EPS * N**2  # double: ~EPS N^2


def test_extended_fd6_d2_stays_at_order_6_beyond_the_double_rounding():
    """Interior fd6 D2 on a smooth f: in double the error reaches the rounding (~eps N^2 |f|) beyond
    N ~ 100 (pairwise 5.37 from 96 to 128); in longdouble 6.00, 6.00 over 96, 128, 192 (5.91 to 256)."""
    def ff(y):
        return np.exp(np.sin(2 * y + LD(3) / 10))

    def ff2(y):
        return (4 * np.cos(2 * y + LD(3) / 10) ** 2 - 4 * np.sin(2 * y + LD(3) / 10)) * ff(y)

    Ns = (96, 128, 192)
    errs = []
    for N in Ns:
        g = extended_grid("fd6", N)
        errs.append(float(np.abs((g.d2 @ ff(g.y) - ff2(g.y))[4:-4]).max()))
    pair = [math.log(errs[i] / errs[i + 1]) / math.log(Ns[i + 1] / Ns[i]) for i in range(2)]
    assert all(abs(q - 6) < 0.05 for q in pair), pair
    double = []
    for N in Ns[:2]:
        gd = make_grid("fd6", N)
        double.append(float(np.abs((gd.d2 @ f(gd.y) - f2(gd.y))[4:-4]).max()))
    assert math.log(double[0] / double[1]) / math.log(Ns[1] / Ns[0]) < 5.6  # rounding already shows


# ----------------------------------------------------------------------------- O(n) set-up (issue 14)
def _dense_fd_reference(n: int, deriv: int, order: int):
    """The row-by-row construction of an FD matrix (every row from its own stencil)."""
    import math
    from fractions import Fraction

    from problems.discretization import _fd_stencil, uniform_stencil

    scale = Fraction(n - 1) ** deriv
    out = np.zeros((n, n))
    for i in range(n):
        idx = _fd_stencil(i, n, deriv, order)
        w = [float(c * scale) for c in uniform_stencil(tuple(int(j) - i for j in idx), deriv)]
        diag = int(np.flatnonzero(idx == i)[0])
        w[diag] = -math.fsum(v for k, v in enumerate(w) if k != diag)
        out[i, idx] = w
    return out


def _dense_cells_reference(grid):
    """The dense construction of the FD cell-integration matrix (cell by cell, exact rationals)."""
    from problems.discretization import _fd_cells

    n = grid.size
    cells = np.zeros((n - 1, n))
    for i, (idx, cw) in enumerate(_fd_cells(n, int(grid.order))):
        cells[i, idx] = [float(c) for c in cw]
    cells = 0.5 * (cells + cells[::-1, ::-1])
    delta = grid.weights - cells.sum(axis=0)
    share = np.full(n, 0.5)
    share[[0, -1]] = 1.0
    k = np.arange(n)
    cells[k[1:] - 1, k[1:]] += share[k[1:]] * delta[k[1:]]
    cells[k[:-1], k[:-1]] += share[k[:-1]] * delta[k[:-1]]
    return cells


@pytest.mark.parametrize("method", ["fd2", "fd4", "fd6"])
@pytest.mark.parametrize("N", [13, 16, 40, 65, 257])
def test_fd_setup_is_bitwise_the_row_by_row_construction(method, N):
    from fractions import Fraction

    from problems.discretization import _fd_cells, cell_integration_matrix, make_grid

    grid = make_grid(method, N)
    order = int(method[2:])
    for deriv, op in ((1, grid.d1), (2, grid.d2)):
        assert np.array_equal(op.toarray(), _dense_fd_reference(N + 1, deriv, order))
    w = [Fraction(0)] * (N + 1)
    for idx, cw in _fd_cells(N + 1, order):
        for j, c in zip(idx, cw):
            w[j] += c
    assert np.array_equal(grid.weights, np.array([float(c) for c in w]))
    cells = cell_integration_matrix(grid)
    ref = _dense_cells_reference(grid)
    assert np.array_equal(cells.toarray(), ref)
    assert cells.nnz == np.count_nonzero(ref)


def test_fd_setup_memory_is_linear():
    """fd4 N = 25600: grid, cell integration and the gPCF problem set up in O(N) memory (the dense
    (N, N + 1) cell matrix alone was 5.2 GB)."""
    import tracemalloc

    from problems.couette.model import CouetteProblem
    from problems.discretization import cell_integration_matrix, make_grid

    tracemalloc.start()
    try:
        grid = make_grid("fd4", 25600)
        cell_integration_matrix(grid)
        pb = CouetteProblem("fd4", 25600)
        p = pb.params({"nu": 0.3, "e": 0.8, "H": 10.0})
        x = pb.uniform_state(p)
        obs = pb.observables(x, p)
        assert pb.under_resolved(x, p, 3e-5) is None
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert obs["T_mid"] == pytest.approx(x[2 * 25601 + 12800], rel=1e-14)
    assert peak < 200e6


@pytest.mark.parametrize("method,N", [("cheb", 16), ("cheb", 17), ("fd2", 16), ("fd4", 33), ("fd6", 64)])
def test_interpolation_weights_equal_interpolate(method, N):
    from problems.discretization import make_grid

    grid = make_grid(method, N)
    for y0 in (0.0, 0.123, -0.5, grid.y[3]):
        ref = np.array([grid.interpolate(e, np.array([y0]))[0] for e in np.eye(grid.size)])
        assert np.array_equal(grid.interpolation_weights(y0), ref)


def test_lagrange_matrix_interpolates_polynomials_exactly():
    from problems.couette.resolution import lagrange_matrix
    from problems.discretization import chebyshev_nodes

    nodes = np.linspace(-0.5, 0.5, 41)
    targets = chebyshev_nodes(40)
    m = lagrange_matrix(nodes, targets, 8)
    assert m.nnz == 8 * targets.size
    poly = np.polynomial.Polynomial([0.3, -1.0, 2.0, 0.5, -0.7, 1.1, 0.2, -0.4])  # degree 7: exact
    assert np.max(np.abs(m @ poly(nodes) - poly(targets))) < 1e-13
    assert np.array_equal(chebyshev_nodes(40), make_grid_nodes(40))


def make_grid_nodes(n):
    from problems.discretization import make_grid

    return make_grid("cheb", n).y


def test_dense_chebyshev_grid_limit_is_one_clear_error():
    """FD grids may be large (O(N)); a Chebyshev grid above MAX_CHEB_INTERVALS is refused before
    any dense matrix is allocated (issue 16's --grid 1e9 without the O(N^2) memory)."""
    from problems.discretization import MAX_CHEB_INTERVALS, make_grid

    with pytest.raises(ValueError, match="grid too large: cheb .* at most 4096 intervals"):
        make_grid("cheb", MAX_CHEB_INTERVALS + 1)
    assert make_grid("fd2", 2 * MAX_CHEB_INTERVALS).size == 2 * MAX_CHEB_INTERVALS + 1


def test_cached_chebyshev_interpolation_is_bitwise_the_direct_formula():
    """Grid.interpolate caches the point-dependent barycentric set-up; the values must be
    bitwise those of the formula computed afresh (including a target that hits a node)."""
    g = make_grid("cheb", 24)
    rng = np.random.default_rng(3)
    y_new = np.concatenate([rng.uniform(-0.5, 0.5, 9), [g.y[5], 0.5]])
    n = g.intervals
    wb = (-1.0) ** np.arange(n + 1)
    wb[0] *= 0.5
    wb[-1] *= 0.5
    for f in (rng.standard_normal(n + 1), rng.standard_normal((n + 1, 3))):
        diff = y_new[:, None] - g.y[None, :]
        exact = np.isclose(diff, 0.0, atol=1e-15)
        diff[exact] = 1.0
        terms = wb / diff
        ref = (terms @ f) / terms.sum(axis=1).reshape((-1,) + (1,) * (np.ndim(f) - 1))
        rows, cols = np.nonzero(exact)
        ref[rows] = f[cols]
        for _ in range(2):  # the second call comes from the cache
            assert np.array_equal(g.interpolate(f, y_new), ref)
