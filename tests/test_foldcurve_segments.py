"""Segment-wise regridding of fold curves (contin.foldcurve.SegmentRegrid) on a non-granular
problem whose fold curve needs finer grids along it: the stretched Bratu problem
(problems.demo.StretchedBratu), fold curve lam = lam* / (1 + a) with the fold state Bratu's fold
solution compressed into a layer of width ~ 1/a (closed forms, independent of the solver)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.continuation import trace
from contin.foldcurve import SegmentRegrid, trace_fold_curve
from contin.options import AdaptOptions, ContinuationOptions, StepOptions
from problems.demo import BRATU_FOLD, StretchedBratu

TOL = 1e-8
A_MAX = 6.0
A_MIN = -0.5


def _fold() -> tuple[StretchedBratu, object]:
    pb = StretchedBratu("cheb", 24)
    b = trace(pb, pb.initial(), {"lam": 0.5, "a": 0.0}, "lam", ContinuationOptions(max_steps=60, bounds={"lam": (0, 4)}))
    return pb, b.fold_points[0]


def _curve(regrid: SegmentRegrid | None):
    pb, lp = _fold()
    opts = ContinuationOptions(bounds={"a": (A_MIN, A_MAX)}, max_steps=300, resolution_tol=TOL,
                               step=StepOptions(ds=0.1, ds_max=0.5))
    return pb, trace_fold_curve(pb, lp, "a", opts, parameter="lam", regrid=regrid, branch_id="fold")


@pytest.fixture(scope="module")
def segmented():
    return _curve(SegmentRegrid(AdaptOptions(tol=TOL)))


def test_fixed_grid_curve_stops_under_resolved():
    """Without regridding the guard stops the a > 0 half on cheb 24 (the reason to regrid)."""
    _, c = _curve(None)
    assert c.status == "MX" and "under-resolved" in c.message
    assert c.grid is None and np.max(c.params["a"]) < 3.0


def test_segmented_curve_is_one_branch_to_the_bound(segmented):
    pb, c = segmented
    assert c.kind == "fold-curve" and c.free == ("lam", "a")
    assert c.status == "EP", c.message
    a = c.params["a"]
    assert np.max(a) == pytest.approx(A_MAX, abs=1e-12) and np.min(a) == pytest.approx(A_MIN, abs=1e-12)
    # per-point grids; the audit names every grid change
    assert c.grid is not None and len(c.grid) == len(c) and c.sizes is not None
    changes = c.grid_changes
    assert len(changes) >= 2
    lines = [line for line in c.audit if line.startswith("grid ")]
    assert len(lines) == len(changes)
    for (_, old, new), line in zip(sorted(changes, key=lambda ch: -ch[2]), lines[::-1]):
        assert line.startswith(f"grid {min(old, new)} -> {max(old, new)} at lam = ")
    for i in range(len(c)):
        assert c.sizes[i] == 2 * (c.grid[i] + 1) + 1  # (u, phi, a) on the point's grid
        assert c.state(i).size == c.sizes[i] and np.all(np.isfinite(c.state(i)))
        assert c.tangent(i).size == c.sizes[i] + 1 and np.all(np.isfinite(c.tangent(i)))


def test_grids_grow_along_the_refined_direction_only(segmented):
    _, c = segmented
    a, g = c.params["a"], c.grid
    start = int(np.argmin(np.abs(a)))
    assert abs(a[start]) < 1e-12 and g[start] == 24
    up = np.arange(start, len(c)) if a[-1] > 0 else np.arange(start, -1, -1)
    down = np.arange(start, -1, -1) if a[-1] > 0 else np.arange(start, len(c))
    assert np.all(np.diff(a[up]) > 0) and np.all(np.diff(g[up]) >= 0) and g[up][-1] > 24
    assert np.all(g[down] == 24)  # the a < 0 half is resolved on the start grid: it does not refine


def test_segmented_curve_agrees_with_the_closed_form(segmented):
    """Every point: lam = lam*/(1 + a) and the state = the exact fold state on the point's grid, to tol."""
    pb, c = segmented
    a, lam = c.params["a"], c.params["lam"]
    np.testing.assert_allclose(lam, BRATU_FOLD / (1.0 + a), rtol=TOL)
    for i in range(len(c)):
        on = pb.with_grid(int(c.grid[i]))
        u = c.state(i)[: on.n]
        exact = on.fold_state(float(a[i]))
        assert np.max(np.abs(u - exact)) <= TOL * np.max(np.abs(exact)), (i, a[i], c.grid[i])
        assert on.error_estimate(u, {"lam": lam[i], "a": a[i]}) <= TOL  # each point met the guard on its grid


