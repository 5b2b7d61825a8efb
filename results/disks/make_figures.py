"""Figures of the disks scenes from their ``--json`` output (results/regenerate.sh, section "disks").

    python results/disks/make_figures.py criticality results/disks/criticality.json results/disks/criticality.png
    python results/disks/make_figures.py savage results/disks/savage.json results/disks/savage.png
"""

from __future__ import annotations

import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def criticality(doc: dict, out: str) -> None:
    ex = doc["extra"]
    nu = np.array(ex["nu"])
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for e, c in ex["curves"].items():
        a = np.array([np.nan if v is None else v for v in c["a"]], float)
        hc = np.array([np.nan if v is None else v for v in c["H_c"]], float)
        line, = ax[0].plot(nu, np.sign(a) * np.log10(1 + np.abs(a)), "o-", ms=3, label=f"e = {e}")
        for t in c["tricritical"]:
            ax[0].axvline(t, color=line.get_color(), ls=":", lw=1)
        ax[0].axvline(c["threshold"], color=line.get_color(), ls="--", lw=0.8)
        ax[1].semilogy(nu, hc, "o-", ms=3, color=line.get_color(), label=f"e = {e}")
    ax[0].axhline(0, color="k", lw=0.8)
    ax[0].axvline(0.53, color="grey", lw=3, alpha=0.3, label="seed 000: nu0 = 0.53 (Lees-Edwards)")
    ax[0].set_xlabel("mean area fraction nu")
    ax[0].set_ylabel("sign(a) log10(1 + |a|),  H - H_1^c ~ a delta^2")
    ax[0].set_title("first pitchfork: a > 0 supercritical, a < 0 subcritical\n(dashed: threshold, dotted: tricritical)")
    ax[0].legend(fontsize=7)
    ax[1].set_xlabel("mean area fraction nu")
    ax[1].set_ylabel("H_1^c = pi psi")
    ax[1].set_title(f"critical gap, pair correlation {doc['parameters']['corr']}")
    fig.tight_layout()
    fig.savefig(out, dpi=120)


def savage(doc: dict, out: str) -> None:
    ex = doc["extra"]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    phi = np.array(ex["phi0"])
    ax[0].plot(phi, ex["p_con_over_kn"], label="p_con / k_n (Eq. 15)")
    ax[0].plot(phi, ex["sigma_con_over_kn"], label="sigma_con / k_n (Eq. 28)")
    ax[0].set_xlabel("phi0")
    ax[0].set_title(f"Savage contact stresses, a0 = {doc['parameters']['a0_over_kn']:g} k_n, e = {doc['parameters']['e']:g}")
    ax[0].legend()
    s = np.array(ex["flow_curves"]["s"])
    for phi0, c in ex["flow_curves"]["curves"].items():
        ax[1].loglog(s, c["sigma"], label=f"phi0 = {phi0}")
    ax[1].loglog(s, 1e2 * s**2, "k:", lw=1, label="~ s^2 (Bagnold)")
    ax[1].set_xlabel("s = gamma_dot t_m")
    ax[1].set_ylabel("sigma  [m / t_m^2]")
    ax[1].set_title(f"flow curves across phi_c = {doc['parameters']['phi_c']:g}")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    kind, src, out = sys.argv[1:4]
    with open(src) as fh:
        doc = json.load(fh)
    {"criticality": criticality, "savage": savage}[kind](doc, out)
    print(f"wrote {out}")
