"""Curves of folds of periodic orbits (LPC curves, ``contin.lpccurve``; AUTO-07p's ISW = 2 at an
LPC label, BifurcationKit's FoldPeriodicOrbitProblem).

References, independent of the collocation: the Bautin normal form's closed form (the fold of
cycles at mu = -b^2/4 with r^2 = b/2 and period 2 pi / w, ending at the Bautin point (0, 0)); for
AUTO's demo ab the generalized Hopf point of its Hopf curve (README: confirmed by a solve of the
GH's defining system) and a fold of cycles found by solve_ivp shooting as the extremum of D along
the family of orbits at fixed B.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from contin.continuation import trace
from contin.cycles import CycleOptions, continue_cycles, orbit_of
from contin.lpccurve import trace_lpc_curve
from contin.options import ContinuationOptions, StepOptions
from tests.cycle_models import Bautin

#: AUTO demo ab's generalized Hopf point in (D, B) (README, confirmed there by an independent
#: solve of the GH's defining system to 1e-8)
AB_GH = (0.2789854144, 11.0158490940)
AB_PARAMS = {"D": 0.0, "B": 14.0, "beta": 3.0}


def bautin_lpc(b=1.0, w=1.0):
    eq = trace(Bautin(), np.zeros(2), {"mu": -0.3, "b": b, "w": w}, "mu", ContinuationOptions(bounds={"mu": (-1, 1)}))
    hb = eq.points("HB")[0]
    br = continue_cycles(Bautin(), hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.3)}, max_steps=200))
    (lpc,) = br.points("LPC")
    return lpc


def test_bautin_lpc_curve_is_mu_equals_minus_b_squared_over_four():
    """r' = r (mu + b r^2 - r^4), theta' = w: the folds of cycles lie on mu = -b^2/4 with
    r^2 = b/2 and T = 2 pi / w, for b > 0; the curve ends at the Bautin point (0, 0), where the
    folding cycles shrink to the equilibrium (GH)."""
    w = 1.0
    lpc = bautin_lpc(w=w)
    curve = trace_lpc_curve(Bautin(), lpc, "b", 2, ContinuationOptions(bounds={"mu": (-1, 0.3), "b": (-1, 2)},
                                                                       max_steps=60), parameter="mu")
    assert curve.kind == "lpc-curve" and curve.free == ("mu", "b") and curve.status == "EP"
    mu, b = curve.params["mu"], curve.params["b"]
    inside = b > 1e-3  # away from the end, where the orbits are of finite amplitude
    assert inside.sum() > 15 and b.max() == pytest.approx(2.0)  # up to the bound b = 2
    # the curve holds mu = -b^2/4 to 1e-11 (the fold's parameters are superconvergent)
    np.testing.assert_allclose(mu[inside], -b[inside] ** 2 / 4, rtol=0, atol=1e-11)
    for i in np.flatnonzero(inside):
        _, nodes, period = orbit_of(curve.state(i), 2)
        # the collocation error of the circle: 7e-9 relative at the interior nodes (O(h^5)), to
        # 3e-11 at the mesh points (superconvergent)
        r2 = nodes[:, 0] ** 2 + nodes[:, 1] ** 2
        np.testing.assert_allclose(r2, b[i] / 2, rtol=2e-8)
        np.testing.assert_allclose(r2[::4], b[i] / 2, rtol=1e-9)
        assert math.isclose(period, 2 * math.pi / w, rel_tol=1e-10)
    # the fold's multiplier +1 (a double one with the trivial multiplier): the others hold it
    assert np.nanmax(np.abs(curve.eigenvalues[inside, 0] - 1)) < 1e-6
    # the end at the Bautin point (0, 0): the curve passes amplitude 0 next to it (b -> 0), and the
    # GH solved on the Hopf curve through that end is (0, 0) to its solve (measured 3e-9 in b)
    j = int(np.argmin(curve.order_parameter))
    assert abs(mu[j]) < 1e-6 and abs(b[j]) < 1e-3
    (gh,) = curve.points("GH")
    assert gh.converged and abs(gh.params["mu"]) < 1e-10 and abs(gh.params["b"]) < 1e-7
    assert [s.type for s in curve.special_points] == ["EP", "GH", "EP"]  # no LP of mu next to the GH
    assert math.isclose(gh.data["period"], 2 * math.pi / w, rel_tol=1e-10)
    assert gh.index in (0, len(curve) - 1) or curve.points("EP")
    assert np.all(b > -1e-3)  # it does not come back over the same folds half a period shifted


def ab_lpc():
    """LPC1 of demo ab's cycles from HB1 (B = 14), as `contin trace ab` then `--cycles` finds it."""
    from problems.demo import AB

    opts = ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=2000, step=StepOptions(ds=0.01, ds_max=0.05))
    hb = trace(AB(), np.zeros(2), AB_PARAMS, "D", opts).points("HB")[0]
    br = continue_cycles(AB(), hb, "D", ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=40))
    return br.points("LPC")[0]


