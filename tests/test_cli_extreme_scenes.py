"""Extreme parameters of the disks and non-local scenes, and problems whose Python-float
arithmetic overflows (session 13 robustness sweep).

Each case used to end in an unrelated or internal message: a branch whose start point does not
converge has no points, and the scene then read its observables (``Error: asym_phi``, ``Error:
shear_stress``, ``index -1 is out of bounds``, ``range object index out of range``); a residual
computing ``W**2`` with Python floats raised OverflowError (``internal error``) at the start
point or after a step ``--ds 1e300``; the non-local start-point message embedded the whole
NewtonResult repr.  Now: one ``Error:`` line that says which branch could not start and why,
and an overflowing step is a failed step (rejected and retried shorter).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from contin.cli import main
from contin.cli._base import error_line
from contin.continuation import trace
from contin.corrector import correct
from contin.extended import ExtendedSystem
from contin.newton import newton
from contin.options import ContinuationOptions, NewtonOptions, StepOptions


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)


def one_error(args: list[str], tmp_path) -> str:
    res = CliRunner().invoke(main, ["trace", *args, "--no-stability", "-q", "--max-steps", "3",
                                    "-o", str(tmp_path / "x.h5")], catch_exceptions=False)
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1, (res.exit_code, res.stderr)
    assert len(errors) == 1 and "Traceback" not in res.stderr, res.stderr
    assert "internal error" not in errors[0] and len(errors[0]) < 400, errors[0]
    return errors[0]


@pytest.mark.parametrize("args, expect", [
    (["nonlocal-shear", "-s", "K=1e300"], "nonlocal-shear: branch uniform.ell could not start: start point ell = 3: estimated relative error"),
    (["nonlocal-muI", "-s", "W=1e300"], "nonlocal-muI: branch muI.U could not start"),
    (["nonlocal-muI", "-s", "A_phi=1e-300"], "nonlocal-muI: branch phiI.U could not start: "),
    (["nonlocal-cylinder", "-s", "W=1e-300"], "nonlocal-cylinder: branch derived.ratio could not start: Newton failed"),
    (["savage-rheology", "--method", "fd2", "--grid", "4"], "savage-rheology: branch a0.0 could not start"),
    (["disks-steady", "--method", "fd2", "--grid", "4"], "disks-steady: branch 0 could not start"),
    (["disks-steady", "-s", "phi_w=1e-300"], "disks-steady: branch 0 could not start"),
])
def test_a_branch_that_cannot_start_is_named_with_its_reason(args, expect, tmp_path):
    assert expect in one_error(args, tmp_path)


def test_start_point_overflow_is_one_line_naming_the_range(tmp_path):
    line = one_error(["nonlocal-cylinder", "-s", "W=1e300"], tmp_path)
    assert "the residual cannot be evaluated at the start point (OverflowError" in line


def test_the_newton_failure_of_a_start_point_is_its_message_not_its_repr(tmp_path):
    line = one_error(["nonlocal-muI", "-s", "K=1e300"], tmp_path)
    assert "NewtonResult" not in line and "array(" not in line


def test_arithmetic_errors_are_named_as_such():
    line = error_line(ZeroDivisionError("float division by zero"))
    assert line.startswith("arithmetic failure (ZeroDivisionError: float division by zero)")
    assert "out of the model's range" in line


class _Overflowing:
    """u - p = 0 whose residual computes exp(p) with Python floats: OverflowError above p ~ 709."""

    def residual(self, u, p):
        math.exp(p["p"])
        return np.array([u[0] - p["p"]])

    def jacobian(self, u, p):
        return np.array([[1.0]])

    def dresidual_dp(self, u, p, name):
        return np.array([-1.0])

    parameter_names = ("p",)


def test_newton_and_corrector_report_an_overflowing_residual_as_a_failed_solve():
    pb = _Overflowing()
    res = newton(pb, np.array([0.0]), {"p": 1e3})
    assert not res.converged and "OverflowError" in res.message
    system = ExtendedSystem(pb, {"p": 0.0}, "p", 0.5)
    system.n = 1
    c = correct(system, np.array([1e3, 1e3]), np.array([0.0, 1.0]), NewtonOptions())
    assert not c.converged and "OverflowError" in c.message


def test_a_step_into_overflow_is_rejected_and_retried_shorter():
    # --ds 1e300 used to end every such run with 'internal error (OverflowError ...)'
    opts = ContinuationOptions(bounds={"p": (0.0, 800.0)}, max_steps=50,
                               step=StepOptions(ds=1e300, ds_max=1e300, ds_min=1e-6))
    br = trace(_Overflowing(), np.array([0.0]), {"p": 0.0}, "p", opts)
    assert len(br) > 1 and br.params["p"].max() < 710


# ----------------------------------------------------------------------------- disks: Luding's global fit
def test_global_fit_far_from_phi_f_is_finite_and_equals_its_limit():
    # exp(-(nu - phi_f)/m_f) overflowed far below phi_f: w_nu = inf/inf = nan, psi nan, and
    # 'contin trace disks-pitchfork -s corr=gf -s m_f=1e-300' said 'psi is not finite (no
    # shear-banding pitchfork)' with exit 0, where G_GF is G_CS there (H_1^c = 15.87).
    from problems.disks.closures import DiskClosure, critical_gaps, pair_correlation
    from problems.disks.model import DEFAULTS

    cs = pair_correlation(np.float64(0.5), "cs", 0.8, 0.9)
    for nu in (np.float64(0.5), np.float64(0.5) + 1e-20j):  # complex steps too
        g, g_nu = pair_correlation(nu, "gf", 0.8, 0.9, 0.7, 1e-300)
        assert np.isfinite(g) and np.isfinite(g_nu)
        assert (np.real(g), np.real(g_nu)) == cs
    fv = pair_correlation(np.float64(0.85), "fv", 0.8, 0.9)
    assert pair_correlation(np.float64(0.85), "gf", 0.8, 0.9, 0.7, 1e-300) == fv
    p = {**DEFAULTS, "nu": 0.5, "e": 0.8, "m_f": 1e-300}
    h_gf, h_cs = critical_gaps(p, DiskClosure(G="gf"), 1), critical_gaps(p, DiskClosure(G="cs"), 1)
    assert math.isfinite(h_gf[0]) and abs(h_gf[0] - h_cs[0]) < 1e-12 * h_cs[0]


@pytest.mark.parametrize("value", ["1e300", "-1", "0", "0.9"])
def test_global_fit_freezing_fraction_outside_0_phi_inf_is_refused(value, tmp_path):
    line = one_error(["disks-pitchfork", "-s", "corr=gf", "-s", f"phi_f={value}"], tmp_path)
    assert "the freezing area fraction phi_f" in line and "must lie in (0, phi_inf = 0.9)" in line


def test_disks_steady_smooth_walls_say_why(tmp_path):
    # used to be 'branch 0: ... initial guess is inadmissible: state has non-finite entries' after
    # a numpy RuntimeWarning line
    res = CliRunner().invoke(main, ["trace", "disks-steady", "-s", "phi_w=0", "--no-stability", "-q",
                                    "-o", str(tmp_path / "x.h5")], catch_exceptions=False)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 1 and len(lines) == 1, res.stderr
    assert lines[0] == ("Error: disks-steady: phi_w = 0 (smooth walls) transmits no shear, so there is no sheared "
                        "steady state; use phi_w > 0")


# ----------------------------------------------------------------------------- damaged files
@pytest.mark.parametrize("dataset, value, expect", [
    ("grid/y", np.nan, "dataset grid/y holds a non-finite value at row 2"),
    ("branches/0/grid", 0, "dataset branches/0/grid holds a grid size outside 1..65536"),
    ("branches/0/grid", 10**9, "dataset branches/0/grid holds a grid size outside 1..65536"),
])
def test_reader_refuses_a_nan_profile_grid_and_impossible_point_grids(dataset, value, expect, tmp_path):
    # NaN in grid/y drew profiles with gaps and exit 0; a grid column of 0 made verify say
    # 'grid too small: cheb needs at least 4 intervals, got 0' instead of naming the damage
    import h5py

    good = tmp_path / "b.h5"
    res = CliRunner().invoke(main, ["trace", "bratu", "--no-stability", "-q", "--max-steps", "5", "-o", str(good)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    with h5py.File(good, "r+") as f:
        a = f[dataset][()]
        a[2] = value
        f[dataset][...] = a
    for cmd in (["info", str(good)], ["verify", str(good)],
                ["profiles", str(good), "--at", "lam=0.1", "-o", str(tmp_path / "p.png")]):
        res = CliRunner().invoke(main, cmd, catch_exceptions=False)
        lines = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
        assert res.exit_code == 1 and len(lines) == 1, (cmd, res.stderr)
        assert "is damaged: " + expect in lines[0], lines[0]


def test_reader_refuses_a_nan_run_parameter(tmp_path):
    # a NaN in the root attribute 'parameters' was shown by info (exit 0) and rebuilt into the
    # problems of verify / stability / continue
    import json

    import h5py

    good = tmp_path / "b.h5"
    res = CliRunner().invoke(main, ["trace", "bratu", "--no-stability", "-q", "--max-steps", "5", "-o", str(good)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    with h5py.File(good, "r+") as f:
        params = json.loads(f.attrs["parameters"])
        name = next(iter(params))
        params[name] = float("nan")
        f.attrs["parameters"] = json.dumps(params)
    for cmd in (["info", str(good)], ["verify", str(good)], ["diagram", str(good), "-o", str(tmp_path / "d.png")]):
        res = CliRunner().invoke(main, cmd, catch_exceptions=False)
        lines = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
        assert res.exit_code == 1 and len(lines) == 1, (cmd, res.stderr)
        assert f"is damaged: attribute parameters holds NaN for {name!r}" in lines[0], lines[0]


def _relabelled(tmp_path, scene_args, scene):
    import h5py

    path = tmp_path / f"{scene_args[0]}_as_{scene}.h5"
    res = CliRunner().invoke(main, ["trace", *scene_args, "--no-stability", "-q", "--max-steps", "3", "-o", str(path)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    with h5py.File(path, "r+") as f:
        f.attrs["scene"] = scene
    return path


@pytest.mark.parametrize("made_by, named, command, expect", [
    # states of another size: 'Error: index 39 is out of bounds for axis 0 with size 13'
    (["bratu"], "disks-steady", "verify", "have no 'nu', 'e', 'H'"),
    # the same size, a parameter the problem reads is missing: 'Error: num'
    (["disks-steady"], "pitchfork", "verify", "the run's parameters have no 'num', which the rebuilt problem needs"),
    # the same size: a stability table of the wrong problem, exit 0
    (["disks-steady"], "pitchfork", "stability", "have no 'num', which the rebuilt problem needs"),
])
def test_a_file_of_another_scene_is_refused_in_one_line(made_by, named, command, expect, tmp_path):
    path = _relabelled(tmp_path, made_by, named)
    args = [command, str(path)] + (["--point", "1"] if command == "stability" else [])
    res = CliRunner().invoke(main, args, catch_exceptions=False)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(lines) == 1, (res.exit_code, res.stderr)
    assert expect in lines[0] and "Traceback" not in res.stderr, lines[0]


def test_verify_refuses_states_that_do_not_fit_their_grid(tmp_path):
    # per-point grid column edited (8 -> 16): 'Error: index 39 is out of bounds' before
    import h5py

    path = _relabelled(tmp_path, ["disks-steady"], "disks-steady")
    with h5py.File(path, "r+") as f:
        g = f["branches/0/grid"][()]
        f["branches/0/grid"][...] = 2 * g
    res = CliRunner().invoke(main, ["verify", str(path)], catch_exceptions=False)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(lines) == 1, (res.exit_code, res.stderr)
    assert "entries but the problem rebuilt for it (grid 16) has" in lines[0]
    assert "the file's scene or discretization does not match its states" in lines[0]


# ----------------------------------------------------------------------------- contin continue -o
def _fold_run(tmp_path):
    path = tmp_path / "sb.h5"
    res = CliRunner().invoke(main, ["trace", "stretched-bratu", "--grid", "24", "--resolution-tol", "1e-8", "--stop-at",
                                    "LP1", "--no-stability", "-q", "-o", str(path)], catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    return path


CONTINUE = ["--from", "LP1", "--free", "a", "--bounds", "a=-0.5:1", "--bounds", "lam=0:8", "--max-steps", "3"]


def test_continue_refuses_to_overwrite_its_own_input(tmp_path):
    # 'contin continue sb.h5 ... -o sb.h5' replaced the run with the curve, exit 0
    from contin import io

    src = _fold_run(tmp_path)
    before = src.read_bytes()
    res = CliRunner().invoke(main, ["continue", str(src), *CONTINUE, "-o", str(src)], catch_exceptions=False)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(lines) == 1, res.stderr
    assert "is the input file" in lines[0] and "would replace the run it starts from" in lines[0]
    assert src.read_bytes() == before
    assert [b.id for b in io.load(src)[0]] == ["0"]


def test_continue_refuses_an_output_another_run_is_writing(tmp_path):
    # the curve was written into a file whose lock another contin run held (trace refuses that)
    import subprocess
    import sys

    src = _fold_run(tmp_path)
    out = tmp_path / "busy.h5"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from contin.atomic import OutputLock; "
                               "OutputLock(sys.argv[1]).acquire(); print('held', flush=True); time.sleep(60)", str(out)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        res = CliRunner().invoke(main, ["continue", str(src), *CONTINUE, "-o", str(out)], catch_exceptions=False)
    finally:
        holder.kill()
        holder.wait()
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(lines) == 1, res.stderr
    assert "is being written by another contin run" in lines[0]
    assert not out.exists()
    res = CliRunner().invoke(main, ["continue", str(src), *CONTINUE, "-o", str(out)], catch_exceptions=False)
    assert res.exit_code == 0 and out.exists(), res.stderr  # and the lock is released after the command
    assert not (tmp_path / ".busy.h5.lock").exists()


def test_first_crossing_neither_overflows_nor_misses_an_underflowing_crossing():
    import warnings

    from contin.branch import first_crossing

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 'overflow encountered in multiply' for --at H=1e300
        assert first_crossing(np.array([2.0, 43.0]), 1e300) is None
        assert first_crossing(np.array([1e200, 3e200]), -1e200) is None
    hit = first_crossing(np.array([1e-200, -1e-200]), 0.0)  # the product underflowed to -0.0: None
    assert hit is not None and hit[:2] == (0, 1) and hit[3] == 1


def test_a_start_guess_that_is_inadmissible_does_not_blame_the_jacobian(tmp_path):
    # 'initial guess is inadmissible: normal stress P = 0 <= 0; check the Jacobian with
    # contin.problem.check_jacobian': no Jacobian was used yet
    line = one_error(["nonlocal-muI", "-s", "A_phi=1e-300"], tmp_path)
    assert "initial guess is inadmissible" in line and "check the Jacobian" not in line


def test_savage_negative_contact_scale_is_refused(tmp_path):
    # -s a0_over_kn=-1 ran to exit 0 with negative contact pressures (a0_band = -1 was refused)
    line = one_error(["savage-rheology", "-s", "a0_over_kn=-1"], tmp_path)
    assert "a0_over_kn = -1 must be >= 0" in line


@pytest.mark.parametrize("args, expect", [
    # scipy: 'The function value at x=2.0020040080160324e+297 is NaN; solver cannot continue.'
    (["disks-criticality", "-s", "phi_inf=1e300"], "maximum area fraction phi_inf = 1e+300 must lie in (0, 1)"),
    # numpy: 'Maximum allowed size exceeded'
    (["disks-criticality", "-s", "dnu=1e-300"], "area fractions; at most 1000"),
    # 'parameter H = -1e+300 is out of range; it must satisfy 0 < H < inf'
    (["gravity-unfolding", "-s", "window=1e300"], "window = 1e+300 must be below the pitchfork's H_c = 13.0685"),
])
def test_range_parameters_of_criticality_and_unfolding_scenes(args, expect, tmp_path):
    assert expect in one_error(args, tmp_path)


def test_a_reader_closing_stderr_does_not_stop_the_run(tmp_path):
    # 'contin trace pitchfork ... 2>&1 | head -1': the second progress line raised BrokenPipeError
    # and the run ended (exit 1, 'incomplete: the run failed: Broken pipe', 2 of 7 branches)
    import os
    import subprocess
    import sys

    from contin import io

    out = tmp_path / "pf.h5"
    env = {k: v for k, v in os.environ.items() if k not in ("CONTIN_SCENES", "CONTIN_DEBUG")}
    proc = subprocess.Popen([sys.executable, "-m", "contin", "trace", "pitchfork", "--grid", "24", "--max-steps", "20",
                             "--no-stability", "-o", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env=env)
    assert proc.stderr.readline().strip()  # the first progress line, then the reader goes away
    proc.stderr.close()
    assert proc.wait(timeout=120) == 3  # the run's own exit code: some banded branches end MX on cheb 24
    branches, meta = io.load(out)
    assert meta["complete"] and len(branches) == 7


def test_nonlocal_shear_wall_friction_beyond_its_branch_is_named(tmp_path):
    # 'Error: start value mu_w=0.3617 lies outside its bounds (0, 0.354564)', after 2 branches
    line = one_error(["nonlocal-shear", "-s", "mu_w=0.3617"], tmp_path)
    assert "mu_w = 0.3617 must be below 0.98 mu = 0.354564" in line


def test_max_grid_below_the_scenes_start_grid_holds_from_the_start(tmp_path):
    # disks-pitchfork starts on cheb 64: with a tol no grid meets the start stayed there and the
    # branch ended 'under-resolved ... on the maximum grid 64 (AdaptOptions.max_grid = 16)'
    from contin import io

    out = tmp_path / "mg.h5"
    res = CliRunner().invoke(main, ["trace", "disks-pitchfork", "-s", "corr=cs", "--tol", "1e-30", "--max-grid", "16",
                                    "--no-stability", "-q", "-o", str(out)], catch_exceptions=False)
    assert res.exit_code == 3, res.stderr
    (b,), _ = io.load(out)
    assert "on the maximum grid 16 (AdaptOptions.max_grid = 16)" in b.message
    assert any("start grid lowered 64 -> 16" in m for m in b.audit)
    assert b.grid is None or int(np.max(b.grid)) <= 16


def test_repeated_user_zero_values_give_one_point_per_crossing(tmp_path):
    # 'contin trace bratu --uz lam=1,1,1' stored UZ1, UZ2, UZ3 at the same point (and 3 more past the fold)
    from contin import io
    from contin.options import ContinuationOptions

    assert ContinuationOptions(user_zeros={"lam": (1.0, 1.0, 2.0, 1.0)}).user_zeros == {"lam": (1.0, 2.0)}
    out = tmp_path / "uz.h5"
    res = CliRunner().invoke(main, ["trace", "bratu", "--uz", "lam=1,1,1", "--no-stability", "-q", "-o", str(out)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.stderr
    (b,), _ = io.load(out)
    assert len([sp for sp in b.special_points if sp.type == "UZ"]) == 2  # lam = 1 below and above the fold
