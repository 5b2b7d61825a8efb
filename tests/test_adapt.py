"""Adaptive resolution (contin.adapt): ask for an accuracy, not a grid.

References are closed forms computed in the tests: the Bratu branch
lam = theta^2 / (2 cosh^2(theta/4)), u(1/2) = 2 ln cosh(theta/4) and its fold lam* (Gel'fand
1963, problems.demo.BRATU_FOLD); gPCF's H_1^c = pi psi (problems.couette.pitchfork).
"""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from scipy.optimize import brentq

from contin import io
from contin.adapt import AdaptOptions, check_problem
from contin.continuation import trace, trace_both
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from problems.demo import BRATU_FOLD, AllenCahn, Bratu, ImperfectPitchfork


def bratu_mid(lam: float) -> float:
    """u(1/2) on the upper Bratu branch at lam (closed form, theta > theta*)."""
    theta = brentq(lambda th: th**2 / (2 * math.cosh(th / 4) ** 2) - lam, 4.7987, 300.0, xtol=1e-15)
    return 2 * math.log(math.cosh(theta / 4))


def bratu_run(method: str, start: int, tol: float, lam_lo: float, **kw):
    pb = Bratu(method, start)
    o = ContinuationOptions(bounds={"lam": (lam_lo, 4.0)}, max_steps=400, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=tol, max_grid=kw.pop("max_grid", 512), min_grid=8,
                                               special_tol=kw.pop("special_tol", tol)))  # the fold's kernel at tol, as the states
    return pb, trace(pb, pb.initial(), {"lam": max(lam_lo, 0.1)}, "lam", o, **kw)


@pytest.mark.parametrize("tol", [1e-6, 1e-10])
def test_bratu_chebyshev_refines_mid_branch_and_keeps_the_fold(tol):
    """Lower branch, fold, upper branch to lam = 0.02 where u(1/2) = 9.35 (a steep, narrow profile):
    the grid is refined along the branch without a restart, the fold is located to its closed form
    and the last point meets tol against the closed form."""
    pb, b = bratu_run("cheb", 8, tol, 0.02)
    assert b.status == "EP" and b.message == "reached bound lam=0.02"
    changes = b.grid_changes
    assert len(changes) >= 2 and all(new > old for _, old, new in changes)  # refined mid-branch, more than once
    assert b.grid[-1] > b.grid[0]
    for i in range(len(b)):  # every point stored on its own grid
        assert b.state(i).size == b.grid[i] + 1
        assert b.tangent(i).size == b.grid[i] + 2
    (lp,) = b.fold_points
    assert lp.converged and lp.grid is not None
    assert abs(lp.params["lam"] - BRATU_FOLD) <= tol * BRATU_FOLD
    lam = b.params["lam"][-1]
    mid = pb.with_grid(b.grid[-1]).order_parameter(b.state(-1), None)
    assert abs(mid - bratu_mid(lam)) <= tol * bratu_mid(lam)


def test_bratu_finite_differences_defect_estimate():
    """fd2 with the defect estimate: refined several times; the fold within tol of lam*."""
    pb, b = bratu_run("fd2", 16, 1e-4, 1.0)
    assert b.status == "EP"
    assert len(b.grid_changes) >= 2
    (lp,) = b.fold_points
    assert abs(lp.params["lam"] - BRATU_FOLD) <= 1e-4 * BRATU_FOLD


def joined():
    """Bratu traced both ways from lam = 1 on a needlessly fine start grid (cheb 96)."""
    pb = Bratu("cheb", 96)
    o = ContinuationOptions(bounds={"lam": (0.05, 4.0)}, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=1e-8, min_grid=8))
    return trace_both(pb, pb.initial(), {"lam": 1.0}, "lam", o)


def test_coarsening_and_both_directions_join():
    """Started on a needlessly fine grid, the start grid is coarsened; trace_both joins halves
    on different grids (padded storage, per-point grid column)."""
    b = joined()
    assert any("start grid coarsened 96" in a for a in b.audit)
    assert b.grid.max() < 96 and len(set(b.grid.tolist())) >= 2
    assert b.sizes is not None and np.array_equal(b.sizes, b.grid + 1)
    (lp,) = b.fold_points
    assert abs(lp.params["lam"] - BRATU_FOLD) <= 1e-8 * BRATU_FOLD
    r = b.reversed()
    assert np.array_equal(r.grid, b.grid[::-1]) and np.array_equal(r.state(0), b.state(-1))


