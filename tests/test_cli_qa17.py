"""Robustness sweep, round 5 (session 16, qa17): the leftovers of qa16 (Ctrl-C in `contin accuracy`
and during argument parsing, codimension-2 points on a bound, the first Ctrl-C's wait) and what
session 16 added (ZH/HH switching, the stored l2 at GH, the adaptive non-local scenes, partial
branches of interrupted runs).

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

import pytest

from contin.cli import main


from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)


def test_ctrl_c_while_click_parses_the_arguments_is_one_error_line(monkeypatch):
    """Ctrl-C while click parsed the group's arguments (before any command ran) printed click's
    'Aborted!' and exit 1 (bad input's code) instead of `Error: interrupted (Ctrl-C)`, exit 130."""
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(type(main), "parse_args", interrupted)
    res = run(["info", "x.h5"])
    assert res.exit_code == 130 and res.stderr == "Error: interrupted (Ctrl-C)\n", res.stderr


@pytest.mark.parametrize("stop, code, reason", [(KeyboardInterrupt, 130, "interrupted (Ctrl-C)"),
                                                ("Terminated", 143, "terminated by SIGTERM")])
def test_an_interrupted_accuracy_run_keeps_its_finished_rows(tmp_path, monkeypatch, stop, code, reason):
    """`contin accuracy bratu -o DIR` stopped by Ctrl-C (SIGTERM) after some runs wrote nothing:
    `Error: interrupted (Ctrl-C)`, exit 130, every finished run lost.  Now the finished runs' rows
    are written (atomically) marked incomplete, with one note line."""
    import json

    import contin.accuracy as acc
    from contin.cli._runctl import Terminated

    exc = Terminated if stop == "Terminated" else stop
    real, calls = acc.measure, []

    def measure(*args, **kwargs):
        calls.append(args[2:4])
        if len(calls) == 3:
            raise exc()
        return real(*args, **kwargs)

    monkeypatch.setattr(acc, "measure", measure)
    res = run(["accuracy", "bratu", "--methods", "cheb", "--grids", "16,24,32", "--no-memory", "--no-plots",
               "-o", str(tmp_path)])
    assert res.exit_code == code and one_error(res) == f"Error: {reason}", res.stderr
    notes = [ln for ln in res.stderr.splitlines() if ln.startswith("note:")]
    assert notes == [f"note: {reason}: 2 of 3 runs finished; their rows are saved in {tmp_path / 'accuracy_bratu.csv'} "
                     "(marked incomplete, reference cheb N=24)"], res.stderr
    lines = (tmp_path / "accuracy_bratu.csv").read_text().splitlines()
    assert [ln.split(",")[1:3] for ln in lines[1:-1]] == [["cheb", "16"], ["cheb", "24"]], lines
    assert lines[-1].startswith(f"#incomplete,{reason}: 2 of 3 runs finished"), lines
    doc = json.loads((tmp_path / "accuracy_bratu.json").read_text())
    assert doc["incomplete"] == f"{reason}: 2 of 3 runs finished" and len(doc["runs"]) == 2
    assert not list(tmp_path.glob("*.tmp*"))


@pytest.fixture
def codim2_scenes(monkeypatch):
    from pathlib import Path

    monkeypatch.syspath_prepend(str(Path(__file__).parent))
    monkeypatch.setenv("CONTIN_SCENES", "codim2_fixture_scenes:SCENES")


@pytest.mark.parametrize("bounds", [("a=-2:2", "b=-0.5:0.6666666666666666"), ("a=-2:2", "b=-0.5:0.6666666666666667"),
                                    ("a=-0.7777777777777778:2", "b=-0.5:1")])
def test_a_zero_hopf_point_on_a_bound_is_reported(tmp_path, codim2_scenes, bounds):
    """`contin continue run.h5 --from LP2 --free b --bounds b=-0.5:0.6666666666666666` (the ZH of
    fold-hopf at (a, b) = (-7/9, 2/3) on the bound of b; also a = -7/9 on the bound of a, which
    the tracer lands on) reported no ZH, exit 0, while a bound 1e-12 further out did: the ZH
    located 1e-12 beyond the landed point was cut (b), its test function kept its sign at the
    landed point (a).  A point on the bound is in the range."""
    import json

    run(["trace", "fold-hopf", "--no-stability", "-q", "-o", str(tmp_path / "run.h5")])
    res = run(["continue", str(tmp_path / "run.h5"), "--from", "LP2", "--free", "b", "--bounds", bounds[0],
               "--bounds", bounds[1], "-o", str(tmp_path / "f.h5"), "--json"])
    assert res.exit_code == 0, res.stderr
    zh = [sp for sp in json.loads(res.stdout)["special_points"] if sp["type"] == "ZH"]
    assert len(zh) == 1, res.stderr
    assert zh[0]["params"]["a"] == pytest.approx(-7 / 9, abs=1e-10) and zh[0]["params"]["b"] == pytest.approx(2 / 3, abs=1e-10)


def test_a_double_hopf_point_on_the_bound_starts_its_curve(tmp_path, codim2_scenes):
    """`contin continue h.h5 --from HH2 --free b --bounds b=0.30277563773199456:0.8` (the bound at
    HH2's b, to rounding) said `Error: start value b=0.302776 of HH2 lies outside its bounds
    (0.302776, 0.8)`: the located HH lay 1e-16 below the bound.  A start on a bound is in the range
    (the bound moves onto it); one really outside is still refused, with 10 digits."""
    from contin import io

    run(["trace", "two-oscillators", "--no-stability", "-q", "-o", str(tmp_path / "osc.h5")])
    res = run(["continue", str(tmp_path / "osc.h5"), "--from", "HB1", "--free", "b", "--bounds", "a=-1:2",
               "--bounds", "b=-0.2:0.8", "-o", str(tmp_path / "h.h5")])
    assert res.exit_code == 0, res.stderr
    (curve,), _ = io.load(tmp_path / "h.h5")
    (hh,) = curve.points("HH")
    b = float(hh.params["b"])
    res = run(["continue", str(tmp_path / "h.h5"), "--from", hh.name, "--free", "b", "--bounds", "a=-1:2",
               "--bounds", f"b={b * (1 + 1e-13)!r}:0.8", "-o", str(tmp_path / "o.h5")])
    assert res.exit_code == 0, res.stderr
    (other,), _ = io.load(tmp_path / "o.h5")
    assert other.params["b"].min() >= b and other.params["b"].max() == pytest.approx(0.8, abs=1e-12)
    res = run(["continue", str(tmp_path / "h.h5"), "--from", hh.name, "--free", "b", "--bounds", "a=-1:2",
               "--bounds", "b=0.3028:0.8", "-o", str(tmp_path / "x.h5")])
    assert one_error(res) == f"Error: start value b={b:.10g} of {hh.name} lies outside its bounds (0.3028, 0.8)"


def test_the_first_ctrl_c_does_not_wait_for_a_stability_pass():
    """`contin trace gravity` + Ctrl-C after 4 s took 35 s to end: the first Ctrl-C ends the branch
    at its last point, but the scene's stability pass then ran over all of its 265 points.  The
    stability loops (contin.stability.stability_pass / growth_columns, the gPCF operator's
    pitchfork._stability_columns) ask contin.cancel.stop_requested() between points; a stopped
    pass leaves the branch without stability (a --resume computes it)."""
    from pathlib import Path

    from contin import io
    from contin.cancel import request_stop, stop_on_sigint
    from contin.stability import growth_columns, stability_pass
    from problems.couette import pitchfork as pf
    from problems.couette.scenes import problem_factory
    from problems.demo import AB

    (branch, *_), meta = io.load(Path(__file__).parents[1] / "results" / "pitchfork.h5")
    problem = problem_factory(meta["parameters"], meta["discretization"])
    branch.stable = branch.n_unstable = branch.eigenvalues = None
    (ab,), ab_meta = io.load(Path(__file__).parents[1] / "results" / "ab.h5")
    ab.stable = ab.n_unstable = ab.eigenvalues = None
    with stop_on_sigint():
        request_stop()
        assert pf.stability(problem, branch, meta["parameters"]) == [] and branch.n_unstable is None
        assert pf.growth_rates(problem, branch, meta["parameters"], 0.5) is None
        stability_pass(AB(), ab, ab_meta["parameters"])
        assert ab.n_unstable is None
        assert growth_columns(AB(), ab, ab_meta["parameters"], kx=0.5) == {}


def test_the_first_ctrl_c_ends_the_disks_criticality_sweep():
    """`contin trace disks-criticality` + Ctrl-C after 3 s ended 41 s later: the scene's sweep over
    (e, nu) ran on (its normal-form computations trace nothing, so no step saw the stop).  It asks
    contin.cancel.stop_requested() between samples; the CLI then exits 130 (143)."""
    import time

    from contin.cancel import request_stop, stop_on_sigint
    from contin.scene import SceneRequest
    from problems.disks.scenes import run_criticality

    t0 = time.perf_counter()
    with stop_on_sigint():
        request_stop()
        result = run_criticality(SceneRequest(params={}))
    assert result.extra["curves"] == {} and time.perf_counter() - t0 < 5


STOP_AFTER_FIRST_BRANCH = (
    "import sys\n"
    "from contin.cancel import request_stop\n"
    "from contin.cli import main\n"
    "import contin.scene as s\n"
    "real = s.SceneRequest.finished\n"
    "def finished(self, branch):\n"
    "    real(self, branch)\n"
    "    request_stop()\n"
    "s.SceneRequest.finished = finished\n"
    "main.main(sys.argv[1:], prog_name='contin')\n")


def interrupted_run(*args: str) -> None:
    """`contin trace ARGS` stopped (as by the first Ctrl-C) when its first branch is finished."""
    import os
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", STOP_AFTER_FIRST_BRANCH, "trace", *args], capture_output=True,
                          text=True, timeout=120, env={**os.environ, "CONTIN_SCENES": ""})
    assert proc.returncode == 130, proc.stderr


