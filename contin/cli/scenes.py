"""``contin scenes``: list the registered scenes."""

from __future__ import annotations

import click

from contin.cli._base import echo_err, echo_json, fmt, main


@main.command("scenes")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
def scenes_command(as_json: bool) -> None:
    """List available scenes with their summaries and default parameters."""
    import contin.scene as scene_mod

    scenes = scene_mod.available_scenes()
    errors = list(scene_mod.SCENE_LOAD_ERRORS)
    if as_json:
        echo_json({
            "scenes": [{"name": s.name, "summary": s.summary, "defaults": dict(s.defaults),
                        "x": s.x, "y": s.y, "depth": s.start is not None} for s in scenes.values()],
            "load_errors": [{"source": src, "error": err} for src, err in errors],
        })
        return
    if not scenes:
        click.echo("no scenes registered")
    for name, s in scenes.items():
        click.echo(f"{name}: {s.summary}" + (" [--depth]" if s.start is not None else ""))
        if s.defaults:
            click.echo("    " + "  ".join(f"{k}={fmt(v)}" for k, v in s.defaults.items()))
    for src, err in errors:
        echo_err(f"warning: scenes from {src} not loaded: {err}")
