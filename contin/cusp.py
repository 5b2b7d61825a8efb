"""Cusp points (CP) on fold curves: where the quadratic coefficient of the fold vanishes.

At a fold of F(u, p) = 0 with simple null vectors phi (J phi = 0) and psi (psi^T J = 0) the
reduced equation is a delta^2 + b delta_p = 0 with a = psi^T B(phi, phi) / 2, B = F_uu.  Along a
fold curve in two parameters a changes sign at a cusp, where two folds meet and the fold
degenerates to a cubic (Kuznetsov, *Elements of Applied Bifurcation Theory*, 3rd ed. 2004,
sec. 8.2; Govaerts 2000, sec. 4.3; AUTO-07p labels the point CP).

psi and phi have arbitrary signs, so a is computed from the bordered matrix
A = [[J, c], [c^T, 0]] (c the fold system's normalisation): A [x; .] = e_{n+1} and
A^T [y; .] = e_{n+1} give x ~ phi and y ~ psi with det(A) x and det(A) y polynomial in the
entries of J (Cramer's rule; the same device as the Bogdanov-Takens test of
``contin.hopfcurve``).  A is nonsingular along a fold curve of simple folds, so
sign(det A) * y^T B(x, x) / (|y| |x|^2) is a smooth function along the curve that vanishes
exactly at cusps.  B(x, x) is the central difference of J along x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from contin.branch import SpecialPoint
from contin.pointtests import Crossing
from contin.problem import Array
from contin.testfunctions import sign_change


@dataclass
class CuspTest:
    """The CP point test of a fold curve (``contin.pointtests``)."""

    fold: Any  # contin.foldcurve.FoldProblem
    name: str = "cusp"
    kind: str = "CP"

    def value(self, system: Any, x: Array) -> float:
        from contin.linalg import factorize_bordered

        fold = self.fold
        n = fold.n
        u, phi, q = fold.split(x[:-1], system.params_at(x[-1]))
        jac = fold.problem.jacobian(u, q)
        c = fold.c / max(float(np.linalg.norm(fold.c)), 1e-300)
        fact = factorize_bordered(jac, c, np.concatenate([c, [0.0]]))
        if fact is None:
            return math.nan
        e = np.zeros(n + 1)
        e[-1] = 1.0
        xr = fact.solve(e)[:n]
        yl = fact.solve(e, trans="T")[:n]
        bxx = np.asarray(fold._hessian_phi(u, xr, q) @ xr)
        scale = float(np.linalg.norm(yl)) * float(xr @ xr)
        if scale == 0 or not math.isfinite(scale):
            return math.nan
        sign, _ = fact.det_sign_log()
        return float(sign * (yl @ bxx) / scale)

    def crossings(self, va: float, vb: float) -> list[Crossing]:
        return [("cusp (psi . B(phi, phi) = 0)", float)] if sign_change(va, vb) else []

    def finish(self, system: Any, sp_: SpecialPoint, x: Array) -> SpecialPoint:
        return sp_
