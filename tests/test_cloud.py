"""Clouds of special points (contin.cloud): one singular point reported several times.

Closed form: F = (x (x^2 + (mu - 1)^2 - 1), y - x^2); the circle x^2 + (mu - 1)^2 = 1 switched
at the pitchfork mu = 0 crosses the trivial branch at mu = 2, where it has one fold (its
rightmost point) and one BP; the tracer crawls across it and lists more: the branch must say so.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from contin.branch import SpecialPoint
from contin.cloud import CLOUD, special_cloud
from test_rejoin import traced


def clouds(b):
    return [m for m in b.audit if m.startswith(CLOUD)]


def test_the_circle_crossing_its_second_pitchfork_says_its_special_points_there_are_a_cloud():
    """Exactly one fold and one BP lie at mu = 2 on the circle; where the branch lists three or
    more special points there (1e-6), the audit says so, at mu = 2 (1e-6), and the arcs bounded
    at mu = 1.9 (no singular point inside) have no such line."""
    _, _, kids = traced(3.0)
    for kid in kids:
        at2 = [s for s in kid.special_points if s.type in ("LP", "BP") and abs(s.params["mu"] - 2) < 1e-6]
        assert len(at2) >= 3  # the crawl across the vertex the line is about
        (line,) = clouds(kid)
        assert abs(float(line.split("mu = ")[1].split(":")[0]) - 2) < 1e-6, line
    for kid in traced(1.9)[2]:
        assert not clouds(kid)


def point(kind, mu, x):
    return SpecialPoint(kind, 0, {"mu": mu}, np.nan, np.array([x, x * x]))


def test_two_points_or_three_apart_are_no_cloud():
    """A pitchfork passed along its bifurcated branch has a BP and an LP at one place (two: no
    cloud); three points 1e-5 apart in mu, or at one mu with states 0.1 apart (three sheets),
    are no cloud either; three within 1e-9 and 1e-6 are one."""
    _, _, kids = traced(1.9)
    b = kids[0]
    two = dataclasses.replace(b, special_points=[point("BP", 2.0, 0.0), point("LP", 2.0, 1e-7)])
    assert special_cloud(two) is None
    apart = dataclasses.replace(b, special_points=[point("LP", 2.0 + 1e-5 * k, 0.0) for k in range(3)])
    assert special_cloud(apart) is None
    sheets = dataclasses.replace(b, special_points=[point("LP", 2.0, 0.1 * k) for k in range(3)])
    assert special_cloud(sheets) is None
    one = dataclasses.replace(b, special_points=[point("LP", 2.0 + 1e-9 * k, 1e-6 * k) for k in range(2)]
                              + [point("BP", 2.0, 0.0)])
    line = special_cloud(one)
    assert line is not None and "3 (2 LP, 1 BP)" in line
