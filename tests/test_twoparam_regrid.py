"""Adaptive grids for two-parameter continuation: ``continue_point(..., regrid=SegmentRegrid)`` and
``contin continue FILE --from LP1 --free a --tol REL [--max-grid N]``, on the non-granular demo
problem problems.demo.StretchedBratu (scene ``stretched-bratu``): its fold curve is
lam = lam*/(1 + a) with the fold state Bratu's fold solution compressed into a layer of width
~ 1/a (closed forms, independent of the solver), so the grid that tol needs grows along the curve
with a."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.branch import SpecialPoint
from contin.cli import main
from contin.continuation import trace
from contin.foldcurve import SegmentRegrid
from contin.options import AdaptOptions, ContinuationOptions, StepOptions
from contin.twoparam import NotAvailable, continue_point
from problems.demo import BRATU_FOLD, StretchedBratu

HERE = Path(__file__).parent
TOL = 1e-8
A_MIN, A_MAX = -0.5, 6.0
START = 24  # the fixed grid of the stored run (cheb 24): the fold curve leaves tol on it near a = 2


def _check_against_closed_form(c, start_grid: int) -> None:
    """Every point: lam = lam*/(1 + a) and the state = the exact fold state on the point's grid, to
    TOL; the guard met on the point's grid; grids non-decreasing towards a = A_MAX (the layer
    sharpens), the start grid on the a <= 0 side (it needs no refinement)."""
    a, lam, g = c.params["a"], c.params["lam"], c.grid
    assert c.status == "EP", c.message
    assert np.min(a) == pytest.approx(A_MIN, abs=1e-12) and np.max(a) == pytest.approx(A_MAX, abs=1e-12)
    np.testing.assert_allclose(lam, BRATU_FOLD / (1.0 + a), rtol=TOL)
    assert g is not None and len(g) == len(c) and c.sizes is not None
    for i in range(len(c)):
        on = StretchedBratu("cheb", int(g[i]))
        assert c.sizes[i] == 2 * on.n + 1  # (u, phi, a) on the point's grid
        u = c.state(i)[: on.n]
        exact = on.fold_state(float(a[i]))
        assert np.max(np.abs(u - exact)) <= TOL * np.max(np.abs(exact)), (i, a[i], g[i])
        assert on.error_estimate(u, {"lam": lam[i], "a": a[i]}) <= TOL
    start = int(np.argmin(np.abs(a)))
    assert abs(a[start]) < 1e-12 and g[start] == start_grid
    up = np.arange(start, len(c)) if a[-1] > a[0] else np.arange(start, -1, -1)
    down = np.arange(start, -1, -1) if a[-1] > a[0] else np.arange(start, len(c))
    assert np.all(np.diff(a[up]) > 0) and np.all(np.diff(g[up]) >= 0) and g[up][-1] > start_grid
    assert np.all(g[down] == start_grid)


# --------------------------------------------------------------------------- library

@pytest.fixture(scope="module")
def fold_point():
    pb = StretchedBratu("cheb", START)
    b = trace(pb, pb.initial(), {"lam": 0.5, "a": 0.0}, "lam", ContinuationOptions(max_steps=60, bounds={"lam": (0, 4)}))
    return pb, b, b.fold_points[0]


def _options(**kw) -> ContinuationOptions:
    return ContinuationOptions(bounds={"a": (A_MIN, A_MAX)}, max_steps=300, step=StepOptions(ds=0.1, ds_max=0.5), **kw)


def test_continue_point_without_regrid_stops_under_resolved(fold_point):
    pb, b, lp = fold_point
    c = continue_point(pb, b, lp, "a", _options(resolution_tol=TOL))
    assert c.status == "MX" and "under-resolved" in c.message
    assert c.grid is None and np.max(c.params["a"]) < 3.0


def test_continue_point_regrids_the_fold_curve_to_the_bound(fold_point):
    pb, b, lp = fold_point
    c = continue_point(pb, b, lp, "a", _options(resolution_tol=TOL), regrid=SegmentRegrid(AdaptOptions(tol=TOL)))
    assert c.kind == "fold-curve" and c.free == ("lam", "a") and c.id == f"{lp.name}.a"
    _check_against_closed_form(c, START)
    assert len(c.grid_changes) >= 2 and sum(line.startswith("grid ") for line in c.audit) == len(c.grid_changes)


def test_continue_point_starts_on_the_points_own_grid(fold_point):
    """A point of an adaptive run (its own grid, SpecialPoint.grid) with the problem on another
    grid: the curve starts on the point's grid."""
    pb, b, lp = fold_point
    fine = StretchedBratu("cheb", 36)
    moved = SpecialPoint(type="LP", index=lp.index, params=dict(lp.params), order_parameter=lp.order_parameter,
                         state=pb.transfer(np.asarray(lp.state), fine), grid=36, label=lp.label)
    c = continue_point(pb, b, moved, "a", _options(resolution_tol=TOL), regrid=SegmentRegrid(AdaptOptions(tol=TOL)))
    _check_against_closed_form(c, 36)


