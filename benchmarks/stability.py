"""The k_x = 0 stability pass per state, former path against the current one:
``python -m benchmarks.stability [--grid 64] [--repeats 3]``.

Traces the main job (scene ``pitchfork``, nu = 0.3, e = 0.8, no stability) and then, on every
state of its branches (the mirror images included, which the scene itself copies), times

- old: the sparse assembly and Schur elimination as they were
  (``benchmarks/reference_sparse_stability.py``);
- new: ``pitchfork.StabilityOperator.spectrum`` (dense assembly with cached grid operators,
  constrained Schur form, S-even/S-odd split on symmetric states).

Prints CPU ms per state (best of ``--repeats``), the ratio (target new <= old / 3), the
largest difference of the six leading eigenvalues (relative to max(1, |omega|)) and the number
of states whose unstable counts differ (must be 0).  A measurement, not a test
(tests/test_couette_linear_dense.py asserts the numbers).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def states(grid: int):
    from contin.blas import limit_blas_threads
    from contin.scene import SceneRequest, get_scene

    limit_blas_threads()
    req = SceneRequest(params={"nu": 0.3, "e": 0.8}, grid=grid, stability=False)
    res = get_scene("pitchfork").run(req)
    from problems.couette.model import CouetteProblem

    pb = CouetteProblem("cheb", grid)
    out = []
    for b in res.branches:
        for i in range(len(b)):
            p = {**res.parameters, **{k: float(v[i]) for k, v in b.params.items()}}
            p = {k: v for k, v in p.items() if isinstance(v, int | float)}
            out.append((b.id, b.state(i), p))
    return pb, out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.stability", description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    from benchmarks.reference_sparse_stability import reference_k0_eigenvalues
    from contin.stability import count_unstable
    from problems.couette import pitchfork as pf

    pb, sts = states(args.grid)
    op = pf.StabilityOperator(pb)

    def old(x, p):
        nu, u, T, _, _ = pb.unpack(x)
        return reference_k0_eigenvalues(pb.grid, nu, u, T, p)

    def new(x, p):
        return op.spectrum(x, p)

    best = {}
    results = {}
    for name, fn in (("old", old), ("new", new)):
        times = []
        for _ in range(args.repeats):
            t = time.process_time()
            results[name] = [fn(x, p) for _, x, p in sts]
            times.append(time.process_time() - t)
        best[name] = min(times) / len(sts)
    worst = 0.0
    counts = 0
    for w0, w1 in zip(results["old"], results["new"]):
        a, b = w1[:6], w0
        worst = max(worst, float(np.max(np.min(np.abs(a[:, None] - b[None, :]), axis=1) / np.maximum(1.0, np.abs(a)))))
        counts += count_unstable(w0) != count_unstable(w1)
    ratio = best["new"] / best["old"]
    print(f"k_x = 0 stability, cheb {args.grid}, {len(sts)} states of the main job (CPU, best of {args.repeats})")
    print(f"  former path  {1e3 * best['old']:7.2f} ms/state")
    print(f"  current      {1e3 * best['new']:7.2f} ms/state   ratio {ratio:.3f} "
          f"(target <= 1/3: {'met' if ratio <= 1 / 3 else 'NOT met'})")
    print(f"  leading 6 eigenvalues: max difference {worst:.1e}; states with different unstable counts: {counts}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
