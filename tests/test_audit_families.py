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
