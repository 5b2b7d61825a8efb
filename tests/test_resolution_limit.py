"""Slowly falling spectra in adaptive resolution (issue 14, the 2-D disks' scenes at max_grid).

- ``problems.discretization.chebyshev_tail_sum``: the extrapolated sum of the omitted Chebyshev
  coefficients, against closed forms (geometric: exact; algebraic k^-3: the sum to 10^6 terms).
- ``contin.adapt.Adaptor.resolution_limit``: on max_grid, an estimate that falls only like N^-p
  (p <= SLOW_ORDER) ends the branch EP "resolution limit" naming the grid tol needs and the last
  point's two-grid difference; a spectral estimate still ends MX (tests/test_adapt.py).  Non-granular
  problem: problems.demo.KinkedBratu (a step source, u'' jumps, |a_k| ~ k^-3), checked against a 2x
  finer solve (contin.verify).
- Disks (slow): Savage's dense band (savage-rheology) ends EP, its stored points checked against
  1.5x finer grids.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from contin.continuation import trace
from contin.options import AdaptOptions, ContinuationOptions, StepOptions
from contin.verify import verify_branch
from problems.demo import KinkedBratu
from problems.discretization import chebyshev_coefficients, chebyshev_tail, chebyshev_tail_sum


def test_tail_sum_geometric_is_exact():
    """|a_k| = 0.9^k: sum_{k > N} 0.9^k = 0.9^(N+1) / 0.1 (the fit is exact on a geometric envelope)."""
    k = np.arange(65.0)
    assert chebyshev_tail_sum(0.9**k)[0] == pytest.approx(0.9**65 / 0.1, rel=1e-12)


def test_tail_sum_algebraic_within_a_factor_where_the_last_coefficients_miss_it():
    """|a_k| = k^-3, N = 128: against the omitted sum (10^6 terms) the tail sum gives 0.44x,
    the last coefficient 0.017x (a 60x under-statement)."""
    n = 128
    k = np.arange(n + 1.0)
    a = np.r_[1.0, k[1:] ** -3.0]
    true = float(np.sum(np.arange(n + 1, 10**6, dtype=float) ** -3.0))
    assert 0.3 < chebyshev_tail_sum(a)[0] / true < 1.5
    assert a[-4:].max() / true < 0.03


def test_tail_sum_ignores_rounding_noise_and_flat_spectra():
    n = 64
    assert chebyshev_tail_sum(np.r_[1.0, np.full(n, 1e-17)])[0] == 0.0  # noise: below 1e-12 of the largest
    assert chebyshev_tail_sum(np.r_[1.0, np.full(n, 1e-3)])[0] == 0.0  # an envelope that does not fall
    rows = np.vstack([0.9 ** np.arange(n + 1.0), np.r_[1.0, np.full(n, 1e-17)]])
    assert chebyshev_tail_sum(rows)[1] == 0.0 and chebyshev_tail_sum(rows)[0] > 0  # rows independent


def kinked_run(tol: float, max_grid: int):
    pb = KinkedBratu("cheb", 8)
    o = ContinuationOptions(bounds={"lam": (0.02, 3.0)}, max_steps=400, step=StepOptions(ds=0.05, ds_max=0.2),
                            adapt=AdaptOptions(tol=tol, max_grid=max_grid, min_grid=8))
    return pb, trace(pb, pb.initial(), {"lam": 0.02}, "lam", o)


def test_kinked_bvp_spectrum_falls_algebraically():
    """KinkedBratu at lam = 0.1 on cheb 128: the coefficient envelope falls like k^-3 (u'' jumps at
    x = 0.3; the fitted log-log slope over the upper half is -3 +- 0.5), and the tail sum exceeds the
    last coefficients by more than 10x."""
    from contin.newton import newton

    pb = KinkedBratu("cheb", 128)
    res = newton(pb, pb.initial(), {"lam": 0.1})
    assert res.converged
    a = np.abs(chebyshev_coefficients(res.u))
    env = np.maximum.accumulate(a[::-1])[::-1]
    k = np.arange(32, 129)
    slope = np.polyfit(np.log(k), np.log(env[k]), 1)[0]
    assert -3.5 < slope < -2.5
    assert chebyshev_tail_sum(a)[0] > 10 * a[-4:].max()
    assert pb.error_estimate(res.u, {"lam": 0.1}) > 10 * chebyshev_tail(res.u)


def test_kinked_bvp_ends_ep_at_the_resolution_limit_with_a_true_two_grid_bound():
    """tol 1e-6, max_grid 64: EP "resolution limit" (not MX), the estimate falling like N^-p with
    1 < p < 3 (fitted over cheb 20..64), tol needing a grid above 64; the message's difference of the
    last point to its cheb 44 solve bounds that point's error against a cheb 128 solve (measured:
    1.3e-4 >= 6.3e-5), while its estimate under-states it (9.4e-7: the jump's position between the
    nodes is not in the spectrum -- why the message carries the two-grid difference)."""
    pb, b = kinked_run(1e-6, 64)
    assert b.status == "EP" and b.message.startswith("resolution limit at lam = ")
    m = re.search(r"falls only like N\^-([0-9.]+) .*tol needs N ~ ([0-9.e+]+) > max_grid 64", b.message)
    assert m, b.message
    assert 1.0 < float(m.group(1)) < 3.0 and float(m.group(2)) > 64
    diff = float(re.search(r"difference ([0-9.e+-]+) to its solve on grid 44", b.message).group(1))
    chk = verify_branch(pb, b, {}, factor=2, max_grid=1024, tol=1e-6, indices=[len(b) - 1])
    (last,) = chk.checked
    assert last.fine_grid == 128 and last.error <= diff
    assert last.estimate < 0.1 * last.error  # the reason for the two-grid number
    assert b.grid[-1] == 64


def test_spectral_estimate_on_max_grid_still_ends_mx():
    """Bratu (analytic) at tol 1e-10 on max_grid 24: its estimate falls far faster than N^-6, so the
    end is MX "under-resolved ... on the maximum grid 24" as before (also tests/test_adapt.py)."""
    from problems.demo import Bratu

    pb = Bratu("cheb", 8)
    o = ContinuationOptions(bounds={"lam": (0.02, 4.0)}, max_steps=400, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=1e-10, max_grid=24, min_grid=8, special_tol=1e-10))
    b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)  # round the fold onto the steep upper branch
    assert b.status == "MX" and "on the maximum grid 24" in b.message


@pytest.mark.slow
def test_savage_band_ends_ep_at_the_resolution_limit_within_two_tol(tmp_path):
    """savage-rheology (~60 s): the dense band's n = 1 branches end EP "resolution limit" on cheb 512
    (the contact pressure's kink at phi_c; docs/disks.md section 9), not MX; every stored point of
    band.n1.1 re-solved on a 1.5x finer grid is within 2 tol = 6e-5 (measured max 5.1e-5; before the
    tail sum 8.3e-3 at H = 24.27), and the scene exits 0."""
    from click.testing import CliRunner

    from contin import io
    from contin.cli import main
    from problems.disks.closures import DiskClosure
    from problems.disks.model import DiskCouetteProblem

    out = tmp_path / "savage.h5"
    r = CliRunner().invoke(main, ["trace", "savage-rheology", "-q", "-o", str(out)])
    assert r.exit_code == 0, r.output
    branches, _ = io.load(out)
    byid = {b.id: b for b in branches}
    for bid in ("band.n1.1", "band.n1.2"):
        assert byid[bid].status == "EP" and byid[bid].message.startswith("resolution limit at H = ")
        assert "on the maximum grid 512" in byid[bid].message
    b = byid["band.n1.1"]
    pb = DiskCouetteProblem("cheb", 16, closure=DiskClosure(G="gf", contact=True, normalization="esi"))
    chk = verify_branch(pb, b, {}, factor=1.5, max_grid=1024, tol=3e-5, indices=range(1, len(b)))
    assert not chk.unchecked
    assert chk.max_error <= 6e-5


def _reference_coefficients(values):
    """chebyshev_coefficients as first written (reversal and concatenation), for the layout test."""
    f = np.asarray(values, dtype=float)[..., ::-1]
    n = f.shape[-1] - 1
    a = np.fft.rfft(np.concatenate([f, f[..., -2:0:-1]], axis=-1), axis=-1).real[..., : n + 1] / n
    a[..., 0] *= 0.5
    a[..., -1] *= 0.5
    return a


@pytest.mark.parametrize("n", [1, 2, 7, 8, 16, 33, 64])
def test_chebyshev_coefficients_gather_is_the_concatenation_bit_for_bit(n):
    # the cached-index gather gives the same values in the same memory layout (C rows for C
    # input, F for F input): the tail estimate's row reductions round by layout
    rng = np.random.default_rng(n)
    for v in (rng.standard_normal(n + 1), rng.standard_normal((3, n + 1)),
              np.asfortranarray(rng.standard_normal((3, n + 1)))):
        got, ref = chebyshev_coefficients(v), _reference_coefficients(v)
        assert got.tobytes() == ref.tobytes() and got.strides == ref.strides


@pytest.mark.parametrize("method,n", [("cheb", 8), ("cheb", 16), ("cheb", 48), ("fd4", 64)])
def test_fast_error_and_rounding_estimates_equal_the_resolution_object(method, n):
    # estimated_error / estimated_rounding (the error_estimate / rounding_error hooks) are
    # resolution(...).error / .rounding bit for bit, on resolved, layered and kinked states
    from problems.couette.model import CouetteProblem
    from problems.couette.resolution import estimated_error, estimated_rounding, resolution

    pb = CouetteProblem(method, n)
    p = pb.params({"nu": 0.3, "e": 0.8, "H": 10.0})
    y = pb.grid.y
    for d in (0.0 * y, 0.01 * np.cos(np.pi * y), 1e-3 * np.tanh(y / 0.1), 1e-3 * np.abs(y)):
        x = pb.uniform_state(p)
        nu, u, T, _, _ = pb.unpack(x)
        nu += d
        u += d
        T += 0.5 * d
        r = resolution(pb, x, p)
        assert estimated_error(pb, x, p) == r.error and pb.error_estimate(x, p) == r.error
        assert estimated_rounding(pb, x, p) == r.rounding and pb.rounding_error(x, p) == r.rounding
        assert chebyshev_tail_sum(np.abs(r.coefficients))[0] <= r.tails[r.field]



def test_a_tol_far_below_rounding_ends_at_the_resolution_limit_not_in_an_overflow():
    """`contin trace bratu --tol 1e-300`: the grid the fitted N^-p line needs for tol overflowed
    exp() ('arithmetic failure (OverflowError: math range error)', exit 1, the run lost; qa18).  On
    max_grid the estimate sits at rounding level and barely falls: the branch ends EP at the
    resolution limit, the grid it needs named as infinite, every stored point within rounding."""
    from problems.demo import Bratu

    pb = Bratu("cheb", 32)
    o = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=60, step=StepOptions(ds=0.05, ds_max=0.25),
                            adapt=AdaptOptions(tol=1e-300, max_grid=512))
    b = trace(pb, pb.initial(), {"lam": 0.0}, "lam", o)
    assert b.status == "EP" and b.message.startswith("resolution limit at lam = "), b.message
    assert "tol needs N ~ inf > max_grid 512" in b.message
