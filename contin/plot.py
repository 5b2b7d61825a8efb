"""Bifurcation diagrams and solution profiles in AUTO/PLAUT style (matplotlib, Agg backend).

Conventions: stable parts of a branch solid, unstable parts dashed (so greyscale print keeps
the information), plain solid when stability is unknown; special points as markers labelled
with their AUTO name (``BP1``, ``LP2``) offset in points; a hollow square marks a point whose
location did not converge.  Nothing here calls ``plt.show()``: figures made here are plain
:class:`matplotlib.figure.Figure` objects (no pyplot state, rendered by Agg), and
:func:`save_figure` writes atomically.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from contin.atomic import publish
from contin.branch import Branch, SpecialPoint

__all__ = [
    "MARKERS",
    "branch_values",
    "plot_branch",
    "plot_diagram",
    "plot_eigenfunction",
    "plot_growth_rate",
    "plot_orbits",
    "plot_profiles",
    "save_figure",
    "stability_runs",
]

#: marker, face colour per AUTO type (BifurcationKit: fold black, BP blue, Hopf red)
MARKERS: dict[str, tuple[str, str]] = {
    "BP": ("o", "tab:blue"),
    "LP": ("o", "black"),
    "HB": ("o", "tab:red"),
    "UZ": ("D", "tab:green"),
    "XT": ("^", "tab:purple"),
    "CP": ("v", "tab:orange"),
    "BT": ("s", "tab:red"),
    "GH": ("P", "tab:red"),
    "ZH": ("*", "tab:purple"),
    "HH": ("h", "tab:red"),
    "MX": ("X", "tab:red"),
    "EP": ("|", "grey"),
    # periodic orbits (contin.cycles): fold, period doubling, torus (AUTO's LP, PD, TR of IPS = 2)
    "LPC": ("o", "black"),
    "PD": ("d", "tab:blue"),
    "NS": ("p", "tab:green"),
}
STABLE_STYLE = "-"
UNSTABLE_STYLE = "--"
#: the neutral-saddle part of a Hopf curve (kappa < 0, past a BT)
NEUTRAL_SADDLE_STYLE = ":"


def branch_values(branch: Branch, name: str) -> np.ndarray:
    """The column ``name`` of a branch: a parameter, an observable ('phi'), or ``'phi'`` = NaN
    when the problem has no order parameter.  ValueError naming the available columns."""
    if name in branch.params:
        return np.asarray(branch.params[name], dtype=float)
    if name in branch.observables:
        return np.asarray(branch.observables[name], dtype=float)
    if name == "phi":
        return np.full(len(branch), np.nan)
    known = ", ".join([*branch.params, *branch.observables])
    raise ValueError(f"branch {branch.id} has no parameter or observable {name!r}; available: {known}")


def _point_value(branch: Branch, sp: SpecialPoint, name: str) -> float:
    """Value of ``name`` at a located special point (falls back to the branch row)."""
    if name in sp.params:
        return float(sp.params[name])
    if name == "phi":
        return float(sp.order_parameter)
    col = branch_values(branch, name)
    return float(col[min(max(sp.index, 0), len(col) - 1)]) if len(col) else float("nan")


def stability_runs(stable: np.ndarray | None, n: int) -> list[tuple[int, int, bool | None]]:
    """Maximal runs ``(first, last, stable)`` of points ``0..n-1`` with equal stability.

    Runs are disjoint; :func:`plot_branch` joins run k to run k+1 through the segment
    between their boundary points (``last`` of run k and ``first`` of run k+1), drawn in the
    style of run k+1 and split at the located special point when there is one.
    """
    if n == 0:
        return []
    if stable is None:
        return [(0, n - 1, None)]
    s = np.asarray(stable, dtype=bool)
    change = np.flatnonzero(s[1:] != s[:-1]) + 1
    starts = np.concatenate([[0], change])
    stops = np.concatenate([change - 1, [n - 1]])
    return [(int(a), int(b), bool(s[a])) for a, b in zip(starts, stops)]


def plot_branch(
    branch: Branch,
    x: str | None = None,
    y: str = "phi",
    ax: Axes | None = None,
    *,
    label: str | None = None,
    special: Iterable[str] | None = ("BP", "LP", "HB", "UZ", "XT", "CP", "BT", "GH", "ZH", "HH", "MX", "LPC", "PD", "NS"),
    annotate: bool = True,
    **line_kw: Any,
) -> list[Any]:
    """Draw one branch: ``y`` against ``x`` (default x = the continuation parameter).

    Stable runs solid, unstable dashed (split where ``branch.stable`` changes, repeating the
    boundary point); special points of the types in ``special`` as markers labelled with their
    name.  Extra keywords go to :meth:`Axes.plot`.  Returns the created artists.
    """
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.gca()
    x = x or branch.parameter
    xs, ys = branch_values(branch, x), branch_values(branch, y)
    color = line_kw.pop("color", None)
    lw = line_kw.pop("linewidth", line_kw.pop("lw", 1.5))
    artists: list[Any] = []
    first = True
    # a Hopf curve past a BT continues as neutral saddles (kappa = omega^2 < 0): drawn dotted, so
    # that it is not read as Hopf points
    saddles = branch.kind == "hopf-curve" and branch.stable is None and "kappa" in branch.observables
    runs = stability_runs(branch.observables["kappa"] > 0 if saddles else branch.stable, len(branch))
    join: dict[int, tuple[float, float]] = {}  # boundary index -> located point splitting it
    for _, b, _ in runs[:-1]:
        for sp in branch.special_points:
            if sp.index == b and sp.type in ("BP", "HB", "LP", "BT", "LPC", "PD", "NS"):
                px, py = _point_value(branch, sp, x), _point_value(branch, sp, y)
                if np.isfinite(px) and np.isfinite(py):
                    join[b] = (px, py)
                    break
    for k, (a, b, st) in enumerate(runs):
        style = (NEUTRAL_SADDLE_STYLE if saddles else UNSTABLE_STYLE) if st is False else STABLE_STYLE
        rx, ry = list(xs[a : b + 1]), list(ys[a : b + 1])
        if k > 0:  # start at the previous run's last point, or at the special point between
            px, py = join.get(a - 1, (xs[a - 1], ys[a - 1]))
            rx, ry = [px, *rx], [py, *ry]
        if k < len(runs) - 1 and b in join:
            rx.append(join[b][0])
            ry.append(join[b][1])
        (line,) = ax.plot(rx, ry, linestyle=style, color=color,
                          linewidth=lw if st is not False else 0.8 * lw,
                          label=(label if first else None), **line_kw)
        color = color or line.get_color()  # one colour for all runs of the branch
        kind = ("hopf" if st else "neutral-saddle") if saddles else ("stable" if st else "unstable" if st is False else "unknown")
        line.set_gid(f"branch-{branch.id}-{kind}")
        artists.append(line)
        first = False
    types = set(special or ())
    # points at one position (a cusp is also an LP and an XT of its curve) share one annotation,
    # "CP3, LP4, XT5", instead of three labels printed over each other
    names: dict[tuple[float, float], list[str]] = {}
    for sp in branch.special_points:
        if sp.type in types:
            names.setdefault(_position(branch, sp, x, y), []).append(sp.name)
    for sp in branch.special_points:
        if sp.type not in types:
            continue
        px, py = _point_value(branch, sp, x), _point_value(branch, sp, y)
        if not (np.isfinite(px) and np.isfinite(py)):
            continue
        shared = names.get(_position(branch, sp, x, y), [sp.name])
        marker, face = MARKERS.get(sp.type, ("o", "grey"))
        if sp.converged:
            art = ax.plot([px], [py], marker=marker, color=face, markersize=5, linestyle="none", zorder=3)[0]
        else:  # honest about points whose location failed
            art = ax.plot([px], [py], marker="s", color=face, markerfacecolor="none", markeredgecolor=face,
                          markersize=6, linestyle="none", zorder=3)[0]
        art.set_gid(f"sp-{sp.name}")
        artists.append(art)
        if annotate and shared[0] == sp.name:
            artists.append(ax.annotate(", ".join(shared), (px, py), xytext=(4, 4), textcoords="offset points",
                                       fontsize=7, color=face if sp.type != "LP" else "black"))
    return artists


def _position(branch: Branch, sp: SpecialPoint, x: str, y: str) -> tuple[float, float]:
    """A special point's plotted position to 6 digits (points located by different test
    functions at one place, e.g. a cusp and the extremum it is, differ in the last digits)."""
    return (float(f"{_point_value(branch, sp, x):.6g}"), float(f"{_point_value(branch, sp, y):.6g}"))


def plot_diagram(
    branches: Sequence[Branch],
    x: str | None = None,
    y: str = "phi",
    ax: Axes | None = None,
    *,
    legend: bool = True,
    **kw: Any,
) -> Axes:
    """Bifurcation diagram of several branches (one colour each); x defaults to the first
    branch's continuation parameter.  Branches lacking column ``x`` or ``y`` are skipped
    (ValueError if none has them)."""
    if ax is None:
        ax = Figure(figsize=(5.3, 3.6)).add_subplot()
    if not branches:
        raise ValueError("no branches to plot")
    x = x or branches[0].parameter
    drawn = 0
    for b in branches:
        try:
            branch_values(b, x)
            branch_values(b, y)
        except ValueError:
            continue
        plot_branch(b, x, y, ax, label=f"{b.id} ({b.kind})" if b.kind else str(b.id), **kw)
        drawn += 1
    if drawn == 0:
        branch_values(branches[0], x)  # raises the ValueError naming the available columns
        branch_values(branches[0], y)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    if legend and drawn > 1:
        ax.legend(fontsize=7, frameon=False)
    return ax


def plot_profiles(
    y: np.ndarray,
    profiles: Mapping[str, np.ndarray],
    names: Sequence[str] | None = None,
    labels: Sequence[str] | None = None,
    axes: Sequence[Axes] | None = None,
) -> Figure:
    """Solution profiles against the wall-normal coordinate, one panel per quantity.

    ``profiles[name]`` has shape (N,) or (M, N) (M profiles, e.g. several branches), N = len(y);
    ``labels`` names the M curves.
    """
    names = list(names or profiles)
    if not names:
        raise ValueError("no profiles to plot")
    y = np.asarray(y, dtype=float)
    if axes is None:
        axes = list(Figure(figsize=(2.0 * len(names) + 1, 3.0)).subplots(1, len(names), squeeze=False)[0])
    fig = axes[0].figure
    for ax, name in zip(axes, names):
        if name not in profiles:
            raise ValueError(f"no profile {name!r}; available: {', '.join(profiles)}")
        data = np.atleast_2d(np.asarray(profiles[name], dtype=float))
        if data.shape[1] != y.size:
            raise ValueError(f"profile {name!r} has {data.shape[1]} points but y has {y.size}")
        for i, row in enumerate(data):
            ax.plot(y, row, label=None if labels is None else labels[i])
        ax.set_xlabel("y")
        ax.set_ylabel(name)
    if labels is not None:
        axes[0].legend(fontsize=7, frameon=False)
    fig.tight_layout()
    return fig


def plot_growth_rate(
    kx: np.ndarray,
    growth: np.ndarray,
    phase_speed: np.ndarray,
    *,
    title: str | None = None,
) -> Figure:
    """Dispersion curve of a steady state: two panels against k_x, the growth rate
    max Re omega (zero line dotted; unstable where above it) and the phase speed
    c = Im omega / |k| of the least-stable mode (nan points, e.g. k = 0, are left out)."""
    kx = np.asarray(kx, dtype=float)
    growth = np.asarray(growth, dtype=float)
    phase_speed = np.asarray(phase_speed, dtype=float)
    if not (kx.shape == growth.shape == phase_speed.shape) or kx.ndim != 1 or kx.size == 0:
        raise ValueError(f"kx, growth and phase_speed must be equal-length 1-d arrays, got shapes "
                         f"{kx.shape}, {growth.shape}, {phase_speed.shape}")
    fig = Figure(figsize=(5.0, 4.6))
    ax_g, ax_c = fig.subplots(2, 1, sharex=True)
    marker = "o" if kx.size < 3 else None
    ax_g.plot(kx, growth, marker=marker, color="tab:blue", gid="growth-rate")
    ax_g.axhline(0.0, color="grey", linewidth=0.6, linestyle=":")
    ax_g.set_ylabel(r"max Re $\omega$")
    ok = np.isfinite(phase_speed)
    ax_c.plot(kx[ok], phase_speed[ok], marker=marker, color="tab:orange", gid="phase-speed")
    ax_c.set_ylabel(r"$c = \mathrm{Im}\,\omega / |k|$")
    ax_c.set_xlabel(r"$k_x$")
    if title:
        ax_g.set_title(title, fontsize=8)
    fig.tight_layout()
    return fig


def plot_eigenfunction(
    y: np.ndarray,
    profiles: Mapping[str, np.ndarray],
    *,
    title: str | None = None,
) -> Figure:
    """Complex eigenfunction profiles, one panel per field: real part solid, imaginary part
    dashed (the caller normalises, e.g. largest component 1)."""
    y = np.asarray(y, dtype=float)
    names = list(profiles)
    if not names:
        raise ValueError("no eigenfunction profiles to plot")
    fig = Figure(figsize=(2.0 * len(names) + 1, 3.0))
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    for ax, name in zip(axes, names):
        f = np.asarray(profiles[name], dtype=complex)
        if f.shape != y.shape:
            raise ValueError(f"eigenfunction {name!r} has shape {f.shape} but y has {y.shape}")
        ax.plot(y, f.real, STABLE_STYLE, color="tab:blue", label="Re", gid=f"{name}-re")
        ax.plot(y, f.imag, UNSTABLE_STYLE, color="tab:red", label="Im", gid=f"{name}-im")
        ax.set_xlabel("y")
        ax.set_title(f"{name} (perturbation)", fontsize=9)
    axes[0].legend(fontsize=7, frameon=False)
    if title:
        fig.suptitle(title, fontsize=8)
    fig.tight_layout()
    return fig


def plot_orbits(
    orbits: Sequence[tuple[str, np.ndarray, np.ndarray]],
    components: Sequence[int],
    *,
    title: str | None = None,
) -> Figure:
    """Periodic orbits ``(label, t, u)`` (t in [0, T], u of shape (len(t), n)): u_i(t) of the
    chosen components over one period, and with two components or more the phase portrait
    (u_a, u_b) of the first two.  Line gids: ``"{label}:u{i}"`` and ``"{label}:phase"`` (i from 1)."""
    if not orbits or not components:
        raise ValueError("no orbit or no component to plot")
    phase = len(components) >= 2
    fig = Figure(figsize=(7.5 if phase else 4.0, 3.0))
    axes = fig.subplots(1, 2 if phase else 1, squeeze=False)[0]
    for label, t, u in orbits:
        for i in components:
            axes[0].plot(t, u[:, i], label=f"{label}: u{i + 1}" if len(orbits) > 1 else f"u{i + 1}",
                         gid=f"{label}:u{i + 1}")
        if phase:
            a, b = components[0], components[1]
            axes[1].plot(u[:, a], u[:, b], label=label, gid=f"{label}:phase")
    axes[0].set_xlabel("t (one period)")
    axes[0].legend(fontsize=7, frameon=False)
    if phase:
        axes[1].set_xlabel(f"u{components[0] + 1}")
        axes[1].set_ylabel(f"u{components[1] + 1}")
        if len(orbits) > 1:
            axes[1].legend(fontsize=7, frameon=False)
    if title:
        fig.suptitle(title, fontsize=8)
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, path: str | os.PathLike[str], **kw: Any) -> Path:
    """``fig.savefig`` to PATH atomically (temporary file in the same directory, then rename).

    The format comes from the extension (png, pdf, svg...).
    """
    p = Path(path)
    fmt = kw.pop("format", None) or p.suffix.lstrip(".").lower() or "png"
    options = {"dpi": 150, "bbox_inches": "tight", **kw}
    return publish(p, lambda tmp: fig.savefig(tmp, format=fmt, **options), temporary=p.with_name(f".{p.name}.tmp"))
