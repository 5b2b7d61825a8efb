"""Robustness sweep, round 2 (session 14, qa14): extreme parameters of the gPCF scenes, the demo
scenes' newer features, the Python API's argument checks, interrupted and concurrent runs.

Each test names the command that misbehaved before its fix (a raw numpy/KeyError message, a
silent loss with exit 0, a RuntimeWarning on stderr, ...).
"""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from contin.cli import main


@pytest.fixture(autouse=True)
def real_scenes(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)


def run(args: list[str]):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def test_pitchfork_banded_branches_that_cannot_start_are_named_and_exit_3(tmp_path):
    """`contin trace pitchfork -s e=0.9999999 --grid 24` ended with `Error: phi` (the criticality fit
    read the observables of a banded branch of no points); with that fixed the branches that could
    not start were dropped silently, exit 0.  Now each is a warning with its reason, exit 3, and the
    base branch is written."""
    out = tmp_path / "pf.h5"
    res = run(["trace", "pitchfork", "-s", "e=0.9999999", "--grid", "24", "--no-stability", "--max-steps", "20",
               "-o", str(out)])
    assert res.exit_code == 3, res.stderr
    assert "Error:" not in res.stderr and "Traceback" not in res.stderr
    warnings = [ln for ln in res.stderr.splitlines() if "could not start (MX, not stored)" in ln]
    assert warnings and all(ln.startswith("warning: branch n") for ln in warnings), res.stderr
    info = run(["info", str(out)])
    assert info.exit_code == 0 and "uniform shear" in info.stderr + info.stdout


@pytest.mark.parametrize("fr", ["1e-3", "0.3"])
def test_gravity_whose_every_branch_cannot_start_is_one_error_line(fr, tmp_path):
    """`contin trace gravity -s Fr=1e-3 --grid 24 -s max_grid=0` ended with `Error: zero-size array to
    reduction operation minimum which has no identity` (classify took np.min of a 0-point branch)."""
    res = run(["trace", "gravity", "-s", f"Fr={fr}", "--grid", "24", "-s", "max_grid=0", "--no-stability",
               "--max-steps", "20", "-q", "-o", str(tmp_path / "g.h5")])
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(errors) == 1, res.stderr
    assert errors[0].startswith("Error: gravity: branch 0 could not start: Newton failed at the start point H=1")


def test_jj_walls_isolated_branch_that_cannot_start_is_named_and_exit_3(tmp_path):
    """`contin trace jj-walls -s nu=0.02 --grid 24` ended with `Error: phi`: the isolated symmetric
    branch s1 was found (Newton converged from the slip guess) but its start point is under-resolved,
    and the departure from the base branch read the observables of its 0 points."""
    res = run(["trace", "jj-walls", "-s", "nu=0.02", "--grid", "24", "--no-stability", "--max-steps", "20",
               "-o", str(tmp_path / "j.h5")])
    assert res.exit_code == 3 and "Error:" not in res.stderr, res.stderr
    assert ("warning: branch s1 could not start (MX, not stored): start point under-resolved at H = 198"
            in res.stderr), res.stderr


