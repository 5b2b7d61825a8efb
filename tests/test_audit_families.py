"""Session 15's accuracy audit of the demo, disk and non-local families, as fast regression tests.

Every stored state of an adaptive run is solved again at its parameters on a fine Chebyshev
reference grid (``benchmarks.audit_families``, independent of the tracer's two-grid check: a fixed
cheb grid, always spectral, also for FD states) and compared in the problem's norm; special points
are compared with closed forms.  The full audit: ``python -m benchmarks.audit_families batch
bratu allen-cahn brusselator stretched-bratu disks-steady ...``.
"""

from __future__ import annotations

import pytest

from benchmarks.audit_families import audit_branches
from contin.continuation import trace
from contin.options import AdaptOptions, ContinuationOptions, StepOptions
from problems.demo import BRATU_FOLD, StretchedBratu


def test_stretched_bratu_has_no_reflection_symmetry():
    """StretchedBratu inherited Bratu's reflection x -> 1 - x, which the stretching breaks for
    a != 0: from u = 0 (invariant) the tracer treated the branch as S-invariant and
    ``contin trace stretched-bratu -s a=4`` ended MX at lam = 1.5e-6 after storing a point 0.47
    off its solution.  Now the branch reaches its fold lam*/(1 + a), every state within tol of a
    cheb reference solve."""
    a, tol = 4.0, 1e-6
    pb = StretchedBratu("cheb", 24)
    o = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=60, step=StepOptions(ds=0.05, ds_max=0.25),
                            adapt=AdaptOptions(tol=tol))
    b = trace(pb, pb.initial(), {"lam": 0.0, "a": a}, "lam", o)
    (lp,) = b.fold_points
    assert lp.params["lam"] == pytest.approx(BRATU_FOLD / (1 + a), rel=1e-10)
    audit = audit_branches([b], lambda _: pb, {"a": a}, ref_min=128, ref_max=256)
    assert len(audit.points) >= 20 and not audit.failed()
    assert max(p.error for p in audit.points) <= tol


def _run(tmp_path, *args):
    from click.testing import CliRunner

    from contin.cli import main

    out = tmp_path / "run.h5"
    r = CliRunner().invoke(main, ["trace", *args, "--no-stability", "-q", "-o", str(out)], catch_exceptions=False)
    return r, out


def test_nonlocal_cylinder_fixed_grid_states_meet_the_resolution_guard(tmp_path):
    """The cylinder had no resolution guard at all (its Chebyshev tail under-reads its error up to
    50x): ``contin trace nonlocal-cylinder --grid 16`` stored states 1.3e-3 off a cheb 128 reference
    with exit 0 and no warning.  Its guard measures the two-grid error now: on cheb 20 the branch
    ends MX "under-resolved ... two-grid error" at ratio 3.6, every stored state within the
    guard's 3e-5 of the reference solve."""
    from benchmarks.audit_families import file_problem

    r, out = _run(tmp_path, "nonlocal-cylinder", "-s", "report_eqs=1", "--grid", "20")
    assert r.exit_code == 3, r.output
    branches, _, problem_of = file_problem(str(out))
    (b,) = branches
    assert b.status == "MX" and "two-grid error" in b.message and "ratio = 3.6" in b.message
    audit = audit_branches(branches, problem_of, {}, ref_min=128, ref_max=128)
    assert len(audit.points) == len(b) >= 15 and not audit.failed()
    assert max(p.error for p in audit.points) <= 3e-5


@pytest.mark.parametrize("scene", ["nonlocal-shear", "nonlocal-muI", "nonlocal-cylinder"])
def test_nonlocal_fd_grids_are_guarded(tmp_path, scene):
    """On FD grids the non-local problems had no resolution guard (plane shear's was Chebyshev
    only): ``--method fd2 --grid 32`` stored states up to 0.16 (shear), 1.6e-2 (mu(I)) and 1.1e-2
    (cylinder) off a cheb reference with exit 0.  Now the start point's two-grid error (1.5e-3,
    2.9e-3, 1.1e-3) stops the run in one line."""
    r, _ = _run(tmp_path, scene, "--method", "fd2", "--grid", "32")
    assert r.exit_code != 0
    assert "two-grid error" in r.output and "on fd2 32" in r.output and "need a finer --grid" in r.output


