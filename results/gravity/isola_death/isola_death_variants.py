"""Death Fr of the third-pitchfork isola and Fr* (floating-plug limit) for model variants.

Helper script for results/gravity/isola_death/isola_death.md (issue 5).  For one variant (grid, chi, nu_m, Dufour,
nu_bar, e) it runs problems.couette.gravity.phase_diagram -- the machinery of
``contin trace gravity-phase`` (formerly ``contin unfold``) -- on a CouetteProblem built with those switches and prints one JSON line:
the critical gaps, Fr* (largest G on the first pitchfork's fold curve) and every G-extremum
(birth/death) of the fold curves, resolved or not.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python results/gravity/isola_death/isola_death_variants.py --grid 64 --chi jj --num 0.65

Closure experiments (not options of the model; the script wraps closures.coefficients as seen by
problems.couette.model): ``--a1 --a2 --a4 --a5`` multiply f1, f2, f4, f5 (and their
nu-derivatives) by constants; ``--transport elastic`` evaluates f2, f4 at e = 1 (elastic
Chapman-Enskog transport coefficients, dissipation f5 unchanged); ``--f5 js83`` uses the older
Jenkins-Savage dissipation f5 = (24/sqrt(pi)) (1 - e) nu^2 chi.

Exact scaling (derived in results/gravity/isola_death/isola_death.md): with f_i -> a_i f_i the steady no-slip/zero-flux
problem at (H, G) is the original one at (H / h, G / g) with T scaled by a2/a5,
h = sqrt(a4/a5), g = a1 a2 sqrt(a5) / a4^(3/2): every critical Fr scales by g^(-1/2).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from problems.couette import closures, model
from problems.couette.gravity import phase_diagram
from problems.couette.model import CouetteProblem


def _with(c, **fields):
    """Copy of closures.Coefficients with some fields replaced (NamedTuple or dataclass)."""
    return c._replace(**fields) if hasattr(c, "_replace") else dataclasses.replace(c, **fields)


def patch_closures(a1: float = 1.0, a2: float = 1.0, a4: float = 1.0, a5: float = 1.0, transport: str = "lsjc",
                   f5: str = "lsjc") -> None:
    """Replace the closures seen by problems.couette.model (this process only)."""
    original = closures.coefficients

    def wrapped(nu, e, chi="jj", nu_max=0.65, dufour=False):
        c = original(nu, e, chi, nu_max, dufour)
        if transport == "elastic":
            el = original(nu, 1.0, chi, nu_max, dufour)
            c = _with(c, f2=el.f2, f2_nu=el.f2_nu, f4=el.f4, f4_nu=el.f4_nu)
        if f5 == "js83":
            k = 24.0 / np.sqrt(np.pi) * (1.0 - e)
            c = _with(c, f5=k * nu * nu * c.chi, f5_nu=k * (2.0 * nu * c.chi + nu * nu * c.chi_nu))
        return _with(c, f1=a1 * c.f1, f1_nu=a1 * c.f1_nu, f2=a2 * c.f2, f2_nu=a2 * c.f2_nu,
                       f4=a4 * c.f4, f4_nu=a4 * c.f4_nu, f5=a5 * c.f5, f5_nu=a5 * c.f5_nu)

    model.coefficients = wrapped
    # the residual's fast path for real states (no Dufour term) must see the same closures
    model.real_coefficients = lambda nu, e, chi="jj", nu_max=0.65: wrapped(nu, e, chi, nu_max, False)


def run(grid: int, chi: str, num: float, dufour: bool, nu: float, e: float, H_max: float, Fr_start: float,
        max_steps: int, closure: dict | None = None) -> dict:
    t0 = time.time()
    pb = CouetteProblem("cheb", grid, chi=chi, gravity=True, dufour=dufour)
    params = pb.params({"nu": nu, "e": e, "num": num})
    d = phase_diagram(pb, params, H_range=(1.0, H_max), Fr_start=Fr_start, max_steps=max_steps)
    rows = [{k: r[k] for k in ("curve", "event", "H", "Fr", "phi", "resolved")} for r in d.extrema + d.unresolved]
    return {"grid": grid, "chi": chi, "num": num, "dufour": dufour, "nu": nu, "e": e, "H_max": H_max,
            "closure": closure or {},
            "critical_gaps": d.critical_gaps, "fr_star": d.fr_min_floating_plug, "extrema": rows,
            "curves": [{"id": c.id, "from": c.parent, "status": c.status, "message": c.message} for c in d.curves],
            "seconds": round(time.time() - t0, 1)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", type=int, default=64)
    ap.add_argument("--chi", default="jj")
    ap.add_argument("--num", type=float, default=0.65)
    ap.add_argument("--dufour", action="store_true")
    ap.add_argument("--nu", type=float, default=0.3)
    ap.add_argument("--e", type=float, default=0.8)
    ap.add_argument("--H-max", type=float, default=70.0)
    ap.add_argument("--Fr-start", type=float, default=2000.0)
    ap.add_argument("--max-steps", type=int, default=300)
    ap.add_argument("--a1", type=float, default=1.0)
    ap.add_argument("--a2", type=float, default=1.0)
    ap.add_argument("--a4", type=float, default=1.0)
    ap.add_argument("--a5", type=float, default=1.0)
    ap.add_argument("--transport", choices=("lsjc", "elastic"), default="lsjc")
    ap.add_argument("--f5", choices=("lsjc", "js83"), default="lsjc")
    a = ap.parse_args()
    given = {"a1": a.a1, "a2": a.a2, "a4": a.a4, "a5": a.a5, "transport": a.transport, "f5": a.f5}
    closure = {k: v for k, v in given.items() if v not in (1.0, "lsjc")}
    if closure:
        patch_closures(a.a1, a.a2, a.a4, a.a5, a.transport, a.f5)
    print(json.dumps(run(a.grid, a.chi, a.num, a.dufour, a.nu, a.e, a.H_max, a.Fr_start, a.max_steps, closure)),
          flush=True)


if __name__ == "__main__":
    main()
