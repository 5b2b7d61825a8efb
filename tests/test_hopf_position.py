"""Two-grid position checks of located Hopf points (contin.specialcheck.hopf_point_error) on the
1-D Brusselator (problems.demo.Brusselator), a non-granular problem with a Hopf point on a grid.

References are computed here, independently of the tracer and of the check: the homogeneous
state (a, b/a) is exact on every grid and the pencil splits mode by mode, so the k = 1 Hopf
point of a grid is at

    b_H = 1 + a^2 + (D1 + D2) lam_1 / L^2,

lam_1 the smallest Dirichlet eigenvalue of the grid's -d^2/dx^2: in closed form for fd2,
4/h^2 sin^2(pi h / 2) (h = 1/N), pi^2 in the continuum, and by numpy.linalg.eigvals of the
interior block of the grid's D2 for fd4 and Chebyshev.  The check's parameter shift must be
b_H(2N) - b_H(N), to first order.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from contin.adapt import AdaptOptions
from contin.continuation import trace
from contin.options import ContinuationOptions, StepOptions
from contin.specialcheck import hopf_point_error
from problems.demo import Brusselator
from problems.discretization import make_grid

PARAMS = {"a": 2.0, "D1": 0.02, "D2": 0.01, "L": 1.0}


def b_hopf(lam: float) -> float:
    """The k = 1 Hopf point for the Dirichlet eigenvalue lam (module docstring)."""
    return 1.0 + PARAMS["a"] ** 2 + (PARAMS["D1"] + PARAMS["D2"]) * lam / PARAMS["L"] ** 2


#: the continuum's Hopf point, b_H = 5 + 0.03 pi^2
B_H = b_hopf(math.pi**2)


def lam_1(method: str, n: int) -> float:
    """The smallest Dirichlet eigenvalue of -d^2/dx^2 on [0, 1] on the grid (method, n)."""
    if method == "fd2":
        return 4.0 * n * n * math.sin(math.pi / (2 * n)) ** 2
    d2 = make_grid(method, n).d2  # on y in [-1/2, 1/2]: x = y + 1/2, the same derivatives
    inner = d2.toarray()[1:-1, 1:-1] if hasattr(d2, "toarray") else np.asarray(d2)[1:-1, 1:-1]
    return float(np.min(np.linalg.eigvals(-inner).real))


def check_at_hopf(method: str, n: int, eigenvector: bool = False):
    """The check of the grid's exact Hopf point (omega from the 2x2 mode problem)."""
    pb = Brusselator(method, n)
    b = b_hopf(lam_1(method, n))
    p = {**PARAMS, "b": b}
    lam = lam_1(method, n)
    d1, d2 = PARAMS["D1"] * lam, PARAMS["D2"] * lam
    omega = math.sqrt(PARAMS["a"] ** 2 * (1 + d1 - d2) - d2 * d2)  # det of the k = 1 block at zero trace
    x = pb.homogeneous(p)
    q = None
    if eigenvector:  # the critical eigenvector by a dense generalized eigensolve (not contin.hopf)
        import scipy.linalg

        w, vr = scipy.linalg.eig(pb.jacobian(x, p).toarray(), pb.mass_matrix(x, p).toarray())
        finite = np.isfinite(w)
        i = int(np.argmin(np.where(finite, np.abs(w - 1j * omega), np.inf)))
        assert abs(w[i] - 1j * omega) < 1e-9 * omega
        q = vr[:, i]
    tangent = np.append(np.zeros(x.size), 1.0)
    return hopf_point_error(pb, x, p, "b", tangent, omega, q, AdaptOptions(tol=1e-6)), b


@pytest.mark.parametrize("n", [8, 16, 64])
def test_hopf_check_fd2_is_the_next_grids_hopf_point(n):
    check, coarse = check_at_hopf("fd2", n)
    fine = b_hopf(lam_1("fd2", 2 * n))
    assert check is not None and check.grid == 2 * n
    # the carried eigenvector is not the fine one: one Newton step leaves O(shift^2)
    # (measured: 1.3e-4, 3.4e-5, 2.1e-6 of the shift on fd2 8, 16, 64)
    assert check.parameter_shift == pytest.approx(fine - coarse, rel=1e-3)
    # the error: the shift over 1 - 2^-2 (Richardson, fd2's order; contin.adapt.richardson),
    # i.e. the coarse grid's own error against the continuum's b_H
    assert check.error == pytest.approx(abs(fine - coarse) / fine / 0.75, rel=1e-3)
    assert check.error == pytest.approx(abs(B_H - coarse) / B_H, rel=0.05)


