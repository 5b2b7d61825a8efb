"""Adaptive resolution: ask for an accuracy, not a grid.

The tracer (``contin.continuation.trace``) calls into this module when
``ContinuationOptions.adapt`` is an :class:`AdaptOptions`; the problem provides the grid hooks
(documented in ``contin.problem``):

    grid_size                 the size of the grid in force (an int, e.g. Chebyshev intervals N)
    error_estimate(u, p)      a-posteriori relative discretization error of the state u
    with_grid(N)              the same problem on the grid of size N
    transfer(u, other)        u (a state, or the state part of a tangent) carried onto other's grid;
                              linear in u
    vector_error(v)           optional: relative error estimate of a perturbation v (a null vector):
                              decides the grid of located branch points and folds, whose position
                              depends on the kernel of J, not only on the state
    suggest_grid(u, p, tol)   optional: the grid size expected to meet tol
    suggest_vector_grid(v, tol)  optional: the same for a perturbation v (a kernel vector)
    rounding_error(u, p)      optional: the part of the estimate no finer grid lowers (rounding)
    precise_residual(u, p)    optional: the residual in extended precision (as float64), used by
                              the two-grid check where rounding_error >= ROUNDING_SHARE x tol

Policy (h-adaptivity in the grid size, as in AUTO-07p's mesh adaption but choosing the number
of points instead of moving them; Boyd, *Chebyshev and Fourier Spectral Methods*, 2nd ed.,
sec. 2.12 for the tail estimate the spectral problems use):

- start: the start state is solved on the problem's grid and re-solved on finer grids (growth
  factor ``growth``, or the problem's suggestion) until its estimate is <= tol; if it is below
  ``coarsen_below * tol`` coarser grids are tried instead (from ``min_grid`` up), and the
  coarsest whose estimate is <= ``COARSEN_MARGIN * tol`` is kept;
- along the branch: a converged candidate point whose estimate exceeds tol is not accepted; the
  last accepted point is carried onto a finer grid (state and tangent transferred, corrected on
  the pseudo-arclength hyperplane of the transferred tangent, tangent re-solved) and the step is
  retried from there.  The same happens when a located BP's null vector or an LP's tangent is
  under-resolved (``vector_error``), so special points are located on a grid that resolves them;
  a located LP, Hopf point or symmetry-breaking BP also has its *position* two-grid checked
  (``contin.specialcheck``): the measurement replaces the kernel's estimate where that exceeds
  special_tol (which it over-states), and refines where the estimate meets special_tol but the
  measurement does not (an FD grid's kernel estimate does not see the scheme's error; a Hopf
  point has no kernel estimate); a grid so refined is not coarsened before the point is located
  again (``Adaptor.hold``);
  a step that brackets an LP/BP whose kernel the bracket's ends already show under-resolved
  refines before the location (:meth:`Adaptor.pre_locate`: located once, not twice);
- an accepted point whose estimate fell below ``coarsen_below * tol`` is moved to a coarser grid
  when the estimate there stays <= ``COARSEN_MARGIN * tol`` (at most once every ``cooldown``
  steps, so the grid does not oscillate);
- past ``max_grid`` the run ends with MX: "under-resolved at p = ...: estimated error ... >
  tol on the maximum grid ...";
- resolution limit: on ``max_grid``, a rejected candidate whose estimate falls only slowly with
  the grid (like N^-p, 0 < p <= SLOW_ORDER, fitted over its interpolants on coarser grids:
  a kink of the solution, a layer far too steep for the grid) ends the branch with status EP
  and a message starting "resolution limit" that names the grid tol would need (algebraic
  extrapolation), the last stored point's estimate and its difference to a solve on a coarser
  grid (behind a kink the estimate can under-state the error; the difference bounds a falling
  error), instead of MX;
- precision limit: where the problem's ``rounding_error`` (the part of the estimate that
  refinement cannot lower, e.g. double-precision rounding next to a closure's singularity,
  which grows with the grid) exceeds tol at a rejected candidate, or would at the last point
  on the finer grid, no grid meets tol: the branch ends with status EP and a message starting
  "precision limit" that states the last stored point's estimate (every stored point meets
  tol), not MX with "refine the grid".

Every point remembers its grid (``Branch.grid``); see ``contin.branch``.
"""

from __future__ import annotations

import math
import warnings
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from contin.cancel import stop_requested
from contin.options import AdaptOptions
from contin.problem import Array, has

__all__ = ["AdaptOptions", "Adaptor", "on_grid", "point_problem", "start_grid", "two_grid_error"]

#: Hooks a problem needs for adaptive resolution.
REQUIRED_HOOKS = ("error_estimate", "with_grid", "transfer")

#: A coarser grid is taken only if its estimate is at most this fraction of tol (hysteresis
#: against refining again at the next step).
COARSEN_MARGIN = 0.1


def missing_hooks(problem: Any) -> list[str]:
    """The grid hooks ``problem`` lacks (empty: adaptive resolution is possible)."""
    out = [h for h in REQUIRED_HOOKS if not has(problem, h)]
    if getattr(problem, "grid_size", None) is None:
        out.insert(0, "grid_size")
    return out


def check_problem(problem: Any) -> None:
    """ValueError naming the missing hooks if ``problem`` cannot change its grid."""
    missing = missing_hooks(problem)
    if missing:
        raise ValueError(f"adaptive resolution needs the problem hooks {', '.join(missing)} "
                         f"({type(problem).__name__} lacks them); use a fixed grid (adapt=None)")


def state_error(problem: Any, u: Array, p: Any) -> float:
    """The problem's estimated relative error of state u (inf if it is not finite)."""
    e = float(problem.error_estimate(np.asarray(u, dtype=float), p))
    return e if math.isfinite(e) else math.inf


def vector_error(problem: Any, v: Array) -> float:
    """The problem's estimated relative error of a perturbation v (0 without the hook)."""
    if not has(problem, "vector_error"):
        return 0.0
    e = float(problem.vector_error(np.asarray(v, dtype=float)))
    return e if math.isfinite(e) else math.inf


#: Messages of the precision-limit end start with this (the tracer ends such a branch EP).
PRECISION_LIMIT = "precision limit"

#: Messages of the resolution-limit end start with this (EP: :meth:`Adaptor.resolution_limit`).
RESOLUTION_LIMIT = "resolution limit"

#: On the maximum grid, an estimate that falls like N^-p with p at most this (fitted over the
#: coarser grids max_grid / growth^j) is *slow* (a 2.25x finer grid gains less than 2.25^6 = 130x):
#: the branch ends EP "resolution limit" with the grid the decay asks for, not MX.  A spectral
#: estimate falls far faster there.
SLOW_ORDER = 6.0

#: Coarser grids (max_grid / growth^j, j = 1..SLOW_GRIDS) the order of that decay is fitted over.
SLOW_GRIDS = 3


def rounding_error(problem: Any, u: Array, p: Any) -> float:
    """The problem's estimated rounding error of u, the floor no grid lowers (0 without the hook)."""
    if not has(problem, "rounding_error"):
        return 0.0
    e = float(problem.rounding_error(np.asarray(u, dtype=float), p))
    return e if math.isfinite(e) else math.inf


def coarsen_worth(problem: Any, u: Array, p: Any, err: float, opts: AdaptOptions) -> bool:
    """Whether to try a coarser grid for a state with estimate ``err``: it is below
    coarsen_below * tol, or rounding (``rounding_error``, which grows with the grid) sets it, so a
    coarser grid can only lower it unless its truncation rises (the coarse grid's estimate then
    decides, against COARSEN_MARGIN * tol)."""
    if opts.coarsen_below is None:
        return False
    return err < opts.coarsen_below * opts.tol or (err > 0 and rounding_error(problem, u, p) >= err)


def _round(n: float, multiple: int) -> int:
    return int(multiple * math.ceil(n / multiple - 1e-12))


def finer(problem: Any, u: Array | None, p: Any, opts: AdaptOptions) -> int | None:
    """The next grid size above the current one (None at max_grid)."""
    n = int(problem.grid_size)
    if n >= opts.max_grid:
        return None
    want = opts.growth * n
    if u is not None and has(problem, "suggest_grid"):
        want = max(want, float(problem.suggest_grid(u, p, opts.tol)))
    return min(max(_round(want, opts.multiple), n + 1), opts.max_grid)


def vector_grid(problem: Any, v: Array | None, tol: float, opts: AdaptOptions) -> int | None:
    """The problem's grid for the perturbation v to meet tol (``suggest_vector_grid``), at most two
    growth steps above the grid in force (growth^2 N: the suggestion extrapolates a decay rate,
    which a grid-scale mode or a short spectrum can make far too slow), rounded to ``multiple``,
    capped at max_grid; None without the hook or a vector."""
    if v is None or not has(problem, "suggest_vector_grid"):
        return None
    want = float(problem.suggest_vector_grid(np.asarray(v, dtype=float), tol))
    if not math.isfinite(want):
        return None
    want = min(want, opts.growth ** 2 * int(problem.grid_size))
    return min(_round(want, opts.multiple), opts.max_grid)


