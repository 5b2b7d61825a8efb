"""Floquet multipliers of a periodic orbit from its collocation equations, and the PD / NS tests.

Method: the monodromy matrix of the *discretized* variational equation M v' = T J(u(t)) v.  The
linearized collocation equations of mesh interval j,

    sum_k E[j, i, k] v_{j,k} = 0,   E[j, i, k] = D[i, k] M - h_j T L[i, k] J(u(z_ji))

(``contin.collocation.Collocation.interval_blocks``), are NCOL n equations in the NCOL n values
v_{j,1..NCOL} given v_{j,0}: solving them condenses the interval to a transfer matrix
v_{j,NCOL} = P_j v_{j,0}, and the monodromy is P_{NTST-1} ... P_0 (the condensation of AUTO's
Floquet computation, Fairgrieve & Jepson, SIAM J. Numer. Anal. 28, 1991, without their periodic
Schur form).  Why this and not an integration of the variational equation by ``solve_ivp``: it
costs NTST small dense solves with the Jacobians the continuation already evaluates, it is the
linearization of exactly the equations that were solved, and its error is the collocation
error (a trivial multiplier 1 to about 1e-10 at the defaults on smooth orbits).  Limitation: the
plain product loses the multipliers that are smaller than about 1e-16 times the largest one
(strongly stable directions of stiff orbits); they come out as rounding-level numbers, which
does not change the stability verdict.

The trivial multiplier (the one nearest 1: the time-shift mode u') is removed; its distance from
1 is reported as the accuracy check (``floquet_error``).  Next to a fold of cycles it is no
accuracy check: there the trivial multiplier is double with a Jordan block (the period changes
with the amplitude), so a discretization error d moves it by sqrt(d) (AUTO demo ab: 1e-4 at the
LPC for every NTST from 20 to 80).  The check that holds there too is the residual of the trivial
multiplier's known eigenvector, the flow direction f = M^{-1} F(u(0)):
``flow_error`` = |P f - f| / |f| with P the monodromy (O(d) at a fold as anywhere); the cycle
guard (``contin.cycles.CycleOptions.floquet_tol``) uses it.  Stability: every other multiplier
strictly inside the unit circle.

Point tests (``contin.pointtests``) located by the tracer like folds: PD, a real multiplier
through -1 (g = |mu| - 1 of the real negative multiplier tracked across the step), and NS, a
complex pair through the unit circle (g = |mu| - 1 of the pair's member with Im mu > 0).  LPC,
the fold of cycles, is the tracer's own LP test on the cycle system (``contin.cycles``).
A PD is a real negative multiplier tracked from one point to the next; a complex pair that turns
real and has a member leave through -1 within one step has no such partner.  Where tracking pairs
an even number of crossings (none) but the sign of det(P + I) = prod (mu + 1) changes
(:func:`plus_one_sign_log`: the parity of the real multipliers below -1) the PD is located on that
product instead (while no multiplier exceeds :data:`PRODUCT_RANGE`, where those near -1 are still
resolved).  AUTO's product prod (|mu| - 1) over the real negative multipliers only, tried
before, flipped sign on the rounding-level multipliers (+-1e-17) of strongly stable orbits and
where a real pair passes through a tiny complex pair (six spurious PDs on Roessler's
period-doubled branch); mu + 1 over all multipliers is positive for both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.branch import SpecialPoint
from contin.hopf import distance_to_segment
from contin.pointtests import Crossing
from contin.problem import Array

#: Relative imaginary part below which a multiplier counts as real.
REAL_TOL = 1e-8
#: Largest multiplier modulus at both ends of a step for the PD test on prod (mu + 1): the plain
#: monodromy product resolves multipliers down to ~1e-16 of the largest, so those near -1 to ~1e-6.
PRODUCT_RANGE = 1e10
#: Distance of the trivial multiplier from 1 above which an orbit's multipliers are doubtful.
FLOQUET_DOUBTFUL = 1e-4


def monodromy(blocks: Array) -> Array:
    """The monodromy matrix P_{NTST-1} ... P_0 from the interval blocks E (module docstring),
    shape (NTST, NCOL, NCOL + 1, n, n)."""
    ntst, ncol, _, n, _ = blocks.shape
    out = np.eye(n)
    for j in range(ntst):
        e = blocks[j].transpose(0, 2, 1, 3).reshape(ncol * n, (ncol + 1) * n)
        transfer = np.linalg.solve(e[:, n:], -e[:, :n])[-n:]
        out = transfer @ out
    return out


def eigenfunction(blocks: Array, v0: Array) -> Array:
    """The solution v of the discretized variational equation with v(0) = v0 at every node
    (shape (NTST NCOL + 1, n): the last row is v(1) = P v0), interval by interval as in
    :func:`monodromy`."""
    ntst, ncol, _, n, _ = blocks.shape
    out = np.empty((ntst * ncol + 1, n), dtype=np.result_type(v0, float))
    v = v0
    for j in range(ntst):
        e = blocks[j].transpose(0, 2, 1, 3).reshape(ncol * n, (ncol + 1) * n)
        rest = np.linalg.solve(e[:, n:], -e[:, :n] @ v).reshape(ncol, n)
        out[j * ncol] = v
        out[j * ncol + 1: (j + 1) * ncol + 1] = rest
        v = rest[-1]
    return out


@dataclass(frozen=True)
class Multipliers:
    """The Floquet multipliers of one orbit: ``others`` (all but the trivial one, by decreasing
    modulus) and the trivial one's distance from 1, ``error``."""

    others: np.ndarray
    trivial: complex
    flow_error: float = math.nan

    @property
    def error(self) -> float:
        return abs(self.trivial - 1.0)

    @property
    def stable(self) -> bool:
        return bool(np.all(np.abs(self.others) < 1.0))

    @property
    def n_unstable(self) -> int:
        return int(np.sum(np.abs(self.others) > 1.0))

    @property
    def all(self) -> np.ndarray:
        return np.concatenate([[self.trivial], self.others])


