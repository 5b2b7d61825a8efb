"""``contin stability FILE.h5``: dispersion curve and least-stable mode of one stored state.

The problem is rebuilt with the scene's ``problem_factory(parameters, discretization)`` from
the file's root attributes (see :mod:`contin.scene`); the state is row INDEX of
``/branches/ID/states`` or a located special point (``--point LP1``), and its parameters are the
file's parameters updated with the branch's columns at that point (or the special point's own
parameters).  For every k_x the generalized eigenproblem A X = omega B X of
``problem.eigenproblem(u, p, kx=..., kz=...)`` (or J x = omega M x at k = 0 for problems
without one) is solved by dense QZ (:func:`contin.stability.eigenpairs`).
"""

from __future__ import annotations

import math
from typing import Any

import click

from contin.cli._base import echo_err, echo_json, fail, fmt, main, table
from contin.cli._runctl import MAX_ABS_KX, MAX_KX

#: leading eigenvalues listed per k_x in the JSON document
N_LEADING = 6
#: matrices up to this size use dense QZ (all finite eigenvalues: the true max Re omega)
DENSE_MAX = 2000


def _refuse_without_stability(meta: dict[str, Any], file: str) -> None:
    """One ``Error:`` line (exit 1) when the file's scene declares no linear-stability operator
    (``Scene.stability = False``): its problem's algebraic rows would count as unstable modes.
    An unknown scene is left to :func:`contin.restart.rebuild_problem`, which names it."""
    from contin.scene import get_scene

    name = str(meta.get("scene") or "")
    try:
        scene = get_scene(name) if name else None
    except ValueError:
        return
    if scene is not None and not scene.stability:
        fail(f"scene {name!r} of {file} has no linear-stability operator (its problem's boundary and constraint "
             "rows have no mass matrix to tell them from dynamics), so the stability of its states is not computed")


#: ``--kx`` without a value, for problems with ``eigenproblem(u, p, kx, kz)``.
DEFAULT_KX = "0:3:61"


def parse_kx_spec(text: str) -> list[float]:
    """``a:b:n`` (n equally spaced values from a to b), ``k1,k2,...`` or one value.

    Raises ValueError with one sentence for anything else (non-numbers, NaN/inf, n < 1,
    a range with n = 1 and a != b).
    """
    t = text.strip()
    bad = f"bad --kx {text!r}: expected START:STOP:COUNT (e.g. 0:3:61), a comma-separated list or one number"
    try:
        if ":" in t:
            parts = t.split(":")
            if len(parts) != 3:
                raise ValueError(bad)
            a, b = float(parts[0]), float(parts[1])
            n = int(parts[2])
            if n < 1:
                raise ValueError(f"bad --kx {text!r}: COUNT must be at least 1")
            if n > MAX_KX:  # 0:3:1000000000 never ended
                raise ValueError(f"bad --kx {text!r}: COUNT must be at most {MAX_KX}")
            if n == 1 and a != b:
                raise ValueError(f"bad --kx {text!r}: COUNT = 1 needs START = STOP")
            values = [a + (b - a) * i / (n - 1) for i in range(n)] if n > 1 else [a]
        else:
            values = [float(x) for x in t.split(",") if x.strip()]
    except ValueError as exc:
        raise ValueError(str(exc) if str(exc).startswith("bad --kx") else bad) from None
    if not values:
        raise ValueError(bad)
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"bad --kx {text!r}: wavenumbers must be finite numbers")
    if len(values) > MAX_KX or max(abs(v) for v in values) > MAX_ABS_KX:
        raise ValueError(f"bad --kx {text!r}: at most {MAX_KX} wavenumbers with |kx| <= {MAX_ABS_KX:g}")
    return values


def _numeric(values: dict[str, Any]) -> dict[str, float]:
    return {k: float(v) for k, v in values.items()
            if isinstance(v, int | float) and not isinstance(v, bool)}


def _is_index(point: str) -> bool:
    """Whether ``--point`` gives an index (an integer, e.g. 12 or -1) rather than a label."""
    try:
        int(point)
    except ValueError:
        return False
    return True