def test_hdf5_round_trip_and_version_1_files(tmp_path):
    b = joined()
    path = io.write(tmp_path / "a.h5", [b], scene="toy")
    (c,), meta = io.load(path)
    assert meta["format_version"] == 2
    np.testing.assert_array_equal(c.grid, b.grid)
    for i in (0, len(b) // 2, len(b) - 1):
        np.testing.assert_array_equal(c.state(i), b.state(i))
        np.testing.assert_array_equal(c.tangent(i), b.tangent(i))
    assert [sp.grid for sp in c.special_points] == [sp.grid for sp in b.special_points]
    # a fixed-grid branch written as version 1 (no grid columns) still loads
    pb = Bratu("cheb", 16)
    fixed = trace(pb, pb.initial(), {"lam": 1.0}, "lam", ContinuationOptions(bounds={"lam": (0.5, 4.0)}))
    old = io.write(tmp_path / "old.h5", [fixed])
    with h5py.File(old, "r+") as f:
        f.attrs["format_version"] = 1
        del f["special_points/grid"]
    (d,), meta = io.load(old)
    assert meta["format_version"] == 1 and d.grid is None and d.sizes is None
    assert all(sp.grid is None for sp in d.special_points)
    np.testing.assert_array_equal(d.states, fixed.states)


def test_max_grid_ends_with_the_reason():
    pb, b = bratu_run("cheb", 8, 1e-10, 0.02, max_grid=24)
    assert b.status == "MX"
    assert "on the maximum grid 24" in b.message and "max_grid" in b.message
    assert b.points("MX")[0].note == b.message


def test_a_start_whose_finer_solve_fails_is_not_said_to_be_on_the_maximum_grid():
    """A start point above tol whose solve on the next finer grid does not converge ended
    "... on the maximum grid 8 (AdaptOptions.max_grid = 512)"; it names its grid, the finer grid
    whose solve failed and max_grid."""

    class Unsolvable(Bratu):
        def residual(self, u, p):
            return np.full(np.asarray(u).size, np.nan)

    pb = Bratu("cheb", 8)
    pb.with_grid = lambda n: Unsolvable("cheb", n)  # type: ignore[method-assign]
    o = ContinuationOptions(bounds={"lam": (0.5, 4.0)}, step=StepOptions(ds=0.1), adapt=AdaptOptions(tol=1e-12))
    b = trace(pb, pb.initial(), {"lam": 3.0}, "lam", o)
    assert b.status == "MX" and len(b) == 0
    assert b.message.startswith("start point lam = 3: estimated relative error")
    assert "on grid 8, and its solve on the finer grid 12 did not converge (AdaptOptions.max_grid = 512)" in b.message
    assert "maximum grid" not in b.message


def test_a_two_grid_measurement_is_made_once_per_state(monkeypatch):
    """two_grid_error remembers its last results per problem: a problem whose estimate is itself
    the two-grid error (the non-local problems) had each candidate measured twice, as its estimate
    and by the tracer's check.  The same state is not measured again (one fine factorization);
    another state, parameter or fine grid is."""
    import contin.adapt as adapt
    from contin.newton import newton

    pb = Bratu("cheb", 12)
    u = newton(pb, pb.initial(), {"lam": 2.0}).u
    calls = []
    real = adapt.state_factorization
    monkeypatch.setattr(adapt, "state_factorization", lambda *a: calls.append(1) or real(*a))
    opts = AdaptOptions(tol=1e-8)
    first = adapt.two_grid_error(pb, u, {"lam": 2.0}, 2.0, opts)
    assert adapt.two_grid_error(pb, u.copy(), {"lam": 2.0}, 2.0, opts) == first and len(calls) == 1
    adapt.two_grid_error(pb, u, {"lam": 2.1}, 2.0, opts)
    adapt.two_grid_error(pb, u * (1 + 1e-9), {"lam": 2.0}, 2.0, opts)
    adapt.two_grid_error(pb, u, {"lam": 2.0}, 3.0, opts)
    assert len(calls) == 4
    fresh = adapt._two_grid_error(pb, u, {"lam": 2.0}, 24, opts)  # the memo holds the computed value
    assert fresh == first and first > 0


def test_options_and_hooks_are_checked():
    with pytest.raises(ValueError, match="tol"):
        AdaptOptions(tol=0.0)
    with pytest.raises(ValueError, match="min_grid"):
        AdaptOptions(min_grid=64, max_grid=32)
    with pytest.raises(ValueError, match="coarsen_below"):
        AdaptOptions(coarsen_below=2.0)
    with pytest.raises(ValueError, match="grid_size"):
        check_problem(ImperfectPitchfork())
    o = ContinuationOptions(adapt=AdaptOptions(tol=1e-6))
    with pytest.raises(ValueError, match="hooks"):
        trace(ImperfectPitchfork(), np.array([1.0]), {"lam": 1.0, "alpha": 0.0, "beta": 0.0}, "lam", o)


def test_grid_hooks_transfer_is_spectrally_accurate():
    """transfer() carries the exact Bratu solution between Chebyshev grids to ~1e-13."""
    lam = 1.0
    theta = brentq(lambda th: th**2 / (2 * math.cosh(th / 4) ** 2) - lam, 0.1, 4.7987)

    def exact(pb):
        x = pb.x
        return -2 * np.log(np.cosh((x - 0.5) * theta / 2) / np.cosh(theta / 4))

    a, b = Bratu("cheb", 24), Bratu("cheb", 40)
    np.testing.assert_allclose(a.transfer(exact(a), b), exact(b), atol=1e-12)
    assert a.grid_size == 24 and a.with_grid(40).grid_size == 40


class BlindBratu(Bratu):
    """Bratu whose error estimate does not see the FD scheme's truncation (0 for every state), as
    an estimate that measures how well a grid samples a state but not the scheme's error (gPCF's
    FD estimate: the Chebyshev tail of the interpolated profiles)."""

    def error_estimate(self, u, p):
        return 0.0


def bratu_lower_exact(x, lam):
    """Bratu's lower-branch solution at lam (closed form, theta below the fold's 4.7987)."""
    theta = brentq(lambda th: th**2 / (2 * math.cosh(th / 4) ** 2) - lam, 1e-9, 4.7987, xtol=1e-15)
    return -2 * np.log(np.cosh((x - 0.5) * theta / 2) / np.cosh(theta / 4))


@pytest.mark.parametrize("method", ["fd2", "fd4"])
def test_fd_states_are_checked_even_where_the_estimate_is_blind(method):
    """On an FD grid every accepted state gets its two-grid check, whatever its estimate says
    (``contin.adapt.estimate_decides_check``): with an estimate blind to the scheme's error the
    states were accepted unchecked on the coarsest grid (fd2 8: 1.2e-2 off the closed form at
    tol 1e-4; fd4 8: 2.7e-4).  Now every stored state is within tol of the closed form."""
    tol = 1e-4
    pb = BlindBratu(method, 16)
    o = ContinuationOptions(bounds={"lam": (0.5, 3.0)}, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=tol, min_grid=8))
    b = trace(pb, pb.initial(), {"lam": 0.5}, "lam", o)
    assert b.status == "EP" and b.parameter_values[-1] == pytest.approx(3.0)
    assert max(b.grid) > 8  # refined by the checks, not left on min_grid by the blind estimate
    for i in range(len(b)):
        grid = pb.with_grid(b.grid_at(i))
        exact = bratu_lower_exact(grid.x, b.parameter_values[i])
        assert np.max(np.abs(b.state(i) - exact)) / np.max(np.abs(exact)) <= tol


