"""Every fold-pair event (G-extremum of a fold curve) of the diagrams at given Fr.

Helper script for results/gravity/isola_death/isola_death.md: which isola could die at the slides' Fr = 922?  At each
Fr the branches are found with problems.couette.gravity.discover (route 1, banded branches of the
first two pitchforks), then the fold curve through every fold of every closed branch is traced
in (H, G) (problems.couette.gravity.fold_curves) and its G-extrema (births/deaths of fold pairs:
isolas dying, loops splitting or merging) are printed as one JSON line.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python results/gravity/isola_death/isola_death_events.py --Fr 922 --grid 64
"""

from __future__ import annotations

import argparse
import json
import time

from problems.couette.gravity import (
    GravitySettings,
    discover,
    extrema,
    fold_curves,
    gravity_free_branches,
)
from problems.couette.model import CouetteProblem


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--Fr", type=float, default=922.0)
    ap.add_argument("--grid", type=int, default=64)
    ap.add_argument("--H-max", type=float, default=70.0)
    ap.add_argument("--modes", type=int, default=2)
    ap.add_argument("--seed-H", type=float, nargs="+", default=[16.0, 30.0])
    a = ap.parse_args()
    t0 = time.time()
    pb = CouetteProblem("cheb", a.grid, gravity=True)
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": a.Fr})
    st = GravitySettings(H_range=(1.0, a.H_max), seed_H=tuple(a.seed_H), modes=a.modes)
    _, kids = gravity_free_branches(pb, {**p, "G": 0.0}, st)
    d = discover(pb, p, st, g0_branches=kids, routes=("homotopy",))
    loops = [b for b in d.branches if b.closed]
    out = {"Fr": a.Fr, "grid": a.grid,
           "branches": [{"id": b.id, "kind": b.kind, "closed": b.closed,
                         "folds": sorted(round(s.params["H"], 4) for s in b.fold_points)} for b in d.branches]}
    curves = fold_curves(pb, loops, bounds={"H": (1.0, a.H_max)}, max_steps=300)
    out["curves"] = [{"id": c.id, "from": c.parent, "status": c.status, "message": c.message[:200],
                      "H": c.params["H"].tolist(), "G": c.params["G"].tolist(), "phi": c.observables["phi"].tolist()}
                     for c in curves]
    out["extrema"] = [{k: r[k] for k in ("curve", "event", "H", "Fr", "phi", "resolved")}
                      for r in extrema(curves, problem=pb)]
    out["seconds"] = round(time.time() - t0, 1)
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