def resolve_point(branch: Any, point: str, fixed: dict[str, float], file: str) -> tuple[Any, dict[str, float], int | str]:
    """(state, parameters, point) of ``point``: an index (returned as int, normalised to
    0..S-1) or a special-point label (returned as its name, e.g. 'LP1')."""
    import numpy as np

    s = len(branch)
    if s == 0:  # a branch that could not start ('point 0 is out of range: ... has 0 points (0..-1)')
        fail(f"branch {branch.id} of {file} has no stored points ({branch.status}: {branch.message})")
    try:
        index = int(point)
    except ValueError:
        index = None
    if index is not None:
        if not -s <= index < s:
            fail(f"point {index} is out of range: branch {branch.id} of {file} has {s} points (0..{s - 1})")
        index = range(s)[index]
        try:
            state = branch.state(index)
        except KeyError:
            fail(f"the state of point {index} of branch {branch.id} was not saved in {file} (save_every > 1)")
        row = {name: float(values[index]) for name, values in branch.params.items()}
        return np.asarray(state, dtype=float), {**fixed, **row}, index
    match = [sp for sp in branch.special_points if sp.name.lower() == point.strip().lower()]
    if not match:
        labels = ", ".join(sp.name for sp in branch.special_points) or "none"
        fail(f"no point {point!r} on branch {branch.id} of {file}: give an index 0..{s - 1} "
             f"or a special-point label ({labels})")
    sp = match[0]
    if sp.state is None or not np.all(np.isfinite(sp.state)):
        fail(f"special point {sp.name} of branch {branch.id} has no stored state")
    i = min(max(sp.index, 0), s - 1)
    row = {name: float(values[i]) for name, values in branch.params.items()}
    return np.asarray(sp.state, dtype=float), {**fixed, **row, **_numeric(dict(sp.params))}, sp.name


def first_crossing_of(branch: Any, name: str, value: float) -> int | None:
    """Index of the first stored point of the step where ``name`` crosses ``value`` (None if none)."""
    from contin.branch import first_crossing

    crossing = first_crossing(branch.params[name], value) if name in branch.params else None
    return None if crossing is None else crossing[0]


