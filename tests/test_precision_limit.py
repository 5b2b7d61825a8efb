"""The precision limit of adaptive resolution (issue 14): where rounding, which no finer grid
lowers, exceeds tol, a branch ends EP "precision limit ..." with every stored point meeting tol,
instead of MX "refine the grid".

References: gPCF's plug states against the same point solved with a longdouble residual and
iterative refinement (problems.couette.extended_precision: rounding floor ~2000x lower), on the
same grid (the rounding error) and on a 1.5x finer grid (truncation + rounding); the core logic
on Bratu (problems.demo) with a synthetic rounding model that grows like N^2.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from click.testing import CliRunner

from contin import io
from contin.adapt import AdaptOptions
from contin.cli import main
from contin.continuation import trace
from contin.options import ContinuationOptions, StepOptions
from problems.demo import Bratu


class NoisyBratu(Bratu):
    """Bratu whose state carries a rounding error K N^2 max|u| (grows with the grid, as
    collocation rounding does): error_estimate = max(truncation, rounding)."""

    K = 2e-10

    def rounding_error(self, u, p):
        return self.K * self.grid_size**2 * float(np.max(np.abs(u)))

    def error_estimate(self, u, p):
        return max(super().error_estimate(u, p), self.rounding_error(u, p))


def noisy_run(K: float):
    NoisyBratu.K = K
    pb = NoisyBratu("cheb", 8)
    o = ContinuationOptions(bounds={"lam": (0.02, 4.0)}, max_steps=400, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=1e-6, max_grid=512, min_grid=8, special_tol=1e-6))
    return pb, trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)


@pytest.mark.parametrize("K, last_grid, named_grid", [(2e-10, 32, 32), (5e-10, 20, 32)])
def test_core_precision_limit_ends_ep_with_every_point_within_tol(K, last_grid, named_grid):
    """K = 2e-10: a candidate on cheb 32 whose rounding (1.1e-6) exceeds tol ends the branch;
    K = 5e-10: refining 20 -> 32 would put the last point's rounding above tol, so the point stays on
    cheb 20 (the grid change is undone) and the branch ends there.  Either way: EP, not MX; every
    stored point (the last included) has its estimate <= tol; the message states that accuracy."""
    pb, b = noisy_run(K)
    assert b.status == "EP" and b.message.startswith("precision limit at lam = ")
    assert f"> tol 1e-06 on grid {named_grid}, which no finer grid lowers" in b.message
    errors = [pb.with_grid(b.grid[i]).error_estimate(b.state(i), None) for i in range(len(b))]
    assert max(errors) <= 1e-6
    assert b.grid[-1] == last_grid and b.grid_changes[-1][2] == last_grid
    assert f"accurate to {errors[-1]:.2g} up to lam = {b.params['lam'][-1]:.6g}" in b.message
    # the rounding at the named grid is what ends it: K N^2 max|u| > tol there
    assert K * named_grid**2 * float(np.max(b.state(-1))) > 1e-6 * 0.5
    assert b.special_points[-1].type == "EP"


class SlowBratu(Bratu):
    """Bratu whose estimate falls only like N^-1/2 with the grid and grows like exp(12 u_max): a
    candidate far along the branch does not halve its estimate when refined, a nearer one meets tol."""

    def error_estimate(self, u, p):
        return max(super().error_estimate(u, p), 1e-9 * np.exp(12.0 * float(np.max(u))) * (8.0 / self.grid_size) ** 0.5)


def test_core_stalled_refinement_retries_a_shorter_step_first():
    """At lam = 2.756 refining 20 -> 32 does not halve the candidate's estimate (6.7e-6 -> 5.2e-6): the
    tracer halves the step instead of ending there ("shortened" in the audit), goes on to lam = 2.999 and
    ends only on the maximum grid (64); every stored point meets tol 1e-6.  There the estimate falls
    like N^-1/2 by construction, so the end is EP "resolution limit" (contin.adapt, SLOW_ORDER) with
    the fitted order 0.5 and the grid tol needs, 64 (err / tol)^2 (tests/test_resolution_limit.py)."""
    pb = SlowBratu("cheb", 8)
    o = ContinuationOptions(bounds={"lam": (0.02, 4.0)}, max_steps=200, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=1e-6, max_grid=64, min_grid=8, special_tol=1e-6))
    b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)
    shortened = [a for a in b.audit if "shortened" in a]
    assert shortened and shortened[0].startswith("step 9: lam=2.755964807 ds=0.5 shortened: under-resolved")
    assert b.status == "EP" and b.message.startswith("resolution limit at lam = ")
    m = re.search(r"error ([0-9.e+-]+) > tol 1e-06 on the maximum grid 64 falls only like N\^-0.5 .*tol needs N ~ "
                  r"([0-9.e+]+) > max_grid 64", b.message)
    assert m, b.message
    assert float(m.group(2)) == pytest.approx(64 * (float(m.group(1)) / 1e-6) ** 2, rel=0.05)
    assert b.params["lam"][-1] > 2.99 and b.grid[-1] == 64
    assert max(pb.with_grid(b.grid[i]).error_estimate(b.state(i), None) for i in range(len(b))) <= 1e-6


def _longdouble_solution(pb, x, p, iterations=5):
    """x refined with the longdouble residual (Newton with the double Jacobian)."""
    from problems.couette.extended_precision import LD, extended

    ext = extended(pb)
    pl = {k: LD(v) if isinstance(v, float) else v for k, v in p.items()}
    X = np.asarray(x).astype(LD)
    for _ in range(iterations):
        lu = spla.splu(sp.csc_matrix(pb.jacobian(np.asarray(X, float), p)))
        X = X - lu.solve(np.asarray(ext.residual(X, pl), float)).astype(LD)
    return X


def _nu_error(pb, x, X):
    """max over the nodes of |nu - nu_ref| / (nu_m - nu_ref): the estimate's measure."""
    from problems.couette.extended_precision import LD

    n = pb.grid.size
    gap = np.asarray(LD(0.65) - X[:n], float)
    return float(np.max(np.abs(np.asarray(np.asarray(x).astype(LD) - X, float)[:n]) / gap))


