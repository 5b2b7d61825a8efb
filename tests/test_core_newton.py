"""Newton: quadratic convergence, failures reported not raised, admissibility backtracking."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from contin.continuation import newton, trace
from contin.options import ContinuationOptions, NewtonOptions, StepOptions
from problems.demo import AllenCahn, Bratu, ImperfectPitchfork


def test_newton_converges_quadratically_on_bratu():
    pb = Bratu("cheb", 32)
    res = newton(pb, pb.initial(), {"lam": 3.0}, NewtonOptions(tol=1e-11, step_tol=1e-10))
    assert res.converged and res.message == "converged"
    r = np.array(res.residual_history)
    assert r[-1] <= 1e-11
    # In the asymptotic phase r_{k+1} ~ C r_k^2: the ratio of logs tends to 2.
    k = [i for i in range(1, len(r) - 1) if 1e-12 < r[i + 1] and r[i] < 1e-1]
    assert k, r
    orders = [math.log(r[i + 1]) / math.log(r[i]) for i in k]
    assert max(orders) > 1.8, (r, orders)
    assert all(r[i + 1] <= 10 * r[i] ** 2 for i in k), r


def test_newton_failure_is_reported_not_raised():
    pb = Bratu("cheb", 16)
    # no solution above the fold lam* = 3.5138
    res = newton(pb, pb.initial(), {"lam": 5.0}, NewtonOptions(max_iterations=8))
    assert not res.converged
    assert res.message and res.iterations >= 1
    # singular Jacobian: Allen-Cahn at u = 0 exactly on the eigenvalue lam = 1 ... of the
    # scalar pitchfork at its BP
    res = newton(ImperfectPitchfork(), np.array([1e-3]), {"lam": 0.0, "alpha": 0.0, "beta": 0.0},
                 NewtonOptions(max_iterations=3))
    assert not res.converged and "no convergence" in res.message


class AtanProblem:
    """F(x) = atan(x - 1), root x = 1; plain Newton from x = 3 overshoots to x < 0 and diverges."""

    parameter_names = ("a",)

    def residual(self, u, p):
        return np.arctan(u - 1.0)

    def jacobian(self, u, p):
        return sp.csr_matrix(np.array([[1.0 / (1.0 + (u[0] - 1.0) ** 2)]]))

    def dresidual_dp(self, u, p, name):
        return np.zeros(1)


class PositiveAtan(AtanProblem):
    def admissible(self, u, p):
        return None if u[0] > 0 else "x must be positive"


def test_admissibility_backtracking_rescues_newton():
    plain = newton(AtanProblem(), np.array([3.0]), {"a": 0.0})
    assert not plain.converged
    safe = newton(PositiveAtan(), np.array([3.0]), {"a": 0.0})
    assert safe.converged
    assert safe.u[0] == pytest.approx(1.0, abs=1e-12)
    bad = newton(PositiveAtan(), np.array([-1.0]), {"a": 0.0})
    assert not bad.converged and "inadmissible" in bad.message


def test_forced_newton_failure_ends_trace_with_mx():
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(newton=NewtonOptions(max_iterations=1, tol=1e-14, step_tol=1e-14),
                               step=StepOptions(ds=0.1, ds_min=1e-3))
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)
    assert br.status == "MX" and not br.success
    assert "ds_min" in br.message and "no convergence" in br.message
    assert br.special_points[-1].type == "MX" and br.special_points[-1].note == br.message
    assert len(br) == 1  # only the start point


def test_unconverged_start_gives_mx():
    pb = Bratu("cheb", 16)
    br = trace(pb, pb.initial(), {"lam": 5.0}, "lam")
    assert br.status == "MX" and "start point" in br.message and len(br) == 0


class BratuCapped(Bratu):
    """Bratu with an artificial physical domain u(1/2) < 2 (as a granular model caps density)."""

    def admissible(self, u, p):
        return None if self.order_parameter(u, p) < 2.0 else "u(1/2) must stay below 2"


def test_trace_stops_with_mx_at_the_admissibility_boundary():
    pb = BratuCapped("cheb", 16)
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", ContinuationOptions(step=StepOptions(ds=0.1, ds_min=1e-6)))
    assert br.status == "MX" and "u(1/2) must stay below 2" in br.message
    phi = br.order_parameter
    assert np.all(phi < 2.0) and phi.max() > 1.999
    assert len(br.fold_points) == 1  # the fold (phi = 1.19) is inside the domain


def test_bad_input_raises_value_error():
    pb = Bratu("cheb", 16)
    with pytest.raises(ValueError, match="unknown continuation parameter"):
        trace(pb, pb.initial(), {"lam": 0.0}, "mu")
    with pytest.raises(ValueError, match="outside its bounds"):
        trace(pb, pb.initial(), {"lam": 5.0}, "lam", ContinuationOptions(bounds={"lam": (0.0, 4.0)}))
    with pytest.raises(ValueError, match="entries"):
        trace(pb, np.zeros(3), {"lam": 0.0}, "lam")
    with pytest.raises(ValueError, match="unknown parameter"):
        trace(AllenCahn("cheb", 8), np.zeros(9), {"lam": 0.0, "mu": 1.0}, "lam")


def test_corrector_give_up_hook_ends_an_unconverged_correction():
    from contin.corrector import correct
    from contin.extended import ExtendedSystem

    pb = Bratu("cheb", 16)
    system = ExtendedSystem(pb, {"lam": 1.0}, "lam")
    x0 = np.concatenate([pb.initial(), [1.0]])
    e_p = np.zeros(x0.size)
    e_p[-1] = 1.0
    full = correct(system, x0, e_p, NewtonOptions())
    assert full.converged and full.iterations >= 3
    seen = []

    def give_up(x, dx):
        seen.append(float(np.max(np.abs(dx))))
        return "enough" if len(seen) == 2 else None

    stopped = correct(system, x0, e_p, NewtonOptions(), give_up=give_up)
    assert not stopped.converged and stopped.message == "enough" and stopped.iterations == 2
    assert stopped.factorization is not None and len(stopped.residual_history) == 3


class BratuDenseOut(Bratu):
    """Bratu with a dense_jacobian hook that takes ``out`` (contin.problem): it records the
    arrays it was handed and overwrites them."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.handed = []

    def dense_jacobian(self, u, p, out=None):
        jac = self.jacobian(u, p).toarray()
        self.handed.append(out)
        if out is None:
            return np.asfortranarray(jac)
        out[...] = jac
        return out


