"""Robustness sweep 4 (session 18, qa18): interrupted `contin continue` and `gravity-phase` runs,
then what a demanding user tried on every command.

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from contin import io

from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)


# ----------------------------------------------------------------------------- gravity-phase
PHASE = ["trace", "gravity-phase", "-s", "H_max=45", "--grid", "24", "--no-stability", "-q"]


def test_gravity_phase_stores_each_fold_curve_and_resume_reuses_it(tmp_path, monkeypatch):
    """`contin trace gravity-phase -o F` passed its fold curves to the file only at the end: a run
    stopped at once (second Ctrl-C, SIGKILL) while the second pitchfork's curve was traced kept
    nothing of the first (~30 s at the default grid), and `--resume F` traced every curve again.
    Now each curve is stored when it is finished and --resume reuses it: only fold1 is traced."""
    import problems.couette.gravity as gravity

    traced: list[int] = []
    original = gravity._bp_fold_curves

    def killed_at_fold1(problem, source, params, base, kids, k, *args, **kwargs):
        traced.append(k)
        if k == 1 and len(traced) == 2:
            raise KeyboardInterrupt  # stopped at once while the second curve is traced
        return original(problem, source, params, base, kids, k, *args, **kwargs)

    monkeypatch.setattr(gravity, "_bp_fold_curves", killed_at_fold1)
    out = tmp_path / "phase.h5"
    res = run([*PHASE, "-o", str(out)])
    assert res.exit_code == 130 and traced == [0, 1], res.stderr
    (kept,), meta = io.load(out)
    assert kept.id == "fold0" and meta["complete"] is False and meta["stopped"] == "interrupted"
    res = run([*PHASE, "--resume", str(out)])
    assert res.exit_code == 3 and traced == [0, 1, 1], res.stderr  # fold0 reused, not traced again
    (fold0, fold1), meta = io.load(out)
    assert meta["complete"] is True and np.array_equal(fold0.states, kept.states)
    # each curve passes through its pitchfork (cusp at G = 0): H_n^c = n pi psi, so H_3^c = 3 H_1^c
    (cp0,), (cp1,) = fold0.points("CP"), fold1.points("CP")
    assert cp1.params["H"] == pytest.approx(3 * cp0.params["H"], rel=1e-6)


# ----------------------------------------------------------------------------- continue
@pytest.fixture(scope="module")
def stretched(tmp_path_factory):
    """A stretched-Bratu run on cheb 32 with its fold LP1 (lam* = 3.51383...; fold curve lam = lam*/(1 + a))."""
    path = tmp_path_factory.mktemp("sb") / "sb.h5"
    res = run(["trace", "stretched-bratu", "--grid", "32", "--no-stability", "-q", "-o", str(path)])
    assert res.exit_code in (0, 3), res.stderr
    return path


LAM_STAR = 3.51383071912516  # Bratu's fold (Jacobsen & Schmitt 2002)


def test_a_long_first_step_across_a_bound_is_shortened_not_taken_for_the_bound(stretched, tmp_path):
    """`contin continue sb.h5 --from LP1 --free a --ds 10`: the first step backward crossed the bound
    lam = 0 and landing on it failed, so the half ended at its start point 'reached bound lam=0
    (landing on it failed ...)', EP, exit 0 -- at lam = 3.5, nowhere near it.  Now a failed landing
    shortens the step (contin.continuation.trace): the curve reaches the a bound, on the fold curve."""
    out = tmp_path / "c.h5"
    res = run(["continue", str(stretched), "--from", "LP1", "--free", "a", "--ds", "10", "--bounds", "a=-0.5:3",
               "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (curve,), _ = io.load(out)
    lam, a = curve.params["lam"], curve.params["a"]
    assert "landing on it failed" not in curve.message
    assert a.max() == 3.0 and lam.max() == 4.0  # both ends on a bound: a = 3 backward, lam = 4 forward
    assert np.allclose(lam * (1 + a), LAM_STAR, rtol=1e-8)


def test_trace_resume_refuses_a_continue_curve_and_leaves_it_alone(stretched, tmp_path):
    """`contin trace stretched-bratu --resume CURVE.h5` (CURVE from `contin continue`): the curve was
    taken for a finished branch, the scene's run traced and written over the file, the curve
    dropped -- lost, exit 0.  Now it is one Error line and the file is untouched."""
    curve = tmp_path / "curve.h5"
    assert run(["continue", str(stretched), "--from", "LP1", "--free", "a", "--max-steps", "5", "-o",
                str(curve)]).exit_code == 0
    before = curve.read_bytes()
    line = one_error(run(["trace", "stretched-bratu", "--resume", str(curve), "-q"]))
    assert "holds a two-parameter curve of `contin continue` (from LP1)" in line
    assert curve.read_bytes() == before


# ----------------------------------------------------------------------------- stability
PITCHFORK = Path(__file__).parents[1] / "results" / "pitchfork.h5"


def test_stability_at_a_label_finds_its_branch(tmp_path):
    """`contin stability pitchfork.h5 --point BP2` (a file of 7 branches): 'holds 7 branches; choose
    one with --branch', though the label names one point of one branch.  Now the label selects its
    branch; an index still needs --branch."""
    import json

    res = run(["stability", str(PITCHFORK), "--point", "BP2", "--kx", "0", "--json"])
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    (base, *_), _ = io.load(PITCHFORK)
    (bp1,) = [sp for sp in base.special_points if sp.name == "BP1"]
    # the state of BP2 of the base branch: H_2^c = 2 pi psi = 2 H_1^c
    assert doc["branch"] == base.id and doc["point"] == "BP2"
    assert doc["params"]["H"] == pytest.approx(2 * bp1.params["H"], rel=1e-6)
    assert "choose one with --branch" in one_error(run(["stability", str(PITCHFORK), "--point", "3", "--kx", "0"]))


# ----------------------------------------------------------------------------- incomplete files
@pytest.mark.parametrize("command", [["diagram", "{f}", "-o", "{d}/d.png"], ["export", "{f}", "--auto", "x", "-d", "{d}"]])
def test_a_diagram_or_export_of_an_unfinished_run_says_so(tmp_path, command):
    """`contin diagram F` / `contin export F` of a run stopped after some of its branches drew and
    exported them as if they were the run, with no word of it (exit 0).  Now a warning line names
    the file as incomplete and why; a finished file gets none."""
    import h5py

    done = tmp_path / "done.h5"
    assert run(["trace", "allen-cahn", "-q", "-o", str(done)]).exit_code == 0
    part = tmp_path / "part.h5"
    part.write_bytes(done.read_bytes())
    with h5py.File(part, "r+") as f:  # what an interrupted run leaves (contin.cli.trace._stopped)
        f.attrs["complete"] = False
        f.attrs["stopped"] = "terminated by SIGTERM"
    for path, warned in ((done, False), (part, True)):
        res = run([a.format(f=path, d=tmp_path) for a in command])
        assert res.exit_code == 0, res.stderr
        warnings = [ln for ln in res.stderr.splitlines() if ln.startswith("warning:")]
        assert warnings == ([f"warning: {path} is incomplete (its run was terminated by SIGTERM): it holds only the "
                             "branches computed before that"] if warned else []), res.stderr
    with h5py.File(part, "r+") as f:  # a checkpoint of a run still going (or SIGKILLed): no reason recorded
        f.attrs["stopped"] = ""
    res = run([a.format(f=part, d=tmp_path) for a in command])
    assert f"warning: {part} is incomplete (its run was still running, or killed)" in res.stderr


# ----------------------------------------------------------------------------- verify
def test_verify_with_no_point_checked_prints_no_nan(tmp_path):
    """`contin verify F --max-grid 2` (below the file's grid): no point can be checked; the table's
    max error column said 'nan' beside FAIL.  Now '-', exit 4, the reason on the 'inaccurate' line."""
    f = tmp_path / "b.h5"
    assert run(["trace", "bratu", "-q", "-o", str(f)]).exit_code == 0
    res = run(["verify", str(f), "--max-grid", "2"])
    assert res.exit_code == 4
    assert "nan" not in res.stdout.lower() and "nan" not in res.stderr.lower(), res.stdout
    (row,) = [ln.split() for ln in res.stdout.splitlines() if ln.startswith("0 ")]
    assert row[3] == "-" and row[-1] == "FAIL"


# ----------------------------------------------------------------------------- closed stderr
def test_a_run_with_stderr_closed_writes_its_file(tmp_path):
    """`contin trace bratu -o F 2>&-` (stderr closed: sys.stderr is None): the first message raised
    AttributeError, click's report of it raised again, and the run ended with exit 120 and no F.
    Now messages go nowhere and the run is as with stderr open: exit 0, F written (LP1 at lam*)."""
    import os
    import subprocess
    import sys

    out = tmp_path / "b.h5"
    env = {k: v for k, v in os.environ.items() if k != "CONTIN_SCENES"}
    proc = subprocess.run([sys.executable, "-m", "contin", "trace", "bratu", "-o", str(out)], env=env,
                          stdout=subprocess.PIPE, preexec_fn=lambda: os.close(2), timeout=120)
    assert proc.returncode == 0
    (branch,), meta = io.load(out)
    assert meta["complete"] is True
    (lp,) = branch.points("LP")
    assert lp.params["lam"] == pytest.approx(3.513830719125162, rel=1e-9)  # Bratu's fold lam*


def _reader_gone_run(args: list[str], tmp_path):
    """``contin ARGS`` with stdout a pipe whose reader has gone before the first write (the
    parent's read end is closed at once): what ``| head -1`` does to the rest, deterministically."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "CONTIN_SCENES"}
    p = subprocess.Popen([sys.executable, "-m", "contin", *args], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, cwd=tmp_path)
    p.stdout.close()
    err = p.stderr.read()
    p.wait(timeout=120)
    return subprocess.CompletedProcess(p.args, p.returncode, b"", err)


@pytest.mark.parametrize("args", [["scenes"], ["trace", "bratu", "--json", "-q", "-o", "b.h5"]])
def test_a_reader_of_stdout_that_has_gone_is_no_error(args, tmp_path):
    """`contin scenes | head -1` and `contin info F | head` ended `Error: Broken pipe`, exit 1: a
    reader that took what it wanted is no failure.  Now stdout becomes a sink: exit 0, nothing on
    stderr ('Exception ignored ... BrokenPipeError' neither: the descriptor goes to /dev/null), and a
    trace still writes its file."""
    proc = _reader_gone_run(args, tmp_path)
    assert proc.returncode == 0 and proc.stderr == b"", proc.stderr
    if "trace" in args:
        (branch,), meta = io.load(tmp_path / "b.h5")
        assert meta["complete"] is True and branch.points("LP")[0].params["lam"] == pytest.approx(3.513830719125162, rel=1e-9)


# ----------------------------------------------------------------------------- gravity-unfolding
@pytest.mark.parametrize("G, expect", [("1e-7,1e-7", "G lists the value 1e-07 twice"),
                                       ("1e-200", "G = 1e-200 is outside 1e-100 <= G <= 1"),
                                       ("1e300", "G = 1e+300 is outside 1e-100 <= G <= 1")])
def test_gravity_unfolding_refuses_repeated_and_far_gravities(G, expect):
    """`contin trace gravity-unfolding -s G=1e-7,1e-7` traced and stored each branch at that G twice
    under the same ids (exit 0); G = 1e-200 ended 'arithmetic failure (ZeroDivisionError)', 1e300
    '(OverflowError)' (the G-homotopy weighs the arclength by 1/G^2).  Now one clear line each."""
    assert expect in one_error(run(["trace", "gravity-unfolding", "-s", f"G={G}", "--grid", "12", "-q"]))


def test_disks_criticality_refuses_a_repeated_restitution_coefficient():
    """`contin trace disks-criticality -s e_list=0.8,0.8` computed e = 0.8 twice (the second over the
    first in extra.curves, two notes), exit 0."""
    assert "lists e = 0.8 twice" in one_error(run(["trace", "disks-criticality", "-s", "e_list=0.8,0.8", "-q"]))


# ----------------------------------------------------------------------------- results that are not branches
def test_ctrl_c_keeps_what_a_scene_without_branches_finished(tmp_path, monkeypatch):
    """`contin trace disks-criticality -o F` + Ctrl-C after the first restitution coefficient: the
    scene stops at the next e (qa17) but its results are notes and extra, not branches, so nothing
    was written -- the finished e lost.  Now F holds them, marked interrupted (exit 130)."""
    import problems.disks.criticality as crit
    from contin.cancel import request_stop

    original = crit.tricritical

    def ctrl_c_after_the_first_e(*args, **kwargs):
        out = original(*args, **kwargs)
        request_stop()  # the Ctrl-C arrives once e = 0.8 is done
        return out

    monkeypatch.setattr(crit, "tricritical", ctrl_c_after_the_first_e)
    out = tmp_path / "dc.h5"
    res = run(["trace", "disks-criticality", "-s", "e_list=0.8,0.9", "-s", "nu_min=0.5", "-s", "nu_max=0.6", "-s",
               "dnu=0.1", "-s", "fold_checks=0", "-o", str(out)])
    assert res.exit_code == 130, res.stderr
    branches, meta = io.load(out)
    assert branches == [] and meta["complete"] is False and meta["stopped"] == "interrupted"
    assert list(meta["extra"]["curves"]) == ["0.8"]  # e = 0.9 was not started
    # the kept result is e = 0.8's: its threshold density solved here from the closure (cs, the scene's defaults)
    from problems.disks.closures import DiskClosure
    from problems.disks.model import DEFAULTS

    nu_th = crit.threshold_density({**DEFAULTS, "phi_inf": 0.9, "phi_f": 0.7, "m_f": 0.01, "e": 0.8}, DiskClosure(G="cs"))
    assert meta["extra"]["curves"]["0.8"]["threshold"] == pytest.approx(nu_th, rel=1e-12)
    assert any(f"e = 0.8: threshold nu_th = {nu_th:.6f}" in n for n in meta["notes"])


def test_info_json_says_why_a_run_stopped(tmp_path):
    """`contin info F --json` of an interrupted run said "complete": false but not why (the text
    says 'incomplete: the run was terminated by SIGTERM'); its provenance now holds "stopped"."""
    import json

    import h5py

    f = tmp_path / "b.h5"
    assert run(["trace", "bratu", "-q", "-o", str(f)]).exit_code == 0
    assert json.loads(run(["info", str(f), "--json"]).stdout)["provenance"]["stopped"] == ""
    with h5py.File(f, "r+") as h:
        h.attrs["complete"] = False
        h.attrs["stopped"] = "terminated by SIGTERM"
    prov = json.loads(run(["info", str(f), "--json"]).stdout)["provenance"]
    assert prov["complete"] is False and prov["stopped"] == "terminated by SIGTERM"


# ----------------------------------------------------------------------------- locks
def test_a_fifo_where_the_lock_file_goes_is_one_clear_line(tmp_path):
    """A FIFO at `.F.lock` (a stray mkfifo): `contin trace bratu -o F` said only 'Error: Invalid
    argument' (ftruncate of the FIFO).  Now it names the lock file and what to do; no F, the FIFO kept."""
    import os
    import stat

    lock = tmp_path / ".b.h5.lock"
    os.mkfifo(lock)
    line = one_error(run(["trace", "bratu", "-q", "-o", str(tmp_path / "b.h5")]))
    assert f"the lock file '{lock}' is not a regular file" in line and "remove it" in line
    assert not (tmp_path / "b.h5").exists() and stat.S_ISFIFO(os.lstat(lock).st_mode)


# ----------------------------------------------------------------------------- second-parameter bounds
def test_a_hopf_curve_that_leaves_through_the_bound_it_starts_on_ends_there(tmp_path):
    """`contin continue ab.h5 --from HB1 --free B --bounds B=14:20` (B = 14 at HB1, on the lower
    bound): the half leaving through B = 14 shows no sign change there, went down to B = 10.5 (its
    GH at B = 11.02 and LP at B = 11.25 stored, below the bound) and was cut only where it came back
    up through B = 14, exit 0.  Now it ends at its first point beyond the bound (here its start), and
    every stored point is a Hopf point of the CSTR with 14 <= B <= 20 (tr J = 0, det J > 0)."""
    from contin.restart import rebuild_problem

    src, out = tmp_path / "ab.h5", tmp_path / "hb.h5"
    assert run(["trace", "ab", "-q", "-o", str(src)]).exit_code == 0
    res = run(["continue", str(src), "--from", "HB1", "--free", "B", "--bounds", "B=14:20", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (curve,), meta = io.load(out)
    B = curve.params["B"]
    assert B.min() >= 14.0 - 1e-9 and B.max() == pytest.approx(20.0, abs=1e-9)
    assert not curve.points("GH") and not curve.points("LP")
    problem = rebuild_problem({**meta, "path": str(src)})
    for i in range(len(curve)):
        p = {**meta["parameters"], **{k: float(v[i]) for k, v in curve.params.items()}}
        jac = problem.jacobian(curve.states[i, :2], p)  # the CSTR's two unknowns lead the augmented state
        jac = np.asarray(jac.todense() if hasattr(jac, "todense") else jac)
        assert jac.shape == (2, 2)
        assert abs(np.trace(jac)) < 1e-8 * np.abs(jac).max() and np.linalg.det(jac) > 0


# ----------------------------------------------------------------------------- accuracy
def test_the_accuracy_table_shows_no_nan():
    """`contin accuracy bratu --grids 8,16`: the table's rel.error of the reference run and the order
    of each first grid read 'nan' (allen-cahn: 15 cells).  Now '-'; the numbers are unchanged: fd2's
    order between N = 8 and 16 is 2 (its truncation error), to 0.1."""
    res = run(["accuracy", "bratu", "--grids", "8,16", "--methods", "cheb,fd2"])
    assert res.exit_code == 0, res.stderr
    assert "nan" not in res.stderr
    rows = [ln.split() for ln in res.stderr.splitlines() if ln.startswith("0/LP1 ")]
    by = {(r[1], r[2]): r for r in rows}
    assert by[("cheb", "16")][4:6] == ["-", "-"]  # the reference: no error, no order
    assert by[("fd2", "8")][5] == "-" and float(by[("fd2", "16")][5]) == pytest.approx(2.0, abs=0.1)


def test_the_accuracy_heartbeat_names_the_run_in_progress(monkeypatch):
    """With stderr not a terminal, `contin accuracy` prints a heartbeat; it said 'running: started'
    throughout (the run lines did not reach it).  Now it repeats the run in progress."""
    import time

    import contin.accuracy as acc

    real = acc.run_accuracy

    def slow(*args, progress=None, **kwargs):
        def paced(message):
            progress(message)
            time.sleep(0.3)  # a few heartbeats per run

        return real(*args, progress=paced, **kwargs)

    monkeypatch.setattr(acc, "run_accuracy", slow)
    monkeypatch.setenv("CONTIN_PROGRESS_SECONDS", "0.05")
    res = run(["accuracy", "bratu", "--grids", "8,16", "--methods", "cheb"])
    assert res.exit_code == 0, res.stderr
    beats = [ln.split("] ", 1)[1] for ln in res.stderr.splitlines() if "] running: " in ln]
    named = [i for i, b in enumerate(beats) if b != "running: started"]
    assert named, beats  # ('started' only before the first run begins)
    assert set(beats[named[0]:]) <= {"running: bratu: cheb N=8", "running: bratu: cheb N=16"}, beats


# ----------------------------------------------------------------------------- branches handed over together
def test_a_stop_keeps_every_branch_a_scene_hands_over_at_its_end(tmp_path, monkeypatch):
    """`contin trace gravity -o F` + Ctrl-C: the scene traces all its branches (problems.couette.
    gravity.discover), then hands them over in one loop; the first one handed over after the stop
    raised the interrupt, so F kept that one only and lost the others finished before the Ctrl-C.
    Now the branches handed over are stored up to the one the stop cut short (and that one)."""
    from types import SimpleNamespace

    import problems.couette.gravity_scenes as gs
    from contin.cancel import CTRL_C, ENDS_AT_LAST_POINT, request_stop
    from tests.cli_fixture_scenes import toy_branches

    def discover(pb, params, settings, progress=None):
        done = toy_branches(1.0, 3)
        done[2].status, done[2].message = "MX", CTRL_C + ENDS_AT_LAST_POINT  # the branch in progress
        request_stop()  # the Ctrl-C came while branch 2 was traced
        return SimpleNamespace(branches=done)

    monkeypatch.setattr(gs, "discover", discover)
    out = tmp_path / "g.h5"
    res = run(["trace", "gravity", "--grid", "16", "--no-stability", "-o", str(out)])
    assert res.exit_code == 130, res.stderr
    kept, meta = io.load(out)
    assert meta["stopped"] == "interrupted" and [len(b) for b in kept] == [len(b) for b in toy_branches(1.0, 3)]
    assert [b.status for b in kept] == ["EP", "EP", "MX"]
