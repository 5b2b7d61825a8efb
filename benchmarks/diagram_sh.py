"""Automatic diagram against the hand-written recursion: ``python -m benchmarks.diagram_sh [--depth 3]``.

1-D Swift-Hohenberg (problems.swift_hohenberg; BifurcationKit's automatic-diagram tutorial),
lam in [-1, 1] from u = 0 at lam = -0.7, nu = 2, the same continuation options for both:

- *hand-written*: what a user writes without contin.diagram -- trace the start branch both ways,
  switch at every BP in both directions, recurse into every new branch up to ``depth``
  (BifurcationKit's level: 1 = the start branch only);
- *contin.diagram.bifurcation_diagram* with the same depth (module docstring of contin.diagram:
  mirrored images, probed BP directions, skipped known crossings).

Prints the branch counts, wall-clock and CPU seconds of each and the ratio hand-written /
diagram (the acceptance asks for >= 4 at depth 3), and how many of the hand-written branches
duplicate another (a point-by-point test on the full states, independent of the diagram's own
coordinates).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from contin.blas import limit_blas_threads
from contin.branch import Branch
from contin.continuation import trace_both
from contin.options import ContinuationOptions, StepOptions

START = {"lam": -0.7, "nu": 2.0}


def options() -> ContinuationOptions:
    """ds_max = 0.02: at 0.05 the pair of BPs of u = 0 at lam = 0.484 and 0.531 falls in one step."""
    return ContinuationOptions(bounds={"lam": (-1.0, 1.0)}, max_steps=1000,
                               step=StepOptions(ds=0.01, ds_max=0.02, max_angle=0.3))


def hand_written(problem: Any, depth: int, opts: ContinuationOptions) -> list[Branch]:
    """The recursion a user writes by hand: every BP, both directions, every new branch."""
    from contin.continuation import switch

    root = trace_both(problem, np.zeros(problem.N), START, "lam", opts, branch_id="0")
    out = [root]

    def recurse(b: Branch, level: int) -> None:
        if level >= depth:
            return
        for bp in b.branch_points:
            try:
                kids = switch(problem, b, bp, opts, branch_id_prefix=f"{b.id}.{len(out)}")
            except ValueError:
                continue
            for k in kids:
                out.append(k)
                recurse(k, level + 1)

    recurse(root, 1)
    return out


def _distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of every point to the polyline ``line`` (8 points at a time: bounded memory)."""
    if len(line) == 1:
        return np.linalg.norm(points - line[0], axis=1)
    a, d = line[:-1], np.diff(line, axis=0)
    dd = np.maximum(np.sum(d * d, axis=1), 1e-300)
    out = []
    for c in range(0, len(points), 8):
        p = points[c: c + 8]
        t = np.clip(np.einsum("psk,sk->ps", p[:, None, :] - a[None], d) / dd, 0.0, 1.0)
        out.append(np.min(np.linalg.norm(p[:, None, :] - a[None] - t[..., None] * d[None], axis=2), axis=1))
    return np.concatenate(out)


def _on(a: np.ndarray, b: np.ndarray, tol: float, fraction: float) -> bool:
    """>= fraction of the points a within tol of the polyline b; 20 evenly spread points first
    (more than 3 of them off means no), then all."""
    probe = a[np.linspace(0, len(a) - 1, min(20, len(a))).astype(int)]
    if np.sum(_distance(probe, b) > tol) > 3:
        return False
    return bool(np.mean(_distance(a, b) <= tol) >= fraction)


def duplicates(branches: list[Branch], tol: float = 1e-3, fraction: float = 0.9) -> int:
    """Branches of which >= fraction of the points lie within tol of the polyline of another
    branch kept before (longest first), in (u / sqrt(n), lam) on the full states."""

    def pts(b: Branch) -> np.ndarray:
        return np.column_stack([b.states / np.sqrt(b.states.shape[1]), b.params["lam"]])

    order = sorted(branches, key=lambda b: -float(np.sum(b.ds)))
    kept: list[Branch] = []
    dup = 0
    for b in order:
        if any(_on(pts(b), pts(k), tol, fraction) for k in kept):
            dup += 1
        else:
            kept.append(b)
    return dup


def main() -> None:
    from contin.diagram import DiagramSettings, bifurcation_diagram
    from problems.swift_hohenberg import SwiftHohenberg

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depth", type=int, default=3)
    ap.add_argument("--N", type=int, default=200)
    args = ap.parse_args()
    limit_blas_threads()
    pb = SwiftHohenberg(args.N)
    opts = options()
    t0, c0 = time.perf_counter(), time.process_time()
    d = bifurcation_diagram(pb, np.zeros(pb.N), START, "lam", opts, DiagramSettings(depth=args.depth))
    t_auto, c_auto = time.perf_counter() - t0, time.process_time() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    hand = hand_written(pb, args.depth, opts)
    t_hand, c_hand = time.perf_counter() - t0, time.process_time() - c0
    print(f"Swift-Hohenberg 1-D, N = {pb.N}, depth {args.depth}")
    print(f"{'':16}{'branches':>10}{'traced':>8}{'duplicates':>12}{'wall s':>9}{'cpu s':>9}")
    print(f"{'hand-written':16}{len(hand):>10}{len(hand):>8}{duplicates(hand):>12}{t_hand:>9.1f}{c_hand:>9.1f}")
    print(f"{'diagram':16}{len(d.branches):>10}{len(d.traced):>8}{duplicates(d.branches):>12}{t_auto:>9.1f}{c_auto:>9.1f}")
    print(f"ratio hand-written / diagram: wall {t_hand / t_auto:.2f}, cpu {c_hand / c_auto:.2f}")


if __name__ == "__main__":
    main()