def test_resume_of_an_interrupted_run_keeps_its_discretization(tmp_path):
    """`contin trace jj-walls --grid 32 -o F` interrupted, then `--resume F --grid 64` (or `--method
    fd4`) was accepted (the checkpoint recorded 'grid', the check read 'intervals'), ended with
    `Error: matmul: dimension mismatch ...` and relabelled F as cheb 64; `--resume F` alone went on
    adaptively (states of 244 unknowns beside the stored 100, F saying cheb 32)."""
    from contin import io

    f = tmp_path / "j.h5"
    interrupted_run("jj-walls", "--grid", "32", "--no-stability", "-q", "-o", str(f))
    err = one_error(run(["trace", "jj-walls", "--resume", str(f), "--grid", "64", "--no-stability", "-q"]))
    assert err == f"Error: '{f}' was computed with --grid 32, not 64; resume with the same discretization (or start a new run)"
    err = one_error(run(["trace", "jj-walls", "--resume", str(f), "--method", "fd4", "--no-stability", "-q"]))
    assert "was computed without --method (the scene's own discretization), not --method fd4" in err, err
    res = run(["trace", "jj-walls", "--resume", str(f), "--no-stability", "-q"])
    assert "Traceback" not in res.stderr and res.exit_code in (0, 3), res.stderr
    branches, meta = io.load(f)
    assert meta["complete"] and meta["discretization"]["intervals"] == 32
    assert len(branches) > 2 and all(b.states.shape[1] == 100 for b in branches)  # cheb 32: 3 x 33 + 1 unknowns


