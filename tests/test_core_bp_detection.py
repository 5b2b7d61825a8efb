"""Branch points that are never missed (issue 12 sec. 3): the eigenvalue count of contin.bpdetect
cross-checked with the determinant tests.

References are closed forms computed here: the diagonal problem's J = diag(-1 + lam L_ii) on
x = 0 (BifurcationKit's test_bif_detection.jl), and the Dirichlet eigenvalues of the discrete
Swift-Hohenberg operator, lam_k = (1 + mu_k)^2 with mu_k = -(4/h^2) sin^2(k pi / (2(N+1))).
"""

from __future__ import annotations

import numpy as np
import pytest

from contin.bpdetect import Spectrum, crossings, kernel_dimension, kernel_dimension_of
from contin.continuation import trace
from contin.options import ContinuationOptions, DetectionOptions, StepOptions
from problems.bp_demos import DIAGONAL_BPS, DIAGONAL_DIMS, Diagonal
from problems.swift_hohenberg import SwiftHohenberg


def diagonal_branch(k: int, **step: float) -> object:
    pb = Diagonal()
    opts = ContinuationOptions(step=StepOptions(**{"ds": 0.1, "ds_max": 0.5, **step}), bounds={"lam": (-1.0, 10.0)},
                               detection=DetectionOptions(bp_eigenvalues=k))
    return trace(pb, np.zeros(pb.n), {"lam": 0.0}, "lam", opts)


def test_diagonal_problem_all_nine_bps_with_their_kernel_dimensions() -> None:
    br = diagonal_branch(12)
    bps = br.branch_points
    # reference: J = diag(-1 + lam L_ii) is singular at lam = 1 / L_ii, with multiplicity
    L = Diagonal().L
    ref = sorted(set(np.round(1 / L, 12)))
    assert ref == pytest.approx(DIAGONAL_BPS, abs=1e-12)
    mult = [int(np.sum(np.isclose(1 / L, v))) for v in ref]
    assert tuple(mult) == DIAGONAL_DIMS
    assert [bp.params["lam"] for bp in bps] == pytest.approx(ref, abs=1e-9)
    assert [kernel_dimension(bp) for bp in bps] == mult
    for bp in bps:
        lo, hi = sorted(bp.bracket)
        assert bp.converged and lo <= bp.params["lam"] <= hi


def test_determinant_alone_misses_the_even_kernels() -> None:
    """Why the second detector exists: det changes sign only at odd kernel dimensions."""
    found = [bp.params["lam"] for bp in diagonal_branch(0).branch_points]
    assert not any(abs(v - 2.0) < 1e-3 or abs(v - 4.0) < 1e-3 for v in found)


def test_disagreement_at_ds_min_is_kept_and_said() -> None:
    """No halving possible (ds = ds_min): two BPs (6.75, 6.875) in one step stay unseparated; the
    step is kept with an audit line and a BP stored unconverged, never silently dropped."""
    br = diagonal_branch(12, ds=0.37, ds_min=0.37, ds_max=0.37)
    assert any("detectors disagree" in line for line in br.audit)
    flagged = [bp for bp in br.branch_points if "detectors disagree" in bp.note]
    assert flagged and not any(bp.converged for bp in flagged if "not located" in bp.note)


def test_swift_hohenberg_all_five_bps_of_the_trivial_branch() -> None:
    pb = SwiftHohenberg()
    ref = pb.trivial_branch_points(-1.0, 1.0)
    assert len(ref) == 5
    opts = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"lam": (-1.0, 1.0)},
                               detection=DetectionOptions(bp_eigenvalues=12), max_steps=400)
    # symmetric=False: this test is about the generic BP detector (the u -> -u symmetry of
    # SwiftHohenberg would switch to the symmetry-breaking test; tests/test_diagram.py covers that)
    br = trace(pb, np.zeros(pb.N), {"lam": -0.7, "nu": 2.0}, "lam", opts, symmetric=False)
    bps = br.branch_points
    assert [bp.params["lam"] for bp in bps] == pytest.approx(ref, abs=1e-9)
    assert [kernel_dimension(bp) for bp in bps] == [1] * 5
    assert all(bp.converged for bp in bps)
    # the 0.4839 / 0.5308 pair fell into one step of ds_max = 0.05 at least once: re-stepped
    assert any("re-stepped with half ds" in line for line in br.audit)


