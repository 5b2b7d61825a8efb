"""``contin profiles FILE.h5 --at NAME=VALUE``: solution profiles of a stored run."""

from __future__ import annotations

import click

from contin.cli._base import echo_err, fail, main, parse_settings, warn_if_incomplete


@main.command("profiles")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option("--at", "at", default=None, metavar="NAME=VALUE", help="Parameter value, e.g. H=25.")
@click.option("--point", "point", default=None, metavar="LABEL",
              help="A labelled point, e.g. LPC1 (files of periodic orbits).")
@click.option("--branch", "branch_ids", multiple=True, metavar="ID", help="Only these branches (repeatable).")
@click.option("--names", default=None, metavar="LIST",
              help="Profiles to draw, e.g. nu,u,T; of orbits the components, e.g. u1,u3 [default: all].")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Figure file.")
def profiles_command(file: str, at: str | None, point: str | None, branch_ids: tuple[str, ...], names: str | None,
                     output: str) -> None:
    """Plot the stored profiles (against y) of each branch at NAME=VALUE.

    Exact at a special point located there (e.g. a UZ point), else interpolated linearly
    between the two stored profiles that bracket the value.  Of a file of periodic orbits: the
    orbit u_i(t) over one period and its phase portrait (u1, u2), at NAME=VALUE or at --point.
    """
    from contin import io

    import math

    from contin.cli._runctl import check_nonempty

    if (at is None) == (point is None):
        fail("give either --at NAME=VALUE or --point LABEL")
    name, value = "", math.nan
    if at is not None:
        ((name, value),) = parse_settings([at], "'--at'").items()
        if not isinstance(value, float) or not math.isfinite(value):  # H=inf drew other points, exit 0
            raise click.BadParameter(f"{at!r} needs a finite numeric value", param_hint="'--at'")
    names = check_nonempty(names, "--names")
    point = check_nonempty(point, "--point")
    io.check_writable(output)
    branches, meta = io.load(file)
    warn_if_incomplete(file, meta)  # a value past where the run stopped is missing, not out of range (qa19)
    if any(b.kind in ("periodic-orbits", "lpc-curve") for b in branches):  # (an LPC curve's orbits: --point)
        from contin.cli.orbit_profiles import draw_orbits

        draw_orbits(file, branches, meta, name, value, point, branch_ids, names, output)
        return
    if point is not None:
        fail(f"--point draws an orbit of a file of periodic orbits; {file} holds none (use --at NAME=VALUE)")
    if meta["y"] is None or not meta["profiles"]:
        if not meta["complete"] and not str(meta.get("stopped", "")).startswith("failed"):
            # an interrupted run is saved before its profiles are written (at the run's end): it said
            # only 'stores no solution profiles', as for a scene that has none (qa17)
            depth = isinstance(meta.get("extra"), dict) and "depth" in meta["extra"]  # --depth refuses --resume
            fail(f"{file} stores no solution profiles: its run was {meta.get('stopped') or 'interrupted'} before "
                 f"they were written (at the end of a run); "
                 + ("run it again (a --depth run starts from scratch)" if depth else "continue it with --resume"))
        fail(f"{file} stores no solution profiles")
    if branch_ids:
        missing = [i for i in branch_ids if i not in {b.id for b in branches}]
        if missing:
            fail(f"no branch {missing[0]!r} in {file}; branches: {', '.join(b.id for b in branches)}")
        branches = [b for b in branches if b.id in branch_ids]
    import numpy as np

    constant = [b for b in branches if name in b.params and len(b)
                and np.all(np.asarray(b.params[name]) == np.asarray(b.params[name])[0])]
    if constant and len(constant) == len([b for b in branches if name in b.params]):
        # every point matched: the profile of some special point was drawn as "at" NAME=VALUE
        b = constant[0]
        fail(f"{name} is constant along the branches of {file} ({name} = {float(b.params[name][0]):g} on branch "
             f"{b.id}): --at needs a parameter that varies along a branch, e.g. --at {b.parameter}=...")
    branches = [b for b in branches if b not in constant]
    found = io.profiles_at(branches, meta, name, value)
    if not found:
        fail(f"no stored branch of {file} reaches {name}={value:g}")
    available = list(found[0][2])
    wanted = [n.strip() for n in names.split(",")] if names else available
    unknown = [n for n in wanted if n not in available]
    if unknown:
        fail(f"no profile {unknown[0]!r}; available: {', '.join(available)}")

    from contin.plot import plot_profiles, save_figure

    data = {n: [f[2][n] for f in found] for n in wanted}
    fig = plot_profiles(meta["y"], data, wanted, labels=[f"{b.id} ({b.kind})" for b, _, _ in found])
    fig.suptitle(f"{meta.get('scene') or ''} {name}={value:g}".strip(), fontsize=8)
    save_figure(fig, output)
    for b, how, _ in found:
        echo_err(f"branch {b.id}: {how}")
    echo_err(f"wrote {output}")
