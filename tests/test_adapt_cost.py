"""Cost of adaptive resolution (issue 14, section 1): the work an adaptive run does beyond a fixed
grid's, counted (solves, grids visited, locations, estimates), never timed.

References: the Allen-Cahn trivial branch u = 0 on [0, pi] (problems.demo.AllenCahn) is exact on
every grid and has its first BP at lam = 1 (kernel sin x, the first eigenvalue of -u''); the
Bratu fold lam* (Gel'fand 1963, problems.demo.BRATU_FOLD); gPCF uniform shear, exact on every
Chebyshev grid from cheb 8 on, and its H_1^c = pi psi (problems.couette.pitchfork).
"""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest

import contin.continuation as continuation
import contin.newton
from contin.adapt import AdaptOptions, near_kernel, null_vector
from contin.continuation import trace
from contin.extended import JACOBIAN_MEMO, ExtendedSystem
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from problems.demo import BRATU_FOLD, AllenCahn, Bratu


@pytest.fixture
def counts(monkeypatch):
    """Counters of the start grid's Newton solves (per grid size), the tracer's locations and the
    problem's error estimates (per (grid, state bytes))."""
    seen: collections.Counter = collections.Counter()
    solve = contin.newton.newton

    def newton(problem, *args, **kw):
        seen[("newton", int(problem.grid_size))] += 1
        return solve(problem, *args, **kw)

    locate = continuation.locate_zero

    def located(*args, **kw):
        seen["locate"] += 1
        return locate(*args, **kw)

    monkeypatch.setattr(contin.newton, "newton", newton)  # start_grid imports it when called
    monkeypatch.setattr(continuation, "locate_zero", located)
    return seen


def count_estimates(monkeypatch, cls):
    estimates: collections.Counter = collections.Counter()
    estimate = cls.error_estimate

    def counted(self, u, p):
        estimates[(int(self.grid_size), np.asarray(u, dtype=float).tobytes(), tuple(sorted(p.items())))] += 1
        return estimate(self, u, p)

    monkeypatch.setattr(cls, "error_estimate", counted)
    return estimates


def allen_cahn_run(start: int, min_grid: int):
    pb = AllenCahn("cheb", start)
    o = ContinuationOptions(bounds={"lam": (0.45, 1.6)}, step=StepOptions(ds=0.2, ds_max=0.3),
                            detection=DetectionOptions(locate_tol=1e-13), adapt=AdaptOptions(tol=1e-8, min_grid=min_grid))
    return trace(pb, pb.initial(), {"lam": 0.45}, "lam", o)


def test_exact_start_state_one_solve_on_the_coarse_grid(counts, monkeypatch):
    """u = 0 is exact on every grid: the start grid goes 64 -> min_grid (8) with one solve there
    and none on the grids in between; each state is estimated once; the BP's bracket refines
    8 -> 16 in one jump (its kernel sin x: estimate 1.2e-3 on cheb 8; growth alone went 8 -> 12,
    located it there at 9e-8 and again on 20) and the BP is located once, at lam = 1 to 1e-13."""
    estimates = count_estimates(monkeypatch, AllenCahn)
    b = allen_cahn_run(64, 8)
    assert {k: v for k, v in counts.items() if k != "locate"} == {("newton", 64): 1, ("newton", 8): 1}
    assert b.audit[0].startswith("start grid coarsened 64 -> 8")
    assert max(estimates.values()) == 1  # no state estimated twice
    (bp,) = b.branch_points
    assert counts["locate"] == 1 and bp.grid == 16
    assert abs(bp.params["lam"] - 1.0) <= 1e-13
    assert sorted(set(b.grid.tolist())) == [8, 16]
    # one jump (AllenCahn.suggest_vector_grid), not growth 8 -> 12 -> 20 with a location on 12
    assert [a.split(" at ")[0] for a in b.audit if a.startswith("grid ")] == ["grid refined 8 -> 16"]


