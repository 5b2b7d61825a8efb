"""Grid hooks of the non-local problems (``contin.adapt``'s ``grid_size``, ``with_grid``,
``transfer``, ``error_estimate``): adaptive resolution (``contin trace nonlocal-* --tol``) and
``contin verify``'s re-solves on a finer grid.

Both problems (:class:`problems.nonlocal_flow.plane.PlaneShear`,
:class:`problems.nonlocal_flow.cylinder.CylindricalCouette`) lay out their states alike: two
profiles on the grid (phi and g = W gamma, or phi and u) and the scalar P.

The estimate (``error_estimate``) is *measured*: the state's two-grid error
(``contin.adapt.two_grid_error``: one Newton correction on the grid GUARD_FACTOR times finer,
Richardson-scaled on FD grids), on Chebyshev grids together with the tail of the profiles'
Chebyshev coefficients (phi's relative to its variation across the gap, the second profile's
relative to its maximum; :meth:`NonlocalGridHooks.tail_error`).  The tail alone under-states the
error of these problems, and FD grids have none: session 15's audit (every stored state against a
cheb 128 reference solve) found ``contin trace nonlocal-cylinder`` (no guard then) storing states
1.3e-3 off on cheb 16, 1.1e-2 on fd2 32 -- the tail read 2.2e-5 where the error was 1.1e-3 -- and
plane shear's guard, Chebyshev only, let ``nonlocal-shear --method fd2 --grid 32`` store states
0.16 off, all with exit 0 and no warning.  The two-grid error matched the reference to 2-5 % in
every case.  Its cost is one residual, Jacobian and LU on the fine grid (states of 2N + 3
unknowns: ~1 ms on cheb 48).

The fixed-grid resolution guard (``under_resolved``, every trace on a --grid at
``resolution_tol``) measures the same: the two-grid error, with the Chebyshev tail on Chebyshev
grids (a run on a fixed grid ends MX "need a finer --grid" where it exceeds tol; an adaptive run
refines instead).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from problems.discretization import chebyshev_coefficients

Array = np.ndarray

#: Highest Chebyshev coefficients measured (as plane shear's resolution guard).
TAIL_MODES = 4

#: The resolution guard's fine grid: GUARD_FACTOR x the state's (``under_resolved``).
GUARD_FACTOR = 2


def chebyshev_tail(values: Array) -> float:
    """max |a_k| of the last TAIL_MODES Chebyshev coefficients of the interpolant through the
    values at the ascending Gauss-Lobatto nodes (``problems.discretization.chebyshev_coefficients``,
    the DCT-I of Trefethen 2000 ch. 8)."""
    return float(np.max(np.abs(chebyshev_coefficients(values)[-TAIL_MODES:])))


def profile_tails(phi: Array, other: Array) -> tuple[float, float]:
    """(tail of phi / its variation (0 for a flat phi), tail of the other profile / its maximum)."""
    span = float(np.ptp(phi))
    e_phi = chebyshev_tail(phi) / span if span > 1e-12 else 0.0
    e_other = chebyshev_tail(other) / max(float(np.max(np.abs(other))), 1e-300)
    return e_phi, e_other


class NonlocalGridHooks:
    """Mixin for a problem with ``grid``, ``split(x) -> (phi, profile, P)`` and ``with_grid(N)``."""

    @property
    def grid_size(self) -> int:
        """Number of grid intervals N."""
        return int(self.grid.intervals)  # type: ignore[attr-defined]

    @property
    def convergence_order(self) -> float:
        """The grid's nominal order (fd2/fd4/fd6: 2, 4, 6; Chebyshev: inf): the contin hook that
        scales two-grid differences to the coarse grid's error (``contin.adapt.richardson``)."""
        return float(self.grid.order)  # type: ignore[attr-defined]

    def inner_product_weights(self, x: Array, p: Mapping[str, Any] | None = None) -> Array:
        """Weights of contin's state norm (``contin.problem``): the grid's quadrature weights
        (sum 1: the gap-mean square in the nondimensional coordinate) on both profiles and 1 for
        the scalar P (a uniform profile of that value), so that sum w x^2 has a grid-independent
        limit and normal-form eigenvectors normalised in it converge with the grid."""
        w = np.asarray(self.grid.weights, dtype=float)  # type: ignore[attr-defined]
        return np.concatenate([w, w, np.ones(1)])

    def transfer(self, x: Array, other: Any) -> Array:
        """A state carried onto ``other``'s grid: both profiles by this grid's interpolant, P
        unchanged (linear in x)."""
        phi, f, P = self.split(np.asarray(x, dtype=float))  # type: ignore[attr-defined]
        y = other.grid.y
        grid = self.grid  # type: ignore[attr-defined]
        return np.concatenate([grid.interpolate(phi, y), grid.interpolate(f, y), [P]])

    def two_grid_error(self, x: Array, p: Mapping[str, Any]) -> float:
        """The state's measured relative error: one Newton correction on the grid GUARD_FACTOR
        times finer (``contin.adapt.two_grid_error``, Richardson-scaled on FD grids; inf where the
        fine Jacobian is singular)."""
        from contin.adapt import AdaptOptions, two_grid_error

        n = int(self.grid.intervals)  # type: ignore[attr-defined]
        err = two_grid_error(self, np.asarray(x, dtype=float), p, GUARD_FACTOR,
                             AdaptOptions(max_grid=max(GUARD_FACTOR * n, 8)))
        return math.inf if err is None else float(err)

    def under_resolved(self, x: Array, p: Mapping[str, Any], tol: float) -> str | None:
        """contin's resolution guard: None if the state's two-grid error (:meth:`two_grid_error`)
        and, on Chebyshev grids, its coefficient tail (:meth:`tail_error`) are <= tol."""
        method, n = self.grid.method, int(self.grid.intervals)  # type: ignore[attr-defined]
        if method == "cheb":
            tail = self.tail_error(x)
            if tail > tol:
                return (f"Chebyshev tail {tail:.1e} of the profiles' scale (> {tol:.1e}) on cheb {n}: "
                        "need a finer --grid")
        err = self.two_grid_error(x, p)
        if err > tol:
            return (f"two-grid error {err:.1e} (> {tol:.1e}) on {method} {n}, measured against the solve on "
                    f"{method} {GUARD_FACTOR * n}: need a finer --grid")
        return None

    def tail_error(self, x: Array) -> float:
        """The larger of :func:`profile_tails` on Chebyshev grids; 0 on finite-difference grids
        (no spectral tail there: the two-grid error alone measures them)."""
        if self.grid.method != "cheb":  # type: ignore[attr-defined]
            return 0.0
        phi, f, _ = self.split(np.asarray(x, dtype=float))  # type: ignore[attr-defined]
        return max(profile_tails(phi, f))

    def error_estimate(self, x: Array, p: Mapping[str, Any]) -> float:
        """Estimated relative error of x (module docstring): the larger of its two-grid error
        (:meth:`two_grid_error`) and, on Chebyshev grids, its coefficient tail (:meth:`tail_error`)."""
        tail = self.tail_error(x)
        return max(tail, self.two_grid_error(x, p))
