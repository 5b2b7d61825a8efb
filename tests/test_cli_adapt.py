"""``contin trace --tol`` (adaptive resolution) and the readers of files with a per-point grid:
``contin info``, ``diagram``, ``profiles`` and ``stability``.

References: the Bratu fold lam* (closed form, problems.demo.BRATU_FOLD) and u(1/2) =
2 ln cosh(theta/4) on the exact branch; gPCF uniform shear's k_x = 0 growth rate, whose
eigenproblem is solved here on a fixed grid (the same state is exact on every grid).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main
from problems.demo import BRATU_FOLD


def run(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.mark.parametrize("tol", [1e-4, 1e-10])
def test_trace_tol_meets_the_fold(tmp_path, tol):
    out = tmp_path / "b.h5"
    r = run("trace", "bratu", "--tol", tol, "-s", "lam_min=0.05", "--max-steps", 120, "-o", out, "--json", "-q")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    (lp,) = [s for s in doc["special_points"] if s["type"] == "LP"]
    assert abs(lp["params"]["lam"] - BRATU_FOLD) <= tol * BRATU_FOLD
    (b,), meta = io.load(out)
    assert meta["format_version"] == 2 and b.grid is not None and len(b.grid_changes) >= 1
    assert b.fold_points[0].grid is not None


def test_special_tol_relaxes_where_special_points_are_located(tmp_path):
    """--special-tol REL: a located LP is re-located on a finer grid only above min(tol, REL);
    the default (1e-10) locates the Bratu fold on a finer grid than --special-tol 1e-4 does,
    and both are within 1e-4 of the closed form."""
    folds = {}
    for extra in ((), ("--special-tol", "1e-4")):
        out = tmp_path / f"b{len(extra)}.h5"
        r = run("trace", "bratu", "--tol", "1e-4", *extra, "-s", "lam_min=0.05", "--max-steps", 120, "-o", out, "-q")
        assert r.exit_code == 0, r.output
        (b,), _ = io.load(out)
        (lp,) = b.fold_points
        assert abs(lp.params["lam"] - BRATU_FOLD) <= 1e-4 * BRATU_FOLD
        folds[extra] = lp
    assert folds[("--special-tol", "1e-4")].grid < folds[()].grid
    assert abs(folds[()].params["lam"] - BRATU_FOLD) <= 1e-10 * BRATU_FOLD
    r = CliRunner().invoke(main, ["trace", "bratu", "--grid", "24", "--special-tol", "1e-4"])
    assert r.exit_code != 0 and "Error: --special-tol needs adaptive resolution" in r.output
    assert "Traceback" not in r.output


def test_info_diagram_profiles_read_adaptive_files(tmp_path):
    out = tmp_path / "b.h5"
    r = run("trace", "bratu", "-s", "lam_min=0.05", "--max-steps", 120, "-o", out, "-q")  # default: the scene's tol (1e-10)
    assert r.exit_code == 0, r.output
    (b,), meta = io.load(out)
    assert len(b.grid_changes) >= 2
    r = run("info", out)
    assert r.exit_code == 0 and f"grid of branch 0: {int(b.grid.min())}..{int(b.grid.max())}" in r.stdout
    assert "grid refined" in r.stdout
    png = tmp_path / "d.png"
    r = run("diagram", out, "-o", png)
    assert r.exit_code == 0 and png.read_bytes()[:4] == b"\x89PNG"
    # profiles on the file's grid (the start grid's nodes): u(1/2) on the upper branch at lam = 0.5
    # matches the closed form although the points there are on other grids
    lam = 0.5
    found = io.profiles_at([b], meta, "lam", lam)
    assert found
    from scipy.optimize import brentq

    mids = []
    for th0, th1 in ((0.01, 4.7987), (4.7987, 300.0)):
        th = brentq(lambda t: t**2 / (2 * math.cosh(t / 4) ** 2) - lam, th0, th1)
        mids.append(2 * math.log(math.cosh(th / 4)))
    u = found[0][2]["u"]
    y = meta["y"]
    mid = float(np.interp(0.5, y, u))
    assert min(abs(mid - m) for m in mids) < 2e-2  # linear interpolation between two stored points
    png = tmp_path / "p.png"
    r = run("profiles", out, "--at", "lam=0.5", "-o", png)
    assert r.exit_code == 0 and png.read_bytes()[:4] == b"\x89PNG"


def test_tol_on_a_fixed_grid_scene_is_one_error_line():
    r = CliRunner().invoke(main, ["trace", "gravity", "--tol", "1e-6"])
    assert r.exit_code != 0
    assert "Error: scene 'gravity' has no adaptive resolution" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(main, ["trace", "bratu", "--tol", "0"])
    assert r.exit_code != 0 and "Traceback" not in r.output


def test_grid_alone_keeps_a_fixed_grid(tmp_path):
    out = tmp_path / "f.h5"
    r = run("trace", "bratu", "--grid", 24, "-o", out, "-q")
    assert r.exit_code == 0, r.output
    (b,), meta = io.load(out)
    assert b.grid is None and b.states.shape[1] == 25


@pytest.mark.slow
def test_stability_reads_points_on_their_own_grid(tmp_path):
    """A short adaptive pitchfork run: k_x = 0 growth rate of a stored uniform-shear point (on its
    own coarse grid) equals that of the same state on a fixed cheb 32 grid."""
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    out = tmp_path / "p.h5"
    r = run("trace", "pitchfork", "-s", "nu=0.3", "-s", "e=0.8", "-s", "H_max=20", "-s", "modes=1", "--tol", "1e-6",
            "--no-stability", "-o", out, "-q")
    assert r.exit_code == 0, r.output
    branches, meta = io.load(out)
    base = branches[0]
    assert base.grid is not None and base.grid.min() < 64
    i = len(base) - 1
    r = run("stability", out, "--branch", "0", "--point", i, "--kx", "0", "--json")
    assert r.exit_code == 0, r.output
    g = json.loads(r.stdout)["growth_rate"][0]
    pb = CouetteProblem("cheb", 32)
    p = pb.params({"nu": 0.3, "e": 0.8})
    p["H"] = float(base.parameter_values[i])
    w = pf.finite_eigenvalues(*pf.StabilityOperator(pb).eigenproblem(pb.uniform_state(p), p))
    assert g == pytest.approx(float(np.max(w.real)), abs=1e-8)
    n1 = branches[1]
    assert n1.grid is not None and n1.status == "EP"
    r = run("stability", out, "--branch", n1.id, "--point", len(n1) - 1, "--kx", "0,0.5", "--json")
    assert r.exit_code == 0, r.output


@pytest.mark.slow
@pytest.mark.parametrize("nu, H_max, fold", [(0.5, 40.0, None), (0.16, 100.0, 41.963)])
def test_dense_plugs_need_no_grid_flag(tmp_path, nu, H_max, fold):
    """Issue 14's cases that ended MX on the fixed default grid: the banded branch reaches H_max
    with the default tol (3e-5), refining as the plug forms; at nu = 0.16 its fold agrees with
    the solve_bvp baseline (41.963 +- 2e-3, benchmarks/baseline_solve_bvp.py).  At nu = 0.5 the
    two-grid check of the solve evaluates the fine residual in extended precision where rounding
    matters (gPCF's ``precise_residual`` hook): without it the band ended EP at a precision limit at
    H = 38.96, where the double residual's rounding on cheb 160 .. 768 (entries ~N^4 in D2) set a
    floor of 0.6-3.6e-4 under the check; now it reaches H = 40 on cheb 80."""
    out = tmp_path / "p.h5"
    r = run("trace", "pitchfork", "-s", f"nu={nu}", "-s", "e=0.8", "-s", f"H_max={H_max}", "-s", "modes=1",
            "--no-stability", "-o", out, "-q")
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    band = [b for b in branches if b.id == "n1.1"][0]
    assert band.status == "EP" and band.message == f"reached bound H={H_max:g}"
    if nu == 0.5:
        assert band.grid[-1] == 80
    assert band.grid[-1] >= 64 and len(band.grid_changes) >= 2
    if fold is not None:
        (lp,) = band.fold_points
        assert lp.params["H"] == pytest.approx(fold, abs=2e-3)


def test_a_point_stored_above_tol_is_a_warning_also_with_q(tmp_path):
    """Bratu fd2 at --tol 1e-4 next to its fold: a candidate whose two-grid error (3.7e-4) was not
    lowered by refinement is stored on its estimate (the fixed-parameter error grows without bound
    at a fold).  That was an audit line in the file only, hidden from the terminal like the
    rejected steps; it is now a warning line (also with -q), and the file keeps it."""
    out = tmp_path / "b.h5"
    r = run("trace", "bratu", "--method", "fd2", "--tol", "1e-4", "-q", "-o", out)
    assert r.exit_code == 0, r.output
    warned = [ln for ln in r.output.splitlines() if ln.startswith("warning: branch 0: step ")]
    assert warned and all("accepted by its estimate: two-grid error" in ln for ln in warned)
    (b,), _ = io.load(out)
    assert [ln for ln in b.audit if "accepted by its estimate" in ln] == [w.removeprefix("warning: branch 0: ") for w in warned]