def coarser(problem: Any, opts: AdaptOptions) -> int | None:
    """The next grid size below the current one (None at min_grid)."""
    n = int(problem.grid_size)
    want = max(_round(n / opts.growth, opts.multiple), opts.min_grid)
    return want if want < n else None


#: A two-grid error that refinement does not lower is a rounding floor (EP precision limit) where
#: the problem's rounding estimate on the check grid is at least this fraction of tol (gPCF nu = 0.5
#: at H = 38.96: 2.9e-6 on cheb 256 for tol 3e-5, the measured differences 1e-4); below it (or
#: without the hook: a kink, whose two-grid differences scatter) the estimate decides instead.
ROUNDING_SHARE = 0.01

#: Floor of the scale of a parameter's relative change in the two-grid checks of augmented
#: curves (contin.foldcurve.augmented_two_grid_error) and of located special points
#: (contin.specialcheck): a parameter that passes through 0 (StretchedBratu's a at its start) has
#: its change measured against max(|p|, PARAM_SCALE_FLOOR) there instead of a vanishing |p|.
PARAM_SCALE_FLOOR = 1e-3

#: A special point's measured position error must fall at least by this factor per refinement
#: for refinement to go on (Adaptor.special_refinable).
MEASURED_FALL = 0.9

#: The audit of a point stored although its two-grid check exceeded tol (the check was not
#: lowered by refinement: a floor, a kink between nodes, or an FD grid not yet in its asymptotic
#: range next to a BP); the command line shows these lines as warnings (``contin.cli.trace``);
#: defined here, where the start point's check (``_check_start``) writes it too.
ACCEPTED_ABOVE_TOL = "accepted by its estimate"

#: A located special point is the one measured before (located again after a refinement) when
#: its parameter lies within SAME_POINT x (the larger measured relative error) of that one's;
#: farther off it is another point, whose measurement is not compared with the previous one's
#: (Adaptor.special_refinable).
SAME_POINT = 10.0

#: An LP whose bracket's tangent estimate is at most this multiple of special_tol is located on
#: the grid in force and left to its two-grid check (Adaptor.pre_locate): an LP's position error
#: measured 0.07x (gPCF nu = 0.16 fold, cheb 32: 1.5e-9 against 2.1e-8) and 0.12x (Bratu cheb 20:
#: 2.6e-9 against 2.2e-8) of its tangent's tail, so within 3x of special_tol it most often meets
#: it; further off, refining first saves the second location.
LP_LOCATE_MARGIN = 3.0

#: Estimates remembered by an Adaptor (the last few points: a bracket's ends, the last accepted).
ESTIMATE_CACHE = 8

#: Up to this size the kernel vectors of the grid decisions are computed densely (LAPACK):
#: sparse bordering's set-up (bmat, splu) costs ~1-2 ms even at n = 30.
DENSE_KERNEL_MAX = 400


def null_vector(jacobian: Any) -> Array:
    """A unit vector spanning the (numerical) kernel of J at a located branch point: bordering
    [[J, b], [c^T, 0]] [phi; s] = [0; 1] with random b, c (``contin.normalform.null_vectors``,
    the same borders; dense LAPACK up to DENSE_KERNEL_MAX unknowns)."""
    import scipy.sparse as sp

    from contin.normalform import borders, null_vectors

    n = jacobian.shape[0]
    if n > DENSE_KERNEL_MAX:
        return null_vectors(sp.csc_matrix(jacobian)).phi
    from scipy.linalg import lu_factor, lu_solve

    from contin.linalg import bordered_dense

    b, c = borders(n)
    border = bordered_dense(jacobian if sp.issparse(jacobian) else np.asarray(jacobian), b, np.append(c, 0.0))
    rhs = np.zeros(n + 1)
    rhs[-1] = 1.0
    phi = lu_solve(lu_factor(border, check_finite=False), rhs, check_finite=False)[:n]
    return phi / np.linalg.norm(phi)


def near_kernel(jacobian: Any, iterations: int = 3) -> Array:
    """A unit vector along the smallest singular direction of a (nearly singular) J: the
    bordered null vector (:func:`null_vector`) refined by inverse iteration v <- J^{-1} v.

    Next to a BP, J is regular; the bordered vector then keeps components along the other
    small singular directions (random borders), whose tails can exceed the kernel's by orders
    (gPCF cheb 32 next to H_2^c: 5e-4 against 2e-8 at the located BP).  Each inverse iteration
    divides them by sigma_2 / sigma_1 (Golub & Van Loan, *Matrix Computations*, sec. 7.6.1).

    For a regular J the bordered solution [[J, b], [c^T, 0]] [phi; s] = [0; 1] is
    phi = J^{-1} b / (c^T J^{-1} b), so the bordered vector is the first inverse-iteration
    step from the border b: one LU of J serves all of them (up to sign, which no estimate
    sees).  An exactly singular J (a zero pivot) falls back to the bordered solve."""
    import scipy.sparse as sp

    from contin.normalform import borders

    n = jacobian.shape[0]
    try:
        if n <= DENSE_KERNEL_MAX:
            from scipy.linalg import LinAlgWarning, lu_factor, lu_solve

            dense = jacobian.toarray() if sp.issparse(jacobian) else np.asarray(jacobian)
            with warnings.catch_warnings():  # a zero pivot is handled here, not warned about
                warnings.simplefilter("ignore", LinAlgWarning)
                factors = lu_factor(dense, check_finite=False)
            if not np.all(np.diag(factors[0])):
                raise RuntimeError("exactly singular")

            def solve(r: Array) -> Array:
                return lu_solve(factors, r, check_finite=False)
        else:
            import scipy.sparse.linalg as spla  # only here: the main path stays dense

            solve = spla.splu(sp.csc_matrix(jacobian)).solve
    except RuntimeError:  # exactly singular: the bordered vector is the kernel
        return null_vector(jacobian)
    v = borders(n)[0]
    for k in range(iterations + 1):
        w = solve(v)
        norm = float(np.linalg.norm(w))
        if not (math.isfinite(norm) and norm > 0):
            return null_vector(jacobian) if k == 0 else v
        v = w / norm
    return v