def test_unresolved_special_point_positions_are_warnings(tmp_path):
    """A located BP whose measured position misses special_tol on max_grid carried the note
    'position not resolved by refinement' in the summary table only, which -q hides:
    ``contin trace allen-cahn --method fd2 --tol 1e-4 -q`` said nothing of BP3 stored 2.8e-5 off
    lam = 9 (closed form k^2).  Each is a warning line now."""
    r, out = _run(tmp_path, "allen-cahn", "--method", "fd2", "--tol", "1e-4")
    assert r.exit_code == 0
    from contin import io

    branches, _ = io.load(out)
    base = next(b for b in branches if b.id == "0")
    for k, bp in enumerate(base.branch_points, start=1):
        lam = bp.params["lam"]
        assert abs(lam - k * k) / (k * k) > 1e-6  # fd2 512: 3.1e-6, 1.3e-5, 2.8e-5 off
        assert f"warning: branch 0: BP{k} at lam={lam:.10g}: position not resolved by refinement" in r.output


@pytest.mark.parametrize("scene, method, tol", [("disks-steady", "cheb", 1e-6), ("disks-steady", "fd4", 1e-4),
                                                ("allen-cahn", "fd4", 1e-4), ("brusselator", "fd2", 1e-6)])
def test_adaptive_states_are_within_tol_of_a_reference(tmp_path, scene, method, tol):
    """Session 15's audit as a regression test: every stored state of an adaptive run (one physics
    family, two demos) solved again on a fine Chebyshev grid at its parameters is within tol
    (measured: disks-steady cheb 1e-6 0.02 tol, fd4 1e-4 0.68 tol; allen-cahn fd4 0.007 tol;
    brusselator fd2 1e-6 1e-6 tol), and no state needed a warning (the special points' positions on
    fd2/fd4 512 do say that they miss the default special_tol 1e-10)."""
    from benchmarks.audit_families import file_problem

    r, out = _run(tmp_path, scene, "--method", method, "--tol", str(tol))
    assert r.exit_code == 0 and "accepted by its estimate" not in r.output, r.output
    branches, meta, problem_of = file_problem(str(out))
    params = {k: v for k, v in meta["parameters"].items() if isinstance(v, int | float)}
    audit = audit_branches(branches, problem_of, params, ref_min=96, ref_max=128)
    assert len(audit.points) >= 12 and not audit.failed()
    assert max(p.error for p in audit.points) <= tol


def test_a_measured_special_point_does_not_block_the_next_ones_refinement():
    """The memory of a measured special point's position error ("not falling with the grid")
    was compared with the next special point's, anywhere on the branch: disks-pitchfork
    (G_CS) fd4 at tol 1e-4 kept H_1^c on fd4 32 (7.5e-6 off, pre-asymptotic: 2.9e-6 on 16), and
    then refused to refine for H_2^c (kept on fd4 24, 2.9e-4 off) and H_3^c (fd4 12, 2.8e-2 off
    n pi psi; the n = 3 branches switched there).  A point located elsewhere starts its own
    history now (fd4 512: 3.7e-9 and 1.9e-8 off); the same point located again keeps it."""
    from contin.adapt import Adaptor

    a = Adaptor(AdaptOptions(tol=1e-4))
    assert a.special_refinable(5.2e-6, measured=True, at=15.8712)
    assert not a.special_refinable(7.5e-6, measured=True, at=15.8713)  # the same BP, not falling
    assert a.special_refinable(2.9e-4, measured=True, at=31.75)  # H_2^c: another point
    assert a.special_refinable(1e-5, measured=True, at=31.7425)  # the same, falling
    assert not a.special_refinable(1e-5, measured=True, at=31.74245)  # the same, not falling
    assert a.special_refinable(2.9e-2, measured=True, at=48.92)  # H_3^c