def test_corrector_reuses_one_jacobian_and_one_bordered_buffer_with_the_same_result():
    # the corrector's Newton loop hands the previous iteration's J to a dense_jacobian hook
    # that takes out= (ExtendedSystem.jacobian scratch=True) and factorizes each bordered
    # matrix in the previous one's buffer: the correction must be bitwise the one of a
    # problem without the out= hook, whose every J and bordered matrix is a new array
    from contin.corrector import correct
    from contin.extended import ExtendedSystem

    pb, plain = BratuDenseOut("cheb", 24), Bratu("cheb", 24)
    plain.dense_jacobian = lambda u, p: np.asfortranarray(plain.jacobian(u, p).toarray())
    x0 = np.concatenate([pb.initial(), [1.0]])
    e_p = np.zeros(x0.size)
    e_p[-1] = 1.0
    system = ExtendedSystem(pb, {"lam": 1.0}, "lam")
    reused = correct(system, x0, e_p, NewtonOptions())
    fresh = correct(ExtendedSystem(plain, {"lam": 1.0}, "lam"), x0, e_p, NewtonOptions())
    assert reused.converged and reused.iterations >= 3
    assert reused.iterations == fresh.iterations and np.array_equal(reused.x, fresh.x)
    assert reused.residual_history == fresh.residual_history
    assert np.array_equal(reused.factorization.lu, fresh.factorization.lu)
    assert reused.factorization.det_sign_log() == fresh.factorization.det_sign_log()
    # one J array reused: the first call had none to give, every later one the first's array
    outs = pb.handed[-reused.iterations:]
    assert outs[1] is not None and all(o is outs[1] for o in outs[1:])
    # the next correction on the same system goes on with that J array (the system keeps it);
    # its factorization is a new array (the caller may still hold the previous one)
    again = correct(system, x0, e_p, NewtonOptions())
    assert all(o is outs[1] for o in pb.handed[-again.iterations:])
    assert again.factorization.lu is not reused.factorization.lu
    assert np.array_equal(again.x, reused.x) and np.array_equal(reused.factorization.lu, fresh.factorization.lu)