@pytest.mark.parametrize("args, expect", [
    (["nonlocal-cylinder", "-s", "W=1e-300"], "residual is not finite at the initial guess"),
    (["nonlocal-muI", "-s", "A_phi=1e-300"], "initial guess is inadmissible"),
])
def test_a_non_finite_start_residual_prints_no_runtime_warning(args, expect, tmp_path):
    """`contin trace nonlocal-cylinder -s W=1e-300` printed numpy's 'RuntimeWarning: divide by zero
    encountered in divide' lines (with their source lines) above its one Error line: the start
    point's shape probe evaluated the residual without np.errstate.  The failure itself is the
    start point's Newton message."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = run(["trace", *args, "--no-stability", "-q", "--max-steps", "3", "-o", str(tmp_path / "x.h5")])
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(errors) == 1, res.stderr
    assert expect in errors[0] and "RuntimeWarning" not in res.stderr, res.stderr


def test_hopf_point_of_an_adaptive_run_is_continued_on_its_own_grid(tmp_path):
    """`contin trace brusselator` (adaptive: HB1 on grid 12, file grid 32) then `contin continue
    FILE --from HB1 --free a` said 'continue it with --tol REL', and with --tol 'adaptive grids are
    not available for BP/Hopf curves ... (without --tol)': the HB could not be continued at all.
    Now the curve runs on HB1's own grid; its ends on b = 4, 6 are the closed form
    b = 1 + a^2 + (D1 + D2) k^2, k^2 the grid's smallest Dirichlet eigenvalue (HB1's own b)."""
    import h5py
    import numpy as np

    from contin import io

    src, out = tmp_path / "br.h5", tmp_path / "c.h5"
    res = run(["trace", "brusselator", "--no-stability", "-q", "-o", str(src)])
    assert res.exit_code == 0, res.stderr
    branches, _ = io.load(str(src))
    hb = branches[0].points("HB")[0]
    assert hb.grid is not None and hb.grid != 32
    res = run(["continue", str(src), "--from", "HB1", "--free", "a", "--max-steps", "30", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    curve = io.load(str(out))[0][0]
    assert set(curve.grid.tolist()) == {hb.grid}
    dk2 = hb.params["b"] - 1 - 4.0  # (D1 + D2) k^2 of HB1's grid, a = 2
    ends = {round(sp.params["b"]): sp.params["a"] for sp in curve.points("EP")}
    assert ends.keys() == {4, 6}
    for b, a in ends.items():
        assert abs(a - np.sqrt(b - 1 - dk2)) < 1e-8 * a
    info = run(["info", str(out)])
    assert info.exit_code == 0 and f"on the fixed grid {hb.grid} of HB1" in info.stderr + info.stdout
    with h5py.File(out) as f:
        assert f.attrs["scene"] == "brusselator"


def test_stretched_bratu_stability_does_not_count_the_boundary_rows(tmp_path):
    """`contin trace stretched-bratu` printed a raw 'blas.py:146: UserWarning: ... no mass_matrix'
    and stored n_unstable = 2 on the stable lower branch (3 past the fold): the two Dirichlet rows
    counted as unstable modes, exit 0.  Bratu's lower branch is stable, its upper branch has one
    unstable mode."""
    from contin import io

    out = tmp_path / "s.h5"
    res = run(["trace", "stretched-bratu", "-q", "-o", str(out)])
    assert res.exit_code == 0 and "Warning" not in res.stderr, res.stderr
    branch = io.load(str(out))[0][0]
    fold = branch.fold_points[0].index
    assert set(branch.n_unstable[:fold].tolist()) == {0}
    assert set(branch.n_unstable[fold + 1:].tolist()) == {1}


def test_accuracy_measures_hopf_points_of_the_brusselator():
    """`contin accuracy brusselator --methods cheb,fd2,fd4 --grids 8,16,32` ended 'Error: no key points:
    ... found no BP/LP': the scene's key point is its Hopf point.  HBs are key points now; fd2
    converges at order 2, fd4 above 3 from 16 to 32, Chebyshev to rounding on 16."""
    import json

    res = run(["accuracy", "brusselator", "--methods", "cheb,fd2,fd4", "--grids", "8,16,32", "--no-memory",
               "--no-plots", "--json"])
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    rows = [r for r in doc["rows"] if r["key"] == "0/HB1"]
    assert len(rows) == 9
    order = {(r["method"], r["grid"]): r["order"] for r in rows}
    assert abs(order[("fd2", 32)] - 2) < 0.05 and order[("fd4", 32)] > 3
    err = {(r["method"], r["grid"]): r["error"] for r in rows}
    assert err[("cheb", 16)] < 1e-12


def test_python_warnings_are_one_warning_line():
    """A Python warning reached the terminal in its two-line default format (file:line: UserWarning:
    ... and the source line `return fn(*args, **kwargs)`).  The CLI prints it as one `warning:` line."""
    import subprocess
    import sys

    code = ("import warnings, click\n"
            "from contin.cli import main\n"
            "@main.command('warn-once')\n"
            "def warn_once():\n"
            "    warnings.warn('something doubtful\\n  on two lines', UserWarning)\n"
            "    warnings.warn('overflow encountered in exp', RuntimeWarning)\n"
            "main(['warn-once'])\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stderr.splitlines() == ["warning: something doubtful on two lines",
                                       "warning: RuntimeWarning: overflow encountered in exp"], res.stderr


def test_swift_hohenberg_trace_prints_no_mass_matrix_warning(tmp_path):
    """`contin trace swift-hohenberg` (and --depth 1) printed the stability pass's 'the problem has no
    mass_matrix ... may count as unstable' on every run: every row of Swift-Hohenberg is dynamic,
    M = I is its mass matrix, now declared.  Same branch, same stability."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        res = run(["trace", "swift-hohenberg", "-q", "-o", str(tmp_path / "sh.h5")])
    assert res.exit_code == 0 and res.stderr == "", res.stderr


