"""Issue-5 figures (gravity): Phi vs H at several Fr, isola profiles, growth rates.

Usage: python results/gravity/make_figures.py [panels|profiles|growth|others|nu0.5|nu0.16|nu0.15] (default: all)
       python results/gravity/make_figures.py growth-figure   (redraws growth_H25.png from growth_H25.json)
       python results/gravity/make_figures.py phase FILE.h5   (phase_diagram_nu0.3.png from a gravity-phase run)

Each panel set also writes its numbers (branches, kinds, folds, routes, stops) to a JSON file
next to the PNG.
"""

from __future__ import annotations

import itertools
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from contin.plot import save_figure
from contin.stability import eigenvalues
from problems.couette.gravity import (
    GravitySettings,
    discover,
    gravity_free_branches,
    gravity_problem,
)
from problems.couette.linear import growth_rate_curve, linear_operator

OUT = "results/gravity"
#: Chebyshev grid of the figures: N = 32 under-resolves the dense plugs (nu -> 0.65) from H ~ 30
GRID = 64
STYLE = {"primary": "k", "isola": "tab:red", "floating-plug": "tab:blue", "bottom-plug": "tab:green"}


def _summary(b) -> dict:
    """Numbers of one branch for the panel JSON files (what results/README.md quotes)."""
    H = b.params["H"]
    if len(b) == 0:  # a branch that could not start (its message says why): listed, nothing to draw
        return {"id": b.id, "kind": b.kind, "closed": False, "status": b.status, "message": b.message,
                "H": [], "phi": [], "folds": []}
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
                if len(b) == 0:  # could not start (in the JSON with its reason); KeyError 'phi' before
                    print(f"warning: nu = {nu:g}, Fr = {fr:g}: branch {b.id} could not start: {b.message}",
                          file=sys.stderr)
                    continue
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


#: Growth-rate figure (issue 5): gap, grid and Froude numbers.  cheb 48 resolves every state of
#: the figure (estimated relative errors in growth_H25.json); w2 and the largest growth rate are
#: recomputed at cheb 64 there as a check.
GROWTH_H = 25.0
GROWTH_GRID = 48
GROWTH_CHECK_GRID = 64
#: bottom-plug curves: the slides' Fr = 1000 and stronger gravity through the sign change of w2 (~166)
BOTTOM_FR = (1000.0, 300.0, 200.0, 150.0, 120.0)
#: floating-plug curves: Fr = 1000 and just above its fold in G at H = 25 (Fr = 288.8)
FLOATING_FR = (1000.0, 300.0)
#: fold in G of the floating plug at H = 25 (tests/test_linear_gravity.py, test_fold_in_G_is_neutral_at_kx0)
FLOATING_FOLD_FR = 288.76
#: Fr sampled for w2(Fr) (descending: each state is continued in G from the previous one).  The
#: bottom plug's densest point nears packing as Fr falls (nu_m - nu = 7e-4 at Fr = 120); cheb 48
#: resolves it down to Fr = 120 (error 1.6e-5 < 3e-5), not at 110 (the homotopy stops with MX)
W2_FR_BOTTOM = (1000.0, 700.0, 500.0, 400.0, 300.0, 250.0, 200.0, 180.0, 170.0, 165.0, 160.0, 150.0,
                140.0, 130.0, 120.0)
W2_FR_FLOATING = (1000.0, 700.0, 500.0, 400.0, 350.0, 320.0, 300.0, 295.0, 291.0)
#: long-wave probe: Re omega = w2 kx^2 + O(kx^4) (Re omega is even in kx), so w2 = Re omega(K)/K^2
#: with K = W2_K, divided by 4 while Re omega(2K)/Re omega(K) is not 4 to 1 % (near the floating
#: plug's fold in G the slowest k_x = 0 mode -> 0 and the asymptotic range shrinks like it)
W2_K = 1e-4
GROWTH_KX = np.logspace(-4, 0.5, 46)


def _leading(pb, x, p, kx: float) -> complex:
    """Least-stable eigenvalue (dense QZ, all finite eigenvalues) at wavenumber kx, k_z = 0."""
    A, B = linear_operator(pb.grid, *_profiles(pb, x), p, kx=kx)
    return complex(eigenvalues(A, B, k=1, dense_max=A.shape[0])[0])


def _w2(pb, x, p) -> tuple[float, float, float]:
    """(w2, K, Re omega(2K) / Re omega(K)) of the long-wave (mass) mode (see W2_K)."""
    K = W2_K
    while True:
        a, b = _leading(pb, x, p, K).real, _leading(pb, x, p, 2 * K).real
        if abs(b / a - 4.0) < 0.04 or K < 1e-6:
            return a / K**2, K, b / a
        K /= 4.0


