"""The resolution and grid-transfer hooks shared by the wall-bounded kinetic-theory problems.

gPCF (:class:`problems.couette.model.CouetteProblem`) and the 2-D disks
(:class:`problems.disks.model.DiskCouetteProblem`) lay out their states alike -- profiles nu, u,
T on the grid, the scalar P, and M with gravity (``unpack``/``pack``) -- and are judged by one
resolution measure, :mod:`problems.couette.resolution` (Chebyshev tails, nu's against the
distance to packing, plus the rounding term that sets the precision limit).  This mixin gives
both the contin hooks built on that (``contin.problem``: ``under_resolved``, ``grid_size``,
``transfer``, ``error_estimate``, ``solution_error``, ``rounding_error``, ``vector_error``,
``suggest_grid``, ``inner_product_weights``); each class keeps its own ``with_grid``.  The measure is imported where it is
used (it loads scipy.sparse), so defining a problem class stays light.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class ResolutionHooks:
    """Mixin: contin's resolution guard and adaptive-grid hooks for a problem with ``N``,
    ``grid``, ``unpack`` and ``pack`` (module docstring)."""

    def under_resolved(self, x: Array, p: Mapping[str, Any], tol: float) -> str | None:
        """None if the grid resolves x to estimated relative error ``tol``, else the reason.

        The contin hook (``ContinuationOptions.resolution_tol``); the estimate, a Chebyshev tail
        measured against the distance to packing, is :mod:`problems.couette.resolution`.
        """
        from problems.couette.resolution import under_resolved

        return under_resolved(self, x, p, tol)

    def inner_product_weights(self, x: Array, p: Mapping[str, Any] | None = None) -> Array:
        """Weights of contin's state norm (``contin.problem``): the grid's quadrature weights on
        each profile (nu, u, T and M; they sum to 1, the nondimensional gap width, so a profile
        counts with its mean square over the gap) and 1 for the scalar P, which is what a
        uniform profile of that value weighs: every piece of sum w x^2 has a grid-independent
        limit, so normal-form eigenvectors normalised in it converge with the grid.  The fields
        are nondimensional (nu a fraction, u and T in wall units) and count equally."""
        w = np.asarray(self.grid.weights, dtype=float)  # type: ignore[attr-defined]
        parts = [w, w, w, np.ones(1)] + ([w] if self.gravity else [])  # type: ignore[attr-defined]
        return np.concatenate(parts)

    @property
    def grid_size(self) -> int:
        """Number of grid intervals N (the size adaptive resolution changes)."""
        return self.N  # type: ignore[attr-defined, no-any-return]

    @property
    def convergence_order(self) -> float:
        """The grid's nominal order (fd2/fd4/fd6: 2, 4, 6; Chebyshev: inf): the contin hook that
        scales two-grid differences to the coarse grid's error (``contin.adapt.richardson``)."""
        return float(self.grid.order)  # type: ignore[attr-defined]

    def transfer(self, x: Array, other: Any) -> Array:
        """A state (or the state part of a tangent) carried onto ``other``'s grid: the profiles
        nu, u, T (and M with gravity) by this grid's interpolant, P unchanged; linear in x."""
        nu, u, T, P, M = self.unpack(np.asarray(x, dtype=float))  # type: ignore[attr-defined]
        y = other.grid.y
        grid = self.grid  # type: ignore[attr-defined]
        moved = [grid.interpolate(f, y) for f in (nu, u, T)]
        return other.pack(*moved, P, None if M is None else grid.interpolate(M, y))  # type: ignore[no-any-return]

    def error_estimate(self, x: Array, p: Mapping[str, Any]) -> float:
        """Estimated relative error of x: the measure of :mod:`problems.couette.resolution`
        (max of truncation and rounding) behind :meth:`under_resolved`."""
        from problems.couette.resolution import estimated_error

        return estimated_error(self, x, p)  # resolution(...).error without the Resolution

    def solution_error(self, x: Array, ref: Array, p: Mapping[str, Any]) -> float:
        """Relative error of state x against a reference solution ref on this grid, in the norm of
        :meth:`error_estimate` (``problems.couette.resolution.solution_error``; ``contin.verify``)."""
        from problems.couette.resolution import solution_error

        return solution_error(self, x, ref, p)

    def rounding_error(self, x: Array, p: Mapping[str, Any]) -> float:
        """The part of :meth:`error_estimate` no finer grid lowers: the rounding error of nu
        against the distance to packing (``Resolution.rounding``, the precision limit)."""
        from problems.couette.resolution import estimated_rounding

        return estimated_rounding(self, x, p)  # resolution(...).rounding without the transform

    def vector_error(self, v: Array) -> float:
        """Estimated relative error of a perturbation v (a null vector at a branch point): the
        largest Chebyshev tail of its profiles nu, u, T relative to the largest profile
        coefficient of v (FD profiles carried to the Chebyshev grid as in the resolution guard)."""
        from problems.couette.resolution import profile_vector_error

        nu, u, T, _, _ = self.unpack(np.asarray(v, dtype=float))  # type: ignore[attr-defined]
        return profile_vector_error(self.grid, (nu, u, T))  # type: ignore[attr-defined]

    def suggest_grid(self, x: Array, p: Mapping[str, Any], tol: float) -> int:
        """The grid the resolution estimate expects to meet tol (``Resolution.suggested_N``)."""
        from problems.couette.resolution import resolution

        return resolution(self, x, p, tol).suggested_N