def test_stability_of_a_demo_scene_file_defaults_to_k_0(tmp_path):
    """`contin stability br.h5 --point HB1` on a brusselator (or lorenz, stretched-bratu) file ended
    'Error: this problem has no eigenproblem(u, p, kx, kz) method, so only kx = kz = 0 is available':
    the default --kx 0:3:61 is gPCF's wavenumber range.  Without --kx such problems get k = 0; at the
    Hopf point the growth rate is 0 (to rounding), a stated --kx 1 is still refused."""
    import json

    src = tmp_path / "br.h5"
    assert run(["trace", "brusselator", "--no-stability", "-q", "-o", str(src)]).exit_code == 0
    res = run(["stability", str(src), "--point", "HB1", "--json"])
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["kx"] == [0.0] and abs(doc["growth_rate"][0]) < 1e-9
    res = run(["stability", str(src), "--point", "HB1", "--kx", "1"])
    assert res.exit_code == 1 and "only kx = kz = 0 is available" in res.stderr


def test_a_bp_that_the_second_parameter_keeps_is_not_traced_as_a_fold_curve(tmp_path):
    """`contin continue pf.h5 --from BP2 --free e` (gPCF, the symmetric mode-2 pitchfork of uniform
    shear, which e keeps) traced the BP locus as a Moore-Spence "fold curve" and reported cusps along
    it (CP rows, some 'converged'), exit 0: psi . dF/de was rounding (2.4e-8 of |psi| |dF/de|, above
    UNFOLD_TOL).  Now it is one Error line; the symmetry-breaking BP1 in e is still a BP curve."""
    src = tmp_path / "pf.h5"
    res = run(["trace", "pitchfork", "-s", "modes=1", "--grid", "32", "--no-stability", "-q", "-o", str(src)])
    assert res.exit_code in (0, 3), res.stderr
    res = run(["continue", str(src), "--from", "BP2", "--free", "e", "--bounds", "e=0.7:0.9", "--max-steps", "10",
               "-o", str(tmp_path / "c.h5")])
    assert res.exit_code == 1, res.stderr
    assert "Error: 'e' does not unfold BP2" in res.stderr and "CP" not in res.stderr
    res = run(["continue", str(src), "--from", "BP1", "--free", "e", "--bounds", "e=0.75:0.85", "--max-steps", "5",
               "-o", str(tmp_path / "c1.h5")])
    assert res.exit_code == 0 and "BP curve from BP1" in res.stderr, res.stderr


