"""Per-point work the core and gPCF's hooks skip (issue 15): the same numbers, fewer constructions.

- ``ExtendedSystem.state_jacobian(x, dense_ok=True)``: J from the problem's ``dense_jacobian``
  hook (memoized), the same entries as the sparse J, for the symmetry determinant of every point
  (``Antisymmetric.reduced`` gathers densely anyway: :meth:`Antisymmetric.reduces_densely`).
- gPCF's compiled kernels share one D1/D2 stencil per grid between problem instances.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from contin.extended import ExtendedSystem
from contin.linalg import factorize
from contin.testfunctions import DENSE_REDUCTION_LIMIT, Antisymmetric, _antisymmetric_basis


class ReflectedCubic:
    """F(u) = A u + u^3 - lam b, A = tridiag(1, -2, 1) (Dirichlet), b even under the reflection
    u_i -> u_{n-1-i}: a non-granular problem with a sparse jacobian and a dense_jacobian hook."""

    parameter_names = ("lam",)

    def __init__(self, n: int = 12) -> None:
        self.n = n
        self.a = sp.diags([np.ones(n - 1), -2.0 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csr")
        self.b = 1.0 + np.cos(np.linspace(0.0, 2.0 * np.pi, n))
        self.dense_calls = 0

    def residual(self, u, p):
        return self.a @ u + u**3 - p["lam"] * self.b

    def jacobian(self, u, p):
        return sp.csr_matrix(self.a + sp.diags(3.0 * u**2))

    def dense_jacobian(self, u, p):
        self.dense_calls += 1
        return np.asfortranarray(self.a.toarray() + np.diag(3.0 * u**2))

    def dresidual_dp(self, u, p, name):
        return -self.b

    def symmetry_matrix(self):
        return sp.csr_matrix((np.ones(self.n), (np.arange(self.n)[::-1], np.arange(self.n))), shape=(self.n, self.n))


def test_dense_state_jacobian_is_the_hooks_memoized_and_equals_the_sparse_one():
    pb = ReflectedCubic()
    system = ExtendedSystem(pb, {"lam": 0.3}, "lam", n=pb.n)
    rng = np.random.default_rng(1)
    x = np.r_[rng.standard_normal(pb.n), 0.3]
    # before the first (dense-deciding) Jacobian the sparse J is returned
    assert sp.issparse(system.state_jacobian(x, dense_ok=True))
    system.jacobian(x)  # decides dense factorization (n = 12)
    calls = pb.dense_calls
    jd = system.state_jacobian(x, dense_ok=True)
    assert isinstance(jd, np.ndarray) and pb.dense_calls == calls + 1
    assert system.state_jacobian(x, dense_ok=True) is jd and pb.dense_calls == calls + 1  # memo
    js = system.state_jacobian(x)
    assert sp.issparse(js)
    np.testing.assert_array_equal(jd, js.toarray())
    # the symmetry determinant: the same sign and log from either J
    anti = Antisymmetric.from_problem(pb, pb.n)
    assert anti.reduces_densely(pb.n)
    assert anti.det(jd) == anti.det(js)
    # without the hook dense_ok changes nothing
    plain = ExtendedSystem(type("NoHook", (), {k: getattr(ReflectedCubic, k) for k in
                                                ("parameter_names", "residual", "jacobian", "dresidual_dp")})(),
                           {"lam": 0.3}, "lam", n=pb.n)
    plain.problem.__dict__.update(a=pb.a, b=pb.b, n=pb.n)
    plain.jacobian(x)
    assert sp.issparse(plain.state_jacobian(x, dense_ok=True))


def test_reduces_densely_only_where_the_sparse_reduction_gathers_densely():
    for n, expect in ((10, True), (DENSE_REDUCTION_LIMIT, True), (DENSE_REDUCTION_LIMIT + 2, False)):
        s = sp.csc_matrix((np.ones(n), (np.arange(n)[::-1], np.arange(n))), shape=(n, n))
        assert Antisymmetric(s, _antisymmetric_basis(s)).reduces_densely(n) is expect
    # a J holding exact negative zeros: its CSR copy drops them, the determinant is the same
    n = 9
    s = sp.csc_matrix((np.ones(n), (np.arange(n)[::-1], np.arange(n))), shape=(n, n))
    anti = Antisymmetric(s, _antisymmetric_basis(s))
    jac = np.random.default_rng(2).standard_normal((n, n))
    jac[jac < -0.5] = -0.0
    assert anti.det(jac) == anti.det(sp.csr_matrix(jac))
    assert anti.det(jac) == factorize(anti.reduced(sp.csr_matrix(jac))).det_sign_log()


def test_gpcf_dense_symmetry_jacobian_and_shared_compiled_stencil():
    from problems.couette import compiled
    from problems.couette.model import CouetteProblem

    if not compiled.available():
        pytest.skip("numba is not installed")
    a, b = CouetteProblem("cheb", 14, engine="numba"), CouetteProblem("cheb", 14, engine="numba")
    for name in ("ptr", "cols", "w1s", "w2s"):  # one stencil per grid, equal to a fresh build
        assert getattr(a._compiled, name) is getattr(b._compiled, name)
    for got, fresh in zip((a._compiled.ptr, a._compiled.cols, a._compiled.w1s, a._compiled.w2s),
                          compiled._stencil(a.grid, a.n)):
        np.testing.assert_array_equal(got, fresh)
    p = a.params({"nu": 0.3, "e": 0.8, "H": 20.0})
    system = ExtendedSystem(a, p, "H", n=a.size)
    x = system.pack(a.uniform_state(p), 20.0)
    x[:-1] += 1e-3 * np.sin(np.arange(a.size))  # not symmetric: a generic J
    system.jacobian(x)
    jd, js = system.state_jacobian(x, dense_ok=True), system.state_jacobian(x)
    assert isinstance(jd, np.ndarray) and sp.issparse(js)
    np.testing.assert_array_equal(jd, js.toarray())
    anti = Antisymmetric.from_problem(a, a.size)
    assert anti.reduces_densely(a.size)
    assert anti.det(jd) == anti.det(js)
