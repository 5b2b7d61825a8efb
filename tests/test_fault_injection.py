"""Fault injection (issue 16): full disk, SIGKILL/SIGTERM mid-run and --resume, concurrent writers,
corrupt files, device and symlink outputs.  Each case ends in one ``Error:`` line (or a clean
resume), a non-zero exit where work was lost, the previous file intact and no stray temporary.

The disk is filled for real on a small tmpfs when this process may mount one (root); otherwise
the writer is patched to fail with ENOSPC.  Runs use the hand-built 'toy' scene
(tests/cli_fixture_scenes.py: 'delay' sleeps after each branch, so a run can be stopped between
branches) and the 'normalform' sweep scene.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.atomic import OutputLock
from contin.cli import main
from tests.signals import signalled as _signalled

HERE = Path(__file__).parent
ENV = {**os.environ, "CONTIN_SCENES": "cli_fixture_scenes:SCENES,sweep_fixture_scenes:SCENES",
       "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
       "CONTIN_PROGRESS_SECONDS": "0"}


@pytest.fixture(autouse=True)
def toy_scenes(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", ENV["CONTIN_SCENES"])


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def popen(*args: str, **env) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "contin", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**ENV, **env})


def signalled(args: list[str], sig: int, ready, what: str, after: float = 0.0) -> tuple[int, str]:
    """:func:`tests.signals.signalled` on the toy and sweep fixture scenes."""
    return _signalled(args, sig, ready, env=ENV, what=what, after=after)


def one_error(code: int, stderr: str, expect: str, exit_code: int = 1) -> str:
    assert code == exit_code, (code, stderr)
    errors = [ln for ln in stderr.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1, stderr
    assert expect in errors[0], errors[0]
    assert "Traceback" not in stderr
    return errors[0]


def wait_for(cond, timeout: float = 60.0, what: str = "condition") -> None:
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def branch_ids(path: Path) -> list[str]:
    """Branch ids of a published file (empty while absent; a file is never half-written)."""
    try:
        return [b.id for b in io.load(path)[0]]
    except (FileNotFoundError, io.FileFormatError):
        return []


def toy_file(tmp_path: Path, name: str = "toy.h5") -> Path:
    out = tmp_path / name
    r = run("trace", "toy", "-o", str(out), "-q")
    assert r.exit_code == 0, r.output
    return out


# ----------------------------------------------------------------------------- full disk
@contextlib.contextmanager
def small_disk(tmp_path: Path, size: str = "512k"):
    """A tmpfs of ``size`` (None if this process cannot mount one)."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    ok = os.geteuid() == 0 and subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)],
                                              capture_output=True).returncode == 0
    try:
        yield mnt if ok else None
    finally:
        if ok:
            subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def fill(directory: Path) -> None:
    with contextlib.suppress(OSError), open(directory / "filler", "wb", buffering=0) as fh:
        while True:
            fh.write(b"\0" * 4096)


def test_disk_full_is_one_error_line_previous_file_intact_no_temporary(tmp_path, monkeypatch):
    with small_disk(tmp_path) as mnt:
        where = mnt if mnt is not None else tmp_path
        out = toy_file(where)
        before = out.read_bytes()
        if mnt is not None:  # the real thing: fill the tmpfs, then the next publish hits ENOSPC
            fill(mnt)
            with open(mnt / "filler", "r+b") as fh:  # room for the lock file, not for a new version
                fh.truncate(os.path.getsize(mnt / "filler") - 16384)
            r = subprocess.run([sys.executable, "-m", "contin", "trace", "toy", "-s", "a=2", "-o", str(out)],
                               capture_output=True, text=True, env=ENV, timeout=120)
            code, stderr = r.returncode, r.stderr
        else:  # no mount possible: the writer fails as a full disk does
            import contin.atomic as atomic

            def full(tmp, data):
                raise OSError(errno.ENOSPC, "No space left on device", str(tmp))

            monkeypatch.setattr(atomic, "write_bytes", full)
            monkeypatch.setattr(io, "write_bytes", full)
            r = run("trace", "toy", "-s", "a=2", "-o", str(out))
            code, stderr = r.exit_code, r.stderr
        one_error(code, stderr, "No space left on device")
        assert "disk or quota full" in stderr and "previous version of the file is unchanged" in stderr
        assert out.read_bytes() == before  # previous file intact
        assert io.load(out)[1]["parameters"]["a"] == 1.0
        assert not [p.name for p in where.iterdir() if p.name.endswith(".tmp")]  # no stray temporary
        if mnt is not None:  # figures go through the same publish
            r = subprocess.run([sys.executable, "-m", "contin", "diagram", str(out), "-o", str(mnt / "d.png")],
                               capture_output=True, text=True, env=ENV, timeout=120)
            one_error(r.returncode, r.stderr, "cannot write")
            assert not (mnt / "d.png").exists() and not list(mnt.glob("*.tmp"))