@pytest.mark.parametrize("method", ["fd2", "fd4"])
def test_the_start_point_gets_the_two_grid_check(method):
    """The start state was judged by its estimate alone (``start_grid``): with an estimate blind to
    the FD scheme's error a start at lam = 3 was coarsened to fd2 8 and stored there 1.2e-2 off
    the closed form (fd4 8: 2.7e-4) at tol 1e-4 -- the first point of every switched branch of
    ``contin trace allen-cahn --method fd2 --tol 1e-4`` was likewise stored up to 1.5e-2 off a cheb
    reference without a warning (session 15).  Now the start is two-grid checked and refined."""
    tol = 1e-4
    pb = BlindBratu(method, 16)
    o = ContinuationOptions(bounds={"lam": (3.0, 3.3)}, max_steps=3, step=StepOptions(ds=0.1, ds_max=0.2),
                            adapt=AdaptOptions(tol=tol, min_grid=8))
    b = trace(pb, bratu_lower_exact(pb.x, 3.0), {"lam": 3.0}, "lam", o)
    assert b.grid_at(0) > 8 and any("two-grid error" in line and "start grid refined" in line for line in b.audit)
    grid = pb.with_grid(b.grid_at(0))
    exact = bratu_lower_exact(grid.x, 3.0)
    assert np.max(np.abs(b.state(0) - exact)) / np.max(np.abs(exact)) <= tol


