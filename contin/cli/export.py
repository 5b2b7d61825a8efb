"""``contin export FILE.h5 --auto NAME``: a stored run as AUTO-07p's b.NAME and s.NAME
(:mod:`contin.autoformat`), for AUTO's plotting (``@pp NAME``) and restarts (``IRS`` from s.NAME)."""

from __future__ import annotations

import click

from contin.cli._base import echo_err, fail, main, warn_if_incomplete

#: largest AUTO PAR index --par accepts (every s-block holds NPAR = the largest index values)
MAX_PAR = 1000


def parse_par(text: str | None) -> dict[str, int] | None:
    """``D=1,B=2,beta=3`` -> {'D': 1, 'B': 2, 'beta': 3}; None when not given."""
    if text is None:
        return None
    out: dict[str, int] = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        try:
            index = int(value)
        except ValueError:
            index = 0
        if not sep or not name.strip() or index < 1:
            fail(f"--par expects NAME=INDEX items with INDEX >= 1 (e.g. D=1,B=2), got {item!r}")
        if index > MAX_PAR:  # PAR(3000000) wrote a 296 MB s-file (NPAR PAR values per block)
            fail(f"--par {item.strip()}: AUTO's PAR indices are small (at most {MAX_PAR} here)")
        if name.strip() in out:  # D=1,...,D=4 kept the last silently
            fail(f"--par gives {name.strip()!r} twice ({name.strip()}={out[name.strip()]}, {item.strip()})")
        out[name.strip()] = index
    return out


@main.command("export")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option("--auto", "name", required=True, metavar="NAME",
              help="Write AUTO-07p's b.NAME (diagram) and s.NAME (labelled solutions).")
@click.option("-d", "--dir", "directory", type=click.Path(file_okay=False), default=".", show_default=True,
              help="Directory of the two files.")
@click.option("--par", "par", default=None, metavar="NAME=I,...",
              help="AUTO's PAR index of each parameter (default: the stored order, PAR(1), PAR(2), ...).")
def export_command(file: str, name: str, directory: str, par: str | None) -> None:
    """Write the run in FILE as AUTO-07p's output files b.NAME and s.NAME."""
    from pathlib import Path

    from contin import io
    from contin.autoformat import write_auto

    indices = parse_par(par)
    if not Path(directory).is_dir():
        fail(f"--dir {directory}: no such directory")
    branches, meta = io.load(file)
    warn_if_incomplete(file, meta)
    try:
        b_path, s_path, notes = write_auto(branches, name, directory, indices,
                                             cycles=(meta.get("extra") or {}).get("cycles"))
    except ValueError as exc:
        fail(str(exc))
    for note in notes:
        echo_err(f"note: {note}")
    click.echo(f"wrote {b_path} and {s_path}")
