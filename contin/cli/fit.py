"""``contin fit FILE.h5``: fit the universal unfolding of the pitchfork to computed branches.

Design.  ``FILE.h5`` holds branches near one pitchfork at several gravities G = Fr^-2 (G = 0
allowed): every branch with an 'H' parameter, a constant 'G' column and the nu_top,
nu_bottom observables is used.  ``contin fit --compute FILE.h5 -s nu=0.3 -s e=0.8`` first
computes such a file (gravity-free uniform shear, its first BP, every solution component in
|H - H_c| <= window at G = 0 and at each G of ``--G``;
problems.couette.unfolding.branches_near_bp) and then fits it.

The fit (contin.fit.fit_graph) is the graph of the solution set in the odd order parameter
delta = (nu(1/2) - nu(-1/2))/2, H - H_c = sum c[k, j] G^j delta^(2k - 3j) up to weight
2 ``--order``; it gives the canonical unfolding

    delta^3 - B(H) delta + alpha(G) + beta(G) delta^2 + q5 delta^5 = 0,
    B = b1 (H - H_c) + b2 (H - H_c)^2,  alpha = alpha1 G,  beta = beta1 G,

with errors (statistical and truncation), alpha(G), beta(G) fitted at each G separately
(contin.fit.fit_imperfections), the comparison with the Lyapunov-Schmidt reduction at the BP
in the same coordinate (problems.couette.unfolding.ls_unfolding; its error is the change
when the stencil is halved), the fold points of the file's branches against the predicted
fold H_LP(G), and where the hysteresis variety alpha = beta^3/27 lies.
"""

from __future__ import annotations

import click

from contin.cli._base import echo_err, echo_json, fmt, main, parse_settings, table

COMPARED = ("b1", "alpha1", "beta1", "b2", "q5")


@main.command("fit")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--compute", is_flag=True, help="Compute the branches first and write them to FILE.")
@click.option("-s", "--set", "settings", multiple=True, metavar="NAME=VALUE", help="nu, e (with --compute).")
@click.option("--G", "g_values", default="3e-8,1e-7,3e-7,1e-6", show_default=True,
              help="Gravities G > 0 (with --compute; G = 0 is always added).")
@click.option("--window", type=float, default=0.3, show_default=True, help="|H - H_c| window of branches and fit.")
@click.option("--delta-max", type=float, default=0.05, show_default=True, help="|delta| window of the fit.")
@click.option("--order", type=click.IntRange(min=2, max=8), default=5, show_default=True,
              help="Highest weight / 2 of the fitted graph (2 = just the unfolding's terms).")
