"""Couette scenes for the stability CLI tests, loaded through ``CONTIN_SCENES``.

'shear': uniform shear (an exact steady state of the no-slip problem at G = 0) at ``n`` gap
widths H from ``Hmin`` to ``Hmax``, built without continuation, with a BP special point at
every H_n^c = n pi psi in the range (physics.md section 4).  ``banded=1`` adds branch 'b': the
n = 1 banded state at H = 14 (Newton from uniform shear plus the critical mode) and its mirror
image.  ``dropbp=1`` drops the BP at H_2^c (an audit disagreement).  ``selfstab=1``: the scene runs ``request.run_stability`` itself; otherwise it leaves the
stability pass to the CLI (through ``problem_factory``).
"""

from __future__ import annotations

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.newton import newton
from contin.options import NewtonOptions
from contin.scene import Scene, SceneError, SceneRequest, SceneResult
from contin.stability import eigenpairs
from problems.couette.closures import critical_gap_factor
from problems.couette.model import CouetteProblem

DEFAULTS = {"nu": 0.3, "e": 0.8, "Hmin": 5.0, "Hmax": 30.0, "n": 11, "banded": 0, "selfstab": 0, "dropbp": 0}


def problem_factory(parameters, discretization) -> CouetteProblem:
    return CouetteProblem(str(discretization.get("method", "cheb")), int(discretization.get("intervals", 32)))


def _branch(problem: CouetteProblem, bid: str, states: list, plist: list[dict], sps=(), kind="primary") -> Branch:
    s = len(states)
    names = list(plist[0])
    obs = [problem.observables(x, p) for x, p in zip(states, plist)]
    return Branch(
        parameter="H", free=("H",),
        params={k: np.array([float(p[k]) for p in plist]) for k in names},
        observables={k: np.array([o[k] for o in obs]) for k in obs[0]},
        states=np.array(states), tangents=np.zeros((s, problem.size + 1)),
        ds=np.zeros(s), newton_iterations=np.zeros(s, dtype=np.int64),
        special_points=list(sps), status="EP", message="built by hand", id=bid, kind=kind)


def shear_branch(problem: CouetteProblem, nu: float, e: float, H_values) -> Branch:
    """Uniform shear at each H, with BPs at the H_n^c inside the range."""
    plist = [problem.params({"nu": nu, "e": e, "H": float(H)}) for H in H_values]
    states = [problem.uniform_state(p) for p in plist]
    psi = float(critical_gap_factor(nu, e))
    sps = []
    H_values = np.asarray(H_values, dtype=float)
    for n in range(1, 10):
        hc = n * np.pi * psi
        i = int(np.searchsorted(H_values, hc)) - 1
        if 0 <= i < H_values.size - 1:
            p = problem.params({"nu": nu, "e": e, "H": hc})
            sps.append(SpecialPoint("BP", i, p, nu, problem.uniform_state(p), bracket=(H_values[i], H_values[i + 1]),
                                    converged=True, label=len(sps) + 1))
    return _branch(problem, "0", states, plist, sps)


def banded_pair(problem: CouetteProblem, nu: float = 0.3, e: float = 0.8, H: float = 14.0) -> tuple[np.ndarray, dict]:
    """(the n = 1 banded state with nu larger at the bottom wall, params) at H just past H_1^c."""
    p = problem.params({"nu": nu, "e": e, "H": H})
    x = problem.uniform_state(p)
    A, B = problem.eigenproblem(x, p)
    _, v = eigenpairs(A, B, k=1)
    egrid = problem.eigen_grid()  # Chebyshev, also for FD problems: interpolate the mode
    f = np.array([egrid.interpolate(np.real(g), problem.grid.y) for g in np.asarray(v[:, 0]).reshape(5, -1)])
    f /= np.max(np.abs(f[0]))
    x0 = x.copy()
    x0[problem.i_nu] += 0.05 * f[0]
    x0[problem.i_u] += 0.05 * f[1]
    x0[problem.i_T] += 0.05 * f[4]
    r = newton(problem, x0, p, NewtonOptions(max_iterations=50))
    if not r.converged:
        raise RuntimeError(f"banded state did not converge: {r.message}")
    u = r.u if r.u[problem.i_nu][0] > r.u[problem.i_nu][-1] else problem.symmetry(r.u)
    return u, p


def run(req: SceneRequest) -> SceneResult:
    par = {**DEFAULTS, **dict(req.params)}
    if not float(par["Hmax"]) > float(par["Hmin"]) > 0:
        raise SceneError("need 0 < Hmin < Hmax")
    disc = {"method": req.method or "cheb", "intervals": int(req.grid or 32)}
    problem = problem_factory(par, disc)
    branches = [shear_branch(problem, float(par["nu"]), float(par["e"]),
                             np.linspace(float(par["Hmin"]), float(par["Hmax"]), int(par["n"])))]
    if int(par["dropbp"]):  # an audit disagreement: the n_unstable change at H_2^c is unexplained
        branches[0].special_points = branches[0].special_points[:1]
    if int(par["banded"]):
        u, p = banded_pair(problem, float(par["nu"]), float(par["e"]))
        branches.append(_branch(problem, "b", [u, problem.symmetry(u)], [p, p], kind="banded"))
    for b in branches:
        if int(par["selfstab"]):
            req.run_stability(problem, b, par)
        req.finished(b)
    return SceneResult(branches=branches, parameters=par, discretization=disc, y=problem.grid.y,
                       profiles=problem.profiles)


SCENES = {"shear": Scene(name="shear", summary="uniform shear states for the stability tests", defaults=DEFAULTS,
                         run=run, x="H", y="phi", problem_factory=problem_factory)}
