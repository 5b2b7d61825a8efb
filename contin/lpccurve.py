"""Two-parameter continuation of folds of periodic orbits (LPC curves; AUTO-07p's restart at an
LPC of a periodic branch with ISW = 2, BifurcationKit's ``FoldPeriodicOrbitProblem``).

The collocated cycle system G(x, p) = 0 (:class:`contin.cycles.CycleProblem`: x = [orbit values
at the nodes, T], the collocation equations, periodicity and AUTO's integral phase condition) is
an ordinary contin problem, and an LPC of a cycle branch is a fold of it: G_x is singular there.
So the core's Moore-Spence fold system (:class:`contin.foldcurve.FoldProblem`)

    G(x, p1, p2) = 0,      G_x phi = 0,      c . phi - 1 = 0

is traced on the cycle system as it is for an equilibrium (:func:`contin.foldcurve.trace_augmented`,
both halves, bounds on either parameter, the cycle problem's resolution guard: an orbit the mesh no
longer resolves ends the half with MX "under-resolved").  The mesh and the phase reference are the
LPC orbit's (or, with ``ntst``, that orbit carried onto an adapted mesh of NTST intervals) for the
whole curve: they are not renewed along it.

End at a generalized Hopf (Bautin) point: where the folding cycles shrink to an equilibrium the LPC
curve ends on the Hopf curve at its GH point (the first Lyapunov coefficient vanishes there).  The
cycle system is singular at amplitude 0, so the curve either passes through it (the orbits' signed
amplitude along the phase reference changes sign: ``contin.floquet.ShrinkTest``, then the half
stops) or the steps fail next to it (the last orbit's amplitude below :data:`GH_FRACTION` of the
curve's largest); the half ends there with EP and a ``GH`` point, which :func:`solve_gh` solves on
the Hopf curve through the end (l1 = 0, ``contin.hopfcurve``): converged, the equilibrium's constant
orbit as its state, the end the LPC curve reached in its note.

Stored per point: the orbit row [node values, T, interior mesh points] (as on a cycle branch,
``contin.cycles.orbit_of``), both parameters, period / amplitude / l2norm, and the Floquet check of
the orbit (``floquet_error``: the trivial multiplier's distance from 1, which at a fold is the
square root of the collocation error; ``flow_error``; the other multipliers in ``eigenvalues``, one
of which is the fold's +1).  Extrema of the first parameter along the curve are ``LP`` points;
extrema of the second are not located.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint, relabel
from contin.cycles import CycleOptions, CycleProblem, constant_mass, orbit_of
from contin.floquet import ShrinkTest
from contin.foldcurve import FoldProblem, trace_augmented
from contin.normalform import null_vectors
from contin.options import ContinuationOptions
from contin.problem import Array

__all__ = ["LPCProblem", "lpc_start", "trace_lpc_curve", "as_lpc_curve", "solve_gh"]

#: Branch.kind of an LPC curve.
KIND = "lpc-curve"

#: A half that fails next to an amplitude below this fraction of the curve's largest ends at a GH.
GH_FRACTION = 0.02

#: The end message of a half at a GH point.
GH_END = "the folding cycles shrink to a generalized Hopf point"


@dataclasses.dataclass
class _Shrink(ShrinkTest):
    """The cycle branch's shrink test on the augmented state [x, phi, p2] (kind HB: the tracer's
    stop_at counts it; renamed GH afterwards)."""

    size: int = 0

    def value(self, system: Any, x: Array) -> float:
        return float(self.cycles.signed_amplitude(x[: self.size]))

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        return dataclasses.replace(sp_, data={**sp_.data, "period": float(x[self.size - 1])})


class LPCProblem(FoldProblem):
    """The fold system of a :class:`contin.cycles.CycleProblem` (state [x, phi, p2]): no cusp,
    BT or ZH tests (they belong to equilibria); the shrink test marks the GH end."""

    detect_cusps = False

    def point_tests(self) -> list[object]:
        return [_Shrink(self.problem, size=self.n)]


def lpc_start(problem: Any, point: SpecialPoint, second: str, n: int, cycle: CycleOptions = CycleOptions(),
              *, parent_ncol: int | None = None, mass: Array | None = None) -> tuple[LPCProblem, Array]:
    """The fold system on the cycle problem of the LPC ``point`` (a stored orbit of a cycle branch,
    NCOL ``parent_ncol``) and its start vector [x, phi, p2]; on ``cycle.ntst`` intervals when they
    differ from the orbit's (the orbit carried onto a mesh adapted to it)."""
    if point.type != "LPC":
        raise ValueError(f"an LPC curve starts at a fold of cycles (LPC), not at {point.name} ({point.type})")
    if second not in point.params:
        raise ValueError(f"unknown parameter {second!r} (the problem has {', '.join(sorted(point.params))})")
    mesh, nodes, period = orbit_of(point.state, n, None, parent_ncol or cycle.ncol)
    if (cycle.ntst, cycle.ncol) != (mesh.ntst, mesh.ncol):
        target = mesh.remeshed(nodes, cycle.ntst, cycle.ncol)
        mesh, nodes = target, mesh.resample(target, nodes)
    params = dict(point.params)
    if mass is None:
        mass = constant_mass(problem, nodes[0], params)
    cp = CycleProblem(problem, mesh, nodes, mass, cycle.floquet_tol)
    x = mesh.pack(nodes, period)
    phi = null_vectors(sp.csc_matrix(cp.jacobian(x, params))).phi
    return LPCProblem(cp, second, phi), np.concatenate([x, phi, [params[second]]])