def test_crossing_count_and_kernel_dimension_units() -> None:
    a = Spectrum(np.array([-1e-3, -0.5, 2.0 + 1j, 2.0 - 1j]), np.inf)
    b = Spectrum(np.array([2e-3, -0.4, 2.5 + 1j, 2.5 - 1j]), np.inf)
    assert crossings(a, b)[:2] == (1, True)
    # two real eigenvalues meeting and turning complex is no crossing
    c = Spectrum(np.array([-1e-3, -0.45 + 0.1j, -0.45 - 0.1j]), np.inf)
    d = Spectrum(np.array([-1e-3, -0.4, -0.5]), np.inf)
    assert crossings(d, c)[:2] == (0, True)
    # one side changes by one, the other not: an eigenvalue left the covered disc, inconclusive
    e = Spectrum(np.array([0.05, -0.25]), np.inf)
    f = Spectrum(np.array([0.05]), 0.3)
    assert crossings(e, f, moved=0.3)[1] is False
    assert kernel_dimension_of(Spectrum(np.array([1e-13, -2e-13, 3e-13, 0.2, 5.0]), np.inf)) == 3
    assert kernel_dimension_of(Spectrum(np.array([0.1, 0.2, 5.0]), np.inf)) == 0


def test_outside_bracket_rule() -> None:
    from contin.locate import outside_bracket

    assert outside_bracket(0.5, 0.0, 1.0, 1e-12) is None
    assert outside_bracket(0.5, 1.0, 0.0, 1e-12, (0.0, 2.0)) is None
    assert "outside its bracket" in outside_bracket(1.2, 0.0, 1.0, 1e-12)
    assert "outside the bounds" in outside_bracket(0.9, 0.0, 1.0, 1e-12, (-1.0, 0.8))


def test_a_bp_located_outside_its_bracket_is_stored_unconverged(monkeypatch) -> None:
    """Regression (issue 12): a BP stored converged=True outside its bracket and the bounds.  The
    locator is made to return a point from another branch beyond the step (what a trial carried
    off by the corrector gives); the tracer must not store it as a converged location."""
    import dataclasses

    import contin.continuation as cc
    from problems.demo import Transcritical

    real = cc.locate_zero

    def carried_off(evaluate, a, b, **kw):
        res = real(evaluate, a, b, **kw)
        far = evaluate(b.s * 3.0)  # a corrected point three step lengths on
        return dataclasses.replace(res, best=far, converged=True)

    monkeypatch.setattr(cc, "locate_zero", carried_off)
    opts = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.1), bounds={"lam": (-1.0, 0.35)},
                               detection=DetectionOptions(retry_unconfirmed_bp=False))
    br = trace(Transcritical(), np.array([0.0]), {"lam": -0.5}, "lam", opts)
    (bp,) = br.branch_points
    lo, hi = sorted(bp.bracket)
    assert not lo <= bp.params["lam"] <= hi
    assert not bp.converged and "outside its bracket" in bp.note


def test_switching_at_a_two_dimensional_kernel_solves_the_reduced_equations() -> None:
    """At lam = 2 (kernel e_1, e_2: L = 1/2 twice) the reduced equations sigma M b + C(b)/6 = 0 have
    the 3^2 - 1 = 8 roots b_i in {0, +-1/sqrt 2}; every new branch is x_i = +-sqrt(lam/2 - 1) on
    its support (closed form of -x + lam x / 2 - x^3 = 0), zero elsewhere."""
    from contin.branch import relabel
    from contin.continuation import switch

    br = diagonal_branch(12)
    relabel([br])
    bp = next(b for b in br.branch_points if kernel_dimension(b) == 2)
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.2), bounds={"lam": (-1.0, 3.5)}, max_steps=15)
    kids = switch(Diagonal(), br, bp, opts)
    assert len(kids) == 8
    L = Diagonal().L
    patterns = set()
    for kid in kids:
        lam, x = kid.params["lam"][1:], kid.states[1:]
        assert np.all(lam > 2.0)
        on = np.abs(x[-1]) > 1e-8
        assert set(np.flatnonzero(on)) <= {1, 2}
        assert np.max(np.abs(x[:, on] ** 2 - (lam[:, None] * L[on] - 1))) < 1e-10
        assert np.max(np.abs(x[:, ~on])) < 1e-10
        patterns.add(tuple(np.where(on, np.sign(x[-1]), 0)[[1, 2]].astype(int)))
    assert patterns == {(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)} - {(0, 0)}