@pytest.mark.slow
def test_nu063_plug_two_grid_check_ends_where_its_error_stops_falling(tmp_path):
    """The default run (two-grid check on): the n = 1 band ends EP on cheb 80 where the check's error
    does not fall with refinement, before the rounding estimate's limit at H = 91.4 and beyond
    H = 85.97, where it ended without the fine residual of gPCF's ``precise_residual`` (the fine
    grids' double rounding); exit 0, every stored point of n1.1 passed its check.  What remains is
    the rounding of the coarse (double) solve itself, which grows with the grid as well.  Where that
    rounding floor first exceeds tol is decided by last bits: H = 87.0361 (4.5e-5 against cheb 160,
    1.7e-4 on cheb 128 against 256) under the earlier numpy/scipy stack, 88.3553 under numpy 2.4.6
    / scipy 1.17.1 (the test asked for 87.0361 to 1e-4 and failed there for no defect)."""
    out = tmp_path / "p.h5"
    r = CliRunner().invoke(main, ["trace", "pitchfork", "-s", "nu=0.63", "-s", "e=0.8", "-s", "modes=1",
                                  "-s", "H_max=100", "--no-stability", "-q", "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    band = next(b for b in branches if b.id == "n1.1")
    end = band.params["H"][-1]
    assert band.status == "EP" and band.message.startswith(f"precision limit at H = {end:.6g}: the two-grid error "
                                                           "of the solve does not fall with refinement")
    assert band.grid[-1] == 80 and 85.97 < end < 91.4


def test_nu063_plug_ends_at_the_precision_limit(tmp_path):
    """nu = 0.63, e = 0.8, n = 1 (issue 14 (1)): the band's plug reaches 6e-9 below nu_m = 0.65 near
    H = 91.3 on cheb 80, where rounding (0.2 eps N^2 nu_m / gap = 2.9e-5) reaches tol 3e-5.  The
    branch ends EP "precision limit" (exit 0), not MX.  Against the extended-precision solution the
    last point's nu is accurate to 9.7e-6 of the distance to packing (estimate 2.9e-5 >= it); on cheb
    192 the same point is *less* accurate (9.6e-5: rounding grows like N^2) -- no finer grid meets tol."""
    from problems.couette.model import CouetteProblem
    from problems.couette.resolution import resolution

    out = tmp_path / "p.h5"
    # the rounding estimate is the subject: the estimate alone (--no-solve-check); the default run's
    # two-grid check ends earlier (test_nu063_plug_two_grid_check_ends_where_its_error_stops_falling)
    r = CliRunner().invoke(main, ["trace", "pitchfork", "-s", "nu=0.63", "-s", "e=0.8", "-s", "modes=1",
                                  "-s", "H_max=100", "--no-stability", "--no-solve-check", "-q", "-o", str(out)],
                           catch_exceptions=False)
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    band = next(b for b in branches if b.id == "n1.1")
    assert band.status == "EP" and band.message.startswith("precision limit at H = ")
    assert 90.0 < band.params["H"][-1] < 93.0 and band.grid[-1] == 80
    pb0 = CouetteProblem("cheb", 64)

    def at(i):
        pb = pb0.with_grid(band.grid_at(i))
        return pb, band.state(i), pb.params({"nu": 0.63, "e": 0.8, "H": float(band.params["H"][i])})

    for i in range(len(band)):
        pb, x, p = at(i)
        assert resolution(pb, x, p).error <= 3e-5
    pb, x, p = at(-1)
    res = resolution(pb, x, p)
    assert 5e-9 < res.gap < 8e-9 and res.precision_limited and 2e-5 < res.rounding <= 3e-5
    rounding = _nu_error(pb, x, _longdouble_solution(pb, x, p))  # same grid: the rounding error
    finer = pb0.with_grid(120)
    total = _nu_error(finer, pb.transfer(x, finer), _longdouble_solution(finer, pb.transfer(x, finer), p))
    assert 1e-7 < rounding <= res.error and 1e-7 < total <= res.error
    # the same point on cheb 192: double-precision Newton, then its error against the ld solution there
    from contin.newton import newton

    fine = pb0.with_grid(192)
    x192 = newton(fine, pb.transfer(x, fine), p).u
    err192 = _nu_error(fine, x192, _longdouble_solution(fine, x192, p))
    assert err192 > 3 * rounding
    assert resolution(fine, x192, p).rounding > 3e-5
    # finite differences: rounding grows like eps N / gap, not eps N^2 / gap (fd4 N = 200 here: the
    # Chebyshev formula would overstate it ~500x); the estimate still bounds the measured error
    fd = CouetteProblem("fd4", 200)
    xfd = newton(fd, fd.pack(*(pb.grid.interpolate(f, fd.grid.y) for f in pb.unpack(x)[:3]), pb.unpack(x)[3]), p).u
    rfd = resolution(fd, xfd, p)
    err_fd = _nu_error(fd, xfd, _longdouble_solution(fd, xfd, p))
    assert 1e-8 < err_fd <= rfd.rounding < 1e-4
    assert rfd.rounding == pytest.approx(0.2 * np.finfo(float).eps * 5 * 200 * 0.65 / rfd.gap, rel=1e-9)


# ----------------------------------------------------------------------------- 2-D disks (problems.disks)
def _disks_longdouble_solution(pb, x, p, iterations=6):
    """x refined with the disks residual in longdouble: the grid's operators, nodes and weights from
    problems.discretization.extended_grid (dense longdouble products), the closure's numpy
    formulas in longdouble; Newton steps with the double Jacobian."""
    import copy

    from problems.discretization import extended_grid

    LD = np.longdouble
    ext = copy.copy(pb)
    g = extended_grid(pb.method, pb.N)
    ext.grid = g

    class Dense:
        def __init__(self, m):
            self.m = np.asarray(m.toarray(), dtype=LD)

        def __matmul__(self, v):
            return self.m @ v

    ext._d1, ext._d2 = Dense(g.d1), Dense(g.d2)
    pl = {k: LD(v) if isinstance(v, float) else v for k, v in p.items()}
    X = np.asarray(x).astype(LD)
    for _ in range(iterations):
        r = ext.residual(X, pl)
        assert r.dtype == LD
        X = X - spla.spsolve(sp.csc_matrix(pb.jacobian(np.asarray(X, float), p)), np.asarray(r, float)).astype(LD)
    return X


def test_disks_grid_hooks_and_adaptive_band_to_the_precision_limit():
    """G_CS disks, nu = 0.5, e = 0.8: the n = 1 band (issue 14 (2): MX on cheb 64 at H = 28.8768, plug
    4.5e-10 below phi_inf = 0.9) traced adaptively from cheb 32 ends EP "precision limit" near
    H = 28.8768 on cheb 80 with every stored point's estimate <= 3e-5; against the longdouble
    solution the last point's nu is within its estimate (rounding, factor 4: 1.3 .. 3.1 x eps N^2
    phi_inf / gap measured), and H_1^c is located to 1e-10 of n pi psi."""
    from contin.adapt import missing_hooks, point_problem
    from contin.continuation import switch
    from contin.options import DetectionOptions
    from problems.couette.resolution import resolution
    from problems.disks.closures import DiskClosure, critical_gaps
    from problems.disks.model import DiskCouetteProblem

    cl = DiskClosure("cs")
    pb = DiskCouetteProblem("cheb", 32, closure=cl)
    assert missing_hooks(pb) == []
    p = pb.params({"nu": 0.5, "e": 0.8})
    hc = critical_gaps(p, cl, 1)[0]
    p["H"] = 0.8 * hc
    # the rounding estimate's precision limit is the subject: the estimate alone decides (the
    # two-grid check, on by default, refines the band to cheb 128 before the same end at H = 28.876)
    ad = AdaptOptions(tol=3e-5, check_factor=None)
    o = ContinuationOptions(bounds={"H": (0.8 * hc, 1.2 * hc)}, max_steps=50, step=StepOptions(ds=0.05 * hc, ds_max=0.1 * hc),
                            detection=DetectionOptions(locate_tol=1e-12, detect_hopf=False), adapt=ad)
    base = trace(pb, pb.uniform_state(p), p, "H", o)
    (bp,) = base.branch_points
    assert abs(bp.params["H"] - hc) < 1e-10 * hc
    ob = ContinuationOptions(bounds={"H": (0.3 * hc, 2.2 * hc)}, max_steps=100,
                             step=StepOptions(ds=0.01, ds_max=0.05 * hc, ds_min=1e-8, newton_target=6, grow=2.0),
                             detection=DetectionOptions(locate_tol=1e-9, detect_hopf=False), adapt=ad)
    band = switch(pb, base, bp, ob, directions=(+1,))[0]
    assert band.status == "EP" and band.message.startswith("precision limit at H = 28.876")
    assert band.grid[-1] == 80 and [c[2] for c in band.grid_changes] == [32, 48, 80]
    res = [resolution(point_problem(pb, band, i), band.state(i), {**p, "H": float(band.params["H"][i])})
           for i in range(len(band))]
    assert max(r.error for r in res) <= 3e-5
    last = res[-1]
    assert 1e-7 < last.gap < 1e-6 and last.precision_limited
    q = {**p, "H": float(band.params["H"][-1])}
    pb80 = point_problem(pb, band, -1)
    X = _disks_longdouble_solution(pb80, band.state(-1), q)
    n = pb80.n
    gap = np.asarray(np.longdouble(0.9) - X[:n], float)
    err = float(np.max(np.abs(np.asarray(band.state(-1).astype(np.longdouble) - X, float)[:n]) / gap))
    assert 1e-7 < err <= last.error
    # transfer is spectrally accurate between grids (a smooth state: the band well before the plug)
    i = len(band) // 3
    a = point_problem(pb, band, i)
    there = a.transfer(band.state(i), pb.with_grid(96))
    np.testing.assert_allclose(pb.with_grid(96).transfer(there, a), band.state(i), atol=1e-12)


def test_fixed_grid_guard_ends_ep_at_the_precision_limit(tmp_path):
    """--grid 80 (no adaptation): the resolution guard's reason for the nu = 0.63 band near H = 91.6 is
    rounding, not the grid, so the branch ends EP "precision limit at H = ..." (exit 0), and
    contin.adapt.retrace_finer does not retrace it on finer grids (under_resolved_stop is False)."""
    from contin.adapt import under_resolved_stop

    out = tmp_path / "g.h5"
    r = CliRunner().invoke(main, ["trace", "pitchfork", "-s", "nu=0.63", "-s", "e=0.8", "-s", "modes=1", "-s", "H_max=100",
                                  "--no-stability", "--grid", "80", "-q", "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    band = next(b for b in branches if b.id == "n1.1")
    assert band.status == "EP" and band.message.startswith("precision limit at H = 91.")
    assert "of the packing limit nu_m = 0.65" in band.message and band.message.endswith("on cheb 80; finer grids only raise it")
    assert 90.5 < band.params["H"][-1] < 91.6 and not under_resolved_stop(band)


# ----------------------------------------------------------------------------- precise_residual hook
EPS = np.finfo(float).eps


class RoundedBratu(Bratu):
    """Bratu whose double residual carries a fixed rounding-like noise K eps N^4 g (g a standard
    normal vector per grid: the size of the cheb D2 rows' rounding, which grows like N^4), and
    whose ``rounding_error`` says so.  Without a precise residual, the two-grid check measures
    the finer grid's noise (16x the point's own at factor 2) and stalls."""

    K = 0.5

    def _noise(self):
        g = getattr(self, "_noise_vector", None)
        if g is None:
            rng = np.random.default_rng(self.grid_size)
            g = self._noise_vector = self.K * EPS * self.grid_size**4 * rng.standard_normal(self.n)
        return g

    def residual(self, u, p):
        return super().residual(u, p) + self._noise()

    def rounding_error(self, u, p):
        return self.K * EPS * self.grid_size**4


class PreciseBratu(RoundedBratu):
    """The same with the optional ``precise_residual`` hook: the residual without the noise."""

    calls = 0

    def precise_residual(self, u, p):
        PreciseBratu.calls += 1
        return Bratu.residual(self, u, p)


def rounded_run(cls, tol):
    pb = cls("cheb", 8)
    o = ContinuationOptions(bounds={"lam": (0.02, 3.0)}, max_steps=200, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=tol, max_grid=512, min_grid=8, special_tol=1e-6))
    return pb, trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)


def test_core_precise_residual_lifts_the_two_grid_rounding_floor():
    """tol 1e-9: without the hook the first point's two-grid error does not fall with refinement
    (2e-9 against cheb 24, 1.2e-8 against cheb 40: the finer grid's noise), so the branch ends EP
    "precision limit" at lam = 0.1; with ``precise_residual`` (rounding_error >= tol / 100 on the
    check grid) the check's residual and its two refinement steps are noise-free, and the branch
    reaches lam = 3 on cheb 12 -> 20, as clean Bratu does.  contin verify polishes its fine solves with
    the hook too: every point within tol (2.1e-10 worst); without the hook it measures the noise."""
    from contin.verify import verify_branch

    _, stalled = rounded_run(RoundedBratu, 1e-9)
    assert stalled.status == "EP" and stalled.message.startswith("precision limit at lam = 0.1: the two-grid error")
    PreciseBratu.calls = 0
    pb, b = rounded_run(PreciseBratu, 1e-9)
    assert PreciseBratu.calls > 0
    assert b.status == "EP" and b.message == "reached bound lam=3"
    assert [c[1:] for c in b.grid_changes] == [(12, 20)]
    check = verify_branch(pb, b, {"lam": 0.1}, tol=1e-9)
    assert check.ok and 1e-11 < check.max_error < 5e-10
    noisy = verify_branch(RoundedBratu("cheb", 8), b, {"lam": 0.1}, tol=1e-9)
    assert noisy.exceeding and noisy.max_error > 2e-9


def test_core_precise_residual_unused_where_rounding_is_negligible():
    """tol 1e-6: the rounding estimate (<= 1.4e-10 on the check grids) is below tol / 100, so the
    hook is never called and the branch is bitwise the one without it."""
    PreciseBratu.calls = 0
    _, a = rounded_run(PreciseBratu, 1e-6)
    assert PreciseBratu.calls == 0
    _, b = rounded_run(RoundedBratu, 1e-6)
    assert a.status == b.status == "EP" and len(a) == len(b)
    for i in range(len(a)):
        assert a.state(i).tobytes() == b.state(i).tobytes()
    assert a.params["lam"].tobytes() == b.params["lam"].tobytes()


def test_gpcf_precise_residual_agrees_with_the_residual():
    """At an ordinary (non-solution) state F is O(1): the longdouble residual agrees with the double
    one to the double's rounding (cheb 32: ~3e-12 of max|F|, the D2 rows ~N^4; fd4: ~2e-14), for
    both engines and wall models; with gravity the hook declines (None: the caller uses residual)."""
    from problems.couette.model import CouetteProblem

    for method, N, rel in (("cheb", 32, 1e-11), ("fd4", 64, 1e-13)):
        for walls in ("noslip", "jj"):
            for engine in ("numpy", "numba"):
                pb = CouetteProblem(method, N, walls=walls, engine=engine)
                p = pb.params({"nu": 0.3, "e": 0.8, "H": 20.0})
                nu, u, T, P, _ = pb.unpack(pb.uniform_state(p))
                y = pb.grid.y
                x = pb.pack(nu * (1 + 0.2 * np.cos(np.pi * y)), u + 0.05 * np.sin(np.pi * y), T * (1 + 0.3 * y**2), P)
                r, rp = pb.residual(x, p), pb.precise_residual(x, p)
                assert rp.dtype == np.float64 and rp.shape == r.shape
                assert 0 < np.max(np.abs(r - rp)) <= rel * np.max(np.abs(r)), (method, walls, engine)
    # the closures are numpy-generic: every field of the evaluation is longdouble (Dufour flux, LS chi too)
    from problems.couette.extended_precision import LD

    for kw in ({"dufour": True}, {"chi": "ls"}):
        pb = CouetteProblem("cheb", 24, **kw)
        p = pb.params({"nu": 0.3, "e": 0.8, "H": 20.0})
        x = pb.uniform_state(p)
        x[pb.i_T] *= 1 + 0.3 * pb.grid.y**2
        r, rp = pb.residual(x, p), pb.precise_residual(x, p)
        assert 0 < np.max(np.abs(r - rp)) <= 1e-11 * np.max(np.abs(r))
        f = pb._extended._compute_fields(x.astype(LD), {k: LD(v) if isinstance(v, float) else v for k, v in p.items()})
        assert all(getattr(f, name).dtype == LD for name in f._fields if hasattr(getattr(f, name), "dtype"))
        assert f.c.f1.dtype == f.c.f2.dtype == f.c.chi.dtype == LD
    pg = CouetteProblem("cheb", 32, gravity=True)
    p = pg.params({"nu": 0.3, "e": 0.8, "H": 20.0})
    assert pg.precise_residual(pg.uniform_state(p), p) is None


def test_gpcf_nu05_band_reaches_h40_with_the_precise_residual(tmp_path):
    """nu = 0.5, e = 0.8, H_max = 40 (before the hook: EP "precision limit" at H = 38.9576, the two-grid
    error's floor 5.5e-5 on cheb 240, 3.6e-4 on 368): the n = 1 band reaches the bound on cheb 80, and
    contin verify finds every point within tol (worst 1.5e-5 at H = 40 against cheb 160)."""
    import json

    out = tmp_path / "p.h5"
    r = CliRunner().invoke(main, ["trace", "pitchfork", "-s", "nu=0.5", "-s", "e=0.8", "-s", "H_max=40", "-s", "modes=1",
                                  "--no-stability", "-q", "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    band = next(b for b in branches if b.id == "n1.1")
    assert band.status == "EP" and band.message == "reached bound H=40"
    assert band.grid[-1] == 80
    r = CliRunner().invoke(main, ["verify", str(out), "--branch", "n1.1", "--json"], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    (doc,) = json.loads(r.stdout)["branches"]
    assert not doc["exceeding"] and not doc["unchecked"]
    assert 1e-5 < doc["max_error"] < 2e-5
