"""Branch switching at a simple branch point (BP) through the algebraic bifurcation equation.

At a simple BP x0 of G(x) = F(u, p) = 0 the extended Jacobian G_x = [J F_p] has a
two-dimensional kernel span{t1, phi} (t1 the tangent of the known branch) and a one-dimensional
left kernel psi.  Tangents alpha t1 + beta phi of the branches through x0 solve the algebraic
bifurcation equation (Keller 1977; Seydel 2010, sec. 5.6; Govaerts 2000, sec. 3.4)

    a alpha^2 + 2 b alpha beta + c beta^2 = 0,
    a = psi . G_xx[t1, t1],  b = psi . G_xx[t1, phi],  c = psi . G_xx[phi, phi].

(alpha, beta) = (1, 0) is a root (the known branch, a ~ 0); the other root, computed without
cancellation, is alpha / beta = c / q with q = -(b + sign(b) sqrt(b^2 - a c)) ~ -2b.  A
transcritical point has c != 0; at a pitchfork c = 0 and the new tangent is phi itself.
G_xx[v, w] is the central difference of G_x v along w (two sparse Jacobians).

This module finds the first point of each new branch (:func:`departures`); the tracer
(``contin.continuation``) imports it and traces on (:func:`contin.continuation.switch`), so the
two modules do not import each other.

Null vectors come from the bordered matrix [[J, F_p], [<t1, .>]], whose kernel at the BP is
phi (orthogonal to t1) and whose left kernel is (psi, 0), by inverse iteration on its sparse LU.
At a symmetry-breaking BP (found by the antisymmetric test) they are the null vectors of J
restricted to the -1 eigenspace of the symmetry, so the new direction is the symmetry-breaking
mode exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint
from contin.corrector import correct
from contin.extended import ExtendedSystem
from contin.linalg import bordered, factorize, factorize_bordered, inverse_iteration
from contin.options import ContinuationOptions
from contin.problem import Array
from contin.testfunctions import Antisymmetric

#: Relative size of the difference step for second derivatives.
FD_STEP = 1e-5
#: Halvings of the first step off the BP before a direction is given up.
MAX_START_HALVINGS = 24


def null_directions(system: ExtendedSystem, x0: Array, t1: Array, symmetry_breaking: bool) -> tuple[Array, Array]:
    """(phi, psi): second kernel vector of G_x (theta-unit, theta-orthogonal to t1) and left null vector."""
    n = x0.size - 1
    jac, fp = system.jacobian(x0)
    anti = Antisymmetric.from_problem(system.problem, n) if symmetry_breaking else None
    if anti is not None and anti.dimension > 0:
        right, left = anti.null_vectors(jac)
        phi = system.pack(right, 0.0)
        psi = left
    else:
        row = system.row(t1)
        fact = factorize_bordered(jac, fp, row)
        if fact is None:  # exactly singular at the located point: shift by a rounding-level amount
            a = bordered(jac, fp, row)
            shift = 1e-14 * max(1.0, float(abs(a).max()))
            fact = factorize(a + shift * sp.identity(n + 1, format="csc"))
        if fact is None:
            raise ValueError("cannot factorize the bordered Jacobian at the branch point")
        phi = inverse_iteration(fact)
        psi = inverse_iteration(fact, trans="T")[:n]
    phi = system.unit(phi - system.dot(phi, t1) * t1)
    return _oriented(system, x0, phi), psi / np.linalg.norm(psi)


def _oriented(system: ExtendedSystem, x0: Array, phi: Array) -> Array:
    """phi with a reproducible sign: the order parameter grows along +phi (else the largest
    component is positive).  A null vector's sign is arbitrary -- it follows rounding in the LU
    -- and it decides which half of a pitchfork ``directions=(+1,)`` follows."""
    h = 1e-6 / max(1.0, float(np.max(np.abs(phi))))
    # NaN without an order parameter (ExtendedSystem.order_parameter)
    slope = (system.order_parameter(x0 + h * phi) - system.order_parameter(x0 - h * phi)) / (2 * h)
    if abs(slope) > 1e-6 * max(1.0, abs(system.order_parameter(x0))):  # False for NaN
        return phi if slope > 0 else -phi
    k = int(np.argmax(np.abs(phi)))
    return phi if phi[k] > 0 else -phi


def second_derivative(system: ExtendedSystem, x0: Array, v: Array, w: Array) -> Array:
    """G_xx[v, w] ~ (G_x(x0 + h w) v - G_x(x0 - h w) v) / (2h)."""
    return _SecondDerivatives(system, x0)(v, w)


class _SecondDerivatives:
    """:func:`second_derivative` at one x0 for several (v, w), each pair of Jacobians
    G_x(x0 +- h w) evaluated once per direction w (the ABE needs four products but only two
    directions)."""

    def __init__(self, system: ExtendedSystem, x0: Array) -> None:
        self.system = system
        self.x0 = x0
        self.scale = FD_STEP * max(1.0, float(np.max(np.abs(x0))))
        self.jacobians: list[tuple[Array, float, tuple]] = []

    def __call__(self, v: Array, w: Array) -> Array:
        for w_, h, pair in self.jacobians:
            if w_ is w:
                break
        else:
            h = self.scale / max(float(np.max(np.abs(w))), 1e-300)
            # The problem's own (sparse) J: a dense product would round the coefficients that
            # vanish in exact arithmetic (c at a pitchfork, ~1e-12) differently, and with them
            # the new tangent at the 1e-10 level; they are computed as they always were.
            pair = (self.system.jacobian(self.x0 + h * w, dense=False),
                    self.system.jacobian(self.x0 - h * w, dense=False))
            self.jacobians.append((w, h, pair))
        (jp, fpp), (jm, fpm) = pair
        return ((np.asarray(jp @ v[:-1]) + fpp * v[-1]) - (np.asarray(jm @ v[:-1]) + fpm * v[-1])) / (2 * h)


def bifurcation_coefficients(system: ExtendedSystem, x0: Array, t1: Array, phi: Array, psi: Array) -> tuple[float, float, float]:
    """(a, b, c) of the algebraic bifurcation equation (module docstring)."""
    n = x0.size - 1
    gxx = _SecondDerivatives(system, x0)
    a = float(psi @ gxx(t1, t1)[:n])
    b = 0.5 * float(psi @ (gxx(t1, phi) + gxx(phi, t1))[:n])
    c = float(psi @ gxx(phi, phi)[:n])
    return a, b, c


def new_tangent(system: ExtendedSystem, t1: Array, phi: Array, a: float, b: float, c: float) -> Array:
    """Theta-unit tangent of the bifurcating branch from the ABE root other than t1."""
    scale = max(abs(a), abs(b), abs(c))
    if scale == 0.0 or abs(b) <= 1e-8 * scale:
        raise ValueError(
            f"the branch point is not simple (ABE coefficients a={a:.3g}, b={b:.3g}, c={c:.3g}); cannot switch"
        )
    q = -(b + math.copysign(math.sqrt(max(b * b - a * c, 0.0)), b))
    return system.unit((c / q) * t1 + phi)


@dataclass(frozen=True)
class Departure:
    """The first point of one bifurcating half-branch (:func:`departures`,
    :func:`contin.ndbp.nd_departures`).

    x0 : the branch point (u, p); start : the converged first point off it; tangent : the
    theta-unit tangent there (d * tau); step : the accepted length of the first step;
    note : how the direction was found (the reduced root at a BP of kernel dimension > 1).
    """

    system: ExtendedSystem
    x0: Array
    start: Array
    tangent: Array
    step: float
    direction: int
    note: str = ""


def first_point(system: ExtendedSystem, x0: Array, tau: Array, step: float,
                options: ContinuationOptions) -> tuple[Array | None, float, str]:
    """(start, step, reason): the corrector's solution from x0 + step * tau in the hyperplane
    orthogonal to tau, the step halved (up to MAX_START_HALVINGS times) until the solution lies
    near the predictor; start None (and the reason) when no step is accepted."""
    corr = None
    # The correction of a pitchfork start grows like curvature * step^2 (H - H_c ~ a delta^2),
    # so a strongly bent branch (gPCF at nu = 0.16: |a| ~ 1e5) needs steps far below ds before
    # the test below passes: halve up to MAX_START_HALVINGS times.
    for _ in range(MAX_START_HALVINGS):
        x_pred = x0 + step * tau
        corr = correct(system, x_pred, system.row(tau), options.newton, give_up=_FarFromPredictor(system, x_pred, 0.5 * step))
        # A good start lies near the predictor; a large correction means the predictor fell
        # back onto the known branch or diverged.
        if corr.converged and system.norm(corr.x - x_pred) < 0.5 * step:
            return corr.x, step, ""
        step *= 0.5
    why = "no corrected first step near the predictor" if corr is None or corr.converged else corr.message
    return None, 2 * step, f"{why} (first step halved to {2 * step:.3g})"


def departures(
    problem: Any,
    branch: Branch,
    point: SpecialPoint,
    options: ContinuationOptions = ContinuationOptions(),
    *,
    directions: tuple[int, ...] = (+1, -1),
    ds: float | None = None,
) -> list[Departure | str]:
    """The first point of each bifurcating half-branch at the simple BP ``point`` of ``branch``.

    The tangent tau of the new branch solves the ABE (module docstring); the first point comes
    from :func:`first_point`.  The list follows ``directions``; a direction without an accepted
    first step gives the reason (a str).  Tracing the rest of the branch is
    :func:`contin.continuation.switch` (this module does not import the tracer).

    Raises
    ------
    ValueError
        If ``point`` is not a BP with a tangent, or the BP is not simple (b = 0 in the ABE).
    """
    if point.type != "BP" or point.tangent is None:
        raise ValueError(f"switching needs a BP with its tangent, got {point.type} ({point.name})")
    from contin.adapt import on_grid

    problem = on_grid(problem, point.grid)  # a BP of an adaptive run is a solution on its own grid
    param = branch.parameter
    system = ExtendedSystem(problem, point.params, param, options.step.theta)
    u0 = np.asarray(point.state, dtype=float)
    system.n = u0.size
    x0 = system.pack(u0, point.params[param])
    t1 = system.unit(np.asarray(point.tangent, dtype=float))
    phi, psi = null_directions(system, x0, t1, "symmetry-breaking" in point.note)
    a, b, c = bifurcation_coefficients(system, x0, t1, phi, psi)
    tau = new_tangent(system, t1, phi, a, b, c)
    out: list[Departure | str] = []
    for d in directions:
        start, step, why = first_point(system, x0, d * tau, abs(ds if ds is not None else options.step.ds), options)
        out.append(Departure(system, x0, start, d * tau, step, d) if start is not None else f"direction {d:+d}: {why}")
    return out


def first_step_options(options: ContinuationOptions, step: float) -> ContinuationOptions:
    """``options`` with ds set to the accepted first step (clipped to [ds_min, ds_max], sign of ds).

    The accepted first step measures the branch's scale near the BP: continuing with it
    beats restarting at options.step.ds, which the halvings of :func:`departures` just rejected.
    """
    sopt = options.step
    return replace(options, step=replace(sopt, ds=math.copysign(min(max(step, sopt.ds_min), sopt.ds_max), sopt.ds)))


class _FarFromPredictor:
    """``give_up`` for the corrector of a trial first step: stop as soon as the limit is sure to
    lie at least ``limit`` (theta-norm) from the predictor, where the trial is rejected anyway.

    Once Newton contracts (|dx_k| <= |dx_k-1| / 2, k >= 2) the remaining updates add up to at
    most |dx_k| (geometric series; quadratic convergence makes them far smaller), so
    |x_k - x_pred| - |dx_k| >= limit bounds the distance of the limit from below.  Saves the
    last iterations of the rejected trials of a strongly bent branch (gPCF at cheb 12: 4 of
    the 12 Newton iterations spent on rejected trials).
    """

    def __init__(self, system: ExtendedSystem, x_pred: Array, limit: float) -> None:
        self.system, self.x_pred, self.limit = system, x_pred, limit
        self.last = math.inf

    def __call__(self, x: Array, dx: Array) -> str | None:
        step = self.system.norm(dx)
        contracting, self.last = step <= 0.5 * self.last < math.inf, step  # from the second update on
        if contracting and self.system.norm(x - self.x_pred) - step >= self.limit:
            return "too far from the predictor"
        return None


def prepend(system: ExtendedSystem, br: Branch, x0: Array, t0: Array) -> Branch:
    """Insert the branch point itself as point 0 of a bifurcated branch."""
    if len(br) == 0:
        return br
    rec = system.record(x0)
    if br.sizes is not None:  # an adaptive branch: its points may lie on other grids than the BP
        return _prepend_regridded(system, br, x0, t0, rec)
    first_len = system.norm(system.pack(br.state(0), br.parameter_values[0]) - x0)
    br.params = {k: np.concatenate([[system.params_at(x0[-1])[k]], v]) for k, v in br.params.items()}
    br.observables = {k: np.concatenate([[rec.get(k, np.nan)], v]) for k, v in br.observables.items()}
    br.states = np.vstack([x0[:-1][None, :], br.states])
    if br.state_index is not None:
        br.state_index = np.concatenate([[0], br.state_index + 1])
    br.tangents = np.vstack([system.unit(t0)[None, :], br.tangents])
    ds = br.ds.copy()
    ds[0] = first_len
    br.ds = np.concatenate([[0.0], ds])
    br.newton_iterations = np.concatenate([[0], br.newton_iterations])
    br.special_points = [replace(sp, index=sp.index + 1) for sp in br.special_points]
    return br


def _prepend_regridded(system: ExtendedSystem, br: Branch, x0: Array, t0: Array, rec: dict[str, float]) -> Branch:
    """:func:`_prepend` for a branch of an adaptive run (``Branch.sizes``): rows padded, the BP's
    grid in the grid column, the first step length measured on the BP's grid."""
    from contin.adapt import on_grid
    from contin.branch import pad_rows

    pb = system.problem
    first = br.state(0)
    if first.size != x0.size - 1:
        first = on_grid(pb, br.grid_at(0)).transfer(first, pb)
    first_len = system.norm(system.pack(first, br.parameter_values[0]) - x0)
    br.params = {k: np.concatenate([[system.params_at(x0[-1])[k]], v]) for k, v in br.params.items()}
    br.observables = {k: np.concatenate([[rec.get(k, np.nan)], v]) for k, v in br.observables.items()}
    width = max(br.states.shape[1], x0.size - 1)
    br.states = pad_rows([x0[:-1], *br.states], width)
    if br.state_index is not None:
        br.state_index = np.concatenate([[0], br.state_index + 1])
    nf = len(br.free)
    tangents = [br.tangents[i, : int(br.sizes[i]) + nf] for i in range(len(br))]
    br.tangents = pad_rows([system.unit(t0), *tangents], max(br.tangents.shape[1], x0.size))
    br.sizes = np.concatenate([[x0.size - 1], br.sizes])
    if br.grid is not None:
        br.grid = np.concatenate([[int(pb.grid_size)], br.grid])
    ds = br.ds.copy()
    ds[0] = first_len
    br.ds = np.concatenate([[0.0], ds])
    br.newton_iterations = np.concatenate([[0], br.newton_iterations])
    br.special_points = [replace(sp, index=sp.index + 1) for sp in br.special_points]
    return br
