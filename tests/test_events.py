"""User zeros and events (UZ, contin.events) on the Lorenz equilibrium branch, where the state
has the closed form x = y = sqrt(beta (rho - 1)), z = rho - 1."""

from __future__ import annotations

import math

import numpy as np
import pytest

from contin.continuation import trace, trace_both
from contin.options import ContinuationOptions, StepOptions
from tests.hopf_models import Lorenz

BETA = 8.0 / 3.0
P0 = {"sigma": 10.0, "rho": 10.0, "beta": BETA}


def start():
    x = math.sqrt(BETA * 9.0)
    return np.array([x, x, 9.0])


def closed_form(rho):
    x = math.sqrt(BETA * (rho - 1))
    return np.array([x, x, rho - 1])


def options(**kw):
    return ContinuationOptions(step=StepOptions(ds=0.5, ds_max=2.0), bounds={"rho": (1.5, 40.0)}, **kw)


def test_parameter_values_and_event_zeros_are_located_with_their_states():
    events = {"x=4": lambda u, p: u[0] - 4.0}  # x = 4 where beta (rho - 1) = 16: rho = 1 + 16 / beta = 7
    br = trace_both(Lorenz(), start(), P0, "rho", options(user_zeros={"rho": [25, 30], "sigma": [3.0]}, events=events))
    uz = br.points("UZ")
    assert [sp.note for sp in uz] == ["x=4", "rho=25", "rho=30"]
    for sp, rho in zip(uz, (1 + 16 / BETA, 25.0, 30.0), strict=True):
        assert sp.converged
        assert sp.params["rho"] == pytest.approx(rho, rel=1e-11, abs=0)
        assert np.allclose(sp.state, closed_form(rho), rtol=1e-9)
    assert [sp.data["value"] for sp in uz] == [0.0, 25.0, 30.0]
    assert uz[0].index < uz[1].index < uz[2].index


def test_stop_at_uz_ends_the_run_after_the_kth_user_zero():
    br = trace(Lorenz(), start(), P0, "rho", options(user_zeros={"rho": (25, 30, 35)}, stop_at=("UZ2",)))
    assert br.status == "EP" and "UZ2" in br.message
    assert [sp.params["rho"] for sp in br.points("UZ")] == pytest.approx([25.0, 30.0], rel=1e-11)
    assert br.parameter_values[-1] < 35.0
    # HB (rho = 470/19) lies before the stop and is counted separately
    br = trace(Lorenz(), start(), P0, "rho", options(stop_at=("HB1",)))
    assert br.points("HB") and "HB1" in br.message and br.parameter_values[-1] < 30.0


def test_bad_user_zero_input_is_one_clear_error():
    with pytest.raises(ValueError, match="unknown parameter 'H'"):
        trace(Lorenz(), start(), P0, "rho", options(user_zeros={"H": [25]}))
    with pytest.raises(ValueError, match="finite"):
        options(user_zeros={"rho": [float("nan")]})
    with pytest.raises(ValueError, match="callable"):
        options(events={"g": 3.0})
    with pytest.raises(ValueError, match="UZ<k>"):
        options(stop_at=("UZ0",))


def test_hb_and_uz_columns_round_trip_through_hdf5_and_json(tmp_path):
    import json

    from contin import io
    from contin.jsonout import dumps, special_point_summary

    opts = options(user_zeros={"rho": [25]}, events={"x=4": lambda u, p: u[0] - 4.0})
    br = trace(Lorenz(), start(), P0, "rho", opts)
    path = io.write(tmp_path / "run.h5", [br], options=opts, scene="lorenz")
    (back,), meta = io.load(path)
    hb, uz = back.points("HB")[0], back.points("UZ")[0]
    assert hb.data == br.points("HB")[0].data and set(hb.data) == {"omega", "l1"}
    assert uz.data == {"value": 25.0}
    assert meta["options"]["events"] == ["x=4"] and meta["options"]["user_zeros"] == {"rho": [25.0]}
    doc = json.loads(dumps([special_point_summary(sp, br.id) for sp in br.special_points]))
    assert [d["data"] for d in doc if d["type"] == "HB"][0]["omega"] == pytest.approx(math.sqrt(1760 / 19), rel=1e-9)