def test_a_start_point_left_above_tol_is_a_warning():
    """Where refinement cannot lower the start's two-grid error (max_grid), the start is stored
    with the audit line of a point accepted by its estimate, which ``contin trace`` prints as a
    warning (``contin.cli.trace.doubtful_points``)."""
    from contin.cli.trace import doubtful_points

    pb = BlindBratu("fd2", 16)
    o = ContinuationOptions(bounds={"lam": (3.0, 3.3)}, max_steps=2, step=StepOptions(ds=0.1, ds_max=0.2),
                            adapt=AdaptOptions(tol=1e-4, min_grid=8, max_grid=16))
    b = trace(pb, bratu_lower_exact(pb.x, 3.0), {"lam": 3.0}, "lam", o)
    (line,) = [m for m in doubtful_points(b) if m.startswith("step 0:")]
    assert line.startswith("step 0: lam=3 accepted by its estimate: two-grid error") and "at the start point" in line


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8, 1e-10])
def test_couette_critical_gap_meets_tol(tol):
    """gPCF uniform shear at nu = 0.3, e = 0.8: started on cheb 64, the start grid is coarsened (the
    uniform state is exact on any grid); the BP's bracket shows its null vector under-resolved on the
    coarse grid, so the grid is refined before the BP is located, once, on the finer grid (not
    located on the coarse grid and again: issue 14's cost): |H_1^c - pi psi| / pi psi <= tol."""
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    exact = pf.analytic_critical_gaps(0.3, 0.8, 1)[0]
    pb = CouetteProblem("cheb", 64)
    p = pb.params({"nu": 0.3, "e": 0.8})
    o = ContinuationOptions(bounds={"H": (0.8 * exact, 1.2 * exact)},
                            step=StepOptions(ds=0.1 * exact, ds_max=0.3 * exact),
                            detection=DetectionOptions(locate_tol=1e-13), adapt=AdaptOptions(tol=tol, min_grid=4))
    b = pf.trace_base(pb, p, 0.8 * exact, o)
    (bp,) = b.branch_points
    assert bp.grid < 64  # cheaper than the fixed default grid
    assert abs(bp.params["H"] - exact) / exact <= tol
    refined = [a for a in b.audit if "BP bracketed, kernel under-resolved" in a]
    assert len(refined) == 1 and "8 -> 16" in refined[0]
    assert not any("located BP under-resolved" in a for a in b.audit)  # no second location
    assert b.grid_at(-1) == bp.grid == 16


