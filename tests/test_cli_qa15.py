"""Robustness sweep, round 3 (session 15, qa15): the leftovers of qa14 (absurdly small ranges,
--kx on scenes with no wavenumber, a user zero next to a fold, a parameter that overflows, NaN test
functions) and areas the earlier sweeps did not touch.

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from click.testing import CliRunner

from contin.cli import main


from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)


@pytest.mark.parametrize("scene, floor", [("pitchfork", "2e-06"), ("jj-walls", "4e-06")])
def test_an_absurdly_small_h_max_is_a_range_error(scene, floor, tmp_path):
    """`contin trace pitchfork -s H_max=1e-6` ended with `Error: need ds_max >= |ds| >= ds_min > 0,
    got ds_max=2e-07, ds=5e-08, ds_min=1e-07` (the step control's check, not the parameter's)."""
    res = run(["trace", scene, "-s", "H_max=1e-6", "--no-stability", "--max-steps", "5", "-q",
               "-o", str(tmp_path / "x.h5")])
    err = one_error(res)
    assert res.exit_code == 1 and err.startswith("Error: parameter H_max = 1e-06 is out of range"), err
    assert f"needs H_max >= {floor}" in err and "ds_max >=" not in err, err
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize("scene", ["lorenz", "brusselator"])
def test_kx_on_a_scene_with_no_wavenumber_says_so_and_keeps_the_k0_stability(scene, tmp_path):
    """`contin trace lorenz --kx 1` printed 'warning: stability of branch 0 failed: this problem has
    no eigenproblem...' and then '--kx 1 ignored: scene 'lorenz' computed no stability' although
    its k_x = 0 pass ran (the kx loop raised after it, dropping the pass's audit)."""
    import h5py

    out = tmp_path / "k.h5"
    res = run(["trace", scene, "--kx", "1", "--max-steps", "5", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    assert "failed" not in res.stderr and "computed no stability" not in res.stderr, res.stderr
    assert (f"warning: --kx 1 ignored: scene '{scene}' has no wavenumber: its problem has no "
            "eigenproblem(u, p, kx, kz), so only k_x = 0 exists") in res.stderr, res.stderr
    with h5py.File(out, "r") as f:
        assert "n_unstable" in f["branches/0"], list(f["branches/0"])


def test_kx_on_a_scene_without_problem_factory_names_the_reason(tmp_path):
    res = run(["trace", "bratu", "--kx", "1", "--max-steps", "5", "-q", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 0, res.stderr
    assert "scene 'bratu' computed no stability (it has no problem_factory" in res.stderr, res.stderr


def test_a_user_zero_next_to_bratus_fold_is_reported_on_both_sides(tmp_path):
    """`contin trace bratu --uz lam=3.5138307` (2e-8 below lam* = 3.5138307191) reported no UZ,
    exit 0: the step that turns at the fold crosses the value twice (lam - value has one sign at
    both ends)."""
    res = run(["trace", "bratu", "--uz", "lam=3.5138307", "--max-steps", "40", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 0, res.stderr
    rows = [ln.split() for ln in res.stderr.splitlines() if ln.startswith("0 ") and " UZ " in ln]
    assert [r[3] for r in rows] == ["lam=3.5138307", "lam=3.5138307"] and all(r[5] == "yes" for r in rows), res.stderr
    order = [ln.split()[2] for ln in res.stderr.splitlines() if ln.startswith("0 ") and ln.split()[2] in ("UZ", "LP")]
    assert order == ["UZ", "LP", "UZ"], res.stderr


def test_detection_gap_lines_are_warnings():
    from types import SimpleNamespace

    from contin.cli.trace import doubtful_points

    b = SimpleNamespace(audit=["step to point 4: rho=12.7 detection gap: the UZ event:e test function was not finite",
                               "step 3: rho=1 ds=0.1 rejected: no convergence"])
    assert doubtful_points(b) == [b.audit[0]]


@pytest.mark.parametrize("a", ["0.5", "3"])
def test_stretched_bratu_at_a_nonzero_finds_its_fold(a, tmp_path):
    """`contin trace stretched-bratu -s a=0.5` ended with MX at lam = 2.4e-5, exit 3 (any a != 0):
    StretchedBratu inherited Bratu's reflection x -> 1 - x, which is a symmetry only at a = 0, so
    the tracer symmetrized the Newton iterates of the branch from u = 0 and no step converged."""
    from problems.demo import BRATU_FOLD

    res = run(["trace", "stretched-bratu", "-s", f"a={a}", "--no-stability", "--max-steps", "80",
               "-o", str(tmp_path / "s.h5")])
    assert res.exit_code == 0, res.stderr
    (note,) = [ln for ln in res.stderr.splitlines() if ln.startswith("note: LP1: lam = ")]
    lam = float(note.split()[4])
    assert lam == pytest.approx(BRATU_FOLD / (1 + float(a)), abs=1e-10), note


@pytest.mark.parametrize("a", ["1e6", "351", "-1"])
def test_stretched_bratu_a_out_of_range_is_a_range_error(a, tmp_path):
    """`contin trace stretched-bratu -s a=1e6` printed 'Error: the residual cannot be evaluated at the
    start point (OverflowError: math range error)...'; now the range of a and why, before any computation."""
    res = run(["trace", "stretched-bratu", "-s", f"a={a}", "--no-stability", "-q", "-o", str(tmp_path / "s.h5")])
    err = one_error(res)
    assert res.exit_code == 1 and err.startswith(f"Error: parameter a = {float(a):g} is out of range: it must be > -1"), err
    assert "<= 350" in err and "overflows double precision beyond a = 354" in err and "Overflow" not in err, err
    assert not (tmp_path / "s.h5").exists()


def test_stretched_bratu_a_60_refines_past_a_saturated_estimate(tmp_path):
    """`contin trace stretched-bratu -s a=60` (after the symmetry fix) ended with MX 'under-resolved at
    lam = 0: estimated relative error 1 > tol 1e-10 does not fall with refinement (1 on grid 12, 1 on
    grid 12)': an estimate of 1 resolves nothing yet and is no floor (contin.adapt.SATURATED_ESTIMATE)."""
    from problems.demo import BRATU_FOLD

    res = run(["trace", "stretched-bratu", "-s", "a=60", "--no-stability", "--stop-at", "LP1", "-o", str(tmp_path / "s.h5")])
    assert res.exit_code == 0 and "does not fall" not in res.stderr, res.stderr
    (note,) = [ln for ln in res.stderr.splitlines() if ln.startswith("note: LP1: lam = ")]
    assert float(note.split()[4]) == pytest.approx(BRATU_FOLD / 61, abs=1e-12), note


def test_stretched_bratu_problem_refuses_a_out_of_range():
    from problems.demo import StretchedBratu

    from contin.continuation import trace

    pb = StretchedBratu("cheb", 24)
    with pytest.raises(ValueError, match="a = 400 is out of range"):
        trace(pb, pb.initial(), {"lam": 0.0, "a": 400.0}, "lam")


def test_sweep_with_a_boolean_for_a_number_is_a_failed_task_not_ok(tmp_path):
    """A sweep file's `lam_min = [true]` ran bratu at lam_min = 1.0 and reported the task 'ok'."""
    toml = tmp_path / "b.toml"
    toml.write_text('[sweep]\nscene = "bratu"\n[grid]\nlam_min = [true]\n[options]\ngrid = 16\nstability = false\n')
    res = run(["sweep", str(toml), "-o", str(tmp_path / "out"), "-j", "1"])
    assert res.exit_code == 3, res.stderr
    assert "error: parameter lam_min of scene 'bratu' must be a number, got the boolean True" in res.stderr, res.stderr


def test_accuracy_with_a_repeated_method_or_grid_measures_each_once():
    """`contin accuracy bratu --methods cheb,cheb --grids 16,24` ran each grid twice and its budget
    table said 'not reached' for every budget (cheb 16 meets 1e-8), exit 0."""
    import json

    base = ["accuracy", "bratu", "--grids", "16,24", "--no-memory", "--no-plots", "--json", "-q"]
    once = json.loads(run([*base, "--methods", "cheb"]).stdout)
    twice = run([*base, "--methods", "cheb,cheb", "--grids", "16,24,16"])
    assert twice.exit_code == 0, twice.stderr
    doc = json.loads(twice.stdout)
    assert [(r["method"], r["grid"]) for r in doc["rows"]] == [("cheb", 16), ("cheb", 24)]
    assert [(r["target"], r["method"], r["grid"]) for r in doc["recommendations"]] == \
        [(r["target"], r["method"], r["grid"]) for r in once["recommendations"]]
    assert doc["recommendations"][0]["grid"] == 16


def test_ds_max_alone_below_the_first_step_caps_it(tmp_path):
    """`contin trace bratu --ds-max 0.01` and `contin continue F --from LP1 --free a --ds-max 0.01`
    ended with 'Error: need ds_max >= |ds| >= ds_min > 0, got ds_max=0.01, ds=0.05, ds_min=1e-08'
    (the scene's first step 0.05 was kept above the cap)."""
    from contin import io

    out = tmp_path / "b.h5"
    res = run(["trace", "bratu", "--ds-max", "0.01", "--max-steps", "5", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (b,), _ = io.load(out)
    assert len(b) == 6 and float(np.max(b.ds)) <= 0.01 * (1 + 1e-6)  # the stored chord length
    sb = tmp_path / "sb.h5"
    assert run(["trace", "stretched-bratu", "--grid", "24", "--stop-at", "LP1", "--no-stability", "-q",
                "-o", str(sb)]).exit_code == 0
    res = run(["continue", str(sb), "--from", "LP1", "--free", "a", "--ds-max", "0.01", "--max-steps", "5",
               "-o", str(tmp_path / "c.h5")])
    assert res.exit_code == 0, res.stderr
    err = one_error(run(["trace", "bratu", "--ds", "1", "--ds-max", "0.5", "-q", "-o", str(tmp_path / "x.h5")]))
    assert err == "Error: --ds (1) must not exceed --ds-max (0.5)", err


def test_max_grid_below_the_smallest_adaptive_grid_is_refused_by_the_option(tmp_path):
    """`contin trace bratu --tol 1e-6 --max-grid 4` ended with 'Error: need 1 <= min_grid <= max_grid,
    got min_grid=8, max_grid=4' (AdaptOptions' field check, naming a setting the user never gave)."""
    from contin.options import AdaptOptions

    res = run(["trace", "bratu", "--tol", "1e-6", "--max-grid", "4", "-q", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 2 and "min_grid" not in res.stderr, res.stderr
    assert f"'--max-grid': 4 is not in the range x>={AdaptOptions().min_grid}" in res.stderr, res.stderr


@pytest.fixture(scope="module")
def allen_cahn_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("ac") / "ac.h5"
    res = CliRunner().invoke(main, ["trace", "allen-cahn", "--max-steps", "20", "-q", "-o", str(path)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    return path


def _damaged(src, tmp_path, change):
    import shutil

    import h5py

    path = tmp_path / "damaged.h5"
    shutil.copy(src, path)
    with h5py.File(path, "r+") as f:
        change(f)
    return str(path)


def _replace(f, name, fn):
    data = fn(f[name][()])
    del f[name]
    f[name] = data


@pytest.mark.parametrize("change, expect", [
    # `contin profiles` ended with numpy's "setting an array element with a sequence. The requested
    # array has an inhomogeneous shape after 1 dimensions..." (info, diagram, verify said nothing)
    (lambda f: _replace(f, "branches/0/profiles/u", lambda d: d[:, :5]),
     "dataset branches/0/profiles/u has 5 columns, grid/y (the profiles' abscissa) has 33 nodes"),
    (lambda f: _replace(f, "grid/y", lambda d: d[:5]),
     "dataset branches/0/profiles/u has 33 columns, grid/y (the profiles' abscissa) has 5 nodes"),
    # `contin info` ended with "Error: foo" (a KeyError); diagram, profiles and verify exit 0
    (lambda f: f["branches/0"].attrs.__setitem__("parameter", "foo"),
     "branch group branches/0 names the free parameter 'foo' (attributes parameter/free) but holds no such column"),
])
@pytest.mark.parametrize("command", [["info"], ["diagram", "-o", "{dir}/d.png"], ["profiles", "--at", "lam=1.5", "-o", "{dir}/p.png"],
                                     ["verify", "--branch", "0"]])
def test_damaged_profile_widths_and_parameter_names_are_one_error_line(allen_cahn_file, tmp_path, change, expect, command):
    path = _damaged(allen_cahn_file, tmp_path, change)
    args = [command[0], path, *[a.format(dir=tmp_path) for a in command[1:]]]
    err = one_error(run(args))
    assert err.startswith(f"Error: {path!r} is damaged: {expect}"), err


def test_diagram_of_a_column_with_no_finite_value_says_so(allen_cahn_file, tmp_path):
    """`contin diagram F --branch 0` of a branch whose phi is NaN everywhere (the file check allows an
    observable NaN everywhere) wrote an empty figure, exit 0."""
    import numpy as np

    def nan_phi(f):
        f["branches/0/phi"][...] = np.nan

    path = _damaged(allen_cahn_file, tmp_path, nan_phi)
    err = one_error(run(["diagram", path, "--branch", "0", "-o", str(tmp_path / "d.png")]))
    assert err == f"Error: nothing to draw: no branch of {path} has a point with finite lam and phi", err
    assert not (tmp_path / "d.png").exists()
    res = run(["diagram", path, "-o", str(tmp_path / "all.png")])
    assert res.exit_code == 0 and "warning: branch 0 has no point with finite lam and phi; it is not drawn" in res.stderr


@pytest.mark.parametrize("make, expect", [
    # trace hung: ds = inf halved an infinite step forever (the CLI checked --ds, the library did not)
    (lambda o: o.StepOptions(ds=math.inf, ds_max=math.inf), "StepOptions.ds must be finite"),
    # every step failed with "residual is not finite at the predicted point" and RuntimeWarnings
    (lambda o: o.StepOptions(theta=0.0), "StepOptions.theta"),
    (lambda o: o.StepOptions(theta=math.nan), "StepOptions.theta"),
    # the step never grew (no LP in 60 steps, exit EP) or could not shrink
    (lambda o: o.StepOptions(grow=0.5), "StepOptions.grow must be a finite number >= 1"),
    (lambda o: o.StepOptions(shrink=0.0), "StepOptions.shrink must lie in (0, 1)"),
    (lambda o: o.StepOptions(newton_target=0), "StepOptions.newton_target must be >= 1"),
    # tol = inf accepted; step_tol NaN / -1 failed every step as "no convergence in 12 iterations"
    (lambda o: o.NewtonOptions(tol=math.inf), "NewtonOptions.tol must be a finite number > 0"),
    (lambda o: o.NewtonOptions(step_tol=math.nan), "NewtonOptions.step_tol must be a finite number > 0"),
    (lambda o: o.NewtonOptions(step_tol=-1.0), "NewtonOptions.step_tol must be a finite number > 0"),
    # locate_tol = inf located bratu's LP 1.2e-10 off, NaN / -1 were accepted; max_bisections 0 ran
    (lambda o: o.DetectionOptions(locate_tol=math.inf), "DetectionOptions.locate_tol must be a finite number > 0"),
    (lambda o: o.DetectionOptions(locate_tol=-1.0), "DetectionOptions.locate_tol must be a finite number > 0"),
    (lambda o: o.DetectionOptions(max_bisections=0), "DetectionOptions.max_bisections must be >= 1"),
    (lambda o: o.ContinuationOptions(save_every=0), "save_every must be >= 1"),
    (lambda o: o.ContinuationOptions(resolution_tol=math.inf), "resolution_tol must be > 0 and finite"),
])
def test_api_options_that_cannot_work_are_refused_by_name(make, expect):
    import contin.options as o

    with pytest.raises(ValueError, match=re.escape(expect)):
        make(o)


def test_profiles_at_without_a_value_names_its_own_option(allen_cahn_file, tmp_path):
    """`contin profiles F --at lam=` said "Invalid value for '-s': expected name=value" (profiles has no -s)."""
    res = run(["profiles", str(allen_cahn_file), "--at", "lam=", "-o", str(tmp_path / "p.png")])
    assert res.exit_code == 2 and "Invalid value for '--at': expected name=value, got 'lam='" in res.stderr, res.stderr


def test_io_restart_with_a_non_string_label_is_a_type_error_naming_it(allen_cahn_file):
    """`contin.io.restart(f, 5)` ended with "AttributeError: 'int' object has no attribute 'strip'"."""
    from contin import io

    with pytest.raises(TypeError, match=r"label must be a special-point label such as 'LP1' or 'BP2', got 5 \(int\)"):
        io.restart(allen_cahn_file, 5)
    assert io.restart(allen_cahn_file, "bp1").point.name == "BP1"


def test_sweep_resume_recomputes_a_damaged_or_stopped_task_file(tmp_path):
    """`contin sweep s.toml -o out` after a task file lost its branch 0 (or carries stopped =
    'interrupted') reused both as 'ok' from their sweep_task attribute: the summary claimed an LP
    the damaged file no longer holds (every other command refuses that file)."""
    import glob
    import json

    import h5py

    toml = tmp_path / "s.toml"
    toml.write_text('[sweep]\nscene = "bratu"\nrecord = ["LP", "EP"]\n[grid]\nlam_min = [0.0, 1.0]\n'
                    '[options]\ngrid = 16\nstability = false\n')
    out = tmp_path / "out"
    assert run(["sweep", str(toml), "-o", str(out), "-j", "1", "-q"]).exit_code == 0
    damaged, stopped = sorted(glob.glob(str(out / "tasks" / "*.h5")))
    with h5py.File(damaged, "r+") as f:
        del f["branches/0"]
    with h5py.File(stopped, "r+") as f:
        f.attrs["stopped"] = "interrupted"
    res = run(["sweep", str(toml), "-o", str(out), "-j", "1"])
    assert res.exit_code == 0, res.stderr
    assert "0 from earlier runs" in res.stderr, res.stderr  # (the reason is a logged warning per file)
    doc = json.loads((out / "summary.json").read_text())
    assert [t["cached"] for t in doc["tasks"]] == [False, False]
    from contin import io

    for path in (damaged, stopped):
        branches, _ = io.load(path)
        assert [sp.type for sp in branches[0].special_points][:1] == ["LP"]


def test_continue_from_a_hopf_point_outside_the_bounds_of_the_second_parameter_is_refused(tmp_path):
    """`contin continue lz.h5 --from HB2 --free sigma --bounds sigma=20:30` from sigma = 10 stored a
    Hopf curve with sigma from 5 to 20 ("reached bound sigma=20"), exit 0: points outside the bounds
    asked for.  Fold curves checked the start against the bounds, Hopf (and BP) curves did not;
    contin.twoparam.continue_point now checks both parameters for every curve kind."""
    lz = tmp_path / "lz.h5"
    assert run(["trace", "lorenz", "-q", "-o", str(lz)]).exit_code == 0
    out = tmp_path / "c.h5"
    err = one_error(run(["continue", str(lz), "--from", "HB2", "--free", "sigma", "--bounds", "sigma=20:30",
                         "-o", str(out)]))
    assert err == "Error: start value sigma=10 of HB2 lies outside its bounds (20, 30)", err
    assert not out.exists()
    res = run(["continue", str(lz), "--from", "HB2", "--free", "sigma", "--bounds", "sigma=5:30", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    from contin import io

    (curve,), _ = io.load(out)
    assert 5 - 1e-9 <= curve.params["sigma"].min() and curve.params["sigma"].max() <= 30 + 1e-9


def test_a_curve_that_starts_on_a_bound_stays_inside_it(tmp_path):
    """A two-parameter curve whose start lies on a bound of the second parameter: the half that leaves
    through that bound was never cut (the bound event min(p2 - lo, hi - p2) is 0 at the start, so no
    sign change), exit 0 with points outside the bounds asked for:
    `contin continue lz.h5 --from HB2 --free sigma --bounds sigma=10:30` stored sigma down to 5, and
    `contin continue sb.h5 --from LP1 --free a --bounds a=0:2` (LP1 at a = 0) stored a down to -0.12."""
    from contin import io

    lz, sb = tmp_path / "lz.h5", tmp_path / "sb.h5"
    assert run(["trace", "lorenz", "-q", "-o", str(lz)]).exit_code == 0
    assert run(["trace", "stretched-bratu", "--grid", "24", "--stop-at", "LP1", "--no-stability", "-q",
                "-o", str(sb)]).exit_code == 0
    for src, label, name, lo, hi in ((lz, "HB2", "sigma", 10.0, 30.0), (sb, "LP1", "a", 0.0, 2.0)):
        out = tmp_path / f"{label}.h5"
        res = run(["continue", str(src), "--from", label, "--free", name, "--bounds", f"{name}={lo:g}:{hi:g}",
                   "--max-steps", "40", "-o", str(out)])
        assert res.exit_code == 0, res.stderr
        (curve,), _ = io.load(out)
        values = curve.params[name]
        assert lo - 1e-9 <= values.min() and values.max() <= hi + 1e-9, (label, values.min(), values.max())
        assert f"reached bound {name}={lo:g}" in curve.message, curve.message


def test_a_bp_curve_that_starts_on_one_bound_lands_on_the_other(tmp_path):
    """`contin continue pf.h5 --from BP1 --free nu --bounds nu=0.3:0.31` (BP1 at nu = 0.3) stored a BP
    curve with nu from 0.2165 to 0.3166, exit 0: the bound event min(nu - lo, hi - nu) is 0 at the
    start, so the first step across nu = 0.31 showed no sign change.  One event per bound now."""
    import shutil
    from pathlib import Path

    from contin import io

    pf = tmp_path / "pf.h5"
    shutil.copy(Path(__file__).resolve().parents[1] / "results" / "pitchfork.h5", pf)
    out = tmp_path / "c.h5"
    res = run(["continue", str(pf), "--from", "BP1", "--free", "nu", "--bounds", "nu=0.3:0.31", "--max-steps", "3",
               "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (curve,), _ = io.load(out)
    nu = curve.params["nu"]
    assert 0.3 - 1e-12 <= nu.min() and nu.max() <= 0.31 + 1e-12, nu
    assert "reached bound nu=0.31" in curve.message and "reached bound nu=0.3" in curve.message, curve.message


def test_kx_with_no_stability_is_a_contradiction_not_a_silent_drop(tmp_path):
    """`contin trace allen-cahn --kx 1 --no-stability` dropped --kx silently, exit 0 (the warning for
    an ignored --kx skipped --no-stability runs); a sweep's kx with stability = false likewise."""
    err = one_error(run(["trace", "allen-cahn", "--kx", "1", "--no-stability", "-q", "-o", str(tmp_path / "a.h5")]))
    assert err == ("Error: --kx 1 asks for stability columns but --no-stability switches the stability pass off; "
                   "drop one of them"), err
    assert not (tmp_path / "a.h5").exists()
    toml = tmp_path / "k.toml"
    toml.write_text('[sweep]\nscene = "allen-cahn"\n[grid]\nlam_max = [3.0]\n[options]\nstability = false\nkx = [1.0]\n')
    err = one_error(run(["sweep", str(toml), "-o", str(tmp_path / "out")]))
    assert "option 'kx' in" in err and "'stability = false' switches the stability pass off" in err, err


@pytest.mark.parametrize("bad", [0.0, math.nan])
def test_trace_with_a_zero_or_nan_tangent_is_refused(bad):
    """trace(..., tangent=zeros) or a NaN tangent failed every step ('residual is not finite at the
    predicted point', MX) with a RuntimeWarning 'invalid value encountered in divide'."""
    from contin.continuation import trace
    from problems.demo import Bratu

    pb = Bratu("cheb", 16)
    with pytest.raises(ValueError, match="tangent must be finite and nonzero"):
        trace(pb, pb.initial(), {"lam": 0.0}, "lam", tangent=np.full(pb.n + 1, bad))


def test_switch_at_a_bp_without_a_usable_state_is_one_sentence():
    """switch() at a BP whose state is missing, NaN, or does not fit its tangent ended in numpy's
    'matmul: dimension mismatch with signature ...' / 'operands could not be broadcast together ...'
    or, for NaN, tried both directions first."""
    import dataclasses

    from contin.branch import relabel
    from contin.continuation import switch, trace
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import AllenCahn

    pb = AllenCahn("cheb", 24)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.3), bounds={"lam": (0, 10)}, max_steps=40)
    trivial = trace(pb, pb.initial(), {"lam": 0.5}, "lam", opts, kind="trivial")
    relabel([trivial])
    bp = trivial.branch_points[0]
    for state, expect in ((None, "needs its located state, and it has none"),
                          (bp.state * np.nan, "needs its located state, and it has non-finite entries"),
                          (bp.state[:-2], "its state (23 entries) and tangent (26) do not fit together")):
        with pytest.raises(ValueError, match=re.escape(expect)):
            switch(pb, trivial, dataclasses.replace(bp, state=state), opts)
    assert len(switch(pb, trivial, bp, opts)) == 2


@pytest.mark.parametrize("kw, expect", [
    ({"max_branches": 0}, "max_branches must be >= 1"),
    ({"tol": math.inf}, "tol must be a finite number > 0"),  # every branch a duplicate of the first
    ({"fraction": 0.0}, "fraction must lie in (0, 1]"),
    ({"fraction": 2.0}, "fraction must lie in (0, 1]"),
    ({"excursion": -1.0}, "excursion must be > 0"),
])
def test_diagram_settings_that_cannot_work_are_refused(kw, expect):
    """DiagramSettings(tol=inf) or fraction=0 made bifurcation_diagram drop every switched branch as a
    duplicate of the first (1 branch of allen-cahn's 5, silently); max_branches 0, fraction 2 or NaN,
    excursion -1 or NaN and depth 2.5 were accepted."""
    from contin.diagram import DiagramSettings

    with pytest.raises(ValueError, match=re.escape(expect)):
        DiagramSettings(**kw)
    with pytest.raises(TypeError, match="DiagramSettings.depth must be a whole number"):
        DiagramSettings(depth=2.5)


def test_adapt_options_refuse_an_infinite_growth_and_a_grid_beyond_the_limit():
    """AdaptOptions(growth=inf) and AdaptOptions(max_grid=10**9) were accepted (the command line caps
    grids at contin.limits.MAX_GRID: a grid of 1e9 intervals ate 330 MB/s)."""
    from contin.limits import MAX_GRID
    from contin.options import AdaptOptions

    with pytest.raises(ValueError, match="growth must be a finite number > 1"):
        AdaptOptions(growth=math.inf)
    with pytest.raises(ValueError, match=f"AdaptOptions.max_grid must be at most {MAX_GRID}"):
        AdaptOptions(max_grid=10**9)
    assert AdaptOptions(max_grid=MAX_GRID).max_grid == MAX_GRID


def test_stop_at_empty_is_a_usage_error(tmp_path):
    """`contin trace bratu --stop-at ''` ran to the end without a word, exit 0."""
    res = run(["trace", "bratu", "--stop-at", "", "-q", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 2 and "Invalid value for '--stop-at': expected labels such as LP1 or UZ2, got ''" in res.stderr


def test_empty_kx_imperfection_and_delta_are_usage_errors(allen_cahn_file, tmp_path):
    """`contin trace bratu --kx ''` was accepted without a word; `contin fit F --at BP1 --imperfection ''`
    (or --delta '') fell back to the default and then asked to 'give it with --imperfection NAME'."""
    res = run(["trace", "bratu", "--kx", "", "-q", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 2 and "Invalid value for '--kx': must not be empty" in res.stderr, res.stderr
    for option in ("--imperfection", "--delta"):
        res = run(["fit", str(allen_cahn_file), "--at", "BP1", option, ""])
        assert res.exit_code == 2 and f"Invalid value for '{option}': must not be empty" in res.stderr, res.stderr


def test_profiles_of_a_branch_that_reaches_the_value_twice_say_which_is_drawn(tmp_path):
    """`contin profiles bratu.h5 --at lam=3.5` drew the lower solution only ('interpolated between
    points 18 and 20'), without a word about the upper one the branch reaches after its fold."""
    out = tmp_path / "b.h5"
    assert run(["trace", "bratu", "--max-steps", "60", "-q", "-o", str(out)]).exit_code == 0
    res = run(["profiles", str(out), "--at", "lam=3.5", "-o", str(tmp_path / "p.png")])
    assert res.exit_code == 0, res.stderr
    assert "(the first of 2 crossings of lam=3.5 along the branch; the others are not drawn)" in res.stderr, res.stderr
    short = tmp_path / "short.h5"  # below the fold only: one crossing, no note
    assert run(["trace", "bratu", "--max-steps", "8", "-q", "-o", str(short)]).exit_code == 0
    res = run(["profiles", str(short), "--at", "lam=0.5", "-o", str(tmp_path / "q.png")])
    assert res.exit_code == 0 and "crossings" not in res.stderr, res.stderr


def test_continue_from_an_end_point_of_an_adaptive_curve_names_the_point_type(tmp_path):
    """`contin continue c1.h5 --from EP1 --free a` (EP1 of a regridded fold curve) said 'EP1 was
    computed on grid 56 (an adaptive run ...): continue it with --tol REL', which then fails for the
    point type; the type is checked first."""
    sb, c1 = tmp_path / "sb.h5", tmp_path / "c1.h5"
    assert run(["trace", "stretched-bratu", "--grid", "24", "--resolution-tol", "1e-8", "--stop-at", "LP1",
                "--no-stability", "-q", "-o", str(sb)]).exit_code == 0
    assert run(["continue", str(sb), "--from", "LP1", "--free", "a", "--bounds", "a=-0.5:6", "--bounds", "lam=0:8",
                "--ds", "0.1", "--ds-max", "0.5", "--tol", "1e-8", "-o", str(c1)]).exit_code == 0
    err = one_error(run(["continue", str(c1), "--from", "EP1", "--free", "a", "-o", str(tmp_path / "x.h5")]))
    assert err == "Error: EP1: only BP, BT, HB, HH, LP, ZH points can be continued in two parameters, not EP", err


def test_resume_with_other_step_settings_is_refused(tmp_path):
    """`contin trace bratu --resume F --uz lam=2` of a finished run without that user zero reused its
    branch as it was, wrote F again with no UZ and the new command line, exit 0; --stop-at,
    --max-steps, --ds, --ds-max, --bp-eigs likewise.  The same settings given again are fine."""
    out = tmp_path / "b.h5"
    assert run(["trace", "bratu", "--max-steps", "30", "-q", "-o", str(out)]).exit_code == 0
    err = one_error(run(["trace", "bratu", "--resume", str(out), "--uz", "lam=2", "-q"]))
    assert err == (f"Error: {str(out)!r} was computed with --uz none, not lam=2; its finished branches are reused "
                   f"as they are, so resume with the same settings (or start a new run)"), err
    err = one_error(run(["trace", "bratu", "--resume", str(out), "--max-steps", "31", "-q"]))
    assert "was computed with --max-steps 30, not 31" in err, err
    err = one_error(run(["trace", "bratu", "--resume", str(out), "--bp-eigs", "0", "-q"]))
    assert "was computed with --bp-eigs its default, not 0" in err, err
    assert run(["trace", "bratu", "--resume", str(out), "--max-steps", "30", "-q"]).exit_code == 0


def test_stability_of_a_file_without_branches_says_so(tmp_path):
    """`contin stability F --point 0` of a file written with no branches said 'F holds 0 branches;
    choose one with --branch (none)'."""
    from contin import io

    empty = tmp_path / "empty.h5"
    io.write(empty, [])
    err = one_error(run(["stability", str(empty), "--point", "0"]))
    assert err == f"Error: {empty} holds no branches", err


def test_a_sweep_into_another_sweeps_directory_says_it_replaces_that_summary(tmp_path):
    """qa15 leftover: `contin sweep b.toml -o out` where out holds a.toml's summary replaced it
    without a word.  Now one warning line (also with -q); a rerun of the same sweep says nothing."""
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text('[sweep]\nscene = "bratu"\n[grid]\nlam_max = [1.0]\n[options]\ngrid = 16\nstability = false\n')
    b.write_text('[sweep]\nscene = "bratu"\n[grid]\nlam_max = [1.5]\n[options]\ngrid = 16\nstability = false\n')
    out = tmp_path / "out"
    first = run(["sweep", str(a), "-o", str(out), "-j", "1", "-q"])
    assert first.exit_code == 0 and "warning" not in first.stderr
    again = run(["sweep", str(a), "-o", str(out), "-j", "1", "-q"])
    assert again.exit_code == 0 and "warning" not in again.stderr
    other = run(["sweep", str(b), "-o", str(out), "-j", "1", "-q"])
    assert other.exit_code == 0
    lines = [ln for ln in other.stderr.splitlines() if ln.startswith("warning:")]
    assert len(lines) == 1 and "summary of another sweep (scene 'bratu')" in lines[0] and "task files are kept" in lines[0]
    assert len(list((out / "tasks").glob("*.h5"))) == 2  # both sweeps' task files