# ----------------------------------------------------------------------------- kill and resume
def test_sigkill_mid_run_then_resume_reuses_every_finished_branch(tmp_path):
    out = tmp_path / "run.h5"
    proc = popen("trace", "toy", "-s", "delay=0.5", "-s", "n=5", "-o", str(out))
    try:
        wait_for(lambda: len(branch_ids(out)) >= 2, what="two published branches")
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        proc.kill()
    saved = branch_ids(out)
    assert proc.returncode == -signal.SIGKILL and 2 <= len(saved) < 5
    meta = io.load(out)[1]
    assert meta["complete"] is False and meta["stopped"] == ""
    info = run("info", str(out)).stdout
    assert "the run was interrupted; continue it with --resume" in info
    r = run("trace", "toy", "-s", "n=5", "--resume", str(out), "--json", "-q")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["extra"]["reused"] == saved  # every finished branch, none retraced
    branches, meta = io.load(out)
    assert [b.id for b in branches] == ["0", "1", "2", "3", "4"] and meta["complete"] is True
    assert not list(tmp_path.glob("*.tmp")) and not list(tmp_path.glob(".*.lock"))


def test_sigterm_is_handled_like_ctrl_c(tmp_path):
    out = tmp_path / "run.h5"
    code, stderr = signalled(["trace", "toy", "-s", "delay=0.5", "-s", "n=6", "-o", str(out)], signal.SIGTERM,
                             lambda: len(branch_ids(out)) >= 1, "a published branch")
    one_error(code, stderr, "terminated by SIGTERM", exit_code=143)
    assert f"saved in {out} (continue with --resume {out})" in stderr
    meta = io.load(out)[1]
    assert meta["complete"] is False and meta["stopped"] == "terminated by SIGTERM"
    assert "the run was terminated by SIGTERM; continue it with --resume" in run("info", str(out)).stdout
    assert not list(tmp_path.glob(".*.lock")) and not list(tmp_path.glob("*.tmp"))


def test_ctrl_c_is_one_error_line_exit_130(tmp_path):
    """qa14: Ctrl-C ended with click's 'Aborted!' and exit 1 (the code of bad input).  Now one Error
    line and 130 (128 + SIGINT), after the note on the saved branches; the file reads as interrupted."""
    out = tmp_path / "run.h5"
    code, stderr = signalled(["trace", "toy", "-s", "delay=0.5", "-s", "n=6", "-o", str(out)], signal.SIGINT,
                             lambda: len(branch_ids(out)) >= 1, "a published branch")
    one_error(code, stderr, "Error: interrupted (Ctrl-C)", exit_code=130)
    assert "Aborted!" not in stderr and f"saved in {out} (continue with --resume {out})" in stderr
    meta = io.load(out)[1]
    assert meta["complete"] is False and meta["stopped"] == "interrupted"
    assert "the run was interrupted; continue it with --resume" in run("info", str(out)).stdout