def parse_at(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` of ``--at`` (e.g. 'H=25')."""
    name, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not sep or not name.strip() or not math.isfinite(number):
        fail(f"--at needs NAME=VALUE with a finite number, e.g. --at H=25; got {text!r}")
    return name.strip(), number


def state_at(problem: Any, branch: Any, name: str, value: float, fixed: dict[str, float],
             file: str) -> tuple[Any, dict[str, float], str]:
    """The solution on ``branch`` where parameter ``name`` equals ``value``: the first stored
    step that brackets it, linearly interpolated and corrected by Newton at ``name = value``
    (a stored state, not a plot interpolation, is what the eigenproblem needs)."""
    import numpy as np

    from contin.branch import first_crossing
    from contin.newton import newton

    if name not in branch.params:
        fail(f"branch {branch.id} of {file} has no parameter {name!r} (it has {', '.join(branch.params)})")
    values = np.asarray(branch.params[name], dtype=float)
    if len(values) and np.all(values == values[0]):  # every point "crossed" it: the first point was taken
        fail(f"{name} is constant ({values[0]:g}) along branch {branch.id} of {file}: --at needs a parameter that "
             f"varies along the branch, e.g. --at {branch.parameter}=...")
    crossing = first_crossing(branch.params[name], value)
    if crossing is None:
        fail(f"branch {branch.id} of {file} does not reach {name} = {value:g} "
             f"(it spans {name} = {branch.params[name].min():.6g} .. {branch.params[name].max():.6g})")
    i, j, w, count = crossing
    try:
        xi, xj = branch.state(i), branch.state(j)
        if branch.grid is not None and branch.grid_at(j) != branch.grid_at(i):  # a grid change in the step
            from contin.adapt import on_grid

            xj = on_grid(problem, branch.grid_at(j)).transfer(xj, problem)
    except KeyError:
        fail(f"the states around {name} = {value:g} on branch {branch.id} were not saved in {file} (save_every > 1)")
    row = {k: float(vals[i]) for k, vals in branch.params.items()}
    params = {**fixed, **row, name: value}
    res = newton(problem, (1 - w) * np.asarray(xi, float) + w * np.asarray(xj, float), params)
    if not res.converged:
        fail(f"Newton at {name} = {value:g} on branch {branch.id} did not converge: {res.message}")
    if count > 1:
        echo_err(f"note: branch {branch.id} crosses {name} = {value:g} {count} times; "
                 f"using the first (after point {i})")
    return res.u, params, f"{name}={value:g}"


def _eigenfunction(problem: Any, state: Any, vec: Any, y: Any) -> tuple[Any, dict[str, Any]]:
    """Named eigenfunction profiles: the problem's ``eigenvector_profiles`` or equal blocks on y."""
    import numpy as np

    from contin.problem import has

    if has(problem, "eigenvector_profiles"):
        return problem.eigenvector_profiles(state, vec)
    if y is not None and len(y) and vec.size % len(y) == 0:
        blocks = vec.reshape(-1, len(y))
        return np.asarray(y), {f"x{k}": blk for k, blk in enumerate(blocks)}
    return np.arange(vec.size, dtype=float), {"x": vec}


@main.command("stability")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option("--branch", "branch_id", default=None, metavar="ID",
              help="Branch id [default: the only branch of FILE].")
@click.option("--point", default=None, metavar="INDEX|LABEL",
              help="Point index along the branch (negative counts from the end) or special-point label (LP1, BP2).")
@click.option("--at", "at", default=None, metavar="NAME=VALUE",
              help="Instead of --point: the state where a parameter has this value (e.g. H=25), corrected by Newton; "
                   "the first crossing along the branch.")
@click.option("--kx", "kx_spec", default=None, metavar="SPEC",
              help="Streamwise wavenumbers: START:STOP:COUNT, a comma list, or one value "
                   "(at most 10000 values, finite, |kx| <= 1e4) [default: 0:3:61 for problems with a "
                   "wavenumber family (eigenproblem), else 0].")
@click.option("--kz", type=float, default=0.0, help="Spanwise wavenumber.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document to stdout.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Figure of growth rate and phase speed against kx (.png, .pdf, .svg).")
@click.option("--eigenfunction", is_flag=True,
              help="Also plot the least-stable eigenfunction at the first kx (to FIG_eigenfunction.EXT; needs -o).")
def stability_command(file: str, branch_id: str | None, point: str | None, at: str | None, kx_spec: str, kz: float,
                      as_json: bool, output: str | None, eigenfunction: bool) -> None:
    """Growth rate max Re omega and phase speed of the least-stable mode against kx, for one state of FILE.

    Perturbations exp(i kx x + i kz z + omega t); c = Im omega / sqrt(kx^2 + kz^2) (null at k = 0).
    """
    import numpy as np

    from contin import io
    from contin.restart import rebuild_problem
    from contin.stability import count_unstable, eigenpairs, operator_pair

    if (point is None) == (at is None):
        fail("give exactly one of --point INDEX|LABEL and --at NAME=VALUE")
    at_spec = parse_at(at) if at is not None else None
    kx_values = parse_kx_spec(kx_spec if kx_spec is not None else DEFAULT_KX)
    if not (math.isfinite(kz) and abs(kz) <= MAX_ABS_KX):
        fail(f"--kz must be a finite number with |kz| <= {MAX_ABS_KX:g}, got {kz}")
    eig_path = None
    if eigenfunction:
        if output is None:
            fail("--eigenfunction needs -o FIG (the eigenfunction goes to FIG_eigenfunction.EXT)")
        from pathlib import Path

        p = Path(output)
        eig_path = p.with_name(f"{p.stem}_eigenfunction{p.suffix or '.png'}")
    if output is not None:
        io.check_writable(output)
        if eig_path is not None:
            io.check_writable(eig_path)

    branches, meta = io.load(file)
    _refuse_without_stability(meta, file)
    ids = [b.id for b in branches]
    if not branches:  # it said "holds 0 branches; choose one with --branch (none)" (qa15)
        fail(f"{file} holds no branches")
    if branch_id is None and len(branches) != 1 and point is not None and not _is_index(point):
        # a label names its branch (labels are unique in a run file): `--point BP2` of a run with
        # several branches asked for --branch all the same (qa18); an ambiguous label still does
        from contin.restart import find_point

        try:
            branch_id = find_point(branches, point, None, file)[0].id
        except ValueError as exc:
            fail(str(exc))
    if branch_id is None:
        if len(branches) != 1:
            fail(f"{file} holds {len(branches)} branches; choose one with --branch ({', '.join(ids) or 'none'})")
        branch = branches[0]
    else:
        if branch_id not in ids:
            fail(f"no branch {branch_id!r} in {file}; branches: {', '.join(ids) or 'none'}")
        branch = branches[ids.index(branch_id)]
    if branch.kind == "periodic-orbits":  # states [orbit nodes, T]: "too many values to unpack"
        fail(f"branch {branch.id} of {file} holds periodic orbits: their stability is the Floquet multipliers "
             "stored with them (eigenvalues, stable: contin info), not the eigenvalues of a steady state")
    if len(branch.free) != 1:  # its states are augmented (u, phi, p2, ...): numpy's broadcast error
        # ('operands could not be broadcast together with shapes (37,) (75,)') or a size mismatch before
        fail(f"branch {branch.id} of {file} is a two-parameter curve ({branch.kind or 'curve'}, free {', '.join(branch.free)}): "
             "its stored states are augmented systems, not states of the problem; stability applies to "
             "one-parameter branches (the file the curve was continued from)")

    fixed = _numeric(dict(meta.get("parameters", {})))
    if point is not None:
        state, params, where = resolve_point(branch, point, fixed, file)

    scene_name = meta.get("scene") or ""
    try:
        problem = rebuild_problem({**meta, "path": file})
    except ValueError as exc:
        fail(str(exc))
    if branch.grid is not None:  # an adaptive run: every point is a solution on its own grid
        from contin.adapt import on_grid

        if at_spec is not None:
            crossing = first_crossing_of(branch, at_spec[0], at_spec[1])
            problem = on_grid(problem, branch.grid_at(crossing)) if crossing is not None else problem
        elif isinstance(where, int):
            problem = on_grid(problem, branch.grid_at(where))
        else:
            problem = on_grid(problem, next(sp.grid for sp in branch.special_points if sp.name == where))
    if at_spec is not None:
        state, params, where = state_at(problem, branch, *at_spec, fixed, file)
    size = getattr(problem, "size", None)
    if isinstance(size, int) and size != state.size:
        fail(f"the state has {state.size} entries but the problem rebuilt from {file} has {size} unknowns "
             f"(discretization {meta.get('discretization')})")
    missing = [n for n in getattr(problem, "parameter_names", ()) if n not in params]
    if missing:  # a file whose scene attribute names another scene, with states of the same size: a
        # stability table of the wrong problem came out with exit 0
        fail(f"the parameters of {file} have no {', '.join(map(repr, missing))}, which the rebuilt problem needs "
             "(is it a file of another scene?)")

    if kx_spec is None and not hasattr(problem, "eigenproblem"):
        # Only k = 0 exists for a problem without a wavenumber family (the demo scenes' Dirichlet
        # problems, Lorenz): the default range 0:3:61 made `contin stability br.h5 --point HB1`
        # fail with 'only kx = kz = 0 is available' unless --kx 0 was given (session 14).
        kx_values = [0.0]
    growth, speed, n_unst, leading = [], [], [], {}
    mode = None
    for j, kx in enumerate(kx_values):
        A, B = operator_pair(problem, state, params, kx=kx, kz=kz)
        want_vec = eigenfunction and j == 0
        w, v = eigenpairs(A, B, dense_max=DENSE_MAX, vectors=want_vec,
                          k=None if A.shape[0] <= DENSE_MAX else max(N_LEADING, 12))
        if w.size == 0:
            fail(f"the eigenproblem at kx={kx:g} has no finite eigenvalues")
        k = math.hypot(kx, kz)
        growth.append(float(w[0].real))
        speed.append(float(w[0].imag / k) if k > 0 else math.nan)
        n_unst.append(count_unstable(w))
        leading[f"{kx:.12g}"] = [[float(z.real), float(z.imag)] for z in w[:N_LEADING]]
        if want_vec:
            vec = v[:, 0]
            vec = vec / vec[np.argmax(np.abs(vec))]
            mode = (kx, complex(w[0]), *_eigenfunction(problem, state, vec, meta.get("y")))

    label = f"branch {branch.id}, point {where}"
    if output is not None:
        from contin.plot import plot_eigenfunction, plot_growth_rate, save_figure

        save_figure(plot_growth_rate(np.array(kx_values), np.array(growth), np.array(speed),
                                     title=f"{scene_name}: {label}, kz={kz:g}"), output)
        echo_err(f"wrote {output}")
        if mode is not None and eig_path is not None:
            kx0, om, y, prof = mode
            save_figure(plot_eigenfunction(y, prof, title=f"{label}: kx={kx0:g}, omega={om.real:.6g}{om.imag:+.6g}i"),
                        eig_path)
            echo_err(f"wrote {eig_path}")

    if as_json:
        doc: dict[str, Any] = {
            "branch": branch.id,
            "point": where,
            "params": params,
            "kz": kz,
            "kx": kx_values,
            "growth_rate": growth,
            "phase_speed": speed,
            "n_unstable": n_unst,
            "leading_eigenvalues": leading,
        }
        if mode is not None:
            kx0, om, y, prof = mode
            doc["eigenfunction"] = {"kx": kx0, "omega": [om.real, om.imag], "y": np.asarray(y),
                                    "fields": {n: {"re": np.real(f), "im": np.imag(f)} for n, f in prof.items()}}
        echo_json(doc)
    elif output is None:
        rows = [(fmt(kx, 6), fmt(g), fmt(c, 6), n) for kx, g, c, n in zip(kx_values, growth, speed, n_unst)]
        click.echo(f"{label} ({', '.join(f'{n}={fmt(v, 6)}' for n, v in params.items())}), kz={fmt(kz)}")
        click.echo(table(rows, ("kx", "growth rate", "phase speed", "n_unstable")))