def test_the_python_api_names_the_wrong_argument():
    """README's library calls with wrong types met deep numpy/Python errors ('could not convert string
    to float', "'<' not supported between 'str' and 'int'", "'dict' object has no attribute 'step'",
    'sequence item 0: expected str instance'), or passed silently: max_steps=2.5, user_zeros
    {'lam': '12'} (UZ at 1 and 2), a complex u0 (imaginary part dropped with a ComplexWarning),
    lam='0.5'.  Now each is a TypeError/ValueError naming the argument."""
    import numpy as np

    from contin.continuation import trace
    from contin.options import ContinuationOptions, NewtonOptions, StepOptions
    from problems.demo import AllenCahn

    pb = AllenCahn(method="cheb", intervals=16)
    u0 = pb.initial()
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.3), bounds={"lam": (0.0, 3.0)}, max_steps=5)
    cases = [
        (lambda: trace(pb, u0, {"lam": "0.5"}, "lam", opts), TypeError, "parameter 'lam' must be a real number"),
        (lambda: trace(pb, u0, {"lam": None}, "lam", opts), TypeError, "parameter 'lam' must be a real number"),
        (lambda: trace(pb, u0, [0.5], "lam", opts), TypeError, "params must be a mapping"),
        (lambda: trace(pb, "abc", {"lam": 0.5}, "lam", opts), TypeError, "u0 (the start state)"),
        (lambda: trace(pb, None, {"lam": 0.5}, "lam", opts), TypeError, "u0 (the start state)"),
        (lambda: trace(pb, u0 + 1j, {"lam": 0.5}, "lam", opts), TypeError, "u0 (the start state) must be real"),
        (lambda: trace(pb, u0, {"lam": 0.5}, "lam", {"max_steps": 5}), TypeError, "options must be a ContinuationOptions"),
        (lambda: trace(pb, u0, {"lam": 0.5}, "lam", ContinuationOptions(bounds={"mu": (0, 1)})), ValueError,
         "bounds given for unknown parameter 'mu'"),
        (lambda: ContinuationOptions(bounds={"lam": ("0", "3")}), TypeError, "bounds for 'lam' must be a real number"),
        (lambda: ContinuationOptions(bounds={"lam": 3}), TypeError, "bounds for 'lam' must be a pair"),
        (lambda: StepOptions(ds=0), ValueError, "ds=0"),
        (lambda: StepOptions(ds="0.1"), TypeError, "StepOptions.ds must be a real number"),
        (lambda: ContinuationOptions(max_steps=-1), ValueError, "max_steps must be >= 1"),
        (lambda: ContinuationOptions(max_steps=2.5), TypeError, "max_steps must be a whole number"),
        (lambda: ContinuationOptions(max_steps="10"), TypeError, "max_steps must be a whole number"),
        (lambda: ContinuationOptions(user_zeros={"lam": "12"}), TypeError, "user_zeros for 'lam' must be numbers"),
        (lambda: NewtonOptions(max_iterations=None), TypeError, "NewtonOptions.max_iterations"),
        (lambda: AllenCahn(method="cheb", intervals=2.5), TypeError, "intervals must be a whole number"),
    ]
    for call, kind, text in cases:
        with pytest.raises(kind, match=None) as info:
            call()
        assert text in str(info.value), (text, str(info.value))
    # what stays accepted: numpy scalars, whole floats, a 1-label stop_at string, a list u0
    ok = ContinuationOptions(max_steps=np.int64(5), bounds={"lam": (np.float64(0), 3)}, stop_at="LP1")
    assert ok.max_steps == 5 and ok.stop_at == ("LP1",) and ContinuationOptions(max_steps=5.0).max_steps == 5
    assert trace(pb, list(u0), {"lam": np.float64(0.5)}, "lam", opts).status == "EP"



