"""Periodic orbits: the cycle problem, its start at a Hopf point, and its continuation.

:class:`CycleProblem` is the collocated periodic BVP of ``contin.collocation`` written as a
contin Problem (state x = [node values, T], the problem's parameters), so that the ordinary
pseudo-arclength tracer (``contin.continuation.trace``) continues it in one parameter.  The
tracer's LP test on this system finds the folds of cycles (relabelled LPC), its BP test branch
points of cycles; the problem brings the Floquet point tests PD and NS (``contin.floquet``).

Start at a Hopf point (u_H, p_H) with J q = i omega M q (``contin.hopf.hopf_vectors``):

    u(t) = u_H + eps Re(q e^{2 pi i t}),   T = 2 pi / omega,
    p = p_H - omega l1 eps^2 / (4 Re lambda'(p_H))

(the amplitude of Kuznetsov's normal form z' = lambda z + c1 z |z|^2, u = u_H + 2 Re(z q),
l1 = Re c1 / omega, so |z|^2 = -Re lambda / Re c1 and eps = 2 |z|; p = p_H when l1 is not
available).  The guess is corrected with the parameter free and its projection on the Hopf
mode held at eps (a pseudo-arclength corrector with the Hopf mode as direction), then traced away
from the Hopf point.

Phase condition: AUTO's int_0^1 <u(t), u_ref'(t)> dt = 0 with u_ref the start orbit for the
first ``rephase_every`` steps; the branch is then traced on in segments, each with the last
orbit of the previous one as reference (AUTO updates it every step; a reference orbit that is
kept too long lets the phase condition degenerate as the orbit changes shape).

Recorded per point (``Branch.observables``): period T, amplitude (max - min over the nodes of the
problem's order parameter, or of the first component without one), l2norm (AUTO's L2-NORM,
sqrt(int_0^1 |u|^2 dt)), floquet_error (the trivial multiplier's distance from 1), flow_error
(the residual of its eigenvector, the check that also holds at folds: ``contin.floquet``); 'phi'
is the amplitude.  Floquet multipliers (all but the trivial one) are the ``eigenvalues`` column, with
``stable`` and ``n_unstable`` from them.

Supported: problems with the required methods (residual, jacobian, dresidual_dp) and, optionally,
a ``mass_matrix`` taken as constant (its value at the Hopf point; M u' = T F).  Not supported:
problems with their own ``eigenproblem`` (their linearization is not J's).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint
from contin.collocation import NCOL, NTST, Collocation, Mesh
from contin.floquet import FLOQUET_DOUBTFUL, FloquetTest, Multipliers, multipliers
from contin.options import ContinuationOptions
from contin.problem import Array, has, inner_product_weights

log = logging.getLogger("contin")

#: Branch.kind of a branch of periodic orbits.
KIND = "periodic-orbits"


@dataclass(frozen=True)
class CycleOptions:
    """Settings of a cycle continuation.

    ntst, ncol : mesh intervals and Gauss points per interval (AUTO's NTST, NCOL).
    amplitude : eps of the first orbit u_H + eps Re(q e^{2 pi i t}) (q with q^H W q = 1, W the
        problem's ``inner_product_weights`` or I); None: 1e-3 max(1, |u_H|_inf) ... see
        :func:`default_amplitude`.
    rephase_every : steps after which the phase reference is renewed (a new segment).
    floquet_tol : largest distance of the trivial multiplier from 1 of an accepted orbit: past it
        the mesh no longer resolves the orbit (a sharpening relaxation oscillation, a period
        growing towards a homoclinic orbit) and the branch ends with MX "under-resolved at ...",
        through the tracer's resolution guard (``ContinuationOptions.resolution_tol`` not None);
        None: no such end (a warning line names the worst point instead).
    """

    ntst: int = NTST
    ncol: int = NCOL
    amplitude: float | None = None
    rephase_every: int = 20
    floquet_tol: float | None = FLOQUET_DOUBTFUL

    def __post_init__(self) -> None:
        if self.ntst < 2 or self.ncol < 1:
            raise ValueError(f"cycles need NTST >= 2 and NCOL >= 1, got NTST = {self.ntst}, NCOL = {self.ncol}")
        if self.amplitude is not None and not (math.isfinite(self.amplitude) and self.amplitude > 0):
            raise ValueError(f"the start amplitude must be a finite number > 0, got {self.amplitude}")
        if self.floquet_tol is not None and not (math.isfinite(self.floquet_tol) and self.floquet_tol > 0):
            raise ValueError(f"floquet_tol must be a finite number > 0 or None, got {self.floquet_tol}")
        if self.rephase_every < 1:
            raise ValueError(f"rephase_every must be >= 1, got {self.rephase_every}")


def default_amplitude(u_h: Array) -> float:
    """The start amplitude when none is given: 1e-2 max(1, |u_H|_inf)."""
    return 1e-2 * max(1.0, float(np.max(np.abs(u_h), initial=0.0)))


class CycleProblem:
    """The periodic BVP of ``problem`` on ``mesh`` as a contin Problem (module docstring)."""

    def __init__(self, problem: Any, mesh: Mesh, reference: Array, mass: Array | None = None,
                 floquet_tol: float | None = FLOQUET_DOUBTFUL) -> None:
        if has(problem, "eigenproblem"):
            raise ValueError("periodic orbits need the dynamics M u' = F(u, p); this problem defines its own "
                             "eigenproblem (its linearization is not the Jacobian of F), which cycles do not support")
        self.problem = problem
        self.mesh = mesh
        self.colloc = Collocation(problem, mesh, reference, mass)
        self.parameter_names = tuple(problem.parameter_names)
        self._cache: tuple[bytes, Multipliers] | None = None
        self.floquet_tol = floquet_tol

    # --- the Problem protocol ------------------------------------------------------------
    def residual(self, x: Array, p: dict[str, float]) -> Array:
        return self.colloc.residual(x, p)

    def jacobian(self, x: Array, p: dict[str, float]) -> sp.csc_matrix:
        return self.colloc.jacobian(x, p)

    def dresidual_dp(self, x: Array, p: dict[str, float], name: str) -> Array:
        return self.colloc.dresidual_dp(x, p, name)

    def validate(self, p: dict[str, float]) -> None:
        if has(self.problem, "validate"):
            self.problem.validate(p)

    # --- recorded numbers --------------------------------------------------------------------
    def _scalar(self, nodes: Array, p: dict[str, float]) -> Array:
        if has(self.problem, "order_parameter"):
            return np.array([float(self.problem.order_parameter(v, p)) for v in nodes])
        return nodes[:, 0]

    def order_parameter(self, x: Array, p: dict[str, float]) -> float:
        """The amplitude (max - min over the nodes of the order parameter / first component)."""
        s = self._scalar(self.mesh.split(x)[0], p)
        return float(np.max(s) - np.min(s))

    def observables(self, x: Array, p: dict[str, float]) -> dict[str, float]:
        nodes, period = self.mesh.split(x)
        s = self._scalar(nodes, p)
        return {"period": period, "amplitude": float(np.max(s) - np.min(s)), "l2norm": self.mesh.l2_norm(nodes)}

    # --- Floquet ---------------------------------------------------------------------------
    def multipliers(self, x: Array, p: dict[str, float]) -> Multipliers:
        """Floquet multipliers of the orbit x (``contin.floquet``), cached for the last x."""
        key = np.asarray(x, dtype=float).tobytes() + repr(sorted(p.items())).encode()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        u0 = self.mesh.split(x)[0][0]
        flow = np.asarray(self.problem.residual(u0, p), dtype=float)
        if self.colloc.mass is not None:
            flow = np.linalg.lstsq(self.colloc.mass, flow, rcond=None)[0]
        mu = multipliers(self.colloc.interval_blocks(x, p), flow)
        self._cache = (key, mu)
        return mu

    def under_resolved(self, x: Array, p: dict[str, float], tol: float) -> str | None:
        """The trivial multiplier's distance from 1 above ``floquet_tol`` (the tracer's ``tol`` is
        a relative state error, which this estimate is not: it is not used)."""
        if self.floquet_tol is None:
            return None
        try:
            err = self.multipliers(x, p).flow_error
        except np.linalg.LinAlgError:
            err = math.inf
        if err <= self.floquet_tol:
            return None
        return (f"the monodromy moves the flow direction by {err:.1e} (> {self.floquet_tol:g}): NTST = "
                f"{self.mesh.ntst} does not resolve the orbit (try NTST = {2 * self.mesh.ntst})")

    def point_tests(self) -> list[Any]:
        return [FloquetTest(self, "PD"), FloquetTest(self, "NS")]

    def orbit(self, x: Array, samples: int | None = None) -> tuple[Array, Array]:
        """(t, u(t)): the orbit at its nodes (t in [0, 1)), or at ``samples`` equally spaced times."""
        nodes, _ = self.mesh.split(x)
        if samples is None:
            return self.mesh.node_times, nodes
        t = np.linspace(0.0, 1.0, samples, endpoint=False)
        return t, self.mesh.evaluate(nodes, t)


# --- start at a Hopf point ------------------------------------------------------------------
@dataclass(frozen=True)
class HopfStart:
    """The Hopf data a cycle branch starts from: u_H, p_H, omega, q (J q = i omega M q),
    Re lambda' and the predicted parameter shift of the first orbit."""

    state: Array
    params: dict[str, float]
    omega: float
    q: np.ndarray
    dlambda: float
    l1: float
    mass: Array | None


def _dense(a: Any) -> Array:
    return a.toarray() if sp.issparse(a) else np.asarray(a, dtype=float)


def hopf_start(problem: Any, point: SpecialPoint, parameter: str) -> HopfStart:
    """The Hopf data of ``point`` (an HB) for cycles in ``parameter`` (module docstring)."""
    from contin.hopf import hopf_vectors, pencil

    if point.type != "HB":
        raise ValueError(f"periodic orbits start at a Hopf point (HB), not at {point.name} ({point.type})")
    u = np.asarray(point.state, dtype=float)
    q_params = dict(point.params)
    jac, mass = pencil(problem, u, q_params)
    omega = float(point.data.get("omega", math.nan))
    if not (math.isfinite(omega) and omega > 0):
        from contin.hopf import hopf_numbers

        omega = float(hopf_numbers(problem, u, q_params)["omega"])
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"{point.name} has no pair of eigenvalues +-i omega (omega = {omega}): not a Hopf point")
    q, pvec = hopf_vectors(jac, mass, omega, weights=inner_product_weights(problem, u, q_params))
    # Re lambda'(p) along the equilibrium branch: p^H (dJ/dp + J_u[u_p]) q with u_p = -J^{-1} F_p
    jd = _dense(jac)
    up = np.linalg.solve(jd, -problem.dresidual_dp(u, q_params, parameter))
    h = 1e-6 * max(1.0, abs(q_params[parameter]))
    hu = h / max(1.0, float(np.max(np.abs(up))))
    plus, minus = dict(q_params), dict(q_params)
    plus[parameter] += hu
    minus[parameter] -= hu
    dj = (_dense(problem.jacobian(u + hu * up, plus)) - _dense(problem.jacobian(u - hu * up, minus))) / (2 * hu)
    dlambda = float(np.vdot(pvec, dj @ q).real)
    mass_const = None if not has(problem, "mass_matrix") else _dense(mass)
    return HopfStart(u, q_params, omega, q, dlambda, float(point.data.get("l1", math.nan)), mass_const)


