"""Generic linear stability (contin.stability): eigen solvers, stability pass, audit."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from contin.branch import Branch, SpecialPoint
from contin.stability import (
    count_unstable,
    eigenpairs,
    eigenvalues,
    stability_of_state,
    stability_pass,
    audit,
)


# ------------------------------------------------------------------ eigen solvers

def test_dense_generalized_2x2():
    # A x = w B x with B = diag(1, 2): w solves det(A - w B) = 0 -> 2w^2 - (2a + d)w + ad - bc = 0
    a, b, c, d = 1.0, 2.0, -3.0, -4.0
    w = eigenvalues(np.array([[a, b], [c, d]]), np.diag([1.0, 2.0]))
    ref = np.roots([2.0, -(2 * a + d), a * d - b * c])
    ref = ref[np.lexsort((-ref.imag, -ref.real))]
    assert w.shape == (2,)
    np.testing.assert_allclose(w, ref, atol=1e-14)
    assert w[0].real >= w[1].real and w[0].imag > 0  # pair: positive imaginary part first


def test_singular_b_discards_infinite_eigenvalues():
    # third row is the constraint x3 = -x1 (zero row of B); reduced system [[-1, 1], [-1, -2]]
    A = np.array([[-1.0, 1.0, 0.0], [0.0, -2.0, 1.0], [1.0, 0.0, 1.0]])
    B = np.diag([1.0, 1.0, 0.0])
    w, v = eigenpairs(A, B)
    assert w.size == 2
    np.testing.assert_allclose(w, [-1.5 + np.sqrt(3) / 2 * 1j, -1.5 - np.sqrt(3) / 2 * 1j], atol=1e-14)
    np.testing.assert_allclose(A @ v - B @ v * w, 0.0, atol=1e-13)


def _dirichlet_laplacian(n: int):
    """d2/dy2 on [0, 1] (FD, n nodes) with boundary rows x = 0 (zero rows of B)."""
    h = 1.0 / (n - 1)
    A = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="lil") / h**2
    for r in (0, n - 1):
        A[r, :] = 0.0
        A[r, r] = 1.0
    b = np.ones(n)
    b[[0, n - 1]] = 0.0
    exact = -(4 / h**2) * np.sin(np.arange(1, n - 1) * np.pi * h / 2) ** 2
    return sp.csr_matrix(A), sp.diags(b, format="csr"), np.sort(exact)[::-1]


def test_sparse_shift_invert_matches_exact_spectrum():
    A, B, exact = _dirichlet_laplacian(900)
    w = eigenvalues(A, B, k=6, sigma=0.0, dense_max=600)  # sparse path (n > dense_max)
    np.testing.assert_allclose(w.real, exact[:6], rtol=1e-10)
    assert np.max(np.abs(w.imag)) < 1e-8


def test_dense_path_on_laplacian_counts_finite_eigenvalues():
    A, B, exact = _dirichlet_laplacian(60)
    w = eigenvalues(A, B)
    assert w.size == 58  # two boundary rows -> two infinite eigenvalues removed
    np.testing.assert_allclose(w.real, exact, rtol=1e-9)


def test_eigen_input_errors():
    with pytest.raises(ValueError, match="square"):
        eigenvalues(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="NaN"):
        eigenvalues(np.array([[np.nan]]), np.eye(1))


def test_count_unstable_tolerance_semantics():
    w = np.array([1e-12, -1e-12, 1e-6, 1e-7 + 1e3j, 2e-5 + 1e3j, -1.0])
    # 1e-12 is noise (< tol), 1e-6 counts, 1e-7 is below tol*|w| = 1e-5 for |w| = 1e3, 2e-5 is above
    assert count_unstable(w, 1e-8) == 2


# ------------------------------------------------------------------ small problems

class Pitchfork:
    """du/dt = lam u - u^3 (supercritical pitchfork at lam = 0)."""

    parameter_names = ("lam",)

    def residual(self, u, p):
        return p["lam"] * u - u**3

    def jacobian(self, u, p):
        return sp.csr_matrix(np.atleast_2d(p["lam"] - 3 * u[0] ** 2))

    def dresidual_dp(self, u, p, name):
        return u.copy()


class Fold(Pitchfork):
    """du/dt = lam - u^2 (saddle node at lam = 0): u = +sqrt(lam) stable, -sqrt(lam) unstable."""

    def residual(self, u, p):
        return p["lam"] - u**2

    def jacobian(self, u, p):
        return sp.csr_matrix(np.atleast_2d(-2 * u[0]))


class WithMass(Pitchfork):
    """2 du/dt = lam u - u^3: eigenvalues halve, signs unchanged."""

    def mass_matrix(self, u, p):
        return sp.identity(1, format="csr") * 2.0


class Hopf:
    """Linear oscillator x' = lam x - y, y' = x + lam y: eigenvalues lam +- i (Hopf at 0)."""

    parameter_names = ("lam",)

    def residual(self, u, p):
        return self.jacobian(u, p) @ u

    def jacobian(self, u, p):
        lam = p["lam"]
        return sp.csr_matrix(np.array([[lam, -1.0], [1.0, lam]]))

    def dresidual_dp(self, u, p, name):
        return u.copy()


def _branch(lam, states, sps=()):
    s = len(lam)
    return Branch(parameter="lam", free=("lam",), params={"lam": np.asarray(lam, float)},
                  observables={"phi": states[:, 0].copy()}, states=states,
                  tangents=np.zeros((s, states.shape[1] + 1)), ds=np.zeros(s),
                  newton_iterations=np.zeros(s, dtype=np.int64), special_points=list(sps))


def _sp(kind, index, lam):
    return SpecialPoint(type=kind, index=index, params={"lam": lam}, order_parameter=0.0,
                        state=np.zeros(1), label=1)


def test_stability_of_state_pitchfork_and_mass_matrix():
    prob = Pitchfork()
    res = stability_of_state(prob, np.array([0.0]), {"lam": -0.5}, n_eigs=3)
    assert res.stable and res.n_unstable == 0 and res.n_finite == 1
    assert res.leading == pytest.approx(-0.5, abs=1e-15)
    assert np.all(np.isnan(res.eigenvalues[1:]))  # padded
    res = stability_of_state(prob, np.array([0.0]), {"lam": 0.5})
    assert not res.stable and res.n_unstable == 1
    # nontrivial branch u = sqrt(lam): J = -2 lam
    res = stability_of_state(prob, np.array([np.sqrt(0.5)]), {"lam": 0.5})
    assert res.stable and res.leading == pytest.approx(-1.0, abs=1e-14)
    res = stability_of_state(WithMass(), np.array([0.0]), {"lam": 0.5})
    assert res.leading == pytest.approx(0.25, abs=1e-15)
    with pytest.raises(ValueError, match="kx = kz = 0"):
        stability_of_state(prob, np.array([0.0]), {"lam": 0.5}, kx=1.0)


def test_stability_pass_and_audit_pitchfork_trivial_branch():
    lam = np.linspace(-1, 1, 10)  # lam = 0 lies between points 4 and 5
    br = _branch(lam, np.zeros((10, 1)), [_sp("BP", 4, 0.0), _sp("EP", 9, 1.0)])
    stability_pass(Pitchfork(), br, n_eigs=2)
    np.testing.assert_array_equal(br.n_unstable, [0] * 5 + [1] * 5)
    np.testing.assert_array_equal(br.stable, lam < 0)
    assert br.eigenvalues.shape == (10, 2)
    np.testing.assert_allclose(br.eigenvalues[:, 0].real, lam, atol=1e-14)
    assert audit(br) == [] and br.audit == []


def test_audit_reports_misplaced_and_missing_points():
    lam = np.linspace(-1, 1, 10)
    br = _branch(lam, np.zeros((10, 1)), [_sp("BP", 2, -0.5)])  # wrong interval
    stability_pass(Pitchfork(), br)
    msgs = audit(br)
    assert len(msgs) == 2
    assert "BP1" in msgs[0] and "does not change between points 2 and 3" in msgs[0]
    assert "changes 0 -> 1 between points 4 and 5" in msgs[1]
    assert br.audit == msgs


def test_audit_fold_branch_and_point_at_stored_node():
    # parametrised by u from -1 to 1; lam = u^2 has a fold at u = 0 (stored point 5)
    u = np.linspace(-1, 1, 11)
    br = _branch(u**2, u[:, None], [_sp("LP", 5, 0.0)])
    stability_pass(Fold(), br)
    np.testing.assert_array_equal(br.n_unstable, (u < 0).astype(int))  # J = -2u; 0 at u = 0 is not unstable
    assert audit(br) == []


def test_audit_flags_hopf_as_unexplained_complex_pair():
    lam = np.linspace(-1, 1, 6)
    br = _branch(lam, np.zeros((6, 2)))
    stability_pass(Hopf(), br)
    np.testing.assert_array_equal(br.n_unstable, [0, 0, 0, 2, 2, 2])
    msgs = audit(br)
    assert len(msgs) == 1 and "complex pair" in msgs[0] and "0 -> 2" in msgs[0]


def test_stability_pass_failure_is_marked_and_audited():
    class Broken(Pitchfork):
        def jacobian(self, u, p):
            if p["lam"] > 0.5:
                raise np.linalg.LinAlgError("boom")
            return super().jacobian(u, p)

    lam = np.linspace(-1, 1, 5)
    br = _branch(lam, np.zeros((5, 1)), [_sp("BP", 1, 0.0)])
    stability_pass(Broken(), br)
    assert br.n_unstable[-1] == -1 and not br.stable[-1] and np.isnan(br.eigenvalues[-1, 0])
    msgs = audit(br)
    assert any("stability unknown at point 4" in m for m in msgs)
    with pytest.raises(ValueError, match="stability_pass"):
        audit(_branch(lam, np.zeros((5, 1))))


def test_audit_counts_point0_of_a_switched_branch_with_point1():
    """Point 0 of a switched branch is its parent's BP (a zero eigenvalue, its sign rounding
    noise): a change of n_unstable between points 0 and 1 is no disagreement there, but is one
    on a branch that does not start at a BP; the stored column is not altered."""
    b = _branch([1.0, 1.1, 1.2], np.zeros((3, 1)))
    b.n_unstable = np.array([0, 1, 1])
    b.parent = "BP2@0"
    assert audit(b) == [] and list(b.n_unstable) == [0, 1, 1]
    b.parent = ""
    (msg,) = audit(b)
    assert "changes 0 -> 1 between points 0 and 1" in msg
    b.parent = "BP2@0"
    b.n_unstable = np.array([0, 1, 2])  # a change later on is still reported
    (msg,) = audit(b)
    assert "between points 1 and 2" in msg


def test_audit_keeps_the_tracers_lines_in_the_file(tmp_path):
    """`contin trace brusselator --method fd4 --tol 1e-6 --special-tol 1e-8` (stability on, the
    scene's pass through contin.stability.audit): the file keeps the tracer's audit lines --
    the start grid, the HB's two-grid checks and the refinements -- after the stability audit,
    which replaced every line but the rejected steps' (the file had none of them).  A second
    audit replaces its own messages only."""
    from click.testing import CliRunner

    from contin import io
    from contin.cli import main
    from contin.stability import audit, is_stability_message

    out = tmp_path / "bru.h5"
    r = CliRunner().invoke(main, ["trace", "brusselator", "--method", "fd4", "--tol", "1e-6", "--special-tol", "1e-8",
                                  "-o", str(out)])
    assert r.exit_code == 0, r.output
    (branch,), _ = io.load(out)
    assert branch.n_unstable is not None
    assert any(a.startswith("start grid coarsened") for a in branch.audit)
    assert sum(a.startswith("located HB") for a in branch.audit) >= 2
    assert any(a.startswith("grid refined") for a in branch.audit)
    kept = [a for a in branch.audit if not is_stability_message(a)]
    branch.audit.append("n_unstable changes 0 -> 1 between points 3 and 4 (b = 1 .. 2) with no BP/LP in between")
    messages = audit(branch)
    assert branch.audit == kept + messages


def test_stability_columns_is_the_one_per_point_loop(caplog):
    """contin.stability.stability_columns with a caller's eigenproblem (the gPCF operator's
    way, problems.couette.pitchfork): the Hopf oscillator's eigenvalues lam +- i in closed form,
    the count relative to max(1, |omega|), a point whose eigenproblem fails or whose state was not
    saved left unknown (-1, nan) with one log line, only the given error types caught, and a stop
    request returning None; stability_pass and growth_columns give the same columns."""
    from contin.cancel import request_stop, stop_on_sigint
    from contin.stability import growth_columns, stability_columns

    lam = np.array([-0.5, -1e-9, 1e-6, 0.25, 0.5])
    br = _branch(lam, np.zeros((5, 2)))
    seen = []

    def spectrum(i, u, p):
        seen.append((i, p))
        if i == 3:
            raise np.linalg.LinAlgError("singular")
        w = np.array([p["lam"] + 1j, p["lam"] - 1j])  # Hopf: lam +- i, |omega| = sqrt(1 + lam^2)
        return w

    with caplog.at_level("WARNING", logger="contin"):
        stable, n_unstable, eigs = stability_columns(br, {"lam": 99.0, "c": 2.0}, spectrum, n_eigs=3, tol=1e-8,
                                                     what="my pass")
    assert [i for i, _ in seen] == list(range(5))
    assert all(p == {"lam": lam[i], "c": 2.0} for i, p in seen)  # the branch's column overrides the fixed value
    # 1e-6 > 1e-8 sqrt(1 + 1e-12): unstable; -1e-9 is not
    np.testing.assert_array_equal(n_unstable, [0, 0, 2, -1, 2])
    np.testing.assert_array_equal(stable, [True, True, False, False, False])
    np.testing.assert_array_equal(eigs[[0, 1, 2, 4], 0], lam[[0, 1, 2, 4]] + 1j)
    np.testing.assert_array_equal(eigs[[0, 1, 2, 4], 1], lam[[0, 1, 2, 4]] - 1j)
    assert np.isnan(eigs[:, 2]).all() and np.isnan(eigs[3]).all()
    assert [r.getMessage() for r in caplog.records] == [f"my pass failed at point 3 of branch {br.id}: singular"]

    def other_error(i, u, p):
        raise ValueError("not an eigenproblem failure")

    with pytest.raises(ValueError, match="not an eigenproblem failure"):
        stability_columns(br, None, other_error)
    stable, n_unstable, eigs = stability_columns(br, None, other_error, errors=(ValueError,))
    assert (n_unstable == -1).all() and not stable.any() and np.isnan(eigs).all()

    # a state not saved (save_every > 1): unknown, its eigenproblem not asked
    sparse_states = _branch(lam, np.zeros((5, 2)))
    sparse_states.states = sparse_states.states[::2]
    sparse_states.state_index = np.array([0, 2, 4])
    seen.clear()
    _, n_unstable, _ = stability_columns(sparse_states, None, spectrum)
    assert [i for i, _ in seen] == [0, 2, 4] and list(n_unstable) == [0, -1, 2, -1, 2]

    # the generic passes are this loop on operator_pair's spectrum
    stability_pass(Hopf(), br, n_eigs=3)
    np.testing.assert_array_equal(br.n_unstable, [0, 0, 2, 2, 2])
    np.testing.assert_allclose(br.eigenvalues[:, :2], np.c_[lam + 1j, lam - 1j], atol=1e-15)
    cols = growth_columns(Hopf(), br, kx=0.0)
    assert set(cols) == {"growth_rate_kx0", "n_unstable_kx0"}
    np.testing.assert_allclose(cols["growth_rate_kx0"], lam, atol=1e-15)
    np.testing.assert_array_equal(cols["n_unstable_kx0"], [0, 0, 2, 2, 2])
    with stop_on_sigint():
        request_stop()
        assert stability_columns(br, None, spectrum) is None
