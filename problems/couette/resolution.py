"""Is a gPCF state resolved by its grid?  The a-posteriori guard behind ``CouetteProblem.under_resolved``.

Measure.  Each profile f in (nu, T, u) is expanded in Chebyshev polynomials on [-1/2, 1/2],
f(y) = sum_k a_k T_k(2y), with the coefficients from the DCT-I of the nodal values at the
Gauss-Lobatto points (Trefethen, *Spectral Methods in MATLAB*, ch. 8; Boyd, *Chebyshev and
Fourier Spectral Methods*, 2nd ed., section 2.12: the truncation error of a Chebyshev
interpolant is of the order of its last coefficients).  The *tail* is

    tail(f) = max_{k > N - TAIL_MODES} |a_k|

(the last four coefficients, so that both parities of a reflection-symmetric profile count), or,
where larger, the extrapolated sum of the omitted coefficients
(``problems.discretization.chebyshev_tail_sum``, below: slow decay), and the estimated relative
error of the state is

    error = max( tail(nu) / min(|a(nu)|_max, nu_m - max nu),  tail(T) / |a(T)|_max,  tail(u) / |a(u)|_max ).

Why the distance to packing.  chi, hence f1..f5, diverge like (nu_m - nu)^-1 or faster
(closures), so an absolute error delta in nu changes the transport coefficients by about
delta / (nu_m - nu), not delta / nu.  Near a dense plug the plain relative tail of nu misses the
loss of resolution by orders of magnitude: on the n = 1 banded branch at nu = 0.5, e = 0.8,
cheb 64, the relative tail is only 2e-10 at H = 36.7 where the k_x = 0 spectrum first shows
spurious unstable modes, while tail / (nu_m - max nu) is 5e-5 there (3e-6 at H = 34.5, still
right).  The same number follows the Fr = 50 bottom plug: 1e-5 at H = 21.3 (shear-stress defect
6e-7), 6e-4 at H = 23.6 (defect 1e-4, pressure drop off by 5e-7).

Known limit: a cold plug.  Viscosity, conductivity and dissipation go like T^(1/2), T^(1/2),
T^(3/2), so where the plug is also cold an absolute error in T matters relative to min T.  On
the nu = 0.16 banded branch (cheb 64) the shear-stress defect |S - S(1/2)| / S follows
tail(T) / min T (1.1e-5 / 6e-4 at H = 87 / 97) more closely than this measure (5e-7 / 1.4e-5):
the last state stored below the stop at H = 100 has a defect of 2.3e-4.  A tail(T) / min T term
with the same tolerance would also end JJ-wall, gravity-isola (Fr = 1000) and coarse-grid
branches that are right to the accuracy their tests check, so it is not part of the estimate.

Slow decay: the last coefficients are the error only when the spectrum falls fast.  Where a
profile crosses a kink of its closure (Savage's contact pressure, zero below phi_c, ESI Eq. 15:
nu' jumps where nu = phi_c, so |a_k| ~ k^-2) or a steep but smooth layer (the 2-D disks' G_GF
logistic of width m_f = 0.01 at phi_f: poles at nu = phi_f +- i pi m_f, a geometric rate of
~0.01 per index at cheb 200-500), the omitted coefficients sum to ~ |a_N| / (1 - rho), and the
last four alone under-stated the error measured against a 1.5x finer solve
(``contin.verify``) by 20-60x on G_GF's n = 1 band (cheb 192-512, H = 18.9-23.3: 1.5e-5
estimated, 3.3e-4 measured at H = 18.9) and by 60-7000x on Savage's dense band (cheb 272-512).
With the tail sum the same points estimate 0.3-2.9x (G_GF) and 1-4.6x (Savage; 0.04x at its
last point, H = 24.27: behind a kink the last coefficients scatter with the kink's position
between the nodes, which the adaptive end reports with a two-grid difference, ``contin.adapt``)
of the measured error.  On gPCF's spectra (the main job, nu = 0.5 to H = 40: 276 stored
points) the tail sum raises no estimate by more than 1.21x and none above tol.

Rounding: the precision limit next to packing.  The state is solved in double precision, and
Newton cannot push the residual below its rounding floor (eps ||J|| ||x||; ||J|| ~ 1e15-1e19 in
a plug within 1e-8..1e-9 of nu_m, where the closures' derivatives are huge).  The computed nu
then carries an absolute rounding error of a few hundred ulps of nu_m, which grows with the
grid; measured against the extended-precision solution on the same grid
(:mod:`problems.couette.extended_precision`, longdouble residual, iterative refinement) on the
nu = 0.63 n = 1 branch (H = 83 .. 95, plug 2e-7 .. 1.2e-9 below nu_m, cheb 48 .. 192), the
error of nu relative to the local distance nu_m - nu(y) is 0.014 .. 0.15 times
eps N^2 nu_m / (nu_m - max nu) in all 20 cases (Don & Solomonoff, SIAM J. Sci. Comput. 16
(1995): rounding of Chebyshev collocation grows like N^2 eps), so the estimate adds

    rounding = ROUNDING_FACTOR eps N^2 nu_m / (nu_m - max nu)      (ROUNDING_FACTOR = 0.2)

(finite-difference grids: 5 N in place of N^2, see FD_ROUNDING)

and reports error = max(truncation, rounding).  The factor depends on the closure: a problem
may set its own ``rounding_factor`` (problems.disks.model: 4.0; the 2-D disks' plug is ~20x more
sensitive to rounding: 1.3 .. 3.1 times eps N^2 phi_inf / gap in 6 cases of the G_CS n = 1 band
at H = 28.8768, gap 1e-7 and 1.3e-8, cheb 48 .. 128, against the same point with a longdouble
residual).  Unlike the tail, no finer grid lowers it (it
grows like N^2), so a state whose rounding exceeds tol is at the *precision limit* of double
precision: the reason says so instead of advising a finer grid, and an adaptive run ends there
(``contin.adapt``: "precision limit").  The tail alone misses it: at H = 94.9 (cheb 80, plug
1.2e-9 below nu_m) the tail estimate is 2.5e-5 while the state is only accurate to 3.9e-5
against the extended-precision reference, and at H = 95.6 on cheb 192 the tail rises to 1.6e-3
because it measures that rounding noise (its estimate 4.2e-5 on cheb 128 then "does not fall
with refinement").

Finite-difference grids.  The nodal profiles are carried to the Chebyshev grid with the same N
by local Lagrange interpolation on FD_WIDTH = 8 nodes (degree 7, whatever the scheme's order)
and measured there.  The error of an FD solution is itself a smooth function, so a high-order
interpolant of the nodal values keeps a small tail unless the *sampling* fails to resolve a
structure (a boundary layer a few nodes wide, grid-scale wiggles); the scheme's O(h^order)
truncation error is the user's accuracy trade, measured by ``contin accuracy``, not what this
guard is for (fd2, N = 32, nu = 0.3 banded at 1.4 H_1^c: 3e-9, although its error is O(1e-3)).
Uniform shear (constants and u = y) is reproduced exactly.

Advice.  The reason names the grid to try: for Chebyshev, from the geometric decay rate of the
coefficient envelope over the upper half of the spectrum, the N at which the tail would fall
to tol / 10 (at least 1.5 N, rounded up to a multiple of 16); for FD grids, the N at which the
degree-7 interpolant's O(h^8) tail falls below tol / 10 (at least 1.5 N).  It is an estimate at
the rejected state only: a plug that keeps approaching nu_m needs ever finer grids.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from dataclasses import field as dc_field
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from problems.discretization import Grid, chebyshev_coefficients, chebyshev_nodes, tail_sum_rows

Array = NDArray[np.float64]

#: Number of highest Chebyshev coefficients whose maximum is the tail.
TAIL_MODES = 4

#: Nodes of the local interpolant that carries FD profiles to the Chebyshev grid.
FD_WIDTH = 8

#: rounding = ROUNDING_FACTOR eps N^2 nu_m / (nu_m - max nu) (module docstring: the measured
#: rounding error of nu against nu_m - nu is 0.014 .. 0.15 times eps N^2 nu_m / gap).
ROUNDING_FACTOR = 0.2

#: Fields measured, in the order they are reported.
FIELDS = ("nu", "T", "u")

_EPS = float(np.finfo(float).eps)


def tail(coefficients: Array, modes: int = TAIL_MODES) -> float:
    """max |a_k| over the last ``modes`` coefficients."""
    return float(np.max(np.abs(coefficients[-modes:])))


def lagrange_matrix(nodes: Array, targets: Array, width: int) -> sp.csr_matrix:
    """Sparse local Lagrange interpolation from ascending ``nodes`` to ``targets``: each target
    uses the ``width`` consecutive nodes around it (shifted inwards at the ends), weights
    l_i(y) = prod_{j != i} (y - x_j) / (x_i - x_j).  O(len(targets) width^2) time and memory."""
    nodes = np.asarray(nodes, dtype=float)
    targets = np.asarray(targets, dtype=float)
    width = min(width, nodes.size)
    i = np.searchsorted(nodes, targets, side="right") - 1
    start = np.clip(i - width // 2 + 1, 0, nodes.size - width)
    idx = start[:, None] + np.arange(width)[None, :]
    x = nodes[idx]  # (T, width)
    diff = targets[:, None] - x
    weights = np.empty_like(x)
    for a in range(width):
        others = [b for b in range(width) if b != a]
        weights[:, a] = np.prod(diff[:, others], axis=1) / np.prod(x[:, [a]] - x[:, others], axis=1)
    rows = np.repeat(np.arange(targets.size), width)
    return sp.csr_matrix((weights.ravel(), (rows, idx.ravel())), shape=(targets.size, nodes.size))


@lru_cache(maxsize=16)
def _to_chebyshev_matrix(grid: Grid) -> sp.csr_matrix:
    """Local Lagrange interpolation (FD_WIDTH nodes) from an FD grid onto the Chebyshev nodes with the same N."""
    return lagrange_matrix(grid.y, chebyshev_nodes(grid.intervals), FD_WIDTH)


def profile_vector_error(grid: Grid, profiles: tuple[Array, ...]) -> float:
    """Estimated relative error of a perturbation (a null vector at a branch point) given by its
    profiles (nu, u, T) on ``grid``: the largest Chebyshev tail of the profiles relative to their
    largest coefficient, FD profiles carried to the Chebyshev grid as in the resolution guard.
    The ``vector_error`` hook of gPCF and of the 2-D disks."""
    fields = list(profiles)
    if grid.method != "cheb":
        m = _to_chebyshev_matrix(grid)
        fields = [m @ f for f in fields]
    coeffs = [chebyshev_coefficients(f) for f in fields]
    scale = max(float(np.max(np.abs(a))) for a in coeffs)
    return max(tail(a) for a in coeffs) / scale if scale > 0 else 0.0


@dataclass(frozen=True)
class Resolution:
    """The resolution estimate of one state.

    error : the estimated relative error (module docstring); the guard compares it with tol
    field : the field that sets ``error``
    tails, scales : tail and the scale it is divided by, per field
    gap : nu_m - max nu (distance of the densest point from the packing limit)
    limit : the packing limit nu_m
    method, N : the grid
    tol, coefficients : the tol of the advice and the Chebyshev coefficients of ``field``
    suggested_N : the grid the advice names for tol (see :func:`resolution`)
    truncation : the tail estimate (``error`` without rounding)
    rounding : the estimated rounding error of nu against the distance to packing (module
        docstring); ``error`` = max(truncation, rounding)
    """

    error: float
    field: str
    tails: dict[str, float]
    scales: dict[str, float]
    gap: float
    limit: float
    method: str
    N: int
    tol: float = 1e-5
    coefficients: Array | None = dc_field(default=None, repr=False, compare=False)
    truncation: float = 0.0
    rounding: float = 0.0

    @property
    def precision_limited(self) -> bool:
        """Whether rounding, which no finer grid lowers, sets the error (module docstring)."""
        return self.rounding >= self.truncation

    @property
    def suggested_N(self) -> int:
        """The grid the advice names for ``tol`` (computed on demand: the adaptive error
        estimate does not need it, and its envelope fit costs as much as the tails)."""
        return _suggest(self.method, self.N, self.truncation, self.tol, self.coefficients)

    def reason(self, tol: float) -> str:
        """One line: what is under-resolved, by how much, near packing or not, and the grid to try
        (or, when rounding sets the error, that no grid meets tol in double precision)."""
        if self.rounding > tol and self.precision_limited:
            return precision_reason(self.rounding, self.gap, self.limit, tol, self.method, self.N)
        f = self.field
        if f == "nu" and self.scales["nu"] == self.gap:
            what = (f"Chebyshev tail of nu {self.tails['nu']:.2g} is {self.error:.2g} of the distance to packing "
                    f"(> {tol:.2g}): plug within {self.gap:.2g} of the packing limit nu_m = {self.limit:g}")
        else:
            what = f"relative Chebyshev tail of {f} {self.error:.2g} > {tol:.2g}"
            if self.gap < 1e-2:
                what += f"; plug within {self.gap:.2g} of the packing limit nu_m = {self.limit:g}"
        grid = "" if self.method == "cheb" else f" (after interpolation from {self.method} to cheb {self.N})"
        return f"{what}{grid}; refine the grid (try --grid {self.suggested_N})"


def _envelope_rate(a: Array) -> float:
    """Geometric decay factor per index of max |a_j| over blocks of TAIL_MODES (upper half of the spectrum)."""
    n = a.size - 1
    k = np.arange(n // 2, n - TAIL_MODES + 2)
    env = np.array([np.max(np.abs(a[j:j + TAIL_MODES])) for j in k])
    env = np.maximum(env, 1e-300)
    slope = np.polyfit(k, np.log(env), 1)[0] if k.size >= 2 else 0.0
    return float(slope)


def _suggest(method: str, n: int, error: float, tol: float, a: Array | None) -> int:
    target = tol / 10.0
    if method == "cheb":
        slope = _envelope_rate(a) if a is not None else 0.0
        extra = math.log(target / error) / slope if slope < -1e-3 and error > target else 0.5 * n
        want = max(1.5 * n, n + extra)
    else:  # the degree-7 interpolant's error falls like h^8
        want = n * (error / target) ** (1.0 / FD_WIDTH) if error > target else 1.5 * n
        want = max(want, 1.5 * n)
    want = min(want, 8.0 * n)
    return int(16 * math.ceil(want / 16))


#: Finite-difference grids: rounding = factor eps FD_ROUNDING N nu_m / gap.  The rounding grows
#: like 1/(smallest spacing): N^2 on Chebyshev nodes, N on uniform FD nodes.  Measured on the same
#: nu = 0.63 states (H = 89.9, 93.5; fd4 N = 200, 400, fd6 300) against the longdouble solution:
#: 0.06 .. 0.67 times eps N nu_m / gap (0.001 .. 0.002 of the Chebyshev formula eps N^2 ...).
FD_ROUNDING = 5.0


def rounding_estimate(N: int, gap: float, limit: float, factor: float = ROUNDING_FACTOR, method: str = "cheb") -> float:
    """factor eps N^2 nu_m / gap (Chebyshev; FD: factor eps FD_ROUNDING N nu_m / gap): the rounding
    error of a computed state's nu relative to its distance to packing (module docstring; inf at
    or past packing)."""
    if not gap > 0:
        return math.inf
    scale = N * N if method == "cheb" else FD_ROUNDING * N
    return factor * _EPS * scale * limit / gap


def precision_reason(rounding: float, gap: float, limit: float, tol: float, method: str, N: int) -> str:
    """The precision-limit reason (one line, no grid advice: finer grids raise the rounding)."""
    return (f"precision limit: plug within {gap:.2g} of the packing limit nu_m = {limit:g}, where double-precision "
            f"rounding alone leaves nu an estimated relative error {rounding:.2g} of the distance to packing "
            f"(> {tol:.2g}) on {method} {N}; finer grids only raise it")


def _limit(problem: Any, p: Mapping[str, Any]) -> float:
    """The packing limit nu_m: problems with their own closure (problems.disks) say where it
    ends; gPCF's is chi's limit."""
    from problems.couette.closures import packing_limit

    own_limit = getattr(problem, "packing_limit", None)
    # .real: np.real's value (the real part of a complex-step num) without its Python wrapper
    return float(own_limit(p)) if callable(own_limit) else packing_limit(problem.chi, float(p["num"].real))


def _measure(problem: Any, x: Array, p: Mapping[str, Any]) -> tuple[Array, Array, Array, float, float]:
    """(Chebyshev coefficients of the FIELDS rows, their tails, their scales, gap, limit) of
    state x: what :func:`resolution` and :func:`estimated_error` are computed from (nu's scale
    not yet capped by the gap)."""
    profiles = problem.profiles(np.asarray(x, dtype=float))
    grid = problem.grid
    limit = _limit(problem, p)
    rows = [profiles[name] for name in FIELDS]
    if grid.method != "cheb":
        m = _to_chebyshev_matrix(grid)
        rows = [m @ v for v in rows]
    # the rows written into one array (np.stack's checks and copies cost more at small N)
    stacked = np.empty((len(FIELDS), rows[0].size))
    for i, v in enumerate(rows):
        stacked[i] = v
    # np.max's wrapper skipped: the same reduction (exact; NaN propagates as there)
    gap = float(limit - np.maximum.reduce(stacked[0]))
    # the three profiles' coefficients in one transform (rows: FIELDS; the same DCT-I as
    # chebyshev_coefficients, row by row): the adaptive tracer estimates every accepted point
    coeffs = chebyshev_coefficients(stacked)
    absc = np.abs(coeffs)
    # the last coefficients, or their extrapolated sum where they fall slowly (module docstring:
    # slow decay); for a fast-falling spectrum the last coefficients are the larger
    # (ufunc reductions: ndarray.max's Python wrapper costs more than these at small N)
    last = np.maximum.reduce(absc[:, -TAIL_MODES:], axis=1)
    scale_v = np.maximum.reduce(absc, axis=1)
    tail_v = np.maximum(last, tail_sum_rows(absc, TAIL_MODES, last, scale_v))
    return coeffs, tail_v, scale_v, gap, limit


def _field_errors(tail_v: Array, scale_v: Array, gap: float) -> tuple[list[float], list[float], list[float]]:
    """(tails, scales, tail / scale) per field in FIELDS order, nu's scale capped by the gap to
    packing (module docstring); a zero scale gives an inf error."""
    tails = tail_v.tolist()
    scales = scale_v.tolist()
    scales[0] = min(scales[0], gap)  # FIELDS[0] is nu
    return tails, scales, [t / s if s > 0 else math.inf for t, s in zip(tails, scales)]


def _rounding(problem: Any, gap: float, limit: float) -> float:
    """:func:`rounding_estimate` of ``problem``'s grid (a problem with another closure states its
    own factor: problems.disks, 4.0, measured)."""
    grid = problem.grid
    return rounding_estimate(grid.intervals, gap, limit, float(getattr(problem, "rounding_factor", ROUNDING_FACTOR)),
                             grid.method)


def resolution(problem: Any, x: Array, p: Mapping[str, Any], tol: float = 1e-5) -> Resolution:
    """The resolution estimate of state x of a :class:`problems.couette.model.CouetteProblem` (or of any
    problem on a ``grid`` with ``profiles`` nu, u, T and a ``packing_limit(p)`` method, e.g. problems.disks).

    ``tol`` only enters the grid suggestion.  :func:`estimated_error` is its ``error`` alone.
    """
    coeffs, tail_v, scale_v, gap, limit = _measure(problem, x, p)
    tail_l, scale_l, error_l = _field_errors(tail_v, scale_v, gap)
    tails, scales, errors = dict(zip(FIELDS, tail_l)), dict(zip(FIELDS, scale_l)), dict(zip(FIELDS, error_l))
    field = max(FIELDS, key=lambda k: errors[k])
    truncation = errors[field]
    rounding = _rounding(problem, gap, limit)
    grid = problem.grid
    return Resolution(max(truncation, rounding), field, tails, scales, gap, limit, grid.method, grid.intervals, tol,
                      coeffs[FIELDS.index(field)], truncation, rounding)


def estimated_error(problem: Any, x: Array, p: Mapping[str, Any]) -> float:
    """``resolution(problem, x, p).error`` without building the :class:`Resolution` (its dicts,
    field name and coefficients): the adaptive tracer's ``error_estimate`` of every accepted
    point.  The same operations on the same values (tested)."""
    _, tail_v, scale_v, gap, limit = _measure(problem, x, p)
    # max over the fields as resolution's max(FIELDS, key=...): the first largest (NaN as there)
    truncation = max(_field_errors(tail_v, scale_v, gap)[2])
    return max(truncation, _rounding(problem, gap, limit))


def estimated_rounding(problem: Any, x: Array, p: Mapping[str, Any]) -> float:
    """``resolution(problem, x, p).rounding`` (module docstring: rounding) without the
    transform: it needs only the gap nu_m - max nu (``ResolutionHooks.rounding_error``)."""
    nu = problem.profiles(np.asarray(x, dtype=float))["nu"]
    grid = problem.grid
    limit = _limit(problem, p)
    if grid.method != "cheb":
        nu = _to_chebyshev_matrix(grid) @ nu
    return _rounding(problem, float(limit - np.maximum.reduce(nu)), limit)


def under_resolved(problem: Any, x: Array, p: Mapping[str, Any], tol: float) -> str | None:
    """None if the estimated relative error of x (module docstring) is at most ``tol``, else the reason."""
    # the guard passes at nearly every point: the Resolution (for the reason) only where it fails
    if estimated_error(problem, x, p) <= tol:
        return None
    return resolution(problem, x, p, tol).reason(tol)


def solution_error(problem: Any, x: Array, ref: Array, p: Mapping[str, Any]) -> float:
    """Relative error of state x against the reference ref on the same grid (``contin.verify``):
    max over nu, T, u of max|f(x) - f(ref)| / scale(f), the scales of :func:`resolution` taken
    on the nodal values of ref (nu's is min(max nu, nu_m - max nu): near a plug the closures
    feel an error in nu against the distance to packing)."""
    a = problem.profiles(np.asarray(x, dtype=float))
    b = problem.profiles(np.asarray(ref, dtype=float))
    limit = _limit(problem, p)
    worst = 0.0
    for name in FIELDS:
        scale = float(np.max(np.abs(b[name])))
        if name == "nu":
            scale = min(scale, float(limit - np.max(b[name])))
        diff = float(np.max(np.abs(a[name] - b[name])))
        worst = max(worst, diff / scale if scale > 0 else (math.inf if diff > 0 else 0.0))
    return worst