def test_start_grid_skips_grids_that_cannot_carry_the_state(counts):
    """gPCF uniform shear from cheb 64 with min_grid 4: cheb 4 cannot carry the linear velocity
    profile with four spare coefficients (the resampled state's estimate is 1), so it is not solved
    on; the run starts on cheb 8 after two solves (64 and 8), refines 8 -> 16 before the BP and
    locates H_1^c once, to 1e-13 of pi psi."""
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    exact = pf.analytic_critical_gaps(0.3, 0.8, 1)[0]
    pb = CouetteProblem("cheb", 64)
    p = pb.params({"nu": 0.3, "e": 0.8})
    o = ContinuationOptions(bounds={"H": (0.8 * exact, 1.2 * exact)}, step=StepOptions(ds=0.1 * exact, ds_max=0.3 * exact),
                            detection=DetectionOptions(locate_tol=1e-13), adapt=AdaptOptions(tol=1e-6, min_grid=4))
    b = pf.trace_base(pb, p, 0.8 * exact, o)
    assert {k: v for k, v in counts.items() if k != "locate"} == {("newton", 64): 1, ("newton", 8): 1}
    (bp,) = b.branch_points
    assert counts["locate"] == 1 and bp.grid == 16
    assert abs(bp.params["H"] - exact) / exact <= 1e-13


def test_special_point_refinement_jumps_to_the_kernels_grid(counts):
    """Bratu from cheb 32, tol 1e-4: the fold's bracket on cheb 12 shows its tangent's tail at
    1.2e-4 (> special_tol 1e-10); the grid goes 12 -> 28 in one jump (the tangent's coefficient
    envelope, Bratu.suggest_vector_grid) and the fold is located once (growth alone went
    12 -> 20, located the fold there at 2.2e-8 and again on 32); lam* to 1e-10."""
    pb = Bratu("cheb", 32)
    o = ContinuationOptions(bounds={"lam": (0.02, 4.0)}, max_steps=400, step=StepOptions(ds=0.1, ds_max=0.5),
                            adapt=AdaptOptions(tol=1e-4, min_grid=8))
    b = trace(pb, pb.initial(), {"lam": 0.1}, "lam", o)
    (fold,) = b.fold_points
    jumps = [a for a in b.audit if "LP bracketed, kernel under-resolved" in a]
    assert len(jumps) == 1 and "12 -> 28" in jumps[0]
    assert not any("located LP under-resolved" in a for a in b.audit)
    assert counts["locate"] == 1 and fold.grid == 28
    assert pb.with_grid(28).vector_error(fold.tangent[:-1]) <= AdaptOptions().special_tol
    assert abs(fold.params["lam"] - BRATU_FOLD) / BRATU_FOLD <= 1e-10


def test_suggest_vector_grid_of_the_demo_problems():
    """Bratu.suggest_vector_grid: for sin(pi x) sampled on cheb 12 (tail ~1e-9) the envelope's
    decay rate gives the grid where the tail meets tol / 10 (at least 1.5 N); a resolved vector
    gets 1.5 N; fd2 follows N^-2 of the defect estimate."""
    pb = Bratu("cheb", 12)
    x = (pb.grid.y + 0.5)  # Bratu lives on [0, 1]
    v = np.sin(np.pi * x)
    err = pb.vector_error(v)
    assert 1e-11 < err < 1e-6
    n_new = pb.suggest_vector_grid(v, 1e-12)
    assert 18 <= n_new <= 40
    assert pb.with_grid(int(math.ceil(n_new))).vector_error(np.sin(np.pi * (pb.with_grid(int(math.ceil(n_new))).grid.y + 0.5))) <= 1e-12
    assert pb.suggest_vector_grid(v, 1.0) == 18  # resolved: 1.5 N
    fd = Bratu("fd2", 16)
    vf = np.sin(np.pi * (fd.grid.y + 0.5))
    e16 = fd.vector_error(vf)
    want = fd.suggest_vector_grid(vf, e16 / 40)  # target e16 / 400: N^-2 -> 20x N
    assert want == pytest.approx(min(16 * 400 ** 0.5, 8 * 16), rel=1e-12)


