"""One periodic orbit of a stored branch of orbits, for ``contin profiles`` of an orbit file.

The orbit is a stored row (``contin.cycles.orbit_of``: node values, T, mesh) at a labelled point
(``--point LPC1``: exact) or where the branch's parameter takes a value (``--at D=0.2``): a special
point located there (exact), else the first step that brackets the value, the two orbits
interpolated linearly, (1 - w) u_i + w u_{i+1} and (1 - w) T_i + w T_{i+1}, the second carried
onto the first one's mesh (consecutive orbits share their phase through the integral phase
condition), then, given the ``problem``, corrected by Newton on the collocation system at the
value (:class:`contin.cycles.CycleProblem`, square at a fixed parameter: node values and T for
the collocation equations and the phase condition against the orbit u_i): an interpolated orbit
is off by O(step^2) (demo ab, 40 steps: closure errors 1e-4 of the amplitude, 2e-3 along the
orbit), the corrected one is an orbit of the ODE (closure 1e-8).  The orbit is sampled on its collocation polynomials, ``refine`` points per node
interval (the nodes among them), t from 0 to T with u(T) = u(0).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from contin.branch import Branch, first_crossing, interleave_located
from contin.collocation import Mesh
from contin.problem import Array

__all__ = ["OrbitProfile", "corrected", "orbit_at", "orbit_at_point", "sample"]

#: samples per node interval of a drawn orbit
REFINE = 4


@dataclass(frozen=True)
class OrbitProfile:
    """One orbit to draw: its branch, how it was found, its parameters, mesh, node values, T;
    ``doubt``: why it is not an orbit of the ODE (an interpolation Newton did not correct), else ''."""

    branch: Branch
    how: str
    params: dict[str, float]
    mesh: Mesh
    nodes: Array
    period: float
    doubt: str = ""


def sample(mesh: Mesh, nodes: Array, period: float, refine: int = REFINE) -> tuple[Array, Array]:
    """(t, u(t)): the orbit at ``refine`` points per node interval, t in [0, T], the last u(T) = u(0)."""
    s = np.arange(refine * mesh.ncol) / (refine * mesh.ncol)
    tau = np.append((mesh.t[:-1, None] + mesh.h[:, None] * s[None, :]).ravel(), 1.0)
    return tau * period, mesh.evaluate(nodes, tau)


def _profile(branch: Branch, how: str, state: Array, params: dict[str, float], n: int, ncol: int) -> OrbitProfile:
    from contin.cycles import orbit_of

    mesh, nodes, period = orbit_of(state, n, None, ncol)
    return OrbitProfile(branch, how, dict(params), mesh, nodes, period)


def orbit_at_point(branches: Sequence[Branch], label: str, n: int, ncol: int,
                   branch_id: str | None = None, where: str = "the run") -> OrbitProfile:
    """The orbit of the special point ``label`` (ValueError: no such point, or no stored orbit)."""
    from contin.restart import find_point

    branch, sp = find_point(branches, label, branch_id, where)
    if sp.state is None or not np.all(np.isfinite(sp.state)):
        raise ValueError(f"{sp.name} of branch {branch.id} has no stored orbit")
    return _profile(branch, f"at {sp.name}", np.asarray(sp.state, float), dict(sp.params), n, ncol)


def corrected(problem: Any, orbit: OrbitProfile, reference: Array) -> OrbitProfile:
    """``orbit`` corrected by Newton on the collocation system at its parameters (phase
    reference: node values on its mesh); ValueError when Newton does not converge."""
    from contin.cycles import CycleProblem, constant_mass
    from contin.newton import newton

    cp = CycleProblem(problem, orbit.mesh, reference, constant_mass(problem, orbit.nodes[0], orbit.params))
    res = newton(cp, orbit.mesh.pack(orbit.nodes, orbit.period), orbit.params)
    if not res.converged:
        raise ValueError(f"Newton on the collocation system did not converge: {res.message}")
    nodes, period = orbit.mesh.split(res.u)
    return dataclasses.replace(orbit, nodes=nodes, period=period)


#: special points located between two stored orbits (at a fold of cycles the parameter turns between
#: them, so a value between the fold and both orbits is crossed only there)
_BETWEEN = ("LP", "LPC", "HB", "PD", "NS", "BP", "UZ")


def _sequence(b: Branch, name: str) -> list[tuple[float, str, Array, dict[str, float]]]:
    """(value of ``name``, what, orbit, parameters) along the branch: its stored orbits and, after
    stored point i, the located points between i and i + 1 (index i) that hold an orbit of the
    branch's layout.  `contin profiles ORBITS.h5 --at D=0.1616962` between ab's fold of cycles
    (D = 0.16169613) and its two neighbouring orbits (0.16169627, 0.16169803) said 'no branch of
    orbits reaches D=0.161696' (qa19)."""
    width = b.states.shape[1] if b.states.ndim == 2 else None
    values = np.asarray(b.params[name], dtype=float)
    between = [(sp.index, sp) for sp in b.special_points
               if sp.type in _BETWEEN and sp.state is not None and np.size(sp.state) == width and name in sp.params]
    seq = []
    for i, sp in interleave_located(range(len(b)), between, len(b)):
        params_i = {k: float(v[i]) for k, v in b.params.items()}
        if sp is None:
            seq.append((float(values[i]), f"stored point {i}", b.state(i), params_i))
        else:
            seq.append((float(sp.params[name]), sp.name, np.asarray(sp.state, dtype=float),
                        {**params_i, **{k: float(v) for k, v in sp.params.items()}}))
    return seq


