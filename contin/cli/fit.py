"""``contin fit FILE.h5 --at BP1``: the normal form of a stored pitchfork, fitted to the file's
branches around it and compared with the Lyapunov-Schmidt reduction (:mod:`contin.bpfit`).

FILE holds the branch through the BP and branches near it at several fixed values of an
imperfection parameter (any scene's run; e.g. ``contin trace gravity-unfolding`` for gPCF).
``--imperfection`` and ``--delta`` (an observable odd under the symmetry) default to the file's
``extra.normal_form`` entries, else the imperfection is the one parameter constant per branch
that varies between branches and delta the diagram's y observable.
"""

from __future__ import annotations

import math

import click

from contin.cli._base import echo_err, echo_json, fail, fmt, main, table, warn_if_incomplete


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        fail(f"{name} must be a finite number > 0, got {value}")


@main.command("fit")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--at", "label", required=True, metavar="LABEL", help="The branch point (BP1, ...).")
@click.option("--branch", "branch_id", default=None, metavar="ID", help="Branch of the point (when the label is not unique).")
@click.option("--imperfection", default=None, metavar="NAME", help="Imperfection parameter (constant per branch).")
@click.option("--delta", default=None, metavar="OBS", help="Odd order-parameter observable.")
@click.option("--window", type=float, default=0.3, show_default=True, help="|lambda - lambda_c| window of the fit.")
@click.option("--delta-max", type=float, default=0.05, show_default=True, help="|delta| window of the fit.")
@click.option("--delta-min", type=float, default=3e-3, show_default=True,
              help="Points with |delta| below this are left out (the graph is singular at delta = 0).")
@click.option("--order", type=click.IntRange(min=2, max=8), default=5, show_default=True,
              help="Highest weight / 2 of the fitted graph (2 = just the unfolding's terms).")
@click.option("--no-ls", is_flag=True, help="Skip the Lyapunov-Schmidt comparison (needs the problem rebuilt).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def fit_command(file: str, label: str, branch_id: str | None, imperfection: str | None, delta: str | None,
                window: float, delta_max: float, delta_min: float, order: int, no_ls: bool, as_json: bool) -> None:
    """Fit delta^3 - B delta + alpha(mu) + beta(mu) delta^2 = 0 around the BP LABEL of FILE."""
    from contin import io
    from contin.bpfit import fit_at_bp, guess_imperfection
    from contin.cli._runctl import check_nonempty
    from contin.restart import find_point, rebuild_problem

    # '' fell back to the default and the error then asked for the option that was given (qa15)
    imperfection, delta = check_nonempty(imperfection, "--imperfection"), check_nonempty(delta, "--delta")
    for name, v in (("--window", window), ("--delta-max", delta_max), ("--delta-min", delta_min)):
        _positive(name, v)
    if delta_min >= delta_max:
        fail(f"--delta-min ({delta_min:g}) must be below --delta-max ({delta_max:g})")
    branches, meta = io.load(file)
    branch, bp = find_point(branches, label, branch_id, repr(file))
    if bp.type != "BP":
        fail(f"{bp.name} of {file} is {'an' if bp.type[0] in 'AEFHILMNORSX' else 'a'} {bp.type}; `contin fit` needs a "
             "branch point")
    warn_if_incomplete(file, meta)  # the branches near the BP may be missing
    parameter = branch.parameter
    hints = dict((meta.get("extra") or {}).get("normal_form") or {})
    imperfection = imperfection or hints.get("imperfection") or guess_imperfection(
        [b for b in branches if parameter in b.params], parameter)
    delta = delta or hints.get("delta") or meta.get("diagram_y") or "phi"
    if imperfection == parameter:
        fail(f"the imperfection must differ from the branch's parameter {parameter!r}")
    if imperfection not in bp.params:
        fail(f"{bp.name} has no value of {imperfection!r}")
    problem, delta0 = None, 0.0
    if not no_ls:
        problem = rebuild_problem({**meta, "path": file})
        delta0 = float(problem.observables(bp.state, bp.params)[delta])
    else:  # the BP's delta interpolated along its branch
        import numpy as np

        if delta in branch.observables and len(branch) > 1:
            i = min(max(bp.index, 0), len(branch) - 2)
            x, y = branch.params[parameter][i:i + 2], branch.observables[delta][i:i + 2]
            w = 0.0 if x[1] == x[0] else (bp.params[parameter] - x[0]) / (x[1] - x[0])
            delta0 = float((1 - w) * y[0] + w * y[1]) if np.all(np.isfinite(y)) else 0.0
    doc = fit_at_bp(branches, bp, parameter, imperfection=imperfection, delta=delta, problem=problem,
                    delta_at_bp=delta0, window=window, delta_max=delta_max, delta_min=delta_min, order=order)
    doc = {"file": file, "branch": branch.id, **doc}
    if as_json:
        echo_json(doc)
        return
    fit = doc["fit"]
    echo_err(f"{bp.name} at {parameter}_c = {fmt(doc['critical_value'])} ({imperfection} = {fmt(doc['imperfection_at_bp'])}); "
             f"delta = {delta}; {fit['n_points']} points, order {order}, rms {fit['rms_residual']:.1e}")
    coeffs = doc["coefficients"]
    if problem is not None:
        rows = [(k, f"{fmt(c['fit'], 6)} +- {fmt(c['fit_err'], 2)}",
                 f"{fmt(c['lyapunov_schmidt'], 6)} +- {fmt(c['lyapunov_schmidt_err'], 2)}",
                 f"{100 * c['relative_difference']:.3f} %") for k, c in coeffs.items()]
        echo_err(table(rows, ("coefficient", "fit", "Lyapunov-Schmidt", "difference")))
    else:
        echo_err(table([(k, f"{fmt(c['fit'], 6)} +- {fmt(c['fit_err'], 2)}") for k, c in coeffs.items()],
                       ("coefficient", "fit")))
    echo_err(table([(f"{a['mu']:.3g}", f"{fmt(a['alpha'], 6)} +- {fmt(a['alpha_err'], 2)}",
                     f"{fmt(b['beta'], 6)} +- {fmt(b['beta_err'], 2)}") for a, b in zip(doc["alpha"], doc["beta"])],
                   ("mu", "alpha(mu)", "beta(mu)")))
    for f in doc["folds"]:
        echo_err(f"fold {f['branch']}: mu = {f['mu']:.3g}, {parameter}_LP - {parameter}_c = {fmt(f['lambda_minus_lc'], 8)}, "
                 f"predicted {fmt(f['predicted'], 8)} ({100 * f['rel_error']:+.3f} %)")
    echo_err(f"hysteresis: {doc['hysteresis']['note']}")
