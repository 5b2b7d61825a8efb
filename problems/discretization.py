"""Wall-normal discretizations on y in [-1/2, 1/2]: Chebyshev collocation and finite differences.

A :class:`Grid` carries nodes, first and second derivative matrices (scipy.sparse CSR),
quadrature weights of matching order and an interpolator onto other points.

- ``cheb``: Chebyshev-Gauss-Lobatto points, the differentiation matrix of Trefethen,
  *Spectral Methods in MATLAB* (SIAM 2000), program ``cheb``; Clenshaw-Curtis weights
  (Trefethen, ``clencurt``).  Spectral (exponential) convergence for smooth solutions.
- ``fd2``, ``fd4``, ``fd6``: uniform grid, Fornberg weights (B. Fornberg, "Generation of
  finite difference formulas on arbitrarily spaced grids", Math. Comp. 51 (1988) 699),
  centred stencils in the interior and one-sided stencils of the same order near the walls;
  banded sparse matrices.  Quadrature: cell-wise integrals of local interpolants of the
  same order.  Weights are computed exactly in rational arithmetic and rounded once, and
  each derivative row sums to zero up to one rounding of its diagonal: floating-point
  Fornberg weights on rounded nodes carried ~30 eps N^2 of noise in the D2 row sums, which
  set a rounding floor (~3e-10 in H_1^c for fd6) above the truncation error on fine grids.

Truncation orders (measured in tests/test_discretization.py): interior rows O(h^p), the
one-sided wall rows O(h^p) with a larger constant, quadrature O(h^p); a Neumann model BVP
converges globally at O(h^p).  The one-sided closures make the global error expansion
contain every power h^p, h^(p+1), ... (not only even ones), which matters for quantities
whose h^p boundary term vanishes (see tests/test_couette_scenes.py, H_1^c orders).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import cache, lru_cache

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

METHODS = ("cheb", "fd2", "fd4", "fd6")

#: Smallest number of intervals N accepted by each method.
MIN_INTERVALS = {"cheb": 4, "fd2": 4, "fd4": 8, "fd6": 12}
#: Chebyshev grids are dense (N + 1)^2 matrices (several per grid, and 5N-unknown eigenproblems)
MAX_CHEB_INTERVALS = 4096


def _fornberg(z, x, m: int) -> list[list]:
    """Fornberg's recursion on any field (float or Fraction): c[j][k] for derivative k at z."""
    n = len(x)
    zero = z - z
    c = [[zero] * (m + 1) for _ in range(n)]
    c1 = zero + 1
    c4 = x[0] - z
    c[0][0] = zero + 1
    for i in range(1, n):
        mn = min(i, m)
        c2 = zero + 1
        c5 = c4
        c4 = x[i] - z
        for j in range(i):
            c3 = x[i] - x[j]
            c2 = c2 * c3
            if j == i - 1:
                for k in range(mn, 0, -1):
                    c[i][k] = c1 * (k * c[i - 1][k - 1] - c5 * c[i - 1][k]) / c2
                c[i][0] = -c1 * c5 * c[i - 1][0] / c2
            for k in range(mn, 0, -1):
                c[j][k] = (c4 * c[j][k] - k * c[j][k - 1]) / c3
            c[j][0] = c4 * c[j][0] / c3
        c1 = c2
    return c


def fornberg_weights(z: float, x: NDArray[np.float64], m: int) -> NDArray[np.float64]:
    """Finite-difference weights at z for derivatives 0..m on nodes x (Fornberg 1988).

    Returns an array c of shape (len(x), m + 1) with f^(k)(z) ~ sum_j c[j, k] f(x_j).
    Floating point; the uniform-grid matrices use :func:`uniform_stencil` (exact) instead.
    """
    return np.array(_fornberg(float(z), [float(v) for v in x], m), dtype=float).reshape(len(x), m + 1)


@cache
def uniform_stencil(offsets: tuple[int, ...], deriv: int) -> tuple[Fraction, ...]:
    """Exact weights of the ``deriv``-th derivative at 0 on the integer nodes ``offsets`` (h = 1).

    Fornberg's recursion in rational arithmetic: the weights on a uniform grid of spacing h are
    these numbers times h^-deriv, so the matrices get correctly rounded entries instead of the
    O(N^deriv * eps * stencil width) noise of the floating-point recursion on rounded nodes.
    """
    c = _fornberg(Fraction(0), [Fraction(o) for o in offsets], deriv)
    return tuple(row[deriv] for row in c)