def trace_lpc_curve(problem: Any, point: SpecialPoint, second: str, n: int,
                    options: ContinuationOptions = ContinuationOptions(), cycle: CycleOptions = CycleOptions(),
                    *, parameter: str, parent_ncol: int | None = None, mass: Array | None = None,
                    branch_id: str = "lpc") -> Branch:
    """The curve of folds of cycles through the LPC ``point`` (of a cycle branch in ``parameter``,
    orbits of ``n`` components) in (parameter, second), both directions (module docstring).
    ``options`` as for a fold curve (bounds on either parameter, max_steps per direction);
    ``cycle``: NTST / NCOL of the curve's orbits (NTST other than the orbit's: carried over) and the
    resolution guard ``floquet_tol``.  Raises ValueError for a point that is no LPC."""
    if second == parameter:
        raise ValueError(f"the second free parameter must differ from the branch's parameter {parameter!r}")
    if second not in point.params:
        raise ValueError(f"unknown parameter {second!r} (the problem has {', '.join(sorted(point.params))})")
    from contin.twoparam import start_within_bounds

    # an LPC on a bound (to its location tolerance) starts there, as a fold or Hopf curve does
    options = start_within_bounds(options, point, (parameter, second))
    lpc, start = lpc_start(problem, point, second, n, cycle, parent_ncol=parent_ncol, mass=mass)
    start_point = dataclasses.replace(point, state=start)
    opts = dataclasses.replace(
        options, save_every=1, stop_at=("HB1",),
        detection=dataclasses.replace(options.detection, detect_hopf=False, detect_branch_points=False))
    raw = trace_augmented(lpc, start, start_point, second, 2 * lpc.n, opts, parameter=parameter, both=True,
                          branch_id=branch_id, kind=KIND, mirror_start=True)
    own = orbit_of(point.state, n, None, parent_ncol or cycle.ncol)[0]
    mesh = lpc.problem.mesh
    if (mesh.ntst, mesh.ncol) != (own.ntst, own.ncol) and "at the start point" in raw.message:
        # the start failed on the orbit carried onto another mesh (--ntst 2): the mesh, not the
        # problem's Jacobian (the generic hint), is the suspect (qa19b)
        from contin.continuation import JACOBIAN_HINT

        hint = (f"; the LPC orbit (NTST = {own.ntst}, NCOL = {own.ncol}) carried onto NTST = {mesh.ntst}, "
                f"NCOL = {mesh.ncol} is no fold there: choose a finer mesh")
        raw.message = raw.message.replace(JACOBIAN_HINT, hint)
        raw.special_points = [dataclasses.replace(sp_, note=sp_.note.replace(JACOBIAN_HINT, hint))
                              for sp_ in raw.special_points]
    curve = as_lpc_curve(raw, lpc, parameter)
    curve.special_points = [solve_gh(problem, lpc.problem, sp_, parameter, second, options) if sp_.type == "GH"
                            else sp_ for sp_ in curve.special_points]
    return curve


