"""Steady gPCF residuals in extended precision (``np.longdouble``) and a mixed-precision fold Newton.

What it is for: measuring convergence orders below the double-precision rounding floor.  In
double, the residual of an FD grid carries rounding ~ eps |u| / h^2 from the second derivatives
(and the rounded weights themselves), which puts a floor of ~1e-11 relative under any computed
quantity; the fd6 fold H at nu = 0.16 reaches that floor before its asymptotic range (see
tests/test_couette_scenes.py, ``test_fd_order_of_fold_at_nu_016``).  Here:

- :func:`extended` gives a copy of a :class:`~problems.couette.model.CouetteProblem` whose
  ``residual`` runs the very same code on the grid of
  :func:`problems.discretization.extended_grid` (nodes, operators, weights in longdouble,
  dense products), so F(x, p) is evaluated in longdouble end to end when x and H are longdouble
  (and in clongdouble for complex x).  Only ``residual`` of the copy may be used: the Jacobian
  and everything else stay on the original (double) problem.
- :func:`fold_newton` solves the fold system F = 0, J phi = 0, c . phi = 1 (unknowns
  (u, phi, H); contin.foldcurve.FoldProblem) by Newton with iterative refinement (Wilkinson;
  Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., ch. 12): the Jacobian
  and its LU in double, the residual in longdouble with J phi by the complex step
  Im F(u + i h phi) / h (Squire & Trapp, SIAM Rev. 40, 1998; no subtractive cancellation), and
  the iterate accumulated in longdouble.  The fixed point is the longdouble solution; the
  double Jacobian only sets the contraction rate.  At the floor the refinement steps move H by
  the evaluation rounding (std 3-6e-14 at fd6 N = 450 .. 650), so H is their mean.

Measured floor (fold H at nu = 0.16): ~1e-14 absolute at fd6 N ~ 450, 2e-14 at 640, 3e-14 for
Chebyshev N = 64 .. 128, against 1-2e-10 in double; it needs FD rows that sum to exactly zero
(problems.discretization._zero_sum_row).  The copy relies on CouetteProblem's private operator
attributes (grid, _d1, _d2, _d1t, _d2t, _cache); tests/test_couette_scenes.py checks it against
the double residual.  The normal double code path is untouched (nothing here is imported by it).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.couette.model import CouetteProblem
from problems.discretization import extended_grid

LD = np.longdouble


def extended(pb: CouetteProblem) -> CouetteProblem:
    """A copy of ``pb`` whose :meth:`residual` evaluates in longdouble (see the module docstring).

    Raises ValueError for ``gravity=True`` (the cumulative-mass rows are not converted).
    """
    if pb.gravity:
        raise ValueError("extended precision is implemented for gravity-free problems only")
    ext = copy.copy(pb)
    g = extended_grid(pb.method, pb.N)
    ext.grid = g
    ext._d1, ext._d2 = g.d1, g.d2
    # Dense transposes: numpy's longdouble matmul (no BLAS) on (fields x n) @ (n x n).
    ext._d1t = np.ascontiguousarray(g.d1.T.toarray())
    ext._d2t = np.ascontiguousarray(g.d2.T.toarray())
    ext._cache = None
    for name in ("jacobian", "dense_jacobian", "dresidual_dp"):  # double-only: keep them off the copy
        if hasattr(pb, name):
            setattr(ext, name, _double_only(name))
    return ext


def _double_only(name: str):
    def refuse(*args, **kwargs):
        raise TypeError(f"{name}() is not available on the extended-precision copy; call it on the double problem")
    return refuse


@dataclass(frozen=True)
class FoldResult:
    """Outcome of :func:`fold_newton`.

    state : (2n + 1,) longdouble [u, phi, H], the last iterate
    H : the fold value (longdouble), mean over the ``average`` refinement steps at the floor
    jitter : standard deviation of H over those steps (the evaluation-rounding noise of one solve)
    corrections : max |update| per Newton step before the averaging (relative to max(1, |U|))
    """

    state: np.ndarray
    H: np.longdouble
    jitter: float
    corrections: tuple[float, ...]


def fold_residual(ext: CouetteProblem, state: np.ndarray, c: np.ndarray, p: Mapping[str, float],
                  second: str = "H") -> np.ndarray:
    """G(u, phi, p2) = [F(u), J(u) phi, c . phi - 1] in longdouble (J phi by the complex step)."""
    n = ext.size
    u, phi = state[:n], state[n:2 * n]
    q = {**p, second: state[2 * n]}
    f = ext.residual(u, q)
    h = LD(1e-40)  # any tiny step: the complex step has no cancellation
    jphi = ext.residual(u + 1j * h * phi, q).imag / h
    return np.concatenate([f, jphi, [np.dot(c.astype(LD), phi) - 1]])


def fold_newton(pb: CouetteProblem, state0: np.ndarray, c: np.ndarray, p: Mapping[str, float], *,
                second: str = "H", max_iterations: int = 20, average: int = 8) -> FoldResult:
    """Mixed-precision Newton on the fold system from ``state0`` = [u, phi, p2] (double or longdouble).

    Newton steps (Jacobian refactored each step, at least two) until a correction is below
    1e-13 relative, then ``average`` refinement steps with that LU, which only move the iterate by the
    longdouble evaluation rounding (std ~3e-14 in H at fd6 N = 448): their mean H is returned.
    Raises ValueError if Newton does not get below 1e-13 within ``max_iterations``.
    """
    from contin.foldcurve import FoldProblem

    ext = extended(pb)
    fold = FoldProblem(pb, second, np.asarray(c, float))
    U = np.asarray(state0).astype(LD)
    steps: list[float] = []
    lu = None
    for _ in range(max_iterations):
        lu = spla.splu(sp.csc_matrix(fold.jacobian(np.asarray(U, float), p)))
        dU = lu.solve(np.asarray(fold_residual(ext, U, fold.c, p, second), float))
        U = U - dU.astype(LD)
        steps.append(float(np.max(np.abs(dU)) / max(1.0, float(np.max(np.abs(U))))))
        if steps[-1] < 1e-13 and len(steps) > 1:
            break
    else:
        raise ValueError(f"mixed-precision fold Newton did not converge on {pb!r}: corrections {steps}")
    hs = []
    for _ in range(average):
        U = U - lu.solve(np.asarray(fold_residual(ext, U, fold.c, p, second), float)).astype(LD)
        hs.append(U[-1])
    h = np.array(hs, dtype=LD)
    return FoldResult(U, h.mean(), float(h.std()), tuple(steps))
