"""Issue-5 figures (gravity): Phi vs H at several Fr, isola profiles, growth rates.

Usage: python results/gravity/make_figures.py [panels|profiles|growth|others|nu0.5|nu0.16|nu0.15] (default: all)

Each panel set also writes its numbers (branches, kinds, folds, routes, stops) to a JSON file
next to the PNG.
"""

from __future__ import annotations

import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from contin.plot import save_figure
from problems.couette.gravity import (
    GravitySettings,
    discover,
    gravity_free_branches,
    gravity_problem,
)

OUT = "results/gravity"
#: Chebyshev grid of the figures: N = 32 under-resolves the dense plugs (nu -> 0.65) from H ~ 30
GRID = 64
STYLE = {"primary": "k", "isola": "tab:red", "floating-plug": "tab:blue", "bottom-plug": "tab:green"}


def _summary(b) -> dict:
    """Numbers of one branch for the panel JSON files (what results/README.md quotes)."""
    H = b.params["H"]
    return {"id": b.id, "kind": b.kind, "closed": bool(b.closed), "status": b.status, "message": b.message,
            "H": [float(H.min()), float(H.max())],
            "phi": [float(b.observables["phi"].min()), float(b.observables["phi"].max())],
            "folds": [{"H": float(lp.params["H"]), "phi": float(lp.order_parameter)} for lp in b.fold_points]}


def panels(nu: float, frs: list[float], name: str, H_max: float = 70.0, N: int = GRID) -> None:
    """Phi(H) at each Fr (both discovery routes); crosses mark MX stops (under-resolved plugs)."""
    pb = gravity_problem("cheb", N)
    st = GravitySettings(H_range=(1.0, H_max))
    p0 = pb.params({"nu": nu, "e": 0.8})
    base, g0 = gravity_free_branches(pb, p0, st)
    ncol = (len(frs) + 1) // 2
    fig, axes = plt.subplots(2, ncol, figsize=(3.2 * ncol, 6), sharex=True, sharey=True)
    doc: dict = {"nu": nu, "e": 0.8, "grid": N, "H_max": H_max, "panels": {}}
    for ax, fr in zip(axes.flat, frs):
        if np.isinf(fr):
            rows = []
            for b in [base] + g0:
                ax.plot(b.params["H"], b.observables["phi"], "k-", lw=1)
                for lp in b.fold_points:
                    ax.plot(lp.params["H"], lp.order_parameter, "ko", ms=3)
                rows.append({**_summary(b), "kind": "G = 0",
                             "branch_points": [float(bp.params["H"]) for bp in b.branch_points]})
            # BPs of uniform shear only: the BPs found on the banded branches near packing are the
            # grid's spurious branch (problems.couette.pitchfork docstring), listed in the JSON
            for bp in base.branch_points:
                ax.plot(bp.params["H"], bp.order_parameter, "ks", ms=3)
            doc["panels"]["inf"] = rows
        else:
            d = discover(pb, pb.params({"nu": nu, "e": 0.8, "Fr": fr}), st, g0_branches=g0, base=base)
            for b in d.branches:
                ax.plot(b.params["H"], b.observables["phi"], "-", color=STYLE[b.kind], lw=1, label=b.kind)
                for lp in b.fold_points:
                    ax.plot(lp.params["H"], lp.order_parameter, "o", color=STYLE[b.kind], ms=3)
                for mx in b.points("MX"):
                    ax.plot(mx.params["H"], mx.order_parameter, "x", color=STYLE[b.kind], ms=4)
            doc["panels"][f"{fr:g}"] = [{**_summary(b), "found_by": d.found_by[b.id]} for b in d.branches]
            doc["panels"][f"{fr:g}"].append({"duplicates": d.duplicates})
        ax.set_title(f"Fr = {fr:g}")
        ax.axhline(nu, color="0.8", lw=0.5)
    handles = {l: h for a in axes.flat for h, l in zip(*a.get_legend_handles_labels())}
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=4, fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("H")
    for ax in axes[:, 0]:
        ax.set_ylabel("Phi = nu(1/2)")
    fig.suptitle(f"nu = {nu:g}, e = 0.8, no-slip walls, cheb N = {N} (o fold, x under-resolved stop)")
    save_figure(fig, f"{OUT}/{name}.png")
    plt.close(fig)
    with open(f"{OUT}/{name}.json", "w") as fh:
        json.dump(doc, fh, indent=1)