def first_orbit(start: HopfStart, mesh: Mesh, parameter: str, eps: float) -> tuple[Array, float, Array]:
    """(x, p, t): the predicted first orbit [nodes, T], its parameter and the Hopf mode direction t
    (unit in the state, zero in the parameter) of the start correction."""
    phase = np.exp(2j * np.pi * mesh.node_times)
    mode = (start.q[None, :] * phase[:, None]).real  # Re(q e^{2 pi i t}) at the nodes
    nodes = start.state[None, :] + eps * mode
    x = mesh.pack(nodes, 2 * np.pi / start.omega)
    shift = 0.0
    if math.isfinite(start.l1) and start.dlambda != 0:
        shift = -start.omega * start.l1 * eps**2 / (4 * start.dlambda)
    direction = np.concatenate([mode.ravel(), [0.0, 0.0]])
    return x, start.params[parameter] + shift, direction


def start_orbit(problem: Any, point: SpecialPoint, parameter: str, cycle: CycleOptions = CycleOptions(),
                options: ContinuationOptions = ContinuationOptions()) -> tuple[CycleProblem, Array, dict[str, float], Array]:
    """(cycle problem, corrected first orbit x, its parameters, the secant from the Hopf point).

    Raises ValueError when the start cannot be corrected."""
    from contin.corrector import correct
    from contin.extended import ExtendedSystem

    start = hopf_start(problem, point, parameter)
    mesh = Mesh(start.state.size, cycle.ntst, cycle.ncol)
    eps = cycle.amplitude if cycle.amplitude is not None else default_amplitude(start.state)
    x, p1, direction = first_orbit(start, mesh, parameter, eps)
    cp = CycleProblem(problem, mesh, x[:-1], start.mass, cycle.floquet_tol)
    system = ExtendedSystem(cp, start.params, parameter, options.step.theta, n=x.size)
    guess = system.pack(x, p1)
    corr = correct(system, guess, system.row(direction), options.newton)
    if not corr.converged:
        raise ValueError(f"the first periodic orbit near {point.name} (amplitude {eps:g}, {parameter} = {p1:g}) "
                         f"did not converge: {corr.message}")
    xs = corr.x
    hopf_x = system.pack(mesh.pack(np.repeat(start.state[None, :], mesh.nodes, axis=0), 2 * np.pi / start.omega),
                         start.params[parameter])
    cp.colloc.set_reference(xs[:-2])
    return cp, xs[:-1], system.params_at(xs[-1]), xs - hopf_x