def test_a_start_point_that_misses_tol_is_carried_onto_a_finer_grid():
    """LP located on cheb 12 without a guard (estimate 2.7e-5): with regrid at tol 1e-8 the curve
    starts on the first finer grid that resolves it (the tracer's Newton start puts the point on
    that grid's fold), and every point meets the closed form to tol."""
    pb = StretchedBratu("cheb", 12)
    b = trace(pb, pb.initial(), {"lam": 0.5, "a": 0.0}, "lam",
              ContinuationOptions(max_steps=60, bounds={"lam": (0, 4)}, resolution_tol=None))
    lp = b.fold_points[0]
    assert pb.error_estimate(lp.state, lp.params) > TOL
    c = continue_point(pb, b, lp, "a", _options(resolution_tol=TOL), regrid=SegmentRegrid(AdaptOptions(tol=TOL)))
    a, lam, g = c.params["a"], c.params["lam"], c.grid
    assert c.status == "EP", c.message
    assert np.min(a) == pytest.approx(A_MIN, abs=1e-12) and np.max(a) == pytest.approx(A_MAX, abs=1e-12)
    assert int(np.min(g)) > 12  # nothing on the start point's own grid
    np.testing.assert_allclose(lam, BRATU_FOLD / (1.0 + a), rtol=TOL)
    for i in range(len(c)):
        on = StretchedBratu("cheb", int(g[i]))
        exact = on.fold_state(float(a[i]))
        assert np.max(np.abs(c.state(i)[: on.n] - exact)) <= TOL * np.max(np.abs(exact)), (i, a[i], g[i])


def test_regrid_needs_the_grid_hooks():
    from tests.twoparam_fixture_scenes import Pitchfork

    base, bp = _pitchfork_base(Pitchfork())
    with pytest.raises(ValueError, match="adaptive grids need the problem hooks grid_size, error_estimate, with_grid, "
                                         "transfer \\(Pitchfork lacks them\\)"):
        continue_point(Pitchfork(), base, bp, "mu", _options(), regrid=SegmentRegrid(AdaptOptions()))


class _GriddedPitchfork:
    """The fixture pitchfork x^3 - lam x + mu + K mu x^2 + Q x^5 with (trivial) grid hooks: one grid."""

    def __init__(self) -> None:
        from tests.twoparam_fixture_scenes import Pitchfork

        self.inner = Pitchfork()
        self.parameter_names = self.inner.parameter_names
        self.residual, self.jacobian, self.dresidual_dp = self.inner.residual, self.inner.jacobian, self.inner.dresidual_dp
        self.grid_size = 1

    def with_grid(self, size):
        return self

    def transfer(self, u, other):
        return np.asarray(u, float).copy()

    def error_estimate(self, u, p):
        return 0.0


def _pitchfork_base(pb):
    """x = 0 in lam at mu = 0 and its pitchfork at lam = 0 (unfolded by mu, kept by K)."""
    opts = ContinuationOptions(bounds={"lam": (-0.3, 0.3)}, max_steps=2000,
                               step=StepOptions(ds=0.002, ds_max=0.005, max_angle=0.1))
    base = trace(pb, np.array([0.0]), {"lam": -0.3, "mu": 0.0, "K": 0.5, "Q": 0.2}, "lam", opts)
    (bp,) = base.branch_points
    return base, bp


