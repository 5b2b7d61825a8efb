"""``contin info FILE.h5``: provenance, branches and special points of a stored run."""

from __future__ import annotations

import click

from contin.cli._base import branches_table, continued_from, echo_json, fmt, main, special_points_table


@main.command("info")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def info_command(file: str, as_json: bool) -> None:
    """Summarise FILE: provenance, branches (status, points) and special points."""
    from contin import io
    from contin.jsonout import run_document

    branches, meta = io.load(file)
    prov = {k: meta[k] for k in ("format_version", "contin_version", "git_commit", "created_utc", "command",
                                 "complete")}
    if meta.get("libraries"):  # files written before session 18 do not record them
        prov["libraries"] = ", ".join(f"{k} {v}" for k, v in meta["libraries"].items())
    if as_json:
        # why an incomplete run stopped ('interrupted', 'terminated by SIGTERM', 'failed: ...'; '' when
        # complete): the text says it, the JSON said only complete: false (qa18)
        echo_json(run_document(scene=meta["scene"], parameters=meta["parameters"],
                               discretization=meta["discretization"], branches=branches,
                               notes=meta["notes"], extra=meta["extra"],
                               provenance={**prov, "stopped": str(meta.get("stopped") or "")},
                               options=meta["options"], audit={b.id: list(b.audit) for b in branches}))
        return
    click.echo(f"file:           {file}")
    click.echo(f"scene:          {meta['scene']}")
    click.echo("parameters:     " + ", ".join(f"{k}={fmt(v)}" for k, v in meta["parameters"].items()))
    click.echo("discretization: " + ", ".join(f"{k}={fmt(v)}" for k, v in meta["discretization"].items()))
    for key, value in prov.items():
        click.echo(f"{key + ':':<16}{value}")
    if not meta["complete"]:
        stopped = meta.get("stopped", "")
        if stopped.startswith("failed"):  # an error, not an interrupt: --resume would fail the same way
            click.echo(f"                (incomplete: the run {stopped})")
        elif continued_from(meta) is not None:  # a `contin continue` curve (no --resume)
            click.echo(f"                (incomplete: the curve was {stopped or 'interrupted'}; `contin continue` "
                       f"computes it again from {continued_from(meta)})")
        elif isinstance(meta.get("extra"), dict) and "depth" in meta["extra"]:  # --depth refuses --resume
            click.echo(f"                (incomplete: the run was {stopped or 'interrupted'}; a --depth run is started "
                       f"again from scratch)")
        else:
            click.echo(f"                (incomplete: the run was {stopped or 'interrupted'}; continue it with --resume)")
    for note in meta["notes"]:
        click.echo(f"note: {note}")
    click.echo("")
    click.echo(branches_table(branches))
    click.echo("")
    click.echo(special_points_table(branches))
    for b in branches:
        if b.grid is not None:  # adaptive resolution: the grid column and where it changes
            changes = ", ".join(f"{old}->{new} at {b.parameter}={fmt(float(b.parameter_values[i]))}"
                                for i, old, new in b.grid_changes) or "none"
            click.echo(f"\ngrid of branch {b.id}: {int(min(b.grid))}..{int(max(b.grid))}; changes: {changes}")
        if b.n_unstable is not None and b.kind in ("periodic-orbits", "lpc-curve"):  # (Floquet multipliers)
            nu = [int(v) for v in b.n_unstable]
            click.echo(f"\nFloquet multipliers of branch {b.id}: outside the unit circle {min(nu)}..{max(nu)}, "
                       f"stable at {int(sum(b.stable))} of {len(b)} points")
        elif b.n_unstable is not None:
            kx, kz = b.stability_k or (0.0, 0.0)
            nu = [int(v) for v in b.n_unstable]
            click.echo(f"\nstability of branch {b.id} (kx={fmt(kx)}, kz={fmt(kz)}): n_unstable "
                       f"{min(nu)}..{max(nu)}, {sum(v < 0 for v in nu)} point(s) unknown")
        if b.audit:
            click.echo(f"audit of branch {b.id}:")
            for message in b.audit:
                click.echo(f"  {message}")