def test_switch_never_returns_an_empty_list() -> None:
    """A switch that finds no branch says why (here every state off x = 0 is inadmissible, so
    no first step off the BP can be corrected); it used to return [] without a word."""
    from contin.branch import relabel
    from contin.continuation import switch
    from problems.demo import Transcritical

    class Fenced(Transcritical):
        def admissible(self, u, p):
            return "off the fence" if abs(u[0]) > 1e-9 else None

    pb = Fenced()
    opts = ContinuationOptions(step=StepOptions(ds=0.1, ds_max=0.1), bounds={"lam": (-1.0, 1.0)})
    br = trace(pb, np.array([0.0]), {"lam": -0.5}, "lam", opts)
    relabel([br])
    (bp,) = br.branch_points
    with pytest.raises(ValueError, match="found no new branch: direction \\+1: .*direction -1: "):
        switch(pb, br, bp, opts)


def test_spectrum_sparse_path_gives_the_eigenvalues_nearest_zero() -> None:
    """n > DENSE_EIG_LIMIT: shift-invert ARPACK; the k - 1 nearest zero and the k-th as radius."""
    import scipy.sparse as sp

    from contin.bpdetect import DENSE_EIG_LIMIT, spectrum

    n = DENSE_EIG_LIMIT + 600
    diag = np.linspace(-3.0, 7.0, n) + 0.0123  # nearest zero: 0.0123 - 10/(n-1) * j
    spec = spectrum(sp.diags(diag, format="csc"), 6)
    ref = diag[np.argsort(np.abs(diag))]
    assert np.sort(spec.values.real) == pytest.approx(np.sort(ref[:5]), abs=1e-10)
    assert spec.radius == pytest.approx(abs(ref[5]), abs=1e-10)


def test_copies_of_a_multiple_eigenvalue_missed_at_one_end_are_no_crossing() -> None:
    """ARPACK returns the copies of a multiple eigenvalue unreliably (one Krylov vector per
    eigenspace, the rest by rounding).  The Brusselator on fd2 372 (746 unknowns) has the
    eigenvalue 1 four times (its boundary rows): listed four times at one end and three at the
    other, the disc count changed by one with nothing crossing zero, every step came back
    "inconclusive" and the branch crawled to its step cap short of its Hopf point (exit 0).
    Values that did not move are set aside: the count is conclusive, zero; a real crossing beside
    them is still one."""
    pair = [-0.0786 + 2.0963j, -0.0786 - 2.0963j, -0.5227 + 2.3585j, -0.5227 - 2.3585j]
    a = Spectrum(np.array([1.0, 1.0, 1.0, 1.0, *pair]), 3.88)
    b = Spectrum(np.array([1.0, 1.0, 1.0, *[w + 0.001 for w in pair]]), 3.87)
    c, conclusive, detail = crossings(a, b, moved=0.01)
    assert (c, conclusive) == (0, True) and "7 eigenvalues that did not move set aside" in detail
    # beside them, an eigenvalue through zero is counted
    a2 = Spectrum(np.append(a.values, -0.002), 3.88)
    b2 = Spectrum(np.append(b.values, 0.003), 3.87)
    assert crossings(a2, b2, moved=0.01)[:2] == (1, True)
    # an eigenvalue that moved is not set aside: one that may have left the disc across its rim
    # keeps the count inconclusive (the case of test_crossing_count_and_kernel_dimension_units)
    a3 = Spectrum(np.array([0.05, -0.25, 1.0, 1.0, 1.0, 1.0]), 3.88)
    b3 = Spectrum(np.array([0.05, 1.0, 1.0, 1.0]), 0.3)
    assert crossings(a3, b3, moved=0.3)[1] is False