def orbit_at(branches: Sequence[Branch], name: str, value: float, n: int, ncol: int,
             problem: Any = None) -> list[OrbitProfile]:
    """The orbit of each branch where parameter ``name`` equals ``value`` (module docstring);
    branches that do not reach it are left out.  An interpolated orbit is corrected by Newton
    when ``problem`` is given; if that fails it is kept, and its ``doubt`` says so."""
    from contin.cycles import orbit_of

    out = []
    tol = 1e-9 * max(1.0, abs(value))
    for b in branches:
        if name not in b.params or not len(b):
            continue
        exact = [sp for sp in b.special_points if sp.state is not None and name in sp.params
                 and abs(float(sp.params[name]) - value) <= tol]
        seq = _sequence(b, name)
        crossing = first_crossing(np.array([v for v, _, _, _ in seq]), value)
        count = 0 if crossing is None else crossing[3]
        if exact:
            sp = exact[0]
            found = _profile(b, f"at {sp.name}", np.asarray(sp.state, float), dict(sp.params), n, ncol)
        elif crossing is not None:
            i, j, w, _ = crossing
            _, what_i, state_i, params_i = seq[i]
            mesh, nodes, period = orbit_of(state_i, n, None, ncol)
            params = dict(params_i)
            how = f"at {what_i}"
            if w != 0.0:
                _, what_j, state_j, params_j = seq[j]
                mesh_j, nodes_j, period_j = orbit_of(state_j, n, None, ncol)
                nodes = (1 - w) * nodes + w * mesh_j.resample(mesh, nodes_j)
                period = (1 - w) * period + w * period_j
                params = {k: (1 - w) * params_i[k] + w * params_j[k] for k in params_i}
                how = (f"interpolated between points {what_i.split()[-1]} and {what_j.split()[-1]}"
                       if what_i.startswith("stored") and what_j.startswith("stored")
                       else f"interpolated between {what_i} and {what_j}")
            found = OrbitProfile(b, how, params, mesh, nodes, period)
            if w != 0.0 and problem is not None:
                try:
                    found = dataclasses.replace(corrected(problem, found, orbit_of(state_i, n, None, ncol)[1]),
                                                how=f"{how}, corrected by Newton at {name}={value:g}")
                except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                    found = dataclasses.replace(found, doubt=f"the orbit {how} was not corrected at {name}={value:g}: "
                                                             f"{exc}")
        else:
            continue
        if count > 1 and not found.how.startswith("at LPC"):  # past a fold the branch reaches the value again
            found = dataclasses.replace(found, how=f"{found.how} (the first of {count} crossings of {name}={value:g} "
                                                   "along the branch; the others are not drawn)")
        out.append(found)
    return out