@pytest.mark.parametrize("uz", ["5.2", "5.2960881320326"])
def test_a_user_zero_in_the_step_of_a_hopf_point_does_not_skip_its_check(uz, tmp_path):
    """`contin trace brusselator --uz b=5.2` kept HB1 where cheb 8 located it, 2.6e-9 off (special_tol
    1e-10), without a note, and its l1 = -0.0406 (cheb 12: -0.0271): the UZ located in the same step
    has no position check, and check_located gave up on the whole step.  A UZ lies on its value by
    construction; the HB is checked, refined to cheb 12, to the closed form within 1e-12."""
    from contin import io

    out = tmp_path / "b.h5"
    res = run(["trace", "brusselator", "--no-stability", "--uz", f"b={uz}", "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    branch = io.load(str(out))[0][0]
    hb = branch.points("HB")[0]
    plain = tmp_path / "p.h5"
    assert run(["trace", "brusselator", "--no-stability", "-q", "-o", str(plain)]).exit_code == 0
    ref = io.load(str(plain))[0][0].points("HB")[0]
    assert hb.grid == ref.grid and abs(hb.params["b"] / ref.params["b"] - 1) < 1e-12
    assert abs(hb.data["l1"] / ref.data["l1"] - 1) < 1e-6
    assert [sp.params["b"] for sp in branch.points("UZ")] == [float(uz)]


def test_stability_of_a_two_parameter_curve_is_refused_in_one_line(tmp_path):
    """`contin stability c.h5 --point 3` on a fold or Hopf curve of a demo scene ended with numpy's
    'Error: operands could not be broadcast together with shapes (13,) (67,)': the curve's augmented
    states reached the problem."""
    src, curve = tmp_path / "br.h5", tmp_path / "c.h5"
    assert run(["trace", "brusselator", "--no-stability", "-q", "-o", str(src)]).exit_code == 0
    assert run(["continue", str(src), "--from", "HB1", "--free", "a", "--max-steps", "10", "-o", str(curve)]).exit_code == 0
    res = run(["stability", str(curve), "--point", "3"])
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
    assert res.exit_code == 1 and len(errors) == 1, res.stderr
    assert "is a two-parameter curve (hopf-curve, free b, a)" in errors[0] and "broadcast" not in errors[0]


def test_first_lyapunov_coefficient_of_a_discretized_pde_converges_with_the_grid(tmp_path):
    """The Brusselator's HB1 was reported with l1 = -0.0406 on cheb 8, -0.0271 on cheb 12, -0.00353 on
    fd2 64, -1.1e-4 on fd2 2048 (exit 0): the Hopf eigenvector was normalized q^H q = 1, so l1 of a
    discretized PDE scaled as 1/N.  With the problem's quadrature weights (q^H W q = 1) it is one
    number, -0.2259, on every grid; an ODE's l1 (no weights) is unchanged (tests/test_hopf.py)."""
    from contin import io

    values = {}
    for args in (["--grid", "8"], ["--grid", "32"], ["--method", "fd2", "--grid", "256"]):
        out = tmp_path / f"b{'-'.join(args)}.h5"
        res = run(["trace", "brusselator", "--no-stability", "-q", *args, "-o", str(out)])
        assert res.exit_code == 0, res.stderr
        values[" ".join(args)] = io.load(str(out))[0][0].points("HB")[0].data["l1"]
    ref = values["--grid 32"]
    assert ref == pytest.approx(-0.225894, rel=1e-5)
    assert values["--grid 8"] == pytest.approx(ref, rel=1e-4)
    assert values["--method fd2 --grid 256"] == pytest.approx(ref, rel=1e-4)


def test_brusselator_notes_compare_each_hopf_point_with_its_own_mode(tmp_path):
    """`contin trace brusselator -s a=1.5` noted 'HB1: b = 4.434... (closed form ... = 3.546..., relative
    error 0.25 ...)': the mode-1 Hopf point lies below b_min and HB1 is the exact mode-2 point; the note
    compared every run's first HB with mode 1 (and said nothing of HB2)."""
    res = run(["trace", "brusselator", "-s", "a=1.5", "--no-stability", "-o", str(tmp_path / "b.h5")])
    assert res.exit_code == 0, res.stderr
    notes = [ln for ln in res.stderr.splitlines() if ln.startswith("note: HB")]
    assert len(notes) == 2 and "closed form of mode 2" in notes[0] and "closed form of mode 3" in notes[1], notes
    for ln in notes:
        err = float(ln.split("relative error ")[1].split(",")[0])
        assert abs(err) <= 1e-10, ln


def test_pitchfork_below_the_first_critical_gap_says_so(tmp_path):
    """`contin trace pitchfork -s H_max=1e-3` ended 'Error: need ds_max >= |ds| >= ds_min > 0, got
    ds_max=0.0001, ds=0.02' (the banded branches' fixed ds 0.02 above their ds_max 0.1 H_max), and
    with H_max between that and H_1^c the run found no BP and said nothing."""
    for h in ("1e-3", "5"):
        res = run(["trace", "pitchfork", "-s", f"H_max={h}", "--grid", "24", "--no-stability", "-o",
                   str(tmp_path / "h.h5")])
        assert res.exit_code == 0 and "Error" not in res.stderr, res.stderr
        assert "note: no pitchfork below H_max" in res.stderr and "H_1^c = pi psi = 13.06852933" in res.stderr


def test_at_a_parameter_constant_along_the_branch_is_refused(tmp_path):
    """`contin profiles br.h5 --at a=2` (a fixed parameter of a brusselator run) drew the profiles of
    HB1 as 'at a=2', exit 0: every point matches a constant; `contin stability br.h5 --at a=2` took the
    first point ('crosses a = 2 26 times').  Now one Error line naming the varying parameter."""
    src = tmp_path / "br.h5"
    assert run(["trace", "brusselator", "--no-stability", "-q", "-o", str(src)]).exit_code == 0
    for args in (["profiles", str(src), "--at", "a=2", "-o", str(tmp_path / "p.png")],
                 ["stability", str(src), "--at", "a=2"]):
        res = run(args)
        errors = [ln for ln in res.stderr.splitlines() if ln.startswith("Error:")]
        assert res.exit_code == 1 and len(errors) == 1, res.stderr
        assert "a is constant" in errors[0] and "--at b=" in errors[0]
    assert not (tmp_path / "p.png").exists()
    assert run(["profiles", str(src), "--at", "b=5", "-o", str(tmp_path / "q.png")]).exit_code == 0


def test_a_special_point_left_at_max_grid_does_not_block_the_refinement_of_the_next():
    """`contin trace allen-cahn --method fd2 --tol 1e-5`: BP1 reached max_grid (fd2 512) unresolved,
    and the adaptor's memory of its last measured error (3.1e-6) refused every later refinement:
    BP2 stayed on fd2 232 (6.1e-5 off), BP3 on fd2 72, lam = 8.987 (1.4e-3 off, 140x tol) with the
    note 'not falling with the grid'.  Now each is refined to max_grid: BP3 2.8e-5 off."""
    from contin.continuation import trace
    from contin.options import AdaptOptions, ContinuationOptions, StepOptions
    from problems.demo import AllenCahn

    pb = AllenCahn(method="fd2", intervals=32)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=1.5), bounds={"lam": (0.5, 10.0)},
                               adapt=AdaptOptions(tol=1e-5))
    br = trace(pb, pb.initial(), {"lam": 0.5}, "lam", opts)
    bps = br.branch_points
    assert [round(b.params["lam"]) for b in bps] == [1, 4, 9]
    for k, b in zip((1, 2, 3), bps):
        assert b.grid == 512, (b.name, b.grid)
        assert abs(b.params["lam"] / k**2 - 1) < 5e-5, (b.name, b.params["lam"])