def test_ctrl_c_during_continue_keeps_the_curve_computed_so_far(tmp_path):
    """``contin continue`` writes its curve at the end, so Ctrl-C lost all of it (qa14).  The first
    Ctrl-C now ends the curve at its last point (``contin.cancel``): the file holds it, marked MX
    'interrupted', then one Error line and exit 130.  (A long stretched-Bratu fold curve,
    lam = lam* / (1 + a): ~1 min at ds 5e-4; interrupted once it is under way.)"""
    src, out = tmp_path / "sb.h5", tmp_path / "curve.h5"
    assert run("trace", "stretched-bratu", "--grid", "32", "--no-stability", "-q", "-o", str(src)).exit_code in (0, 3)
    code, stderr = signalled(["continue", str(src), "--from", "LP1", "--free", "a", "--bounds", "a=-0.5:3", "--ds",
                              "0.0005", "--ds-max", "0.0005", "--max-steps", "100000", "-o", str(out)], signal.SIGINT,
                             lambda: (tmp_path / ".curve.h5.lock").exists(), "the output lock (computing starts)",
                             after=1.5)
    one_error(code, stderr, "Error: interrupted (Ctrl-C)", exit_code=130)
    assert f"is saved in {out}" in stderr
    (curve,), meta = io.load(out)
    assert curve.status == "MX" and "interrupted (Ctrl-C)" in curve.message
    assert len(curve) > 10
    # a partial curve is marked as trace marks a stopped run (qa18: it was complete=True, and `contin
    # info` showed a finished curve); info names the command that computes it again (it has no --resume)
    assert meta["complete"] is False and meta["stopped"] == "interrupted"
    shown = run("info", str(out)).stdout
    assert "(incomplete: the curve was interrupted; `contin continue` computes it again from LP1)" in shown
    assert "--resume" not in shown
    lam, a = curve.params["lam"], curve.params["a"]
    assert np.allclose(lam * (1 + a), 3.51383071912516, rtol=1e-8)  # every saved point on the fold curve


