"""Check the achieved accuracy of a stored branch by re-solving its points on a finer grid.

Why.  The adaptive tracer (:mod:`contin.adapt`) accepts a point when the problem's
``error_estimate`` of its *state* (for Chebyshev the coefficient tail: how well the grid carries
the computed profiles) is <= tol.  The error of the discrete *solution* is the truncation error
carried through J^-1: next to a branch point or fold (J nearly singular, its kernel
under-resolved on the grid) it is the truncation amplified by ||J^-1||, so a point can meet tol
by its estimate and miss it by two orders of magnitude (gPCF, ``trace pitchfork -s nu=0.3 -s
e=0.8``: n1.1 at H = 26.49 on cheb 32, estimate 4.7e-7, error 7.4e-5 against cheb 160).

What.  For each stored point i of a one-parameter branch (state u_i on grid N_i, parameters
p_i): carry u_i onto a finer grid N_f = ceil(factor N_i) (rounded up to a multiple of 4, at most
``max_grid``) with the problem's ``transfer`` hook, solve F(u, p_i) = 0 there by plain Newton at
the same parameters (a point of a one-parameter branch is a regular solution of F(., p_i) unless
it *is* the singular point), and measure

    error_i = || T u_i - u_f || / || u_f ||

in the problem's norm: its ``solution_error(x, ref, p)`` hook when it has one (gPCF and disks:
the largest relative max-norm difference of the profiles nu, T, u, nu's against the distance to
packing, the scaling of their ``error_estimate``), else the relative max-norm of the state.
This is a two-grid (Richardson-type) estimate of the coarse point's error e_c: the difference is
e_c - e_f with the fine solution's error e_f ~ e_c factor^-q for a method of order q, so it
under-states e_c by the fraction factor^-q (fd2 at factor 2: 0.75 e_c, measured 0.75-0.8 on Bratu
against the closed form; Chebyshev: e_f is negligible); error_i is that difference divided by
1 - (N/N_f)^q (``contin.adapt.richardson``, the problem's ``convergence_order``: e_c in the
asymptotic range).  The order parameter's difference
is reported as well.  Points whose fine solve fails, or that sit on the largest grid already, are
reported as not checked, never dropped.

Generic: uses only the grid hooks of :mod:`contin.adapt` (``grid_size``, ``with_grid``,
``transfer``, ``error_estimate``) and ``order_parameter`` when present; works on fixed-grid
branches too (every point then lives on the problem's grid).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from contin.adapt import richardson, solution_error  # the norm and scaling the tracer's two-grid checks share
from contin.problem import has

__all__ = ["BranchCheck", "PointCheck", "fine_grid", "solution_error", "verify_branch"]

#: fine grids are rounded up to a multiple of this (as AdaptOptions.multiple's default)
MULTIPLE = 4


@dataclass(frozen=True)
class PointCheck:
    """One stored point re-solved on a finer grid.

    index : row of the point on its branch
    params : the parameters of the point (file parameters updated with the branch's columns)
    grid, fine_grid : grid size of the stored point and of the re-solve (None: not changeable)
    estimate : the problem's ``error_estimate`` of the stored state (what the tracer checked)
    error : achieved relative error against the fine solve (NaN when not checked)
    observable_error : |order parameter - fine order parameter| (NaN without the hook)
    message : why the point was not checked ('' when it was)
    singular : the point is a branch or limit point itself (the start of a branch switched at a
        BP, or a BP/LP stored on the branch) and the fine solve at its fixed parameters failed --
        or, for the start of a switched branch (the parent's BP state), moved it by more than
        tol: J is singular there, so the plain Newton solve is ill-posed (it converges anywhere
        along the near-kernel); such points are located by
        their own test functions to ``AdaptOptions.special_tol`` and checked directly
        (``contin accuracy``), and are listed apart instead of failing the check
    """

    index: int
    params: Mapping[str, float]
    grid: int | None
    fine_grid: int | None
    estimate: float
    error: float
    observable_error: float
    message: str = ""
    singular: bool = False

    @property
    def checked(self) -> bool:
        return not self.message

    @property
    def amplification(self) -> float:
        """error / estimate: how far the estimate under-states the error."""
        return self.error / self.estimate if self.estimate > 0 else math.inf


@dataclass(frozen=True)
class BranchCheck:
    """The points of one branch checked against a finer grid (:func:`verify_branch`)."""

    branch: str
    tol: float
    factor: float
    points: tuple[PointCheck, ...]

    @property
    def checked(self) -> tuple[PointCheck, ...]:
        return tuple(p for p in self.points if p.checked)

    @property
    def unchecked(self) -> tuple[PointCheck, ...]:
        """Points whose fine solve failed or that could not be refined (reported, not dropped);
        singular points (:attr:`PointCheck.singular`) are listed in :attr:`singular` instead."""
        return tuple(p for p in self.points if not p.checked and not p.singular)

    @property
    def singular(self) -> tuple[PointCheck, ...]:
        """Branch or limit points whose fixed-parameter fine solve failed, and switched branches'
        first points (their parent's BP) that it moved beyond tol (J singular there)."""
        return tuple(p for p in self.points if p.singular)

    @property
    def exceeding(self) -> tuple[PointCheck, ...]:
        """Checked points whose achieved error exceeds tol."""
        return tuple(p for p in self.checked if p.error > self.tol)

    @property
    def max_error(self) -> float:
        errs = [p.error for p in self.checked]
        return max(errs) if errs else math.nan

    def worst(self, k: int = 3) -> tuple[PointCheck, ...]:
        """The k checked points with the largest achieved error, largest first."""
        return tuple(sorted(self.checked, key=lambda p: -p.error)[:k])

    @property
    def ok(self) -> bool:
        """Every point checked and within tol."""
        return not self.unchecked and not self.exceeding


def fine_grid(grid: int, factor: float, max_grid: int | None) -> int:
    """ceil(factor * grid) rounded up to a multiple of 4, capped by max_grid."""
    from contin.adapt import _round

    n = _round(factor * grid, MULTIPLE)
    return min(n, int(max_grid)) if max_grid is not None else n




#: Newton steps with the problem's ``precise_residual`` after the fine solve (:func:`_polish`).
POLISH_STEPS = 2


def _polish(fine: Any, u: Any, p: Mapping[str, Any], tol: float) -> Any:
    """The fine solution u refined by POLISH_STEPS Newton steps whose residual is the problem's
    optional ``precise_residual`` (extended precision; the Jacobian and its LU in double, once):
    where rounding in the double residual is not negligible against tol, the double solve stops
    at its rounding floor (gPCF next to packing: ~1e-4 at nu = 0.5, H = 40 on cheb 160), so the
    measured error would be that rounding, not the stored point's.  Used where the hook is present
    and the problem's ``rounding_error`` (if it has one) is at least ``contin.adapt.ROUNDING_SHARE``
    x tol, as in the tracer's two-grid check (:func:`contin.adapt.precise_residual`; without the
    ``rounding_error`` hook, always); else u unchanged.  A step that is not finite is dropped."""
    from contin.adapt import precise_residual, state_factorization

    # (tol 0: without the rounding_error hook the rounding is not known to be negligible)
    precise = precise_residual(fine, u, p, tol if has(fine, "rounding_error") else 0.0)
    if precise is None:
        return u
    with np.errstate(all="ignore"):
        fact = state_factorization(fine, u, p)
        if fact is None:
            return u
        for _ in range(POLISH_STEPS):
            r = precise(u)
            if r is None:
                break
            step = fact.solve(-r)
            if not np.all(np.isfinite(step)):
                break
            u = u + step
    return u


def _observable(problem: Any, u: Any, p: Mapping[str, Any]) -> float:
    if not has(problem, "order_parameter"):
        return math.nan
    try:
        return float(problem.order_parameter(u, p))
    except Exception:  # noqa: BLE001 -- an optional column; the state error decides
        return math.nan


def _special_at(branch: Any, i: int) -> str:
    """'' unless point i is a BP/LP: the start of a branch switched at a BP (its parent), or a BP
    or LP stored at row i."""
    for sp in getattr(branch, "special_points", ()):
        kind = str(getattr(sp, "type", ""))
        if kind in ("BP", "LP") and int(getattr(sp, "index", -1)) == i:
            return f"{sp.name} ({kind})"
    parent = getattr(branch, "parent", None)
    if i == 0 and parent and str(parent).upper().startswith(("BP", "LP")):
        return f"the start of a branch switched at {parent}"
    return ""


def verify_branch(problem: Any, branch: Any, params: Mapping[str, Any], *, factor: float = 2.0,
                  tol: float | None = None, max_grid: int | None = 1024, newton_options: Any = None,
                  indices: Sequence[int] | None = None) -> BranchCheck:
    """Re-solve the stored points of ``branch`` on a grid ``factor`` times finer and measure
    their achieved error (module docstring).

    problem : the run's problem on any grid (each point is taken on its own grid,
        :func:`contin.adapt.point_problem`)
    params : the run's fixed parameters; each point's are these updated with the branch columns
    tol : the accuracy the points should meet (default: 3e-5, AdaptOptions' default)
    max_grid : the largest fine grid (None: no cap); a point already on it is reported unchecked.
        Default 1024, twice AdaptOptions' max_grid: a point an adaptive run stored on its
        largest grid is checked too
    indices : the rows to check (default: every row with a stored state)

    Raises ValueError for a multi-parameter branch (its states carry more than the problem's
    unknowns) or a problem without the grid hooks.
    """
    from contin.adapt import check_problem, on_grid
    from contin.newton import newton
    from contin.options import NewtonOptions

    if not (math.isfinite(factor) and factor > 1):
        raise ValueError(f"factor must be a finite number > 1, got {factor}")
    if tol is None:
        from contin.options import AdaptOptions

        tol = AdaptOptions().tol
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a finite number > 0, got {tol}")
    if len(getattr(branch, "free", ())) != 1:
        raise ValueError(f"branch {branch.id} has free parameters {tuple(branch.free)}: only one-parameter "
                         "branches (states of the problem) can be re-solved at fixed parameters")
    check_problem(problem)
    opts = newton_options if newton_options is not None else NewtonOptions()
    fixed = {k: v for k, v in params.items()}
    missing = [n for n in getattr(problem, "parameter_names", ()) if n not in fixed and n not in branch.params]
    if missing:  # 'Error: num' from inside the problem: a file whose scene attribute names another scene
        raise ValueError(f"branch {branch.id}: the run's parameters have no {', '.join(map(repr, missing))}, which "
                         "the rebuilt problem needs (is it a file of another scene?)")
    rows = range(len(branch)) if indices is None else [range(len(branch))[i] for i in indices]
    out = []
    for i in rows:
        try:
            u = np.asarray(branch.state(i), dtype=float)
        except KeyError:
            if indices is None:
                continue  # save_every > 1: rows without a state are not points to check
            raise
        p = {**fixed, **{k: float(v[i]) for k, v in branch.params.items()}}
        coarse = on_grid(problem, branch.grid_at(i))
        size = getattr(coarse, "size", None)  # as contin continue / stability check it
        if isinstance(size, int) and size != u.size:
            # a file whose scene or discretization attribute disagrees with its states: the
            # problem read them out of bounds ('Error: index 39 is out of bounds for axis 0')
            raise ValueError(f"the state of branch {branch.id} point {i} has {u.size} entries but the problem "
                             f"rebuilt for it (grid {coarse.grid_size}) has {size} unknowns: the file's scene or "
                             f"discretization does not match its states")
        n = int(coarse.grid_size)
        n_f = fine_grid(n, factor, max_grid)
        estimate = float(coarse.error_estimate(u, p))
        if n_f <= n:
            out.append(PointCheck(i, p, n, None, estimate, math.nan, math.nan,
                                  f"already on the largest grid {n} (max_grid {max_grid})"))
            continue
        fine = on_grid(problem, n_f)
        moved = np.asarray(coarse.transfer(u, fine), dtype=float)
        res = newton(fine, moved, p, opts)
        if not res.converged:
            special = _special_at(branch, i)
            why = f"the Newton solve on grid {n_f} failed: {res.message}"
            if special:
                why = f"{special}: J is singular at fixed parameters ({why})"
            out.append(PointCheck(i, p, n, n_f, estimate, math.nan, math.nan, why, singular=bool(special)))
            continue
        u_f = _polish(fine, res.u, p, tol)
        err = richardson(coarse, n_f) * solution_error(fine, moved, u_f, p)
        obs = abs(_observable(coarse, u, p) - _observable(fine, u_f, p))
        special = _special_at(branch, i) if err > tol and i == 0 else ""
        if special.startswith("the start of a branch switched at"):
            # the first point of a switched branch is its parent's BP, where J is singular: the
            # fixed-parameter solve converges anywhere along the near-kernel (gPCF nu = 0.63:
            # the exactly uniform BP state at the start of n1.1, sigma_min(J) = 1e-11 on cheb 32,
            # moved 2.4e-5 by two Newton steps), so the difference measures the kernel, not the
            # point's error; the state is the parent's, checked on the parent.  (A BP or LP
            # stored on the branch itself keeps its measured error: next to a fold the
            # difference is mostly the truncation error, Bratu fd2 at tol 1e-3.)
            out.append(PointCheck(i, p, n, n_f, estimate, math.nan, math.nan,
                                  f"{special}: J is singular at fixed parameters (the fine solve moved it by "
                                  f"{err:.2g} along the kernel, which is not its error; the state is the parent's BP)", singular=True))
            continue
        out.append(PointCheck(i, p, n, n_f, estimate, err, obs))
    return BranchCheck(str(branch.id), float(tol), float(factor), tuple(out))