def test_unfolded_bp_fold_curve_takes_regrid():
    """BP unfolded by mu: the Moore-Spence curve through it takes regrid (the same curve, each
    point with its grid); the closed form lam = 3x^2 + 2K mu x + 5Q x^4 holds."""
    pb = _GriddedPitchfork()
    base, bp = _pitchfork_base(pb)
    two = ContinuationOptions(bounds={"mu": (-0.01, 0.01)}, max_steps=60, step=StepOptions(ds=0.002, ds_max=0.005, max_angle=0.1))
    ref = continue_point(pb, base, bp, "mu", two)
    c = continue_point(pb, base, bp, "mu", two, regrid=SegmentRegrid(AdaptOptions()))
    assert c.status == "EP" and ref.grid is None and np.all(c.grid == 1)
    np.testing.assert_array_equal(c.states, ref.states)
    x, lam, mu = c.states[:, 0], c.params["lam"], c.params["mu"]
    assert np.max(np.abs(lam - (3 * x**2 + 2 * 0.5 * mu * x + 5 * 0.2 * x**4))) < 1e-9


def test_regrid_is_not_available_for_bp_and_hopf_curves():
    from tests.hopf_models import BTNormalForm

    x = 0.5 * (1 - math.sqrt(1 + 4 * 0.5))
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-1.0, 0.2)}, max_steps=200)
    br = trace(BTNormalForm(), np.array([x, 0.0]), {"b1": -0.5, "b2": -1.0}, "b1", opts)
    (hb,) = br.points("HB")
    with pytest.raises(NotAvailable, match="adaptive grids are not available for BP/Hopf curves .HB.* is a Hopf point"):
        continue_point(BTNormalForm(), br, hb, "b2", opts, regrid=SegmentRegrid(AdaptOptions()))
    # a symmetry-breaking pitchfork that the second parameter keeps: its curve is a BP curve
    pb = _GriddedPitchfork()
    base, bp = _pitchfork_base(pb)
    from dataclasses import replace

    sym = replace(bp, note="symmetry-breaking pitchfork")
    with pytest.raises(NotAvailable, match="adaptive grids are not available for BP/Hopf curves .* its curve is a BP curve"):
        continue_point(pb, base, sym, "K", opts, regrid=SegmentRegrid(AdaptOptions()))


# --------------------------------------------------------------------------- CLI

