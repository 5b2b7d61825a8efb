"""``contin.verify`` / ``contin verify``: the achieved error of stored points against a finer grid.

References: Bratu's closed form u(x) = -2 ln(cosh((x - 1/2) theta/2) / cosh(theta/4)) with
theta = sqrt(2 lam) cosh(theta/4) (two roots: the lower and upper branch); gPCF's uniform shear
(exact on every grid); and the audit of the main job (issue 14: n1.1 at H = 26.49 on cheb 32,
estimate 4.7e-7, relative error 7.4e-5 and phi off by 1.8e-6 against cheb 160).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.optimize import brentq

from contin import io
from contin.cli import main
from contin.continuation import trace
from contin.options import AdaptOptions, ContinuationOptions, StepOptions
from contin.verify import fine_grid, verify_branch
from problems.demo import Bratu

#: theta at the fold of Bratu (theta = 4 coth(theta/4)); the branch root lies below it
THETA_FOLD = 4.798714560


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def bratu_exact(lam: float, x: np.ndarray, upper: bool) -> np.ndarray:
    if lam == 0:
        return np.zeros_like(x)
    f = lambda th: th - math.sqrt(2 * lam) * math.cosh(th / 4)  # noqa: E731
    th = brentq(f, THETA_FOLD, 60.0) if upper else brentq(f, 0.0, THETA_FOLD)
    return -2 * np.log(np.cosh((x - 0.5) * th / 2) / np.cosh(th / 4))


def bratu_fd2_run(check_factor):
    pb = Bratu("fd2", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=60, step=StepOptions(ds=0.05, ds_max=0.25),
                               adapt=AdaptOptions(tol=1e-3, check_factor=check_factor))
    return pb, trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)


@pytest.fixture(scope="module")
def bratu_fd2():
    """Bratu on fd2 with a loose tol 1e-3, points accepted by their estimate alone (the tracer's
    two-grid check off): the defect estimate misses the fold's amplification."""
    return bratu_fd2_run(None)


def true_errors(pb, branch, points):
    """Each stored point's error: its interpolant against the closed form on 400 intervals."""
    ref = pb.with_grid(400)
    true = {}
    for p in points:
        u = branch.state(p.index)
        moved = pb.with_grid(p.grid).transfer(u, ref)
        ex = bratu_exact(p.params["lam"], ref.x, upper=bool(np.max(u) > 1.1868))  # max u at the fold: 1.18684
        true[p.index] = float(np.max(np.abs(moved - ex)) / np.max(np.abs(ex))) if p.params["lam"] > 0 else 0.0
    return true


def test_fine_grid_rounds_and_caps():
    assert fine_grid(32, 2.0, 512) == 64
    assert fine_grid(24, 1.5, None) == 36
    assert fine_grid(27, 1.5, None) == 44  # 40.5 -> next multiple of 4
    assert fine_grid(400, 2.0, 512) == 512


def test_bratu_loose_tol_points_beyond_tol_found_and_measured_against_the_closed_form(bratu_fd2):
    pb, branch = bratu_fd2
    check = verify_branch(pb, branch, {}, tol=1e-3)
    assert len(check.points) == len(branch) and not check.unchecked
    true = true_errors(pb, branch, check.points)
    beyond = {i for i, e in true.items() if e > 1e-3}
    flagged = {p.index for p in check.exceeding}
    # every stored point next to the fold (lam > 3.3) estimated <= 1e-3 yet up to ~7e-3 off: found
    assert len(beyond) >= 5 and beyond <= flagged | {i for i, e in true.items() if e < 1.4e-3}
    assert flagged and all(check.points[i].params["lam"] > 3.3 for i in flagged)
    assert all(true[i] > 1e-3 for i in flagged)
    assert all(check.points[i].estimate <= 1e-3 for i in flagged)  # the tracer's check passed them
    # fd2 at factor 2: the two-grid difference is e_c (1 - 2^-2) = 0.75 e_c, divided by 0.75
    # (contin.adapt.richardson): the closed form's error to 0-6 % (the difference alone: 0.75-0.8)
    worst = check.worst(1)[0]
    assert beyond == flagged  # (the difference alone missed one of the 8)
    assert 0.97 <= check.max_error / max(true.values()) <= 1.1
    assert 0.97 <= worst.error / true[worst.index] <= 1.1
    assert check.max_error > 20 * worst.estimate  # the fold amplifies the defect ~30x


