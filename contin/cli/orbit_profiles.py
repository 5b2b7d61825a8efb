"""``contin profiles ORBITS.h5 --at D=0.2`` / ``--point LPC1``: one periodic orbit of each branch
of a file of orbits, u_i(t) over one period and the phase portrait (``contin.orbitprofile``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from contin.cli._base import echo_err, fail

#: components drawn by default (an orbit of a discretized PDE has many)
DEFAULT_COMPONENTS = 8


def components(names: str | None, n: int) -> list[int]:
    """The 0-based components of ``--names u1,u3`` (default: the first DEFAULT_COMPONENTS)."""
    if names is None:
        return list(range(min(n, DEFAULT_COMPONENTS)))
    out = []
    for item in (x.strip() for x in names.split(",")):
        k = int(item[1:]) if item[:1] == "u" and item[1:].isdigit() else 0
        if not 1 <= k <= n:
            fail(f"--names: no component {item!r}; the orbits have u1..u{n}")
        out.append(k - 1)
    return out


def draw_orbits(file: str, branches: list[Any], meta: dict[str, Any], name: str, value: float, point: str | None,
                branch_ids: tuple[str, ...], names: str | None, output: str) -> None:
    from contin.orbitprofile import orbit_at, orbit_at_point, sample
    from contin.plot import plot_orbits, save_figure

    cycles = (meta.get("extra") or {}).get("cycles") or {}
    if "n" not in cycles or "ncol" not in cycles:
        fail(f"{file} holds periodic orbits but does not say their size n and NCOL (no 'cycles' entry): it was not "
             "written by contin continue --cycles")
    n, ncol = int(cycles["n"]), int(cycles["ncol"])
    if branch_ids:
        missing = [i for i in branch_ids if i not in {b.id for b in branches}]
        if missing:
            fail(f"no branch {missing[0]!r} in {file}; branches: {', '.join(b.id for b in branches)}")
        branches = [b for b in branches if b.id in branch_ids]
    if point is None and all(b.kind == "lpc-curve" for b in branches):
        fail(f"{file} holds an LPC curve: its orbits are drawn at its labelled points (--point GH2, ...), not --at a "
             "value (two parameters vary along it)")
    branches = [b for b in branches if b.kind in ("periodic-orbits", "lpc-curve")]
    if point is not None:
        try:
            found = [orbit_at_point(branches, point, n, ncol, where=file)]
        except ValueError as exc:
            fail(str(exc))
    else:
        if not any(name in b.params for b in branches):
            fail(f"no parameter {name!r} in {file}; its orbits vary {branches[0].parameter}")
        varying = [b for b in branches if name in b.params and len(b) and float(np.ptp(b.params[name])) > 0]
        if not varying:  # every orbit "is at" the value: one of them would be drawn as the orbit there
            b = next(b for b in branches if name in b.params)
            fail(f"{name} is constant along the orbits of {file} ({name} = {float(b.params[name][0]):g}): --at "
                 f"needs the parameter they vary, e.g. --at {b.parameter}=...")
        branches = varying
        from contin.restart import rebuild_problem

        try:  # to correct an interpolated orbit at the value
            problem = rebuild_problem({**meta, "path": file})
        except ValueError as exc:
            problem = None
            echo_err(f"note: an orbit between two stored ones is drawn interpolated, not corrected ({exc})")
        found = orbit_at(branches, name, value, n, ncol, problem)
        if not found:
            # the range each covers, its located points included (the value was shown rounded: 'reaches D=0.161696')
            spans = []
            for b in branches:
                vals = [float(v) for v in b.params[name]] + [float(sp.params[name]) for sp in b.special_points
                                                             if name in sp.params]
                spans.append(f"branch {b.id}: {name} = {min(vals):.10g} .. {max(vals):.10g}")
            fail(f"no branch of orbits in {file} reaches {name}={value:.10g} ({'; '.join(spans)})")
    wanted = components(names, n)
    data = [(f"{f.branch.id} {f.how.split(' (')[0]}", *sample(f.mesh, f.nodes, f.period)) for f in found]
    where = point or f"{name}={value:g}"
    fig = plot_orbits(data, wanted, title=f"{meta.get('scene') or ''} orbits at {where}".strip())
    save_figure(fig, output)
    for f in found:
        p = ", ".join(f"{k} = {v:.10g}" for k, v in f.params.items() if k == f.branch.parameter)
        echo_err(f"branch {f.branch.id}: {f.how}, {p}, period T = {f.period:.10g}")
        if f.doubt:
            echo_err(f"warning: branch {f.branch.id}: {f.doubt}; it is drawn as interpolated")
    if names is None and n > DEFAULT_COMPONENTS:
        echo_err(f"note: u1..u{DEFAULT_COMPONENTS} of {n} components drawn (choose others with --names)")
    echo_err(f"wrote {output}")