def test_resume_keeps_the_accuracy_of_the_stored_branches(tmp_path):
    """`contin trace brusselator --method fd2 --tol 1e-6 -o F` then `--resume F --tol 1e-8` (or `--resume F`
    alone, the scene's default tol 1e-10) recorded the finished tol-1e-6 branch as computed at the new
    tol; a fixed-grid file resumed without --grid was continued adaptively.  Now the file's accuracy
    is kept, and another --tol is refused like another --grid."""
    from contin import io

    f = tmp_path / "b.h5"
    assert run(["trace", "brusselator", "--method", "fd2", "--tol", "1e-6", "--no-stability", "-q", "-o",
                str(f)]).exit_code == 0
    res = run(["trace", "brusselator", "--resume", str(f), "--tol", "1e-8", "--no-stability", "-q"])
    assert res.exit_code == 1 and "was computed with --tol 1e-06, not 1e-08" in res.stderr, res.stderr
    assert run(["trace", "brusselator", "--resume", str(f), "--no-stability", "-q"]).exit_code == 0
    assert io.load(str(f))[1]["options"]["adapt"]["tol"] == 1e-6
    fixed = tmp_path / "fixed.h5"
    assert run(["trace", "bratu", "--grid", "16", "--no-stability", "-q", "-o", str(fixed)]).exit_code == 0
    assert run(["trace", "bratu", "--resume", str(fixed), "--no-stability", "-q"]).exit_code == 0
    assert io.load(str(fixed))[1]["options"]["adapt"] is None
    res = run(["trace", "bratu", "--resume", str(fixed), "--tol", "1e-6", "--no-stability", "-q"])
    assert res.exit_code == 1 and "was computed on a fixed grid" in res.stderr
    res = run(["trace", "bratu", "--resume", str(fixed), "--resolution-tol", "1e-3", "--no-stability", "-q"])
    assert res.exit_code == 1 and "was computed with --resolution-tol 3e-05, not 1e-3" in res.stderr
    assert run(["trace", "bratu", "--resume", str(fixed), "--resolution-tol", "3e-5", "--no-stability", "-q"]).exit_code == 0


