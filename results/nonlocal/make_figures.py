"""Issue-18 figures (Dsouza-Nott non-local model) from the runs in results/nonlocal/*.h5.

Usage: python results/nonlocal/make_figures.py   (after the contin trace commands of results/regenerate.sh)

Branch data (wall-layer width, slip, P, ... along the continuation parameters) come from the
HDF5 files; the profiles at the scene defaults are re-solved by Newton with the same problem
classes and parameters (phi, u need K and W, which the stored profiles do not carry).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from contin import io
from contin.continuation import newton
from contin.plot import save_figure
from problems.nonlocal_flow.closures import CriticalState, PlaneShearAnalytic
from problems.nonlocal_flow.cylinder import CylindricalCouette
from problems.nonlocal_flow.plane import DEFAULTS, PlaneShear

OUT = "results/nonlocal"


def _solve(pb, p):
    res = newton(pb, pb.initial(p), p)
    assert res.converged, res.message
    return res.u


def _branches(name):
    branches, meta = io.load(f"{OUT}/{name}.h5")
    return {b.id: b for b in branches}, meta


def shear() -> None:
    br, meta = _branches("shear")
    s = meta["parameters"]
    cs = CriticalState(s["phi_min"], s["phi_max"], s["n1"], s["n2"])
    pb = PlaneShear("cheb", 96, cs)
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.8), layout="constrained")
    for k, (K, mw, c) in enumerate([(s["K"], s["mu_w"], "tab:blue"), (s["K2"], s["mu_w2"], "tab:red")], start=1):
        p = dict(DEFAULTS, **{n: s[n] for n in ("W", "ell", "mu", "phi_bar", "phi_w")}, K=K, mu_w=mw)
        x = _solve(pb, p)
        y = pb.y(p)
        ax[0].plot(x[:pb.n], y, color=c, label=f"K = {K:g}, $\\mu_w$ = {mw:g}")
        ax[1].plot(pb.velocity(x, p), y, color=c, label=f"coupled, K = {K:g}, $\\mu_w$ = {mw:g}")
        an = PlaneShearAnalytic(p["W"], K, p["ell"], mw, p["mu"])
        yy = np.linspace(0, p["W"], 200)
        ax[1].plot(an.u(yy), yy, "--", color=c, lw=1, label="uniform $\\phi$ (closed form)")
        if k == 1:
            ax[1].plot(an.report_profile(yy), yy, ":", color="gray", label="report's printed sign")
    ax[0].set_xlabel(r"$\phi$")
    ax[0].set_ylabel(r"$y / d_p$")
    ax[1].set_xlabel(r"$u / u_w$")
    ax[0].legend(fontsize=7)
    ax[1].legend(fontsize=7)
    ax[0].set_title(rf"$\bar\phi$ = {s['phi_bar']:g}, W = {s['W']:g} $d_p$, $\ell$ = {s['ell']:g} $d_p$", fontsize=9)
    save_figure(fig, f"{OUT}/shear_profiles.png")

    fig, ax = plt.subplots(1, 3, figsize=(12, 3.6), layout="constrained")
    for k, c in ((1, "tab:blue"), (2, "tab:red")):
        for j, (name, xname) in enumerate((("ell", "ell_over_W"), ("mu_w", "mu_w_over_mu"), ("W", "W"))):
            b = br[f"pair{k}.{name}"]
            xv = b.observables[xname] if xname in b.observables else b.params[xname]
            ax[j].plot(xv, b.observables["delta"], color=c, label=f"pair {k} coupled")
            ax[j].plot(xv, b.observables["zeta_inv"], "--", color=c, lw=1, label=f"pair {k}: 1/$\\zeta$")
    u = br["uniform.ell"]
    ax[0].plot(u.observables["ell_over_W"], u.observables["delta"], "k.", ms=3, label="uniform $\\phi$ (pair 1), computed")
    ell = np.sort(u.params["ell"])
    exact = [PlaneShearAnalytic(s["W"], s["K"], e, s["mu_w"], s["mu"]).wall_layer for e in ell]
    ax[0].plot(ell / s["W"], exact, "k-", lw=0.7, label=r"uniform $\phi$: $1/(\zeta \tanh(\zeta W/2))$")
    ax[1].set_title("K only scales the amplitude: the pairs' curves coincide", fontsize=8)
    for a, xl in zip(ax, (r"$\ell / W$", r"$\mu_w / \mu$", r"$W / d_p$")):
        a.set_xlabel(xl)
        a.set_ylabel(r"wall layer $\dot\gamma / |\dot\gamma'|$ ($d_p$)")
    ax[1].set_yscale("log")
    ax[0].legend(fontsize=7)
    save_figure(fig, f"{OUT}/shear_localization.png")


def cylinder() -> None:
    br, meta = _branches("cylinder")
    s = meta["parameters"]
    cs = CriticalState(s["phi_min"], s["phi_max"], s["n1"], s["n2"])
    p = {k: s[k] for k in ("W", "ratio", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w")}
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.6), layout="constrained")
    for op, c in (("derived", "k"), ("report", "tab:orange")):
        pb = CylindricalCouette("cheb", 64, cs, operator=op)
        x = _solve(pb, p)
        _, r = pb.radii(p)
        ax[0].plot(r, x[:pb.n], color=c, label=f"{op} equations")
        ax[1].plot(r, x[pb.n:2 * pb.n], color=c, label=f"{op} equations")
        b = br[f"{op}.ratio"]
        ax[2].plot(b.params["ratio"], b.observables["u_inner"], color=c, label=f"{op}: $u(r_i)$")
        ax[2].plot(b.params["ratio"], b.observables["u_mid"], "--", color=c, label=f"{op}: u(mid-gap)")
    ax[0].set_xlabel(r"$r / d_p$")
    ax[0].set_ylabel(r"$\phi$")
    ax[1].set_xlabel(r"$r / d_p$")
    ax[1].set_ylabel(r"$u_\theta / u_w$")
    ax[2].set_xlabel(r"$r_o / r_i$ (gap W fixed)")
    ax[2].set_ylabel(r"$u_\theta / u_w$")
    ax[1].legend(fontsize=7)
    ax[2].legend(fontsize=7)
    ax[0].set_title(f"W = {p['W']:g} $d_p$, $r_o/r_i$ = {p['ratio']:g}, K = {p['K']:g}, $\\mu_w/\\mu$ = {p['mu_w'] / p['mu']:.2f}",
                    fontsize=9)
    save_figure(fig, f"{OUT}/cylinder.png")


def muI() -> None:
    br, meta = _branches("muI")
    s = meta["parameters"]
    cs = CriticalState(s["phi_min"], s["phi_max"], s["n1"], s["n2"])
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.6), layout="constrained")
    m, f = br["muI.U"], br["phiI.U"]
    ax[0].plot(m.params["U"], m.observables["delta"], "k", label=r"$\mu(I)$ non-local: wall layer ($d_p$)")
    ax[0].plot(m.params["U"], 10 * m.observables["u_slip"], "k--", label=r"10 $u(0)/u_w$ (slip)")
    ax[0].plot(f.params["U"], f.observables["delta"], "tab:green", label=r"$\phi(I)$: wall layer")
    ax[0].set_xlabel(r"$U = u_w / (d_p \sqrt{\alpha/\rho_p})$")
    ax[0].legend(fontsize=7)
    ax[1].plot(m.params["U"], m.observables["I_max"], "k", label=r"$\mu(I)$ non-local")
    ax[1].plot(f.params["U"], f.observables["I_max"], "tab:green", label=r"$\phi(I)$")
    ax[1].axhline(0.1, color="gray", lw=0.5)
    ax[1].set_xlabel("U")
    ax[1].set_ylabel(r"$I_{max}$ (at the walls)")
    ax[1].legend(fontsize=7)
    U = float(s["U_max"])
    p = dict(DEFAULTS, **{k: s[k] for k in ("W", "ell", "K", "mu_w", "mu", "phi_bar", "phi_w", "dmu", "I0", "A_phi")})
    for model, c, lab in (("nonlocal", "k", "non-local"), ("phiI", "tab:green", r"local $\phi(I)$")):
        pb = PlaneShear("cheb", 64, cs, phi_model=model)
        q = dict(p, U=U)
        x = _solve(pb, q)
        ax[2].plot(x[:pb.n], pb.y(q), color=c, label=f"{lab}, U = {U:g}")
    ax[2].set_xlabel(r"$\phi$")
    ax[2].set_ylabel(r"$y / d_p$")
    ax[2].legend(fontsize=7)
    save_figure(fig, f"{OUT}/muI.png")


if __name__ == "__main__":
    shear()
    cylinder()
    muI()