def test_bratu_fd2_solve_check_keeps_every_point_within_tol_against_the_closed_form(bratu_fd2):
    """The same run with the tracer's two-grid check (the default, AdaptOptions.check_factor = 2):
    the 8 points that the estimate passed next to the fold (up to 7.5e-3) are refused and the grid
    refined, so verify finds none beyond tol, every point checked; against the closed form every
    point is within tol (the check's difference divided by 1 - 2^-2, fd2's Richardson factor) and
    the fold lam* within 1e-5 (7.0e-6, 2.0e-6 relative; 1e-4 off when accepted by the estimate alone)."""
    from problems.demo import BRATU_FOLD

    pb, branch = bratu_fd2_run(2.0)
    check = verify_branch(pb, branch, {}, tol=1e-3)
    assert len(check.points) == len(branch) == 61 and check.ok and not check.exceeding
    assert check.max_error <= 1e-3
    true = true_errors(pb, branch, check.points)
    assert max(true.values()) <= 1e-3
    before = verify_branch(bratu_fd2[0], bratu_fd2[1], {}, tol=1e-3)
    assert len(before.exceeding) == 8  # estimate alone (the fixture): 8 points beyond tol
    (lp,) = branch.fold_points
    (lp0,) = bratu_fd2[1].fold_points
    assert abs(lp.params["lam"] - BRATU_FOLD) <= 1e-5 < abs(lp0.params["lam"] - BRATU_FOLD)
    assert any("two-grid error above tol" in line for line in branch.audit)


class _NoSolution(Bratu):
    """|F(u)| + 1 never vanishes: the fine solve must fail."""

    def residual(self, u, p):
        return np.abs(super().residual(u, p)) + 1.0


def test_bratu_cheb_errors_equal_the_closed_form_and_failures_are_reported():
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=25, step=StepOptions(ds=0.05, ds_max=0.25),
                               adapt=AdaptOptions(tol=1e-4))
    branch = trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)
    check = verify_branch(pb, branch, {}, tol=1e-4)
    ref = pb.with_grid(400)
    compared = 0
    for p in check.points:
        u = branch.state(p.index)
        ex = bratu_exact(p.params["lam"], ref.x, upper=bool(np.max(u) > 1.1868))
        true = float(np.max(np.abs(pb.with_grid(p.grid).transfer(u, ref) - ex)) / np.max(np.abs(ex))) if p.params["lam"] else 0
        if true > 1e-9:  # above the fine solve's own Newton tolerance: spectral, the difference is e_c
            assert p.error == pytest.approx(true, rel=0.05)
            compared += 1
    assert compared >= 10 and check.ok
    # a point on the largest grid already, and a fine solve that cannot converge: reported, not dropped
    capped = verify_branch(pb, branch, {}, max_grid=int(branch.grid.min()))
    assert len(capped.points) == len(branch) and capped.unchecked and not capped.ok
    assert all("largest grid" in p.message and math.isnan(p.error) for p in capped.unchecked)
    failing = verify_branch(_NoSolution("cheb", 16), branch, {}, indices=[5, 10])
    assert [p.index for p in failing.unchecked] == [5, 10] and not failing.ok
    assert all("Newton" in p.message for p in failing.unchecked)
    # the first point of a branch switched at a BP: J singular there, listed apart (not a failure)
    switched = dataclasses.replace(branch, parent="BP1@0")
    at_bp = verify_branch(_NoSolution("cheb", 16), switched, {}, indices=[0, 5])
    assert [p.index for p in at_bp.singular] == [0] and [p.index for p in at_bp.unchecked] == [5]
    assert "BP1@0" in at_bp.singular[0].message