@cache
def uniform_cell_weights(offsets: tuple[int, ...]) -> tuple[Fraction, ...]:
    """Exact integrals over [0, 1] of the Lagrange basis polynomials on the integer nodes ``offsets``."""
    out = []
    for j, oj in enumerate(offsets):
        poly = [Fraction(1)]  # coefficients of prod_(k != j) (s - o_k) / (o_j - o_k), ascending powers
        for k, ok in enumerate(offsets):
            if k == j:
                continue
            scale = Fraction(1, oj - ok)
            nxt = [Fraction(0)] * (len(poly) + 1)
            for n, a in enumerate(poly):
                nxt[n + 1] += a * scale
                nxt[n] -= a * ok * scale
            poly = nxt
        out.append(sum(a / (n + 1) for n, a in enumerate(poly)))
    return tuple(out)


def _fd_stencil(i: int, n: int, deriv: int, order: int) -> NDArray[np.int64]:
    """Node indices of row i: the centred order + 1 points, or at a wall the first/last
    order + deriv points (the fewest that keep the order, see :func:`_fd_matrix`)."""
    half = order // 2
    if half <= i <= n - 1 - half:
        return np.arange(i - half, i + half + 1)
    edge = order + deriv
    return np.arange(0, edge) if i < half else np.arange(n - edge, n)


def _fd_matrix(n: int, deriv: int, order: int) -> sp.csr_matrix:
    """Banded matrix of the ``deriv``-th derivative on the uniform grid of n nodes, O(h^order).

    Interior rows use the centred (order + 1)-point stencil; rows too close to a wall use a
    one-sided stencil of order + deriv points (the fewest that keep the order), mirrored at
    the two walls.  The weights are exact rationals times (n - 1)^deriv, correctly rounded
    (:func:`uniform_stencil`), hence exactly odd (deriv = 1) or even (deriv = 2) under
    y -> -y; the diagonal is then set to minus the exactly summed off-diagonal entries, so
    each row sum (the image of a constant, 0 in exact arithmetic) is one rounding of the
    diagonal, ~eps |D_ii|, instead of ~eps * stencil width * max |D_ij|.

    O(n): the interior rows all hold the same numbers, computed once.
    """
    scale = Fraction(n - 1) ** deriv
    half = order // 2

    def row(i: int) -> tuple[NDArray[np.int64], list[float]]:
        idx = _fd_stencil(i, n, deriv, order)
        w = [float(c * scale) for c in uniform_stencil(tuple(int(j) - i for j in idx), deriv)]
        diag = int(np.flatnonzero(idx == i)[0])
        w[diag] = -math.fsum(v for k, v in enumerate(w) if k != diag)
        return idx, w

    walls = [i for i in range(n) if not half <= i <= n - 1 - half]
    interior = np.arange(half, n - half)
    parts_r, parts_c, parts_v = [], [], []
    for i in walls:
        idx, w = row(i)
        parts_r.append(np.full(len(idx), i))
        parts_c.append(idx)
        parts_v.append(np.array(w))
    if interior.size:
        idx, w = row(int(interior[0]))
        offsets = idx - interior[0]
        parts_r.append(np.repeat(interior, len(offsets)))
        parts_c.append((interior[:, None] + offsets[None, :]).ravel())
        parts_v.append(np.tile(np.array(w), interior.size))
    return sp.csr_matrix((np.concatenate(parts_v), (np.concatenate(parts_r), np.concatenate(parts_c))), shape=(n, n))


