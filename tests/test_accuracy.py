"""contin.accuracy and ``contin accuracy``: key points against method and grid.

Numbers: the Bratu fold lam* = 3.513830719125162 (problems.demo), gPCF H_1^c = pi psi(0.3, 0.8)
= 13.0685293255 (physics.md section 4) and the banded-branch fold at nu = 0.16, H = 41.9625
(independently 41.963 by solve_bvp pinning, benchmarks/baseline_solve_bvp.py).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from contin.accuracy import key_points, recommend, references, relative_error, run_accuracy, tabulate, write_outputs
from contin.cli import main
from contin.scene import SceneRequest, get_scene
from problems.demo import BRATU_FOLD


@pytest.fixture(scope="module")
def bratu_report():
    scene = get_scene("bratu")
    return run_accuracy(scene, {}, ["cheb", "fd2", "fd4"], [8, 16, 32, 64], memory=False)


def _rows(report, method):
    return sorted((r for r in report.rows if r.method == method), key=lambda r: r.grid)


def test_bratu_reference_is_finest_chebyshev_and_exact(bratu_report):
    assert bratu_report.reference_from == "cheb N=64"
    assert list(bratu_report.reference) == ["0/LP1"]
    assert relative_error(bratu_report.reference["0/LP1"], BRATU_FOLD) < 1e-13
    cheb = _rows(bratu_report, "cheb")
    assert math.isnan(cheb[-1].error)  # the reference itself
    assert cheb[2].error < 1e-12  # N = 32
    assert 1e-6 < cheb[0].error < 1e-3  # N = 8 is visibly under-resolved


@pytest.mark.parametrize("method,order", [("fd2", 2.0), ("fd4", 4.0)])
def test_bratu_observed_orders(bratu_report, method, order):
    rows = _rows(bratu_report, method)
    observed = [r.order for r in rows[1:]]
    assert all(abs(o - order) < 0.7 for o in observed), observed
    assert abs(observed[-1] - order) < 0.25  # asymptotic on the finest pair
    for r in rows:  # errors against the exact fold, not just the reference
        assert r.error == pytest.approx(relative_error(r.value, BRATU_FOLD), rel=1e-6, abs=1e-13)


def test_bratu_costs_recorded(bratu_report):
    for run in bratu_report.runs:
        assert not run.failed
        assert run.wall > 0 and run.cpu > 0 and run.newton_iterations > 10 and run.points > 10
        assert math.isnan(run.peak_memory_mb)  # memory=False


def test_recommendation_picks_cheapest_run_meeting_budget(bratu_report):
    rec = {r["target"]: r for r in recommend(bratu_report, targets=(1e-2, 1e-6, 1e-10, 1e-16))}
    assert rec[1e-10]["method"] == "cheb" and rec[1e-10]["worst_error"] <= 1e-10
    assert rec[1e-16]["method"] is None  # nothing is that accurate against a cheb reference
    ok = [(r.cpu, r.method, r.grid) for r in bratu_report.rows if r.error <= 1e-2]
    assert (rec[1e-2]["method"], rec[1e-2]["grid"]) == min(ok)[1:]


def test_richardson_reference_without_chebyshev():
    scene = get_scene("bratu")
    rep = run_accuracy(scene, {}, ["fd2"], [32, 64], memory=False)
    assert rep.reference_from.startswith("Richardson fd2")
    fd2_64 = [r for r in rep.rows if r.grid == 64][0]
    # h^2 extrapolation removes the leading error: 1.3e-4 -> below 1e-6
    assert relative_error(fd2_64.value, BRATU_FOLD) > 1e-4
    assert relative_error(rep.reference["0/LP1"], BRATU_FOLD) < 1e-6


def test_too_small_grid_is_a_labelled_failure_not_a_crash():
    rep = run_accuracy(get_scene("bratu"), {}, ["fd6", "cheb"], [6, 16], memory=False)
    failed = [r for r in rep.runs if r.failed]
    assert [(r.method, r.grid) for r in failed] == [("fd6", 6)]
    assert "fd6 needs at least 12 intervals" in failed[0].failed
    assert rep.reference_from == "cheb N=16"


def test_peak_memory_and_outputs(tmp_path):
    rep = run_accuracy(get_scene("bratu"), {}, ["cheb", "fd4"], [16, 32], memory=True)
    assert all(0.01 < r.peak_memory_mb < 200 for r in rep.runs)
    paths = write_outputs(rep, tmp_path)
    names = sorted(p.name for p in paths)
    assert names == ["accuracy_bratu.csv", "accuracy_bratu.json", "accuracy_bratu_error_vs_N.png",
                     "accuracy_bratu_error_vs_time.png"]
    lines = (tmp_path / "accuracy_bratu.csv").read_text().splitlines()
    assert lines[0].startswith("key,method,grid,value,reference,error,order")
    assert len(lines) == 1 + 4
    doc = json.loads((tmp_path / "accuracy_bratu.json").read_text())
    assert doc["reference_from"] == "cheb N=32" and len(doc["rows"]) == 4
    assert doc["recommendations"][0]["target"] == 1e-3
    assert all((tmp_path / n).stat().st_size > 5000 for n in names if n.endswith(".png"))


def test_key_points_from_special_points_skip_unconverged():
    res = get_scene("bratu").run(SceneRequest(grid=16, stability=False))
    assert set(key_points(res)) == {"0/LP1"}
    sps = res.branches[0].special_points
    res.branches[0].special_points = [dataclasses.replace(s, converged=False) if s.type == "LP" else s for s in sps]
    assert key_points(res) == {}
    assert references([])[1] == "none (every run failed)"


def test_closed_forms_replace_the_numeric_reference():
    """A key point with a closed form (SceneResult.extra['exact']) is measured against it on every
    grid, the finest included; the others against the finest Chebyshev grid."""
    from contin.accuracy import Run

    runs = [Run("cheb", n, 1.0, 1.0, 1, 1, math.nan, {"a": 1.0 + d, "b": 2.0 + d}, exact={"a": 1.0})
            for n, d in ((16, 1e-6), (32, 1e-9))]
    ref, what = references(runs)
    assert ref == {"a": 1.0, "b": 2.0 + 1e-9}
    assert what == "closed form for a; cheb N=32 for b"
    rows = {(r.key, r.grid): r.error for r in tabulate(runs, ref)}
    assert rows[("a", 32)] == pytest.approx(1e-9) and rows[("a", 16)] == pytest.approx(1e-6)
    assert math.isnan(rows[("b", 32)]) and rows[("b", 16)] == pytest.approx((1e-6 - 1e-9) / (2 + 1e-9))


# ----------------------------------------------------------------------------- gPCF
@pytest.fixture(scope="module")
def gpcf():
    from problems.couette.keypoints import SCENES

    return SCENES["gpcf-keypoints"]


@pytest.mark.parametrize("n", [16, 24, 32, 48])
def test_gpcf_critical_gap_to_1e10_at_chebyshev_n_le_48(gpcf, n):
    from problems.couette.keypoints import exact_hc1

    res = gpcf.run(SceneRequest(method="cheb", grid=n))
    hc = exact_hc1(0.3, 0.8)
    assert hc == pytest.approx(13.0685293255, abs=1e-10)
    assert relative_error(res.extra["key_points"]["Hc1"], hc) < 1e-10


def test_gpcf_banded_fold_converges_and_matches_baseline(gpcf):
    rep = run_accuracy(gpcf, {}, ["cheb", "fd4"], [32, 48, 64], memory=False)
    lp = {(r.method, r.grid): r for r in rep.rows if r.key == "LP_nu0.16"}
    ref = rep.reference["LP_nu0.16"]
    assert ref == pytest.approx(41.963, abs=1.5e-3)  # solve_bvp pinning scan
    assert lp["cheb", 32].error < 1e-7 and lp["cheb", 48].error < 1e-9
    assert 1e-4 < lp["fd4", 32].error < 1e-2
    assert lp["fd4", 64].error < lp["fd4", 48].error < lp["fd4", 32].error
    assert 3.5 < lp["fd4", 64].order < 5.5  # fourth order (pre-asymptotic: ~4.7)


# ----------------------------------------------------------------------------- CLI
def test_cli_accuracy_json_and_files(tmp_path):
    r = CliRunner().invoke(main, ["accuracy", "bratu", "--methods", "cheb,fd2", "--grids", "16,32", "--json",
                                  "--no-memory", "-o", str(tmp_path / "acc")])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["scene"] == "bratu" and len(doc["rows"]) == 4
    assert (tmp_path / "acc" / "accuracy_bratu.csv").exists()
    assert "budget" in r.stderr


@pytest.mark.parametrize("args,message", [
    (["--methods", "cheb,spectral"], "unknown method 'spectral'"),
    (["--grids", "16,x"], "comma-separated list"),
    (["--grids", "1,16"], "grids must be at least 2"),
    (["-s", "mu=1"], "unknown parameter 'mu'"),
])
def test_cli_accuracy_bad_input_one_line(args, message):
    r = CliRunner().invoke(main, ["accuracy", "bratu", "--no-memory", *args])
    assert r.exit_code in (1, 2)
    err = r.stderr.strip().splitlines()
    assert message in r.stderr and "Traceback" not in r.stderr
    assert len([line for line in err if line.startswith("Error")]) == 1


def test_cli_accuracy_all_runs_failed():
    r = CliRunner().invoke(main, ["accuracy", "bratu", "--methods", "fd6", "--grids", "6,8", "--no-memory"])
    assert r.exit_code == 1
    assert "no key points" in r.stderr and "fd6 needs at least 12 intervals" in r.stderr


# ------------------------------------------------------------ asking for an accuracy (--tols)
@pytest.fixture(scope="module")
def bratu_tols():
    return run_accuracy(get_scene("bratu"), {}, ["cheb"], [8, 16, 32, 64], memory=False, tols=[1e-4, 1e-8])


def test_adaptive_runs_meet_their_tol_against_the_closed_form(bratu_tols):
    assert [a.tol for a in bratu_tols.adaptive] == [1e-4, 1e-8]
    for a in bratu_tols.adaptive:
        assert a.met and not a.failed
        # independent of the report's reference: the fold against the closed form of problems.demo
        (fold,) = [v for k, v in a.values.items() if "LP" in k]
        assert relative_error(fold, BRATU_FOLD) <= a.tol
        assert a.worst_error == max(a.errors.values()) <= a.tol
        assert a.grids is not None and a.grids[0] <= a.grids[1]


def test_adaptive_cost_is_against_the_cheapest_complete_fixed_run_meeting_tol(bratu_tols):
    for a in bratu_tols.adaptive:
        ok = [r for r in bratu_tols.runs if not r.stopped and r.values
              and all(relative_error(r.values[k], v) <= a.tol for k, v in bratu_tols.reference.items())
              and (r.method, r.grid) != ("cheb", 64)]  # the reference itself has no error
        cheapest = min(ok, key=lambda r: r.cpu)
        assert (a.fixed_method, a.fixed_grid) == (cheapest.method, cheapest.grid)
        assert a.ratio == pytest.approx(a.cpu / cheapest.cpu)


def test_adaptive_row_flags_a_run_beyond_tol():
    from contin.accuracy import AccuracyReport, Run, adaptive_row

    fixed = [Run("cheb", 32, 1.0, 0.5, 10, 5, math.nan, {"a": 1.0 + 1e-9}),
             Run("cheb", 64, 2.0, 1.0, 10, 5, math.nan, {"a": 1.0})]
    rep = AccuracyReport("s", {}, {"a": 1.0}, "cheb N=64", fixed)
    from contin.accuracy import tabulate

    rep.rows = tabulate(fixed, rep.reference)
    bad = adaptive_row(Run("cheb", 48, 1.0, 0.25, 10, 5, math.nan, {"a": 1.0 + 3e-6}), 1e-6, rep)
    assert not bad.met and bad.worst_error == pytest.approx(3e-6) and bad.worst_key == "a"
    assert (bad.fixed_grid, bad.ratio) == (32, pytest.approx(0.5))
    missing = adaptive_row(Run("cheb", 48, 1.0, 0.25, 10, 5, math.nan, {}), 1e-6, rep)
    assert not missing.met and "not found" in missing.failed
    assert rep.inaccurate == [] and AccuracyReport("s", {}, {}, "", [], adaptive=[bad]).inaccurate == [bad]


def test_gpcf_keypoints_adaptive_meet_tol(gpcf):
    """H_1^c against n pi psi and the nu = 0.16 fold against the cheb-96 reference, asked for
    1e-4 and 1e-8 instead of a grid (issue 14's tol-vs-achieved check)."""
    from problems.couette.keypoints import exact_hc1

    rep = run_accuracy(gpcf, {}, ["cheb"], [32, 48, 96], memory=False, tols=[1e-4, 1e-8])
    assert rep.reference["LP_nu0.16"] == pytest.approx(41.9625323, abs=1e-6)
    assert rep.reference["Hc1"] == exact_hc1(0.3, 0.8)  # the closed form, not the cheb-96 value
    for a in rep.adaptive:
        assert a.met, a
        assert relative_error(a.values["Hc1"], exact_hc1(0.3, 0.8)) <= a.tol
        assert relative_error(a.values["LP_nu0.16"], rep.reference["LP_nu0.16"]) <= a.tol
    # the banded branch stops at its fold (STOP LP1), so every fixed grid completes the job; the
    # cheapest fixed grid is the coarsest whose key points are all within tol
    assert [r.stopped for r in rep.runs] == [0, 0, 0]
    for a in rep.adaptive:
        meets = [r.grid for r in rep.runs[:-1] if all(relative_error(r.values[k], rep.reference[k]) <= a.tol
                                                      for k in r.values)]
        assert a.fixed_grid == min(meets)
    assert [a.fixed_grid for a in rep.adaptive] == [32, 32, 32, 32]  # cheb 32: fold error 1.6e-9
    # both requests (the scene's key points are special points): everything at tol, then the
    # key points alone (the states at the scene's default tol)
    assert [(a.request, a.tol) for a in rep.adaptive] == [("all", 1e-4), ("all", 1e-8), ("key points", 1e-4),
                                                          ("key points", 1e-8)]


def test_cli_accuracy_tols_json_csv_and_table(tmp_path):
    r = CliRunner().invoke(main, ["accuracy", "bratu", "--methods", "cheb", "--grids", "16,32,64", "--tols", "1e-6",
                                  "--repeats", "2", "--json", "--no-memory", "--no-plots", "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    (row,) = json.loads(r.stdout)["adaptive"]
    assert row["tol"] == 1e-6 and row["met"] and row["worst_error"] <= 1e-6
    # one request: bratu is not marked special_key_points (its states' default tol, 1e-10, would
    # ask more of them than the request "all" does)
    assert row["request"] == "all"
    assert (tmp_path / "accuracy_bratu_adaptive.csv").read_text().startswith("tol,request,worst_error")
    assert "cheapest fixed" in r.stderr


def test_cli_accuracy_inaccurate_adaptive_run_exits_4(monkeypatch):
    import contin.accuracy as acc

    real = acc.run_accuracy

    def fake(*args, **kwargs):
        rep = real(*args, **kwargs)
        rep.adaptive = [dataclasses.replace(a, met=False, worst_error=10 * a.tol) for a in rep.adaptive]
        return rep

    monkeypatch.setattr(acc, "run_accuracy", fake)
    r = CliRunner().invoke(main, ["accuracy", "bratu", "--methods", "cheb", "--grids", "16,32", "--tols", "1e-4",
                                  "--no-memory", "-q"])
    assert r.exit_code == 4
    assert r.stderr.strip().startswith("inaccurate: adaptive run at tol 0.0001 (all): achieved error 0.001")


@pytest.mark.parametrize("args,message", [
    (["--tols", "0"], "--tols must be numbers in (0, 1)"),
    (["--tols", "1e-4,nan"], "--tols must be numbers in (0, 1)"),
    (["--tols", "x"], "comma-separated list"),
])
def test_cli_accuracy_tols_bad_input_one_line(args, message):
    r = CliRunner().invoke(main, ["accuracy", "bratu", "--no-memory", "--grids", "16,32", *args])
    assert r.exit_code in (1, 2) and message in r.stderr and "Traceback" not in r.stderr


def test_cli_accuracy_tols_needs_an_adaptive_scene():
    r = CliRunner().invoke(main, ["accuracy", "lorenz", "--no-memory", "--tols", "1e-4"])
    assert r.exit_code == 1 and "has no adaptive resolution" in r.stderr
    assert len([line for line in r.stderr.splitlines() if line.startswith("Error")]) == 1


@pytest.mark.slow
def test_gpcf_frstar_asked_for_tol_meets_it():
    """Fr* (the floating-plug limit, max of G on the first pitchfork's fold curve) asked for
    1e-4 instead of a grid, against the fixed cheb 48 run (whose Fr* agrees with cheb 96 to
    1e-12) and AUTO-07p's 254.1204 (benchmarks/auto_peer, DSMAX 0.02)."""
    from problems.couette.keypoints import SCENES

    rep = run_accuracy(SCENES["gpcf-frstar"], {}, ["cheb"], [24, 48], memory=False, tols=[1e-4])
    (a,) = rep.adaptive
    assert rep.reference["Fr*"] == pytest.approx(254.1204, abs=2e-4)
    assert a.met and relative_error(a.values["Fr*"], rep.reference["Fr*"]) <= 1e-4
    assert a.grids is not None and a.grids[1] <= 48  # the curve's grid chosen from its seed, not the start's 32 refined


@pytest.mark.slow
def test_gpcf_frstar_at_1e_8_regrids_the_fold_curve_segment_wise():
    """Fr* asked for 1e-8: the fold curve starts on its seed's grid and only its dense-plug ends
    (H near 30, both halves) continue on a finer grid (contin.foldcurve.SegmentRegrid): one curve
    whose grids fall then rise along it (each direction from the seed refines on its own), Fr*
    located on the coarse segment, within 1e-8 of the fixed cheb 48 run (which agrees with cheb 96
    to 1e-13, README) and of AUTO-07p's 254.1204."""
    from contin.scene import SceneRequest
    from problems.couette.keypoints import SCENES

    scene = SCENES["gpcf-frstar"]
    fixed = scene.run(SceneRequest(params={}, method="cheb", grid=48, stability=False))
    ref = fixed.extra["key_points"]["Fr*"]
    assert ref == pytest.approx(254.1204, abs=2e-4)
    res = scene.run(SceneRequest(params={}, method="cheb", grid=None, stability=False, overrides={"tol": 1e-8}))
    assert relative_error(res.extra["key_points"]["Fr*"], ref) <= 1e-8
    (curve,) = [b for b in res.branches if b.id == "fold0"]
    assert curve.status == "EP" and curve.grid is not None and len(curve.grid) == len(curve)
    g = curve.grid
    low = int(np.argmin(g))
    assert np.all(np.diff(g[:low + 1]) <= 0) and np.all(np.diff(g[low:]) >= 0)  # refined outward only
    assert g[0] > g[low] and g[-1] > g[low] and int(np.max(g)) <= 48
    assert len([line for line in curve.audit if line.startswith("grid ")]) == len(curve.grid_changes) == 2
    (xt,) = [s for s in curve.special_points if s.type == "XT" and s.params["G"] > 0]
    assert xt.grid == g[low] and xt.params["G"] ** -0.5 == pytest.approx(res.extra["key_points"]["Fr*"], rel=1e-14)