def test_gpcf_audit_point_flagged_and_uniform_shear_exact(tmp_path):
    out = tmp_path / "pf.h5"
    # the estimate alone (--no-solve-check): the audit's point is stored on cheb 32
    r = run("trace", "pitchfork", "-s", "nu=0.3", "-s", "e=0.8", "-s", "modes=1", "--no-stability", "--no-solve-check",
            "-q", "-o", out)
    assert r.exit_code == 0, r.output
    branches, meta = io.load(out)
    from contin.restart import rebuild_problem

    problem = rebuild_problem({**meta, "path": str(out)})
    base = branches[0]
    assert base.free == ("H",)
    shear = verify_branch(problem, base, meta["parameters"], tol=3e-5)
    assert shear.ok and shear.max_error < 1e-12  # uniform shear: exact on every grid
    n1 = next(b for b in branches if b.id == "n1.1")
    i = int(np.argmin(np.abs(n1.params["H"] - 26.491)))
    assert abs(n1.params["H"][i] - 26.491) < 1e-3 and n1.grid_at(i) == 32
    (p2,) = verify_branch(problem, n1, meta["parameters"], tol=3e-5, indices=[i]).points
    (p5,) = verify_branch(problem, n1, meta["parameters"], tol=3e-5, indices=[i], factor=5.0).points  # cheb 160
    assert p5.fine_grid == 160
    # the audit: estimate 4.7e-7, error 7.4e-5 against cheb 160, phi off by 1.8e-6
    assert p2.estimate == pytest.approx(4.7e-7, rel=0.05)
    assert p5.error == pytest.approx(7.4e-5, rel=0.05) and p5.observable_error == pytest.approx(1.8e-6, rel=0.05)
    assert p2.error == pytest.approx(p5.error, rel=0.02)  # spectral: cheb 64 is as good a reference as 160
    assert p2.error > 3e-5


def test_cli_verify_exit_codes_and_bad_input(tmp_path):
    out = tmp_path / "b.h5"
    r = run("trace", "bratu", "--method", "fd2", "--tol", "1e-3", "--no-solve-check", "-q", "-o", out)
    assert r.exit_code == 0, r.output
    r = run("verify", out)
    assert r.exit_code == 4, r.output
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("inaccurate: branch 0:")]
    assert len(lines) == 1 and "exceed tol 0.001" in lines[0]
    assert "FAIL" in r.stdout
    r = run("verify", out, "--tol", "1")  # every point within a tol of 100%
    assert r.exit_code == 0, r.output
    assert "inaccurate" not in r.stderr
    for args, needle in [((out, "--branch", "nope"), "no branch 'nope'"),
                         ((out, "--factor", "1"), "--factor must be"),
                         ((out, "--tol", "nan"), "--tol must be"),
                         ((tmp_path / "missing.h5",), "does not exist")]:
        r = run("verify", *args)
        assert r.exit_code in (1, 2) and "Error:" in r.stderr and needle in r.stderr, r.output
        assert "Traceback" not in r.output
    # a file whose problem cannot change its grid (Lorenz: a factory, no grid hooks)
    lor = tmp_path / "lorenz.h5"
    assert run("trace", "lorenz", "-q", "-o", lor).exit_code == 0
    r = run("verify", lor)
    assert r.exit_code == 1 and r.stderr.count("Error:") == 1 and "cannot change its grid" in r.stderr
    r = run("trace", "lorenz", "--no-solve-check", "-q", "-o", lor)  # a fixed-grid scene: one Error line
    assert r.exit_code != 0 and r.stderr.count("Error:") == 1 and "no adaptive resolution" in r.stderr


def test_cli_trace_with_the_solve_check_verifies_clean(tmp_path):
    """The CLI default (the two-grid check on): the Bratu fd2 run at tol 1e-3 that
    ``--no-solve-check`` leaves with 7 points beyond tol (test above) verifies clean, exit 0."""
    checked = tmp_path / "checked.h5"
    r = run("trace", "bratu", "--method", "fd2", "--tol", "1e-3", "-q", "-o", checked)
    assert r.exit_code == 0, r.output
    r = run("verify", checked, "--json")
    assert r.exit_code == 0 and "inaccurate" not in r.stderr, r.output
    import json

    (b,) = json.loads(r.stdout)["branches"]
    assert len(b["points"]) == 61 and not b["exceeding"] and not b["unchecked"] and b["max_error"] <= 1e-3