def _at_H(pb, b, p, H: float) -> list:
    """States of branch b at gap H exactly: Newton at H from the stored point nearest each crossing."""
    from contin.newton import newton
    from contin.options import NewtonOptions

    Hs = b.params["H"]
    out = []
    for i in np.nonzero(np.diff(np.sign(Hs - H)) != 0)[0]:
        j = int(i) if abs(Hs[i] - H) < abs(Hs[i + 1] - H) else int(i) + 1
        r = newton(pb, b.state(j), {**p, "H": H}, NewtonOptions())
        if r.converged:
            out.append(r.u)
    return out


def _regrid(pb, x, p, N: int):
    """State x re-solved on cheb N (interpolated start); None if Newton fails."""
    from contin.newton import newton
    from contin.options import NewtonOptions

    pb2 = gravity_problem("cheb", N)
    nu, u, T, P, _ = pb.unpack(x)
    r = newton(pb2, pb2.pack(*(pb.grid.interpolate(f, pb2.grid.y) for f in (nu, u, T)), P), p, NewtonOptions())
    return (pb2, r.u) if r.converged else (pb2, None)


def growth() -> None:
    """Growth rate max Re omega(k_x) (k_z = 0) of the states at H = 25 (nu = 0.3, e = 0.8): the
    floating plug and the middle (saddle) sheet at Fr = 1000, the floating plug at Fr = 300, the
    bottom plug at BOTTOM_FR; the long-wave coefficient w2 = lim Re omega / k_x^2 of both plugs
    against Fr (problems.couette.linear docstring, "The long-wave limit"; tests/test_linear_gravity.py)."""
    from problems.couette.gravity import homotopy_in_G
    from problems.couette.resolution import resolution

    pb = gravity_problem("cheb", GROWTH_GRID)
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 1000.0})
    d = discover(pb, p, GravitySettings(H_range=(1.0, GROWTH_H + 5.0), modes=1), routes=("homotopy",))
    q1000 = {**p, "H": GROWTH_H}
    start: dict[str, np.ndarray] = {}
    for b in d.branches:
        for x in _at_H(pb, b, p, GROWTH_H):
            nu = pb.unpack(x)[0]
            if nu[0] > nu[-1] + 0.1:
                start["bottom"] = x
            elif nu[-1] > nu[0] + 0.1:
                start["floating"] = x
            else:
                start["middle"] = x  # the near-uniform middle sheet of the imperfect pitchfork
    assert set(start) == {"bottom", "floating", "middle"}, f"states at H = {GROWTH_H}: {sorted(start)}"

    kx = GROWTH_KX
    doc: dict = {"nu": 0.3, "e": 0.8, "H": GROWTH_H, "kz": 0.0, "grid": GROWTH_GRID,
                 "check_grid": GROWTH_CHECK_GRID, "w2_probe_kx": W2_K, "curves": [], "w2": {}}

    def curve(side: str, fr: float, x) -> None:
        q = {**q1000, "G": fr**-2}
        g0 = _leading(pb, x, q, 0.0).real
        _, g, c = growth_rate_curve(pb.grid, *_profiles(pb, x), q, kx, gravity=True)
        # the middle sheet's least-stable mode is its k_x = 0 instability, not the mass mode: no w2
        w2, K, ratio = _w2(pb, x, q) if side != "middle" else (None, None, None)
        res = resolution(pb, x, q)
        row = {"side": side, "Fr": fr, "phi": float(pb.unpack(x)[0][-1]), "nu_bottom": float(pb.unpack(x)[0][0]),
               "resolution_error": res.error, "growth_kx0": g0, "w2": w2, "w2_kx": K, "w2_ratio_2k": ratio,
               "kx": kx.tolist(), "growth": g.tolist(), "phase_speed": c.tolist(),
               "max_growth": float(g.max()), "kx_of_max": float(kx[np.argmax(g)])}
        pb2, x2 = _regrid(pb, x, q, GROWTH_CHECK_GRID)
        if x2 is not None:  # every third k_x of the curve, to keep the check cheap
            _, g2, _ = growth_rate_curve(pb2.grid, *_profiles(pb2, x2), q, kx[::3], gravity=True)
            row["check"] = {"w2": _w2(pb2, x2, q)[0] if side != "middle" else None,
                            "growth_kx0": _leading(pb2, x2, q, 0.0).real,
                            "max_growth_every_third_kx": float(g2.max()),
                            "max_growth_same_kx": float(g[::3].max())}
        doc["curves"].append(row)

    curve("middle", 1000.0, start["middle"])
    for side, frs_w2, frs_curve in (("floating", W2_FR_FLOATING, FLOATING_FR), ("bottom", W2_FR_BOTTOM, BOTTOM_FR)):
        x, G = start[side], 1e-6
        rows = []
        for fr in frs_w2:
            if fr**-2 != G:
                x = homotopy_in_G(pb, x, {**q1000, "G": G}, fr**-2, max_steps=300)
                assert x is not None, f"{side} plug at H = {GROWTH_H} lost before Fr = {fr:g}"
                G = fr**-2
            w2, K, ratio = _w2(pb, x, {**q1000, "G": G})
            rows.append({"Fr": fr, "w2": w2, "kx": K, "ratio_2k": ratio,
                         "growth_kx0": _leading(pb, x, {**q1000, "G": G}, 0.0).real})
            if fr in frs_curve:
                curve(side, fr, x)
        doc["w2"][side] = rows
    # sign change of the bottom plug's w2, linear in Fr between the bracketing samples
    rows = doc["w2"]["bottom"]
    for a, b in itertools.pairwise(rows):
        if a["w2"] > 0 >= b["w2"]:
            doc["w2_sign_change_Fr"] = a["Fr"] + (b["Fr"] - a["Fr"]) * a["w2"] / (a["w2"] - b["w2"])
    with open(f"{OUT}/growth_H25.json", "w") as fh:
        json.dump(doc, fh, indent=1)
    growth_figure(doc)