@pytest.mark.parametrize("method,n", [("fd4", 16), ("cheb", 8)])
def test_hopf_check_fd4_and_chebyshev(method, n):
    """fd4 16: b_H 3.7e-6 off b_H(fd4 32) (measured to 1.6e-7 of it); Chebyshev 8: 1.4e-8 off
    (to 1.8e-7 of it).  The eigenvector handed in (scipy.linalg.eig) gives the same shift as
    the one the check computes itself (contin.hopf.hopf_vectors)."""
    check, coarse = check_at_hopf(method, n)
    fine = b_hopf(lam_1(method, 2 * n))
    assert 1e-9 < abs(fine - coarse) < 1e-4  # a visible error, so the check has something to measure
    assert check.parameter_shift == pytest.approx(fine - coarse, rel=1e-5)
    given, _ = check_at_hopf(method, n, eigenvector=True)
    assert given.parameter_shift == pytest.approx(check.parameter_shift, rel=1e-6)


def test_hopf_check_not_applicable():
    """None without check_factor or without a positive omega."""
    pb = Brusselator("fd2", 8)
    p = {**PARAMS, "b": B_H}
    x = pb.homogeneous(p)
    t = np.append(np.zeros(x.size), 1.0)
    assert hopf_point_error(pb, x, p, "b", t, 2.0, None, AdaptOptions(check_factor=None)) is None
    assert hopf_point_error(pb, x, p, "b", t, math.nan, None, AdaptOptions()) is None
    assert hopf_point_error(pb, x, p, "b", t, 0.0, None, AdaptOptions()) is None


def adaptive_trace(method: str, n: int, special_tol: float, max_grid: int = 512):
    pb = Brusselator(method, n)
    p = {**PARAMS, "b": 4.0}
    o = ContinuationOptions(bounds={"b": (4.0, 6.0)}, max_steps=200, step=StepOptions(ds=0.05, ds_max=0.25),
                            adapt=AdaptOptions(tol=1e-6, special_tol=special_tol, max_grid=max_grid))
    branch = trace(pb, pb.homogeneous(p), p, "b", o)
    (hb,) = branch.points("HB")
    return branch, hb


def test_adaptive_trace_fd4_refines_the_hopf_point_to_special_tol():
    """fd4 from 16, special_tol 1e-8: the homogeneous state is exact on every grid (estimate 0),
    so the start grid is coarsened to 12, and only the HB's two-grid check sees its position's
    error: measured 1.6e-6, 3.4e-7, 5.6e-8, 1.1e-8 on fd4 12, 20, 32, 48, the HB is located
    again each time and kept on fd4 72, 2.2e-9 off the continuum's b_H.  Before the check (HB
    had none) it stayed on fd4 12 at b = 5.296079421, 1.6e-6 off, without a note."""
    branch, hb = adaptive_trace("fd4", 16, 1e-8)
    assert abs(hb.params["b"] / B_H - 1) <= 1e-8
    assert hb.grid > 12 and "not resolved" not in hb.note
    assert hb.params["b"] == pytest.approx(b_hopf(lam_1("fd4", hb.grid)), rel=1e-11)  # located on its grid
    checked = [a for a in branch.audit if a.startswith("located HB") and "two-grid error of its position" in a]
    assert len(checked) >= 2 and all("exceeds 1e-08" in a for a in checked)
    assert any("grid refined 12 -> " in a and "located HB under-resolved" in a for a in branch.audit)
    first = float(checked[0].split("two-grid error of its position ")[1].split()[0])
    # the first check, on fd4 12, is b_H(12) against b_H(24) in closed form over 1 - 2^-4
    # (Richardson): fd4 12's own error against the continuum
    assert first == pytest.approx(abs(b_hopf(lam_1("fd4", 24)) / b_hopf(lam_1("fd4", 12)) - 1) / (1 - 2.0**-4), rel=0.05)
    assert first == pytest.approx(abs(b_hopf(lam_1("fd4", 12)) / B_H - 1), rel=0.05)


