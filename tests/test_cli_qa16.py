"""Robustness sweep, round 4 (session 16, qa16): the leftovers of qa15 (Ctrl-C during ``trace``
lost the branch in progress; a user zero at the start value) and the features of session 15
(``contin export --auto``, ``contin continue --from BT``, the ``ab`` scene, two-parameter files).

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from contin import io

HERE = Path(__file__).resolve().parent
FIXTURE_ENV = {**os.environ, "CONTIN_SCENES": "cli_fixture_scenes:SCENES",
               "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
               "CONTIN_PROGRESS_SECONDS": "0"}


from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)
from tests.signals import signalled  # noqa: E402


def _branches(path: Path) -> list:
    try:
        return io.load(path)[0]
    except (FileNotFoundError, io.FileFormatError):
        return []


def _signalled(args: list[str], sig: int, ready, after: float) -> tuple[int, str]:
    """:func:`tests.signals.signalled` on the fixture scenes."""
    return signalled(args, sig, ready, env=FIXTURE_ENV, after=after)


@pytest.mark.parametrize("sig, code, reason, stopped", [(signal.SIGINT, 130, "interrupted (Ctrl-C)", "interrupted"),
                                                        (signal.SIGTERM, 143, "terminated by SIGTERM",
                                                         "terminated by SIGTERM")])
def test_ctrl_c_during_trace_keeps_the_branch_in_progress_and_resume_retraces_it(tmp_path, sig, code, reason,
                                                                                  stopped):
    """`contin trace SCENE -o F` + Ctrl-C (or SIGTERM) saved the finished branches only: the points
    of the branch being traced were lost.  Now the first signal ends that branch at its last point
    (MX "interrupted (Ctrl-C): ..."), it is saved and named in the note, exit 130 / 143; and
    `trace --resume F` traces it again (it reuses the finished branch 0 only)."""
    out = tmp_path / "run.h5"
    rc, stderr = _signalled(["trace", "slow-bratu", "-s", "delay=0.01", "-s", "steps=400", "-o", str(out)], sig,
                            lambda: [b.id for b in _branches(out)] == ["0"], after=1.5)
    assert rc == code, stderr
    errors = [ln for ln in stderr.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1 and reason.split(" (")[0] in errors[0] and "Traceback" not in stderr, stderr
    branches, meta = io.load(out)
    assert [b.id for b in branches] == ["0", "1"] and meta["complete"] is False and meta["stopped"] == stopped
    assert branches[0].status == "EP"
    partial = branches[1]
    assert partial.status == "MX" and partial.message.startswith(reason), partial.message
    assert 3 < len(partial) < 400
    assert (f"note: 1 finished branch(es) and branch 1 up to its last point ({len(partial)} points, {reason}; "
            f"--resume traces it again) are saved in {out} (continue with --resume {out})") in stderr, stderr
    again = subprocess.run([sys.executable, "-m", "contin", "trace", "slow-bratu", "-s", "steps=400", "--resume",
                            str(out), "-q"], capture_output=True, text=True, env=FIXTURE_ENV, timeout=120)
    assert again.returncode == 0, again.stderr
    branches, meta = io.load(out)
    assert meta["complete"] and meta["extra"]["reused"] == ["0"]
    assert branches[1].status == "EP" and len(branches[1]) > len(partial)


def test_a_user_zero_at_the_start_value_labels_the_start_point(tmp_path):
    """`contin trace bratu --uz lam=0` (bratu starts at lam = 0) reported no UZ: p - value is 0 at
    the start, so no step crosses it.  Now the start point is labelled UZ (note 'at the start
    point'), once; it does not count for --stop-at (UZ1 still stops at the first UZ after it)."""
    out = tmp_path / "b.h5"
    res = run(["trace", "bratu", "--uz", "lam=0,2", "--no-stability", "--max-steps", "30", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (b,), _ = io.load(out)
    uz = [sp for sp in b.special_points if sp.type == "UZ"]
    assert [(sp.index, sp.data["value"]) for sp in uz][:2] == [(0, 0.0), (uz[1].index, 2.0)] and uz[1].index > 0
    assert "at the start point" in uz[0].note and sum(sp.data["value"] == 0.0 for sp in uz) == 1
    res = run(["trace", "bratu", "--uz", "lam=0,2", "--stop-at", "UZ1", "--no-stability", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (b,), _ = io.load(out)
    values = [sp.data["value"] for sp in b.special_points if sp.type == "UZ"]
    assert b.message == "stopped after UZ1 (stop_at)" and values == [0.0, 2.0] and 2.0 < b.params["lam"][-1] < 2.5


def test_a_user_zero_at_the_start_of_a_branch_traced_both_ways_is_labelled_once():
    """trace_both (lorenz and other scenes trace both ways from the start): each half labels its start
    point UZ; the join kept both copies (the reversed half's at index off - 1)."""
    from contin.continuation import trace_both
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import Bratu

    pb = Bratu("cheb", 8)
    opts = ContinuationOptions(bounds={"lam": (0.5, 2.0)}, max_steps=100, step=StepOptions(ds=0.05, ds_max=0.05),
                               user_zeros={"lam": [1.0, 1.5]})
    b = trace_both(pb, pb.initial(), {"lam": 1.0}, "lam", opts)
    assert [sp.data["value"] for sp in b.special_points if sp.type == "UZ"] == [1.0, 1.5]


# ----------------------------------------------------------------------------- contin export --auto
AB_HOPF = Path(__file__).resolve().parents[1] / "results" / "ab_hopf.h5"


@pytest.mark.parametrize("par, expect", [
    ("D=1,B=2,beta=3,Q=4", "--par names 'Q', which the run does not have; its parameters are D, B, beta"),
    ("D=1,B=2,beta=3,D=4", "--par gives 'D' twice (D=1, D=4)"),
    ("D=1,B=2,beta=3000000", "AUTO's PAR indices are small (at most 1000 here)")])
def test_export_par_refuses_unknown_repeated_and_huge_indices(tmp_path, par, expect):
    """`contin export ab_hopf.h5 --auto x --par D=1,B=2,beta=3,Q=4` ignored the unknown Q (a typo
    went unnoticed), `D=1,...,D=4` kept D=4 silently, and `beta=3000000` wrote a 296 MB s.x
    (every block holds NPAR values): each is one Error line now, before anything is written."""
    res = run(["export", str(AB_HOPF), "--auto", "x", "-d", str(tmp_path), "--par", par])
    assert expect in one_error(res)
    assert not list(tmp_path.iterdir())


def test_export_l2_norm_of_huge_states_is_finite_and_fixed_width(tmp_path):
    """A state with entries near 1e300 (the file format allows any finite value) was exported with
    L2-NORM 'INF' (np.linalg.norm overflowed, a RuntimeWarning on stderr), not a 19-character
    number; now the norm is scaled (math.hypot)."""
    import warnings

    from contin.autoformat import write_auto

    (branch,), _ = io.load(AB_HOPF)
    branch.states[1, :2] = [1e300, -1e300]  # (point 0 is the EP: its row shows the EP's own state)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_auto([branch], "big", tmp_path)
    rows = [ln for ln in (tmp_path / "b.big").read_text().splitlines() if not ln.startswith("   0")]
    first = rows[1]
    assert "INF" not in first.upper() and len(first) == 19 + 19 * 6
    assert float(first[19 + 19:19 + 38]) == pytest.approx(2**0.5 * 1e300, rel=1e-10)


def test_export_checks_both_outputs_before_writing_either(tmp_path):
    """`contin export ab_hopf.h5 --auto w -d D` with D/s.w a symbolic link wrote a new D/b.w, then
    refused s.w: a half export (a new b.w beside no or an old s.w).  Both targets are checked first."""
    (tmp_path / "s.w").symlink_to("/dev/null")
    res = run(["export", str(AB_HOPF), "--auto", "w", "-d", str(tmp_path)])
    assert "is a symbolic link" in one_error(res)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.w"]


# ----------------------------------------------------------------------------- contin continue --from
RESULTS = Path(__file__).resolve().parents[1] / "results"


@pytest.mark.parametrize("file, kind", [("ab_hopf.h5", "hopf curve HB1.B"), ("ab_fold.h5", "fold curve BT2.B")])
def test_continue_from_an_lp_of_a_curve_says_what_it_is(tmp_path, file, kind):
    """`contin continue results/ab_hopf.h5 --from LP4 --free B` (LP4: the extremum of D on the Hopf
    curve) ended `Error: too many values to unpack (expected 2)`: the curve's augmented state went
    to the problem's Jacobian.  Now one line says what the point is and what can be continued."""
    res = run(["continue", str(RESULTS / file), "--from", "LP4", "--free", "B", "-o", str(tmp_path / "c.h5")])
    err = one_error(res)
    assert f"LP4 lies on the {kind} in (D, B) (extremum of D): of a curve's points only a BT, ZH or HH starts" in err, err
    assert not (tmp_path / "c.h5").exists()


# ----------------------------------------------------------------------------- tiny parameter ranges
def test_a_bound_close_to_the_start_is_reached_not_assumed(tmp_path):
    """`contin trace ab -s D_max=1e-12` stored one point, D = 0, with EP 'reached bound D=1e-12',
    exit 0: the tracer took any bound within 1e-12 (absolute) of the last point as reached.  The
    test is relative now: the branch lands on D = 1e-12.  The core side on Bratu (non-granular)."""
    from contin.continuation import trace
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import Bratu

    out = tmp_path / "ab.h5"
    res = run(["trace", "ab", "-s", "D_max=1e-12", "--no-stability", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    (b,), _ = io.load(out)
    assert list(b.params["D"]) == [0.0, 1e-12] and b.message == "reached bound D=1e-12"
    pb = Bratu("cheb", 8)
    for hi in (1e-12, 1e-300):
        opts = ContinuationOptions(bounds={"lam": (0.0, hi)}, max_steps=20, step=StepOptions(ds=0.05, ds_max=0.05))
        b = trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)
        assert list(b.params["lam"]) == [0.0, hi] and b.message == f"reached bound lam={hi:g}"


# ----------------------------------------------------------------------------- damaged two-parameter files
def _damaged(tmp_path: Path, src: str, edit) -> Path:
    import shutil

    import h5py

    out = tmp_path / f"damaged_{src}"
    shutil.copy(RESULTS / src, out)
    with h5py.File(out, "r+") as f:
        edit(f, f"branches/{'HB1.B' if 'hopf' in src else 'BT2.B'}")
    return out


@pytest.mark.parametrize("src", ["ab_hopf.h5", "ab_fold.h5"])
def test_a_curve_with_one_free_parameter_is_a_damaged_file(tmp_path, src):
    """A copy of ab_hopf.h5 / ab_fold.h5 whose curve names one free parameter (attribute free = D)
    read as a curve: `contin stability F --at D=0.1` ended `Error: too many values to unpack
    (expected 2)`.  The reader refuses it, naming the attribute."""
    import numpy as np

    f = _damaged(tmp_path, src, lambda h, b: h[b].attrs.__setitem__("free", np.array(["D"], dtype=object)))
    for args in (["info", str(f)], ["stability", str(f), "--at", "D=0.1"]):
        err = one_error(run(args))
        assert "is damaged: branch group branches/" in err and "free parameters (attribute free) are D" in err, err


def test_a_bt_whose_curve_kind_was_edited_is_one_clear_error(tmp_path):
    """ab_fold.h5 with the curve's kind edited to hopf-curve (its 5-entry states read as a Hopf
    curve of n = 1): `contin continue F --from BT2 --free B` ended `Error: not enough values to
    unpack (expected 2, got 1)` in ab's Jacobian.  The BT's base state is checked against the
    problem's residual first."""
    f = _damaged(tmp_path, "ab_fold.h5", lambda h, b: h[b].attrs.__setitem__("kind", "hopf-curve"))
    res = run(["continue", str(f), "--from", "BT2", "--free", "B", "--max-steps", "5", "-o", str(tmp_path / "c.h5")])
    err = one_error(res)
    assert "the state of BT2 (5 entries) is not a hopf-curve state of this problem" in err, err


def test_a_joined_branch_with_an_interrupted_half_is_partial():
    """A branch traced both ways from its start (contin.continuation.join: message "backward: ...;
    forward: ...") whose second half a Ctrl-C stopped was not recognised as partial (the check read
    the start of the message), so `trace --resume` would have reused it as finished."""
    from types import SimpleNamespace

    from contin.cancel import CTRL_C, ENDS_AT_LAST_POINT, SIGTERM, is_stopped_branch, stopped_by

    joined = SimpleNamespace(status="MX", message=f"backward: reached bound rho=1.5; forward: {SIGTERM}{ENDS_AT_LAST_POINT}")
    assert is_stopped_branch(joined) and stopped_by(joined) == SIGTERM
    assert stopped_by(SimpleNamespace(status="MX", message=CTRL_C + ENDS_AT_LAST_POINT)) == CTRL_C
    assert not is_stopped_branch(SimpleNamespace(status="EP", message="reached bound rho=40"))
    assert not is_stopped_branch(SimpleNamespace(status="MX", message="step failed at lam=1 (interrupted (Ctrl-C))"))


def test_sigterm_during_continue_keeps_the_curve_computed_so_far(tmp_path):
    """`contin continue` kept its curve on Ctrl-C (qa14) but SIGTERM still lost all of it (the
    command group's handler raised at once).  Now the first SIGTERM ends the curve at its last point
    too: saved (MX 'terminated by SIGTERM: ...'), `Error: terminated by SIGTERM`, exit 143."""
    src, out = tmp_path / "sb.h5", tmp_path / "curve.h5"
    assert run(["trace", "stretched-bratu", "--grid", "32", "--no-stability", "-q", "-o", str(src)]).exit_code in (0, 3)
    rc, stderr = _signalled(["continue", str(src), "--from", "LP1", "--free", "a", "--bounds", "a=-0.5:3", "--ds",
                             "0.0005", "--ds-max", "0.0005", "--max-steps", "100000", "-o", str(out)], signal.SIGTERM,
                            lambda: (tmp_path / ".curve.h5.lock").exists(), after=1.5)
    errors = [ln for ln in stderr.splitlines() if ln.startswith("Error: ")]
    assert rc == 143 and errors == ["Error: terminated by SIGTERM"], stderr
    assert "note: the curve computed before SIGTERM (" in stderr and f"is saved in {out}" in stderr
    (curve,), meta = io.load(out)
    assert curve.status == "MX" and "terminated by SIGTERM: the branch ends at its last point" in curve.message
    assert len(curve) > 10
    assert meta["complete"] is False and meta["stopped"] == "terminated by SIGTERM"  # (qa18: complete=True)


def test_ctrl_c_in_the_stability_pass_after_the_run_keeps_every_traced_branch(tmp_path):
    """`contin trace SCENE -o F` + Ctrl-C during the stability pass that follows the run (outside the
    run's handler): F held only the branches of the last checkpoint (branch 1 lost) and was not
    marked stopped.  Now every traced branch is saved, the note says so, the file reads as
    interrupted (exit 130)."""
    out = tmp_path / "run.h5"
    rc, stderr = _signalled(["trace", "slow-bratu-stab", "-s", "sdelay=0.2", "-o", str(out)], signal.SIGINT,
                            lambda: [b.id for b in _branches(out)] == ["0"], after=1.5)
    assert rc == 130, stderr
    assert f"note: 2 finished branch(es) are saved in {out} (continue with --resume {out})" in stderr, stderr
    branches, meta = io.load(out)
    assert [(b.id, len(b)) for b in branches] == [("0", 12), ("1", 41)]
    assert meta["complete"] is False and meta["stopped"] == "interrupted"


# ----------------------------------------------------------------------------- --resume of an unfinished file
def _in_progress_copy(tmp_path: Path, name: str, options: dict) -> Path:
    """A finished bratu file turned into what an interrupted run leaves: complete False, stopped
    'interrupted', and the options attribute as the writer holds it during the run (the command
    line's overrides, contin.cli.trace: H5Writer(options=overrides))."""
    import json
    import shutil

    import h5py

    src = tmp_path / "bratu_done.h5"
    if not src.exists():
        res = run(["trace", "bratu", "--tol", "1e-6", "--ds-max", "0.05", "--no-stability", "-q", "-o", str(src)])
        assert res.exit_code == 0, res.stderr
    out = tmp_path / name
    shutil.copy(src, out)
    with h5py.File(out, "r+") as f:
        f.attrs["options"] = json.dumps(options)
        f.attrs["complete"] = False
        f.attrs["stopped"] = "interrupted"
    return out


def test_resume_of_an_interrupted_run_checks_and_keeps_its_command_line_settings(tmp_path):
    """The file of an interrupted run holds the command line's overrides ({"ds_max": 0.05, "tol":
    1e-06}), which --resume read as a finished run's options: `trace bratu --resume F --ds-max 0.05`
    (the run's own value) was refused 'computed with --ds-max None', `--resume F --tol 1e-8` was
    accepted (the file then claimed tol 1e-8 for branches computed at 1e-6), and `--resume F` alone
    traced the rest with the scene's ds_max.  Now the overrides are compared and reused."""
    raw = {"ds_max": 0.05, "tol": 1e-06}
    f = _in_progress_copy(tmp_path, "a.h5", raw)
    res = run(["trace", "bratu", "--resume", str(f), "--ds-max", "0.05", "--no-stability", "-q"])
    assert res.exit_code == 0, res.stderr
    f = _in_progress_copy(tmp_path, "b.h5", raw)
    err = one_error(run(["trace", "bratu", "--resume", str(f), "--tol", "1e-8", "--no-stability", "-q"]))
    assert "was computed with --tol 1e-06, not 1e-08" in err, err
    f = _in_progress_copy(tmp_path, "c.h5", raw)
    err = one_error(run(["trace", "bratu", "--resume", str(f), "--ds-max", "0.1", "--no-stability", "-q"]))
    assert "was computed with --ds-max 0.05, not 0.1" in err, err
    f = _in_progress_copy(tmp_path, "d.h5", raw)
    res = run(["trace", "bratu", "--resume", str(f), "--no-stability", "-q"])
    assert res.exit_code == 0, res.stderr
    options = io.load(f)[1]["options"]
    assert options["adapt"]["tol"] == 1e-06 and options["step"]["ds_max"] == 0.05


def test_export_writes_a_bp_curve_with_its_base_state(tmp_path):
    """`contin export` of a `contin trace bp-curve` file wrote the BP curve's whole augmented state
    [u, phi, p2] as its solution (NDIM 201 for a problem of 100 unknowns, the L2-NORM of all of
    it): fold and Hopf curves were cut to u, BP curves (the same [u, phi, p2] layout) were not."""
    src = tmp_path / "bpc.h5"
    res = run(["trace", "bp-curve", "--no-stability", "-q", "-o", str(src)])
    assert res.exit_code == 0, res.stderr
    branches, _ = io.load(src)
    curve = next(b for b in branches if b.kind == "bp-curve")
    n = branches[0].states.shape[1]
    assert curve.states.shape[1] == 2 * n + 1
    res = run(["export", str(src), "--auto", "bpc", "-d", str(tmp_path)])
    assert res.exit_code == 0, res.stderr
    text = (tmp_path / "b.bpc").read_text()
    assert text.count(f"NDIM={n:4d}") == 2 and f"NDIM={2 * n + 1:4d}" not in text
    s_heads = [ln.split() for ln in (tmp_path / "s.bpc").read_text().splitlines() if len(ln.split()) == 16]
    assert s_heads and all(int(h[13]) == n for h in s_heads)  # NDIM of every labelled solution


# ----------------------------------------------------------------------------- ODE scenes (no discretization)
@pytest.mark.parametrize("args, expect", [
    (["trace", "ab", "--grid", "10"], "scene 'ab' is a system of ODEs without a discretization: --method and --grid"),
    (["trace", "lorenz", "--method", "cheb"], "scene 'lorenz' is a system of ODEs without a discretization"),
    (["accuracy", "ab", "--grids", "16,24", "--no-memory", "--no-plots"],
     "scene 'ab' is a system of ODEs without a discretization; accuracy compares discretizations")])
def test_discretization_options_on_an_ode_scene_are_refused(tmp_path, args, expect):
    """`contin trace ab --grid 10` (and lorenz --method cheb) ran, ignored the option and exited 0
    (the file's discretization attribute empty); `contin accuracy ab` printed a discretization
    study of an ODE, every 'grid' giving the same value.  One Error line each now
    (Scene.discretized = False), before computing."""
    out = tmp_path / "x.h5"
    res = run([*args, *(["-o", str(out)] if args[0] == "trace" else [])])
    assert expect in one_error(res)
    assert not out.exists()


def test_a_sweep_with_a_grid_on_an_ode_scene_is_refused(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nscene = "ab"\n[grid]\nB = [14.0, 15.0]\n[options]\ngrid = 16\n')
    res = run(["sweep", str(spec), "-o", str(tmp_path / "out")])
    assert "scene 'ab' is a system of ODEs without a discretization" in one_error(res)


def test_export_leaves_out_an_order_parameter_that_is_nan_everywhere(tmp_path):
    """A file whose phi column is NaN everywhere (the reader's "not computed") could not be exported
    at all: `Error: branch BT2.B: the order parameter of point 1 is not finite`.  The column is left
    out now, as for a branch without phi."""
    import numpy as np

    def nan_phi(h, b):
        data = h[f"{b}/phi"][...] * np.nan
        del h[f"{b}/phi"]
        h[f"{b}/phi"] = data

    f = _damaged(tmp_path, "ab_fold.h5", nan_phi)
    res = run(["export", str(f), "--auto", "nophi", "-d", str(tmp_path)])
    assert res.exit_code == 0, res.stderr
    header = next(ln for ln in (tmp_path / "b.nophi").read_text().splitlines() if "PT  TY  LAB" in ln)
    assert "phi" not in header and "PAR(2)" in header


def test_ctrl_c_while_the_command_line_loads_is_one_error_line():
    """Ctrl-C in the first ~0.2 s of `contin trace ...` (while contin.cli imports its commands) printed
    a KeyboardInterrupt traceback, exit -2; now `Error: interrupted (Ctrl-C)`, exit 130.  (The
    interrupt is raised by an import hook when contin.cli.verify is loaded.)"""
    code = ("import sys\n"
            "class Hook:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'contin.cli.verify':\n"
            "            raise KeyboardInterrupt\n"
            "sys.meta_path.insert(0, Hook())\n"
            "from contin.cli import main\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130 and proc.stderr == "Error: interrupted (Ctrl-C)\n", proc.stderr


def test_a_stop_before_the_first_step_of_a_curve_is_an_interrupt_not_a_failure():
    """Ctrl-C while `contin continue` set up its curve (before the first step) ended with `Error: the
    HB curve from HB1 did not start: ... interrupted (Ctrl-C) ...`, exit 1 (bad input's code):
    continue_point took the one-point curve for a failed start.  Now the stopped curve is returned
    (the command saves it and exits 130), as a stop later on does."""
    from contin.cancel import request_stop, stop_on_sigint
    from contin.options import ContinuationOptions
    from contin.twoparam import continue_point
    from problems.demo import AB

    (branch,), _ = io.load(RESULTS / "ab.h5")
    hb = next(sp for sp in branch.special_points if sp.name == "HB1")
    with stop_on_sigint() as stop:
        request_stop()
        curve = continue_point(AB(), branch, hb, "B", ContinuationOptions(bounds={"B": (0, 40)}))
    assert stop.requested and len(curve) == 1 and curve.status == "MX" and "interrupted (Ctrl-C)" in curve.message


def test_a_scene_error_after_ctrl_c_is_still_an_interrupt(tmp_path):
    """A scene that cannot use a branch the first Ctrl-C shortened (here: it raises a SceneError on
    an MX branch before handing it on) ended the run `Error: ... ended early`, exit 1, the file
    marked 'failed' without a --resume hint.  After a stop the run is interrupted: the finished
    branches are saved, one note names the scene's error, exit 130."""
    out = tmp_path / "run.h5"
    rc, stderr = _signalled(["trace", "slow-bratu", "-s", "delay=0.01", "-s", "steps=400", "-s", "strict=1", "-o",
                             str(out)], signal.SIGINT, lambda: [b.id for b in _branches(out)] == ["0"], after=1.0)
    errors = [ln for ln in stderr.splitlines() if ln.startswith("Error: ")]
    assert rc == 130 and errors == ["Error: interrupted (Ctrl-C)"], stderr
    assert "note: after the Ctrl-C the scene ended with: branch 1 ended early" in stderr
    assert f"saved in {out} (continue with --resume {out})" in stderr
    assert io.load(out)[1]["stopped"] == "interrupted"


def test_an_interrupted_depth_run_does_not_suggest_resume(tmp_path):
    """`contin trace SCENE --depth 2 -o F` + Ctrl-C said `(continue with --resume F)` (and `contin info
    F` 'continue it with --resume'), but --depth refuses --resume ('runs ... from scratch').  The
    note and info no longer suggest it for a --depth run."""
    import h5py

    out = tmp_path / "d.h5"
    res = run(["trace", "swift-hohenberg", "--depth", "1", "--no-stability", "-q", "-o", str(out)])
    assert res.exit_code in (0, 3), res.stderr
    with h5py.File(out, "r+") as f:  # what an interrupted --depth run leaves
        f.attrs["complete"], f.attrs["stopped"] = False, "interrupted"
    text = run(["info", str(out)]).stdout
    assert "(incomplete: the run was interrupted; a --depth run is started again from scratch)" in text
    assert "--resume" not in text
    err = one_error(run(["trace", "swift-hohenberg", "--depth", "1", "--resume", str(out)]))
    assert "--depth runs on a fixed grid and from scratch" in err