def test_profiles_of_an_interrupted_run_say_why_there_are_none(tmp_path):
    """`contin profiles F --at ell=5` of a nonlocal-shear run interrupted by Ctrl-C said `Error: F
    stores no solution profiles`, as for a scene that has none: the profiles are written at the
    end of a run.  It now says the run was interrupted before they were written, and --resume."""
    import subprocess
    import sys

    out = tmp_path / "n.h5"
    code = STOP_AFTER_FIRST_BRANCH
    proc = subprocess.run([sys.executable, "-c", code, "trace", "nonlocal-shear", "--no-stability", "-q",
                           "--tol", "1e-6", "--max-grid", "64", "-o", str(out)],
                          capture_output=True, text=True, timeout=120, env={**__import__("os").environ, "CONTIN_SCENES": ""})
    assert proc.returncode == 130, proc.stderr
    res = run(["profiles", str(out), "--at", "ell=5", "-o", str(tmp_path / "p.png")])
    assert one_error(res) == (f"Error: {out} stores no solution profiles: its run was interrupted before they were "
                              "written (at the end of a run); continue it with --resume")


def test_an_interrupt_inside_the_lock_release_does_not_close_it_twice(tmp_path, monkeypatch):
    """A Ctrl-C at the very end of `contin trace bp-curve -o F` (inside the output lock's release,
    after its descriptor was closed) ended with `Error: Bad file descriptor`, exit 1: the lock
    still held the closed descriptor and the interrupt handler's release closed it again."""
    import os

    from contin import atomic

    lock = atomic.OutputLock(tmp_path / "x.h5").acquire()
    real_close = os.close

    def close_then_interrupt(fd):
        real_close(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic.os, "close", close_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        lock.release()
    monkeypatch.setattr(atomic.os, "close", real_close)
    lock.release()  # the interrupt handler's release: OSError [Errno 9] Bad file descriptor before
    assert lock.fd is None


def test_an_interrupted_accuracy_run_without_output_shows_its_finished_rows(monkeypatch):
    """`contin accuracy bratu` (no -o) + Ctrl-C printed only `Error: interrupted (Ctrl-C)`: the
    finished runs' table is shown, with one note line."""
    import contin.accuracy as acc

    real, calls = acc.measure, []

    def measure(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(acc, "measure", measure)
    res = run(["accuracy", "bratu", "--methods", "cheb", "--grids", "16,24,32", "--no-memory", "--no-plots"])
    assert res.exit_code == 130 and one_error(res) == "Error: interrupted (Ctrl-C)"
    assert "reference: cheb N=24" in res.stderr and "0/LP1      cheb    16" in res.stderr, res.stderr
    assert ("note: interrupted (Ctrl-C): 2 of 3 runs finished; their rows are shown above; no file is written "
            "(no -o DIR)") in res.stderr


def test_a_double_hopf_point_whose_other_pair_is_its_own_is_refused(tmp_path, codim2_scenes):
    """`contin continue h.h5 --from HH2 --free b` of a file whose HH2 has omega2 = omega (damaged)
    traced the Hopf curve HH2 lies on again and called it 'the Hopf curve from HH2', exit 0."""
    import h5py

    osc, h = tmp_path / "osc.h5", tmp_path / "h.h5"
    run(["trace", "two-oscillators", "--no-stability", "-q", "-o", str(osc)])
    box = ["--bounds", "a=-1:2", "--bounds", "b=-0.2:0.8"]
    assert run(["continue", str(osc), "--from", "HB1", "--free", "b", *box, "-o", str(h)]).exit_code == 0
    with h5py.File(h, "r+") as f:
        sp = f["special_points"]
        i = [t.decode() if isinstance(t, bytes) else t for t in sp["type"][:]].index("HH")
        sp["data"]["omega2"][i] = sp["data"]["omega"][i]
    res = run(["continue", str(h), "--from", "HH2", "--free", "b", *box, "-o", str(tmp_path / "o.h5")])
    assert one_error(res).startswith("Error: HH2's omega2 = 1 is the frequency of the Hopf curve it lies on (omega = 1)")
    assert not (tmp_path / "o.h5").exists()


@pytest.mark.parametrize("omega", [3.0, 1e-8])
def test_a_zero_hopf_point_with_a_wrong_omega(tmp_path, codim2_scenes, omega):
    """`contin continue f.h5 --from ZH2 --free b` of a file whose ZH2 omega was damaged: with 3 the
    Hopf curve (omega 1) was found but its start was shown as 'omega=3'; with 1e-8 the start failed
    and the command ended `Error: attempt to get argmin of an empty sequence`."""
    import json

    import h5py

    run(["trace", "fold-hopf", "--no-stability", "-q", "-o", str(tmp_path / "run.h5")])
    box = ["--bounds", "a=-2:2", "--bounds", "b=-0.5:1"]
    f = tmp_path / "f.h5"
    assert run(["continue", str(tmp_path / "run.h5"), "--from", "LP2", "--free", "b", *box, "-o", str(f)]).exit_code == 0
    with h5py.File(f, "r+") as h:
        sp = h["special_points"]
        sp["data"]["omega"][[t.decode() if isinstance(t, bytes) else t for t in sp["type"][:]].index("ZH")] = omega
    res = run(["continue", str(f), "--from", "ZH2", "--free", "b", *box, "-o", str(tmp_path / "o.h5"), "--json"])
    if omega == 3.0:
        assert res.exit_code == 0, res.stderr
        (start,) = [sp for sp in json.loads(res.stdout)["special_points"] if sp["type"] == "ZH"]
        assert start["data"]["omega"] == pytest.approx(1.0, abs=1e-10)
    else:
        assert one_error(res).startswith("Error: the Hopf curve from ZH2 did not start: "), res.stderr
