"""``contin unfold``: fold curves of gravity-driven granular Couette flow in the (H, Fr) plane.

Runs :func:`problems.couette.gravity.phase_diagram` (fold curves in (H, G = Fr^-2) through the
imperfect symmetry-breaking pitchforks) and reports where fold pairs / isolas are born and die
(extrema of G along the curves, type XT) and the smallest Fr at which a floating-plug state
exists.  The problem package is imported inside the command (contin itself knows no physics).
"""

from __future__ import annotations

import math

import click

from contin.cli._base import (
    echo_err,
    echo_json,
    engine_option,
    fmt,
    main,
    parse_settings,
    resolution_guard,
    resolution_tol_option,
    table,
)

_KNOWN = {"nu": 0.3, "e": 0.8, "H_min": 1.0, "H_max": 50.0, "Fr_start": 2000.0}


@main.command("unfold")
@click.option("-s", "--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="nu, e, H_min, H_max, Fr_start (the Fr at which each fold is first found).")
@click.option("--method", default="cheb", help="Discretization method.")
@click.option("--grid", type=click.IntRange(min=8), default=32, help="Number of grid intervals.")
@click.option("--max-steps", type=click.IntRange(min=10), default=300, help="Steps per fold-curve direction.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, help="Figure (PNG/PDF) of the fold curves.")
@resolution_tol_option
@engine_option
def unfold_command(settings: tuple[str, ...], method: str, grid: int, max_steps: int, as_json: bool,
                   output: str | None, resolution_tol: str | None, engine: str) -> None:
    """Fold curves in the (H, Fr) plane: birth/death of isolas and the floating-plug limit Fr*.

    --resolution-tol applies to every trace of the run, the fold curves included (their base
    states are guarded like branch states); the check that leaves unresolved extrema out of
    the births/deaths list keeps its own tolerance (problems.couette.gravity.RESOLUTION_TOL).
    """
    from problems.couette.gravity import gravity_problem, phase_diagram

    guard, rtol = resolution_guard(resolution_tol)

    values = dict(_KNOWN)
    for name, v in parse_settings(settings).items():
        if name not in _KNOWN:
            raise ValueError(f"unknown setting {name!r} for unfold; known: {', '.join(_KNOWN)}")
        if not isinstance(v, float) or not math.isfinite(v):
            raise ValueError(f"setting {name} must be a finite number, got {v!r}")
        values[name] = v
    pb = gravity_problem(method, grid, engine=engine)
    params = pb.params({"nu": values["nu"], "e": values["e"]})
    with guard:
        d = phase_diagram(pb, params, H_range=(values["H_min"], values["H_max"]), Fr_start=values["Fr_start"],
                          max_steps=max_steps)
    for c in d.curves:  # e.g. a curve the resolution guard stopped (where the plug nears packing)
        if c.status == "MX":
            echo_err(f"warning: fold curve {c.id} ended with MX: {c.message}")
    if output:
        _figure(d, output, values)
    doc = {
        "parameters": values,
        "discretization": {"method": method, "intervals": grid, "engine": pb.engine},
        "resolution_tol": rtol,
        "critical_gaps": d.critical_gaps,
        "fr_min_floating_plug": d.fr_min_floating_plug,
        "births": [r for r in d.extrema if r["event"] == "birth"],
        "deaths": [r for r in d.extrema if r["event"] == "death"],
        "curves": [{"id": c.id, "from": c.parent, "H": c.params["H"], "G": c.params["G"], "phi": c.observables["phi"],
                    "status": c.status, "message": c.message} for c in d.curves],
        "figure": output,
    }
    if as_json:
        echo_json(doc)
    else:
        rows = [(r["curve"], r["event"], fmt(r["H"], 6), fmt(r["Fr"], 6), fmt(r["phi"], 4)) for r in d.extrema]
        echo_err(table(rows, ("curve", "event", "H", "Fr", "phi")) if rows else "no extrema of G with G > 0")
        echo_err(f"smallest Fr with a floating-plug state: {fmt(d.fr_min_floating_plug, 6)}")


def _figure(d, path: str, values) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from contin.plot import save_figure

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for c in d.curves:
        G = c.params["G"]
        Fr = np.where(G > 0, np.abs(G) ** -0.5, np.nan)
        ax.plot(c.params["H"], Fr, label=f"{c.id} ({c.parent})")
    for r in d.extrema:
        ax.plot(r["H"], r["Fr"], "v" if r["event"] == "death" else "^", color="k", ms=5)
    ax.set_yscale("log")
    ax.set_xlabel("H")
    ax.set_ylabel("Fr")
    ax.set_ylim(100, 1e4)
    ax.set_title(f"fold curves, nu={values['nu']:g}, e={values['e']:g} (^ birth, v death)")
    ax.legend(fontsize=7)
    save_figure(fig, path)
    plt.close(fig)