def shooting_fold(problem, params, u_top, period, d_guess):
    """The fold of cycles of ``problem`` at fixed B by solve_ivp shooting.  The orbits are labelled
    by c, the largest u1 on the orbit: unknowns (u2(0), T, D) with u1(0) = c, solving periodicity
    and u1'(0) = 0 (a regular system while c grows along the family); the fold is where D(c) is
    extremal.  ``u_top``: a guess of the point of largest u1.  Returns (D at the fold, its period)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import fsolve, minimize_scalar

    state = {"guess": np.array([u_top[1], period, d_guess])}

    def orbit(c):
        def g(v):
            y0, t_end, d = v
            q = {**params, "D": d}
            run = solve_ivp(lambda t, u: problem.residual(u, q), (0, t_end), [c, y0], method="DOP853", rtol=1e-12,
                            atol=1e-13)
            end = run.y[:, -1]
            return [end[0] - c, end[1] - y0, problem.residual(np.array([c, y0]), q)[0]]

        sol, _, ok, msg = fsolve(g, state["guess"], xtol=1e-13, full_output=True)
        assert ok == 1, msg
        state["guess"] = sol
        return sol

    c0 = u_top[0]
    res = minimize_scalar(lambda c: orbit(c)[2], bracket=(c0 - 0.01, c0, c0 + 0.01), tol=1e-8)
    sol = orbit(res.x)
    return float(sol[2]), float(sol[1])


def test_ab_lpc_curve_ends_at_the_generalized_hopf_point_and_matches_shooting():
    """Demo ab: the LPC curve from LPC1 (B = 14) in (D, B) ends where its cycles shrink to the
    equilibrium, at the GH point of the Hopf curve; an interior fold agrees with a solve_ivp
    shooting fold (the extremum of D along the family at the same B)."""
    from problems.demo import AB

    lpc = ab_lpc()
    curve = trace_lpc_curve(AB(), lpc, "B", 2, ContinuationOptions(bounds={"D": (0.0, 0.5)}, max_steps=100),
                            CycleOptions(ntst=40), parameter="D")
    d, b, amp = curve.params["D"], curve.params["B"], curve.order_parameter
    # the curve approaches the GH: amplitude -> 0 (< 2 % of the largest) at its end.  The distance of
    # its smallest orbit from the GH is the collocation error of the fold (plus O(amplitude^2) along
    # the curve): measured (1.1e-7, 1.3e-6) in (D, B) on NTST = 40, and (2.5e-6, 3e-5) on NTST = 20,
    # i.e. ~h^4..h^5: the bounds below are 10x the NTST = 40 error and fail on NTST = 20.
    j = int(np.argmin(amp))
    assert j >= len(curve) - 2 and amp[j] < 0.02 * amp.max()
    assert abs(d[j] - AB_GH[0]) < 1e-6 and abs(b[j] - AB_GH[1]) < 1e-5
    # the GH end, solved on the Hopf curve through it (l1 = 0): the README's GH (which an
    # independent solve of the GH's defining system confirms to 1e-8); measured (1.5e-9, 1.8e-8) here,
    # (4e-8, 5e-7) from the CLI's start orbit: the GH's position on the Hopf curve is uncertain to
    # ~3e-8 in D (its finite-difference l1; reported as position_error), x12 in B (the curve's slope)
    (gh,) = curve.points("GH")
    assert gh.converged and gh.index >= len(curve) - 2
    assert abs(gh.params["D"] - AB_GH[0]) < 1e-7 and abs(gh.params["B"] - AB_GH[1]) < 1e-6
    assert curve.special_points[-1].type == "EP" and "generalized Hopf" in curve.message
    # B falls from 14 to the GH along the curve; the start is on it
    assert b.min() == pytest.approx(gh.params["B"]) and b.max() > 14.0
    # an interior point against shooting (the fold value of D is insensitive to the location of the
    # extremum in c: the shooting's own error, rtol 1e-12, dominates; measured difference 1.6e-13)
    i = int(np.argmin(np.abs(b - 12.5)))
    _, nodes, period = orbit_of(curve.state(i), 2, None, 4)
    top = nodes[int(np.argmax(nodes[:, 0]))]
    d_fold, t_fold = shooting_fold(AB(), {**AB_PARAMS, "B": float(b[i])}, top, period, float(d[i]))
    assert abs(d[i] - d_fold) < 1e-10
    assert math.isclose(period, t_fold, rel_tol=1e-7)
    # the Floquet check: a nontrivial multiplier at +1 (the fold), to the square root of the error
    assert abs(curve.eigenvalues[i, 0] - 1) < 1e-3


def _cli(*args):
    from click.testing import CliRunner

    from contin.cli import main

    return CliRunner().invoke(main, [str(a) for a in args])


def test_cli_lpc_curve_end_to_end(tmp_path):
    """trace ab -> continue --cycles -> continue --from LPC1 --free B -> info / diagram."""
    from contin import io

    ab, orbits, out = tmp_path / "ab.h5", tmp_path / "abc.h5", tmp_path / "lpc.h5"
    assert _cli("trace", "ab", "-q", "-o", ab).exit_code == 0
    r = _cli("continue", ab, "--from", "HB1", "--cycles", "--max-steps", "40", "-o", orbits)
    assert r.exit_code == 0, r.output
    r = _cli("continue", orbits, "--from", "LPC1", "--free", "B", "--ntst", "20", "--bounds", "B=0:14.5", "-o", out)
    assert r.exit_code == 0, r.output  # both halves end (EP): the bound B = 14.5, the GH point
    assert "LPC curve from LPC1" in r.output and "GH" in r.output
    (curve,), meta = io.load(str(out))
    assert curve.kind == "lpc-curve" and curve.free == ("D", "B") and curve.status == "EP"
    assert curve.params["B"].max() == pytest.approx(14.5)
    (gh,) = curve.points("GH")
    assert gh.converged and abs(gh.params["D"] - AB_GH[0]) < 1e-7 and abs(gh.params["B"] - AB_GH[1]) < 1e-6
    _, nodes, period = orbit_of(curve.state(0), 2, 20, 4)  # the orbits are stored
    assert meta["extra"]["cycles"]["ntst"] == 20 and period > 0
    r = _cli("info", out)
    assert r.exit_code == 0 and "lpc-curve" in r.output and "GH" in r.output
    assert "Floquet multipliers of branch lpc" in r.output and "kx=" not in r.output
    r = _cli("profiles", out, "--point", curve.special_points[0].name, "-o", tmp_path / "orbit.png")
    assert r.exit_code == 0 and (tmp_path / "orbit.png").stat().st_size > 1000, r.output
    r = _cli("profiles", out, "--at", "D=0.2", "-o", tmp_path / "x.png")  # two parameters vary: refused
    assert r.exit_code == 1 and "holds an LPC curve" in r.output.strip().splitlines()[-1]
    r = _cli("export", out, "--auto", "lpc")  # not as a 180-dimensional IPS = 1 state
    assert r.exit_code == 1 and "is an LPC curve" in r.output.strip().splitlines()[-1]
    r = _cli("diagram", out, "-x", "D", "-y", "B", "-o", tmp_path / "lpc.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "lpc.png").stat().st_size > 0
    # bad input: one Error line
    r = _cli("continue", orbits, "--from", "LPC1", "--free", "nope")
    assert r.exit_code != 0 and r.output.strip().splitlines()[-1].startswith("Error:")
    r = _cli("continue", ab, "--from", "HB1", "--free", "B", "--ntst", "40")
    assert r.exit_code != 0 and "Error:" in r.output


def test_ctrl_c_keeps_the_lpc_curve_computed_so_far(tmp_path):
    """The first Ctrl-C ends the LPC curve at its last point: the file holds it, marked incomplete
    ('interrupted'), then one Error line and exit 130 (as for the other `continue` curves)."""
    import os
    import signal

    from contin import io
    from tests.signals import signalled

    ab, orbits, out = tmp_path / "ab.h5", tmp_path / "abc.h5", tmp_path / "lpc.h5"
    assert _cli("trace", "ab", "-q", "-o", ab).exit_code == 0
    assert _cli("continue", ab, "--from", "HB1", "--cycles", "--max-steps", "40", "-o", orbits).exit_code == 0
    code, stderr = signalled(["continue", str(orbits), "--from", "LPC1", "--free", "B", "--ds", "1e-4", "--ds-max",
                              "1e-4", "--max-steps", "100000", "-o", str(out)], signal.SIGINT,
                             lambda: (tmp_path / ".lpc.h5.lock").exists(), env=os.environ,
                             what="the output lock (computing starts)", after=2.0)
    errors = [line for line in stderr.splitlines() if line.startswith("Error:")]
    assert code == 130 and errors == ["Error: interrupted (Ctrl-C)"], stderr
    assert f"is saved in {out}" in stderr
    (curve,), meta = io.load(out)
    assert meta["complete"] is False and meta["stopped"] == "interrupted"
    assert curve.kind == "lpc-curve" and len(curve) > 3 and "interrupted" in curve.message