def test_fine_fixed_grid_curve_agrees(segmented):
    """The same curve on a fixed fine grid (cheb 64, no guard): both land exactly on the bounds of
    a, where lam and the state agree to tol (the state on the fine grid interpolated onto the
    segment's grid)."""
    pb, c = segmented
    fine = StretchedBratu("cheb", 64)
    b = trace(fine, fine.initial(), {"lam": 0.5, "a": 0.0}, "lam", ContinuationOptions(max_steps=60, bounds={"lam": (0, 4)}))
    ref = trace_fold_curve(fine, b.fold_points[0], "a", ContinuationOptions(bounds={"a": (A_MIN, A_MAX)}, max_steps=300,
                                                                          step=StepOptions(ds=0.1, ds_max=0.5)),
                           parameter="lam")
    assert ref.status == "EP" and ref.grid is None
    for end in (A_MIN, A_MAX):
        i, j = int(np.argmin(np.abs(c.params["a"] - end))), int(np.argmin(np.abs(ref.params["a"] - end)))
        assert c.params["a"][i] == ref.params["a"][j] == pytest.approx(end, abs=1e-12)
        assert c.params["lam"][i] == pytest.approx(ref.params["lam"][j], rel=TOL)
        on = pb.with_grid(int(c.grid[i]))
        u = c.state(i)[: on.n]
        u_ref = fine.transfer(ref.state(j)[: fine.n], on)
        assert np.max(np.abs(u - u_ref)) <= TOL * np.max(np.abs(u_ref))


def test_special_points_keep_their_segment_grid(segmented):
    _, c = segmented
    for s in c.special_points:
        assert s.grid == c.grid[s.index], s
        assert s.params["a"] == pytest.approx(float(s.state[-1]), abs=0)


