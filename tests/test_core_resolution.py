"""The resolution guard of trace (ContinuationOptions.resolution_tol, optional problem hook
``under_resolved(u, p, tol) -> str | None``), on a toy problem with a known error estimate.

Toy: F(u, lam) = u - lam (1, 2), whose branch is u = lam (1, 2); its "discretization error"
is declared to be err(lam) = 10^(lam - 8), so err = tol = 1e-5 exactly at lam = 3.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from resolution_fixture_scenes import (  # tests/: the toy the CLI tests use too
    DIRECTION,
    Toy,
)

from contin.continuation import trace, trace_both
from contin.options import ContinuationOptions, StepOptions


def opts(hi=6.0, **kw):
    return ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.25), bounds={"lam": (-1.0, hi)}, **kw)


def test_branch_stops_mx_before_the_first_under_resolved_point():
    toy = Toy()
    br = trace(toy, np.zeros(2), {"lam": 0.0}, "lam", opts(resolution_tol=1e-5))
    lam = br.parameter_values
    assert br.status == "MX"
    # every stored point resolved, the last one within one step (ds_max = 0.25) of lam = 3
    assert np.all(lam <= 3.0) and 3.0 - 0.25 * math.sqrt(5) <= lam[-1] < 3.0
    assert all(toy.error(v) <= 1e-5 for v in lam)
    # the message names the parameter and the rejected value, then the problem's reason
    head, reason = br.message.split(": ", 1)
    assert head.startswith("under-resolved at lam = ")
    rejected = float(head.rsplit("= ", 1)[1])
    assert lam[-1] < 3.0 < rejected and reason == f"toy tail {toy.error(rejected):.3g} > 1e-05"
    mx = br.special_points[-1]
    assert mx.type == "MX" and mx.note == br.message and mx.params["lam"] == lam[-1]
    assert np.allclose(br.states[-1], lam[-1] * DIRECTION)
    # the hook got the tolerance of the options, once per candidate point
    assert {t for _, t in toy.calls} == {1e-5}


def test_guard_off_and_loose_tolerance_reach_the_bound():
    for tol in (None, 1e-1):
        toy = Toy()
        br = trace(toy, np.zeros(2), {"lam": 0.0}, "lam", opts(resolution_tol=tol))
        assert br.status == "EP" and br.message == "reached bound lam=6" and br.parameter_values[-1] == 6.0
        assert (toy.calls == []) == (tol is None)
    # err(6) = 1e-2 <= 1e-1: the loose run stores the bound point itself


def test_default_tolerance_is_3e_5():
    assert ContinuationOptions().resolution_tol == 3e-5
    br = trace(Toy(), np.zeros(2), {"lam": 0.0}, "lam", opts())
    rejected = float(br.message.split("= ")[1].split(":")[0])
    assert br.status == "MX" and br.parameter_values[-1] < 8 + math.log10(3e-5) < rejected  # err = tol at 3.477


def test_under_resolved_landing_on_the_bound_is_not_stored():
    """The predictor overshoots the bound lam = 3; the landed point (lam = 3) is under-resolved."""
    toy = Toy(jump_at=3.0)
    br = trace(toy, np.zeros(2), {"lam": 0.0}, "lam", opts(hi=3.0, resolution_tol=1e-5))
    assert br.status == "MX" and br.message == "under-resolved at lam = 3: toy tail 1 > 1e-05"
    assert br.parameter_values[-1] < 3.0


def test_under_resolved_start_point_gives_an_empty_mx_branch():
    toy = Toy()
    br = trace(toy, 4.0 * DIRECTION, {"lam": 4.0}, "lam", opts(resolution_tol=1e-5))
    assert br.status == "MX" and len(br) == 0
    assert br.message == "start point under-resolved at lam = 4: toy tail 0.0001 > 1e-05"
    both = trace_both(toy, 4.0 * DIRECTION, {"lam": 4.0}, "lam", opts(resolution_tol=1e-5))
    assert both.status == "MX" and len(both) == 0


def test_backward_direction_is_unaffected_where_resolved():
    """Going down from lam = 2 the error only falls: the run ends at the lower bound."""
    br = trace(Toy(), 2.0 * DIRECTION, {"lam": 2.0}, "lam", opts(resolution_tol=1e-5), direction=-1)
    assert br.status == "EP" and br.parameter_values[-1] == -1.0


@pytest.mark.parametrize("tol", [0.0, -1e-5, float("nan")])
def test_invalid_resolution_tol_is_one_clear_error(tol):
    with pytest.raises(ValueError, match="resolution_tol must be > 0"):
        ContinuationOptions(resolution_tol=tol)