# --- continuation ----------------------------------------------------------------------------
def continue_cycles(problem: Any, point: SpecialPoint, parameter: str,
                    options: ContinuationOptions = ContinuationOptions(), cycle: CycleOptions = CycleOptions(),
                    *, branch_id: str = "0", parent: str = "") -> Branch:
    """The branch of periodic orbits born at the Hopf point ``point``, continued in ``parameter``
    away from it (module docstring).  Raises ValueError for a point that is no Hopf point or a
    start that does not converge."""
    from contin.continuation import trace

    cp, x0, params, secant = start_orbit(problem, point, parameter, cycle, options)
    options = dataclasses.replace(options, save_every=1)  # every orbit: the multipliers need them
    remaining = options.max_steps
    parent = parent or point.name
    segments: list[Branch] = []
    tangent: Array | None = secant
    while True:
        steps = min(cycle.rephase_every, remaining)
        seg = trace(cp, x0, params, parameter, dataclasses.replace(options, max_steps=steps), tangent=tangent,
                    branch_id=branch_id, kind=KIND, parent=parent)
        segments.append(seg)
        remaining -= len(seg) - 1
        if not _stopped_by_count(seg, steps) or remaining <= 0 or len(seg) < 2:
            break
        # a new segment from the last orbit, which becomes the phase reference
        x0 = seg.state(-1)
        params = {k: float(v[-1]) for k, v in seg.params.items()}
        tangent = seg.tangent(-1)
        last = float(abs(seg.ds[-1])) or abs(options.step.ds)  # go on with the step the tracer had reached
        options = dataclasses.replace(options, step=dataclasses.replace(
            options.step, ds=math.copysign(min(last, options.step.ds_max), options.step.ds)))
        cp.colloc.set_reference(x0[:-1])
        cp._cache = None
    branch = _concatenate(segments)
    return finish_branch(cp, branch)