def growth_figure(doc: dict | None = None) -> None:
    """The four panels of growth_H25.png from the numbers of :func:`growth` (default: read from
    growth_H25.json, so the figure can be redrawn without recomputing)."""
    if doc is None:
        with open(f"{OUT}/growth_H25.json") as fh:
            doc = json.load(fh)
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    ax_g, ax_w, ax_fr, ax_c = axes.flat
    greens = plt.cm.Greens(np.linspace(0.45, 1.0, len(BOTTOM_FR)))[::-1]
    colour = {("middle", 1000.0): "0.4", ("floating", 1000.0): "tab:blue", ("floating", 300.0): "tab:purple",
              **{("bottom", fr): greens[i] for i, fr in enumerate(BOTTOM_FR)}}
    x0 = 5e-5  # where the k_x = 0 (mass-constrained) values are drawn
    for r in doc["curves"]:
        kx = np.array(r["kx"])
        col = colour[(r["side"], r["Fr"])]
        name = {"middle": "middle sheet"}.get(r["side"], r["side"] + " plug")
        lab = f"{name}, Fr = {r['Fr']:g} (Phi = {r['phi']:.3f})"
        ls = ":" if r["side"] == "middle" else ("--" if r["side"] == "floating" else "-")
        g = np.array(r["growth"])
        ax_g.plot(kx, g, ls, color=col, lw=1.2, label=lab)
        ax_g.plot(x0, r["growth_kx0"], "s", mfc="none", color=col, ms=4)
        if r["side"] != "middle":  # its growth is the k_x = 0 instability, Re omega / k_x^2 ~ 1/k_x^2
            ax_w.plot(kx, g / kx**2, ls, color=col, lw=1.2, label=lab)
        ax_c.plot(kx, r["phase_speed"], ls, color=col, lw=1.2, label=lab)
    ax_g.axvline(7e-5, color="0.7", lw=0.5)
    ax_g.set_xscale("log")
    ax_g.set_xticks([x0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0], ["0", "1e-4", "1e-3", "0.01", "0.1", "1"])
    # long-wave growth rates are 1e-9 .. 1e-4, the decay at k_x ~ 1 is ~0.1: symlog over both
    ax_g.set_yscale("symlog", linthresh=1e-9)
    ax_g.set_xlim(3.5e-5, kx[-1])
    ax_g.set_ylabel("max Re omega")
    ax_g.set_title("(a) growth rate (squares: k_x = 0, mass mode excluded)", fontsize=9)
    ax_w.set_xscale("log")
    ax_w.set_yscale("symlog", linthresh=1.0)
    ax_w.set_xlim(kx[0], 0.1)
    ax_w.set_ylabel("max Re omega / k_x^2")
    ax_w.set_title("(b) long waves: Re omega / k_x^2 -> w2 as k_x -> 0", fontsize=9)
    for side, col, mk in (("bottom", "tab:green", "o-"), ("floating", "tab:blue", "s--")):
        rows = doc["w2"][side]
        ax_fr.plot([r["Fr"] for r in rows], [r["w2"] for r in rows], mk, color=col, ms=3, lw=1, label=f"{side} plug")
    if "w2_sign_change_Fr" in doc:
        ax_fr.axvline(doc["w2_sign_change_Fr"], color="tab:green", lw=0.5, ls=":")
        ax_fr.annotate(f"w2 = 0 at Fr = {doc['w2_sign_change_Fr']:.1f}", (doc["w2_sign_change_Fr"], 0.0),
                       xytext=(8, 12), textcoords="offset points", fontsize=7)
    ax_fr.axvline(FLOATING_FOLD_FR, color="tab:blue", lw=0.5, ls=":")
    ax_fr.set_xscale("log")
    ax_fr.set_xticks([120, 150, 200, 300, 500, 1000], ["120", "150", "200", "300", "500", "1000"])
    ax_fr.minorticks_off()
    ax_fr.set_yscale("symlog", linthresh=1.0)
    ax_fr.set_xlabel("Fr")
    ax_fr.set_ylabel(f"w2 = Re omega / k_x^2 at k_x <= {W2_K:g}")
    ax_fr.set_title(f"(c) long-wave coefficient against Fr (floating plug dies at Fr = {FLOATING_FOLD_FR:g})",
                    fontsize=9)
    ax_fr.legend(fontsize=7)
    ax_c.set_xscale("log")
    ax_c.set_xlim(kx[0], kx[-1])
    ax_c.set_xlabel("k_x")
    ax_c.set_ylabel("phase speed c = Im omega / k_x")
    ax_c.set_title("(d) phase speed of the least-stable mode (walls at u = +-1/2; other modes lead at k_x > 1)",
                   fontsize=9)
    ax_g.set_xlabel("k_x")
    ax_w.set_xlabel("k_x")
    for ax in axes.flat:
        ax.axhline(0, color="0.5", lw=0.5)
    fig.suptitle(f"nu = 0.3, e = 0.8, H = {doc['H']:g}, k_z = 0, no-slip walls, cheb N = {doc['grid']}", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.legend(*ax_g.get_legend_handles_labels(), loc="lower center", ncol=4, fontsize=7)
    save_figure(fig, f"{OUT}/growth_H25.png")
    plt.close(fig)


def _profiles(pb, x):
    nu, u, T, _, _ = pb.unpack(x)
    return nu, u, T


def phase_figure(path: str, out: str = f"{OUT}/phase_diagram_nu0.3.png") -> None:
    """Fold curves in (H, Fr) of a ``contin trace gravity-phase`` file, births (^) and deaths (v)."""
    from contin import io

    curves, meta = io.load(path)
    p, extra = meta["parameters"], meta["extra"]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for c in curves:
        G = c.params["G"]
        Fr = np.where(G > 0, np.abs(G) ** -0.5, np.nan)
        ax.plot(c.params["H"], Fr, label=f"{c.id} ({c.parent})")
    for r in extra["births"] + extra["deaths"]:
        ax.plot(r["H"], r["Fr"], "v" if r["event"] == "death" else "^", color="k", ms=5)
    ax.set_yscale("log")
    ax.set_xlabel("H")
    ax.set_ylabel("Fr")
    ax.set_ylim(100, 1e4)
    ax.set_title(f"fold curves, nu={p['nu']:g}, e={p['e']:g} (^ birth, v death)")
    ax.legend(fontsize=7)
    save_figure(fig, out)
    plt.close(fig)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "all"
    if what == "phase":
        phase_figure(sys.argv[2])
    if what in ("panels", "all"):
        panels(0.3, [np.inf, 2000, 1000, 922, 750, 400, 300, 250], "phi_vs_H_nu0.3")
    if what in ("profiles", "all"):
        profiles()
    if what in ("growth", "all"):
        growth()
    if what == "growth-figure":
        growth_figure()
    if what in ("others", "nu0.5", "all"):
        panels(0.5, [np.inf, 1000, 500, 300], "phi_vs_H_nu0.5")
    if what in ("others", "nu0.16", "all"):
        panels(0.16, [np.inf, 5000, 2500, 2350], "phi_vs_H_nu0.16", H_max=80.0)
    if what in ("others", "nu0.15", "all"):
        panels(0.15, [np.inf, 10000, 5000, 4000], "phi_vs_H_nu0.15", H_max=80.0)