def test_io_round_trip_of_the_per_point_grid_column(segmented, tmp_path):
    _, c = segmented
    path = io.write(tmp_path / "curve.h5", [c])
    (d,), _ = io.load(path)
    np.testing.assert_array_equal(d.grid, c.grid)
    np.testing.assert_array_equal(d.sizes, c.sizes)
    assert d.grid_changes == c.grid_changes
    for i in range(len(c)):
        np.testing.assert_array_equal(d.state(i), c.state(i))
        np.testing.assert_array_equal(d.tangent(i), c.tangent(i))
    assert [s.grid for s in d.special_points] == [s.grid for s in c.special_points]
    assert [line for line in d.audit if line.startswith("grid ")] == [line for line in c.audit if line.startswith("grid ")]
    from contin.cli import main

    r = CliRunner().invoke(main, ["info", str(path)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    png = tmp_path / "d.png"
    r = CliRunner().invoke(main, ["diagram", str(path), "-x", "lam", "-y", "a", "-o", str(png)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --------------------------------------------------------------------------- two-grid check

def _loose_curve(check_factor, guard):
    """The fold curve regridded at tol TOL with the resolution guard at ``guard`` (looser than
    TOL, or off): only the two-grid check of the augmented solve can hold the points to TOL."""
    pb, lp = _fold()
    opts = ContinuationOptions(bounds={"a": (A_MIN, A_MAX)}, max_steps=300, resolution_tol=guard,
                               step=StepOptions(ds=0.1, ds_max=0.5))
    regrid = SegmentRegrid(AdaptOptions(tol=TOL, check_factor=check_factor))
    return pb, trace_fold_curve(pb, lp, "a", opts, parameter="lam", regrid=regrid, branch_id="fold")


def _errors(c):
    """Relative errors of lam (closed form lam*/(1 + a)) and of the state (the exact fold state on
    the point's grid, max-norm) at every point."""
    a, lam = c.params["a"], c.params["lam"]
    e_lam = np.abs(lam / (BRATU_FOLD / (1.0 + a)) - 1.0)
    e_u = []
    for i in range(len(c)):
        on = StretchedBratu("cheb", int(c.grid[i]))
        exact = on.fold_state(float(a[i]))
        e_u.append(np.max(np.abs(c.state(i)[: on.n] - exact)) / np.max(np.abs(exact)))
    return e_lam, np.array(e_u)


@pytest.mark.parametrize("guard", [1e-4, None])
def test_two_grid_check_holds_every_point_to_tol(guard):
    """Guard at 1e-4 (or off), tol 1e-8: without the check the a > 3.5 points stay on cheb 24 with
    lam up to 5.8e-8 and the state up to 3.6e-7 off the closed forms; with it (check_factor 2)
    they are recomputed on a finer grid and every point meets both to TOL."""
    from contin.foldcurve import augmented_two_grid_error, fold_start

    pb, off = _loose_curve(None, guard)
    assert off.status == "EP", off.message
    e_lam, e_u = _errors(off)
    assert np.sum(e_lam > TOL) >= 1 and np.sum(e_u > TOL) >= 1
    assert "two-grid check of the augmented solve: off (check_factor None)" in off.audit
    # the check itself flags exactly such a point: its two-grid error exceeds both true errors
    i = int(np.argmax(e_lam))
    fold, _ = fold_start(pb, _fold()[1], "a")
    fold = fold.with_grid(int(off.grid[i]))
    p = {"lam": float(off.params["lam"][i]), "a": float(off.params["a"][i])}
    e, n_f = augmented_two_grid_error(fold, off.state(i), off.tangent(i), p, "lam", 1.0, AdaptOptions(tol=TOL))
    assert n_f == 48 and e > max(TOL, e_lam[i], e_u[i])

    _, on = _loose_curve(2.0, guard)
    assert on.status == "EP", on.message
    a = on.params["a"]
    assert np.min(a) == pytest.approx(A_MIN, abs=1e-12) and np.max(a) == pytest.approx(A_MAX, abs=1e-12)
    e_lam, e_u = _errors(on)
    assert np.all(e_lam <= TOL) and np.all(e_u <= TOL), (e_lam.max(), e_u.max())
    assert int(np.max(on.grid)) > 24
    (summary,) = [line for line in on.audit if line.startswith("two-grid check of the augmented solve: ")]
    checks, worst, refused = (float(w) for w in re.findall(r": (\d+) checks, worst accepted error (\S+) .*?, (\d+) points", summary)[0])
    assert checks >= len(on) - 2 and 0 < worst <= TOL and refused >= 1
    # the grid changes name the check as their reason
    assert any(line.startswith("grid 24 -> ") and "two-grid error" in line for line in on.audit)


def test_a_point_no_grid_up_to_max_grid_passes_ends_the_curve_before_it():
    """max_grid 24 (the start grid), guard 1e-4, tol 1e-8: the first point of the a > 0 half that
    misses the two-grid check (checked on 48 = 2 x max_grid) cannot be recomputed on a finer grid,
    so the half ends MX at the point before it; every stored point meets the closed forms to TOL."""
    pb, lp = _fold()
    opts = ContinuationOptions(bounds={"a": (A_MIN, A_MAX)}, max_steps=300, resolution_tol=1e-4,
                               step=StepOptions(ds=0.1, ds_max=0.5))
    c = trace_fold_curve(pb, lp, "a", opts, parameter="lam",
                         regrid=SegmentRegrid(AdaptOptions(tol=TOL, max_grid=24)), branch_id="fold")
    assert c.status == "MX" and "two-grid error" in c.message and "no finer grid (max_grid 24)" in c.message
    assert set(c.grid.tolist()) == {24}
    a = c.params["a"]
    assert np.min(a) == pytest.approx(A_MIN, abs=1e-12) and 2.0 < np.max(a) < A_MAX
    e_lam, e_u = _errors(c)
    assert np.all(e_lam <= TOL) and np.all(e_u <= TOL)
    (mx,) = [s for s in c.special_points if s.type == "MX"]
    assert mx.params["a"] == pytest.approx(np.max(a), abs=0)