def solve_gh(problem: Any, cp: CycleProblem, gh: SpecialPoint, parameter: str, second: str,
             options: ContinuationOptions) -> SpecialPoint:
    """The GH end of an LPC curve solved on the Hopf curve through it: the cycle system is singular
    at amplitude 0, so the end the LPC curve reached is an estimate.  From its orbit's mean and
    period the Hopf point at the same ``second`` is solved (``contin.cycles._hopf_end``), its Hopf
    curve traced a few steps each way (:func:`contin.hopfcurve.trace_hopf_curve`) and the GH located
    there (l1 = 0) nearest the estimate replaces it (converged, its state the equilibrium's constant
    orbit).  The estimate stays (not converged, a note) when that fails."""
    from contin.cycles import _hopf_end
    from contin.hopfcurve import trace_hopf_curve

    hb = _hopf_end(cp, dataclasses.replace(gh, type="HB", note=""), parameter)
    why = hb.note
    if hb.converged:
        mesh = cp.mesh
        u_h = mesh.split(np.asarray(hb.state)[: mesh.size])[0][0]
        start = SpecialPoint(type="HB", index=0, params=dict(hb.params), order_parameter=0.0, state=u_h,
                             converged=True, data={"omega": float(hb.data["omega"])})
        scale = max(1e-6, 1e-3 * max(abs(gh.params[parameter]), abs(gh.params[second]), 1e-3))
        opts = dataclasses.replace(options, max_steps=4, stop_at=(), bounds={},
                                   step=dataclasses.replace(options.step, ds=scale, ds_max=scale,
                                                            ds_min=min(options.step.ds_min, scale / 100)))
        try:
            curve = trace_hopf_curve(problem, start, second, opts, parameter=parameter, generalized_hopf=True)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            curve, why = None, f"its Hopf curve not traced: {exc}"
        found = [] if curve is None else [p for p in curve.points("GH") if p.converged]
        if found:
            def dist(p: SpecialPoint) -> float:
                return sum(abs(p.params[k] - gh.params[k]) / max(1.0, abs(gh.params[k])) for k in (parameter, second))

            best = min(found, key=dist)
            omega = float(best.data.get("omega", hb.data["omega"]))
            u = np.asarray(best.state, float)[: mesh.n]
            state = np.concatenate([mesh.pack(np.repeat(u[None, :], mesh.nodes, axis=0), 2 * math.pi / omega),
                                    np.asarray(gh.state)[mesh.size:]])
            note = (f"generalized Hopf (Bautin) point, where the folding cycles shrink to an equilibrium: solved on "
                    f"the Hopf curve through the LPC curve's end (l1 = 0) at ({parameter}, {second}) = "
                    f"({best.params[parameter]:.10g}, {best.params[second]:.10g}), period 2 pi / omega = "
                    f"{2 * math.pi / omega:.10g}; the LPC curve reached ({gh.params[parameter]:.10g}, "
                    f"{gh.params[second]:.10g})")
            reached = {f"reached_{k}": float(gh.params[k]) for k in (parameter, second)}  # the LPC curve's own end
            return dataclasses.replace(gh, params=dict(best.params), state=state, converged=True, order_parameter=0.0,
                                       note=note, data={**gh.data, **best.data, "omega": omega,
                                                        "period": 2 * math.pi / omega, **reached})
        if curve is not None:
            why = f"no GH located on the Hopf curve through ({parameter}, {second}) = " \
                  f"({hb.params[parameter]:.10g}, {hb.params[second]:.10g})"
    return dataclasses.replace(gh, note=f"{gh.note}; not solved on the Hopf curve: {why}")


