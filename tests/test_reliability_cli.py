"""Issue 16, bad and extreme input: every case is one ``Error:`` line and a non-zero exit before
anything is computed (exit 2 for click usage errors, 1 otherwise), never a hang, a traceback or
a silent fallback with exit 0.  Scenes: the hand-built 'toy' (tests/cli_fixture_scenes.py) and
'normalform' (tests/sweep_fixture_scenes.py).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main

HERE = Path(__file__).parent


@pytest.fixture(autouse=True)
def toy_scenes(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", "cli_fixture_scenes:SCENES,sweep_fixture_scenes:SCENES")


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def one_error(r, expect: str, codes=(1, 2)) -> None:
    assert r.exit_code in codes, (r.exit_code, r.output)
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1 and expect in errors[0], r.stderr
    assert "Traceback" not in r.output and r.stdout == ""


@pytest.fixture
def toy_file(tmp_path):
    out = tmp_path / "toy.h5"
    assert run("trace", "toy", "-q", "-o", str(out)).exit_code == 0
    return out


@pytest.mark.parametrize("args, expect", [
    (("--ds", "inf"), "must be a finite number > 0"),
    (("--ds-max", "inf"), "must be a finite number > 0"),
    (("--ds", "nan"), "'--ds'"),
    (("--grid", "1000000000"), "2<=x<=65536"),
    (("--max-steps", "10000000000"), "1<=x<=1000000"),
    (("--kx", "nan"), "must be a finite number with |kx| <= 10000"),
    (("--kx", "inf"), "must be a finite number with |kx| <= 10000"),
    (("--kx", "1e300"), "must be a finite number with |kx| <= 10000"),
    (("--kx", ",".join(["0.5"] * 33)), "33 wavenumbers; at most 32"),
    (("--method", ""), "must not be empty"),
    (("--method", "  "), "must not be empty"),
])
def test_trace_refuses_bad_sizes_and_steps(tmp_path, args, expect):
    out = tmp_path / "x.h5"
    one_error(run("trace", "toy", *args, "-o", str(out)), expect)
    assert not out.exists()


def test_trace_refuses_a_figure_suffix_for_its_hdf5_output(tmp_path):
    one_error(run("trace", "toy", "-o", str(tmp_path / "x.png")), "has suffix '.png', but this command writes an HDF5")
    assert not (tmp_path / "x.png").exists()


def test_limits_are_stated_in_help():
    text = run("trace", "--help").output
    for limit in ("2..65536", "1..1000000", "at most 32", "finite number > 0"):
        assert limit in text, limit
    assert "at most 10000 values" in run("stability", "--help").output


def test_resume_with_another_discretization_is_refused(toy_file):
    # the toy run stores method=none, intervals=4
    one_error(run("trace", "toy", "--resume", str(toy_file), "--grid", "8"), "was computed with --grid 4, not 8")
    one_error(run("trace", "toy", "--resume", str(toy_file), "--method", "cheb"), "was computed with --method none")
    before = toy_file.read_bytes()
    assert toy_file.read_bytes() == before
    r = run("trace", "toy", "--resume", str(toy_file), "--grid", "4", "-q")  # the same one is fine
    assert r.exit_code == 0, r.output


def test_profiles_at_non_finite_value_and_empty_names(toy_file, tmp_path):
    for at in ("lam=inf", "lam=-inf"):
        one_error(run("profiles", str(toy_file), "--at", at, "-o", str(tmp_path / "p.png")), "'--at'")
    one_error(run("profiles", str(toy_file), "--at", "lam=nan", "-o", str(tmp_path / "p.png")), "is not a number")
    one_error(run("profiles", str(toy_file), "--at", "lam=0.5", "--names", "", "-o", str(tmp_path / "p.png")),
              "must not be empty")
    assert not (tmp_path / "p.png").exists()


def test_diagram_empty_axis_names(toy_file, tmp_path):
    for opt in ("-x", "-y"):
        one_error(run("diagram", str(toy_file), opt, "", "-o", str(tmp_path / "d.png")), "must not be empty")


def test_stability_kx_range_with_a_billion_values_is_refused_at_once(toy_file):
    from contin.cli.stability import parse_kx_spec

    with pytest.raises(ValueError, match="COUNT must be at most 10000"):
        parse_kx_spec("0:3:1000000000")
    with pytest.raises(ValueError, match=r"\|kx\| <= 10000"):
        parse_kx_spec("1e300")
    assert parse_kx_spec("0:3:4") == [0.0, 1.0, 2.0, 3.0]
    one_error(run("stability", str(toy_file), "--point", "0", "--kx", "0:3:1000000000"), "COUNT must be at most 10000")
    one_error(run("stability", str(toy_file), "--point", "0", "--kz", "1e300"), "--kz must be a finite number")


def test_accuracy_with_one_grid_is_an_error():
    one_error(run("accuracy", "bratu", "--grids", "16"), "at least two different grid sizes")
    one_error(run("accuracy", "bratu", "--grids", "16,100000"), "at most 65536")


@pytest.mark.parametrize("option, expect", [
    ("ds = inf", "option 'ds'"), ("ds = nan", "option 'ds'"), ("ds_max = inf", "option 'ds_max'"),
    ("grid = 1000000000", "option 'grid'"), ("kx = [nan]", "option 'kx'"), ("kx = [1e300]", "option 'kx'"),
])
def test_sweep_options_non_finite_or_huge_are_refused(tmp_path, option, expect):
    sweep = tmp_path / "s.toml"
    sweep.write_text(f'[sweep]\nscene = "normalform"\n[grid]\na = [0.0, 1.0]\n[options]\n{option}\n')
    one_error(run("sweep", str(sweep), "-o", str(tmp_path / "out")), expect)
    assert not (tmp_path / "out" / "summary.json").exists()


def test_progress_lines_on_a_non_terminal(tmp_path, monkeypatch):
    """A heartbeat line every CONTIN_PROGRESS_SECONDS while a run is busy, and a line per branch."""
    monkeypatch.setenv("CONTIN_PROGRESS_SECONDS", "0.2")
    r = run("trace", "toy", "-s", "delay=0.6", "-s", "n=3", "-o", str(tmp_path / "x.h5"))
    assert r.exit_code == 0, r.output
    lines = r.stderr.splitlines()
    assert sum("running: branch" in ln for ln in lines) >= 3
    assert sum(ln.endswith("EP bound reached") and "] branch " in ln for ln in lines) == 3
    assert io.load(tmp_path / "x.h5")[1]["complete"]
    quiet = run("trace", "toy", "-s", "delay=0.6", "-q", "-o", str(tmp_path / "y.h5"))
    assert quiet.stderr == ""


@pytest.mark.parametrize("args, expect", [
    # `contin unfold -s Fr_start=-100` printed "smallest Fr ... nan": now the gravity-phase scene
    (("gravity-phase", "-s", "Fr_start=-100"), "Fr_start (the Fr at which each fold is first found) must be > 0"),
    (("gravity-phase", "-s", "H_min=inf"), "must be finite"),
    # unknown -s names on `fit --compute` were ignored: now the gravity-unfolding scene
    (("gravity-unfolding", "-s", "bogus=1"), "unknown parameter 'bogus' for scene 'gravity-unfolding'"),
    (("gravity-unfolding", "-s", "G=1e-7,nan"), "G needs positive finite gravities"),
    # outputs are checked before computing (unfold -o missing/u.png, fit --compute missing/fit.h5)
    (("gravity-phase", "-o", "missing_dir_xyz/u.h5"), "directory 'missing_dir_xyz' does not exist"),
    (("gravity-unfolding", "-o", "missing_dir_xyz/fit.h5"), "directory 'missing_dir_xyz' does not exist"),
])
def test_former_unfold_and_fit_compute_inputs_are_refused_before_computing(args, expect):
    one_error(run("trace", *args), expect)


def test_continue_refuses_a_figure_suffix_for_its_hdf5_output(toy_file, tmp_path):
    one_error(run("continue", str(toy_file), "--from", "LP2", "--free", "a", "-o", str(tmp_path / "c.png")),
              "has suffix '.png', but this command writes an HDF5")