def test_adaptive_trace_chebyshev_hopf_point_is_not_refined_needlessly():
    """Chebyshev: b_H converges spectrally (2.6e-9 off on cheb 8, 2.3e-14 on cheb 12).  With
    special_tol 1e-8 the HB located on cheb 8 (the start grid coarsened: the state is exact)
    passes its check and no grid is refined; with 1e-12 it is refined once, to cheb 12."""
    branch, hb = adaptive_trace("cheb", 16, 1e-8)
    assert hb.grid == 8 and abs(hb.params["b"] / B_H - 1) <= 1e-8
    assert not any(a.startswith("grid refined") for a in branch.audit)
    branch, hb = adaptive_trace("cheb", 16, 1e-12)
    assert hb.grid == 12 and abs(hb.params["b"] / B_H - 1) <= 1e-12
    assert sum(a.startswith("grid refined") for a in branch.audit) == 1


def test_cli_trace_brusselator_fd2_special_tol(tmp_path):
    """`contin trace brusselator --method fd2 --tol 1e-6 --special-tol 2e-8`: fd2's b_H is
    (pi h)^2 / 12 x 0.3 / 5.3 off (relative), so 2e-8 needs fd2 ~1500 -- past the default
    max_grid 512, where the HB is stored with a note that its position is not resolved (1.8e-7
    off and measured so: not silent); with --max-grid 2048 it is located on fd2 1892 (after the
    refinements from 8; 1260 measured 2.9e-8), within 2e-8 of the continuum's b_H.  The two-grid check measures
    b_H(N) - b_H(2N), which for a second-order scheme is 1 - 2^-2 = 3/4 of the error, and
    divides it by that (contin.adapt.richardson), so special_tol bounds the error itself."""
    from click.testing import CliRunner

    from contin import io
    from contin.cli import main

    out = tmp_path / "bru.h5"
    args = ["trace", "brusselator", "--method", "fd2", "--tol", "1e-6", "--special-tol", "2e-8", "--no-stability"]
    r = CliRunner().invoke(main, [*args, "--max-grid", "2048", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "two-grid error of its position" in r.stderr
    branches, meta = io.load(out)
    (hb,) = branches[0].points("HB")
    assert "not resolved" not in hb.note
    assert hb.grid > 512
    assert abs(hb.params["b"] / B_H - 1) <= 2e-8
    assert hb.params["b"] == pytest.approx(b_hopf(lam_1("fd2", hb.grid)), rel=1e-11)  # fd2's own b_H there
    assert hb.data["omega"] == pytest.approx(Brusselator.hopf_point(PARAMS)[1], rel=1e-7)

    out = tmp_path / "bru512.h5"
    r = CliRunner().invoke(main, [*args, "-o", str(out)])
    assert r.exit_code == 0, r.output
    (hb,) = io.load(out)[0][0].points("HB")
    assert hb.grid == 512 and "position not resolved by refinement" in hb.note
    assert 2e-8 < abs(hb.params["b"] / B_H - 1) < 1e-6


def test_cli_trace_brusselator_default_is_spectral(tmp_path):
    """The scene's default (Chebyshev, tol and special_tol 1e-10): the HB on cheb 12, 2.3e-14
    off the closed form, with the stability columns (0 unstable before it, 2 after)."""
    from click.testing import CliRunner

    from contin import io
    from contin.cli import main

    out = tmp_path / "bru.h5"
    r = CliRunner().invoke(main, ["trace", "brusselator", "-o", str(out)])
    assert r.exit_code == 0, r.output
    branch = io.load(out)[0][0]
    (hb,) = branch.points("HB")
    assert abs(hb.params["b"] / B_H - 1) <= 1e-12
    nu = np.asarray(branch.n_unstable)
    assert nu[0] == 0 and nu[-1] == 2