def multipliers(blocks: Array, flow: Array | None = None) -> Multipliers:
    """The multipliers of the orbit whose interval blocks are ``blocks``; ``flow`` (u'(0), up to
    a factor) gives ``flow_error`` (module docstring)."""
    mono = monodromy(blocks)
    mu = np.linalg.eigvals(mono)
    k = int(np.argmin(np.abs(mu - 1.0)))
    rest = np.delete(mu, k)
    err = math.nan
    if flow is not None and np.any(flow):
        err = float(np.linalg.norm(mono @ flow - flow) / np.linalg.norm(flow))
    return Multipliers(rest[np.argsort(-np.abs(rest), kind="stable")], complex(mu[k]), err)


def _is_real(mu: complex) -> bool:
    return abs(mu.imag) <= REAL_TOL * max(1.0, abs(mu))


def _log_distance(v: np.ndarray, target: complex) -> np.ndarray:
    """Distances in log |mu| and arg mu (on the circle): multipliers spread over many decades (a
    strongly stable orbit's 1e-18 next to -0.9) are paired by their growth, not by their
    difference (a step from -0.88 to -15.9 paired -0.88 with 1e-17 and missed the PD)."""
    lv = np.log(np.maximum(np.abs(v), 1e-300))
    lt = math.log(max(abs(target), 1e-300))
    da = np.abs(np.angle(v) - np.angle(target))
    return np.abs(lv - lt) + np.minimum(da, 2 * np.pi - da)


def _nearest(v: np.ndarray, target: complex) -> int:
    return int(np.argmin(_log_distance(v, target)))


def circle_crossings(va: np.ndarray, vb: np.ndarray, kind: str) -> list[tuple[complex, complex]]:
    """Multipliers at two points paired by mutual nearest neighbours whose modulus crosses 1:
    ``kind`` 'PD' keeps the real negative ones, 'NS' the complex ones with Im > 0."""
    out: list[tuple[complex, complex]] = []
    for i, a in enumerate(va):
        if vb.size == 0:
            break
        b = vb[_nearest(vb, a)]
        if _nearest(va, b) != i or (abs(a) - 1.0) * (abs(b) - 1.0) >= 0:
            continue
        if kind == "PD" and _is_real(a) and _is_real(b) and a.real < 0 and b.real < 0:
            out.append((complex(a), complex(b)))
        elif kind == "NS" and not _is_real(a) and not _is_real(b) and a.imag > 0 and b.imag > 0:
            out.append((complex(a), complex(b)))
    return out


