"""User zeros and events (label UZ): AUTO-07p's UZR / UZSTOP, BifurcationKit's events.

Two kinds of point test (``contin.pointtests``), each located along the branch like a fold
(re-correction at intermediate arclengths, Anderson-Bjorck regula falsi, ``contin.locate``):

- a parameter value, ``ContinuationOptions.user_zeros = {"H": (25, 30)}``: the test function
  is g = p - value for the continuation parameter p (AUTO's UZR);
- an event, ``ContinuationOptions.events = {"name": g}`` with ``g(u, params) -> float``: a UZ
  wherever g changes sign (the note names the event).

Each UZ stores its state, like every special point, and ``data['value']`` (the target value
of a parameter zero, 0 for an event).  ``stop_at=("UZ1",)`` ends the run at the first one
(AUTO's negative UZR / UZSTOP).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contin.branch import SpecialPoint
from contin.pointtests import Crossing
from contin.problem import Array
from contin.testfunctions import sign_change


#: a parameter value within this relative distance of a user zero is at it (a few roundings)
START_ROUNDING = 4 * float(np.finfo(float).eps)
#: the note of a UZ at the start point of a branch (after its "NAME=VALUE")
AT_START = "at the start point (not counted by stop_at)"


@dataclass(frozen=True)
class ParameterZeros:
    """UZ where the continuation parameter equals one of ``values``."""

    parameter: str
    values: tuple[float, ...]
    kind: str = "UZ"

    @property
    def name(self) -> str:
        return f"uz:{self.parameter}"

    def value(self, system: Any, x: Array) -> float:
        return float(x[-1])

    def crossings(self, va: float, vb: float) -> list[Crossing]:
        out: list[Crossing] = []
        for target in self.values:
            if (va - target) * (vb - target) < 0:
                out.append((f"{self.parameter}={_exact(target)}", lambda v, t=target: float(v) - t))
        return out

    def at_start(self, v: float) -> list[str]:
        """The values the start point's parameter ``v`` equals within rounding (p - value is 0
        there, so no step crosses them: ``contin trace bratu --uz lam=0.1``, the start value,
        was reported nowhere); the tracer labels the start point UZ for each."""
        return [f"{self.parameter}={_exact(t)}" for t in self.values
                if abs(v - t) <= START_ROUNDING * max(abs(t), abs(v))]

    def turning_crossings(self, va: float, vb: float, v_turn: float) -> list[Crossing]:
        """The values crossed twice in a step that turned at a fold where the parameter is
        ``v_turn``: between the ends' side and the fold's (p - value has one sign at both ends);
        the tracer locates each on both sides of the fold."""
        out: list[Crossing] = []
        for target in self.values:
            if (va - target) * (vb - target) > 0 and (v_turn - target) * (va - target) < 0:
                out.append((f"{self.parameter}={_exact(target)}", lambda v, t=target: float(v) - t))
        return out

    def beyond(self, va: float, vb: float, reach: float) -> list[str]:
        """The values beyond both ends of a step (on either side) by at most ``reach``: those a
        fold inside the step that was not located may hide."""
        lo, hi = min(va, vb), max(va, vb)
        return [f"{self.parameter}={_exact(t)}" for t in self.values if lo - reach <= t < lo or hi < t <= hi + reach]

    def finish(self, system: Any, sp: SpecialPoint, x: Array) -> SpecialPoint:
        note = sp.note.split(";")[0]
        target = float(note.split("=", 1)[1]) if "=" in note else math.nan
        return replace(sp, data={**sp.data, "value": target})


@dataclass(frozen=True)
class Event:
    """UZ where the user function g(u, params) changes sign."""

    label: str
    g: Callable[..., float]
    kind: str = "UZ"

    @property
    def name(self) -> str:
        return f"event:{self.label}"

    def value(self, system: Any, x: Array) -> float:
        # NaN is returned, not raised: the whole trace ended in a ValueError at the first point
        # where g was NaN (all of it lost); the tracer's detection says where g was not finite
        return float(self.g(x[:-1], system.params_at(x[-1])))

    def crossings(self, va: float, vb: float) -> list[Crossing]:
        return [(self.label, float)] if sign_change(va, vb) else []

    def turning_crossings(self, va: float, vb: float, v_turn: float) -> list[Crossing]:
        """In a step that turned at a fold where g is ``v_turn``: g has one sign at both ends and
        the other at the fold, so it vanishes on both sides of it (as a parameter value does,
        :meth:`ParameterZeros.turning_crossings`)."""
        if not all(math.isfinite(v) for v in (va, vb, v_turn)) or va == 0 or vb == 0 or v_turn == 0:
            return []
        if (va > 0) == (vb > 0) and (v_turn > 0) != (va > 0):
            return [(self.label, float)]
        return []

    def finish(self, system: Any, sp: SpecialPoint, x: Array) -> SpecialPoint:
        return replace(sp, data={**sp.data, "value": 0.0})


def _exact(value: float) -> str:
    """Short text of ``value`` that reads back as the same float (finish() parses the note)."""
    text = f"{value:g}"
    return text if float(text) == value else repr(value)


def user_tests(problem: Any, parameter: str, options: Any) -> list[Any]:
    """The UZ point tests of one trace in ``parameter``; ValueError for an unknown name.

    A value of a parameter other than the continuation one is never crossed on a
    one-parameter branch, so it is accepted and ignored (the same options serve traces in
    different parameters).
    """
    out: list[Any] = []
    names = tuple(problem.parameter_names)
    for name, values in options.user_zeros.items():
        if name not in names:
            raise ValueError(f"user_zeros given for unknown parameter {name!r}; the problem has {', '.join(names)}")
        if name == parameter and values:
            out.append(ParameterZeros(name, tuple(np.asarray(values, dtype=float).tolist())))
    for label, g in options.events.items():
        out.append(Event(str(label), g))
    return out
