"""``contin diagram FILE.h5``: bifurcation diagram of a stored run."""

from __future__ import annotations

from collections import Counter

import click

from contin.cli._base import echo_err, fail, main, warn_if_incomplete


@main.command("diagram")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option("-x", "x", default=None, help="Parameter on the x axis [default: the continuation parameter].")
@click.option("-y", "y", default=None, help="Observable or parameter on the y axis [default: phi].")
@click.option("--branch", "branch_ids", multiple=True, metavar="ID", help="Plot only these branches (repeatable).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Figure file (.png, .pdf, .svg).")
@click.option("--title/--no-title", default=True, help="Title with the scene and its parameters.")
def diagram_command(file: str, x: str | None, y: str | None, branch_ids: tuple[str, ...], output: str,
                    title: bool) -> None:
    """Plot a bifurcation diagram from FILE (stable solid, unstable dashed, BP/LP labelled)."""
    from contin import io
    from contin.cli._runctl import check_nonempty

    x, y = check_nonempty(x, "-x"), check_nonempty(y, "-y")  # "" fell back to the default axis silently
    io.check_writable(output)
    branches, meta = io.load(file)
    warn_if_incomplete(file, meta)
    if branch_ids:
        known = [b.id for b in branches]
        missing = [i for i in branch_ids if i not in known]
        if missing:
            fail(f"no branch {missing[0]!r} in {file}; branches: {', '.join(known)}")
        branches = [b for b in branches if b.id in branch_ids]
    if not branches:
        fail(f"{file} holds no branches")
    x = x or meta.get("diagram_x") or Counter(b.parameter for b in branches).most_common(1)[0][0]
    y = y or meta.get("diagram_y") or "phi"

    import numpy as np

    from contin.plot import branch_values, plot_diagram, save_figure

    # a branch with no finite (x, y) pair is an empty line: say so (an all-NaN column drew an
    # empty figure, exit 0); nothing to draw at all is an error, and no figure is written
    empty = [b.id for b in branches if len(b) and not np.any(np.isfinite(branch_values(b, x))
                                                              & np.isfinite(branch_values(b, y)))]
    if empty and len(empty) == len([b for b in branches if len(b)]):
        fail(f"nothing to draw: no branch of {file} has a point with finite {x} and {y}")
    for bid in empty:
        echo_err(f"warning: branch {bid} has no point with finite {x} and {y}; it is not drawn")
    ax = plot_diagram(branches, x, y)
    if title:
        fixed = {k: v for k, v in meta.get("parameters", {}).items() if k != x}
        ptxt = ", ".join(f"{k}={v:g}" if isinstance(v, float | int) else f"{k}={v}" for k, v in fixed.items())
        ax.set_title(f"{meta.get('scene') or ''}  {ptxt}".strip(), fontsize=8)
    save_figure(ax.figure, output)
    echo_err(f"wrote {output}")