@click.option("--grid", type=click.IntRange(min=8), default=32, show_default=True, help="Grid intervals (with --compute).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def fit_command(file: str, compute: bool, settings: tuple[str, ...], g_values: str, window: float,
                delta_max: float, order: int, grid: int, as_json: bool) -> None:
    """Fit delta^3 - B(H) delta + alpha(G) + beta(G) delta^2 = 0 near a pitchfork; compare with Lyapunov-Schmidt."""
    import numpy as np

    from contin import io
    from contin.fit import fit_graph, fit_imperfections
    from problems.couette.gravity import gravity_problem
    from problems.couette.unfolding import (
        branches_near_bp,
        first_pitchfork,
        ls_unfolding,
        unfolding_data,
    )

    if not (window > 0 and delta_max > 0):
        raise ValueError("--window and --delta-max must be positive")
    if compute:
        vals = {"nu": 0.3, "e": 0.8, **parse_settings(settings)}
        try:
            Gs = [float(g) for g in g_values.split(",") if g.strip()]
        except ValueError:
            raise click.BadParameter(f"expected comma-separated numbers, got {g_values!r}", param_hint="'--G'") from None
        if not Gs or min(Gs) <= 0:
            raise ValueError("--G needs positive gravities G = Fr^-2 (G = 0 is added by itself)")
        pb = gravity_problem("cheb", grid)
        base, bp = first_pitchfork(pb, vals["nu"], vals["e"])
        branches = []
        for G in [0.0, *Gs]:
            branches += branches_near_bp(pb, base, bp, G, window)
        io.write(file, branches, scene="gravity-unfolding", parameters={"nu": vals["nu"], "e": vals["e"]},
                 discretization={"method": "cheb", "intervals": grid}, diagram_x="H")
    branches, meta = io.load(file)
    use = [b for b in branches if "H" in b.params and "G" in b.params and len(b) > 2
           and np.ptp(b.params["G"]) == 0 and {"nu_top", "nu_bottom"} <= set(b.observables)]
    if not any(b.params["G"][0] != 0 for b in use):
        raise ValueError(f"{file!r} has no branches at constant G != 0 with an H column and nu_top, nu_bottom")
    nu = float(meta["parameters"].get("nu", use[0].params["nu"][0]))
    e = float(meta["parameters"].get("e", use[0].params["e"][0]))
    n = int(meta["discretization"].get("intervals", grid))
    pb = gravity_problem(meta["discretization"].get("method", "cheb"), n)
    H_all = np.concatenate([b.params["H"] for b in use])
    _, bp = first_pitchfork(pb, nu, e, H_max=float(H_all.max()) + 1.0)
    Hc = float(bp.params["H"])
    if not H_all.min() - window <= Hc <= H_all.max() + window:
        raise ValueError(f"the first pitchfork (H_c = {Hc:.6g}) is not near the file's branches "
                         f"(H in [{H_all.min():.6g}, {H_all.max():.6g}])")
    lam, delta, mu = unfolding_data(use, Hc)
    fit = fit_graph(lam, delta, mu, critical_value=Hc, order=order, window=window, delta_max=delta_max)
    per_g = fit_imperfections(lam, delta, mu, fit, window=window, delta_max=delta_max)
    ls = ls_unfolding(pb, bp, amplitude=1e-2)
    ls_fine = ls_unfolding(pb, bp, amplitude=5e-3)
    fu, lu, lf = fit.unfolding, ls.unfolding, ls_fine.unfolding
    ferr = fit.errors()
    coeffs = {}
    for k in COMPARED:
        f_v, l_v = getattr(fu, k), getattr(lf, k)
        rel = abs(f_v - l_v) / abs(l_v)
        coeffs[k] = {"fit": f_v, "fit_err": ferr[k], "fit_stat_err": fu.errors()[k], "fit_truncation": fit.systematic[k],
                     "lyapunov_schmidt": l_v, "lyapunov_schmidt_err": abs(l_v - getattr(lu, k)),
                     "relative_difference": rel, "agree_5pct": bool(rel <= 0.05)}
    folds = []
    for b in use:
        for lp in b.fold_points:
            G = float(lp.params["G"])
            if not lp.converged or G == 0:
                continue
            pred = fu.fold(G)[0]
            folds.append({"branch": b.id, "G": G, "H_minus_Hc": lp.params["H"] - Hc, "predicted": pred,
                          "predicted_leading": fu.fold(G, leading=True)[0],
                          "rel_error": pred / (lp.params["H"] - Hc) - 1})
    hyst = lf.hysteresis()
    m2 = 27 * lf.alpha1 / lf.beta1**3
    formal = float(np.sqrt(abs(m2)))
    hysteresis = {"exists": hyst is not None, "G": formal, "Fr": formal ** -0.5, "delta": abs(lf.beta1 * formal / 3),
                  "note": ("alpha1 beta1 < 0: the line (alpha1 G, beta1 G) meets alpha = beta^3/27 only at G = 0; "
                           "G, Fr, delta are where it would if beta1 changed sign" if hyst is None else
                           "hysteresis point of the cubic truncation"),
                  "perturbative": bool(abs(lf.beta1 * formal / 3) <= delta_max)}
    doc = {"file": file, "nu": nu, "e": e, "critical_value": Hc,
           "G": sorted({float(b.params["G"][0]) for b in use}), "branches": [b.id for b in use],
           "B": {"b1": fu.b1, "b1_err": ferr["b1"], "b2": fu.b2, "b2_err": ferr["b2"],
                 "formula": "B(H) = b1 (H - H_c) + b2 (H - H_c)^2"},
           "alpha": [{"G": r.mu, "alpha": r.alpha, "alpha_err": r.alpha_err, "n_points": r.n_points} for r in per_g],
           "beta": [{"G": r.mu, "beta": r.beta, "beta_err": r.beta_err, "n_points": r.n_points} for r in per_g],
           "coefficients": coeffs,
           "relative_difference": {k: coeffs[k]["relative_difference"] for k in ("b1", "alpha1", "beta1")},
           "agree_5pct": {k: coeffs[k]["agree_5pct"] for k in ("b1", "alpha1", "beta1")},
           "fit": fit.as_dict(),
           "lyapunov_schmidt": {"unfolding": lf.as_dict(), "raw": ls_fine.coefficients, "stencil_residual": ls_fine.residual,
                                "amplitudes": [ls.amplitude, ls_fine.amplitude]},
           "folds": folds, "hysteresis": hysteresis,
           "convention": "delta = (nu(1/2) - nu(-1/2))/2; delta^3 - B(H) delta + alpha(G) + beta(G) delta^2 + q5 delta^5 = 0"}
    if as_json:
        echo_json(doc)
        return
    rows = [(k, f"{fmt(c['fit'], 6)} +- {fmt(c['fit_err'], 2)}", f"{fmt(c['lyapunov_schmidt'], 6)} +- {fmt(c['lyapunov_schmidt_err'], 2)}",
             f"{100 * c['relative_difference']:.3f} %") for k, c in coeffs.items()]
    echo_err(f"pitchfork at H_c = {fmt(Hc)} (nu = {nu:g}, e = {e:g}); {fit.n_points} points, order {order}, "
             f"rms {fit.rms_residual:.1e}")
    echo_err(table(rows, ("coefficient", "fit", "Lyapunov-Schmidt", "difference")))
    echo_err(table([(f"{r.mu:.3g}", f"{fmt(r.alpha, 6)} +- {fmt(r.alpha_err, 2)}", f"{fmt(r.beta, 6)} +- {fmt(r.beta_err, 2)}")
                    for r in per_g], ("G", "alpha(G)", "beta(G)")))
    for f in folds:
        echo_err(f"fold {f['branch']}: G = {f['G']:.3g}, H_LP - H_c = {fmt(f['H_minus_Hc'], 8)}, "
                 f"predicted {fmt(f['predicted'], 8)} ({100 * f['rel_error']:+.3f} %)")
    echo_err(f"hysteresis: {hysteresis['note']}")