def test_a_stop_request_ends_the_branch_at_its_last_point_and_is_cleared():
    """The core side of it (non-granular): a stop asked for inside ``stop_on_sigint`` (here by the
    residual after 200 evaluations) ends the trace MX at its last accepted point; on leaving the
    block the request is reported and cleared, so the next trace runs to its bound."""
    from contin.cancel import request_stop, stop_on_sigint
    from contin.continuation import trace
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import Bratu

    class Stopping(Bratu):
        calls = 0

        def residual(self, u, p):
            Stopping.calls += 1
            if Stopping.calls == 200:
                request_stop()
            return super().residual(u, p)

    pb = Stopping("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.1, 3.0)}, max_steps=500, step=StepOptions(ds=0.01, ds_max=0.01))
    with stop_on_sigint() as stop:
        b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", opts)
    assert stop.requested and b.status == "MX" and b.message.startswith("interrupted (Ctrl-C)")
    assert 5 < len(b) < 200 and b.parameter_values[-1] < 3.0
    again = trace(Bratu("cheb", 16), Bratu("cheb", 16).initial(), {"lam": 0.1}, "lam", opts)
    assert again.status == "EP" and again.parameter_values[-1] == pytest.approx(3.0)


def test_info_does_not_call_a_failed_run_interrupted(tmp_path):
    out = tmp_path / "run.h5"
    r = run("trace", "toy", "-s", "fail=crash", "-o", str(out))
    assert r.exit_code == 1
    meta = io.load(out)[1]
    assert meta["stopped"].startswith("failed: internal error (RuntimeError: deliberate crash")
    text = run("info", str(out)).stdout
    assert "(incomplete: the run failed: internal error" in text and "interrupted" not in text


def test_jj_walls_phi_w_0_says_the_real_cause_in_one_line(tmp_path):
    out = tmp_path / "jj.h5"
    r = run("trace", "jj-walls", "-s", "phi_w=0", "--no-stability", "--grid", "16", "-o", str(out))
    err = one_error(r.exit_code, r.stderr, "the base branch could not start")
    assert "temperature not positive" in err and "use phi_w > 0" in err
    assert "--resume" not in r.stderr


# ----------------------------------------------------------------------------- concurrent writers
def test_second_writer_of_the_same_output_is_refused_up_front(tmp_path):
    out = tmp_path / "run.h5"
    first = popen("trace", "toy", "-s", "delay=2", "-s", "n=5", "-o", str(out))
    try:
        wait_for(lambda: (tmp_path / ".run.h5.lock").exists(), what="the first run's lock")
        second = subprocess.run([sys.executable, "-m", "contin", "trace", "toy", "-s", "a=2", "-o", str(out)],
                                capture_output=True, text=True, env=ENV, timeout=60)
        one_error(second.returncode, second.stderr, "is being written by another contin run")
        assert first.poll() is None  # refused while the first run is still going, before computing
        _, stderr = first.communicate(timeout=120)
    finally:
        first.kill()
    assert first.returncode == 0, stderr
    branches, meta = io.load(out)
    assert meta["complete"] and meta["parameters"]["a"] == 1.0 and len(branches) == 5  # the first run won
    assert not (tmp_path / ".run.h5.lock").exists()


def test_second_sweep_into_one_directory_is_refused(tmp_path):
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nscene = "normalform"\n[grid]\na = [0.0, 1.0]\n')
    outdir = tmp_path / "out"
    outdir.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        from contin.atomic import OutputLock
        OutputLock({str(outdir)!r}, directory=True).acquire()
        print("locked", flush=True)
        time.sleep(60)
    """)], stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        assert holder.stdout.readline().strip() == "locked"
        r = run("sweep", str(sweep), "-o", str(outdir), "-j", "1")
        one_error(r.exit_code, r.stderr, "is being written by another contin run")
        assert not (outdir / "summary.json").exists()
    finally:
        holder.kill()
        holder.wait()
    r = run("sweep", str(sweep), "-o", str(outdir), "-j", "1", "-q")  # the lock died with its holder
    assert r.exit_code == 0, r.output


def test_lock_is_exclusive_between_processes_and_survives_no_holder(tmp_path):
    target = tmp_path / "x.h5"
    with OutputLock(target):
        code = subprocess.run([sys.executable, "-c", textwrap.dedent(f"""
            from contin.atomic import OutputLock, OutputRefused
            try:
                OutputLock({str(target)!r}).acquire()
            except OutputRefused:
                raise SystemExit(7)
        """)], env=ENV).returncode
        assert code == 7
    assert not (tmp_path / ".x.h5.lock").exists()


def _sweep_children(pid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
                if int(fields[1]) == pid:
                    out.append(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to find the workers")
def test_sweep_workers_die_with_the_parent(tmp_path):
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nscene = "normalform"\n[fixed]\ndelay = 30.0\n[grid]\na = [0.0, 1.0]\n')
    proc = popen("sweep", str(sweep), "-o", str(tmp_path / "out"), "-j", "2")
    try:
        wait_for(lambda: len(_sweep_children(proc.pid)) >= 2, what="the sweep's workers")
        time.sleep(1.0)  # let the workers run their initializer
        children = _sweep_children(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        wait_for(lambda: not any(_alive(c) for c in children), timeout=15, what="the workers to exit")
    finally:
        proc.kill()


def test_sweep_summary_matches_the_task_files_after_ctrl_c(tmp_path):
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nscene = "normalform"\n[fixed]\ndelay = 1.0\n[grid]\na = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]\n')
    outdir = tmp_path / "out"
    proc = popen("sweep", str(sweep), "-o", str(outdir), "-j", "2")
    try:
        wait_for(lambda: len(list((outdir / "tasks").glob("*.h5"))) >= 1, what="a task file")
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    finally:
        proc.kill()
    files = {f"tasks/{p.name}" for p in (outdir / "tasks").glob("*.h5")}
    doc = json.loads((outdir / "summary.json").read_text())
    done = {t["file"] for t in doc["tasks"] if t["status"] == "ok"}
    assert done == files  # ok in the summary exactly when the task file exists
    assert doc["counts"]["ok"] + doc["counts"]["pending"] == 6


# ----------------------------------------------------------------------------- corrupt files
def _corrupt(path: Path, edit) -> None:
    with h5py.File(path, "r+") as f:
        edit(f)


@pytest.mark.parametrize("dataset, kind", [
    ("branches/0/lam", "nan"), ("branches/0/phi", "nan"), ("branches/0/states", "nan"),
    ("branches/0/profiles/nu", "nan"), ("special_points/params/lam", "nan"), ("special_points/states", "nan"),
    ("branches/1/lam", "short"), ("branches/1/phi", "short"), ("branches/1/states", "short"),
    ("branches/1/tangents", "short"), ("special_points/phi", "short"),
])
def test_reader_refuses_nan_and_short_datasets_naming_them(tmp_path, dataset, kind):
    f = toy_file(tmp_path)

    def edit(h5):
        data = h5[dataset][()]
        del h5[dataset]
        if kind == "nan":
            data = np.array(data, dtype=float)
            data.flat[min(1, data.size - 1)] = np.nan
        else:
            data = data[:-2]
        h5.create_dataset(dataset, data=data)

    _corrupt(f, edit)
    with pytest.raises(io.FileFormatError, match=f"dataset {dataset} "):
        io.load(f)
    r = run("info", str(f))
    one_error(r.exit_code, r.stderr, f"dataset {dataset} ")


def test_reader_allows_what_the_writer_allows(tmp_path):
    """inf in a fixed parameter (Fr = inf) and an observable NaN everywhere are valid."""
    f = toy_file(tmp_path)

    def edit(h5):
        n = h5["branches/0/phi"].shape[0]
        del h5["branches/0/phi"]
        h5.create_dataset("branches/0/phi", data=np.full(n, np.nan))

    _corrupt(f, edit)
    branches, _ = io.load(f)
    assert np.isinf(branches[0].params["Fr"]).all() and np.isnan(branches[0].observables["phi"]).all()


# ----------------------------------------------------------------------------- outputs that are not files
@pytest.mark.parametrize("target", ["/dev/null", "/dev/full"])
def test_device_outputs_are_refused_and_left_alone(tmp_path, target):
    before = os.lstat(target)
    for args in (("trace", "toy", "-o", target), ("diagram", str(toy_file(tmp_path)), "-o", target)):
        r = run(*args)
        one_error(r.exit_code, r.stderr, "it is not a regular file")
    after = os.lstat(target)
    assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev and after.st_ino == before.st_ino


def test_symlink_output_is_refused_and_the_link_kept(tmp_path):
    real = toy_file(tmp_path, "real.h5")
    link = tmp_path / "link.h5"
    link.symlink_to(real)
    before = real.read_bytes()
    for args in (("trace", "toy", "-s", "a=2", "-o", str(link)), ("diagram", str(real), "-o", str(link))):
        r = run(*args)
        one_error(r.exit_code, r.stderr, "it is a symbolic link")
    assert link.is_symlink() and real.read_bytes() == before


def test_sigterm_on_any_command_is_one_error_line_and_exit_143(tmp_path):
    """The command group handles SIGTERM for every command; here a sweep busy in a slow task: one
    Error line, exit 143, the summary written (the task pending), the directory lock gone."""
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nscene = "normalform"\n[fixed]\ndelay = 30.0\n[grid]\na = [0.0]\n')
    proc = popen("sweep", str(sweep), "-o", str(tmp_path / "out"), "-j", "1")
    try:
        wait_for(lambda: (tmp_path / "out" / ".contin.lock").exists(), what="the sweep to start")
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    one_error(proc.returncode, stderr, "terminated by SIGTERM", exit_code=143)
    doc = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert doc["counts"]["pending"] == 1 and not (tmp_path / "out" / ".contin.lock").exists()


def test_switch_reusing_keeps_each_finished_half_allen_cahn(monkeypatch):
    """contin.resume.switch_reusing on a non-granular scene: a run killed between the two halves
    of a switched branch retraces only the missing half, with the id and values it had."""
    import contin.continuation as cont
    from contin.scene import SceneRequest, get_scene

    req = dict(params={"lam_max": 5.0}, stability=False)
    full = {b.id: b for b in get_scene("allen-cahn").run(SceneRequest(**req)).branches}
    halves = sorted(i for i in full if i.endswith((".1", ".2")))
    assert halves == ["0.BP1.1", "0.BP1.2", "0.BP2.1", "0.BP2.2"]  # pitchforks at lam = 1, 4
    calls = []
    real = cont.switch

    def counting(*args, directions=(1, -1), **kw):
        calls.append(tuple(directions))
        return real(*args, directions=directions, **kw)

    monkeypatch.setattr(cont, "switch", counting)
    done = {k: v for k, v in full.items() if k not in ("0.BP2.2",)}  # killed while tracing 0.BP2.2
    again = {b.id: b for b in get_scene("allen-cahn").run(SceneRequest(**req, completed=done)).branches}
    assert calls == [(-1,)]
    assert all(again[k] is done[k] for k in done)
    np.testing.assert_allclose(again["0.BP2.2"].observables["phi"], full["0.BP2.2"].observables["phi"], atol=1e-10)
