"""Unfolding of the first pitchfork of uniform shear by gravity: data and normal form.

Problem-side helpers for :mod:`contin.fit` and :func:`contin.normalform.pitchfork_unfolding`
(A13 slides "Bifurcation with gravity"; physics.md section 6 rows 10-12).

Order parameter.  The reflection y -> -y maps a solution at G to one at -G (F(Sx, -G) =
S F(x, G)).  Phi = nu(1/2) is not odd under it (Phi(Sx) = nu(-1/2)), so in delta = Phi - nu_bar
the unfolding picks up even terms (delta^4, (H - H_c) delta^2, ...) at a LOWER order than the
beta G delta^2 term one wants to measure.  We therefore use the odd order parameter

    delta_s = (nu(1/2) - nu(-1/2)) / 2,       delta_s(S x) = -delta_s(x),

which equals Phi - nu_bar to leading order and makes the solution set a graph
H - H_c = lambda(delta_s, G) with lambda(-delta_s, -G) = lambda(delta_s, G).

Pieces:

- :func:`odd_order_parameter` -- the linear functional l with l . x = delta_s;
- :func:`odd_delta` -- delta_s along a branch (from its nu_top / nu_bottom observables);
- :func:`first_pitchfork` -- uniform shear at G = 0 and its first BP;
- :func:`branches_near_bp` -- every solution component inside |H - H_c| <= window at one G
  (any sign; G = 0 gives both halves of the pitchfork, each by its own switch);
- :func:`unfolding_data` -- (lambda, delta_s, G) arrays for :func:`contin.fit.fit_graph`;
- :func:`ls_unfolding` -- the Lyapunov-Schmidt unfolding at the BP in the same coordinate.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from contin.branch import Branch, SpecialPoint
from contin.continuation import newton, switch, trace
from contin.normalform import ReducedUnfolding, pitchfork_unfolding
from contin.options import (
    ContinuationOptions,
    DetectionOptions,
    NewtonOptions,
    StepOptions,
)
from problems.couette.gravity import GravitySettings, on_branch, trace_in_H
from problems.couette.model import CouetteProblem

Array = np.ndarray


def odd_order_parameter(problem: CouetteProblem) -> Array:
    """l with l . x = (nu(1/2) - nu(-1/2)) / 2 (nu block: nodes from y = -1/2 to y = 1/2)."""
    idx = np.arange(problem.size)[problem.i_nu]
    ell = np.zeros(problem.size)
    ell[idx[-1]] = 0.5
    ell[idx[0]] = -0.5
    return ell


def odd_delta(branch: Branch) -> Array:
    """delta_s = (nu_top - nu_bottom) / 2 along ``branch``."""
    ob = branch.observables
    return 0.5 * (np.asarray(ob["nu_top"]) - np.asarray(ob["nu_bottom"]))


def first_pitchfork(problem: CouetteProblem, nu: float, e: float, H_max: float = 20.0) -> tuple[Branch, SpecialPoint]:
    """Uniform shear at G = 0 traced in H from 1 and its first (symmetry-breaking) BP."""
    from problems.couette.pitchfork import trace_base

    p = problem.params({"nu": nu, "e": e, "G": 0.0})
    opts = ContinuationOptions(bounds={"H": (1.0, H_max)}, max_steps=400,
                               step=StepOptions(ds=0.3, ds_max=1.0, max_angle=0.2))
    base = trace_base(problem, p, 1.0, opts, branch_id="g0")
    bps = [b for b in base.branch_points if b.converged]
    if not bps:
        raise ValueError(f"uniform shear has no branch point in 1 <= H <= {H_max:g} at nu = {nu:g}, e = {e:g}")
    return base, bps[0]


def _g_homotopy(problem: CouetteProblem, x: Array, p: Mapping[str, float], G: float) -> Array | None:
    """x continued in G at fixed H from p['G'] = 0 to ``G`` (either sign); None if not reached.
    theta = 1/G^2 makes the path O(1) long (see problems.couette.gravity)."""
    opts = ContinuationOptions(bounds={"G": (min(0.0, G), max(0.0, G))}, max_steps=80,
                               step=StepOptions(ds=0.1, ds_max=0.25, ds_min=1e-8, theta=1.0 / G**2),
                               detection=DetectionOptions(detect_branch_points=False))
    br = trace(problem, x, dict(p), "G", opts, direction=1 if G > 0 else -1, symmetric=False, branch_id="homotopy")
    if br.status != "EP" or abs(br.params["G"][-1] - G) > 1e-12 * abs(G):
        return None
    return br.state(-1)


class SignedGravity:
    """``problem`` with G < 0 admitted (gravity pointing up, the mirror image of G > 0).

    CouetteProblem.validate rejects G < 0 as unphysical; the equations are the same, and the
    branches at -G, computed independently, check alpha(-G) = -alpha(G) numerically.
    Everything else is delegated to ``problem``.
    """

    def __init__(self, problem: CouetteProblem) -> None:
        self._problem = problem

    def __getattr__(self, name: str) -> object:
        return getattr(self._problem, name)

    def validate(self, p: Mapping[str, float]) -> None:
        self._problem.validate({**p, "G": abs(float(p.get("G", 0.0)))})


def _states_at(branch: Branch, H: float) -> Iterable[tuple[Array, dict[str, float]]]:
    i = int(np.argmin(np.abs(branch.params["H"] - H)))
    yield branch.state(i), {k: float(v[i]) for k, v in branch.params.items()}


def branches_near_bp(problem: CouetteProblem, base: Branch, bp: SpecialPoint, G: float, window: float,
                     *, ds_max: float = 0.01) -> list[Branch]:
    """Every solution component crossing |H - H_c| <= window near the BP at gravity ``G``.

    G = 0: both halves of the pitchfork, each by its own branch switch (not one mirrored).
    G != 0: the state at H_c - window on uniform shear and the two pitchfork states at
    H_c + window, each continued in G from 0 to ``G``, then traced in H inside the window;
    a seed already on a traced component is dropped.  Branch ids are f"G{G:g}.k".
    """
    Hc = float(bp.params["H"])
    settings = GravitySettings(H_range=(Hc - window, Hc + window), ds=0.002, ds_max=ds_max, max_angle=0.1,
                               max_steps=4000)
    opts = settings.h_options()
    if G == 0:
        halves = switch(problem, base, bp, _no_bp_detection(opts), directions=(+1, -1), branch_id_prefix="G0")
        for k, b in enumerate(halves):
            b.id = f"G0.{k}"
        return halves
    if G < 0:
        problem = SignedGravity(problem)  # type: ignore[assignment]
    p0 = {**bp.params, "G": 0.0}
    halves = switch(problem, base, bp, _no_bp_detection(opts), directions=(+1, -1), branch_id_prefix="s")
    seeds: list[tuple[Array, dict[str, float]]] = []
    pl = {**p0, "H": Hc - window}
    seeds.append((problem.initial_guess(pl), pl))
    for h in halves:
        seeds += list(_states_at(h, Hc + window))
    out: list[Branch] = []
    for x, p in seeds:
        x = newton(problem, x, p, NewtonOptions(max_iterations=20)).u
        xg = _g_homotopy(problem, x, {**p, "G": 0.0}, G)
        if xg is None:
            continue
        q = {**p, "G": G}
        if any(on_branch(problem, xg, q, b, tol=1e-4) for b in out):
            continue
        out.append(trace_in_H(problem, xg, q, settings, branch_id=f"G{G:g}.{len(out)}"))
    if not out:
        raise ValueError(f"no solution near the BP at H = {Hc:.6g} survived the homotopy to G = {G:g}")
    return out


def _no_bp_detection(opts: ContinuationOptions) -> ContinuationOptions:
    """The gravity-free halves are traced with BP detection off (the window holds no other BP)."""
    from dataclasses import replace

    return replace(opts, detection=DetectionOptions(detect_branch_points=False))


def unfolding_data(branches: Sequence[Branch], critical_value: float) -> tuple[list[Array], list[Array], list[float]]:
    """Per branch: H - H_c, delta_s and G (constant along each branch), for contin.fit."""
    lam, delta, mu = [], [], []
    for b in branches:
        g = np.asarray(b.params["G"])
        if np.ptp(g) != 0:
            raise ValueError(f"branch {b.id!r} is not at constant G")
        lam.append(np.asarray(b.params["H"]) - critical_value)
        delta.append(odd_delta(b))
        mu.append(float(g[0]))
    return lam, delta, mu


def ls_unfolding(problem: CouetteProblem, bp: SpecialPoint, *, amplitude: float = 1e-2) -> ReducedUnfolding:
    """Lyapunov-Schmidt unfolding at the BP in delta_s, G (contin.normalform.pitchfork_unfolding)."""
    return pitchfork_unfolding(problem, bp.state, {**bp.params, "G": 0.0}, "H", "G", odd_order_parameter(problem),
                               amplitude=amplitude, tol=1e-11, polish=1)


def fold_on_curve_at(problem: CouetteProblem, curve: Branch, G: float, *, tol: float = 1e-11) -> tuple[float, Array]:
    """The point of the fold curve ``curve`` (from contin.foldcurve.trace_fold_curve in (H, G))
    at gravity ``G``: Newton on the same augmented fold system F = 0, J phi = 0, c.phi = 1 with
    the roles swapped (G fixed, H an unknown), from the curve point nearest in G.
    Returns (H, state)."""
    from contin.foldcurve import FoldProblem

    g = np.asarray(curve.params["G"])
    i = int(np.argmin(np.abs(g - G)))
    aug = np.asarray(curve.states[i], float)
    n = (aug.size - 1) // 2
    u, phi = aug[:n], aug[n: 2 * n]
    fold = FoldProblem(problem, "H", phi / (phi @ phi))
    p = {k: float(v[i]) for k, v in curve.params.items()}
    p["G"] = float(G)
    start = np.concatenate([u, phi, [p["H"]]])
    res = newton(fold, start, p, NewtonOptions(tol=tol, max_iterations=20))
    if not res.converged:
        raise ValueError(f"the fold curve {curve.id!r} could not be corrected to G = {G:g}: {res.message}")
    return float(res.u[2 * n]), res.u[:n]


def fold_curve_check(unfolding: object, curve: Branch, critical_value: float,
                     G_range: tuple[float, float] = (1e-8, 1e-6)) -> dict[str, object]:
    """Computed fold points (H_LP - H_c at the curve's own G values, G in ``G_range``) against
    the unfolding's prediction (contin.normalform.Unfolding.fold: next order, and leading
    order 3/b1 (alpha1 G/2)^(2/3)); with the exponent of H_LP - H_c ~ G^p fitted to the
    computed points in [G_range[0], 10 G_range[0]]."""
    g = np.asarray(curve.params["G"])
    h = np.asarray(curve.params["H"]) - critical_value
    sel = (g >= G_range[0]) & (g <= G_range[1])
    if sel.sum() < 3:
        raise ValueError(f"the fold curve has fewer than 3 points with {G_range[0]:g} <= G <= {G_range[1]:g}")
    rows = []
    for G, dh in sorted(zip(g[sel], h[sel])):
        pred = unfolding.fold(G)[0]  # type: ignore[attr-defined]
        lead = unfolding.fold(G, leading=True)[0]  # type: ignore[attr-defined]
        rows.append({"G": float(G), "H_minus_Hc": float(dh), "predicted": float(pred), "leading": float(lead),
                     "rel_error": float(pred / dh - 1), "rel_error_leading": float(lead / dh - 1)})
    low = sel & (g <= 10 * G_range[0])
    if low.sum() < 2:
        low = sel
    slope = float(np.polyfit(np.log(g[low]), np.log(h[low]), 1)[0])
    return {"points": rows, "exponent": slope, "exponent_range": [float(g[low].min()), float(g[low].max())],
            "max_rel_error": max(abs(r["rel_error"]) for r in rows),
            "max_rel_error_leading": max(abs(r["rel_error_leading"]) for r in rows)}