def solution_error(problem: Any, x: Any, ref: Any, p: Mapping[str, Any]) -> float:
    """Relative error of state x against the reference ref (both on ``problem``'s grid): the
    problem's ``solution_error`` hook, else max|x - ref| / max|ref|."""
    x = np.asarray(x, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if has(problem, "solution_error"):
        e = float(problem.solution_error(x, ref, p))
    else:
        scale = float(np.max(np.abs(ref))) if ref.size else 0.0
        e = float(np.max(np.abs(x - ref)) / scale) if scale > 0 else float(np.max(np.abs(x - ref), initial=0.0))
    return e if math.isfinite(e) else math.inf


def check_grid(problem: Any, factor: float, opts: AdaptOptions) -> int | None:
    """The grid of the two-grid check of a point on ``problem``'s grid: ceil(factor N) rounded
    up to ``multiple`` (verify's fine grid), capped at max_grid for points below it; a point on
    max_grid is checked on factor x max_grid (a measurement, not a grid the run computes on).
    None only if factor N rounds to N."""
    n = int(problem.grid_size)
    n_f = _round(factor * n, opts.multiple)
    if n < opts.max_grid:
        n_f = min(n_f, opts.max_grid)  # (gPCF: a check of cheb 368 on 512, 1/3 of the LU flops of 736)
    return n_f if n_f > n else None


def stall_fraction(problem: Any, previous_grid: int) -> float:
    """The fraction of the previous estimate that a refinement from ``previous_grid`` to the
    problem's grid must reach not to count as stalled (:meth:`Adaptor.refine`): one half, or on a
    grid of finite order q the square root of the expected fall (N_old / N_new)^q where that is
    larger -- fd2 refined by 1.5 falls 2.25x in the asymptotic range, so "halves" refused
    ``contin trace stretched-bratu -s a=4 --method fd2 --tol 1e-4`` at its start (0.079 on fd2 8,
    0.04 on 12: MX 'does not fall with refinement', session 15)."""
    q = getattr(problem, "convergence_order", None)
    try:
        q = float(q)  # type: ignore[arg-type]
        ratio = float(previous_grid) / float(problem.grid_size)
    except (TypeError, ValueError, AttributeError):
        return 0.5
    if not (0.0 < q < math.inf and 0.0 < ratio < 1.0):
        return 0.5
    return max(0.5, math.sqrt(ratio**q))


def estimate_decides_check(problem: Any) -> bool:
    """Whether a state whose estimate is at most ``check_above`` x tol may skip its two-grid
    check: only on grids of infinite (spectral) or unknown ``convergence_order``.  On an FD grid
    the estimate need not see the scheme's truncation error (gPCF's is the Chebyshev tail of the
    interpolated profiles: 1e-10 on fd4 192 at H = 43 on the n = 1 branch, whose error there is
    2.3e-3 against cheb 128-256 references; a ``--tol 1e-4`` run coarsened onto that grid by the
    estimate and stored the point without a check or a note), so every FD state is checked."""
    q = getattr(problem, "convergence_order", None)
    try:
        q = float(q)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return True
    return not 0.0 < q < math.inf


def richardson(problem: Any, fine_grid: int) -> float:
    """1 / (1 - (N_c / N_f)^q): the factor that turns a two-grid difference e_c - e_f into the
    coarse grid's error e_c, for a discretization of algebraic order q (the problem's
    ``convergence_order``; e_f ~ e_c (N_c / N_f)^q in the asymptotic range, Richardson's
    extrapolation).  1 for spectral methods (q = inf), an unknown order or an unusable grid
    ratio: their fine error is negligible against the coarse one (fd2 at factor 2: 4/3, the
    difference alone passed a point at 3/4 of its error; fd4 16/15, fd6 64/63)."""
    q = getattr(problem, "convergence_order", None)
    try:
        q = float(q)  # type: ignore[arg-type]
        ratio = float(problem.grid_size) / float(fine_grid)
    except (TypeError, ValueError, AttributeError):
        return 1.0
    if not (0.0 < q < math.inf and 0.0 < ratio < 1.0):
        return 1.0
    return 1.0 / (1.0 - ratio**q)


def two_grid_error(problem: Any, u: Array, p: Any, factor: float, opts: AdaptOptions) -> float | None:
    """Achieved relative error of the discrete solution u (on ``problem``'s grid), measured on a
    grid ``factor`` times finer by one Newton correction (a two-grid estimate; Brandt's tau
    correction without the coarse solve, W. Hackbusch, *Multi-Grid Methods*, 1985, ch. 9):

        v = T u,   delta = -J_f(v)^-1 F_f(v, p),   error = ||delta|| / ||v + delta||

    in the problem's ``solution_error`` norm (:func:`solution_error`, which ``contin.verify`` uses).  v + delta
    is the fine solution to O(||delta||^2), so this is the quantity ``contin verify`` measures
    (the fine grid's own error subtracted: equal to the error for spectral grids, 1 - factor^-q
    of it for FD of order q, which :func:`richardson` divides out).  Unlike the state's estimate it sees the truncation amplified by
    ||J^-1||, which grows next to a BP or LP.  Cost: one fine residual, Jacobian, LU and solve.

    Where rounding matters (the problem's ``rounding_error`` of v on the fine grid is at least
    ROUNDING_SHARE x tol) and the problem has the optional ``precise_residual`` hook, F_f is
    evaluated by it and delta refined PRECISE_REFINEMENTS times, delta += -J_f^-1 F_precise(v +
    delta): the error is then measured against the fine solution of the precise residual, not
    against double-precision rounding in F_f (gPCF next to packing: the D2 rows of cheb 160-768
    carry entries ~N^4, whose rounding in double set a floor of ~1e-4 at nu = 0.5, H = 38.96).
    Elsewhere nothing changes (the same operations as without the hook).
    None when factor N rounds to N; inf when the fine J is exactly singular or the
    result is not finite.

    The last TWO_GRID_MEMO results per problem are remembered (keyed by the fine grid, the exact
    bytes of u and the parameters; and tol where the problem has ``precise_residual``): a problem
    whose ``error_estimate`` is itself this measurement (the non-local problems) had each candidate
    measured twice, as its estimate and by the tracer's check (:meth:`Adaptor.solve_check`)."""
    n_f = check_grid(problem, factor, opts)
    if n_f is None:
        return None
    key = _two_grid_key(problem, u, p, n_f, opts)
    memo = _two_grid_memo(problem) if key is not None else None
    if memo is not None and key in memo:
        return memo[key]
    err = _two_grid_error(problem, u, p, n_f, opts)
    if memo is not None:
        if len(memo) >= TWO_GRID_MEMO:
            memo.pop(next(iter(memo)))
        memo[key] = err
    return err


#: two_grid_error results remembered per problem (the last few states).
TWO_GRID_MEMO = 4

#: problem -> {key: two-grid error} (:func:`two_grid_error`).
_TWO_GRID: weakref.WeakKeyDictionary[Any, dict[Any, float]] = weakref.WeakKeyDictionary()


def _two_grid_key(problem: Any, u: Array, p: Any, n_f: int, opts: AdaptOptions) -> Any:
    """The memo key of a two-grid measurement (None: parameters that cannot be a key)."""
    try:
        tol = float(opts.tol) if has(problem, "precise_residual") else None
        key = (int(n_f), np.asarray(u, dtype=float).tobytes(), tuple(sorted(p.items())), tol)
        hash(key)
    except (TypeError, AttributeError):
        return None
    return key


def _two_grid_memo(problem: Any) -> dict[Any, float] | None:
    try:
        return _TWO_GRID.setdefault(problem, {})
    except TypeError:  # not weak-referenceable: no memory
        return None


def _two_grid_error(problem: Any, u: Array, p: Any, n_f: int, opts: AdaptOptions) -> float:
    """:func:`two_grid_error` on the fine grid n_f, computed."""
    fine = on_grid(problem, n_f)
    with np.errstate(all="ignore"):
        v = np.asarray(problem.transfer(np.asarray(u, dtype=float), fine), dtype=float)
        precise = precise_residual(fine, v, p, opts.tol)
        f = None if precise is None else precise(v)
        if f is None:  # (no hook, rounding negligible for tol, or the hook declined)
            precise = None
            f = np.asarray(fine.residual(v, p), dtype=float)
        fact = state_factorization(fine, v, p)
        if fact is None:
            return math.inf
        delta = fact.solve(-f)
        if precise is not None:
            # iterative refinement (Wilkinson; Higham, *Accuracy and Stability of Numerical
            # Algorithms*, 2nd ed., ch. 12): the double J's LU, the residual in extended
            # precision, so delta is limited by the precise residual, not by F's rounding
            for _ in range(PRECISE_REFINEMENTS):
                r = precise(v + delta) if np.all(np.isfinite(delta)) else None
                if r is None:
                    break
                delta = delta + fact.solve(-r)
        if not np.all(np.isfinite(delta)):
            return math.inf
        return richardson(problem, n_f) * solution_error(fine, v, v + delta, p)


def state_factorization(problem: Any, u: Array, p: Any) -> Any:
    """LU of the problem's J(u, p) (None where exactly singular), taken from its optional
    ``dense_jacobian`` hook where the factorization is dense anyway (``contin.problem``)."""
    from contin.linalg import factorize

    return factorize(factorizable_jacobian(problem, u, p))


def factorizable_jacobian(problem: Any, u: Array, p: Any) -> Any:
    """J(u, p) as it is best handed to ``contin.linalg.factorize`` (or, bordered, to
    ``factorize_bordered``): from the problem's optional ``dense_jacobian`` hook where the
    factorization is dense anyway (the same entries, without building a sparse J only to copy it
    densely), else the problem's (sparse) ``jacobian``."""
    from contin.linalg import counted_dense, dense_factorization

    if not has(problem, "dense_jacobian"):
        return problem.jacobian(u, p)
    dense = _DENSE_DECIDED.get(problem) if _weakrefable(problem) else None
    if dense is None:
        # a small problem's dense J, counted, may decide without a sparse J
        probe = counted_dense(lambda: problem.dense_jacobian(u, p), np.asarray(u).size)
        if probe is not None:
            if _weakrefable(problem):
                _DENSE_DECIDED[problem] = True
            return probe
        # the structure of J is the grid's, not the point's: decided once per problem (a
        # sparse J built only to be looked at cost ~0.35 ms per two-grid check of gPCF)
        jac = problem.jacobian(u, p)
        dense = dense_factorization(jac)
        if _weakrefable(problem):
            _DENSE_DECIDED[problem] = dense
        if not dense:
            return jac
    return problem.dense_jacobian(u, p) if dense else problem.jacobian(u, p)


#: problem -> whether its J factorizes densely (state_factorization).
_DENSE_DECIDED: weakref.WeakKeyDictionary[Any, bool] = weakref.WeakKeyDictionary()


def _weakrefable(obj: Any) -> bool:
    try:
        weakref.ref(obj)
    except TypeError:
        return False
    return True


#: Iterative-refinement steps of the two-grid check with the problem's ``precise_residual``
#: (after the first correction): each divides the remaining error by ~||J^-1 dJ||, the double
#: Jacobian's own error, and the limit is the precise residual's floor.
PRECISE_REFINEMENTS = 2

#: A relative error estimate this large says the grid resolves nothing yet (a layer narrower than
#: its nodes): refinement that does not halve it has found no floor (:meth:`Adaptor.refine`).
SATURATED_ESTIMATE = 0.5


def precise_residual(problem: Any, u: Array, p: Any, tol: float) -> Any:
    """``f(x) -> F(x, p)`` evaluated by the problem's optional ``precise_residual`` hook (the same
    residual in extended precision, as float64), where the problem has it and its
    ``rounding_error`` of u is at least ROUNDING_SHARE x tol (rounding matters for tol); else
    None (the caller uses ``residual``: bitwise the same as without the hook).  The hook may
    decline by returning None (a model variant it does not cover); so does ``f`` then, and the
    caller falls back to ``residual``."""
    if not has(problem, "precise_residual") or rounding_error(problem, u, p) < ROUNDING_SHARE * tol:
        return None

    def f(x: Array) -> Array | None:
        r = problem.precise_residual(np.asarray(x, dtype=float), p)
        return None if r is None else np.asarray(r, dtype=float)

    return f


@dataclass(frozen=True)
class GridChange:
    """One grid change along a branch (kept in ``Branch.audit`` as text)."""

    parameter: str
    value: float
    old: int
    new: int
    error: float
    why: str

    def line(self) -> str:
        kind = "refined" if self.new > self.old else "coarsened"
        return (f"grid {kind} {self.old} -> {self.new} at {self.parameter}={self.value:.10g} "
                f"({self.why}, estimate {self.error:.2g})")


def start_grid(problem: Any, u0: Array, params: Any, opts: AdaptOptions, newton_options: Any, *,
               coarsen: bool = True, estimate: Any = None, parameter: str | None = None) -> tuple[Any, Array, list[str]]:
    """The grid to start a branch on: (problem on it, start state on it (converged where
    possible), audit lines).  Refines while the estimate of the solved start state exceeds tol;
    coarsens while it is below coarsen_below * tol and the coarser grid keeps it <=
    COARSEN_MARGIN * tol (unless ``coarsen`` is False: the tracer passes False for a start with a
    given tangent, e.g. one step off a branch point, where a coarser grid moves the BP and the
    small-amplitude branch next to it may not exist there).  A start state that fails to
    converge is returned as given (the tracer then reports the failure).

    Coarsening jumps: the solved state is resampled onto the candidate grids (from min_grid up)
    and only the first whose *resampled* state meets COARSEN_MARGIN * tol is solved on; it is
    kept if its solution does too (else the next candidate).  One resample and estimate per
    candidate that fails, one solve for the grid taken (issue 14: a start state exact on every
    grid, gPCF uniform shear, was solved on cheb 4 and 8 on its way down from 64).
    ``estimate(problem, u, params)``: the estimator (default :func:`state_error`; the tracer
    passes its :class:`Adaptor`'s, which remembers the estimates for the first point).  A start
    whose estimate meets tol then gets the two-grid check of a candidate (:func:`_check_start`);
    ``parameter`` names the continuation parameter in its audit line."""
    from contin.newton import newton

    check_problem(problem)
    est = state_error if estimate is None else estimate
    lines: list[str] = []
    res = newton(problem, u0, params, newton_options)
    if not res.converged:
        return problem, np.asarray(u0, dtype=float), lines
    u = res.u
    if problem.grid_size > opts.max_grid:
        # A scene's start grid above the user's --max-grid (disks-pitchfork starts on cheb 64): a
        # tol no grid meets kept the start there, stored points on 64 and ended 'under-resolved ...
        # on the maximum grid 64 (AdaptOptions.max_grid = 16)'.  The cap holds from the start.
        other = problem.with_grid(opts.max_grid)
        trial = newton(other, problem.transfer(u, other), params, newton_options)
        if trial.converged:
            lines.append(f"start grid lowered {problem.grid_size} -> {opts.max_grid} (AdaptOptions.max_grid)")
            problem, u = other, trial.u
    err = est(problem, u, params)
    while err > opts.tol:
        n_new = finer(problem, u, params, opts)
        if n_new is None:
            break
        other = problem.with_grid(n_new)
        trial = newton(other, problem.transfer(u, other), params, newton_options)
        if not trial.converged:
            break
        lines.append(f"start grid refined {problem.grid_size} -> {n_new} (estimate {err:.2g} > tol {opts.tol:.2g})")
        problem, u = other, trial.u
        err = est(problem, u, params)
    else:
        if coarsen and coarsen_worth(problem, u, params, err, opts):
            # The coarsest grid that keeps the estimate <= COARSEN_MARGIN tol: candidates from
            # min_grid up by the growth factor, first fit taken (module docstring: one solve).
            n, sizes = opts.min_grid, []
            while n < problem.grid_size:
                sizes.append(n)
                n = max(_round(opts.growth * n, opts.multiple), n + 1)
            margin = COARSEN_MARGIN * opts.tol
            for n_new in sizes:
                other = problem.with_grid(n_new)
                guess = problem.transfer(u, other)
                if est(other, guess, params) > margin:  # the grid cannot even carry the state
                    continue
                trial = newton(other, guess, params, newton_options)
                if not trial.converged:
                    continue
                e_new = est(other, trial.u, params)
                if e_new <= margin:
                    lines.append(f"start grid coarsened {problem.grid_size} -> {n_new} (estimate {err:.2g} -> {e_new:.2g})")
                    problem, u = other, trial.u
                    err = e_new
                    break
    if err <= opts.tol:
        problem, u = _check_start(problem, u, params, err, opts, newton_options, est, lines, parameter)
    return problem, u, lines


def _check_start(problem: Any, u: Array, params: Any, err: float, opts: AdaptOptions, newton_options: Any,
                 est: Any, lines: list[str], parameter: str | None) -> tuple[Any, Array]:
    """The two-grid check of the start state, as of every candidate (:meth:`Adaptor.solve_check`):
    the start was judged by its estimate alone, which on an FD grid need not see the scheme's
    error at all, and next to a BP does not see its amplification by ||J^-1|| (session 15:
    ``contin trace allen-cahn --method fd2 --tol 1e-4`` stored the first point of each switched
    branch, one step off the BP on fd2 512, 4.2e-4 .. 1.5e-2 off a cheb reference without a
    warning; the points after it were warned).  Above tol the start is refined while its error
    falls (halves), the refined solve kept only where it stays next to the checked state (a
    refinement moves a BP; a start one step off it must not fall onto the other branch); where
    refinement does not lower it the start is kept with the audit line of a point accepted by
    its estimate (the terminal's warning)."""
    from contin.newton import newton

    if opts.check_factor is None or not opts.solve_check:
        return problem, u
    previous = math.inf
    while True:
        if estimate_decides_check(problem) and err <= opts.check_above * opts.tol:
            return problem, u
        e2 = two_grid_error(problem, u, params, opts.check_factor, opts)
        if e2 is None or e2 <= opts.tol:
            return problem, u
        n_new = finer(problem, u, params, opts)
        why = (f"on the maximum grid {problem.grid_size}" if n_new is None else
               f"does not fall with refinement (grid {problem.grid_size})" if e2 > 0.5 * previous else "")
        trial = None
        if not why:
            other = problem.with_grid(n_new)
            guess = problem.transfer(u, other)
            trial = newton(other, guess, params, newton_options)
            # the refined solve stays within a few two-grid errors of the state (else it left it)
            if not trial.converged or solution_error(other, guess, trial.u, params) > 4.0 * e2:
                why = f"the solve on grid {n_new} left the start state"
        if why:
            p_text = f"{parameter}={float(params[parameter]):.10g}" if parameter else "the start"
            lines.append(f"step 0: {p_text} {ACCEPTED_ABOVE_TOL}: two-grid error {e2:.2g} > tol {opts.tol:.2g} "
                         f"at the start point, not lowered by refinement ({why})")
            return problem, u
        lines.append(f"start grid refined {problem.grid_size} -> {n_new} (two-grid error {e2:.2g} > tol {opts.tol:.2g})")
        previous = e2
        problem, u = other, trial.u
        err = est(problem, u, params)


class Adaptor:
    """The grid changes of one trace (``contin.continuation.trace`` holds one when
    ``ContinuationOptions.adapt`` is set).  Works on the tracer's ``system`` (an
    ``ExtendedSystem``), ``anti``, ``points``, ``records`` and ``grids``."""

    def __init__(self, opts: AdaptOptions) -> None:
        self.opts = opts
        #: Newton settings of the two-grid check in a resolution-limit message (the tracer's)
        self.newton_options: Any = None
        self.since_change = 0
        self.checks = 0  # two-grid checks done (solve_check)
        self.checked: float | None = None  # the last solve_check's error (None: estimate decided)
        #: (points, snapshot) of the last refinement, to undo it at a two-grid floor (solve_floor)
        self._undo: tuple[int, tuple, int] | None = None
        #: the grid in force was raised by the two-grid check, not by the estimate: coarsening is
        #: tried where the estimate is below COARSEN_MARGIN * tol (the check then decides), else
        #: an FD branch refined to max_grid at a fold would stay there (Bratu fd2: its defect
        #: estimate never falls below coarsen_below * tol)
        self.check_raised = False
        self.lines: list[str] = []
        self._state_refine: tuple[int, float, int] | None = None  # (points, estimate, grid) at the last refinement
        self._special: float | None = None  # estimate that triggered the last refinement for a special point
        self._measured: float | None = None  # the same for a measured position (special_refinable)
        self._measured_at: float | None = None  # ... and the parameter value of that position
        self._rises = 0  # measurements of that point that did not fall (special_refinable)
        self._estimates: dict[tuple[Any, ...], tuple[Any, float]] = {}  # see estimate()
        #: (estimate, vector) of the kernel behind the last special_error (None: no kernel)
        self.kernel: tuple[float, Array] | None = None
        #: set by :meth:`refine` when the estimate did not halve with the last refinement: the
        #: tracer then retries a shorter step before ending the branch (a candidate far from the
        #: resolved last point can sit where the tails are still pre-asymptotic: 2-D disks G_GF
        #: band past H = 18.05, 4.7e-4 / 2.1e-4 / 1.8e-5 / 2.3e-6 on cheb 48 / 80 / 160 / 256 at
        #: H = 18.8, 1.2e-12 on cheb 80 at H = 18.06)
        self.stalled = False
        #: (parameter where the grid was refined, parameter of the located special point that
        #: asked for it): no coarsening until the point is located again (the tracer clears it)
        #: or the branch has passed it.  Without the hold, steps shortened on the way back to
        #: the point (bpdetect's halvings) let the cooldown expire, and an exact state (estimate
        #: 0) coarsened the grid before the point was reached: the Brusselator's HB on fd2 840
        #: went back to 560, was located there again, and its measured error, not falling,
        #: ended the refinement ("position not resolved" on 560).
        self.hold: tuple[float, float] | None = None

    def special_refinable(self, err: float, measured: bool = False, at: float | None = None,
                          finite_order: bool = False) -> bool:
        """Whether to refine for a located special point whose estimate ``err`` exceeds tol: not
        when the previous such refinement left a special point with more than a tenth of its
        estimate.  A genuine BP's or LP's kernel converges with the grid (spectrally: 4e-3 -> 2e-8
        from cheb 8 to 16 at gPCF's H_1^c); a kernel that does not is a grid-scale mode (a
        discretization artefact that moves with the grid, which refinement would chase to
        max_grid: 3e-2, 6e-3, 2e-3, 1e-3 on cheb 80..288 on gPCF's nu = 0.5 banded branch).
        The memory is cleared by a special point that meets tol (:meth:`special_resolved`).
        ``measured``: err is the two-grid error of the point's position (comment below);
        ``at``: its parameter value (a measurement is compared only with the same point's);
        ``finite_order``: the grid is of finite order (FD), where one measurement that does not
        fall is allowed per point (pre-asymptotic range), a second ends the refinement.
        """
        last = self._special
        if measured:
            # A measured position error (contin.specialcheck) is the point's error itself, not
            # the tail of its kernel: it may fall slower than tenfold per refinement (an FD
            # scheme, pre-asymptotic: gPCF fd4 H_1^c 2.9e-5, 1.4e-5, 1.3e-6 on 16, 32, 64), and
            # refinement goes on while it falls (by MEASURED_FALL at least); an artefact's
            # position does not converge, and its measurement does not fall.
            if self._measured is not None and at is not None and self._measured_at is not None and \
                    abs(at - self._measured_at) > SAME_POINT * max(err, self._measured) * max(abs(at), PARAM_SCALE_FLOOR):
                # Another special point, not the same one located again on a finer grid: its
                # measurement starts its own history.  The previous point's "not falling" memory
                # refused every later refinement: ``contin trace disks-pitchfork -s corr=cs
                # --method fd4 --tol 1e-4`` kept H_1^c on fd4 32 (7.5e-6 off, not falling), then
                # H_2^c on fd4 24 (2.9e-4) and H_3^c on fd4 12, 2.8e-2 off n pi psi (session 15).
                self._measured, self._rises = None, 0
            if self._measured is not None and err > MEASURED_FALL * self._measured:
                # On an FD grid the first rise may be pre-asymptotic (disks G_CS H_1^c on fd4:
                # 2.9e-6 off on 16, 7.7e-6 on 32, then converging), so one is allowed per point.
                self._rises += 1
                if not (finite_order and self._rises == 1):
                    return False
            self._measured, self._measured_at = err, at
            self._special = err
            return True
        if last is not None and err > 0.1 * last:
            return False
        self._special = err
        return True

    def special_resolved(self) -> None:
        self._special = None
        self._measured = self._measured_at = None
        self._rises = 0

    # --- estimates -------------------------------------------------------------------------
    def error(self, system: Any, x: Array) -> float:
        """The problem's estimate of the state of x = (u, p) (:meth:`estimate`)."""
        return self.estimate(system.problem, x[:-1], system.params_at(x[-1]))

    def estimate(self, problem: Any, u: Array, params: Any) -> float:
        """:func:`state_error`, computed once per (problem, u, params): the same state is
        estimated when the start grid is chosen and as the first point, when a point is accepted
        (``too_coarse``) and when coarsening is considered, and at the ends of a bracket
        (``pre_locate``).  Keyed by the exact bytes of u (a changed state is a new key); the
        problem is kept with its entry so that its id is not reused."""
        u = np.asarray(u, dtype=float)
        try:
            key = (id(problem), u.tobytes(), tuple(sorted(params.items())))
            hash(key)
        except (TypeError, AttributeError):  # parameters that cannot be a key: no memory
            return state_error(problem, u, params)
        hit = self._estimates.get(key)
        if hit is not None and hit[0] is problem:
            return float(hit[1])
        err = state_error(problem, u, params)
        if len(self._estimates) >= ESTIMATE_CACHE:
            self._estimates.pop(next(iter(self._estimates)))
        self._estimates[key] = (problem, err)
        return err

    def special_error(self, system: Any, kind: str, x: Array, t: Array | None, *, near: bool = False) -> float:
        """Estimate for a located special point: its state, and the kernel direction that fixes
        its position (an LP's tangent, a BP's null vector of J; ``near``: x lies next to the BP,
        not on it, and the null vector is refined by inverse iteration, :func:`near_kernel`)."""
        err = self.error(system, x)
        self.kernel = None
        if not has(system.problem, "vector_error"):
            return err
        v = None
        if kind == "LP" and t is not None:
            v = t[:-1]
        elif kind == "BP":
            jac = system.state_jacobian(x)
            v = near_kernel(jac) if near else null_vector(jac)
        if v is not None:
            e_v = vector_error(system.problem, v)
            self.kernel = (e_v, v)
            err = max(err, e_v)
        return err

    def pre_locate(self, system: Any, kind: str, a: Any, b: Any, special_tol: float,
                   checkable: bool = False) -> float | None:
        """Before locating an LP/BP bracketed by the points a, b (``_Point``: x, t): the
        estimate if the grid in force does not resolve it, so that the tracer refines first and
        locates once, on the finer grid; else None (locate here).

        The estimate is :meth:`special_error` at the bracket's ends, the smaller of the two: next
        to a simple BP the smallest singular direction of J (:func:`near_kernel`) and, next to an
        LP, the tangent approach the kernel at the point, so their tails are the located kernel's
        up to O(distance) (gPCF cheb 8 at H_1^c: 3.9e-3 at the ends, 4e-3 located; cheb 32 at
        H_2^c: 6.1e-8 and 1.5e-8).  This only saves a location: the located
        point's own estimate is still checked (``trace``), so a kernel that the ends misjudge
        as resolved is refined after the location as before.  Only the first refinement of a
        chain is taken here (see below); ``special_refinable`` is honoured.  ``checkable``: the
        located point will get a two-grid check of its position (an LP, or a symmetry-breaking
        BP: :func:`contin.specialcheck.check_located`): it is located here unless the
        estimate's square (BP) or the estimate over LP_LOCATE_MARGIN (LP) exceeds special_tol
        (comment below)."""
        if kind not in ("LP", "BP") or not has(system.problem, "vector_error") or self._special is not None:
            # After a special-point refinement that has not yet produced a resolved point, the
            # located point's estimate decides (special_refinable's test for a grid-scale mode
            # compares located estimates; the ends' may be smaller and would chase the mode:
            # gPCF nu = 0.3 branch n1.1, an artefact at H ~ 30 refined 32 -> 48 -> 80 -> 128).
            return None
        # min over the ends: the second end is estimated only if the first does not meet tol
        err = self.special_error(system, kind, b.x, b.t, near=True)
        kernel = self.kernel
        if err > special_tol:
            e_a = self.special_error(system, kind, a.x, a.t, near=True)
            if e_a < err:
                err, kernel = e_a, self.kernel
        self.kernel = kernel  # the refinement's grid (refine, ``vector``) follows the better resolved end
        if err <= special_tol:
            return None
        if checkable and self.opts.check_factor is not None and (
                err * err <= special_tol if kind == "BP" else err <= LP_LOCATE_MARGIN * special_tol):
            # The located point's two-grid check (contin.specialcheck.check_located) measures its
            # position, which the kernel's tail over-states: locate here and let the check
            # decide (a failed check refines and locates again).  A symmetry-breaking BP's
            # position converges about as the square of its kernel (an eigenvalue's error
            # against its eigenvector's: gPCF H_1^c on cheb 8, kernel 3.9e-3, position 4.2e-6);
            # an LP's is a fraction of its tangent's tail (LP_LOCATE_MARGIN).
            return None
        if not self.special_refinable(err):
            return None
        return err

    def too_coarse(self, system: Any, x: Array) -> float | None:
        """The estimate at x if it exceeds tol, else None."""
        e = self.error(system, x)
        self.checked = None
        return e if e > self.opts.tol else None

    def solve_check(self, system: Any, x: Array) -> float | None:
        """The two-grid error of the point x (:func:`two_grid_error`) if it exceeds tol, else None
        (also without ``check_factor``, with ``solve_check`` False, or on max_grid).  Called for a candidate whose estimate
        meets tol: the estimate does not see the amplification by ||J^-1|| next to a BP/LP."""
        factor = self.opts.check_factor
        self.checked = None
        if factor is None or not self.opts.solve_check or self._estimate_passes(system, x):
            return None
        self.checks += 1
        e = two_grid_error(system.problem, x[:-1], system.params_at(x[-1]), factor, self.opts)
        self.checked = e
        return e if e is not None and e > self.opts.tol else None

    def candidate_error(self, system: Any, x: Array) -> float | None:
        """The error that refuses the candidate x: its estimate above tol (:meth:`too_coarse`), else
        its two-grid error above tol (:meth:`solve_check`; ``checked`` then holds it), else None."""
        err = self.too_coarse(system, x)
        return err if err is not None else self.solve_check(system, x)

    def _estimate_passes(self, system: Any, x: Array) -> bool:
        """Whether x's estimate alone clears it of a two-grid check: at most check_above x tol on a
        grid where the estimate sees the truncation (:func:`estimate_decides_check`)."""
        return (estimate_decides_check(system.problem)
                and self.error(system, x) <= self.opts.check_above * self.opts.tol)

    def rounding_floor(self, system: Any, x: Array) -> bool:
        """Whether the problem's ``rounding_error`` of the candidate x on its check grid is at least
        ROUNDING_SHARE x tol: then a two-grid error that refinement does not lower is the finer
        grids' rounding (a floor, :meth:`solve_floor`); without the hook, or far below, it is not."""
        n_f = None if self.opts.check_factor is None else check_grid(system.problem, self.opts.check_factor, self.opts)
        if n_f is None or not has(system.problem, "rounding_error"):
            return False
        fine = on_grid(system.problem, n_f)
        v = system.problem.transfer(x[:-1], fine)
        return rounding_error(fine, v, system.params_at(x[-1])) >= ROUNDING_SHARE * self.opts.tol

    def solve_floor(self, tracer: Any, stop: str) -> str:
        """The end of a branch whose two-grid error did not fall with refinement (``stop``, from
        :meth:`refine`, stalled): the solve's error has a floor above tol that finer grids do
        not lower -- rounding next to a closure's singularity, which the problem's
        ``rounding_error`` under-reads (gPCF nu = 0.5, H = 38.96: the solutions on cheb 80 .. 384
        all differ by 0.6-1.5e-4, their rounding estimate 2e-7 .. 6e-6).  The refinements of the
        last point are undone (back to the grid on which it passed its check), so that every
        stored point keeps its passed check, and the
        message is a precision limit (the tracer ends the branch EP)."""
        count = len(tracer.points)
        if self._undo is not None and self._undo[0] == count:
            # undo every refinement from this point (a chain of them: 80 -> 128 -> 240 -> 368)
            _, keep, n_lines = self._undo
            tracer.system, tracer.anti, tracer.points[-1], tracer.records[-1], tracer.grids[-1] = keep[:5]
            tracer.point_tests = keep[6]
            del tracer.audit[keep[5]:]
            del self.lines[n_lines:]
        self._undo = None
        sys = tracer.system
        cur = tracer.points[-1]
        return (f"{PRECISION_LIMIT} at {sys.parameter} = {cur.x[-1]:.6g}: the two-grid error of the solve "
                f"does not fall with refinement ({stop.split('does not fall with refinement (')[-1].split(')')[0]}) "
                f"> tol {self.opts.tol:.2g}: an error floor (rounding) no grid lowers; every stored point meets tol "
                f"up to {sys.parameter} = {cur.x[-1]:.6g} (its last point, grid {sys.problem.grid_size})")

    def _solve_exceeds(self, system: Any, x: Array, limit: float) -> bool:
        """Whether the two-grid error of x exceeds ``limit`` (False without the check)."""
        if self.opts.check_factor is None or self._estimate_passes(system, x):
            return False
        self.checks += 1
        e = two_grid_error(system.problem, x[:-1], system.params_at(x[-1]), self.opts.check_factor, self.opts)
        return e is not None and e > limit

    def precision_limit(self, tracer: Any, x: Array) -> str | None:
        """The precision-limit message if the rounding part of the estimate at the candidate x
        (rejected: its estimate exceeds tol) exceeds tol, else None (refine as usual)."""
        sys = tracer.system
        rnd = rounding_error(sys.problem, x[:-1], sys.params_at(x[-1]))
        if rnd <= self.opts.tol:
            return None
        return self._precision_message(tracer, x, rnd, int(sys.problem.grid_size))

    def _precision_message(self, tracer: Any, x: Array, rnd: float, grid: int) -> str:
        sys = tracer.system
        cur = tracer.points[-1]
        last = self.error(sys, cur.x)
        return (f"{PRECISION_LIMIT} at {sys.parameter} = {x[-1]:.6g}: estimated rounding error {rnd:.2g} > tol "
                f"{self.opts.tol:.2g} on grid {grid}, which no finer grid lowers; the branch is accurate to {last:.2g} up to {sys.parameter} = {cur.x[-1]:.6g} (its last point, "
                f"grid {sys.problem.grid_size})")

    def resolution_limit(self, tracer: Any, x: Array, err: float) -> str | None:
        """On the maximum grid, the resolution-limit message for the rejected candidate x (its
        estimate ``err`` > tol) if the estimate falls only slowly with the grid, else None.

        The candidate's state is carried onto the coarser grids N / growth^j, j = 1..SLOW_GRIDS
        (its interpolant there: the truncation a solve on that grid would have) and estimated;
        a least-squares line log e = c - p log N through these and (N, err) gives the order p (a
        fit, not two grids: behind a kink the estimate of one grid scatters by 2-5x with the
        kink's position between the nodes).  0 < p <= SLOW_ORDER is algebraic-like decay (a kink
        of the solution, or a layer that a spectral grid resolves only at N >> max_grid): the
        line's N at tol names the grid tol would need, and the branch ends EP with it and the
        estimate of its last stored point.  A faster decay (a larger max_grid would do) or none
        (the estimate does not fall) is left to :meth:`at_max` (MX)."""
        sys = tracer.system
        problem = sys.problem
        n = int(problem.grid_size)
        if n < self.opts.max_grid or not err > self.opts.tol:
            return None
        params = sys.params_at(x[-1])
        sizes, errors = [n], [err]
        for j in range(1, SLOW_GRIDS + 1):
            n_c = _round(n / self.opts.growth ** j, self.opts.multiple)
            if n_c < self.opts.min_grid or n_c in sizes:
                break
            coarse = problem.with_grid(n_c)
            e_c = state_error(coarse, problem.transfer(x[:-1], coarse), params)
            if not (math.isfinite(e_c) and e_c > 0):
                return None
            sizes.append(n_c)
            errors.append(e_c)
        if len(sizes) < 3:
            return None
        slope, icpt = np.polyfit(np.log(sizes), np.log(errors), 1)
        order = -float(slope)
        if not 0 < order <= SLOW_ORDER:
            return None
        # (a tol far below rounding, e.g. 1e-300, overflowed exp: "math range error", exit 1; qa18)
        log_need = (float(icpt) - math.log(self.opts.tol)) / order
        need = math.exp(log_need) if log_need < 700 else math.inf
        cur = tracer.points[-1]
        last = self.error(sys, cur.x)
        fit = ", ".join(f"{e:.2g} on {m}" for m, e in zip(sizes[1:], errors[1:]))
        return (f"{RESOLUTION_LIMIT} at {sys.parameter} = {x[-1]:.6g}: estimated relative error {err:.2g} > tol "
                f"{self.opts.tol:.2g} on the maximum grid {n} falls only like N^-{order:.2g} ({fit}): tol needs "
                f"N ~ {need:.3g} > max_grid {self.opts.max_grid}; the branch ends at {sys.parameter} = "
                f"{cur.x[-1]:.6g} (its last point, grid {problem.grid_size}: estimate {last:.2g}"
                f"{self._two_grid(sys, cur.x, sizes[1])})")

    def _two_grid(self, sys: Any, x: Array, n_c: int) -> str:
        """', difference D to its solve on grid n_c' ('' if that solve fails): behind a
        kink the estimate can under-state the error (the jump's position between the nodes is
        not in the spectrum: 55-110x on KinkedBratu, up to 12x on Savage's dense band), while the
        difference to a coarser solve bounds a monotonically falling error (``contin.verify``'s
        norm; a coarser grid, so the check costs less than a step on max_grid)."""
        from contin.newton import newton

        problem = sys.problem
        params = sys.params_at(x[-1])
        coarse = problem.with_grid(n_c)
        guess = problem.transfer(x[:-1], coarse)
        res = newton(coarse, guess, params) if self.newton_options is None else newton(coarse, guess, params,
                                                                                        self.newton_options)
        if not res.converged:
            return ""
        diff = solution_error(problem, coarse.transfer(res.u, problem), x[:-1], params)
        return f", difference {diff:.2g} to its solve on grid {n_c}"

    def at_max(self, system: Any, x: Array, err: float) -> str:
        return (f"under-resolved at {system.parameter} = {x[-1]:.6g}: estimated relative error {err:.2g} > tol "
                f"{self.opts.tol:.2g} on the maximum grid {system.problem.grid_size} (AdaptOptions.max_grid = "
                f"{self.opts.max_grid})")

    def at_start(self, system: Any, x: Array, err: float) -> str:
        """Why the start point x, whose estimate err exceeds tol, stays unresolved: on max_grid
        (:meth:`at_max`), or below it because :func:`start_grid`'s solve on the next finer grid
        failed (``contin trace nonlocal-shear -s K=1e300`` said "on the maximum grid 48
        (AdaptOptions.max_grid = 512)")."""
        n = int(system.problem.grid_size)
        if n >= self.opts.max_grid:
            return self.at_max(system, x, err).removeprefix("under-resolved at ")
        n_new = finer(system.problem, x[:-1], system.params_at(x[-1]), self.opts)
        return (f"{system.parameter} = {x[-1]:.6g}: estimated relative error {err:.2g} > tol {self.opts.tol:.2g} "
                f"on grid {n}, and its solve on the finer grid {n_new} did not converge (AdaptOptions.max_grid = "
                f"{self.opts.max_grid})")

    # --- grid changes ----------------------------------------------------------------------
    def regrid(self, tracer: Any, size: int, why: str, err: float, newton_options: Any) -> bool:
        """Carry the tracer's last point onto the grid of ``size``: transfer state and tangent,
        correct on the hyperplane through the transferred point normal to the transferred
        tangent (regular at folds, unlike a correction at fixed parameter), re-solve the tangent
        and the test functions there, and make the new system the tracer's.  False (nothing
        changed) if the correction fails."""
        from contin.extended import ExtendedSystem
        from contin.testfunctions import Antisymmetric

        sys = tracer.system
        old = sys.problem
        cur = tracer.points[-1]
        # on_grid: the instance the two-grid checks of this grid's points used (its per-instance
        # set-up -- symmetry basis, structure decisions -- is reused)
        other = on_grid(old, int(size))
        new_sys = ExtendedSystem(other, sys.params, sys.parameter, sys.theta)
        x = self.carry(old, new_sys, cur.x)
        new_sys.n = x.size - 1
        t = new_sys.unit(self.carry(old, new_sys, cur.t))
        anti = Antisymmetric.from_problem(other, new_sys.n) if tracer.anti is not None else None
        corr = _correct_across(new_sys, x, t, anti, newton_options)
        if corr is None:
            return False
        saved = (tracer.system, tracer.anti, tracer.point_tests)
        tracer.use_system(new_sys, anti)  # also sets up the HB/UZ test functions on the new grid
        try:
            pt = tracer.finish_point(corr, t)
        except Exception:  # noqa: BLE001 -- keep the old grid if the new one cannot give a tangent
            tracer.system, tracer.anti, tracer.point_tests = saved
            return False
        change = GridChange(sys.parameter, float(cur.x[-1]), int(old.grid_size), int(size), err, why)
        tracer.points[-1] = pt
        tracer.records[-1] = new_sys.record(pt.x)
        tracer.grids[-1] = int(size)
        self.lines.append(change.line())
        tracer.audit.append(change.line())
        self.since_change = 0
        return True

    def refine(self, tracer: Any, err: float, why: str, newton_options: Any, *,
               vector: tuple[Array, float] | None = None, measured: bool = False) -> str | None:
        """Refine at the tracer's last point; None on success, else why the run must end: at
        max_grid, or when the previous refinement from the same point did not halve the estimate
        (the estimate has reached a floor that finer grids cannot lower, e.g. the rounding of a
        spectral tail measured against a tiny scale: tol is then below what the problem's
        estimate can certify there).  ``vector``: (kernel vector, its tol) for a refinement
        that a special point's kernel asks for; the grid is then at least the problem's
        ``suggest_vector_grid`` (one jump: Bratu cheb 12 -> 28 at the fold for special_tol 1e-10,
        where growth took 12 -> 20 -> 32 and located the fold on 20 too)."""
        sys = tracer.system
        cur = tracer.points[-1]
        count = len(tracer.points)
        self.stalled = False  # only this refinement's outcome counts
        last = self._state_refine
        self._state_refine = (count, err, int(sys.problem.grid_size))
        # (``measured``: a special point's measured position, whose progress special_refinable
        # judged -- MEASURED_FALL, not halving)
        # (an estimate of SATURATED_ESTIMATE or more resolves nothing yet: it cannot fall until a
        # grid resolves the state, so it is no floor -- stretched-bratu a = 60 stopped at "1 on grid 12,
        # 1 on grid 12"; refinement goes on, bounded by max_grid)
        if (not measured and last is not None and last[0] == count
                and err > stall_fraction(sys.problem, last[2]) * last[1] and last[1] < SATURATED_ESTIMATE):
            self.stalled = True  # the tracer first retries with a shorter step (see trace)
            return (f"under-resolved at {sys.parameter} = {cur.x[-1]:.6g}: estimated relative error {err:.2g} > tol "
                    f"{self.opts.tol:.2g} does not fall with refinement ({last[1]:.2g} on grid {last[2]}, {err:.2g} on "
                    f"grid {sys.problem.grid_size}): the estimate's floor is above tol here")
        size = finer(sys.problem, cur.x[:-1], sys.params_at(cur.x[-1]), self.opts)
        if size is not None and vector is not None:
            jump = vector_grid(sys.problem, vector[0], vector[1], self.opts)
            if jump is not None:
                size = max(size, jump)
        while size is not None:
            keep = self._snapshot(tracer)
            if self.regrid(tracer, size, why, err, newton_options):
                new = tracer.system
                rnd = rounding_error(new.problem, tracer.points[-1].x[:-1], new.params_at(tracer.points[-1].x[-1]))
                if rnd > self.opts.tol:
                    # The finer grid's rounding exceeds tol at the (accepted) last point: keep
                    # the point on its old grid, where it met tol, and end at the precision limit.
                    self._restore(tracer, keep)
                    return self._precision_message(tracer, tracer.points[-1].x, rnd, int(size))
                # The carried point met tol on its old grid; on the finer one it can exceed it
                # where the coarse spectrum had not yet shown a forming kink or layer (Savage's
                # dense band, cheb 32 -> 48 -> 144: 4.6e-5 on 144, 1e-4 against cheb 216): refine
                # on until it meets tol again (on max_grid its estimate is what the end states).
                if self._undo is None or self._undo[0] != count:
                    # the point's grid before its first refinement (where it passed its check),
                    # restored at a two-grid floor (solve_floor)
                    self._undo = (count, keep, len(self.lines) - 1)
                self.check_raised = self.checked is not None
                x_last = tracer.points[-1].x
                e_last = self.error(new, x_last)
                if e_last <= self.opts.tol:
                    return None
                nxt = finer(new.problem, x_last[:-1], new.params_at(x_last[-1]), self.opts)
                if nxt is None:
                    return None
                why, err, size = "last point above tol on the refined grid", e_last, nxt
                continue
            size = finer(sys.problem.with_grid(size), None, None, self.opts)
        return self.at_max(sys, cur.x, err)

    @staticmethod
    def _snapshot(tracer: Any) -> tuple:
        return (tracer.system, tracer.anti, tracer.points[-1], tracer.records[-1], tracer.grids[-1],
                len(tracer.audit), tracer.point_tests)

    def _restore(self, tracer: Any, keep: tuple) -> None:
        """Undo :meth:`regrid` (one grid change) from a :meth:`_snapshot`."""
        tracer.system, tracer.anti, tracer.points[-1], tracer.records[-1], tracer.grids[-1] = keep[:5]
        tracer.point_tests = keep[6]
        del tracer.audit[keep[5]:]
        self.lines.pop()

    def maybe_coarsen(self, tracer: Any, newton_options: Any) -> None:
        """Move the last accepted point to a coarser grid if the estimate allows (module docstring)."""
        self.since_change += 1
        opts = self.opts
        if opts.coarsen_below is None or self.since_change <= opts.cooldown:
            return
        sys = tracer.system
        cur = tracer.points[-1]
        if self.hold is not None:
            start, point = self.hold
            if (float(cur.x[-1]) - point) * (start - point) > 0:
                return  # the special point the grid was refined for lies ahead (``hold``)
            self.hold = None
        err = self.error(sys, cur.x)
        if not (coarsen_worth(sys.problem, cur.x[:-1], sys.params_at(cur.x[-1]), err, opts)
                or (self.check_raised and err <= COARSEN_MARGIN * opts.tol)):
            return
        size = coarser(sys.problem, opts)
        if size is None:
            return
        if not self.check_raised:
            # (a grid the check raised is left by the corrected state's estimate and check: the
            # resampled, unsolved state's estimate is no guide for an FD defect estimate)
            other = sys.problem.with_grid(size)
            trial = sys.problem.transfer(cur.x[:-1], other)
            e_new = state_error(other, trial, sys.params_at(cur.x[-1]))
            if e_new > COARSEN_MARGIN * opts.tol:
                self.since_change = 0  # try again after the cooldown
                return
        keep = self._snapshot(tracer)
        if not self.regrid(tracer, size, f"estimate below {opts.coarsen_below:g} tol", err, newton_options):
            return
        new = tracer.system
        x = tracer.points[-1].x
        if self.error(new, x) > COARSEN_MARGIN * opts.tol or self._solve_exceeds(new, x, COARSEN_MARGIN * opts.tol):
            # the corrected state says no (its estimate, or its solve's two-grid error)
            self._restore(tracer, keep)
            self.since_change = 0

    def carry_point(self, tracer: Any, j: int, newton_options: Any) -> Any:
        """The tracer's stored point j re-solved on the grid in force (a ``_Point`` with its
        tangent and test functions there), or None where the correction fails: state and tangent
        transferred from the point's own grid, corrected on the hyperplane normal to the tangent
        (as :meth:`regrid`)."""
        sys = tracer.system
        pt = tracer.points[j]
        grid = tracer.grids[j]
        src = sys.problem if grid is None else on_grid(sys.problem, int(grid))
        t = sys.unit(self.carry(src, sys, pt.t))
        corr = _correct_across(sys, self.carry(src, sys, pt.x), t, tracer.anti, newton_options)
        return None if corr is None else tracer.finish_point(corr, t)

    def forget_points(self) -> None:
        """The tracer dropped stored points (a retreat): the per-point memory of refinements
        (a stall is judged at the same point count; the undo of a two-grid floor) is void."""
        self._state_refine = None
        self._undo = None

    def carry(self, old: Any, new_system: Any, x: Array) -> Array:
        """A point x = (u, p) of the old problem carried onto the new system's grid."""
        if x.size - 1 == new_system.n:
            return x
        return new_system.pack(old.transfer(x[:-1], new_system.problem), x[-1])


def _correct_across(system: Any, x: Array, t: Array, anti: Any, newton_options: Any) -> Any:
    """The correction of a carried point x on the hyperplane through it normal to the carried
    tangent t (regular at folds, unlike a correction at fixed parameter), symmetrized by ``anti``
    where the branch is S-invariant; None where it does not converge, leaves the domain or has no
    factorization (:meth:`Adaptor.regrid`, :meth:`Adaptor.carry_point`)."""
    from contin.corrector import correct

    project = anti.symmetrize if anti is not None else None
    if project is not None:
        x = system.pack(project(x[:-1]), x[-1])
    corr = correct(system, x, system.row(t), newton_options, project)
    if not corr.converged or system.admissible(corr.x) is not None or corr.factorization is None:
        return None
    return corr


#: problem -> {grid size: the problem on that grid}; weak keys, so problems are not kept alive.
_ON_GRID: weakref.WeakKeyDictionary[Any, dict[int, Any]] = weakref.WeakKeyDictionary()


def on_grid(problem: Any, grid: int | None) -> Any:
    """``problem`` on the grid of size ``grid`` (``problem`` itself for None or its own grid).

    For consumers of stored branches (stability, switching, profiles): a point of an adaptive
    run is a solution of the problem on *its* grid (``Branch.grid``, ``SpecialPoint.grid``).
    The rebuilt problems are cached per problem instance.
    """
    if grid is None or int(getattr(problem, "grid_size", -1)) == int(grid):
        return problem
    check_problem(problem)
    try:
        table = _ON_GRID.setdefault(problem, {})
    except TypeError:  # not weak-referenceable: no cache
        return problem.with_grid(int(grid))
    if int(grid) not in table:
        table[int(grid)] = problem.with_grid(int(grid))
    return table[int(grid)]


def point_problem(problem: Any, branch: Any, i: int) -> Any:
    """The problem whose solution point ``i`` of ``branch`` is (its grid, see :func:`on_grid`)."""
    return on_grid(problem, branch.grid_at(i))


def under_resolved_stop(branch: Any) -> bool:
    """Whether ``branch`` ended MX because its grid does not resolve it (the resolution guard's
    or an adaptive run's 'under-resolved' stop), not for another reason."""
    # (a precision limit ends EP: a finer grid would only raise the rounding)
    return getattr(branch, "status", None) == "MX" and "under-resolved" in str(getattr(branch, "message", ""))


def retrace_finer(problem: Any, compute: Any, opts: AdaptOptions = AdaptOptions(),
                  suggest: Any = None) -> tuple[Any, list[Any], list[int]]:
    """Run ``compute(problem)`` (a list of branches) on finer grids until none of its branches
    stops under-resolved (:func:`under_resolved_stop`) or the grid would exceed
    ``opts.max_grid``.  Returns (the problem of the last run, its branches, the grid sizes
    tried).

    For computations the tracer cannot regrid point by point (augmented two-parameter systems
    such as fold curves, whose state carries a null vector; a fold curve can instead continue
    from where the guard stopped it on a finer grid, :class:`contin.foldcurve.SegmentRegrid`):
    the whole computation is repeated on the next grid (growth factor
    ``opts.growth``, as :func:`finer`), which is what a user did by hand after the guard's
    "refine the grid" message.  The growth is geometric, so the total cost is at most
    1/(1 - 1/growth^a) times the last run's (a ~ 1-3, the cost's order in the grid size).
    ``suggest(problem, stopped)`` (optional) returns a grid size for the stopped branches (e.g.
    the problem's ``suggest_grid`` at their last states); the next grid is the larger of it and
    the growth step, so one retrace can skip several growth steps.
    """
    check_problem(problem)
    sizes = [int(problem.grid_size)]
    while True:
        branches = list(compute(problem))
        if not any(under_resolved_stop(b) for b in branches) or stop_requested():
            # after a Ctrl-C/SIGTERM (contin.cancel) a retrace would stop at its first point and
            # replace what was traced: the branches are kept as they are (partial, MX)
            return problem, branches, sizes
        n_new = finer(problem, None, None, opts)
        if n_new is None:
            return problem, branches, sizes
        if suggest is not None:
            want = suggest(problem, [b for b in branches if under_resolved_stop(b)])
            if want is not None:
                n_new = min(max(n_new, _round(float(want), opts.multiple)), opts.max_grid)
        problem = problem.with_grid(n_new)
        sizes.append(n_new)