def test_vector_grid_jump_is_capped():
    """contin.adapt.vector_grid: the problem's suggestion rounded up to ``multiple`` and held to
    at most growth^2 N (an extrapolated decay rate can ask for far too much) and max_grid."""
    from contin.adapt import vector_grid

    class Asks:
        grid_size = 12

        def __init__(self, want):
            self.want = want

        def suggest_vector_grid(self, v, tol):
            return self.want

    opts = AdaptOptions(growth=1.5, multiple=4, max_grid=64)
    v = np.ones(3)
    assert vector_grid(Asks(25.0), v, 1e-10, opts) == 28
    assert vector_grid(Asks(1000.0), v, 1e-10, opts) == 28  # 1.5^2 * 12 = 27 -> 28
    assert vector_grid(Asks(1000.0), v, 1e-10, AdaptOptions(growth=3.0, multiple=4, max_grid=64)) == 64
    assert vector_grid(Asks(float("nan")), v, 1e-10, opts) is None
    assert vector_grid(Bratu("cheb", 12), None, 1e-10, opts) is None


def test_near_kernel_is_inverse_iteration_from_the_border():
    """near_kernel(J) with one LU: the unit vector of J^-4 b (b the border of null_vector) up to
    sign, i.e. the bordered null vector (J^-1 b normalised, for a regular J) followed by three
    inverse iterations; the smallest singular direction of a nearly singular J to 1e-12, and an
    exactly singular J falls back to the bordered null vector."""
    from contin.normalform import borders

    rng = np.random.default_rng(3)
    n = 30
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = np.linspace(1.0, 2.0, n)
    s[0] = 1e-7
    jac = q @ np.diag(s) @ q.T
    v = near_kernel(jac)
    assert abs(abs(v @ q[:, 0]) - 1.0) <= 1e-12
    b = borders(n)[0]
    w = np.linalg.solve(jac, np.linalg.solve(jac, np.linalg.solve(jac, np.linalg.solve(jac, b))))
    assert abs(abs(v @ (w / np.linalg.norm(w))) - 1.0) <= 1e-12
    phi = null_vector(jac)  # bordered: J^-1 b direction for a regular J
    w1 = np.linalg.solve(jac, b)
    assert abs(abs(phi @ (w1 / np.linalg.norm(w1))) - 1.0) <= 1e-10
    sing = jac.copy()
    sing[:, 0] = 0.0  # J e_0 = 0 exactly: a zero pivot, the bordered solve takes over
    out = near_kernel(sing)
    assert abs(abs(out[0]) - 1.0) <= 1e-12


def test_state_jacobian_memo():
    """ExtendedSystem.state_jacobian returns the same J for the same x (no second assembly) and
    keeps only the last JACOBIAN_MEMO of them; a given parameter set is never memoised."""
    pb = Bratu("cheb", 12)
    sys_ = ExtendedSystem(pb, {"lam": 1.0}, "lam")
    calls = []
    jacobian = pb.jacobian

    def counted(u, p):
        calls.append(1)
        return jacobian(u, p)

    pb.jacobian = counted
    xs = [np.concatenate([0.1 * k * np.sin(np.pi * (pb.grid.y + 0.5)), [1.0]]) for k in range(JACOBIAN_MEMO + 1)]
    first = sys_.state_jacobian(xs[0])
    assert sys_.state_jacobian(xs[0]) is first and len(calls) == 1
    for x in xs[1:]:
        sys_.state_jacobian(x)
    assert len(calls) == JACOBIAN_MEMO + 1
    sys_.state_jacobian(xs[0])  # evicted by the later ones
    assert len(calls) == JACOBIAN_MEMO + 2
    sys_.state_jacobian(xs[-1], {"lam": 1.0})
    assert len(calls) == JACOBIAN_MEMO + 3
    ref = jacobian(xs[1][:-1], {"lam": 1.0})
    got = sys_.state_jacobian(xs[1])
    assert abs(got - ref).max() == 0.0