def profiles() -> None:
    """Profiles at six points around the isola at Fr = 1000 (nu = 0.3; the third pitchfork's)."""
    pb = gravity_problem("cheb", GRID)
    st = GravitySettings(H_range=(35.0, 70.0), seed_H=(44.0,))
    p0 = pb.params({"nu": 0.3, "e": 0.8})
    _, g0 = gravity_free_branches(pb, p0, GravitySettings(H_range=(1.0, 70.0)))
    mode3 = [b for b in g0 if b.id.startswith("g0.3.")]
    d = discover(pb, pb.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0}), st, g0_branches=mode3, routes=("homotopy",))
    fig, axes = plt.subplots(1, 3, figsize=(10, 3.5))
    rows = []
    for b in d.of_kind("isola"):
        for i in np.linspace(0, len(b) - 1, 7).astype(int)[:-1]:
            x = b.state(i)
            pr = pb.profiles(x)
            lab = f"H={b.params['H'][i]:.1f} Phi={b.observables['phi'][i]:.2f}"
            rows.append({"H": float(b.params["H"][i]), "phi": float(b.observables["phi"][i]),
                         "nu_bottom": float(b.observables["nu_bottom"][i]), "T_min": float(np.min(pr["T"])),
                         "T_bottom": float(pr["T"][0]), "T_top": float(pr["T"][-1])})
            for ax, k in zip(axes, ("nu", "u", "T")):
                ax.plot(pr[k], pb.grid.y, label=lab if k == "nu" else None)
        break
    for ax, k in zip(axes, ("nu", "u", "T")):
        ax.set_xlabel(k)
        ax.set_ylabel("y")
    axes[0].legend(fontsize=6)
    fig.suptitle(f"profiles on the isola at nu = 0.3, e = 0.8, Fr = 1000 (cheb {GRID})")
    save_figure(fig, f"{OUT}/isola_profiles.png")
    plt.close(fig)
    with open(f"{OUT}/isola_profiles.json", "w") as fh:
        json.dump(rows, fh, indent=1)


def growth() -> None:
    from problems.couette.linear import growth_rate_curve

    pb = gravity_problem("cheb", 32)
    st = GravitySettings(H_range=(1.0, 50.0))
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0})
    d = discover(pb, p, st, routes=("homotopy",))
    kx = np.concatenate([[0.0], np.logspace(-2, 0.5, 25)])
    fig, ax = plt.subplots(figsize=(6, 4.5))
    rows = []
    for b in d.branches:
        Hs = b.params["H"]
        for i in np.nonzero(np.abs(np.diff(np.sign(Hs - 25.0))) > 0)[0]:
            x = b.state(int(i))
            nu, u, T, _, _ = pb.unpack(x)
            q = {**p, "H": float(Hs[i])}
            side = "floating plug" if b.observables["nu_top"][i] > b.observables["nu_bottom"][i] else "bottom plug"
            _, g, _ = growth_rate_curve(pb.grid, nu, u, T, q, kx, gravity=True)
            lab = f"{side}, branch {b.id} ({b.kind}), H={Hs[i]:.2f}, Phi={b.observables['phi'][i]:.3f}"
            ax.plot(kx, g, "o-", ms=2, label=lab)
            rows.append({"label": lab, "H": float(Hs[i]), "phi": float(b.observables["phi"][i]),
                         "kx": kx.tolist(), "growth": g.tolist()})
    # the growth rates span ~1e-4 .. 40 (a near-packing state is violently unstable): symlog y
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set_xscale("symlog", linthresh=1e-2)
    ax.set_xlim(0, kx[-1])
    ax.set_xlabel("k_x")
    ax.set_ylabel("max Re omega")
    ax.set_title("nu = 0.3, e = 0.8, Fr = 1000, H ~ 25")
    ax.legend(fontsize=6)
    save_figure(fig, f"{OUT}/growth_H25.png")
    with open(f"{OUT}/growth_H25.json", "w") as fh:
        json.dump(rows, fh, indent=1)
    plt.close(fig)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "all"
    if what in ("panels", "all"):
        panels(0.3, [np.inf, 2000, 1000, 922, 750, 400, 300, 250], "phi_vs_H_nu0.3")
    if what in ("profiles", "all"):
        profiles()
    if what in ("growth", "all"):
        growth()
    if what in ("others", "nu0.5", "all"):
        panels(0.5, [np.inf, 1000, 500, 300], "phi_vs_H_nu0.5")
    if what in ("others", "nu0.16", "all"):
        panels(0.16, [np.inf, 5000, 2500, 2350], "phi_vs_H_nu0.16", H_max=80.0)
    if what in ("others", "nu0.15", "all"):
        panels(0.15, [np.inf, 10000, 5000, 4000], "phi_vs_H_nu0.15", H_max=80.0)
