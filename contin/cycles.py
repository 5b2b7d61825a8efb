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

Phase condition and mesh: AUTO's int_0^1 <u(t), u_ref'(t)> dt = 0 with u_ref the start orbit for
the first ``rephase_every`` steps; the branch is then traced on in segments, each with the last
orbit of the previous one as reference (AUTO updates it every step; a reference orbit that is
kept too long lets the phase condition degenerate as the orbit changes shape) and on a mesh
adapted to it (``contin.collocation.Mesh.adapted``; AUTO's IAD).  A stored orbit is the row
[node values, T, interior mesh points] (:func:`orbit_of`).

Period doubling: :func:`continue_doubled` starts the branch of period-doubled orbits at a PD of a
cycle branch (:func:`period_doubled_start`: the orbit twice plus the multiplier -1's eigenfunction).

Branch points of cycles (BPC, AUTO's BP of a periodic branch): a nontrivial multiplier through +1
that is no fold makes [G_x G_p] of the cycle system lose rank, so the tracer's determinant BP test
finds them (at an LPC and at PD / NS it keeps its sign); :func:`finish_branch` confirms each BP by
its multiplier nearest +1 (:func:`_branch_point_of_cycles`).  :func:`continue_branch_point` switches
there with the core's algebraic bifurcation equation (:func:`branch_point_start`).

End at a Hopf point: where the orbits shrink to an equilibrium (their signed amplitude along the
reference changes sign: ``contin.floquet.ShrinkTest``) the branch ends (HB, then EP one step past
it); the HB is solved from the equilibrium's Hopf system, since the cycle system is singular at
amplitude 0.  Beyond it the tracer would come back over the same orbits, half a period shifted.

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
from contin.collocation import NCOL, NTST, Collocation, Mesh, dense_matrix
from contin.floquet import FLOQUET_DOUBTFUL, FloquetTest, Multipliers, ShrinkTest, multipliers
from contin.options import ContinuationOptions
from contin.problem import Array, has, inner_product_weights

log = logging.getLogger("contin")

__all__ = ["CycleOptions", "CycleProblem", "continue_cycles", "continue_doubled", "continue_branch_point", "orbit_of",
           "hopf_start", "start_orbit", "period_doubled_start", "branch_point_start", "finish_branch"]

#: Branch.kind of a branch of periodic orbits.
KIND = "periodic-orbits"
#: Largest distance from +1 of the nontrivial multiplier at a confirmed branch point of cycles.
BPC_TOL = 1e-3


@dataclass(frozen=True)
class CycleOptions:
    """Settings of a cycle continuation.

    ntst, ncol : mesh intervals and Gauss points per interval (AUTO's NTST, NCOL).
    amplitude : eps of the first orbit u_H + eps Re(q e^{2 pi i t}) (q with q^H W q = 1, W the
        problem's ``inner_product_weights`` or I); None: :func:`default_amplitude`.
    rephase_every : steps after which the phase reference is renewed (a new segment) and, with
        ``adapt_mesh``, the mesh adapted to the last orbit (AUTO's IAD).
    adapt_mesh : equidistribute the mesh at every new segment (``contin.collocation.Mesh.adapted``),
        and where an orbit is under-resolved (``floquet_tol``) go on from the last accepted orbit on
        its adapted mesh (once per point: a second miss there ends the branch); False: the uniform
        mesh throughout.
    floquet_tol : largest flow residual |P f - f| / |f| of an accepted orbit (P the monodromy,
        f = u'(0); ``contin.floquet``): past it the mesh no longer resolves the orbit (a sharpening
        relaxation oscillation, a period growing towards a homoclinic orbit); with ``adapt_mesh``
        the branch goes on from the last orbit on an adapted mesh, else (or when that misses too)
        it ends with MX "under-resolved at ...", through the tracer's resolution guard
        (``ContinuationOptions.resolution_tol`` not None); None: no such end (a warning line names
        the worst point instead).
    """

    ntst: int = NTST
    ncol: int = NCOL
    amplitude: float | None = None
    rephase_every: int = 5
    floquet_tol: float | None = FLOQUET_DOUBTFUL
    adapt_mesh: bool = True

    def __post_init__(self) -> None:
        if self.ntst < 2 or self.ncol < 1:
            raise ValueError(f"cycles need NTST >= 2 and NCOL >= 1, got NTST = {self.ntst}, NCOL = {self.ncol}")
        if self.amplitude is not None and not (math.isfinite(self.amplitude) and self.amplitude > 0):
            raise ValueError(f"the start amplitude must be a finite number > 0, got {self.amplitude}")
        if self.floquet_tol is not None and not (math.isfinite(self.floquet_tol) and self.floquet_tol > 0):
            raise ValueError(f"floquet_tol must be a finite number > 0 or None, got {self.floquet_tol}")
        if self.rephase_every < 1:
            raise ValueError(f"rephase_every must be >= 1, got {self.rephase_every}")


def constant_mass(problem: Any, u: Array, params: dict[str, float]) -> Array | None:
    """The problem's mass matrix M (M u' = T F), dense, taken at (u, params) as the constant it must
    be (:func:`hopf_start` refuses one that changes); None without the ``mass_matrix`` hook (M = I)."""
    return dense_matrix(problem.mass_matrix(u, params)) if has(problem, "mass_matrix") else None


def default_amplitude(u_h: Array) -> float:
    """The start amplitude when none is given: 1e-2 max(1, |u_H|_inf)."""
    return 1e-2 * max(1.0, float(np.max(np.abs(u_h), initial=0.0)))


def check_dynamics(problem: Any) -> None:
    """ValueError for a problem whose dynamics is not M u' = F(u, p) with J = dF/du (its own
    ``eigenproblem``): its orbits are not those of the collocated F."""
    if has(problem, "eigenproblem"):
        raise ValueError("periodic orbits need the dynamics M u' = F(u, p); this problem defines its own "
                         "eigenproblem (its linearization is not the Jacobian of F), which cycles do not support")


class CycleProblem:
    """The periodic BVP of ``problem`` on ``mesh`` as a contin Problem (module docstring)."""

    def __init__(self, problem: Any, mesh: Mesh, reference: Array, mass: Array | None = None,
                 floquet_tol: float | None = FLOQUET_DOUBTFUL) -> None:
        check_dynamics(problem)
        self.problem = problem
        self.mesh = mesh
        self.colloc = Collocation(problem, mesh, reference, mass)
        self.parameter_names = tuple(problem.parameter_names)
        self._cache: tuple[bytes, Multipliers] | None = None
        self.floquet_tol = floquet_tol

    def with_mesh(self, mesh: Mesh, reference: Array | None = None) -> CycleProblem:
        """The same problem collocated on ``mesh`` (phase reference: the given node values, else
        the present reference carried over)."""
        if reference is None:
            reference = self.mesh.resample(mesh, self.colloc.reference)
        return CycleProblem(self.problem, mesh, reference, self.colloc.mass, self.floquet_tol)

    # --- the Problem protocol ------------------------------------------------------------
    def residual(self, x: Array, p: dict[str, float]) -> Array:
        return self.colloc.residual(x, p)

    def jacobian(self, x: Array, p: dict[str, float]) -> sp.csc_matrix:
        return self.colloc.jacobian(x, p)

    def dresidual_dp(self, x: Array, p: dict[str, float], name: str) -> Array:
        return self.colloc.dresidual_dp(x, p, name)

    def admissible(self, x: Array, p: dict[str, float]) -> str | None:
        """The base problem's ``admissible`` at every node (None: all inside its domain)."""
        if not has(self.problem, "admissible"):
            return None
        for k, v in enumerate(self.mesh.split(x)[0]):
            reason = self.problem.admissible(v, p)
            if reason is not None:
                return f"{reason} (orbit node {k})"
        return None

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
        return [FloquetTest(self, "PD"), FloquetTest(self, "NS"), ShrinkTest(self)]

    def signed_amplitude(self, x: Array) -> float:
        """The orbit's amplitude along the phase reference's, signed (``contin.floquet.ShrinkTest``)."""
        mesh = self.mesh
        u = mesh.at_gauss(mesh.split(x)[0])
        r = mesh.at_gauss(self.colloc.reference)
        _, w, _, _ = mesh.tables

        def centred(v: Array) -> Array:
            return v - np.einsum("j,i,jin->n", mesh.h, w, v)

        cu, cr = centred(u), centred(r)
        ref = mesh.integrate(np.sum(cr * cr, axis=-1))
        return mesh.integrate(np.sum(cu * cr, axis=-1)) / ref if ref > 0 else math.nan

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


def hopf_start(problem: Any, point: SpecialPoint, parameter: str) -> HopfStart:
    """The Hopf data of ``point`` (an HB) for cycles in ``parameter`` (module docstring)."""
    from contin.hopf import hopf_vectors, pencil

    if point.type != "HB":
        raise ValueError(f"periodic orbits start at a Hopf point (HB), not at {point.name} ({point.type})")
    check_dynamics(problem)  # before the eigenvectors: an eigenproblem's pencil is not (J, M)
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
    jd = dense_matrix(jac)
    up = np.linalg.solve(jd, -problem.dresidual_dp(u, q_params, parameter))
    h = 1e-6 * max(1.0, abs(q_params[parameter]))
    hu = h / max(1.0, float(np.max(np.abs(up))))
    plus, minus = dict(q_params), dict(q_params)
    plus[parameter] += hu
    minus[parameter] -= hu
    dj = (dense_matrix(problem.jacobian(u + hu * up, plus)) - dense_matrix(problem.jacobian(u - hu * up, minus))) / (2 * hu)
    dlambda = float(np.vdot(pvec, dj @ q).real)
    mass_const = None if not has(problem, "mass_matrix") else dense_matrix(mass)
    if mass_const is not None:
        # M is taken constant: a state- or parameter-dependent one would give wrong orbits silently
        shifted = u + 0.1 * np.random.default_rng(1).standard_normal(u.size) * max(1.0, float(np.max(np.abs(u))))
        other = dense_matrix(problem.mass_matrix(shifted, plus))
        if not np.allclose(other, mass_const, rtol=1e-12, atol=1e-14 * max(1.0, float(np.max(np.abs(mass_const))))):
            raise ValueError("periodic orbits need a constant mass matrix M (M u' = T F); this problem's "
                             "mass_matrix(u, p) changes with u or the parameter")
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
        try:
            shift = -start.omega * start.l1 * eps**2 / (4 * start.dlambda)
        except OverflowError:  # eps**2 past the float range (--amplitude 1e300): an infinite shift, refused
            shift = -math.copysign(math.inf, start.omega * start.l1 * start.dlambda)  # by start_orbit (qa19)
    direction = np.concatenate([mode.ravel(), [0.0, 0.0]])
    return x, start.params[parameter] + shift, direction


def start_orbit(problem: Any, point: SpecialPoint, parameter: str, cycle: CycleOptions = CycleOptions(),
                options: ContinuationOptions = ContinuationOptions()
                ) -> tuple[CycleProblem, Array, dict[str, float], Array]:
    """(cycle problem, corrected first orbit x, its parameters, the secant from the Hopf point).

    Raises ValueError when the start cannot be corrected."""
    from contin.corrector import correct
    from contin.extended import ExtendedSystem

    start = hopf_start(problem, point, parameter)
    mesh = Mesh(start.state.size, cycle.ntst, cycle.ncol)
    eps = cycle.amplitude if cycle.amplitude is not None else default_amplitude(start.state)
    x, p1, direction = first_orbit(start, mesh, parameter, eps)
    lo, hi = options.bounds.get(parameter, (-math.inf, math.inf))
    if not lo <= start.params[parameter] <= hi:
        raise ValueError(f"{point.name} at {parameter} = {start.params[parameter]:.10g} lies outside the bounds "
                         f"{lo:g} <= {parameter} <= {hi:g}; its orbits start there")
    if not (math.isfinite(p1) and np.all(np.isfinite(x)) and lo <= p1 <= hi):
        # the normal form puts an orbit of amplitude eps at |p - p_H| ~ eps^2: --amplitude 1e300 ended
        # 'arithmetic failure (OverflowError)', --amplitude 100 of ab's HB1 'Newton diverged' at D = -75.9 (qa19)
        raise ValueError(f"the first periodic orbit near {point.name} (amplitude {eps:g}) is predicted at "
                         f"{parameter} = {p1:g}, outside the bounds {lo:g} <= {parameter} <= {hi:g} (the normal form "
                         f"puts an orbit of amplitude eps at a distance ~ eps^2 from the Hopf point); give a smaller "
                         f"amplitude (--amplitude; default {default_amplitude(start.state):g})")
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
    away from it (module docstring).  ``options`` as for a trace, except ``save_every`` (every
    orbit is kept) and ``stop_at`` (replaced: the branch ends at the first Hopf point of the
    orbits).  Raises ValueError for a point that is no Hopf point or a start that does not
    converge."""
    cp, x0, params, secant = start_orbit(problem, point, parameter, cycle, options)
    return _continue_from(problem, cp, x0, params, secant, parameter, options, cycle, branch_id,
                          parent or point.name)


def _continue_from(problem: Any, cp: CycleProblem, x0: Array, params: dict[str, float], secant: Array,
                   parameter: str, options: ContinuationOptions, cycle: CycleOptions, branch_id: str,
                   parent: str) -> Branch:
    """The segmented continuation of :func:`continue_cycles` from the corrected orbit x0 of ``cp``."""
    from contin.continuation import trace

    # every orbit stored (the multipliers need them); a segment ends at the first Hopf point (the
    # orbits shrink to an equilibrium: beyond it the branch would come back over itself)
    options = dataclasses.replace(options, save_every=1, stop_at=("HB1",))
    remaining = options.max_steps
    segments: list[Branch] = []
    tangent: Array | None = secant
    retried = -1  # the point count at the last restart after an under-resolved orbit
    while True:
        steps = min(cycle.rephase_every, remaining)
        seg = trace(cp, x0, params, parameter, dataclasses.replace(options, max_steps=steps), tangent=tangent,
                    branch_id=branch_id, kind=KIND, parent=parent)
        segments.append(_with_mesh(seg, cp.mesh))
        remaining -= max(len(seg) - 1, 0)
        done = sum(len(b) - 1 for b in segments)
        unresolved = (cycle.adapt_mesh and seg.status == "MX" and seg.message.startswith("under-resolved")
                      and len(seg) >= 2 and done != retried)
        if unresolved:
            retried = done
        elif not _stopped_by_count(seg, steps) or len(seg) < 2:
            if seg.points("HB"):
                hb = _hopf_end(cp, seg.points("HB")[0], parameter)
                seg.special_points = [hb if sp.type == "HB" else sp for sp in seg.special_points]
                seg.message = f"the orbits shrink to a Hopf point at {parameter} = {hb.params[parameter]:.10g}"
                if not hb.converged:  # a sign change of the signed amplitude without a Hopf point: say so
                    seg.status = "MX"
                    seg.message = (f"the orbits' amplitude along the phase reference changed sign near {parameter} = "
                                   f"{hb.params[parameter]:.10g}, but no Hopf point solves there ({hb.note})")
                # the reversal through amplitude 0 is no fold of cycles
                end = "EP" if hb.converged else "MX"
                seg.special_points = [dataclasses.replace(sp, type=end, note=seg.message) if sp.type == "EP" else sp
                                      for sp in seg.special_points if not (sp.type == "LP" and sp.index == hb.index)]
            break
        if remaining <= 0:
            break
        # a new segment from the last orbit: the new phase reference, on its adapted mesh
        size = cp.mesh.size  # (the stored rows carry the mesh after [nodes, T]: _with_mesh)
        x_last, t_last = seg.state(-1)[:size], seg.tangent(-1)
        params = {k: float(v[-1]) for k, v in seg.params.items()}
        nodes, period = cp.mesh.split(x_last)
        mesh = cp.mesh.adapted(nodes) if cycle.adapt_mesh else cp.mesh
        new_nodes = cp.mesh.resample(mesh, nodes)
        x0 = mesh.pack(new_nodes, period)
        tangent = np.concatenate([cp.mesh.resample(mesh, cp.mesh.split(t_last[:size])[0]).ravel(),
                                  [t_last[size - 1], t_last[-1]]])
        cp = cp.with_mesh(mesh, new_nodes)
        if unresolved:  # the last stored orbit ends this segment; its MX is not the branch's end
            segments[-1].special_points = [sp for sp in segments[-1].special_points if sp.type != "MX"]
            segments[-1].status = "EP"
        last = float(abs(seg.ds[-1])) or abs(options.step.ds)  # go on with the step the tracer had reached
        options = dataclasses.replace(options, step=dataclasses.replace(
            options.step, ds=math.copysign(min(last, options.step.ds_max), options.step.ds)))
    branch = _concatenate(segments)
    if _stopped_by_count(segments[-1], 0) and remaining <= 0:  # the segment's count is not the run's
        msg = f"maximum number of steps ({options.max_steps}) reached"
        branch.message = msg
        branch.special_points = [dataclasses.replace(sp, note=msg) if sp.type == "EP" and sp.index == len(branch) - 1
                                 else sp for sp in branch.special_points]
    return finish_branch(problem, branch, cp.mesh.n, cycle, cp.colloc.mass)


def period_doubled_start(problem: Any, point: SpecialPoint, parameter: str, n: int,
                         cycle: CycleOptions = CycleOptions(), options: ContinuationOptions = ContinuationOptions(),
                         mass: Array | None = None, parent_ncol: int | None = None
                         ) -> tuple[CycleProblem, Array, dict[str, float], Array]:
    """(cycle problem, corrected first orbit, its parameters, secant) of the period-doubled branch
    at a PD point of a cycle branch (its state a stored orbit, :func:`orbit_of`, of NCOL
    ``parent_ncol``, default ``cycle.ncol``).

    The orbit u of period T traversed twice is an orbit of period 2 T; at the PD it is a branch
    point of the doubled problem, the new branch leaving along w = (v, -v), v the solution of the
    variational equation with v(0) the eigenvector of the multiplier -1 (v(1) = -v(0), so w is
    continuous and 2T-periodic).  The guess u2 + eps w, 2 T is corrected with its projection on w
    held (as at a Hopf point), on NTST intervals of ``cycle`` (adapted to the doubled orbit)."""
    from contin.corrector import correct
    from contin.extended import ExtendedSystem
    from contin.floquet import eigenfunction, monodromy

    if point.type != "PD":
        raise ValueError(f"a period-doubled branch starts at a PD point, not at {point.name} ({point.type})")
    mesh, nodes, period = orbit_of(point.state, n, None, parent_ncol or cycle.ncol)
    params = dict(point.params)
    if mass is None:  # the CLI passed none: a problem's M was replaced by I, period and orbits wrong
        mass = constant_mass(problem, nodes[0], params)
    base = CycleProblem(problem, mesh, nodes, mass, cycle.floquet_tol)
    blocks = base.colloc.interval_blocks(mesh.pack(nodes, period), params)
    mu, vecs = np.linalg.eig(monodromy(blocks))
    k = int(np.argmin(np.abs(mu + 1.0)))
    if not abs(mu[k] + 1.0) < 1e-3:
        raise ValueError(f"{point.name} has no Floquet multiplier at -1 (nearest {complex(mu[k]):.6g})")
    v = eigenfunction(blocks, np.real(vecs[:, k]))
    v /= float(np.max(np.abs(v)))
    twice = Mesh(n, 2 * mesh.ntst, mesh.ncol, tuple(np.concatenate([mesh.t / 2, 0.5 + mesh.t[1:] / 2])))
    u2, w2 = np.vstack([nodes, nodes]), np.vstack([v[:-1], -v[:-1]])
    target = twice.remeshed(u2, cycle.ntst, cycle.ncol, cycle.adapt_mesh)
    u_t, w_t = twice.resample(target, u2), twice.resample(target, w2)
    eps = cycle.amplitude if cycle.amplitude is not None else default_amplitude(nodes.ravel())
    cp = CycleProblem(problem, target, u_t, mass, cycle.floquet_tol)
    system = ExtendedSystem(cp, params, parameter, options.step.theta, n=target.size)
    doubled = system.pack(target.pack(u_t, 2 * period), params[parameter])
    guess = system.pack(target.pack(u_t + eps * w_t, 2 * period), params[parameter])
    corr = correct(system, guess, system.row(np.concatenate([w_t.ravel(), [0.0, 0.0]])), options.newton)
    if not corr.converged:
        raise ValueError(f"the first period-doubled orbit at {point.name} (amplitude {eps:g}) did not converge: "
                         f"{corr.message}")
    cp.colloc.set_reference(corr.x[:-2])
    return cp, corr.x[:-1], system.params_at(corr.x[-1]), corr.x - doubled


def continue_doubled(problem: Any, point: SpecialPoint, parameter: str, n: int,
                     options: ContinuationOptions = ContinuationOptions(), cycle: CycleOptions = CycleOptions(),
                     *, parent_ncol: int | None = None, mass: Array | None = None,
                     branch_id: str = "0", parent: str = "") -> Branch:
    """The branch of period-doubled orbits born at the PD ``point`` of a cycle branch
    (:func:`period_doubled_start`), continued as :func:`continue_cycles` continues orbits."""
    cp, x0, params, secant = period_doubled_start(problem, point, parameter, n, cycle, options, mass, parent_ncol)
    return _continue_from(problem, cp, x0, params, secant, parameter, options, cycle, branch_id, parent or point.name)


def branch_point_start(problem: Any, point: SpecialPoint, parameter: str, n: int,
                       cycle: CycleOptions = CycleOptions(), options: ContinuationOptions = ContinuationOptions(),
                       mass: Array | None = None, parent_ncol: int | None = None, direction: int = 1
                       ) -> tuple[CycleProblem, Array, dict[str, float], Array, float]:
    """(cycle problem, corrected first orbit, its parameters, tangent, accepted first step) of the
    branch of cycles bifurcating at the branch point of cycles ``point`` (a BP of a cycle branch,
    its state a stored orbit of NCOL ``parent_ncol``, its tangent the known branch's).

    The orbit at the BP is the phase reference of the new problem (it satisfies its own phase
    condition), on its own mesh (or carried onto NTST/NCOL of ``cycle`` where they differ).  The
    core's switching then works on the cycle system as on an equilibrium (``contin.switching``):
    the second kernel vector phi of [G_x G_p] -- the multiplier +1's eigenfunction, (v, 0, 0) at a
    pitchfork of cycles -- and the left one psi by inverse iteration on the bordered Jacobian, the
    algebraic bifurcation equation for the new tangent tau, and the first orbit corrected from
    x_BP + ds tau in the hyperplane orthogonal to tau (``direction`` -1: from x_BP - ds tau, the
    other half).  The known branch's tangent is first carried into this phase reference's kernel
    (the kernel vector orthogonal to phi: the stored tangent satisfies the old reference's phase
    condition, not this one)."""
    from contin.extended import ExtendedSystem
    from contin.switching import bifurcation_coefficients, first_point, new_tangent, null_directions

    if point.type != "BP":
        raise ValueError(f"a branch of cycles switches at a branch point of cycles (BP), not at {point.name} "
                         f"({point.type})")
    if point.tangent is None:
        raise ValueError(f"{point.name} has no tangent of the known branch: cannot switch there")
    crit = point.data.get("multiplier", math.nan)
    if not abs(crit - 1.0) <= BPC_TOL:
        raise ValueError(f"{point.name} has no Floquet multiplier at +1 (nearest {crit:.6g}): not a branch point "
                         "of cycles")
    from contin.hopfcurve import within_bounds

    lo, hi = options.bounds.get(parameter, (-math.inf, math.inf))
    # as at a Hopf point (the first orbit's value was named, qa19b); on a bound to its location
    # tolerance is inside (as in contin.twoparam.start_within_bounds)
    if not within_bounds(point.params[parameter], lo, hi):
        raise ValueError(f"{point.name} at {parameter} = {point.params[parameter]:.10g} lies outside the bounds "
                         f"{lo:g} <= {parameter} <= {hi:g}; its cycles bifurcate there")
    ncol = parent_ncol or cycle.ncol
    mesh, nodes, period = orbit_of(point.state, n, None, ncol)
    tangent = np.asarray(point.tangent, dtype=float)
    t_state, t_param = tangent[: mesh.size], float(tangent[-1])
    if (cycle.ntst, cycle.ncol) != (mesh.ntst, mesh.ncol):  # another mesh: the orbit and tangent carried over
        target = mesh.remeshed(nodes, cycle.ntst, cycle.ncol, cycle.adapt_mesh)
        t_nodes = mesh.resample(target, mesh.split(t_state)[0])
        t_state = target.pack(t_nodes, float(t_state[-1]))
        mesh, nodes = target, mesh.resample(target, nodes)
    if mass is None:
        mass = constant_mass(problem, nodes[0], dict(point.params))
    cp = CycleProblem(problem, mesh, nodes, mass, cycle.floquet_tol)
    params = dict(point.params)
    system = ExtendedSystem(cp, params, parameter, options.step.theta, n=mesh.size)
    x0 = system.pack(mesh.pack(nodes, period), params[parameter])
    old = system.unit(np.concatenate([t_state, [t_param]]))
    phi, _ = null_directions(system, x0, old, False)
    t1, _ = null_directions(system, x0, phi, False)  # the known branch's tangent for this phase reference
    t1 = t1 if system.dot(t1, old) >= 0 else -t1
    phi, psi = null_directions(system, x0, t1, False)
    a, b, c = bifurcation_coefficients(system, x0, t1, phi, psi)
    tau = (1 if direction >= 0 else -1) * new_tangent(system, t1, phi, a, b, c)
    start, step, why = first_point(system, x0, tau, abs(options.step.ds), options)
    if start is None:
        raise ValueError(f"no orbit of the branch bifurcating at {point.name} ({parameter} = "
                         f"{params[parameter]:.10g}): {why}")
    if not lo <= start[-1] <= hi:  # the tracer said 'start value mu=0.499699 lies outside its bounds (0.5, 0.9)'
        raise ValueError(f"the branch bifurcating at {point.name} ({parameter} = {params[parameter]:.10g}) leaves "
                         f"the bounds {lo:g} <= {parameter} <= {hi:g} at once: its first orbit is at {parameter} = "
                         f"{start[-1]:.10g}{' (try --other-half)' if direction >= 0 else ''}")
    cp.colloc.set_reference(start[:-2])
    return cp, start[:-1], system.params_at(start[-1]), tau, step


def continue_branch_point(problem: Any, point: SpecialPoint, parameter: str, n: int,
                          options: ContinuationOptions = ContinuationOptions(), cycle: CycleOptions = CycleOptions(),
                          *, parent_ncol: int | None = None, mass: Array | None = None, direction: int = 1,
                          branch_id: str = "0", parent: str = "") -> Branch:
    """The branch of cycles bifurcating at the branch point of cycles ``point`` (a BP of a cycle
    branch; :func:`branch_point_start`), continued as :func:`continue_cycles` continues orbits,
    away from the BP along +tau (``direction`` -1: the other half), the first step the accepted one."""
    from contin.switching import first_step_options

    cp, x0, params, tau, step = branch_point_start(problem, point, parameter, n, cycle, options, mass, parent_ncol,
                                                   direction)
    options = first_step_options(options, step)
    return _continue_from(problem, cp, x0, params, math.copysign(1.0, options.step.ds) * tau, parameter, options,
                          cycle, branch_id, parent or point.name)


def _hopf_end(cp: CycleProblem, sp: SpecialPoint, parameter: str) -> SpecialPoint:
    """The Hopf point where the orbits shrink to an equilibrium, solved from the Hopf defining
    system of the base problem (``contin.hopfsystem.HopfCurveProblem`` with the branch's parameter
    as its unknown), started from the mean and the period of the orbit the locator reached: the
    locator's own point is inexact (the cycle system is singular at amplitude 0).  The point keeps
    the locator's estimate (converged False, a note) when that solve fails."""
    from contin.hopfsystem import HopfCurveProblem, hopf_basis
    from contin.newton import newton

    mesh = cp.mesh
    nodes, period = mesh.split(np.asarray(sp.state)[: mesh.size])
    u0 = np.einsum("j,i,jin->n", mesh.h, mesh.tables[1], mesh.at_gauss(nodes))
    omega = 2 * math.pi / period
    params = dict(sp.params)
    try:
        v, w, d = hopf_basis(cp.problem, u0, params, omega)
        curve = HopfCurveProblem(cp.problem, parameter, v.copy(), d)
        res = newton(curve, np.concatenate([u0, v, w, [omega**2, params[parameter]]]), params)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError) as exc:
        return dataclasses.replace(sp, converged=False, note=f"{sp.note}; Hopf system not solved: {exc}")
    n = u0.size
    kappa = float(res.u[3 * n])
    if not (res.converged and kappa > 0):
        return dataclasses.replace(sp, converged=False, note=f"{sp.note}; Hopf system not solved: {res.message}")
    u_h, omega = res.u[:n], math.sqrt(kappa)
    params[parameter] = float(res.u[-1])
    state = mesh.pack(np.repeat(u_h[None, :], mesh.nodes, axis=0), 2 * math.pi / omega)
    return dataclasses.replace(sp, params=params, state=np.concatenate([state, np.asarray(sp.state)[mesh.size:]]),
                               converged=True, order_parameter=0.0,
                               note="Hopf point: the orbits shrink to an equilibrium (amplitude 0), "
                                    "solved from its Hopf system",
                               data={**sp.data, "omega": omega, "period": 2 * math.pi / omega})


def _branch_point_of_cycles(problem: Any, sp: SpecialPoint, n: int, cycle: CycleOptions,
                            mass: Array | None) -> SpecialPoint:
    """A BP of the tracer's determinant test on a cycle branch: a branch point of cycles (AUTO's BP
    of a periodic branch), a nontrivial real Floquet multiplier through +1 that is no fold (at an
    LPC the determinant keeps its sign).  Its note says so; data: period, floquet_error and
    ``multiplier``, the nontrivial multiplier nearest +1.  A BP without a multiplier within
    :data:`BPC_TOL` of +1 is marked not converged (the determinant changed sign for another
    reason)."""
    mesh, nodes, period = orbit_of(sp.state, n, None, cycle.ncol)
    try:
        mu = CycleProblem(problem, mesh, nodes, mass).multipliers(mesh.pack(nodes, period), dict(sp.params))
    except np.linalg.LinAlgError as exc:
        return dataclasses.replace(sp, converged=False, note="; ".join(
            t for t in ("branch point of cycles?", f"Floquet multipliers not computed: {exc}", sp.note) if t))
    others = mu.others
    crit = complex(others[int(np.argmin(np.abs(others - 1.0)))]) if others.size else complex(math.nan)
    data = {**sp.data, "period": float(period), "floquet_error": mu.error, "multiplier": float(crit.real)}
    if abs(crit - 1.0) <= BPC_TOL:
        note = "branch point of cycles (a Floquet multiplier through +1)"
        return dataclasses.replace(sp, data=data, note="; ".join(t for t in (note, sp.note) if t))
    note = (f"not confirmed: the BP test function of the cycle system changed sign, but no Floquet multiplier "
            f"is at +1 (nearest {crit:.6g})")
    return dataclasses.replace(sp, data=data, converged=False, note="; ".join(t for t in (note, sp.note) if t))


def orbit_of(state: Array, n: int, ntst: int | None = None, ncol: int = NCOL) -> tuple[Mesh, Array, float]:
    """(mesh, node values (NTST NCOL, n), T) of a stored orbit: a row of a cycle branch's states,
    [node values, T, interior mesh points t_1 .. t_{NTST-1}] (NTST None: from the row's size)."""
    state = np.asarray(state, dtype=float)
    if ntst is None:
        ntst = max(state.size // (n * ncol + 1), 2)
    size = n * ntst * ncol + 1
    if state.size != size + ntst - 1:
        raise ValueError(f"a stored orbit of n = {n}, NTST = {ntst}, NCOL = {ncol} has {size + ntst - 1} entries, "
                         f"not {state.size}")
    mesh = Mesh(n, ntst, ncol, (0.0, *(float(v) for v in state[size:]), 1.0))
    nodes, period = mesh.split(state[:size])
    return mesh, nodes, period


def _with_mesh(seg: Branch, mesh: Mesh) -> Branch:
    """The segment with the interior mesh points appended to every state (the stored orbit,
    :func:`orbit_of`), zeros in the tangents before the parameter, and the same in its points."""
    inner = mesh.t[1:-1]
    k = inner.size
    if len(seg):
        seg.states = np.hstack([seg.states, np.repeat(inner[None, :], seg.states.shape[0], axis=0)])
        seg.tangents = np.hstack([seg.tangents[:, :-1], np.zeros((len(seg), k)), seg.tangents[:, -1:]])
    seg.special_points = [dataclasses.replace(
        sp, state=np.concatenate([sp.state, inner]),
        tangent=None if sp.tangent is None else np.concatenate([sp.tangent[:-1], np.zeros(k), sp.tangent[-1:]]))
        for sp in seg.special_points]
    return seg


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


def finish_branch(problem: Any, branch: Branch, n: int, cycle: CycleOptions = CycleOptions(),
                  mass: Array | None = None) -> Branch:
    """Multipliers, stability, floquet_error and flow_error at every point; LP -> LPC; warning when
    the flow residual exceeds :data:`FLOQUET_DOUBTFUL` (the guard was off)."""
    s = len(branch)
    eig = np.full((s, n - 1 if n > 1 else 1), np.nan + 0j)
    err = np.full(s, np.nan)
    flow_err = np.full(s, np.nan)
    stable = np.zeros(s, dtype=bool)
    n_unst = np.zeros(s, dtype=np.int64)
    problems: dict[tuple[float, ...], CycleProblem] = {}
    for i in range(s):
        mesh, nodes, period = orbit_of(branch.state(i), n, cycle.ntst, cycle.ncol)
        key = tuple(mesh.t)
        if key not in problems:
            problems[key] = CycleProblem(problem, mesh, nodes, mass)
        p = {k: float(v[i]) for k, v in branch.params.items()}
        mu = problems[key].multipliers(mesh.pack(nodes, period), p)
        eig[i, : mu.others.size] = mu.others
        err[i] = mu.error
        flow_err[i] = mu.flow_error
        stable[i] = mu.stable
        n_unst[i] = mu.n_unstable
    branch.eigenvalues, branch.stable, branch.n_unstable = eig, stable, n_unst
    branch.observables["floquet_error"] = err
    branch.observables["flow_error"] = flow_err
    branch.kind = KIND
    marked = []
    for pt in branch.special_points:
        if pt.type == "LP":
            pt = dataclasses.replace(pt, type="LPC", note="; ".join(t for t in ("fold of cycles", pt.note) if t))
        elif pt.type == "BP":
            pt = _branch_point_of_cycles(problem, pt, n, cycle, mass)
        marked.append(pt)
    branch.special_points = marked
    worst = float(np.nanmax(flow_err)) if s else 0.0
    if worst > FLOQUET_DOUBTFUL:
        i = int(np.nanargmax(flow_err))
        line = (f"Floquet multipliers doubtful: the monodromy moves the flow direction by {worst:.1e} at "
                f"{branch.parameter} = {branch.parameter_values[i]:.6g} (refine the mesh: NTST)")
        log.warning(line)
        branch.audit.append("warning: " + line)
    return branch