def _cell_start(i: int, n: int, width: int) -> int:
    return min(max(i - width // 2 + 1, 0), n - width)


def _fd_cells(n: int, order: int) -> list[tuple[NDArray[np.int64], list[Fraction]]]:
    """Per cell [y_i, y_i+1]: the nodes of its local interpolant and their exact weights."""
    width = max(order, 2)
    h = Fraction(1, n - 1)
    out = []
    for i in range(n - 1):
        start = _cell_start(i, n, width)
        idx = np.arange(start, start + width)
        out.append((idx, [h * c for c in uniform_cell_weights(tuple(int(j) - i for j in idx))]))
    return out


def _fd_cell_arrays(n: int, order: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """(cell, node, float weight) of every entry of :func:`_fd_cells`, cell by cell, in O(n):
    cells whose interpolant is centred all carry the same numbers times h."""
    width = max(order, 2)
    h = Fraction(1, n - 1)
    centred = [i for i in range(n - 1) if _cell_start(i, n, width) == i - width // 2 + 1]
    if not centred:
        cells = _fd_cells(n, order)
        rows = np.repeat(np.arange(n - 1), width)
        return rows, np.concatenate([idx for idx, _ in cells]), np.array([float(c) for _, cw in cells for c in cw])
    lo, hi = centred[0], centred[-1]
    rows, cols, vals = [], [], []
    for i in [*range(lo), *range(hi + 1, n - 1)]:
        start = _cell_start(i, n, width)
        idx = np.arange(start, start + width)
        rows.append(np.full(width, i))
        cols.append(idx)
        vals.append(np.array([float(h * c) for c in uniform_cell_weights(tuple(int(j) - i for j in idx))]))
    mid = np.arange(lo, hi + 1)
    offsets = np.arange(width) - width // 2 + 1
    w = np.array([float(h * c) for c in uniform_cell_weights(tuple(int(o) for o in offsets))])
    rows.append(np.repeat(mid, width))
    cols.append((mid[:, None] + offsets[None, :]).ravel())
    vals.append(np.tile(w, mid.size))
    r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    order_ = np.argsort(r, kind="stable")
    return r[order_], c[order_], v[order_]


def interpolatory_weights(y: NDArray[np.float64], order: int) -> NDArray[np.float64]:
    """Quadrature weights from integrating local Lagrange interpolants cell by cell.

    Each cell [y_i, y_i+1] of the uniform grid integrates the polynomial through the
    ``order`` nodes centred on the cell (shifted inside the domain near the walls), exactly
    in rational arithmetic (:func:`uniform_cell_weights`).  The rule is O(h^order), exactly
    symmetric under y -> -y, sums to 1 up to one rounding per weight, and reduces to the
    trapezoid rule for order 2.

    O(n): the exact sum of a node's cell weights depends only on its distance to the nearer
    wall once that exceeds the interpolant's width, so it is computed for the nodes next to
    the walls and for one interior node (on a template grid, in units of h), and rounded once.
    """
    n = len(y)
    width = max(order, 2)
    edge = 2 * width  # nodes this close to a wall see a one-sided interpolant
    if n <= 4 * edge:
        w = [Fraction(0)] * n
        for idx, cw in _fd_cells(n, order):
            for j, c in zip(idx, cw):
                w[j] += c
        return np.array([float(c) for c in w])
    m = 4 * edge + 1  # template grid: sums of the unscaled weights, exact
    sums = [Fraction(0)] * m
    for i in range(m - 1):
        start = _cell_start(i, m, width)
        idx = range(start, start + width)
        for j, c in zip(idx, uniform_cell_weights(tuple(j - i for j in idx))):
            sums[j] += c
    h = Fraction(1, n - 1)
    out = np.full(n, float(h * sums[m // 2]))
    out[:edge] = [float(h * c) for c in sums[:edge]]
    out[n - edge:] = [float(h * c) for c in sums[m - edge:]]
    return out


def chebyshev_nodes(n: int) -> NDArray[np.float64]:
    """The n + 1 Gauss-Lobatto points on [-1/2, 1/2], ascending: ``make_grid("cheb", n).y``
    bitwise, without the O(n^2) differentiation matrices."""
    return np.cos(np.pi * np.arange(n + 1) / n)[::-1] / 2


def chebyshev(n: int, dtype: type = np.float64) -> tuple[NDArray, NDArray, NDArray]:
    """Nodes (ascending on [-1/2, 1/2]), differentiation matrix and Clenshaw-Curtis weights.

    Trefethen (2000), programs ``cheb`` and ``clencurt``, mapped by y = x / 2.  ``dtype``
    ``np.longdouble`` evaluates the same formulas in extended precision (:func:`extended_grid`),
    with pi in extended precision and the nodes as x_j = sin(pi (n - 2j) / (2n)), which is
    exactly odd; double keeps x_j = cos(pi j / n).
    """
    j = np.arange(n + 1)
    if dtype == np.float64:
        pi = np.pi
        x = np.cos(np.pi * j / n)  # descending on [-1, 1]
    else:
        pi = 4 * np.arctan(dtype(1))
        x = np.sin(pi * (n - 2 * j).astype(dtype) / (2 * n))
    one, two = dtype(1), dtype(2)
    c = np.where((j == 0) | (j == n), two, one) * np.where(j % 2 == 0, one, -one)
    dx = x[:, None] - x[None, :]
    d = np.outer(c, 1 / c) / (dx + np.eye(n + 1, dtype=dtype))
    d -= np.diag(d.sum(axis=1))
    # Clenshaw-Curtis
    theta = pi * j.astype(dtype) / n
    w = np.zeros(n + 1, dtype=dtype)
    v = np.ones(n - 1, dtype=dtype)
    inner = np.arange(1, n)
    if n % 2 == 0:
        w[0] = w[n] = 1 / dtype(n**2 - 1)
        for k in range(1, n // 2):
            v -= 2 * np.cos(2 * k * theta[inner]) / dtype(4 * k**2 - 1)
        v -= np.cos(n * theta[inner]) / dtype(n**2 - 1)
    else:
        w[0] = w[n] = 1 / dtype(n**2)
        for k in range(1, (n - 1) // 2 + 1):
            v -= 2 * np.cos(2 * k * theta[inner]) / dtype(4 * k**2 - 1)
    w[inner] = 2 * v / n
    # reverse to ascending order and map to [-1/2, 1/2]
    rev = slice(None, None, -1)
    d = 2 * d[rev, rev]
    # Impose the exact parity D[i, j] = -D[N-i, N-j] that rounding breaks.
    d = (d - d[::-1, ::-1]) / 2
    w = w[rev] / 2
    return x[rev] / 2, d, (w + w[::-1]) / 2


@dataclass(frozen=True, eq=False)
class Grid:
    """A discretization of [-1/2, 1/2].

    Attributes
    ----------
    method : 'cheb', 'fd2', 'fd4' or 'fd6'
    intervals : N; the grid has N + 1 nodes including both walls
    y : (N+1,) ascending nodes, y[0] = -1/2, y[-1] = 1/2, symmetric (y[j] = -y[N-j])
    d1, d2 : (N+1, N+1) CSR first and second derivative matrices
    weights : (N+1,) quadrature weights, sum = 1
    order : nominal order (inf for Chebyshev)
    """

    method: str
    intervals: int
    y: NDArray[np.float64]
    d1: sp.csr_matrix
    d2: sp.csr_matrix
    weights: NDArray[np.float64]
    order: float

    @property
    def size(self) -> int:
        return self.intervals + 1

    def integrate(self, f: NDArray) -> NDArray:
        """Quadrature of nodal values over [-1/2, 1/2] (works on complex input)."""
        return self.weights @ f

    def interpolate(self, f: NDArray[np.float64], y_new: NDArray[np.float64]) -> NDArray[np.float64]:
        """Interpolate nodal values to ``y_new``.

        Chebyshev: barycentric interpolation (Berrut & Trefethen, SIAM Rev. 46, 2004).
        Finite differences: local Lagrange interpolation of the scheme's order.
        ``f`` may have trailing axes (columns interpolated together; e.g. the identity gives the
        interpolation matrix).
        """
        y_new = np.atleast_1d(np.asarray(y_new, dtype=float))
        if self.method == "cheb":
            terms, row_sums, hit_rows, hit_cols = _barycentric_setup(self.y.tobytes(), y_new.tobytes())
            out = (terms @ f) / row_sums.reshape((-1,) + (1,) * (np.ndim(f) - 1))
            out[hit_rows] = f[hit_cols]
            return out
        return _lagrange_setup(self.y.tobytes(), y_new.tobytes(), int(self.order) + 1, self.intervals) @ f

    def interpolation_weights(self, y0: float) -> NDArray[np.float64]:
        """Weights w (n,) with w . f = ``interpolate(f, [y0])[0]`` for every f, in O(n) time and
        memory (the same barycentric or local Lagrange formula as :meth:`interpolate`)."""
        w = np.zeros(self.size)
        if self.method == "cheb":
            n = self.intervals
            diff = y0 - self.y
            exact = np.isclose(diff, 0.0, atol=1e-15)
            if exact.any():
                w[np.argmax(exact)] = 1.0
                return w
            wb = (-1.0) ** np.arange(n + 1)
            wb[0] *= 0.5
            wb[-1] *= 0.5
            terms = wb / diff
            return terms / terms.sum()
        width = int(self.order) + 1
        h = 1.0 / self.intervals
        i = int(np.clip(np.floor((y0 + 0.5) / h), 0, self.intervals))
        start = min(max(i - width // 2 + 1, 0), self.size - width)
        idx = np.arange(start, start + width)
        w[idx] = fornberg_weights(y0, self.y[idx], 0)[:, 0]
        return w

    def reflection(self) -> NDArray[np.int64]:
        """Index permutation j -> N - j, i.e. y -> -y on this symmetric grid."""
        return np.arange(self.intervals, -1, -1)


def chebyshev_coefficients(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """a_0..a_N of the interpolant sum a_k T_k(2y) through values at ascending Gauss-Lobatto nodes
    (along the last axis: a 2-D array transforms its rows together).

    DCT-I: a_k = (2/N) sum_j'' f(x_j) cos(pi j k / N) with x_j = cos(pi j / N) (descending, hence
    the reversal), the first and last terms of the sum and a_0, a_N halved (Trefethen, *Spectral
    Methods in MATLAB*, ch. 8).  The DCT-I is the real FFT of the even extension
    (f_0, ..., f_N, f_{N-1}, ..., f_1): numpy's FFT, because importing scipy.fft (and the
    scipy.special it pulls in) costs a process 0.1-0.3 s for this one transform.
    """
    f = np.asarray(values, dtype=float)
    n = f.shape[-1] - 1
    if f.ndim == 1 or f.flags.c_contiguous:
        # the even extension by one gather (a cached index per N): the adaptive tracer
        # transforms every accepted point, and at small N the reversal, the slices and the
        # concatenation cost more than the FFT.  take, not f[..., idx]: the same values in the
        # same C-ordered layout as the concatenation (a fancy index lays 2-D rows out
        # F-ordered, and row reductions of the coefficients round differently on strided rows)
        even = f.take(_even_extension(n), axis=-1)
    else:  # the concatenation keeps another layout of f (the coefficients' layout with it)
        f = f[..., ::-1]
        even = np.concatenate([f, f[..., -2:0:-1]], axis=-1)
    a = np.fft.rfft(even, axis=-1).real[..., : n + 1] / n
    a[..., 0] *= 0.5
    a[..., -1] *= 0.5
    return a


@lru_cache(maxsize=64)
def _even_extension(n: int) -> NDArray[np.intp]:
    """Indices of (f_N, ..., f_0, f_1, ..., f_{N-1}): the even extension of the reversed nodal
    values f_0..f_N of :func:`chebyshev_coefficients` (read-only)."""
    idx = np.concatenate([np.arange(n, -1, -1), np.arange(1, n)])
    idx.flags.writeable = False
    return idx


def chebyshev_tail(values: NDArray[np.float64], modes: int = 4) -> float:
    """Relative Chebyshev tail max_{k > N - modes} |a_k| / max_k |a_k| of nodal values on a
    Chebyshev grid: the a-posteriori truncation-error estimate of a spectral interpolant (Boyd,
    *Chebyshev and Fourier Spectral Methods*, 2nd ed., sec. 2.12).  0 for a zero vector.  The last
    ``modes`` coefficients (4: both parities of a symmetric or antisymmetric profile count)."""
    a = np.abs(chebyshev_coefficients(values))
    scale = float(np.max(a)) if a.size else 0.0
    return float(np.max(a[-modes:]) / scale) if scale > 0 else 0.0



@lru_cache(maxsize=32)
def _lagrange_setup(y_bytes: bytes, y_new_bytes: bytes, width: int, intervals: int) -> sp.csr_matrix:
    """The sparse matrix of local Lagrange interpolation (``width`` nodes, Fornberg weights) from
    the uniform nodes ``y`` onto ``y_new``, cached per pair of grids: an adaptive run and its
    two-grid checks carry states between the same FD grids again and again (the per-node
    Fornberg loop cost ~60 ms per transfer at N = 512)."""
    y = np.frombuffer(y_bytes, dtype=float)
    y_new = np.frombuffer(y_new_bytes, dtype=float)
    h = 1.0 / intervals
    size = y.size
    rows = np.repeat(np.arange(y_new.size), width)
    cols = np.empty(y_new.size * width, dtype=np.int64)
    vals = np.empty(y_new.size * width)
    for k, yk in enumerate(y_new):
        i = int(np.clip(np.floor((yk + 0.5) / h), 0, intervals))
        start = min(max(i - width // 2 + 1, 0), size - width)
        idx = np.arange(start, start + width)
        cols[k * width:(k + 1) * width] = idx
        vals[k * width:(k + 1) * width] = fornberg_weights(yk, y[idx], 0)[:, 0]
    return sp.csr_matrix((vals, (rows, cols)), shape=(y_new.size, size))


#: Tails at or below this fraction of the largest coefficient are rounding noise: no tail sum.
TAIL_SUM_NOISE = 1e-12


def chebyshev_tail_sum(absc: NDArray[np.float64], modes: int = 4) -> NDArray[np.float64]:
    """Extrapolated sum of the *omitted* Chebyshev coefficients sum_{k > N} |a_k| of each row of
    |a_0..a_N| (``absc``, as from :func:`chebyshev_coefficients`): the suffix-maximum envelope
    E_k = max_{j >= k} |a_j| is fitted by log E_k = c + s k over the upper half of the spectrum
    (least squares) and summed geometrically, E(N) rho / (1 - rho) with rho = e^s (capped at N
    terms).

    Why: the last coefficients (:func:`chebyshev_tail`) are the truncation error only when the
    coefficients fall fast (rho << 1, Boyd, *Chebyshev and Fourier Spectral Methods*, 2nd ed.,
    sec. 2.12).  When they fall slowly -- algebraically, |a_k| ~ k^-p, behind a kink of the
    solution (sec. 2.6: a jump in the q-th derivative gives p = q + 1), or geometrically with
    rho -> 1, behind a complex singularity close to the interval (a steep interior layer) -- the
    omitted sum is ~ |a_N| / (1 - rho) ~ |a_N| N / p, one or two orders above |a_N| (2-D disks:
    measured errors 20-300x the last coefficients at cheb 192-512, docs/disks.md section 9).
    0 for a row whose tail is rounding noise (<= TAIL_SUM_NOISE of its largest coefficient) or
    whose envelope does not fall.
    """
    a = np.atleast_2d(np.asarray(absc, dtype=float))
    if a.shape[-1] - 1 < 2 * modes:
        return np.zeros(a.shape[0])
    return tail_sum_rows(a, modes, a[:, -modes:].max(axis=1), a.max(axis=1))


def tail_sum_rows(a: NDArray[np.float64], modes: int, last: NDArray[np.float64],
                  largest: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`chebyshev_tail_sum` of the rows of the 2-D |a_0..a_N| ``a`` given their largest
    last ``modes`` coefficients ``last`` and their largest coefficients ``largest`` (the
    resolution estimate has both already: ``problems.couette.resolution``)."""
    n = a.shape[-1] - 1
    out = np.zeros(a.shape[0])
    if n < 2 * modes:
        return out
    live = last > TAIL_SUM_NOISE * largest
    if not np.count_nonzero(live):  # every tail is rounding noise: no fit (its rows would all be 0)
        return out
    env = np.maximum.accumulate(a[:, ::-1], axis=1)[:, ::-1]
    logs = np.log(np.maximum(env[:, n // 2:], 1e-300))
    km, km_km, n_from_mean = _envelope_fit(n)
    # logs.mean(axis=1) is this sum divided by the count (numpy's _mean), taken once here
    mean = np.add.reduce(logs, axis=1) / logs.shape[1]
    slope = (logs - mean[:, None]) @ km / km_km
    at_n = np.exp(mean + slope * n_from_mean)
    live &= slope < 0
    slope = np.minimum(slope, -1e-12)  # rows with slope >= 0 are not live
    factor = np.minimum(np.exp(slope) / -np.expm1(slope), float(n))
    out[live] = (at_n * factor)[live]
    return out


@lru_cache(maxsize=64)
def _envelope_fit(n: int) -> tuple[NDArray[np.float64], float, np.float64]:
    """The grid's constants of the envelope fit of :func:`tail_sum_rows`: k - mean(k) over
    k = N/2 .. N (read-only), its squared norm and N - mean(k)."""
    k = np.arange(n // 2, n + 1, dtype=float)
    km = k - k.mean()
    km.flags.writeable = False
    return km, float(km @ km), n - k.mean()


@lru_cache(maxsize=32)
def _barycentric_setup(y_bytes: bytes, y_new_bytes: bytes) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The point-dependent part of :meth:`Grid.interpolate` from the Chebyshev nodes y to y_new:
    terms w_j / (y_k - y_j), their row sums and the rows that hit a node exactly.  Cached because
    an adaptive run maps every stored state onto one reference grid (hundreds of calls with the
    same points, each O(N m) divisions); the arithmetic is the same as computing it per call, so
    results are bitwise unchanged.  Arrays are read-only (shared between calls)."""
    y_new = np.frombuffer(y_new_bytes, dtype=float)
    y = np.frombuffer(y_bytes, dtype=float)
    n = len(y) - 1
    wb = (-1.0) ** np.arange(n + 1)
    wb[0] *= 0.5
    wb[-1] *= 0.5
    diff = y_new[:, None] - y[None, :]
    exact = np.isclose(diff, 0.0, atol=1e-15)
    diff[exact] = 1.0
    terms = wb / diff
    row_sums = terms.sum(axis=1)
    hit_rows, hit_cols = np.nonzero(exact)
    for a in (terms, row_sums, hit_rows, hit_cols):
        a.flags.writeable = False
    return terms, row_sums, hit_rows, hit_cols


@lru_cache(maxsize=64)
def make_grid(method: str, intervals: int) -> Grid:
    """Build (and cache) the grid for ``method`` with ``intervals`` intervals.

    Raises
    ------
    ValueError
        For an unknown method or a grid too small for it.
    """
    if method not in METHODS:
        raise ValueError(f"unknown discretization {method!r}; choose one of {', '.join(METHODS)}")
    if isinstance(intervals, bool) or not isinstance(intervals, int | np.integer):  # 2.5 was "grid too small"
        raise TypeError(f"intervals must be a whole number of grid intervals, got {intervals!r} ({type(intervals).__name__})")
    if intervals < MIN_INTERVALS[method]:
        raise ValueError(f"grid too small: {method} needs at least {MIN_INTERVALS[method]} intervals, got {intervals}")
    if method == "cheb" and intervals > MAX_CHEB_INTERVALS:
        raise ValueError(f"grid too large: cheb has dense N x N differentiation matrices, at most "
                         f"{MAX_CHEB_INTERVALS} intervals, got {intervals} (finite differences are O(N): use fd2/fd4/fd6)")
    if method == "cheb":
        y, d, w = chebyshev(intervals)
        d1 = sp.csr_matrix(d)
        dd = d @ d
        d2 = sp.csr_matrix(0.5 * (dd + dd[::-1, ::-1]))
        return Grid(method, intervals, y, d1, d2, w, float("inf"))
    order = int(method[2:])
    # y_j = (2j - N) / (2N), correctly rounded and exactly antisymmetric.
    y = np.arange(-intervals, intervals + 1, 2, dtype=float) / (2 * intervals)
    d1 = _fd_matrix(intervals + 1, 1, order)
    d2 = _fd_matrix(intervals + 1, 2, order)
    w = interpolatory_weights(y, order)
    return Grid(method, intervals, y, d1, d2, w, float(order))


@lru_cache(maxsize=64)
def cell_integration_matrix(grid: Grid) -> sp.csr_matrix:
    """Matrix C (N x (N+1)) with (C f)_j = integral of the interpolant of f over [y_j, y_j+1].

    ``cheb``: the global Chebyshev interpolant integrated exactly (coefficients from the
    Chebyshev-Vandermonde matrix at the Gauss-Lobatto nodes, antiderivative by
    ``numpy.polynomial.chebyshev.chebint``).  ``fd*``: the same local Lagrange interpolants,
    integrated exactly, as :func:`interpolatory_weights` (banded).

    The rows are symmetrized under y -> -y and corrected by rounding-level amounts so that
    ``C.sum(axis=0) == grid.weights`` (cell integrals add up to the grid's quadrature), hence
    cumulative integrals end exactly at ``grid.integrate``.
    """
    n = grid.size
    y = grid.y
    if grid.method == "cheb":
        cheb = np.polynomial.chebyshev
        x = 2.0 * y
        vander = cheb.chebvander(x, n - 1)
        anti = np.stack([cheb.chebval(x, cheb.chebint(col, lbnd=-1.0)) for col in np.eye(n)], axis=1)
        cumulative = 0.5 * np.linalg.solve(vander.T, anti.T).T  # anti @ inv(vander), dy = dx / 2
        cells = cumulative[1:] - cumulative[:-1]
    else:
        return _fd_cell_integration_matrix(grid)
    cells = 0.5 * (cells + cells[::-1, ::-1])
    # Give each node's rounding discrepancy to the (one or two) cells it bounds: keeps the
    # band and the reflection symmetry.
    delta = grid.weights - cells.sum(axis=0)
    share = np.full(n, 0.5)
    share[[0, -1]] = 1.0
    k = np.arange(n)
    left, right = k[1:], k[:-1]  # node k closes cell k-1 and opens cell k
    cells[left - 1, left] += share[left] * delta[left]
    cells[right, right] += share[right] * delta[right]
    return sp.csr_matrix(cells)


def _fd_cell_integration_matrix(grid: Grid) -> sp.csr_matrix:
    """:func:`cell_integration_matrix` of an FD grid, sparse and O(n): the same entries, the
    same symmetrization and the same rounding corrections as the dense construction (column
    sums accumulated row by row in the same order), without the (N, N + 1) dense array."""
    n = grid.size
    r, c, v = _fd_cell_arrays(n, int(grid.order))
    # 0.5 (C + C reflected): entries of C and of its reflection on the union of the two patterns
    key = np.concatenate([r * n + c, (n - 2 - r) * n + (n - 1 - c)])
    uniq, inv = np.unique(key, return_inverse=True)
    a = np.zeros(uniq.size)
    b = np.zeros(uniq.size)
    a[inv[: r.size]] = v
    b[inv[r.size:]] = v
    vals = 0.5 * (a + b)
    rows, cols = uniq // n, uniq % n  # sorted by row, then column
    # column sums row by row (as numpy sums a dense array over axis 0)
    by_col = np.lexsort((rows, cols))
    counts = np.bincount(cols, minlength=n)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rank = np.arange(uniq.size) - np.repeat(first, counts)
    padded = np.zeros((n, int(counts.max())))
    padded[cols[by_col], rank] = vals[by_col]
    colsum = np.zeros(n)
    for k in range(padded.shape[1]):
        colsum += padded[:, k]
    delta = grid.weights - colsum
    share = np.full(n, 0.5)
    share[[0, -1]] = 1.0
    k = np.arange(n)
    left, right = k[1:], k[:-1]  # node k closes cell k-1 and opens cell k
    pos_left = np.searchsorted(uniq, (left - 1) * n + left)
    pos_right = np.searchsorted(uniq, right * n + right)
    assert np.array_equal(uniq[pos_left], (left - 1) * n + left) and np.array_equal(uniq[pos_right], right * n + right)
    vals[pos_left] += share[left] * delta[left]
    vals[pos_right] += share[right] * delta[right]
    out = sp.csr_matrix((vals, (rows, cols)), shape=(n - 1, n))
    out.eliminate_zeros()
    return out


# ----------------------------------------------------------------------------- extended precision
def to_longdouble(q: Fraction) -> np.longdouble:
    """The rational q correctly rounded to ``np.longdouble`` (x86: 64-bit significand, eps 1.1e-19).

    Integer arithmetic: the 64-bit significand m = round(|q| / 2^e) (half to even), then m 2^e.
    """
    if q == 0:
        return np.longdouble(0)
    a = abs(Fraction(q))
    bits = np.finfo(np.longdouble).nmant + 1  # 64 on x86
    e = a.numerator.bit_length() - a.denominator.bit_length() - bits
    while a / Fraction(2) ** e >= 2**bits:
        e += 1
    while a / Fraction(2) ** e < 2 ** (bits - 1):
        e -= 1
    m = round(a / Fraction(2) ** e)  # Fraction.__round__: half to even
    hi, lo = divmod(m, 2**32)  # m <= 2^64: two exact pieces
    out = np.ldexp(np.longdouble(hi) * np.longdouble(2**32) + np.longdouble(lo), e)
    return out if q > 0 else -out


def _zero_sum_row(values: list[Fraction], diag: int) -> list[np.longdouble]:
    """One matrix row in ``np.longdouble`` whose entries sum to exactly zero.

    The off-diagonal values are rounded to multiples of 2^k, the unit in the last place of the
    row's sum of |values|, so that their exact sum is representable, and the diagonal is exactly
    minus it.  Why exactly zero: the interior FD rows are all the same stencil, so a row sum
    left at one rounding of the diagonal (as in double) is the same small number delta in every
    row, D c = delta for constants, a coherent source term in the equations; at fd6 N = 448 it
    moved the fold H (nu = 0.16) by a few 1e-13, N-dependently, 10x the evaluation noise.
    Rounding the small entries to 2^k instead costs ~1e-17 relative on them.
    """
    bits = np.finfo(np.longdouble).nmant + 1
    total = sum(abs(c) for c in values)
    k = math.ceil(math.log2(total)) - bits + 1  # |sum of off-diagonals| <= total < 2^(bits + k - 1)
    unit = Fraction(2) ** k
    off = [round(c / unit) * unit for c in values]
    off[diag] = -sum(c for j, c in enumerate(off) if j != diag)
    return [to_longdouble(c) for c in off]


def _fd_matrix_longdouble(n: int, deriv: int, order: int) -> NDArray[np.longdouble]:
    """:func:`_fd_matrix` in ``np.longdouble`` (dense) from the exact rationals, every row
    summing to exactly zero (:func:`_zero_sum_row`)."""
    scale = Fraction(n - 1) ** deriv
    out = np.zeros((n, n), dtype=np.longdouble)
    for i in range(n):
        idx = _fd_stencil(i, n, deriv, order)
        exact = [c * scale for c in uniform_stencil(tuple(int(j) - i for j in idx), deriv)]
        out[i, idx] = _zero_sum_row(exact, int(np.flatnonzero(idx == i)[0]))
    return out


@lru_cache(maxsize=16)
def extended_grid(method: str, intervals: int) -> Grid:
    """The grid of :func:`make_grid` with nodes, derivative matrices and weights in ``np.longdouble``.

    For measurements below the double-precision rounding floor (e.g. the fd6 convergence order
    of the fold at nu = 0.16, tests/test_couette_scenes.py; problems/couette/extended_precision.py):
    the FD entries are the same exact rationals rounded to 64 bits instead of 53, with every row
    summing to exactly zero (:func:`_zero_sum_row`), the Chebyshev ones the same formulas
    evaluated in extended precision.  ``d1``, ``d2`` are CSR matrices of
    dtype longdouble (dense storage pattern for Chebyshev); ``interpolate`` still works in double.
    Not used by the normal (double) code path.
    """
    make_grid(method, intervals)  # same validation
    ld = np.longdouble
    if method == "cheb":
        y, d, w = chebyshev(intervals, np.longdouble)
        dd = d @ d
        # Not passed through _zero_sum_row: quantizing the O(1) entries of a Chebyshev row to the
        # unit of its O(N^2) ones made the fold H at nu = 0.16 scatter 2x more over N = 64..128.
        return Grid(method, intervals, y, sp.csr_matrix(d), sp.csr_matrix((dd + dd[::-1, ::-1]) / 2), w, float("inf"))
    order = int(method[2:])
    n = intervals + 1
    y = np.arange(-intervals, intervals + 1, 2).astype(ld) / ld(2 * intervals)  # one rounding, exactly odd
    wq = [Fraction(0)] * n
    for idx, cw in _fd_cells(n, order):
        for j, c in zip(idx, cw):
            wq[j] += c
    d1 = sp.csr_matrix(_fd_matrix_longdouble(n, 1, order))
    d2 = sp.csr_matrix(_fd_matrix_longdouble(n, 2, order))
    return Grid(method, intervals, y, d1, d2, np.array([to_longdouble(c) for c in wq]), float(order))
