"""Point tests: test functions beyond LP/BP that the tracer evaluates at every point.

A point test computes a value at each corrected point x = (u, p) (any object: a number, an
array of eigenvalues), says which zeros its values bracket between two neighbouring points
(``crossings``: one real function g of the value per zero, with g(v_a) and g(v_b) of opposite
sign), and completes the located special point (``finish``: e.g. omega and l1 of a Hopf point).
The tracer (``contin.continuation``) locates each zero like a fold, by re-correcting at
intermediate arclengths (``contin.locate``), so a point test inherits the fold's accuracy.

Implemented: Hopf points (``contin.hopf``, label HB), user zeros / events (``contin.events``,
label UZ), and Bogdanov-Takens points of fold and Hopf curves (``contin.hopfcurve``, label BT),
which those augmented problems supply through an optional ``point_tests()`` method.
:func:`contin.pointtestset.point_tests` builds the list for one trace (a module of its own:
the tests import :data:`Crossing` from here, so this module imports none of them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from contin.branch import SpecialPoint
from contin.problem import Array

#: A located zero: (note, g) with g(value) -> float changing sign across it.
Crossing = tuple[str, Callable[[Any], float]]


class PointTest(Protocol):
    """Interface of a point test (see the module docstring)."""

    name: str  # key in TestValues.extra
    kind: str  # AUTO label of its points ('HB', 'UZ')

    def value(self, system: Any, x: Array) -> Any: ...

    def crossings(self, va: Any, vb: Any) -> list[Crossing]: ...

    def finish(self, system: Any, sp: SpecialPoint, x: Array) -> SpecialPoint: ...

    # Optional: ``value_error(system, x) -> float``, an estimate of the absolute error of the
    # crossing's test value at x (a value from difference quotients: l1 at a GH).  The tracer
    # turns it into the located point's position uncertainty (error / the value's change across
    # the step, times the step's parameter span) and says so where that exceeds the location
    # tolerance (``contin.continuation.position_doubt``).