def test_sparse_spectrum_is_the_same_in_every_call() -> None:
    """ARPACK's own start vector comes from a seed that advances with every call in the process:
    the same J gave three copies of the Brusselator's eigenvalue 1 in one call and four in the
    next.  The start vector is fixed, so the same J gives the same eigenvalues."""
    from contin.bpdetect import spectrum
    from problems.demo import Brusselator

    problem = Brusselator("fd2", 372)
    p = dict(Brusselator.PARAMS, b=5.1389)
    jac = problem.jacobian(problem.homogeneous(p), p)
    first = spectrum(jac, 12)
    for _ in range(4):
        again = spectrum(jac, 12)
        assert np.array_equal(again.values, first.values) and again.radius == first.radius
    # the nearest zero are the Hopf pair of mode 1 (trace b - 1 - a^2 - 0.03 lam_1) and the
    # boundary rows' eigenvalue 1
    lam_1 = problem.dirichlet_eigenvalue()
    real_part = (p["b"] - 1 - p["a"] ** 2 - (p["D1"] + p["D2"]) * lam_1) / 2
    assert np.min(np.abs(first.values - real_part - 1j * np.abs(first.values.imag))) < 1e-8
    # the stability pass's shift-invert ARPACK (the pencil J, M) likewise
    from contin.stability import eigenvalues

    mass = problem.mass_matrix(None, p)
    w = eigenvalues(jac, mass, k=8, sigma=0.0, dense_max=100)
    assert np.array_equal(eigenvalues(jac, mass, k=8, sigma=0.0, dense_max=100), w)
    assert np.min(np.abs(w.real - real_part)) < 1e-8


def test_stability_audit_checks_kernel_dimensions() -> None:
    """The stability pass's n_unstable (eigenvalues of J, M = I) changes by each BP's kernel
    dimension on the diagonal problem; a BP claiming the wrong dimension is reported."""
    import dataclasses

    from contin.stability import audit, stability_pass

    br = diagonal_branch(12)
    stability_pass(Diagonal(), br, n_eigs=19)
    assert audit(br) == []
    # n_unstable = number of i with lam L_i > 1, stepping by the multiplicities 1, 2, 3, 4, 5, 1, 1, 1, 1
    L = Diagonal().L
    assert list(br.n_unstable) == [int(np.sum(lam * L > 1 + 1e-12)) for lam in br.params["lam"]]
    wrong = [dataclasses.replace(bp, note=bp.note.replace("kernel dimension 2", "kernel dimension 1"))
             for bp in br.special_points]
    br.special_points = wrong
    (msg,) = audit(br)
    assert "n_unstable changes by 2" in msg and "add up to 1" in msg