def plus_one_sign_log(others: np.ndarray) -> tuple[float, float]:
    """(sign, log|.|) of det(P + I) / 2 = prod (mu + 1) over the nontrivial multipliers: a complex
    pair gives |mu + 1|^2 > 0 and a real multiplier mu + 1, so the sign is (-1)^(number of real
    multipliers below -1) and changes exactly where an odd number of real multipliers passes -1,
    however they were complex or real before; rounding-level multipliers (+-1e-17) give +1 either
    way (AUTO's product of |mu| - 1 over the real negative ones flipped on them).  (0, -inf)
    for no multipliers or a multiplier at -1 exactly."""
    v = np.asarray(others, dtype=complex)
    if v.size == 0:
        return (0.0, -math.inf)
    factors = np.abs(v + 1.0)
    if np.any(factors == 0.0):
        return (0.0, -math.inf)
    below = sum(1 for m in v if _is_real(complex(m)) and m.real < -1.0)
    return (-1.0 if below % 2 else 1.0, float(np.sum(np.log(factors))))


@dataclass
class ShrinkTest:
    """Point test HB on a cycle branch: the orbits shrink to an equilibrium (a Hopf point).  g is the
    signed amplitude a(x) = int <u - mean u, r - mean r> dt / int |r - mean r|^2 dt against the
    segment's phase reference r: through zero amplitude the branch goes on with the orbits of the
    approach traversed half a period shifted (a = -1 times theirs), so a changes sign there."""

    cycles: Any
    name: str = "shrink"
    kind: str = "HB"

    def value(self, system: Any, x: Array) -> float:
        return float(self.cycles.signed_amplitude(x[:-1]))

    def crossings(self, va: float, vb: float) -> list[Crossing]:
        if math.isfinite(va) and math.isfinite(vb) and va * vb < 0:
            return [("", lambda v: float(v))]
        return []

    def finish(self, system: Any, sp: SpecialPoint, x: Array) -> SpecialPoint:
        note = "Hopf point: the orbits shrink to an equilibrium (amplitude 0)"
        return replace(sp, data={**sp.data, "period": float(x[-2])}, note="; ".join(t for t in (note, sp.note) if t))


@dataclass
class FloquetTest:
    """Point test PD or NS on a cycle branch (module docstring); ``cycles`` is the
    ``contin.cycles.CycleProblem`` (it computes and caches the multipliers)."""

    cycles: Any
    kind: str = "PD"

    @property
    def name(self) -> str:
        return self.kind.lower()

    def value(self, system: Any, x: Array) -> np.ndarray:
        try:
            return self.cycles.multipliers(x[:-1], system.params_at(x[-1])).others
        except np.linalg.LinAlgError:
            return np.zeros(0, dtype=complex)

    def crossings(self, va: np.ndarray, vb: np.ndarray) -> list[Crossing]:
        out: list[Crossing] = []
        for a, b in circle_crossings(va, vb, self.kind):

            def g(v: np.ndarray, a: complex = a, b: complex = b) -> float:
                if v.size == 0:
                    return math.nan
                # the multiplier nearest the segment [a, b] (as the Hopf test tracks its eigenvalue)
                return float(abs(v[int(np.argmin(distance_to_segment(v, a, b)))]) - 1.0)

            out.append(("", g))
        resolved = va.size and vb.size and max(np.max(np.abs(va)), np.max(np.abs(vb))) < PRODUCT_RANGE
        if self.kind == "PD" and len(out) % 2 == 0 and resolved:
            sa, sb = plus_one_sign_log(va), plus_one_sign_log(vb)
            if sa[0] * sb[0] < 0:  # an odd number of real multipliers through -1 that tracking did not pair
                from contin.testfunctions import signed_value

                ref = max(sa[1], sb[1])

                def gd(v: np.ndarray, ref: float = ref) -> float:
                    return signed_value(plus_one_sign_log(v), ref) if v.size else math.nan

                out.append(("", gd))
        return out

    def finish(self, system: Any, sp: SpecialPoint, x: Array) -> SpecialPoint:
        mu = self.cycles.multipliers(x[:-1], system.params_at(x[-1]))
        crit = mu.others[int(np.argmin(np.abs(np.abs(mu.others) - 1.0)))]
        data = {"period": float(x[-2]), "floquet_error": mu.error}
        if self.kind == "PD":
            note = "period doubling (a multiplier through -1)"
            data["multiplier"] = float(crit.real)
        else:
            note = "Neimark-Sacker (a complex pair through the unit circle)"
            data["theta"] = abs(float(np.angle(crit)))
        return replace(sp, data={**sp.data, **data}, note="; ".join(t for t in (note, sp.note) if t))
