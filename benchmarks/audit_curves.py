"""Re-solve audit of two-parameter curves (session 16, audit16): every stored point of a fold or
Hopf curve against scipy's fsolve of its defining system, written here independently of contin
(the models' residuals and Jacobians by hand): at the point's second parameter, (u, p1) with

    fold:  F(u, p) = 0, det J = 0;
    Hopf:  F(u, p) = 0, and for n = 2 tr J = 0, for n = 3 a1 a2 - a3 = 0 (Routh-Hurwitz:
           det(mu - J) = mu^3 + a1 mu^2 + a2 mu + a3 has a pair +-i sqrt(a2); a neutral saddle
           where a2 < 0, as the curve's own kappa < 0 part).

    python -m benchmarks.audit_curves results/ab_fold.h5 results/ab_hopf.h5 [more files]
    python -m benchmarks.audit_curves --co      # CO oxidation's Hopf and fold curves in (q2, k)

Prints per curve the max error max(|u - u_ref|_inf, |p1 - p1_ref|) / max(1, |.|) over its points.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.optimize import fsolve


def ab_model(beta: float) -> tuple[Callable[..., Any], Callable[..., Any]]:
    def f(u, d, b):
        h = d * (1 - u[0]) * math.exp(u[1])
        return np.array([-u[0] + h, -u[1] + b * h - beta * u[1]])

    def j(u, d, b):
        e = d * math.exp(u[1])
        return np.array([[-1 - e, (1 - u[0]) * e], [-b * e, -1 + b * (1 - u[0]) * e - beta]])

    return f, j


def co_model(p: dict[str, float]) -> tuple[Callable[..., Any], Callable[..., Any]]:
    """BifurcationKit's tutorialCO (tests/hopf_models.CO), parameters (q2, k) free."""
    q1, q3, q4, q5, q6 = (p[k] for k in ("q1", "q3", "q4", "q5", "q6"))

    def f(u, q2, k):
        x, y, s = u
        z = 1 - x - y - s
        return np.array([2 * q1 * z ** 2 - 2 * q5 * x ** 2 - q3 * x * y,
                         q2 * z - q6 * y - q3 * x * y,
                         q4 * z - k * q4 * s])

    def j(u, q2, k):
        x, y, s = u
        z = 1 - x - y - s
        return np.array([[-4 * q1 * z - 4 * q5 * x - q3 * y, -4 * q1 * z - q3 * x, -4 * q1 * z],
                         [-q2 - q3 * y, -q2 - q6 - q3 * x, -q2],
                         [-q4, -q4, -q4 - k * q4]])

    return f, j


def condition(kind: str, jac: np.ndarray) -> float:
    if kind == "fold-curve":
        return float(np.linalg.det(jac))
    n = jac.shape[0]
    if n == 2:
        return float(np.trace(jac))
    a1 = -np.trace(jac)
    a2 = sum(np.linalg.det(jac[np.ix_(ix, ix)]) for ix in ([0, 1], [0, 2], [1, 2]))
    a3 = -np.linalg.det(jac)
    return float(a1 * a2 - a3)


def audit_curve(kind: str, n: int, states: np.ndarray, p1: np.ndarray, p2: np.ndarray,
                f: Callable[..., Any], j: Callable[..., Any]) -> tuple[float, int]:
    """(max error, index) of the stored points (u = states[i, :n], p1[i]) at p2[i]."""
    worst, at = 0.0, -1
    for i in range(len(p1)):
        guess = np.concatenate([states[i, :n], [p1[i]]])

        def system(z, i=i):
            return np.concatenate([f(z[:n], z[n], p2[i]), [condition(kind, j(z[:n], z[n], p2[i]))]])

        z, _, ok, _ = fsolve(system, guess, xtol=1e-14, full_output=True)
        if np.max(np.abs(system(z))) > 1e-11:
            err = math.inf
        else:
            err = float(np.max(np.abs(z - guess) / np.maximum(1.0, np.abs(z))))
        if not err <= worst:
            worst, at = err, i
    return worst, at


def audit_file(path: str) -> None:
    from contin import io

    branches, meta = io.load(path)
    params = meta.get("parameters", {})
    f, j = ab_model(float(params.get("beta", 3.0)))
    for b in branches:
        if b.kind not in ("fold-curve", "hopf-curve"):
            continue
        first, second = b.free
        err, at = audit_curve(b.kind, 2, np.asarray(b.states), np.asarray(b.params[first]),
                              np.asarray(b.params[second]), f, j)
        print(f"{path} {b.id} {b.kind} {len(b)} points: max error {err:.2g} at point {at}")


def audit_co() -> None:
    from contin.continuation import trace
    from contin.foldcurve import trace_fold_curve
    from contin.hopfcurve import trace_hopf_curve
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import COOxidation as CO

    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.01), bounds={"q2": (0.5, 1.9)}, max_steps=3000)
    branch = trace(CO(), np.array([0.2, 0.05, 0.5]), CO.PARAMS, "q2", opts)
    copts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.02), bounds={"q2": (0.5, 2.2), "k": (0.0, 1.0)},
                                max_steps=600)
    f, j = co_model(CO.PARAMS)
    curves = [("hopf", trace_hopf_curve(CO(), branch.points("HB")[0], "k", copts, parameter="q2"))]
    if branch.points("LP"):
        curves.append(("fold", trace_fold_curve(CO(), branch.points("LP")[0], "k", copts, parameter="q2")))
    from contin.twoparam import continue_point

    for name, c in list(curves):  # the other curve through each BT (the BT switch)
        for bt in c.points("BT")[:1]:
            curves.append((f"{'fold' if name == 'hopf' else 'hopf'} from {name} {bt.name}",
                           continue_point(CO(), c, bt, "k", copts)))
    for name, c in curves:
        err, at = audit_curve(c.kind, 3, np.asarray(c.states), np.asarray(c.params["q2"]), np.asarray(c.params["k"]), f, j)
        print(f"CO {name} curve {len(c)} points ({', '.join(s.name for s in c.special_points)}): max error {err:.2g} at point {at}")


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--co" in args:
        audit_co()
    for path in (a for a in args if a != "--co"):
        audit_file(path)