def test_swift_hohenberg_secondary_branch_bps_are_located() -> None:
    """Issue 12 regression: the BPs of a secondary Swift-Hohenberg branch (switched at the
    fourth BP of u = 0) ended "location did not converge": next to them the corrector's update
    (rounding floor x condition ~ 1/distance) never met the step tolerance, in a band ~1e-5 wide
    that the locator could not split.  Now located by inverse interpolation across that band
    (contin.locate._interpolated_zero): converged, inside the bracket, and at the point where
    an independent scipy solve (Levenberg-Marquardt) of F = 0, J v = 0, <v, v> = 1 puts them."""
    import scipy.linalg as la
    from scipy.optimize import least_squares

    from contin.continuation import switch

    pb = SwiftHohenberg()
    step = StepOptions(ds=0.01, ds_max=0.02, max_angle=0.3)
    root = trace(pb, np.zeros(pb.N), {"lam": 0.5, "nu": 2.0}, "lam",
                 ContinuationOptions(bounds={"lam": (0.5, 0.56)}, step=step))
    (start,) = root.branch_points
    assert start.params["lam"] == pytest.approx(pb.trivial_branch_points(-1, 1)[3], abs=1e-8)
    kid = switch(pb, root, start, ContinuationOptions(bounds={"lam": (-0.33, 0.6)}, max_steps=1000, step=step))[0]
    bps = kid.branch_points
    assert len(bps) == 2
    n = pb.N
    for bp in bps:
        lam = bp.params["lam"]
        assert bp.converged, bp.note
        assert min(bp.bracket) <= lam <= max(bp.bracket)
        u = bp.state
        J = pb.jacobian(u, bp.params).toarray()
        v = la.svd(J)[2][-1]

        def g(z: np.ndarray) -> np.ndarray:
            p = {"lam": z[n], "nu": 2.0}
            return np.concatenate([pb.residual(z[:n], p), pb.jacobian(z[:n], p) @ z[n + 1:], [z[n + 1:] @ z[n + 1:] - 1]])

        ref = least_squares(g, np.concatenate([u, [lam], v]), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        assert np.max(np.abs(g(ref.x))) < 1e-9  # the reference solves the augmented system
        assert abs(ref.x[n] - lam) < 5e-9
        assert np.max(np.abs(ref.x[:n] - u)) < 1e-5
        sv = la.svdvals(J)
        assert sv[-1] < 1e-6 * sv[-2]  # a kernel at the located state itself


def test_default_policy_of_the_eigenvalue_count() -> None:
    """bp_eigenvalues=None: on (k = 12) up to BP_AUTO_MAX unknowns for problems without their own
    eigenproblem; off above, for problems with an eigenproblem (their stability pass is the
    second witness), for augmented systems and for problems that opt out; k given: k."""
    from contin.bpdetect import bp_eigen_count
    from contin.options import BP_AUTO_MAX, BP_EIGS_AUTO
    from problems.couette.pitchfork import CouetteProblem
    from problems.disks.model import DiskCouetteProblem

    auto, forced, off = DetectionOptions(), DetectionOptions(bp_eigenvalues=6), DetectionOptions(bp_eigenvalues=0)
    diag = Diagonal()
    assert diag.n <= BP_AUTO_MAX and bp_eigen_count(diag, auto, diag.n) == BP_EIGS_AUTO == 12
    assert bp_eigen_count(diag, forced, diag.n) == 6 and bp_eigen_count(diag, off, diag.n) == 0
    sh = SwiftHohenberg()
    assert bp_eigen_count(sh, auto, sh.N) == 0 and bp_eigen_count(sh, forced, sh.N) == 6
    gpcf = CouetteProblem("cheb", 8)
    assert bp_eigen_count(gpcf, auto, 30) == 0 and bp_eigen_count(gpcf, forced, 30) == 6
    disks = DiskCouetteProblem("cheb", 8)
    assert bp_eigen_count(disks, auto, 30) == 0 and bp_eigen_count(disks, forced, 30) == 6

    class Augmented(Diagonal):
        def point_tests(self):
            return []

    assert bp_eigen_count(Augmented(), auto, diag.n) == 0


def test_equivariance_defect_takes_a_rounding_level_parameter_derivative_as_zero():
    """Uniform shear solves F at every H, so dF/dH there is rounding (~1e-15); measured against
    itself its 'defect' was 1, the symmetry was switched off for the H branch and the savage
    band (disks, fd2) lost its BPs (session 15 merge).  F_p is measured against sqrt(eps) |J| too."""
    import scipy.sparse as sp

    from contin.testfunctions import Antisymmetric
    from problems.disks.model import DiskCouetteProblem

    pb = DiskCouetteProblem("fd2", 16)
    p = pb.params({"nu": 0.5, "e": 0.8, "H": 10.0})
    u = pb.uniform_state(p)
    anti = Antisymmetric.from_problem(pb, u.size)
    jac = sp.csr_matrix(pb.jacobian(u, p))
    rounding = 1e-15 * np.random.default_rng(0).standard_normal(u.size)  # an F_p of rounding noise
    assert anti.equivariance_defect(jac, rounding) < 1e-6
    asymmetric = np.zeros(u.size)
    asymmetric[1] = 1.0  # an O(1) F_p on one side only
    assert anti.equivariance_defect(jac, asymmetric) > 0.5