def test_max_norm_and_converged_equal_their_reference_formulas():
    # max_norm goes through argmax, converged() skips ||x|| when the step alone decides: the
    # same values and decisions as the plain formulas, NaN, inf, signed zeros and edge
    # tolerances included
    from contin.newton import converged, max_norm, rounding_floor

    rng = np.random.default_rng(3)
    vectors = [np.zeros(0), np.array([-0.0, 0.0]), np.array([np.nan, 1.0]), np.array([1.0, -np.inf, np.nan]),
               np.array([-3.0, 2.0, -3.0])] + [rng.standard_normal(int(n)) * 10.0 ** rng.integers(-12, 12) for n in
                                                 rng.integers(1, 300, 30)]
    for v in vectors:
        ref = float(np.max(np.abs(v))) if v.size else 0.0
        got = max_norm(v)
        assert (math.isnan(ref) and math.isnan(got)) or got == ref

    def reference(options, r, lam, dx, x, jac, x_jac):
        return (lam * max_norm(dx) <= options.step_tol * max(1.0, max_norm(x))
                and (r <= options.tol or r <= rounding_floor(jac, x_jac)))

    jac = rng.standard_normal((6, 6))
    for step_tol in (1e-8, 0.0, -1e-8, 1e-3):
        # the predicate's edge tolerances (NewtonOptions itself refuses step_tol <= 0 since qa15)
        options = SimpleNamespace(tol=1e-10, step_tol=step_tol)
        for _ in range(200):
            scale = 10.0 ** rng.integers(-14, 4)
            dx = rng.standard_normal(6) * scale
            x = rng.standard_normal(6) * 10.0 ** rng.integers(-3, 6)
            if rng.random() < 0.1:
                x[rng.integers(6)] = np.nan
            if rng.random() < 0.1:
                dx[rng.integers(6)] = np.nan
            r = float(10.0 ** rng.uniform(-17, -6))
            lam = float(rng.choice([1.0, 0.5, 0.0]))
            assert converged(options, r, lam, dx, x, jac, x) == reference(options, r, lam, dx, x, jac, x)


def test_corrector_equals_the_plain_newton_loop_bitwise():
    # contin.corrector's loop (negated right-hand side written in place, ndarray.dot, argmax
    # norms, the convergence shortcut) against the plain textbook form it replaced, on a
    # dense-Jacobian problem and a sparse one: the same iterates, residuals and LU bit for bit
    from contin.corrector import correct
    from contin.extended import ExtendedSystem
    from contin.linalg import factorize_bordered

    def plain(system, x_pred, row, options):
        x = np.array(x_pred, dtype=float)
        f = system.residual(x)
        history = [float(np.max(np.abs(f)))]
        for it in range(1, options.max_iterations + 1):
            jac, fp = system.jacobian(x)
            fact = factorize_bordered(jac, fp, row)
            rhs = np.concatenate([f, [row @ (x - x_pred)]])
            dx = fact.solve(-rhs)
            x_old, x = x, x + dx
            assert system.admissible(x) is None
            f = system.residual(x)
            history.append(float(np.max(np.abs(f))))
            step_ok = np.max(np.abs(dx)) <= options.step_tol * max(1.0, float(np.max(np.abs(x))))
            if step_ok and (history[-1] <= options.tol or history[-1] <= rounding(jac, x_old)):
                return x, it, history, fact
        raise AssertionError("no convergence")

    from contin.newton import rounding_floor as rounding

    # dense LU (cheb 24), banded LU with the border eliminated (fd2 200), a symmetric-breaking
    # Allen-Cahn state (cheb 32)
    for pb in (Bratu("cheb", 24), Bratu("fd2", 200), AllenCahn("cheb", 32)):
        params = {"lam": 1.0} if isinstance(pb, Bratu) else {"lam": 3.0}
        system = ExtendedSystem(pb, params, "lam")
        x0 = np.concatenate([pb.initial(), [params["lam"]]])
        t = np.zeros(x0.size)
        t[-1] = 1.0
        row = system.row(t)
        x_pred = x0 + 1e-2 * np.sin(np.arange(x0.size))
        c = correct(system, x_pred, row, NewtonOptions())
        x, it, history, fact = plain(ExtendedSystem(pb, params, "lam"), x_pred, row, NewtonOptions())
        assert c.converged and c.iterations == it >= 2
        assert np.array_equal(c.x, x) and c.residual_history == history
        b = np.cos(np.arange(x0.size))
        assert np.array_equal(c.factorization.solve(b), fact.solve(b))
        assert c.factorization.det_sign_log() == fact.det_sign_log()