def test_an_fd_special_point_may_rise_once_before_its_refinement_ends():
    """disks-pitchfork G_CS H_1^c on fd4 is 2.9e-6 off on 16 and 7.7e-6 on 32 (pre-asymptotic),
    then converges (3.2e-7 on 80, 6e-10 on 432): on finite-order grids one measurement that does
    not fall is allowed per point (it was kept on fd4 32, 7.7e-6 off); a second ends it, and on
    spectral grids the first does (a rounding floor: pitchfork nu = 0.5's symmetric BP)."""
    from contin.adapt import Adaptor

    fd = Adaptor(AdaptOptions(tol=1e-4))
    assert fd.special_refinable(5.2e-6, measured=True, at=15.87125, finite_order=True)
    assert fd.special_refinable(7.5e-6, measured=True, at=15.87133, finite_order=True)  # one rise
    assert fd.special_refinable(2e-6, measured=True, at=15.87123, finite_order=True)
    assert not fd.special_refinable(2e-6, measured=True, at=15.871231, finite_order=True)  # a second
    cheb = Adaptor(AdaptOptions(tol=1e-4))
    assert cheb.special_refinable(1.2e-9, measured=True, at=34.837)
    assert not cheb.special_refinable(1.2e-9, measured=True, at=34.837)


def test_an_fd_refinement_is_judged_by_its_order(tmp_path):
    """A refinement 'stalled' unless it halved the estimate; fd2 refined by 1.5 falls 2.25x in the
    asymptotic range and 1.97x before it: ``contin trace stretched-bratu -s a=4 --method fd2
    --tol 1e-4`` ended MX at its start (0.079 on fd2 8, 0.04 on 12).  On finite-order grids the
    fall asked for is the square root of the expected one where that is weaker than a half; the run
    now reaches its fold (EP, the states above tol warned)."""
    from contin.adapt import stall_fraction

    assert stall_fraction(StretchedBratu("fd2", 12), 8) == pytest.approx(2 / 3)
    assert stall_fraction(StretchedBratu("fd4", 12), 8) == 0.5
    assert stall_fraction(StretchedBratu("cheb", 12), 8) == 0.5
    r, out = _run(tmp_path, "stretched-bratu", "-s", "a=4", "--method", "fd2", "--tol", "1e-4")
    assert r.exit_code == 0, r.output
    from contin import io

    (b,), _ = io.load(out)
    (lp,) = b.fold_points
    assert lp.params["lam"] == pytest.approx(BRATU_FOLD / 5, rel=1e-4)



def test_an_fd_branch_that_missed_its_bps_on_a_coarse_grid_is_retraced(tmp_path):
    """Uniform shear is exact on every grid, so ``contin trace savage-rheology --method fd2 --tol
    1e-4`` coarsened the dense band's branch to fd2 8, whose spectrum has no crossing in H =
    8.55 .. 42.77, and located neither H_1^c = 17.108 nor H_2^c = 34.217 (closed form), exit 0
    with the note 'BPs located at none'.  At the end of an FD branch the LP/BP test functions of
    its first and last points on the check grid are compared with the points located; the band
    disagreed on fd2 16 and is retraced with min_grid 16: both BPs are found (within 1e-3 of the
    closed form on fd2 512, each with its 'position not resolved' warning) and the banded
    branches are traced."""
    from contin import io

    r, out = _run(tmp_path, "savage-rheology", "--method", "fd2", "--tol", "1e-4")
    assert r.exit_code == 0, r.output
    branches, meta = io.load(out)
    band = next(b for b in branches if b.id == "band")
    assert band.audit[0].startswith("retraced with min_grid 16")
    hcs = meta["extra"]["band"]["H_c"]
    found = [bp.params["H"] for bp in band.branch_points]
    assert len(found) == 2 and all(abs(f - h) / h < 1e-3 for f, h in zip(found, hcs))
    assert {"band.n1.1", "band.n1.2"} <= {b.id for b in branches}


def test_an_unconverged_location_is_a_warning():
    """A special point whose location did not converge said so in the summary table's note only
    (savage-rheology's symmetric BP4 on cheb 32, 3.0e-10 off a cheb 96 solve at special_tol 1e-10)."""
    from types import SimpleNamespace

    from contin.cli.trace import doubtful_special_points

    bp = SimpleNamespace(name="BP4", params={"H": 34.2168388523}, note="symmetric; location did not converge")
    (line,) = doubtful_special_points(SimpleNamespace(parameter="H", special_points=[bp]))
    assert line.startswith("BP4 at H=34.21683885: location did not converge")