def _stopped_by_count(seg: Branch, steps: int) -> bool:
    """True if the segment ended only because it made its ``steps`` steps."""
    return seg.status == "EP" and len(seg) - 1 >= steps and not seg.closed and "max" in seg.message.lower()


def _concatenate(segments: list[Branch]) -> Branch:
    """Segments traced one after the other (each starting at the last point of the previous) as
    one branch: the end points between segments are dropped."""
    from contin.continuation import join

    out = segments[0]
    for seg in segments[1:]:
        out.special_points = [s for s in out.special_points if s.type != "EP" or s.index != len(out) - 1]
        out = join(out.reversed(), seg)
    out.status, out.message = segments[-1].status, segments[-1].message
    return out


def finish_branch(cp: CycleProblem, branch: Branch) -> Branch:
    """Multipliers, stability, floquet_error at every point; LP -> LPC; warning when the trivial
    multiplier is off by more than :data:`FLOQUET_DOUBTFUL`."""
    s = len(branch)
    n = cp.mesh.n
    eig = np.full((s, n - 1 if n > 1 else 1), np.nan + 0j)
    err = np.full(s, np.nan)
    flow_err = np.full(s, np.nan)
    stable = np.zeros(s, dtype=bool)
    n_unst = np.zeros(s, dtype=np.int64)
    for i in range(s):
        x = branch.state(i)
        p = {k: float(v[i]) for k, v in branch.params.items()}
        mu = cp.multipliers(x, p)
        eig[i, : mu.others.size] = mu.others
        err[i] = mu.error
        flow_err[i] = mu.flow_error
        stable[i] = mu.stable
        n_unst[i] = mu.n_unstable
    branch.eigenvalues, branch.stable, branch.n_unstable = eig, stable, n_unst
    branch.observables["floquet_error"] = err
    branch.observables["flow_error"] = flow_err
    branch.kind = KIND
    branch.special_points = [dataclasses.replace(sp, type="LPC", note="; ".join(
        t for t in ("fold of cycles", sp.note) if t)) if sp.type == "LP" else sp for sp in branch.special_points]
    worst = float(np.nanmax(flow_err)) if s else 0.0
    if worst > FLOQUET_DOUBTFUL:
        i = int(np.nanargmax(flow_err))
        line = (f"Floquet multipliers doubtful: the monodromy moves the flow direction by {worst:.1e} at "
                f"{branch.parameter} = {branch.parameter_values[i]:.6g} (refine the mesh: NTST)")
        log.warning(line)
        branch.audit.append("warning: " + line)
    return branch