def test_switch_and_io_write_name_their_wrong_arguments(tmp_path):
    """switch(pb, branch, None/'BP1', opts) met "'NoneType'/'str' object has no attribute 'type'";
    io.write(path, branch) "'Branch' object is not iterable", io.write(path, [1, 2]) "object of type
    'int' has no len()".  Now a label is looked up, a single Branch is written, the rest is a
    TypeError naming the argument."""
    from contin import io
    from contin.continuation import switch, trace
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import AllenCahn

    pb = AllenCahn(method="cheb", intervals=16)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.3), bounds={"lam": (0.0, 3.0)})
    br = trace(pb, pb.initial(), {"lam": 0.5}, "lam", opts)
    with pytest.raises(TypeError, match="point must be a SpecialPoint"):
        switch(pb, br, None, opts)
    with pytest.raises(ValueError, match="no point 'BP9' on branch"):
        switch(pb, br, "BP9", opts)
    label = br.branch_points[0].name
    assert [len(b) > 1 for b in switch(pb, br, label, opts)] == [True, True]
    with pytest.raises(TypeError, match="branches must be a list of Branch objects"):
        io.write(tmp_path / "x.h5", [1, 2])
    with pytest.raises(TypeError, match="branches must be a list of Branch objects"):
        io.write(tmp_path / "x.h5", "abc")
    io.write(tmp_path / "one.h5", br)
    assert [b.id for b in io.load(tmp_path / "one.h5")[0]] == [br.id]


def test_stability_of_a_branch_without_points_says_why(tmp_path):
    """`contin stability F --branch bad --point 0` on a branch that could not start said 'point 0 is out
    of range: branch bad of F has 0 points (0..-1)'; now it names the branch's failure."""
    import numpy as np

    from contin import io
    from contin.continuation import trace
    from contin.options import ContinuationOptions, StepOptions
    from problems.demo import Bratu

    pb = Bratu(method="cheb", intervals=16)
    good = trace(pb, np.zeros(pb.n), {"lam": 0.0}, "lam",
                 ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.3), bounds={"lam": (0.0, 4.0)}))
    bad = trace(pb, np.full(pb.n, 50.0), {"lam": 90.0}, "lam",
                ContinuationOptions(bounds={"lam": (0.0, 100.0)}), branch_id="bad")
    assert len(bad) == 0
    f = tmp_path / "e.h5"
    io.write(f, [good, bad], scene="bratu", parameters={"lam_min": 0.0, "lam_max": 4.0})
    res = run(["stability", str(f), "--branch", "bad", "--point", "0"])
    assert res.exit_code == 1 and "branch bad of" in res.stderr and "has no stored points (MX: Newton failed" in res.stderr
