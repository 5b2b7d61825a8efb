"""The click CLI: outputs, strict JSON, exit codes, one-line errors, crash safety and resume.

Scenes come from tests/cli_fixture_scenes.py through the CONTIN_SCENES variable, in-process
(CliRunner) and in subprocesses.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main

HERE = Path(__file__).parent
SCENES_ENV = "cli_fixture_scenes:SCENES"


@pytest.fixture(autouse=True)
def toy_scenes(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", SCENES_ENV)


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def strict_json(text: str):
    def reject(name):
        raise AssertionError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=reject)


def one_error_line(result, expect: str) -> None:
    assert result.exit_code == 1, (result.exit_code, result.output)
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("Error: ")]
    assert len(errors) == 1, result.stderr
    assert expect in errors[0], errors[0]
    assert "Traceback" not in result.output
    assert result.stdout == ""


def subprocess_contin(*args: str, timeout: float = 60, **kw):
    env = {**os.environ, "CONTIN_SCENES": SCENES_ENV,
           "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "contin", *args], capture_output=True, text=True,
                          env=env, timeout=timeout, **kw)


def test_scenes_lists_toy_and_reports_broken_modules(monkeypatch):
    r = run("scenes")
    assert r.exit_code == 0
    assert "toy: hand-built pitchfork branches" in r.stdout
    assert "a=1" in r.stdout and "Fr=inf" in r.stdout and "chi=jj" in r.stdout
    monkeypatch.setenv("CONTIN_SCENES", SCENES_ENV + ",no_such_module_xyz:SCENES")
    r = run("scenes")
    assert r.exit_code == 0 and "toy:" in r.stdout
    bad = [ln for ln in r.stderr.splitlines() if "no_such_module_xyz" in ln]
    assert len(bad) == 1 and "ModuleNotFoundError" in bad[0]
    doc = strict_json(run("scenes", "--json").stdout)
    toy = [s for s in doc["scenes"] if s["name"] == "toy"]
    assert len(toy) == 1 and toy[0]["defaults"]["Fr"] == "inf"


def test_trace_json_file_and_summary(tmp_path):
    out = tmp_path / "toy.h5"
    r = run("trace", "toy", "-s", "a=2", "-s", "chi=cs", "-o", str(out), "--json")
    assert r.exit_code == 0, r.output
    doc = strict_json(r.stdout)  # stdout holds exactly one JSON document
    assert doc["scene"] == "toy"
    assert doc["parameters"]["a"] == 2.0 and doc["parameters"]["chi"] == "cs"
    assert doc["parameters"]["Fr"] == "inf"
    assert [b["id"] for b in doc["branches"]] == ["0", "1", "2"]
    assert doc["branches"][1] == {"id": "1", "kind": "bifurcated", "parent": "BP1@0", "parameter": "lam",
                                  "free": ["lam"], "status": "EP", "message": "bound reached", "closed": False,
                                  "n_points": 6}
    sps = doc["special_points"]
    assert [(s["type"], s["label"], s["branch"]) for s in sps] == [("BP", "BP1", "0"), ("LP", "LP2", "1")]
    assert sps[0]["params"] == {"lam": 0.0, "a": 2.0, "Fr": "inf"}
    assert sps[1]["phi"] == 0.4 and sps[1]["converged"] is False and sps[1]["bracket"] == [0.1, 0.2]
    assert doc["extra"]["nan"] is None and doc["extra"]["inf"] == "inf"
    # the summary table goes to stderr
    assert "BP1" in r.stderr and "LP2" in r.stderr and "lam=0.16" in r.stderr
    assert "NO" in r.stderr  # unconverged location is flagged
    branches, meta = io.load(out)
    assert meta["complete"] and meta["scene"] == "toy" and meta["parameters"]["chi"] == "cs"
    assert meta["command"].endswith("")  # argv of the test runner; exact argv is checked in a subprocess
    assert [len(b) for b in branches] == [9, 6, 6]
    assert meta["profiles"]["0"]["nu"].shape == (9, 5)
    assert io.options_from_dict(meta["options"]).step.ds == 0.02


def test_json_has_null_for_nan():
    r = run("trace", "toy", "-s", "fail=nanphi", "--json", "--quiet")
    assert r.exit_code == 0
    doc = strict_json(r.stdout)
    assert doc["special_points"][0]["phi"] is None
    assert "NaN" not in r.stdout and "Infinity" not in r.stdout
    assert r.stderr == ""  # --quiet


def test_option_overrides_reach_the_scene(tmp_path):
    r = run("trace", "toy", "--ds", "0.125", "--ds-max", "0.5", "--max-steps", "7", "--json", "-q",
            "-o", str(tmp_path / "t.h5"))
    doc = strict_json(r.stdout)
    assert doc["extra"]["ds"] == 0.125 and doc["extra"]["max_steps"] == 7
    opts = io.options_from_dict(io.load(tmp_path / "t.h5")[1]["options"])
    assert (opts.step.ds, opts.step.ds_max, opts.max_steps) == (0.125, 0.5, 7)


def test_mx_exits_3():
    r = run("trace", "toy", "-s", "fail=mx", "--json")
    assert r.exit_code == 3
    assert strict_json(r.stdout)["branches"][1]["status"] == "MX"
    assert "warning: branch 1 ended with MX: step size underflow at lam=0.16" in r.stderr


@pytest.mark.parametrize("args, expect", [
    (("trace", "nosuchscene"), "unknown scene 'nosuchscene'; known scenes: "),
    (("trace", "toy", "-s", "zeta=1"), "unknown parameter 'zeta' for scene 'toy'"),
    (("trace", "toy", "-s", "a=-1"), "a must be > 0, got -1"),
    (("trace", "toy", "-s", "fail=crash"), "deliberate crash in the toy scene"),
])
def test_bad_input_is_one_line_exit_1(args, expect):
    one_error_line(run(*args), expect)


def test_usage_errors_exit_2():
    assert run("trace", "toy", "-s", "a").exit_code == 2
    assert run("trace", "toy", "-s", "a=nan").exit_code == 2
    assert run("trace", "toy", "--kx", "1,x").exit_code == 2
    assert run("trace").exit_code == 2


def test_unwritable_output_fails_before_computing(tmp_path):
    # fail=crash would raise inside the scene: the output error must come first
    t0 = time.perf_counter()
    r = run("trace", "toy", "-s", "fail=crash", "-s", "delay=5", "-o", str(tmp_path / "missing" / "x.h5"))
    one_error_line(r, "does not exist")
    assert time.perf_counter() - t0 < 3.0
    r = run("trace", "toy", "-s", "fail=crash", "-o", str(tmp_path))
    assert r.exit_code in (1, 2) and "Traceback" not in r.output
    r = run("diagram", str(_toy_file(tmp_path)), "-o", str(tmp_path / "missing" / "x.png"))
    one_error_line(r, "does not exist")


def _toy_file(tmp_path: Path, *extra: str) -> Path:
    out = tmp_path / "toy.h5"
    if not out.exists():
        assert run("trace", "toy", "-q", "-o", str(out), *extra).exit_code == 0
    return out


def test_crash_keeps_finished_branches_and_resume_reuses_them(tmp_path):
    out = tmp_path / "run.h5"
    r = run("trace", "toy", "-s", "fail=crash", "-o", str(out))
    one_error_line(r, "deliberate crash")
    assert "--resume" in r.stderr
    branches, meta = io.load(out)
    assert [b.id for b in branches] == ["0"] and meta["complete"] is False
    # resuming with a different parameter value is refused
    one_error_line(run("trace", "toy", "-s", "a=3", "--resume", str(out)), "was computed with a=1, not 3")
    r = run("trace", "toy", "--resume", str(out), "--json", "-q")
    assert r.exit_code == 0, r.output
    doc = strict_json(r.stdout)
    assert doc["extra"]["reused"] == ["0"]
    branches, meta = io.load(out)
    assert [b.id for b in branches] == ["0", "1", "2"] and meta["complete"] is True


def test_info_text_and_json(tmp_path):
    f = _toy_file(tmp_path)
    r = run("info", str(f))
    assert r.exit_code == 0
    for text in ("scene:          toy", "bifurcated", "BP1@0", "LP2", "bound reached", "git_commit:"):
        assert text in r.stdout, text
    doc = strict_json(run("info", str(f), "--json").stdout)
    assert [s["label"] for s in doc["special_points"]] == ["BP1", "LP2"]
    assert doc["provenance"]["complete"] is True


def test_diagram_writes_png(tmp_path):
    f = _toy_file(tmp_path)
    png = tmp_path / "d.png"
    r = run("diagram", str(f), "-o", str(png))
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = run("diagram", str(f), "-x", "lam", "-y", "energy", "--branch", "1", "-o", str(tmp_path / "e.pdf"))
    assert r.exit_code == 0 and (tmp_path / "e.pdf").read_bytes()[:4] == b"%PDF"
    one_error_line(run("diagram", str(f), "-y", "nope", "-o", str(png)), "no parameter or observable 'nope'")
    one_error_line(run("diagram", str(f), "--branch", "9", "-o", str(png)), "no branch '9'")


def test_corrupt_file_one_line_error(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    good = _toy_file(tmp_path)
    trunc = tmp_path / "trunc.h5"
    trunc.write_bytes(good.read_bytes()[:3000])
    for f in (bad, trunc):
        one_error_line(run("info", str(f)), str(f))
        one_error_line(run("diagram", str(f), "-o", str(tmp_path / "x.png")), "not a readable HDF5 file")
        one_error_line(run("trace", "toy", "--resume", str(f)), str(f))
    assert not (tmp_path / "x.png").exists()


def test_subprocess_errors_exit_codes_and_debug(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"garbage" * 10)
    r = subprocess_contin("info", str(bad))
    assert r.returncode == 1
    assert r.stderr.strip().count("\n") == 0 and r.stderr.startswith("Error: ") and "Traceback" not in r.stderr
    r = subprocess_contin("trace", "nosuch")
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "unknown scene 'nosuch'" in r.stderr
    r = subprocess_contin("trace", "toy", "-s", "a=-2", "-o", str(tmp_path / "nodir" / "x.h5"))
    assert r.returncode == 1 and "does not exist" in r.stderr and r.stderr.count("\n") == 1
    r = subprocess_contin("--debug", "info", str(bad))
    assert r.returncode == 1 and "Traceback" in r.stderr and "FileFormatError" in r.stderr
    r = subprocess_contin("trace", "toy", "-s", "fail=mx", "-q")
    assert r.returncode == 3
    out = tmp_path / "ok.h5"
    r = subprocess_contin("trace", "toy", "-s", "a=1.5", "-o", str(out), "--json")
    assert r.returncode == 0
    assert strict_json(r.stdout)["parameters"]["a"] == 1.5
    assert io.load(out)[1]["command"].endswith(f"trace toy -s a=1.5 -o {out} --json")


def test_help_is_fast_and_imports_nothing_heavy():
    code = ("import sys, contin.cli; "
            "heavy = [m for m in ('h5py', 'matplotlib', 'scipy.sparse.linalg') if m in sys.modules]; "
            "print(heavy)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == "[]", r.stdout + r.stderr
    r = subprocess_contin("--help")
    assert r.returncode == 0 and "trace" in r.stdout and "diagram" in r.stdout


def test_sigkill_midway_then_resume_gives_same_special_points(tmp_path):
    ref = tmp_path / "ref.h5"
    assert subprocess_contin("trace", "toy", "-s", "n=6", "-q", "-o", str(ref)).returncode == 0
    out = tmp_path / "killed.h5"
    env = {**os.environ, "CONTIN_SCENES": SCENES_ENV,
           "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "contin", "trace", "toy", "-s", "n=6", "-s", "delay=0.3",
                             "-q", "-o", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seen = 0
    deadline = time.time() + 30
    try:
        while time.time() < deadline:  # the file must be loadable whenever it exists
            if out.exists():
                branches, meta = io.load(out)
                assert meta["complete"] is False
                seen = max(seen, len(branches))
                if seen >= 3:
                    break
            time.sleep(0.02)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL and seen >= 3
    branches, meta = io.load(out)
    assert 3 <= len(branches) < 6 and meta["complete"] is False
    r = subprocess_contin("trace", "toy", "-s", "n=6", "-q", "--resume", str(out), "--json")
    assert r.returncode == 0, r.stderr
    assert strict_json(r.stdout)["extra"]["reused"] == [b.id for b in branches]
    got, meta = io.load(out)
    want, _ = io.load(ref)
    assert meta["complete"] is True
    key = lambda bs: [(b.id, sp.name, sp.params["lam"], sp.order_parameter, sp.converged)  # noqa: E731
                      for b in bs for sp in b.special_points]
    assert key(got) == key(want)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a.states, b.states)
    assert not math.isnan(want[0].special_points[0].params["lam"])


# ------------------------------------------------------------------ end to end with real scenes

BRATU_FOLD = 3.513830719125162


def test_bratu_end_to_end_json_info_diagram(tmp_path):
    out = tmp_path / "bratu.h5"
    r = subprocess_contin("trace", "bratu", "--json", "-o", str(out), timeout=120)
    assert r.returncode == 0, r.stderr
    doc = strict_json(r.stdout)
    lps = [s for s in doc["special_points"] if s["type"] == "LP"]
    assert len(lps) == 1 and lps[0]["converged"] is True
    assert abs(lps[0]["params"]["lam"] - BRATU_FOLD) < 1e-9
    assert "LP1" in r.stderr  # human table on stderr
    branches, meta = io.load(out)
    assert meta["complete"] and meta["scene"] == "bratu"
    lp = branches[0].fold_points[0]
    assert lp.params["lam"] == lps[0]["params"]["lam"] and lp.state.size == lp.grid + 1  # located on its own grid (adaptive default)
    r = subprocess_contin("info", str(out))
    assert r.returncode == 0 and "LP1" in r.stdout and "bratu" in r.stdout
    png = tmp_path / "bratu.png"
    r = subprocess_contin("diagram", str(out), "-o", str(png))
    assert r.returncode == 0 and png.read_bytes()[:4] == b"\x89PNG"


def _readme() -> str:
    return (HERE.parent / "README.md").read_text()


def test_ci_script_runs_the_readme_test_command():
    import re

    blocks = re.findall(r"```bash\n(.*?)\n```", _readme(), flags=re.S)
    test_cmd = [b for b in blocks if b.rstrip().endswith("&& pytest")]
    assert len(test_cmd) == 1
    ci = (HERE.parent / ".ci" / "run").read_text()
    assert f'TEST_COMMAND="{test_cmd[0].strip()}"' in ci
    assert "set -euo pipefail" in ci and "-eq 5" in ci


def test_readme_library_example_runs(tmp_path, monkeypatch):
    import re

    section = _readme().split("\n## Library usage\n", 1)[1].split("\n## ", 1)[0]
    (code,) = [b for b in re.findall(r"```python\n(.*?)\n```", section, flags=re.S) if "trace(" in b]
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)
    bps = [bp.params["lam"] for bp in ns["trivial"].branch_points]
    np.testing.assert_allclose(bps, [1.0, 4.0, 9.0], atol=1e-8)
    assert len(ns["branches"]) == 7 and (tmp_path / "allen-cahn.png").exists()


def test_profiles_at_special_point_stored_point_and_interpolated(tmp_path):
    from cli_fixture_scenes import profiles as prof_fn
    from cli_fixture_scenes import toy_branches

    f = _toy_file(tmp_path)
    branches, meta = io.load(f)
    found = {b.id: (how, p) for b, how, p in io.profiles_at(branches, meta, "lam", 0.16)}
    lp = toy_branches()[1].special_points[0]
    assert found["1"][0] == "at LP2"  # exact: the located state's profile
    np.testing.assert_array_equal(found["1"][1]["T"], prof_fn(lp.state)["T"])
    # branch 0 (lam = -1, -0.75, ..., 1): 0.5 is stored point 6, 0.3 lies 20 % of the way 5 -> 6
    (how, p), = [(h, p) for b, h, p in io.profiles_at(branches[:1], meta, "lam", 0.5)]
    assert how == "at stored point 6"
    np.testing.assert_array_equal(p["nu"], prof_fn(branches[0].states[6])["nu"])
    (how, p), = [(h, p) for b, h, p in io.profiles_at(branches[:1], meta, "lam", 0.3)]
    assert how == "interpolated between points 5 and 6"
    want = 0.8 * prof_fn(branches[0].states[5])["T"] + 0.2 * prof_fn(branches[0].states[6])["T"]
    np.testing.assert_allclose(p["T"], want, rtol=1e-12)
    assert io.profiles_at(branches, meta, "lam", 7.0) == []
    png = tmp_path / "p.png"
    r = run("profiles", str(f), "--at", "lam=0.16", "--names", "nu,T", "-o", str(png))
    assert r.exit_code == 0, r.output
    assert "branch 1: at LP2" in r.stderr and png.read_bytes()[:4] == b"\x89PNG"
    one_error_line(run("profiles", str(f), "--at", "lam=7", "-o", str(png)), "reaches lam=7")
    one_error_line(run("profiles", str(f), "--at", "lam=0.1", "--names", "q", "-o", str(png)), "no profile 'q'")