def test_user_zero_value_is_exact_for_values_with_many_digits():
    target = 25.123456789012345
    br = trace(Lorenz(), start(), P0, "rho", options(user_zeros={"rho": [target]}))
    (uz,) = br.points("UZ")
    assert uz.data["value"] == target and uz.params["rho"] == pytest.approx(target, rel=1e-11)


def test_a_test_function_that_is_nan_at_one_point_is_a_detection_gap_not_a_lost_trace():
    """An event g that is NaN at one stored point: the trace ended in 'ValueError: event 'e' returned
    NaN at rho=12.7623' (everything traced was lost), and the detection, had it gone on, passed a
    NaN on to the locator (its sign comparison (nan > 0) == (g_b > 0) is False), unlike the
    retreat's _sign_changed, which refused it.  Now both use contin.testfunctions.sign_change: no
    special point is made up from the NaN, and the two steps next to it say that the event's test
    function was not finite there (Branch.audit, 'detection gap'; the command line shows it as a
    warning)."""
    def g(u, p):  # a sign change at rho = 12.5, NaN for 12 < rho < 13 (one stored point)
        return math.nan if 12 < p["rho"] < 13 else p["rho"] - 12.5

    br = trace(Lorenz(), start(), P0, "rho", options(events={"e": g}))
    assert br.status == "EP" and br.parameter_values[-1] == 40.0
    nan_at = [k for k, rho in enumerate(br.parameter_values) if 12 < rho < 13]
    assert len(nan_at) == 1
    assert not br.points("UZ")
    gaps = [line for line in br.audit if "detection gap" in line]
    assert len(gaps) == 2 and all(f"was not finite at point {nan_at[0]} (rho=" in line for line in gaps), gaps
    assert [sp.type for sp in br.special_points] == ["HB", "EP"]


def test_sign_change_is_the_one_comparison():
    from contin.continuation import _sign_changed
    from contin.testfunctions import sign_change

    nan, inf = math.nan, math.inf
    assert sign_change(1.0, -2.0) is True and sign_change(-1.0, -2.0) is False and sign_change(0.0, 1.0) is False
    assert sign_change((1.0, 3.0), (-1.0, -inf)) is True and sign_change((1.0, 3.0), (1.0, 2.0)) is False
    for bad in (nan, inf, None, (nan, 1.0), (1.0, nan)):
        assert sign_change(bad, 1.0) is None and sign_change(-1.0, bad) is None
        assert _sign_changed(bad, -1.0) is False


def test_a_stop_event_ends_the_run_after_its_zero():
    """trace(..., stop_events=(name,)): the run ends with EP right after the step in which that
    event's zero is located (the bounds of a two-parameter curve's second parameter use it),
    other events do not stop it."""
    from problems.demo import Lorenz as DemoLorenz  # with its closed-form equilibrium

    p = {"sigma": 10.0, "beta": 8 / 3, "rho": 10.0}
    events = {"x=5": lambda u, q: u[0] - 5.0, "x=7": lambda u, q: u[0] - 7.0}
    opts = ContinuationOptions(step=StepOptions(ds=0.5, ds_max=1.0), bounds={"rho": (1.5, 40.0)}, events=events)
    br = trace(DemoLorenz(), DemoLorenz.equilibrium(p), p, "rho", opts, stop_events=("x=7",))
    assert br.status == "EP" and br.message == "stopped at event x=7"
    assert [s.note for s in br.special_points if s.type == "UZ"] == ["x=5", "x=7"]
    # x = sqrt(beta (rho - 1)) = 7 at rho = 1 + 49 / beta; the run ends within one step beyond it
    assert br.points("UZ")[1].params["rho"] == pytest.approx(1 + 49 / (8 / 3), rel=1e-10)
    assert br.params["rho"][-1] - (1 + 49 / (8 / 3)) < 1.0 + 1e-9
    full = trace(DemoLorenz(), DemoLorenz.equilibrium(p), p, "rho", opts)
    assert full.params["rho"][-1] == 40.0