def test_couette_special_points_keep_fine_grid_accuracy_at_default_tol():
    """At the default tol (3e-5, what the states need) the uniform branch runs on coarse grids,
    but every BP is located on a grid whose kernel estimate meets AdaptOptions.special_tol
    (1e-10): H_1^c..H_3^c to 1e-9 of n pi psi (at special_tol = tol = 3e-5 H_3^c was off by 1.3e-8)."""
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    exact = pf.analytic_critical_gaps(0.3, 0.8, 3)
    pb = CouetteProblem("cheb", 64)
    p = pb.params({"nu": 0.3, "e": 0.8})
    o = ContinuationOptions(bounds={"H": (0.5 * exact[0], 3.2 * exact[0])},
                            step=StepOptions(ds=0.1 * exact[0], ds_max=0.4 * exact[0]), adapt=AdaptOptions())
    b = pf.trace_base(pb, p, 0.5 * exact[0], o)
    found = sorted(bp.params["H"] for bp in b.branch_points)
    assert len(found) == 3
    for h, ref in zip(found, exact):
        assert abs(h - ref) / ref <= 1e-9
    assert max(b.grid) < 64  # still cheaper than the fixed default grid
    with pytest.raises(ValueError, match="special_tol"):
        AdaptOptions(special_tol=0.0)


def test_fold_refined_before_it_is_located():
    """Core behaviour on a non-granular problem (Bratu, Chebyshev, tol 1e-6 from cheb 32): the
    fold's bracket shows its kernel (the tangent) under-resolved on cheb 20, so the grid is
    refined before the fold is located (Adaptor.pre_locate) and the fold is located once, on
    the finer grid, where its kernel meets special_tol; lam* to tol of the closed form."""
    from problems.demo import BRATU_FOLD, Bratu

    pb = Bratu("cheb", 32)
    o = ContinuationOptions(bounds={"lam": (0.02, 4.0)}, max_steps=400, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=1e-6, min_grid=8))
    b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)
    (fold,) = b.fold_points
    first = [a for a in b.audit if "LP bracketed, kernel under-resolved" in a]
    assert len(first) == 1 and "20 -> 32" in first[0]
    assert not any("located LP under-resolved" in a for a in b.audit)  # located once
    assert fold.grid == 32
    assert pb.with_grid(32).vector_error(fold.tangent[:-1]) <= AdaptOptions().special_tol
    assert abs(fold.params["lam"] - BRATU_FOLD) / BRATU_FOLD <= 1e-6


def test_kernel_vectors_of_the_grid_decisions():
    """adapt.null_vector (dense LAPACK bordering up to DENSE_KERNEL_MAX) equals the sparse
    bordering of contin.normalform.null_vectors; near_kernel recovers the smallest singular
    direction of a regular J next to a singular one, where the bordered vector alone keeps the
    other small directions: J = Q diag(1e-6, 1e-3, 1, ..., 1) Q^T."""
    import scipy.sparse as sp

    from contin.adapt import near_kernel, null_vector
    from contin.normalform import null_vectors

    rng = np.random.default_rng(3)
    n = 40
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    d = np.ones(n)
    d[0], d[1] = 0.0, 1e-3
    sing = sp.csr_matrix(q @ np.diag(d) @ q.T)
    v, ref = null_vector(sing), null_vectors(sp.csc_matrix(sing)).phi
    assert min(np.abs(v - ref).max(), np.abs(v + ref).max()) < 1e-10
    d[0] = 1e-6
    near = q @ np.diag(d) @ q.T
    k = near_kernel(sp.csr_matrix(near))
    assert 1 - abs(k @ q[:, 0]) < 1e-12
    assert 1 - abs(null_vector(sp.csr_matrix(near)) @ q[:, 0]) > 1e-8  # what the iterations remove


def test_slice_of_a_regridded_branch_keeps_each_points_grid():
    """contin.overlap.slice_branch (the trims of contin.jumps/seeds) on a branch whose points lie
    on several grids: the grid and size columns are sliced with the points, so every kept point's
    state is still the solution on its own grid (residual ~0 there)."""
    from contin.adapt import point_problem
    from contin.overlap import slice_branch

    pb, b = bratu_run("cheb", 8, 1e-8, 0.02)
    (i, old, new), *_ = b.grid_changes
    part = slice_branch(b, i - 2, len(b) - 1)
    assert len(part.grid) == len(part.sizes) == len(part) == len(b) - i + 2
    assert part.grid_changes[0] == (2, old, new)
    for j in range(len(part)):
        q = {"lam": float(part.params["lam"][j])}
        assert part.state(j).size == part.grid[j] + 1
        assert np.max(np.abs(point_problem(pb, part, j).residual(part.state(j), q))) < 1e-8


