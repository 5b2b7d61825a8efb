"""``--resolution-tol FLOAT|off`` on ``contin trace`` (also of the gPCF ``gravity-phase`` scene, formerly
``contin unfold``) and ``contin accuracy``:
ContinuationOptions.resolution_tol for every trace of the run (contin.options.resolution_override),
one ``Error:`` line (exit 1) for a bad value.

The scene is tests/resolution_fixture_scenes.py (a toy whose declared error 10^(lam - 8) passes
tol at lam = 8 + log10(tol)); it traces one branch with options_for and one with options of its
own, as gPCF scenes do.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main
from contin.options import (
    ContinuationOptions,
    effective_resolution_tol,
    resolution_override,
)

HERE = Path(__file__).parent
SCENES_ENV = "resolution_fixture_scenes:SCENES"


@pytest.fixture(autouse=True)
def guarded_scene(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", SCENES_ENV)


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def trace_json(*args: str):
    r = run("trace", "guarded", "--json", *args)
    return r, json.loads(r.stdout)


def rejected_at(message: str) -> float:
    """The lam of 'under-resolved at lam = X: ...'."""
    return float(message.split("under-resolved at lam = ")[1].split(":")[0])


def test_default_tolerance_stops_every_branch_at_3e_5():
    r, doc = trace_json()
    assert r.exit_code == 3  # a branch ended with MX
    for b in doc["branches"]:
        assert b["status"] == "MX"
        assert rejected_at(b["message"]) > 8 + math.log10(3e-5) > rejected_at(b["message"]) - 0.25 * math.sqrt(5)
    assert doc["extra"]["options_resolution_tol"] == 3e-5


def test_tolerance_reaches_the_scene_options_and_its_own_traces(tmp_path):
    out = tmp_path / "g.h5"
    r, doc = trace_json("--resolution-tol", "1e-5", "-o", str(out))
    assert r.exit_code == 3
    by_id = {b["id"]: b for b in doc["branches"]}
    for bid in ("0", "own"):  # 'own' is traced with options the scene built itself
        assert by_id[bid]["status"] == "MX" and by_id[bid]["message"].endswith("> 1e-05")
        assert 3.0 < rejected_at(by_id[bid]["message"]) < 3.0 + 0.25 * math.sqrt(5)
    assert doc["extra"]["options_resolution_tol"] == 1e-5
    _, meta = io.load(out)
    assert meta["options"]["resolution_tol"] == 1e-5  # the file records the setting


@pytest.mark.parametrize("value", ["off", "OFF", " off "])
def test_off_switches_the_guard_off_everywhere(tmp_path, value):
    out = tmp_path / "g.h5"
    r, doc = trace_json("--resolution-tol", value, "-o", str(out))
    assert r.exit_code == 0, r.stderr
    assert [(b["id"], b["status"], b["message"]) for b in doc["branches"]] == [
        ("0", "EP", "reached bound lam=6"), ("own", "EP", "reached bound lam=6")]
    assert doc["extra"]["options_resolution_tol"] is None
    _, meta = io.load(out)
    assert meta["options"]["resolution_tol"] is None


def test_loose_tolerance_reaches_the_bound():
    r, doc = trace_json("--resolution-tol", "0.1")  # err(6) = 0.01
    assert r.exit_code == 0 and {b["status"] for b in doc["branches"]} == {"EP"}


BAD = ["0", "-1e-5", "nan", "inf", "-inf", "abc", "", "1e-5x", "of"]


def one_error_line(result, expect: str) -> None:
    assert result.exit_code == 1, (result.exit_code, result.output)
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and expect in lines[0], result.stderr
    assert "Traceback" not in result.output and result.stdout == ""


@pytest.mark.parametrize("value", BAD)
@pytest.mark.parametrize("command", [["trace", "guarded"], ["trace", "gravity-phase"], ["accuracy", "guarded"]])
def test_bad_value_is_one_error_line(command, value):
    r = run(*command, "--resolution-tol", value)
    one_error_line(r, f"--resolution-tol must be a number > 0 (largest estimated relative discretization error "
                      f"of a stored state) or 'off', got {value!r}")


def test_bad_value_in_a_subprocess():
    env = {**os.environ, "CONTIN_SCENES": SCENES_ENV,
           "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    env.pop("CONTIN_DEBUG", None)
    r = subprocess.run([sys.executable, "-m", "contin", "trace", "guarded", "--resolution-tol", "-3"],
                       capture_output=True, text=True, env=env, timeout=60, check=False)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.strip().splitlines() == [
        ("Error: --resolution-tol must be a number > 0 (largest estimated relative discretization error of a "
         "stored state) or 'off', got '-3'")]


def test_help_names_the_option():
    for command in ("trace", "accuracy"):
        r = run(command, "--help")
        assert r.exit_code == 0 and "--resolution-tol FLOAT|off" in r.output


def test_override_is_scoped():
    opts = ContinuationOptions(resolution_tol=2e-5)
    assert effective_resolution_tol(opts) == 2e-5
    with resolution_override(None):
        assert effective_resolution_tol(opts) is None
        with resolution_override(1e-3):
            assert effective_resolution_tol(opts) == 1e-3
        assert effective_resolution_tol(opts) is None
    with pytest.raises(RuntimeError), resolution_override(1e-4):
        raise RuntimeError("the override ends with the block, also on an exception")
    assert effective_resolution_tol(opts) == 2e-5
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="resolution_tol must be a finite number > 0"), resolution_override(bad):
            pass


def test_unfold_guard_off_on_a_resolved_run(tmp_path):
    """gPCF fold curve of the first imperfect pitchfork (nu = 0.3, e = 0.8, cheb 24, H <= 20; scene
    gravity-phase, formerly `contin unfold`): every state is resolved far below 3e-5, so switching
    the guard off changes nothing (Fr* = 254.12038, the default run's value); the setting is in the
    file's options."""
    out = tmp_path / "phase.h5"
    r = run("trace", "gravity-phase", "--grid", "24", "-s", "H_max=20", "--json", "--resolution-tol", "off",
            "-q", "-o", str(out))
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["extra"]["fr_min_floating_plug"] == pytest.approx(254.1203789772, rel=1e-10)
    assert [(c["id"], c["status"]) for c in doc["branches"]] == [("fold0", "EP")]
    _, meta = io.load(out)
    assert meta["options"]["overrides"]["resolution_tol"] is None