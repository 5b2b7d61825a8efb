"""The contin side of the AUTO-07p peer jobs, one job per process:
``python -m benchmarks.auto_peer.contin_jobs JOB`` prints one JSON line (points, special points).

Jobs (cheb 64, numba engine where installed, as ``contin trace`` picks it; e = 0.8):
  a  uniform shear at nu = 0.3 from H = H_max/20 to H_max = 3.3 H_1^c (43.13) with BP detection
  c  nu = 0.16: uniform shear in H from 30 to 70 (BP at H_1^c = 63.503), switch at the BP and
     follow one sign of the n = 1 branch through its fold (H = 41.9625323) back to H = 70
  d  gravity: the (H, G) fold curve of the first (symmetry-breaking) pitchfork at nu = 0.3 for
     1 <= H <= 30 and its maximum of G, Fr* = G_max^-1/2 = 254.12
     (problems.couette.gravity.pitchfork_fold_curves, as ``contin unfold`` computes it)
Job b (the main job) is the command line itself: ``contin trace pitchfork -s nu=0.3 -s e=0.8``.
"""

from __future__ import annotations

import json
import sys

NU, E = 0.3, 0.8
H_MAX = 43.126146774024086  # 3.3 H_1^c at nu = 0.3, e = 0.8 (the pitchfork scene's default H_max)


def _engine() -> str:
    from problems.couette.compiled import available

    return "numba" if available() else "numpy"


def _options(lo: float, hi: float, ds: float, ds_max: float):
    from contin.options import ContinuationOptions, DetectionOptions, StepOptions

    # the pitchfork scene's step control (problems/couette/scenes.py, _options)
    return ContinuationOptions(bounds={"H": (lo, hi)}, max_steps=200,
                               step=StepOptions(ds=ds, ds_max=ds_max, ds_min=1e-7, newton_target=6, grow=2.0),
                               detection=DetectionOptions(locate_tol=1e-9))


def job_a() -> dict:
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    pb = CouetteProblem("cheb", 64, engine=_engine())
    p = pb.params({"nu": NU, "e": E})
    base = pf.trace_base(pb, p, H_MAX / 20, _options(H_MAX / 20, H_MAX, 0.05 * H_MAX, 0.2 * H_MAX))
    return {"points": len(base), "BP": [b.params["H"] for b in base.branch_points]}


def job_c() -> dict:
    from contin.continuation import switch
    from problems.couette import pitchfork as pf
    from problems.couette.model import CouetteProblem

    pb = CouetteProblem("cheb", 64, engine=_engine())
    p = pb.params({"nu": 0.16, "e": E})
    base = pf.trace_base(pb, p, 30.0, _options(30.0, 70.0, 2.0, 8.0))
    bp = base.branch_points[0]
    band = switch(pb, base, bp, _options(30.0, 70.0, 0.02, 4.3), directions=(+1,))[0]
    return {"points": len(base) + len(band), "BP": [bp.params["H"]],
            "LP": [lp.params["H"] for lp in band.fold_points]}


def job_d() -> dict:
    from problems.couette.gravity import GravitySettings, extrema, gravity_free_branches, gravity_problem, pitchfork_fold_curves

    pb = gravity_problem("cheb", 64, engine=_engine())
    p = pb.params({"nu": NU, "e": E, "G": 0.0})
    settings = GravitySettings(H_range=(1.0, 30.0), modes=1)
    base, kids = gravity_free_branches(pb, p, settings)
    curves = pitchfork_fold_curves(pb, p, base, kids, H_range=(1.0, 30.0))
    first = [r for r in extrema(curves) if r["curve"] == "fold0" and r["extremum"] == "max"]
    return {"points": len(base) + sum(len(k) for k in kids) + sum(len(c) for c in curves),
            "Fr*": min(r["Fr"] for r in first) if first else float("nan"),
            "H(Fr*)": min(first, key=lambda r: r["Fr"])["H"] if first else float("nan")}


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    from contin.blas import limit_blas_threads

    limit_blas_threads()  # as the CLI does
    job = {"a": job_a, "c": job_c, "d": job_d}[args[0]]
    print(json.dumps(job()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