def as_lpc_curve(raw: Branch, lpc: LPCProblem, parameter: str) -> Branch:
    """A traced augmented branch as an LPC curve: orbit rows as states, p2 as a parameter column,
    Floquet checks, the shrink points and the failed ends next to amplitude 0 as GH."""
    cp: CycleProblem = lpc.problem
    second, size = lpc.second, lpc.n
    mesh = cp.mesh
    inner = mesh.t[1:-1]
    s = len(raw)
    p2 = raw.states[:, 2 * size].copy() if s else np.zeros(0)
    states = np.hstack([raw.states[:, :size], np.repeat(inner[None, :], s, axis=0)]) if s else \
        np.zeros((0, size + inner.size))
    tangents = np.hstack([raw.tangents[:, :size], np.zeros((s, inner.size)), raw.tangents[:, 2 * size:]]) if s else \
        np.zeros((0, size + inner.size + 2))
    params = {**raw.params, second: p2}
    observables = {k: v for k, v in raw.observables.items() if k != second}
    m = mesh.n
    eig = np.full((s, m - 1 if m > 1 else 1), np.nan + 0j)
    err, flow = np.full(s, np.nan), np.full(s, np.nan)
    stable, n_unst = np.zeros(s, dtype=bool), np.zeros(s, dtype=np.int64)
    for i in range(s):
        q = {k: float(v[i]) for k, v in params.items()}
        try:
            mu = cp.multipliers(raw.states[i, :size], q)
        except np.linalg.LinAlgError:
            continue
        eig[i, : mu.others.size] = mu.others
        err[i], flow[i], stable[i], n_unst[i] = mu.error, mu.flow_error, mu.stable, mu.n_unstable
    observables["floquet_error"], observables["flow_error"] = err, flow
    amp = np.asarray(raw.order_parameter, float)
    big = float(np.max(amp)) if s else 0.0

    def gh(sp_: SpecialPoint, how: str) -> SpecialPoint:
        q = {**sp_.params, second: float(sp_.state[2 * size])}
        note = (f"generalized Hopf (Bautin) point: the folding cycles shrink to an equilibrium (amplitude 0); {how} "
                f"at ({parameter}, {second}) = ({q[parameter]:.10g}, {q[second]:.10g}), period "
                f"{float(sp_.state[size - 1]):.10g}")
        return dataclasses.replace(sp_, type="GH", params=q, note=note, converged=False,
                                   data={**sp_.data, "period": float(sp_.state[size - 1])})

    specials: list[SpecialPoint] = []
    failed: list[str] = []  # the step failures next to amplitude 0 (GH ends)
    message = raw.message
    status = raw.status
    shrunk = [sp_ for sp_ in raw.special_points if sp_.type == "HB"]
    for sp_ in raw.special_points:
        if sp_.type == "HB":
            specials.append(gh(sp_, "located where the signed amplitude changes sign"))
            continue
        q = {**sp_.params, second: float(sp_.state[2 * size])}
        if sp_.type == "MX" and big > 0 and amp[sp_.index] <= GH_FRACTION * big and \
                sp_.note.startswith("step failed") and not any(abs(h.index - sp_.index) <= 1 for h in shrunk):
            # (only the tracer's failure next to amplitude 0: not an under-resolved or interrupted end)
            specials.append(gh(sp_, f"approached to amplitude {amp[sp_.index]:.2g} (of {big:.3g} on the curve), "
                                    "the last point reached"))
            failed.append(sp_.note)
            specials.append(dataclasses.replace(sp_, type="EP", params=q, note=GH_END, converged=True))
            continue
        if sp_.type == "EP" and sp_.note.startswith("stopped after HB1"):
            sp_ = dataclasses.replace(sp_, note=GH_END)
        elif sp_.type == "LP" and not sp_.converged and amp[sp_.index] <= GH_FRACTION * big:
            raw.audit.append(f"dropped {sp_.name}: an unlocated extremum of {parameter} next to amplitude 0 "
                             "(the cycle system is singular there)")
            continue
        elif sp_.type == "LP":
            sp_ = dataclasses.replace(sp_, note=sp_.note or f"extremum of {parameter}")
        specials.append(dataclasses.replace(sp_, params=q))
    # an LP in the GH's step (or the next) is the curve touching the Hopf curve there, located on the
    # singular cycle system (Bautin's mu = -b^2/4 has its extremum of mu at the GH itself)
    ends = {sp_.index for sp_ in specials if sp_.type == "GH"}
    for sp_ in [t for t in specials if t.type == "LP" and any(abs(t.index - i) <= 1 for i in ends)]:
        raw.audit.append(f"dropped {sp_.name} ({parameter} = {sp_.params[parameter]:.10g}): an extremum of "
                         f"{parameter} in the step of the GH end, where the cycle system is singular")
        specials.remove(sp_)
    specials = [_orbit_row(sp_, size, inner) for sp_ in specials]
    ends = [sp_ for sp_ in specials if sp_.type in ("EP", "MX")]
    if ends and not any(sp_.type == "MX" for sp_ in ends):
        status = "EP"
    message = message.replace("stopped after HB1 (stop_at)", GH_END)
    for note in failed:
        message = message.replace(note, GH_END, 1)
    out = dataclasses.replace(raw, states=states, tangents=tangents, params=params, observables=observables,
                              free=(parameter, second), kind=KIND, eigenvalues=eig, stable=stable,
                              n_unstable=n_unst, special_points=sorted(specials, key=lambda t: t.index),
                              status=status, message=message)
    relabel([out])
    return out


def _orbit_row(sp_: SpecialPoint, size: int, inner: Array) -> SpecialPoint:
    """A special point of the augmented trace with the orbit row [x, interior mesh] as its state."""
    state = np.concatenate([np.asarray(sp_.state)[:size], inner])
    tangent = None if sp_.tangent is None else np.concatenate(
        [np.asarray(sp_.tangent)[:size], np.zeros(inner.size), np.asarray(sp_.tangent)[2 * size:]])
    return dataclasses.replace(sp_, state=state, tangent=tangent)
