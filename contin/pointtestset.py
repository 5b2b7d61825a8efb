"""The point tests of one trace (:func:`point_tests`), assembled from their modules.

Separate from :mod:`contin.pointtests` (the interface), which the test modules import, so the
imports run one way: continuation -> pointtestset -> events, hopf -> pointtests.
"""

from __future__ import annotations

from typing import Any

from contin.events import user_tests
from contin.hopf import hopf_test
from contin.pointtests import PointTest


def point_tests(problem: Any, system: Any, options: Any, n: int) -> list[PointTest]:
    """The point tests of one trace: Hopf (``DetectionOptions.detect_hopf``) and user zeros
    (``ContinuationOptions.user_zeros`` / ``events``)."""
    out: list[PointTest] = []
    hb = hopf_test(problem, options.detection, n)
    if hb is not None:
        out.append(hb)
    out.extend(user_tests(problem, system.parameter, options))
    if callable(getattr(problem, "point_tests", None)):  # augmented systems bring their own (BT)
        out.extend(problem.point_tests())
    return out