def test_readme_verify_example_runs_as_printed():
    import re
    from pathlib import Path

    text = (Path(__file__).parent.parent / "README.md").read_text()
    section = text.split("**Checking the achieved error**", 1)[1].split("\n**", 1)[0]
    (code,) = re.findall(r"```python\n(.*?)\n```", section, flags=re.S)
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)
    check, before = ns["check"], ns["before"]
    assert len(before.exceeding) == 8 and before.max_error == pytest.approx(7.5e-3, rel=0.05)
    assert before.worst(1)[0].params["lam"] == pytest.approx(3.5133, abs=1e-3)
    assert not check.exceeding and check.ok and check.max_error == pytest.approx(8.1e-4, rel=0.05)


@pytest.mark.slow
@pytest.mark.parametrize("settings, points, beyond, worst", [
    (("-s", "nu=0.3"), 136, 0, 8.16e-6),                      # the main job (10 beyond, 1.26e-4 before the check)
    (("-s", "nu=0.5", "-s", "H_max=40"), 140, 0, 1.51e-5),    # 6 beyond, 2.52e-4 before; to H = 40 (precise_residual)
    (("-s", "nu=0.3", "--no-solve-check"), 136, 10, 1.26e-4),  # the estimate alone: as before
])
def test_readme_table_gpcf_runs(tmp_path, settings, points, beyond, worst):
    """The README's table of `contin verify` on the main job and the dense nu = 0.5 run."""
    out = tmp_path / "pf.h5"
    r = run("trace", "pitchfork", *settings, "-s", "e=0.8", "--no-stability", "-q", "-o", out)
    assert r.exit_code == 0, r.output
    r = run("verify", out, "--json")
    assert r.exit_code == (4 if beyond else 0)
    import json

    doc = json.loads(r.stdout)
    assert sum(len(b["points"]) for b in doc["branches"]) == points
    assert sum(len(b["exceeding"]) for b in doc["branches"]) == beyond
    assert max(b["max_error"] for b in doc["branches"]) == pytest.approx(worst, rel=0.05)
    assert not any(b["unchecked"] for b in doc["branches"])


def test_singular_start_of_a_switched_branch_is_listed_apart_not_failed(tmp_path):
    """gPCF nu = 0.63 (n = 1): the switched branch's first point is the BP itself, the exactly
    uniform state (nu constant to rounding), where J on the check grid is singular to rounding
    (sigma_min / sigma_max ~ 1e-18): the fixed-parameter Newton solve drifts along the kernel by
    ~6e-5, which is not an error of the stored point.  verify lists it as singular and passes;
    every other point is checked."""
    from contin.adapt import on_grid
    from contin.restart import rebuild_problem

    out = tmp_path / "p.h5"
    r = run("trace", "pitchfork", "-s", "nu=0.63", "-s", "e=0.8", "-s", "modes=1", "-s", "H_max=60",
            "--no-stability", "-q", "-o", out)
    assert r.exit_code == 0, r.output
    branches, meta = io.load(out)
    band = next(b for b in branches if b.id == "n1.1")
    pb = rebuild_problem(meta)
    coarse = on_grid(pb, band.grid_at(0))
    u0 = np.asarray(band.state(0), float)
    nu = u0[: coarse.N + 1]
    assert np.ptp(nu) <= 4 * np.finfo(float).eps  # the uniform state: exact on every grid
    p = {**{k: v for k, v in meta["parameters"].items() if isinstance(v, (int, float))},
         **{k: float(v[0]) for k, v in band.params.items()}}
    fine = on_grid(pb, fine_grid(band.grid_at(0), 2.0, None))
    s = np.linalg.svd(fine.dense_jacobian(coarse.transfer(u0, fine), p), compute_uv=False)
    assert s[-1] / s[0] < 1e-14
    check = verify_branch(pb, band, p)
    assert [c.index for c in check.singular] == [0] and "switched at BP" in check.singular[0].message
    assert len(check.checked) == len(band) - 1 and not check.exceeding and check.ok
    r = run("verify", out)
    assert r.exit_code == 0, r.output
