"""Figures of the two criticality sweeps (run from the repository root after the sweeps):

    contin sweep results/sweeps/threshold_tricritical.toml -o results/sweeps/threshold_tricritical -j 2
    contin sweep results/sweeps/critical_gap.toml -o results/sweeps/critical_gap -j 2
    python results/sweeps/plot_criticality.py [--threshold DIR] [--gap DIR] [--out DIR]

Writes
- ``threshold_tricritical.png``: nu_th(e) (threshold of linear instability of uniform shear) and
  nu_tc(e) (tricritical density; normal form and fold curve), with the difference of the two
  nu_tc routes in a second panel;
- ``critical_gap.png``: filled contours of H_1^c(nu, e) = pi psi from the sweep, the grid points
  marked by the outcome of the continuation check, and the nu_th(e), nu_tc(e) curves overlaid.

The smooth nu_th(e) line is the analytic root of the bracket of psi
(:func:`problems.couette.criticality.threshold_density`) on a fine e grid; everything else
comes from the sweeps' ``summary.json``.  Exits with one error line if a summary is missing
or a task failed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402

from contin.plot import save_figure  # noqa: E402
from problems.couette.criticality import threshold_density  # noqa: E402

HERE = Path(__file__).resolve().parent


def _tasks(directory: Path) -> list[dict]:
    path = directory / "summary.json"
    if not path.is_file():
        raise SystemExit(f"Error: {path} is missing; run the sweep first (see {Path(__file__).name})")
    doc = json.loads(path.read_text())
    bad = [t for t in doc["tasks"] if t["status"] != "ok"]
    if bad:
        raise SystemExit(f"Error: {len(bad)} task(s) of {directory} did not finish ok, e.g. {bad[0]['params']}: "
                         f"{bad[0]['status']} {bad[0]['reason']}")
    return doc["tasks"]


def threshold_figure(tasks: list[dict], out: Path) -> Path:
    x = sorted((t["extra"] for t in tasks), key=lambda v: v["e"])
    e = np.array([v["e"] for v in x])
    nu_th = np.array([v["nu_th"] for v in x])
    nf = np.array([v["nu_tc_normal_form"] for v in x])
    fc = np.array([v["nu_tc_fold_curve"] for v in x])
    fine = np.linspace(e.min(), e.max(), 200)
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(6.4, 6.4), sharex=True, height_ratios=(3, 1.3))
    ax.fill_between(fine, 0.14, [threshold_density(v) for v in fine], color="0.9", label="no instability (psi not finite)")
    ax.plot(fine, [threshold_density(v) for v in fine], "k-", lw=1.2, label=r"$\nu_{th}(e)$ (root of the bracket of $\psi$)")
    ax.plot(e, nu_th, "ko", ms=4)
    ax.plot(e, nf, "C3-", lw=1.2, label=r"$\nu_{tc}(e)$, normal form ($a = 0$)")
    ax.plot(e, fc, "C0x", ms=8, label=r"$\nu_{tc}(e)$, fold curve ends on BP curve")
    ax.text(0.52, 0.5 * (nu_th[0] + nf[0]) - 0.0015, "subcritical", color="C3")
    ax.text(0.52, nf[0] + 0.004, "supercritical", color="C3")
    ax.set_ylabel(r"$\bar\nu$")
    ax.set_ylim(0.148, max(nf) + 0.012)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(r"gPCF shear banding ($\chi_{JJ}$, $\nu_m = 0.65$, no-slip walls)", fontsize=10)
    ax2.semilogy(e, np.maximum(np.abs(fc - nf), 1e-13), "C0s-", ms=4, label=r"$|\nu_{tc}^{fold} - \nu_{tc}^{NF}|$")
    ax2.semilogy(e, [max(v["nu_tc_fit_error"], 1e-13) for v in x], "C1^:", ms=4, label="fold-curve fit error estimate")
    ax2.set_xlabel("e")
    ax2.set_ylabel("difference")
    ax2.legend(fontsize=8)
    path = save_figure(fig, out / "threshold_tricritical.png")
    plt.close(fig)
    return path


def gap_figure(tasks: list[dict], threshold_tasks: list[dict], out: Path) -> Path:
    x = [t["extra"] for t in tasks]
    es = np.array(sorted({v["e"] for v in x}))
    nus = np.array(sorted({v["nu"] for v in x}))
    H = np.full((es.size, nus.size), np.nan)
    for v in x:
        if v["H1c_analytic"] is not None:
            H[np.searchsorted(es, v["e"]), np.searchsorted(nus, v["nu"])] = v["H1c_analytic"]
    fig, ax = plt.subplots(figsize=(7.0, 4.8))
    levels = np.geomspace(np.nanmin(H), np.nanmax(H), 15)
    cs = ax.contourf(nus, es, np.ma.masked_invalid(H), levels=levels, norm=LogNorm(), cmap="viridis")
    lines = ax.contour(nus, es, np.ma.masked_invalid(H), levels=[10, 20, 50, 100, 200, 500, 1000], colors="w",
                       linewidths=0.7)
    ax.clabel(lines, fmt="%g", fontsize=7)
    fig.colorbar(cs, ax=ax, label=r"$H_1^c = \pi\psi$", format="%.0f")
    ok = [v for v in x if v["unstable"] and v["H1c_rel_error"] is not None and v["H1c_rel_error"] < 1e-8]
    none = [v for v in x if not v["unstable"] and not v["bp_found"]]
    bad = [v for v in x if v not in ok and v not in none]
    ax.plot([v["nu"] for v in ok], [v["e"] for v in ok], "o", ms=2.5, mfc="w", mec="k", mew=0.3, ls="none",
            label=f"continuation BP = $\\pi\\psi$ (rel. diff. < 1e-8): {len(ok)}")
    ax.plot([v["nu"] for v in none], [v["e"] for v in none], "kx", ms=5,
            label=f"no BP on uniform shear up to H = {x[0]['H_max']:g}: {len(none)}")
    if bad:
        ax.plot([v["nu"] for v in bad], [v["e"] for v in bad], "rs", ms=6, label=f"disagreement: {len(bad)}")
    fine = np.linspace(es.min(), es.max(), 200)
    ax.plot([threshold_density(v) for v in fine], fine, "r-", lw=1.5, label=r"threshold $\nu_{th}(e)$")
    t = sorted((tt["extra"] for tt in threshold_tasks), key=lambda v: v["e"])
    ax.plot([v["nu_tc_normal_form"] for v in t], [v["e"] for v in t], "m--", lw=1.2,
            label=r"tricritical $\nu_{tc}(e)$")
    ax.set_xlim(nus.min() - 0.005, nus.max())
    ax.set_xlabel(r"$\bar\nu$")
    ax.set_ylabel("e")
    ax.set_title(r"critical gap of the n = 1 shear-banding mode ($\chi_{JJ}$, $\nu_m = 0.65$)", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=7)
    path = save_figure(fig, out / "critical_gap.png")
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threshold", type=Path, default=HERE / "threshold_tricritical")
    ap.add_argument("--gap", type=Path, default=HERE / "critical_gap")
    ap.add_argument("--out", type=Path, default=HERE)
    args = ap.parse_args(argv)
    thr = _tasks(args.threshold)
    gap = _tasks(args.gap)
    for path in (threshold_figure(thr, args.out), gap_figure(gap, thr, args.out)):
        print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