def test_fd4_demo_does_not_coarsen_below_its_reference_scheme(tmp_path):
    """The demo BVPs' fd4 estimate is the defect against fd6 on the same nodes, which needs 12
    intervals: on fewer the estimate is inf, so the start grid is not coarsened to min_grid 8
    (that stopped `contin trace bratu --method fd4 --tol 1e-6` with 'grid too small: fd6 needs at
    least 12 intervals, got 8').  The fold within 1e-6 of lam*."""
    from click.testing import CliRunner

    from contin.cli import main

    assert math.isinf(Bratu("fd4", 8).error_estimate(np.zeros(9), {"lam": 1.0}))
    out = tmp_path / "b.h5"
    r = CliRunner().invoke(main, ["trace", "bratu", "--method", "fd4", "--tol", "1e-6", "--no-stability", "-q", "-o", str(out)])
    assert r.exit_code == 0, r.output
    (b,), _ = io.load(out)
    (lp,) = b.fold_points
    assert abs(lp.params["lam"] / BRATU_FOLD - 1) <= 1e-6
    assert int(np.min(b.grid)) >= 12


def test_couette_fd4_branch_states_meet_tol(tmp_path):
    """gPCF (problems.couette) fd4 at --tol 1e-4: its FD estimate (the Chebyshev tail of the
    interpolated profiles) is ~1e-10 on the n = 1 branch, which once let the run coarsen to fd4
    192 and store H = 34 .. 43 unchecked with errors up to 2.3e-3.  Every stored state of the
    branch is now within tol of a cheb 128 reference (the same state solved on the finer grid)."""
    from click.testing import CliRunner

    from contin.adapt import solution_error
    from contin.cli import main
    from contin.newton import newton
    from contin.options import NewtonOptions
    from problems.couette.model import CouetteProblem

    tol = 1e-4
    out = tmp_path / "fd4.h5"
    r = CliRunner().invoke(main, ["trace", "pitchfork", "-s", "nu=0.3", "-s", "e=0.8", "--method", "fd4", "--tol",
                                  str(tol), "--no-stability", "-q", "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    (b,) = [x for x in branches if x.id == "n1.1"]
    assert b.status == "EP" and b.parameter_values[-1] == pytest.approx(43.12614677)
    ref = CouetteProblem("cheb", 128)
    for i in range(1, len(b)):  # (point 0 is the BP: J singular there, Newton stalls at rounding)
        pb = CouetteProblem("fd4", b.grid_at(i))
        p = pb.params({"nu": 0.3, "e": 0.8, "H": float(b.parameter_values[i])})
        v = pb.transfer(b.state(i), ref)
        sol = newton(ref, v, p, NewtonOptions())
        assert sol.converged
        assert solution_error(ref, v, sol.u, p) <= tol


class BumpBratu(Bratu):
    """Bratu whose estimate is large within 0.02 of lam = 2 only (a feature there that falls like
    N^-2): a state at lam = 2 needs N >= 64 for tol 1e-4, the states around it do not."""

    def error_estimate(self, u, p):
        base = super().error_estimate(u, p)
        return max(base, 4e-3 * (8.0 / self.grid_size) ** 2) if abs(p["lam"] - 2.0) < 0.02 else base


def test_the_point_landed_on_a_bound_is_checked():
    """A step that crosses a bound is landed on it by a new correction; that landed state was
    stored unchecked (its estimate 1.8e-3 on cheb 12 at tol 1e-4: the candidate beyond the bound
    had passed).  Now it is judged like any candidate: refined at the last point until the bound
    state's own estimate meets tol."""
    pb = BumpBratu("cheb", 16)
    o = ContinuationOptions(bounds={"lam": (0.5, 2.0)}, step=StepOptions(ds=0.4, ds_max=0.4),
                            adapt=AdaptOptions(tol=1e-4, min_grid=8))
    b = trace(pb, pb.initial(), {"lam": 0.5}, "lam", o)
    assert b.status == "EP" and b.parameter_values[-1] == 2.0
    last = pb.with_grid(b.grid_at(-1))
    assert last.error_estimate(b.state(-1), {"lam": 2.0}) <= 1e-4 < 4e-3 * (8.0 / b.grid_at(0)) ** 2
    assert any("above tol at the bound" in line for line in b.audit)


def test_a_bp_that_refinement_moves_behind_the_last_point_is_found():
    """Allen-Cahn fd2 traced down from lam = 35: the start grid coarsens to fd2 8 (u = 0 is exact
    on every grid), where the eigenvalue of mode 5 sits far below 25 (fd2 lowers it); the BP is
    bracketed there, the grid refined at the last point -- and on the finer grid the BP lies
    behind that point.  Tracing on from it skipped lam = 25 (BPs found: 16 and 9 only).  Now the
    tracer retreats to the last stored point before the finer grid's zero and finds all three
    BPs k^2 (within fd2's error)."""
    pb = AllenCahn("fd2", 16)
    o = ContinuationOptions(bounds={"lam": (5.0, 35.0)}, max_steps=200, step=StepOptions(ds=2.0, ds_max=4.0),
                            adapt=AdaptOptions(tol=1e-4, min_grid=8))
    b = trace(pb, pb.initial(), {"lam": 35.0}, "lam", o, direction=-1)
    lams = [s.params["lam"] for s in b.points("BP")]
    assert len(lams) == 3
    for lam, k in zip(lams, (5, 4, 3)):
        assert abs(lam - k * k) <= 1e-3 * k * k
    assert any(line.startswith("retreated 1 point(s)") for line in b.audit)


def test_couette_fd2_base_branch_finds_its_three_bps():
    """gPCF (problems.couette) fd2 at --tol 1e-4: the uniform state is exact on every grid, so the
    start grid coarsens to fd2 8; the first BP is bracketed there at H = 13.85 .. 17.1, and fd2 16
    has it at 13.07 -- behind the point the grid was refined at.  The run found none of the three
    BPs (``contin trace pitchfork --method fd2 --tol 1e-4``: 'modes 1, 2, 3 not found').  Now
    H_1^c, H_2^c, H_3^c are found, each within fd2's error of n pi psi."""
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    pb = CouetteProblem("fd2", 64)
    p = pb.params({"nu": 0.3, "e": 0.8})
    o = ContinuationOptions(bounds={"H": (2.0, 43.2)}, step=StepOptions(ds=1.0, ds_max=5.0),
                            detection=DetectionOptions(), adapt=AdaptOptions(tol=1e-4))
    b = pf.trace_base(pb, p, 2.0, o)
    exact = pf.analytic_critical_gaps(0.3, 0.8, 3)
    found = sorted(s.params["H"] for s in b.branch_points)
    assert len(found) == 3
    for h, h_exact in zip(found, exact):
        assert abs(h / h_exact - 1) <= 1e-3


def test_each_special_point_is_refined_afresh():
    """Allen-Cahn fd2 at tol 1e-4 (special_tol 1e-10): BP1 is refined to max_grid 512 and stored
    there unresolved (its fd2 error 3.1e-6 > special_tol); the memory of that chain judged BP2's
    first measurement (6.1e-5 on fd2 232) as 'not falling', so BP2 and BP3 were stored without a
    single refinement (BP3 1.4e-3 off on fd2 72).  A point stored on max_grid now clears that
    memory (a chain that stalled below it keeps it: the artefact guard), so each BP gets its own
    chain: all three on fd2 512, each the discrete eigenvalue (4/h^2) sin^2(k h/2), h = pi/512."""
    pb = AllenCahn("fd2", 32)
    o = ContinuationOptions(bounds={"lam": (0.5, 10.0)}, max_steps=300, step=StepOptions(ds=0.5, ds_max=1.5),
                            adapt=AdaptOptions(tol=1e-4))
    b = trace(pb, pb.initial(), {"lam": 0.5}, "lam", o)
    bps = b.points("BP")
    assert len(bps) == 3
    h = math.pi / 512
    for k, bp in zip((1, 2, 3), bps):
        assert bp.grid == 512
        assert bp.params["lam"] == pytest.approx(4 / h**2 * math.sin(k * h / 2) ** 2, rel=1e-9)
