"""Two-parameter continuation of symmetry-breaking branch points (BP curves).

On a branch of S-invariant states (S an involution with F(S u) = S F(u)) a symmetry-breaking
pitchfork is a point where J has a simple null vector phi with S phi = -phi.  Werner & Spence
(SIAM J. Numer. Anal. 21, 1984) showed that such a point is a *regular* solution of the fold
system of Moore & Spence (``contin.foldcurve``)

    F(u, p1, p2) = 0,      J(u, p1, p2) phi = 0,      c . phi - 1 = 0

once u is restricted to the symmetric subspace Fix(S) and phi to the antisymmetric one.  In the
full space the system is singular all along the curve ((phi, w, 0) is a null vector: the
bifurcating branch), so Newton there only converges to the rounding noise of that null
direction.  :class:`BPCurveProblem` therefore works in reduced coordinates: u = Q_s y,
phi = Q_a z with orthonormal bases Q_s of Fix(S) and Q_a of its complement, and the equations
projected by Q_s^T (F is S-symmetric for symmetric u) and Q_a^T (J phi is antisymmetric).
Residual, Jacobian and dF/dp are the fold system's, sandwiched between the projections.

The quadratic fold coefficient psi . B(phi, phi) vanishes identically on a BP curve
(B(phi, phi) is symmetric, psi antisymmetric), so no cusps are looked for; extrema of the
second parameter are not located either (use the LP points of the continuation parameter, or
swap the two parameters).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint
from contin.foldcurve import FoldProblem, trace_augmented
from contin.options import ContinuationOptions
from contin.problem import Array
from contin.testfunctions import Antisymmetric, _antisymmetric_basis


class BPCurveProblem:
    """The Werner-Spence system in reduced coordinates V = [y, z, p2] (module docstring)."""

    def __init__(self, fold: FoldProblem, qs: sp.spmatrix, qa: sp.spmatrix) -> None:
        self.fold = fold
        self.parameter_names = fold.parameter_names
        self.second = fold.second
        self.P = sp.block_diag([qs, qa, sp.identity(1)], format="csr")
        self.L = sp.csr_matrix(self.P.T)
        self.ms, self.ma = qs.shape[1], qa.shape[1]
        self.index = self.ms + self.ma  # p2 in the reduced state

    def full(self, v: Array) -> Array:
        return np.asarray(self.P @ v)

    def reduce(self, w: Array) -> Array:
        return np.asarray(self.L @ w)

    def residual(self, v: Array, p: Mapping[str, float]) -> Array:
        return self.reduce(self.fold.residual(self.full(v), p))

    def jacobian(self, v: Array, p: Mapping[str, float]) -> sp.csr_matrix:
        return sp.csr_matrix(self.L @ self.fold.jacobian(self.full(v), p) @ self.P)

    def dresidual_dp(self, v: Array, p: Mapping[str, float], name: str) -> Array:
        return self.reduce(self.fold.dresidual_dp(self.full(v), p, name))

    def order_parameter(self, v: Array, p: Mapping[str, float]) -> float:
        return self.fold.order_parameter(self.full(v), p)

    def observables(self, v: Array, p: Mapping[str, float]) -> dict[str, float]:
        return self.fold.observables(self.full(v), p)

    def admissible(self, v: Array, p: Mapping[str, float]) -> str | None:
        return self.fold.admissible(self.full(v), p)

    def under_resolved(self, v: Array, p: Mapping[str, float], tol: float) -> str | None:
        return self.fold.under_resolved(self.full(v), p, tol)

    @property
    def n(self) -> int:  # for contin.hopfcurve._second_bound_event's default (not used: index given)
        return self.fold.n


def bp_curve_start(problem: object, point: SpecialPoint, second: str) -> tuple[BPCurveProblem, Array]:
    """The reduced Werner-Spence problem and its start vector at a symmetry-breaking BP."""
    if point.type != "BP" or "symmetry-breaking" not in point.note:
        raise ValueError(f"{point.name} is not a symmetry-breaking BP ({point.note or 'no symmetry noted'}); "
                         "only those are regular points of the extended system that BP curves continue "
                         "(Werner & Spence 1984)")
    u = np.asarray(point.state, float)
    anti = Antisymmetric.from_problem(problem, u.size)
    if anti is None or anti.dimension == 0:
        raise ValueError("the problem provides no symmetry, so its BP curves cannot be continued")
    phi, _ = anti.null_vectors(problem.jacobian(u, point.params))  # type: ignore[attr-defined]
    c = phi / float(phi @ phi)
    fold = FoldProblem(problem, second, c)
    qs = _antisymmetric_basis(sp.csc_matrix(-anti.s))  # {v : S v = v}
    red = BPCurveProblem(fold, qs, anti.q)
    v0 = red.reduce(np.concatenate([anti.symmetrize(u), c, [point.params[second]]]))
    return red, v0


def trace_bp_curve(problem: object, point: SpecialPoint, second: str, options: ContinuationOptions, *,
                   parameter: str, both: bool = True, branch_id: str = "bp-curve") -> Branch:
    """Continue the symmetry-breaking BP ``point`` in (parameter, second); both halves joined.

    Returns a Branch of kind 'bp-curve' whose states are the full [u, phi, p2] (like a fold
    curve's), with ``second`` as a parameter column and ``LP`` points at the extrema of
    ``parameter``; bounds on either parameter in ``options.bounds`` end it with EP.  ValueError
    for a BP that is not symmetry-breaking or a problem without a symmetry.
    """
    red, start = bp_curve_start(problem, point, second)
    raw = trace_augmented(red, start, point, second, red.index, options, parameter=parameter, both=both,
                          branch_id=branch_id, kind="bp-curve")
    return _expanded(raw, red)


def _expanded(branch: Branch, red: BPCurveProblem) -> Branch:
    """The traced reduced branch with full states [u, phi, p2] and p2 as a parameter column."""
    states = (red.P @ branch.states.T).T
    tangents = np.column_stack([(red.P @ branch.tangents[:, :-1].T).T, branch.tangents[:, -1]])
    params = dict(branch.params)
    params[red.second] = branch.states[:, red.index].copy()

    def point(s: SpecialPoint) -> SpecialPoint:
        full = red.full(s.state)
        tangent = None if s.tangent is None else np.concatenate([red.full(s.tangent[:-1]), s.tangent[-1:]])
        return replace(s, state=full, tangent=tangent, params={**s.params, red.second: float(s.state[red.index])},
                       note=s.note or (f"extremum of {branch.parameter}" if s.type == "LP" else s.note))

    return replace(branch, free=(branch.parameter, red.second), params=params, states=states, tangents=tangents,
                   observables={k: v for k, v in branch.observables.items() if k != red.second},
                   special_points=[point(s) for s in branch.special_points], kind="bp-curve")
