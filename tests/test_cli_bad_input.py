"""Bad input through the REAL gPCF scenes (pitchfork, jj-walls, gravity) and non-finite data in files.

tests/test_cli.py checks the error machinery with hand-built fixture scenes; here every invalid
value of issue 6 goes through the scenes registered by entry points, in-process (click's
CliRunner) and in a subprocess (``python -m contin``): exactly one stderr line starting
``Error:``, the reason named, no traceback, exit code 1, nothing on stdout.  All of these fail
before any continuation step, so each case takes well under a second.

The last section checks contin.io's refusal to write NaN/inf where a file needs finite values
(module docstring of contin.io, "Non-finite data").
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.branch import Branch, SpecialPoint
from contin.cli import main

HERE = Path(__file__).parent


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)  # the entry-point scenes only


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def subprocess_contin(*args: str, env_extra: dict[str, str] | None = None):
    env = {k: v for k, v in os.environ.items() if k not in ("CONTIN_SCENES", "CONTIN_DEBUG")}
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "contin", *args], capture_output=True, text=True, env=env, timeout=120)


def assert_one_error(exit_code: int, stdout: str, stderr: str, expect: str) -> None:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert exit_code == 1, (exit_code, stderr)
    assert len(lines) == 1 and lines[0].startswith("Error: "), stderr
    assert expect in lines[0], lines[0]
    assert "Traceback" not in stderr and "nan" not in lines[0].lower().replace("nanphi", "")
    assert stdout == ""


LIMIT = "it must satisfy 0 < nu < 0.65"
E_RANGE = "it must satisfy 0 < e <= 1"
BAD_VALUES = [
    # (scene, -s settings, expected text in the error line)
    ("pitchfork", ["nu=0"], "parameter nu = 0.0 is out of range; " + LIMIT),
    ("pitchfork", ["nu=-0.1"], "parameter nu = -0.1 is out of range"),
    ("pitchfork", ["nu=0.65"], "parameter nu = 0.65 is out of range; " + LIMIT),
    ("pitchfork", ["nu=0.9"], "parameter nu = 0.9 is out of range"),
    ("pitchfork", ["e=0"], "parameter e = 0.0 is out of range; " + E_RANGE),
    ("pitchfork", ["e=1.2"], "parameter e = 1.2 is out of range; " + E_RANGE),
    # e = 1 is a valid restitution coefficient, but f5 = 0: uniform shear has no finite T
    ("pitchfork", ["e=1"], "e = 1 has no steady sheared state (no collisional dissipation)"),
    ("pitchfork", ["H=0"], "parameter H = 0 is out of range; it must be a positive finite gap"),
    ("pitchfork", ["H=-3"], "parameter H = -3 is out of range"),
    ("pitchfork", ["H_max=-1"], "parameter H_max = -1 is out of range"),
    ("pitchfork", ["Fr=50"], "unknown parameter 'Fr' for scene 'pitchfork'"),
    ("pitchfork", ["zeta=1"], "unknown parameter 'zeta' for scene 'pitchfork'; its parameters are nu, e, H"),
    ("jj-walls", ["phi_w=-0.1"], "parameter phi_w = -0.1 is out of range; it must satisfy 0 <= phi_w <= 1"),
    ("jj-walls", ["phi_w=1.5"], "parameter phi_w = 1.5 is out of range; it must satisfy 0 <= phi_w <= 1"),
    ("jj-walls", ["ew=1.5"], "parameter ew = 1.5 is out of range"),
    ("gravity", ["nu=0"], "parameter nu = 0.0 is out of range; " + LIMIT),
    ("gravity", ["nu=0.65"], "parameter nu = 0.65 is out of range; " + LIMIT),
    ("gravity", ["e=0"], "parameter e = 0.0 is out of range; " + E_RANGE),
    ("gravity", ["e=1.2"], "parameter e = 1.2 is out of range; " + E_RANGE),
    ("gravity", ["e=1"], "uniform shear has no steady temperature at e = 1 (no collisional dissipation)"),
    ("gravity", ["Fr=0"], "scene 'gravity' needs a finite Froude number Fr > 0, got 0"),
    ("gravity", ["Fr=-5"], "scene 'gravity' needs a finite Froude number Fr > 0, got -5"),
    ("gravity", ["Fr=inf"], "(Fr = inf is the pitchfork scene)"),
    ("gravity", ["H_min=0"], "need 0 < H_min < H_max, got H_min=0, H_max=70"),
    ("gravity", ["H_max=-1"], "need 0 < H_min < H_max, got H_min=1, H_max=-1"),
    ("gravity", ["H=10"], "unknown parameter 'H' for scene 'gravity'; its parameters are nu, e, Fr, H_min, H_max"),
    ("gravity", ["zeta=1"], "unknown parameter 'zeta' for scene 'gravity'"),
]


def _argv(scene: str, settings: list[str], *extra: str) -> list[str]:
    out = ["trace", scene, *extra]
    for s in settings:
        out += ["-s", s]
    return out


@pytest.mark.parametrize("scene, settings, expect", BAD_VALUES, ids=lambda v: str(v) if not isinstance(v, list) else ",".join(v))
def test_invalid_value_in_real_scene_is_one_error_line(scene, settings, expect, tmp_path):
    out = tmp_path / "x.h5"
    r = run(*_argv(scene, settings, "-o", str(out)))
    assert_one_error(r.exit_code, r.stdout, r.stderr, expect)
    assert not out.exists()  # nothing computed, nothing written


OTHER_ERRORS = [
    (["trace", "nosuchscene"], "unknown scene 'nosuchscene'; known scenes: "),
    (["trace", "pitchfork", "--method", "fd3"], "unknown discretization 'fd3'; choose one of cheb, fd2, fd4, fd6"),
    (["trace", "gravity", "--method", "fd3"], "unknown discretization 'fd3'; choose one of cheb, fd2, fd4, fd6"),
    (["trace", "pitchfork", "--grid", "2"], "grid too small: cheb needs at least 4 intervals, got 2"),
    (["trace", "pitchfork", "--method", "fd4", "--grid", "6"], "grid too small: fd4 needs at least 8 intervals, got 6"),
    (["trace", "gravity", "--method", "fd6", "--grid", "2"], "grid too small: fd6 needs at least 12 intervals, got 2"),
    (["trace", "gravity", "--method", "fd2", "--grid", "2"], "grid too small: fd2 needs at least 4 intervals, got 2"),
    (["trace", "pitchfork", "-o", "/nonexistent_dir_xyz/x.h5"], "directory '/nonexistent_dir_xyz' does not exist"),
    (["trace", "gravity", "-o", "/nonexistent_dir_xyz/x.h5"], "directory '/nonexistent_dir_xyz' does not exist"),
]


@pytest.mark.parametrize("args, expect", OTHER_ERRORS, ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_unknown_names_small_grids_and_bad_paths(args, expect):
    r = run(*args)
    assert_one_error(r.exit_code, r.stdout, r.stderr, expect)


def test_output_is_a_directory_or_read_only(tmp_path):
    # click rejects a directory while parsing: a usage error (exit 2), still one Error line
    r = run("trace", "pitchfork", "-o", str(tmp_path))
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error:")]
    assert r.exit_code == 2 and len(errors) == 1 and "is a directory" in errors[0]
    assert "Traceback" not in r.stderr and r.stdout == ""
    if os.geteuid() != 0:  # root ignores permissions
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        r = run("trace", "gravity", "-o", str(ro / "x.h5"))
        assert_one_error(r.exit_code, r.stdout, r.stderr, "cannot write")


def test_grid_one_is_a_usage_error():
    r = run("trace", "pitchfork", "--grid", "1")
    assert r.exit_code == 2 and "Traceback" not in r.output


def _corrupt_files(tmp_path: Path) -> list[Path]:
    good = tmp_path / "good.h5"
    # H_max = 16: cheb 16 resolves the banded branch there (the resolution guard ends it MX at H = 17.95)
    r = run("trace", "pitchfork", "-s", "modes=1", "-s", "H_max=16", "--grid", "16", "--no-stability", "-q",
            "-o", str(good))
    assert r.exit_code == 0, r.output
    garbage = tmp_path / "garbage.h5"
    garbage.write_bytes(b"not an hdf5 file at all\n" * 20)
    header_only = tmp_path / "header.h5"
    header_only.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 200)
    trunc = tmp_path / "trunc.h5"
    trunc.write_bytes(good.read_bytes()[: good.stat().st_size // 3])
    return [garbage, header_only, trunc]


def test_corrupt_files_for_info_diagram_stability(tmp_path):
    png = tmp_path / "x.png"
    for f in _corrupt_files(tmp_path):
        for args in (["info", str(f)], ["info", str(f), "--json"], ["diagram", str(f), "-o", str(png)],
                     ["stability", str(f), "--point", "0"]):
            r = run(*args)
            assert_one_error(r.exit_code, r.stdout, r.stderr, str(f))
        r = run("trace", "pitchfork", "--resume", str(f))
        assert_one_error(r.exit_code, r.stdout, r.stderr, str(f))
    assert not png.exists()
    r = run("info", str(tmp_path / "missing.h5"))
    assert r.exit_code in (1, 2) and "Traceback" not in r.output


SUBPROCESS_CASES = [
    (["trace", "pitchfork", "-s", "nu=0.65"], "parameter nu = 0.65 is out of range"),
    (["trace", "pitchfork", "-s", "e=1.2"], "parameter e = 1.2 is out of range"),
    (["trace", "pitchfork", "-s", "e=1"], "no steady sheared state"),
    (["trace", "pitchfork", "-s", "H=-1"], "parameter H = -1 is out of range"),
    (["trace", "gravity", "-s", "Fr=0"], "needs a finite Froude number Fr > 0"),
    (["trace", "gravity", "-s", "e=0"], "parameter e = 0.0 is out of range"),
    (["trace", "jj-walls", "-s", "phi_w=2"], "parameter phi_w = 2.0 is out of range"),
    (["trace", "nosuchscene"], "unknown scene 'nosuchscene'"),
    (["trace", "gravity", "-s", "zeta=1"], "unknown parameter 'zeta'"),
    (["trace", "pitchfork", "--method", "fd3"], "unknown discretization 'fd3'"),
    (["trace", "gravity", "--grid", "2"], "grid too small"),
    (["trace", "pitchfork", "-o", "/nonexistent_dir_xyz/x.h5"], "does not exist"),
]


def test_subprocess_bad_input(tmp_path):
    """The same errors from a fresh interpreter (entry points, logging, exit status)."""
    # one interpreter per case would cost ~1 s each; a small driver runs them through
    # `python -m contin` semantics (runpy) in one subprocess and reports exit code + stderr
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 64)
    cases = SUBPROCESS_CASES + [(["info", str(bad)], str(bad)), (["diagram", str(bad), "-o", str(tmp_path / "d.png")],
                                                                  "not a readable HDF5 file")]
    for args, expect in cases[:3] + cases[-2:]:  # real `python -m contin` processes
        r = subprocess_contin(*args)
        assert_one_error(r.returncode, r.stdout, r.stderr, expect)
    driver = (
        "import json, runpy, sys, io, contextlib\n"
        "out = []\n"
        "for args in json.loads(sys.argv[1]):\n"
        "    err, std = io.StringIO(), io.StringIO()\n"
        "    sys.argv = ['contin', *args]\n"
        "    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):\n"
        "        try:\n"
        "            runpy.run_module('contin', run_name='__main__', alter_sys=False)\n"
        "            code = 0\n"
        "        except SystemExit as e:\n"
        "            code = e.code if isinstance(e.code, int) else 1\n"
        "    out.append([code, std.getvalue(), err.getvalue()])\n"
        "print(json.dumps(out))\n"
    )
    import json

    env = {k: v for k, v in os.environ.items() if k not in ("CONTIN_SCENES", "CONTIN_DEBUG")}
    r = subprocess.run([sys.executable, "-c", driver, json.dumps([a for a, _ in cases])], capture_output=True,
                       text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    results = json.loads(r.stdout.strip().splitlines()[-1])
    for (args, expect), (code, stdout, stderr) in zip(cases, results, strict=True):
        assert_one_error(code, stdout, stderr, expect)


def test_debug_flag_shows_the_traceback_instead():
    r = subprocess_contin("--debug", "trace", "pitchfork", "-s", "nu=0.65")
    assert r.returncode == 1 and "Traceback" in r.stderr and "SceneError" in r.stderr


# ------------------------------------------------------------------ non-finite data never reaches a file

def _branch(**changes) -> Branch:
    s = 4
    lam = np.linspace(0.0, 1.0, s)
    states = np.column_stack([lam, lam**2])
    kw = dict(parameter="lam", free=("lam",), params={"lam": lam, "Fr": np.full(s, math.inf)},
              observables={"phi": lam.copy(), "undefined": np.full(s, np.nan)},
              states=states, tangents=np.column_stack([states, np.ones(s)]), ds=np.r_[0.0, np.diff(lam)],
              newton_iterations=np.zeros(s, dtype=np.int64),
              special_points=[SpecialPoint("LP", 1, {"lam": 0.5, "Fr": math.inf}, math.nan, np.array([0.5, 0.25]),
                                           label=1)],
              status="EP", message="bound reached", id="b")
    kw.update(changes)
    return Branch(**kw)


def test_io_writes_allowed_non_finite_values(tmp_path):
    """inf in a fixed parameter (Fr = inf), an all-NaN observable and a NaN phi of a special point
    are meaningful and stored as such."""
    f = io.write(tmp_path / "ok.h5", [_branch()])
    (b,), _ = io.load(f)
    assert np.all(np.isinf(b.params["Fr"])) and np.all(np.isnan(b.observables["undefined"]))
    np.testing.assert_array_equal(b.states[:, 1], np.linspace(0, 1, 4) ** 2)
    assert math.isnan(b.special_points[0].order_parameter)


def _with(array: np.ndarray, row: int, value: float) -> np.ndarray:
    a = np.array(array, dtype=float, copy=True)
    a.reshape(a.shape[0], -1)[row, 0] = value
    return a


@pytest.mark.parametrize("what, make, expect", [
    ("state NaN", lambda b: {"states": _with(b.states, 2, np.nan)}, "branch b: the state is not finite at point 2"),
    ("state inf", lambda b: {"states": _with(b.states, 1, np.inf)}, "the state is not finite at point 1"),
    ("tangent", lambda b: {"tangents": _with(b.tangents, 3, np.nan)}, "the tangent is not finite at point 3"),
    ("free parameter inf", lambda b: {"params": {**b.params, "lam": _with(b.params["lam"], 1, np.inf)}},
     "parameter lam is not finite at point 1"),
    ("fixed parameter NaN", lambda b: {"params": {**b.params, "Fr": _with(b.params["Fr"], 0, np.nan)}},
     "parameter Fr is not finite at point 0"),
    ("observable partly NaN", lambda b: {"observables": {**b.observables, "phi": _with(b.observables["phi"], 3, np.nan)}},
     "observable phi is not finite at point 3"),
    ("observable inf", lambda b: {"observables": {**b.observables, "phi": _with(b.observables["phi"], 0, -np.inf)}},
     "observable phi is not finite at point 0"),
    ("special point state", lambda b: {"special_points": [SpecialPoint("BP", 2, {"lam": 0.6}, 0.1, np.array([np.nan, 1.0]),
                                                                       label=3)]},
     "the located state of BP3 is not finite"),
])
def test_io_refuses_non_finite_data(tmp_path, what, make, expect):
    good = _branch()
    bad = _branch(**make(good))
    path = tmp_path / "run.h5"
    with pytest.raises(io.NonFiniteError, match="refusing to write non-finite data") as info:
        io.write(path, [bad])
    assert expect in str(info.value) and "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)
    assert not path.exists() and not path.with_name("run.h5.tmp").exists()
    # incremental writer: the last good publish stays on disk untouched
    w = io.H5Writer(path)
    w.add_branch(good)
    before = path.read_bytes()
    with pytest.raises(io.NonFiniteError):
        w.add_branch(_branch(id="c", **make(good)))
    assert path.read_bytes() == before
    assert [b.id for b in io.load(path)[0]] == ["b"]


def test_cli_scene_with_nan_observable_cannot_write_it(tmp_path, monkeypatch):
    """The fixture scene 'toy' with fail=nanphi puts NaN into one value of an observable: the
    run stops with one error line instead of storing it (without -o nothing is written and the
    JSON shows null, tests/test_cli.py)."""
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", "cli_fixture_scenes:SCENES")
    out = tmp_path / "toy.h5"
    r = run("trace", "toy", "-s", "fail=nanphi", "-q", "-o", str(out))
    assert r.exit_code == 1 and "Traceback" not in r.output
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1 and "branch 0: observable energy is not finite at point 3" in errors[0], r.stderr
    assert not out.exists()