def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def one_error_line(r, expect: str) -> None:
    assert r.exit_code == 1, r.output
    lines = [line for line in r.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and expect in lines[0], r.output
    assert "Traceback" not in r.output


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """stretched-bratu traced to its LP: on the fixed grid cheb 24 with the guard at TOL, and
    adaptively at tol TOL with special_tol 1e-12 (the LP on its own, finer grid)."""
    d = tmp_path_factory.mktemp("regrid")
    fixed, adaptive = d / "fixed.h5", d / "adaptive.h5"
    r = invoke("trace", "stretched-bratu", "--grid", START, "--resolution-tol", TOL, "--stop-at", "LP1",
               "--no-stability", "-q", "-o", fixed)
    assert r.exit_code == 0, r.output
    # --special-tol 1e-12: the LP on a grid of its own (at special_tol = tol its position, measured
    # 2.7e-11 on the run's last grid, cheb 24 -- the file's start grid -- meets tol there)
    r = invoke("trace", "stretched-bratu", "--tol", TOL, "--special-tol", "1e-12", "--stop-at", "LP1", "--no-stability",
               "-q", "-o", adaptive)
    assert r.exit_code == 0, r.output
    return fixed, adaptive


BOUNDS = ("--bounds", f"a={A_MIN}:{A_MAX}", "--bounds", "lam=0:8", "--ds", "0.1", "--ds-max", "0.5")


def test_cli_without_tol_the_curve_stops_under_resolved(runs, tmp_path):
    fixed, _ = runs
    out = tmp_path / "c.h5"
    r = invoke("continue", fixed, "--from", "LP1", "--free", "a", *BOUNDS, "-o", out)
    assert r.exit_code == 3, r.output  # EXIT_INCOMPLETE
    assert "under-resolved" in r.output and "grids along the curve" not in r.output
    (c,), meta = io.load(out)
    assert c.status == "MX" and c.grid is None and np.max(c.params["a"]) < 3.0
    assert "regrid" not in meta.get("extra", {})


def test_stored_adaptive_settings_are_read_back_and_not_applied_to_the_curve(runs, tmp_path):
    """A file's adaptive settings come back as AdaptOptions (io.options_from_dict), and `contin
    continue` without --tol does not hand them to the tracer (an augmented curve changes grid only
    segment-wise): the fixed run's file with an adaptive run's options continues exactly as
    without them (same curve; before, the tracer refused: FoldProblem has no error_estimate)."""
    import json
    import shutil

    import h5py

    settings = AdaptOptions(tol=1e-6, max_grid=256)
    back = io.options_from_dict(io._options_dict(ContinuationOptions(adapt=settings)))
    assert back.adapt == settings
    fixed, _ = runs
    edited = tmp_path / "edited.h5"
    shutil.copy(fixed, edited)
    with h5py.File(edited, "r+") as f:
        o = json.loads(f.attrs["options"])
        o["adapt"] = io._options_dict(ContinuationOptions(adapt=settings))["adapt"]
        f.attrs["options"] = json.dumps(o)
    curves = []
    for src in (fixed, edited):
        out = tmp_path / f"c_{src.stem}.h5"
        r = invoke("continue", src, "--from", "LP1", "--free", "a", "--bounds", "a=-0.5:1", "--bounds", "lam=0:8",
                   "--ds", "0.1", "--ds-max", "0.5", "-o", out)
        assert r.exit_code == 0, r.output
        (c,), _ = io.load(out)
        curves.append(c)
    assert np.array_equal(curves[0].params["a"], curves[1].params["a"])
    assert np.array_equal(curves[0].params["lam"], curves[1].params["lam"])


def test_cli_tol_regrids_to_the_bound(runs, tmp_path):
    fixed, _ = runs
    out = tmp_path / "c.h5"
    r = invoke("continue", fixed, "--from", "LP1", "--free", "a", *BOUNDS, "--tol", TOL, "-o", out)
    assert r.exit_code == 0, r.output
    assert f"grids along the curve (tol {TOL:g}): {START}, " in r.output
    (c,), meta = io.load(out)
    assert meta["scene"] == "stretched-bratu" and c.free == ("lam", "a")
    _check_against_closed_form(c, START)
    assert meta["extra"]["regrid"] == {"tol": TOL, "max_grid": 512}
    assert meta["options"]["resolution_tol"] == TOL and meta["options"]["adapt"] is None
    r = invoke("info", out)
    assert r.exit_code == 0 and f"grid of branch {c.id}: {START}.." in r.output, r.output
    png = tmp_path / "d.png"
    r = invoke("diagram", out, "-x", "lam", "-y", "a", "-o", png)
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_no_solve_check_switches_the_two_grid_check_off(runs, tmp_path):
    """--tol checks every point's augmented solve on a twice finer grid (the curve's audit counts the
    checks); --no-solve-check switches the check off (AdaptOptions.solve_check = False)."""
    fixed, _ = runs
    audits = {}
    for flag in ((), ("--no-solve-check",)):
        out = tmp_path / f"c{len(flag)}.h5"
        r = invoke("continue", fixed, "--from", "LP1", "--free", "a", *BOUNDS, "--tol", TOL, *flag, "-o", out)
        assert r.exit_code == 0, r.output
        (c,), _ = io.load(out)
        _check_against_closed_form(c, START)
        (audits[flag],) = [line for line in c.audit if line.startswith("two-grid check of the augmented solve: ")]
    assert audits[("--no-solve-check",)].endswith(": off (solve_check False)")
    checks = int(audits[()].split(": ")[1].split(" checks")[0])
    assert checks >= 10 and "worst accepted error" in audits[()]


def test_cli_tol_starts_on_the_adaptive_points_grid(runs, tmp_path):
    _, adaptive = runs
    branches, meta = io.load(adaptive)
    lp = next(s for b in branches for s in b.fold_points)
    assert lp.grid is not None and lp.grid != meta["discretization"]["intervals"]  # the LP has its own grid
    # without --tol the file's grid is not the point's: one error line
    one_error_line(invoke("continue", adaptive, "--from", "LP1", "--free", "a", *BOUNDS),
                   f"LP1 was computed on grid {lp.grid}")
    out = tmp_path / "c.h5"
    r = invoke("continue", adaptive, "--from", "LP1", "--free", "a", *BOUNDS, "--tol", TOL, "-o", out)
    assert r.exit_code == 0, r.output
    (c,), _ = io.load(out)
    _check_against_closed_form(c, int(lp.grid))
    r = invoke("continue", adaptive, "--from", "LP1", "--free", "a", *BOUNDS, "--tol", TOL, "--json")
    assert r.exit_code == 0
    import json

    doc = json.loads(r.stdout)
    assert doc["extra"]["regrid"] == {"tol": TOL, "max_grid": 512, "grids": sorted(set(c.grid.tolist()))}


def test_cli_max_grid_caps_the_refinement(runs, tmp_path):
    fixed, _ = runs
    out = tmp_path / "c.h5"
    r = invoke("continue", fixed, "--from", "LP1", "--free", "a", *BOUNDS, "--tol", TOL, "--max-grid", 32, "-o", out)
    assert r.exit_code == 3, r.output
    (c,), meta = io.load(out)
    assert c.status == "MX" and "under-resolved" in c.message and int(np.max(c.grid)) == 32
    assert np.max(c.params["a"]) < A_MAX
    a, lam = c.params["a"], c.params["lam"]
    np.testing.assert_allclose(lam, BRATU_FOLD / (1.0 + a), rtol=TOL)  # what it computed met tol
    assert meta["extra"]["regrid"]["max_grid"] == 32


def test_cli_tol_bad_input(runs, monkeypatch, tmp_path):
    fixed, _ = runs
    one_error_line(invoke("continue", fixed, "--from", "LP1", "--free", "a", "--max-grid", 64),
                   "--max-grid needs --tol")
    one_error_line(invoke("continue", fixed, "--from", "LP1", "--free", "a", "--no-solve-check"),
                   "--no-solve-check needs --tol")
    one_error_line(invoke("continue", fixed, "--from", "LP1", "--free", "a", "--tol", TOL, "--max-grid", 16),
                   "--max-grid (16) is below the grid of LP1 (24)")
    r = invoke("continue", fixed, "--from", "LP1", "--free", "a", "--tol", "0")
    assert r.exit_code == 2 and "Traceback" not in r.output
    # a problem without the grid hooks (the two-parameter fixture scene)
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", "twoparam_fixture_scenes:SCENES")
    ip = tmp_path / "ip.h5"
    r = invoke("trace", "imperfect-pitchfork", "--no-stability", "-q", "-o", ip)
    assert r.exit_code == 0, r.output
    one_error_line(invoke("continue", ip, "--from", "BP2", "--free", "mu", "--tol", TOL),
                   "--tol needs a problem with the grid hooks grid_size, with_grid, transfer, error_estimate; "
                   "the problem of scene 'imperfect-pitchfork'")
    # a Hopf point: no adaptive grids for Hopf curves
    lz = tmp_path / "lorenz.h5"
    r = invoke("trace", "lorenz", "--no-stability", "-q", "-o", lz)
    assert r.exit_code == 0, r.output
    one_error_line(invoke("continue", lz, "--from", "HB2", "--free", "sigma", "--tol", TOL),
                   "adaptive grids are not available for BP/Hopf curves (HB2 is a Hopf point)")


def _fold_at_fixed_second(problem, u0, params, free: str, tol: float = 1e-12, iterations: int = 30) -> float:
    """Reference fold location by an independent Newton solve of the fold conditions
    F(u, p) = 0, J(u, p) phi = 0, phi . phi0 = 1 on ``problem``'s fixed grid with every parameter
    but ``free`` fixed (the second parameter held at its bound: no continuation, no regridding,
    no guard).  Starts from u0 and the null vector of J there; the Jacobian (dense central
    differences of F_u phi along phi) only drives convergence, the root is fixed by the
    residual, converged here to ``tol`` relative."""
    import scipy.linalg as sla
    import scipy.sparse as sp

    p = dict(params)
    jac = sp.csr_matrix(problem.jacobian(u0, p)).toarray()
    _, _, vt = np.linalg.svd(jac)
    phi = vt[-1] / np.linalg.norm(vt[-1])
    c = phi.copy()
    n = u0.size
    x = np.concatenate([u0, phi, [p[free]]])

    def residual(x):
        q = {**p, free: float(x[-1])}
        u, v = x[:n], x[n:2 * n]
        return np.concatenate([problem.residual(u, q), sp.csr_matrix(problem.jacobian(u, q)) @ v, [c @ v - 1.0]])

    for _ in range(iterations):
        q = {**p, free: float(x[-1])}
        u, v = x[:n], x[n:2 * n]
        J = sp.csr_matrix(problem.jacobian(u, q)).toarray()
        h = 1e-6 * max(1.0, np.max(np.abs(u)))
        Jv = (sp.csr_matrix(problem.jacobian(u + h * v, q)).toarray() - sp.csr_matrix(problem.jacobian(u - h * v, q)).toarray()) / (2 * h)
        hp = 1e-7 * max(1.0, abs(q[free]))
        fp = (problem.residual(u, {**q, free: q[free] + hp}) - problem.residual(u, {**q, free: q[free] - hp})) / (2 * hp)
        jp = ((sp.csr_matrix(problem.jacobian(u, {**q, free: q[free] + hp})) - sp.csr_matrix(problem.jacobian(u, {**q, free: q[free] - hp}))) @ v) / (2 * hp)
        big = np.zeros((2 * n + 1, 2 * n + 1))
        big[:n, :n], big[:n, -1] = J, fp
        big[n:2 * n, :n], big[n:2 * n, n:2 * n], big[n:2 * n, -1] = Jv, J, jp
        big[-1, n:2 * n] = c
        dx = sla.solve(big, -residual(x))
        x = x + dx
        if abs(dx[-1]) <= tol * abs(x[-1]) and np.max(np.abs(dx[:n])) <= tol * np.max(np.abs(x[:n])):
            break
    else:
        raise AssertionError("reference Newton did not converge")
    return float(x[-1])


@pytest.mark.slow
def test_cli_tol_on_the_gpcf_banded_fold(monkeypatch, tmp_path):
    """gPCF: the fold of the nu = 0.16 banded branch (scene gpcf-keypoints, fixed cheb 32)
    continued in nu with --tol 1e-8: every point passes the two-grid check of its augmented solve
    (contin.foldcurve.augmented_two_grid_error), which the start point on cheb 32 misses (3.5e-8;
    its guard estimate meets tol), so both halves start on cheb 48; the half towards small nu (the
    band densifies, H grows) is regridded 48 -> 80 where a point misses the check, and both halves
    reach their bounds.  Every point meets tol on its grid; the nu = 0.17 end is the fold the
    one-parameter trace on a fixed cheb 64 locates (an independent solve; 4e-12 measured), and
    the nu = 0.14 end is the fold of a Newton solve of the fold conditions at nu = 0.14 on a fixed
    cheb 96 (1e-11 measured; 3.3e-7 without the check, whose guard estimates all met 1e-8).
    ~13 s."""
    from dataclasses import replace

    from problems.couette.keypoints import banded_fold, fold_options
    from problems.couette.model import CouetteProblem

    monkeypatch.setenv("CONTIN_SCENES", "problems.couette.keypoints:SCENES")
    kp, out = tmp_path / "kp.h5", tmp_path / "c.h5"
    r = invoke("trace", "gpcf-keypoints", "--grid", 32, "--no-stability", "-q", "-o", kp)
    assert r.exit_code == 0, r.output
    branches, _ = io.load(kp)
    (lp,) = [s for b in branches for s in b.fold_points]
    assert lp.params["nu"] == 0.16
    r = invoke("continue", kp, "--from", lp.name, "--free", "nu", "--bounds", "nu=0.14:0.17", "--bounds", "H=10:200",
               "--ds", 0.01, "--ds-max", 0.5, "--tol", TOL, "-o", out)
    assert r.exit_code == 0, r.output
    (c,), _ = io.load(out)
    nu, g = c.params["nu"], c.grid
    assert c.status == "EP" and min(nu) == pytest.approx(0.14, abs=1e-12) and max(nu) == pytest.approx(0.17, abs=1e-12)
    assert sorted(set(g.tolist())) == [48, 80]
    order = np.argsort(-nu)  # from nu = 0.17 down to 0.14: the grid only grows
    assert np.all(np.diff(g[order]) >= 0)
    for i in range(len(c)):
        on = CouetteProblem("cheb", int(g[i]))
        p = {k: float(v[i]) for k, v in c.params.items()}
        assert on.error_estimate(c.state(i)[: on.size], p) <= TOL
    (summary,) = [line for line in c.audit if line.startswith("two-grid check of the augmented solve: ")]
    assert "points refused" in summary and " 0 points refused" not in summary
    _, ref = banded_fold(CouetteProblem("cheb", 64), 0.17, 0.8, replace(fold_options(0.17, 0.8), resolution_tol=None))
    end = int(np.argmax(nu))
    assert c.params["H"][end] == pytest.approx(ref.params["H"], rel=TOL)
    # the nu = 0.14 end against the fold on a fixed cheb 96 at nu = 0.14
    end = int(np.argmin(nu))
    fine = CouetteProblem("cheb", 96)
    coarse = CouetteProblem("cheb", int(g[end]))
    p = {k: float(v[end]) for k, v in c.params.items()}
    u0 = coarse.transfer(c.state(end)[: coarse.size], fine)
    H_ref = _fold_at_fixed_second(fine, u0, p, "H")
    assert c.params["H"][end] == pytest.approx(H_ref, rel=TOL)
