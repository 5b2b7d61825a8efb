"""``contin fit FILE.h5``: fit the universal unfolding of the pitchfork to computed branches.

Design.  ``FILE.h5`` holds branches near one pitchfork at several small imperfections: every
branch with an 'H' parameter, a constant 'G' > 0 column and the 'phi' observable is used.
``contin fit --compute FILE.h5 -s nu=0.3 -s e=0.8`` first computes such a file (gravity-free
uniform shear, its first BP, short branches in a window |H - H_c| <= window at each G of
``--G``; problems.couette.gravity.unfolding_branches) and then fits it.

The fit (contin.fit.fit_unfolding) is delta^3 - B delta + alpha + beta delta^2 = 0 with
delta = Phi - nu_bar, B = b1 (H - H_c), alpha = alpha1 G, beta = beta1 G; reported with
one-sigma errors and compared with the Lyapunov-Schmidt values b1 = -a1/a3, alpha1 = a0/a3,
beta1 = a2/a3 at the BP (recomputed from the file's nu, e and grid).
"""

from __future__ import annotations

import click

from contin.cli._base import echo_err, echo_json, fmt, main, parse_settings, table


@main.command("fit")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--compute", is_flag=True, help="Compute the branches first and write them to FILE.")
@click.option("-s", "--set", "settings", multiple=True, metavar="NAME=VALUE", help="nu, e (with --compute).")
@click.option("--G", "g_values", default="2e-8,5e-8,1e-7", show_default=True, help="Imperfections G (with --compute).")
@click.option("--window", type=float, default=0.3, show_default=True, help="|H - H_c| window of branches and fit.")
@click.option("--delta-max", type=float, default=0.025, show_default=True, help="|Phi - nu_bar| window of the fit.")
@click.option("--grid", type=click.IntRange(min=8), default=32, show_default=True, help="Grid intervals (with --compute).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def fit_command(file: str, compute: bool, settings: tuple[str, ...], g_values: str, window: float,
                delta_max: float, grid: int, as_json: bool) -> None:
    """Fit delta^3 - B delta + alpha + beta delta^2 = 0 near a pitchfork; compare with Lyapunov-Schmidt."""
    import numpy as np

    from contin import io
    from contin.fit import fit_unfolding
    from problems.couette.gravity import branch_point_normal_forms, gravity_free_branches, gravity_problem, GravitySettings

    if compute:
        vals = {"nu": 0.3, "e": 0.8, **parse_settings(settings)}
        try:
            Gs = [float(g) for g in g_values.split(",") if g.strip()]
        except ValueError:
            raise click.BadParameter(f"expected comma-separated numbers, got {g_values!r}", param_hint="'--G'") from None
        if not Gs or min(Gs) <= 0:
            raise ValueError("--G needs positive imperfections")
        from problems.couette.gravity import unfolding_branches

        pb = gravity_problem("cheb", grid)
        p = pb.params({"nu": vals["nu"], "e": vals["e"]})
        base, _ = gravity_free_branches(pb, p, GravitySettings(H_range=(1.0, 60.0), modes=0))
        if not base.branch_points:
            raise ValueError("uniform shear has no branch point in H <= 60 at these parameters")
        branches = unfolding_branches(pb, base.branch_points[0], Gs, window)
        io.write(file, branches, scene="gravity-unfolding", parameters={"nu": vals["nu"], "e": vals["e"]},
                 discretization={"method": "cheb", "intervals": grid}, diagram_x="H")
    branches, meta = io.load(file)
    use = [b for b in branches if "H" in b.params and "G" in b.params and len(b) > 2
           and np.ptp(b.params["G"]) == 0 and b.params["G"][0] > 0 and "phi" in b.observables]
    if not use:
        raise ValueError(f"{file!r} has no branches at constant G > 0 with an H column and phi")
    nu = float(meta["parameters"].get("nu", use[0].params["nu"][0]))
    e = float(meta["parameters"].get("e", use[0].params["e"][0]))
    n = int(meta["discretization"].get("intervals", grid))
    pb = gravity_problem(meta["discretization"].get("method", "cheb"), n)
    p = pb.params({"nu": nu, "e": e})
    H_all = np.concatenate([b.params["H"] for b in use])
    base, _ = gravity_free_branches(pb, p, GravitySettings(H_range=(1.0, float(H_all.max()) + 1.0), modes=0))
    forms = branch_point_normal_forms(pb, base)
    if not forms:
        raise ValueError("no branch point of uniform shear below the file's H range")
    bp, nf = min(forms, key=lambda f: abs(f[0].params["H"] - float(np.median(H_all))))
    Hc = bp.params["H"]
    fit = fit_unfolding([b.params["H"] for b in use], [b.observables["phi"] - nu for b in use],
                        [float(b.params["G"][0]) for b in use], delta_max=delta_max, window=window, center=Hc)
    ls = {"b1": -nf.a1 / nf.a3, "alpha1": nf.a0["G"] / nf.a3, "beta1": nf.a2["G"] / nf.a3}
    rel = {k: abs(getattr(fit, k) - v) / abs(v) for k, v in ls.items()}
    doc = {"file": file, "nu": nu, "e": e, "critical_value": Hc, "fit": fit.as_dict(), "lyapunov_schmidt": ls,
           "normal_form": nf.as_dict(), "relative_difference": rel,
           "G": sorted({float(b.params["G"][0]) for b in use}), "branches": [b.id for b in use],
           "agree_5pct": {k: bool(v <= 0.05) for k, v in rel.items()}}
    if as_json:
        echo_json(doc)
    else:
        rows = [(k, f"{fmt(getattr(fit, k), 6)} +- {fmt(getattr(fit, k + '_err'), 2)}", fmt(ls[k], 6), f"{100 * rel[k]:.2f} %")
                for k in ("b1", "alpha1", "beta1")]
        echo_err(f"pitchfork at H_c = {fmt(Hc)} (nu = {nu:g}, e = {e:g}); fitted H_c = {fmt(fit.critical_value, 8)}")
        echo_err(table(rows, ("coefficient", "fit", "Lyapunov-Schmidt", "difference")))
