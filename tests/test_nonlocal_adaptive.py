"""Adaptive resolution of the non-local scenes (``contin trace nonlocal-* --tol``).

Their estimate is the measured two-grid error (``problems.nonlocal_flow.grids``); a state
under-resolved on a fixed grid ended the branch MX "need a finer --grid", an adaptive run refines
instead.  References are independent of the tracer: the closed-form sinh profile of uniform phi
(``PlaneShearAnalytic``) and re-solves on a fine Chebyshev grid (``benchmarks.audit_families``,
``contin verify``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from benchmarks.audit_families import audit_branches, file_problem
from contin import io
from contin.adapt import point_problem
from contin.cli import main
from contin.continuation import trace_both
from contin.options import AdaptOptions, ContinuationOptions, StepOptions
from problems.nonlocal_flow.closures import PlaneShearAnalytic
from problems.nonlocal_flow.plane import DEFAULTS, PlaneShear


def _trace(tmp_path, *args, name="run"):
    out = tmp_path / f"{name}.h5"
    r = CliRunner().invoke(main, ["trace", *args, "--no-stability", "-q", "-o", str(out)], catch_exceptions=False)
    return r, out


def _uniform_branch(method: str, grid: int, tol: float) -> tuple[PlaneShear, dict, object]:
    """nonlocal-shear's uniform-phi branch for its second pair (mu_w = 0.1: wall layers of
    1/zeta = 3.5 d_p at ell = 3, 1.2 d_p at ell = 1 in W = 40), ell in [1, 12], from a coarse grid."""
    p = dict(DEFAULTS, K=0.95, mu_w=0.1)
    p["phi_w"] = p["phi_bar"]
    pb = PlaneShear(method, grid)
    o = ContinuationOptions(bounds={"ell": (1.0, 12.0)}, max_steps=80,
                            step=StepOptions(ds=0.1, ds_max=1.0, ds_min=1e-8), adapt=AdaptOptions(tol=tol))
    return pb, p, trace_both(pb, pb.initial(p), p, "ell", o, branch_id="uniform.ell")


@pytest.mark.parametrize("method, grid, tol", [("cheb", 8, 1e-8), ("fd4", 16, 1e-5)])
def test_uniform_phi_meets_tol_against_the_sinh_profile(method, grid, tol):
    """Every stored point of the uniform-phi branch, each on its own grid, within tol of the
    closed form u(y) (A sinh + B cosh) and its P = Pi(phi_bar); the grid was refined from the
    coarse start (cheb 8: 8 -> 12 -> 20, then 32 for the thin layers at small ell; measured
    3.4e-13; fd4 16 -> 84..288 by the two-grid error, the estimate FD grids lacked (NaN): 1.4e-6)."""
    pb, p, b = _uniform_branch(method, grid, tol)
    assert b.status == "EP" and len(b) >= 20
    assert b.grid is not None and min(b.grid) > grid and len(set(b.grid.tolist())) >= 2
    assert any("refined" in line for line in b.audit)
    P_exact = float(pb.cs.pi(p["phi_bar"])[0])
    for i in range(len(b)):
        q = dict(p, ell=float(b.params["ell"][i]))
        own = point_problem(pb, b, i)
        x = b.state(i)
        an = PlaneShearAnalytic(q["W"], q["K"], q["ell"], q["mu_w"], q["mu"])
        assert np.max(np.abs(own.velocity(x, q) - an.u(own.y(q)))) <= tol
        assert abs(own.split(x)[2] / P_exact - 1.0) <= tol


def test_shear_scene_compares_each_point_on_its_own_grid(tmp_path):
    """``contin trace nonlocal-shear --tol 1e-8 --grid 16`` (cheb 16: the fixed grid stops at the
    start of the uniform branch, "need a finer --grid"): every branch ends EP, the uniform branch's
    comparison with the closed form (each point on its own grid) meets the tol, and the stored
    states are within tol of a cheb reference re-solve (measured: u 4.3e-15 off the closed form, the
    wall layer width 7.4e-13; states 1.9e-9 off cheb 128; grids 12..72)."""
    r, out = _trace(tmp_path, "nonlocal-shear", "--grid", "16", "--tol", "1e-8", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output[r.output.index("{"):])
    assert doc["extra"]["analytic"]["max_abs_error_u"] <= 1e-8
    assert doc["extra"]["analytic"]["max_rel_error_delta"] <= 1e-6
    branches, meta, problem_of = file_problem(str(out))
    assert all(b.status == "EP" for b in branches) and len(branches) == 7
    assert any(b.grid is not None and max(b.grid) > 16 for b in branches)
    params = {k: v for k, v in meta["parameters"].items() if k in DEFAULTS}
    audit = audit_branches(branches, problem_of, {**DEFAULTS, **params}, ref_min=128, ref_max=128)
    assert len(audit.points) >= 150 and not audit.failed()
    assert max(p.error for p in audit.points) <= 1e-8
    assert max(doc["extra"][f"pair{k}"]["max_asymmetry"] for k in (1, 2)) <= 1e-10
    fixed, _ = _trace(tmp_path, "nonlocal-shear", "--grid", "16", name="fixed")
    assert fixed.exit_code != 0 and "need a finer" in fixed.output


def test_cylinder_refines_where_the_fixed_grid_stopped(tmp_path):
    """``contin trace nonlocal-cylinder -s report_eqs=1 --grid 20`` ends MX at ratio 3.6 ("two-grid
    error ... need a finer --grid", tests/test_audit_families.py); with ``--tol 3e-5`` the branch
    refines there (20 -> 32) and reaches ratio = 6, every state within tol of a cheb 128 re-solve
    and of ``contin verify``'s re-solve on twice its grid (measured 2.3e-5)."""
    r, out = _trace(tmp_path, "nonlocal-cylinder", "-s", "report_eqs=1", "--grid", "20", "--tol", "3e-5")
    assert r.exit_code == 0, r.output
    branches, _, problem_of = file_problem(str(out))
    (b,) = branches
    assert b.status == "EP" and max(b.grid) > 20 and float(np.max(b.params["ratio"])) == pytest.approx(6.0)
    audit = audit_branches(branches, problem_of, {}, ref_min=128, ref_max=128)
    assert len(audit.points) == len(b) >= 20 and not audit.failed()
    assert max(p.error for p in audit.points) <= 3e-5
    v = CliRunner().invoke(main, ["verify", str(out), "-q"], catch_exceptions=False)
    assert v.exit_code == 0 and "ok" in v.output, v.output


def test_max_grid_too_small_ends_mx_with_the_reason(tmp_path):
    """Past --max-grid the branch ends MX (exit 3) naming the maximum grid, its stored states
    within tol of the reference (measured 2.8e-5 off cheb 128 on cheb 20)."""
    r, out = _trace(tmp_path, "nonlocal-cylinder", "-s", "report_eqs=1", "--grid", "20", "--tol", "3e-5",
                    "--max-grid", "20")
    assert r.exit_code == 3, r.output
    branches, _, problem_of = file_problem(str(out))
    (b,) = branches
    assert b.status == "MX" and "under-resolved" in b.message and "maximum grid 20" in b.message
    assert "maximum grid 20" in r.output
    audit = audit_branches(branches, problem_of, {}, ref_min=128, ref_max=128)
    assert not audit.failed() and max(p.error for p in audit.points) <= 3e-5


def test_fd_grids_adapt_by_the_two_grid_error(tmp_path):
    """``--method fd2 --grid 32`` stopped at the start (two-grid error 1.1e-3 on fd2 32,
    tests/test_audit_families.py); with ``--tol 1e-4`` the run refines by the Richardson-scaled
    two-grid error (fd2 32 -> 248) and every state is within tol of a cheb 128 re-solve (measured
    9.8e-5: the Richardson-scaled estimate is the error, not a bound with a margin)."""
    r, out = _trace(tmp_path, "nonlocal-cylinder", "-s", "report_eqs=1", "--method", "fd2", "--grid", "32",
                    "--tol", "1e-4")
    assert r.exit_code == 0, r.output
    branches, _, problem_of = file_problem(str(out))
    (b,) = branches
    assert b.status == "EP" and max(b.grid) > 128
    audit = audit_branches(branches, problem_of, {}, ref_min=128, ref_max=128)
    assert len(audit.points) == len(b) and not audit.failed()
    assert max(p.error for p in audit.points) <= 1e-4


def test_muI_checks_use_each_points_grid(tmp_path):
    """``contin trace nonlocal-muI --grid 16`` cannot start (Chebyshev tail 2.7e-4 on cheb 16);
    with ``--tol 1e-8`` it refines, the U = 0 point equals the quasi-static problem's solve on its
    own grid to rounding, P / U^2 of the phi(I) branch is constant (its closed form) along points
    on several grids, and every state is within tol of a cheb reference re-solve (measured 2.1e-9;
    grids 24..56)."""
    r, out = _trace(tmp_path, "nonlocal-muI", "--grid", "16", "--tol", "1e-8", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output[r.output.index("{"):])
    assert doc["extra"]["muI"]["quasi_static_difference"] <= 1e-12
    assert doc["extra"]["phiI"]["P_over_U2_spread"] <= 1e-10
    branches, meta, problem_of = file_problem(str(out))
    assert [b.status for b in branches] == ["EP", "EP"] and all(min(b.grid) > 16 for b in branches)
    params = {k: v for k, v in meta["parameters"].items() if k in DEFAULTS}
    audit = audit_branches(branches, problem_of, {**DEFAULTS, **params}, ref_min=96, ref_max=128)
    assert len(audit.points) >= 30 and not audit.failed()
    assert max(p.error for p in audit.points) <= 1e-8
    fixed, _ = _trace(tmp_path, "nonlocal-muI", "--grid", "16", name="fixed")
    assert fixed.exit_code != 0 and "need a finer --grid" in fixed.output


def test_profiles_of_an_adaptive_run_are_on_the_start_grid(tmp_path):
    """States of several grids are stored with profiles on the file's y (the start grid): the
    profile of a refined point equals its state interpolated there."""
    r, out = _trace(tmp_path, "nonlocal-cylinder", "-s", "report_eqs=1", "--grid", "20", "--tol", "3e-5")
    assert r.exit_code == 0, r.output
    import h5py

    (b,), _ = io.load(out)
    i = int(np.argmax(b.grid))
    pb = file_problem(str(out))[2](b)
    own = point_problem(pb, b, i)
    assert own.grid_size > pb.grid_size
    phi = pb.split(own.transfer(b.state(i), pb))[0]
    with h5py.File(out, "r") as f:
        stored = np.asarray(f["branches/report.ratio/profiles/phi"])[i]
    assert np.max(np.abs(stored - phi)) <= 1e-14


def test_thin_wall_layers_refine_where_cheb_48_stopped(tmp_path):
    """``contin trace nonlocal-shear -s ell_min=0.3``: on cheb 48 the ell branches end MX at
    ell = 0.305 ("need a finer --grid than 48", docs/nonlocal.md); at the default tol 1e-8 every
    branch reaches ell = 0.3 (pair 2 refined up to cheb 164), the uniform branch within tol of the
    closed form (measured 6.5e-13) and the ell branches' states within tol of cheb re-solves."""
    r, out = _trace(tmp_path, "nonlocal-shear", "-s", "ell_min=0.3", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output[r.output.index("{"):])
    assert doc["extra"]["analytic"]["max_abs_error_u"] <= 1e-8
    branches, meta, problem_of = file_problem(str(out))
    ell = [b for b in branches if b.id.endswith(".ell")]
    assert len(ell) == 3 and all(b.status == "EP" and float(np.min(b.params["ell"])) == pytest.approx(0.3) for b in ell)
    assert max(int(np.max(b.grid)) for b in ell) > 128
    params = {k: v for k, v in meta["parameters"].items() if k in DEFAULTS}
    audit = audit_branches(ell, problem_of, {**DEFAULTS, **params}, ref_min=128, ref_max=256)
    assert len(audit.points) >= 80 and not audit.failed()
    assert max(p.error for p in audit.points) <= 1e-8
