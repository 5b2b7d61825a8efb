"""Export of a stored run to AUTO-07p's output files b.NAME (fort.7) and s.NAME (fort.8).

The files follow AUTO-07p's own writers (``python/auto/parseB.py`` and ``parseS.py`` of the
Debian package 0.9.x), so AUTO's tools read them: ``@pp NAME`` (PLAUT), the Python CLUI's
``loadbd('NAME')``, and the Fortran core itself, which restarts from a label of s.NAME (fort.3).

b.NAME, one section per branch (AUTO's branch number BR = position + 1):
    header lines starting with ``   0``: the bounds line (RL0 RL1 A0 A1), NDIM / IPS / ISW / NPAR
    in AUTO's layout, ``User-specified parameter:`` and ``Active continuation parameter:`` (the
    PAR indices of the branch's free parameters), ``parnames = {1: 'D', ...}`` (an AUTO constant:
    the contin names of PAR(1..)), then the column names; one line per point
    ``%4d%6d%4d%5d`` (BR, PT, TY, LAB) and 19-character values: the free parameters, L2-NORM
    (the Euclidean norm of u, AUTO's measure of algebraic problems), U(1..) (up to
    :data:`MAX_U_COLUMNS`, for problems of at most that many unknowns), contin's order parameter
    and observables.  PT < 0 marks a stable point (AUTO's convention); points without stability
    are written as unstable (PT > 0), as AUTO has no "unknown".
    contin locates special points between stored points; AUTO's special points are computed
    points.  A special point whose parameters are those of a stored point labels that line
    (the end points EP/MX); any other is inserted as a line of its own after the point it
    follows, with its located parameters and state.
s.NAME, one block per labelled point with a state (AUTO's algebraic layout, IPS = 1, NTST = 1,
    NCOL = 0): the 16-integer header, T = 0 and u (7 numbers a line), the free parameters'
    indices, the tangent's parameter and state components (rldot, udotps), and PAR(1..NPAR),
    NPAR = max(11, number of parameters); at an HB, PAR(11) = 2 pi / omega (AUTO's period
    estimate, used when a periodic orbit is started there) when the problem has fewer than 11
    parameters.  Points of fold and Hopf curves are written with their base state u only (their
    augmented vectors are contin's, not AUTO's extended systems).

Branches of periodic orbits are written as AUTO's periodic solutions (IPS = 2, with their
collocation mesh): :mod:`contin.autoorbits`.

Type codes (AUTO-07p's ``type_translation_dict``): BP 1, LP 2, HB 3, UZ -4, EP 9, MX -9, CP -2,
BT -1, ZH -3, GH -32.  AUTO has none for contin's XT (extremum of the second parameter) and HH
(double Hopf): they are written as UZ (-4) and listed in the returned notes.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from contin.autofields import PERIOD_PAR, Row, b_header, branch_rows, check_finite, e19
from contin.branch import Branch, base_state_size

__all__ = ["TYPE_CODES", "base_size", "e19", "write_auto"]

#: AUTO-07p's point type numbers (parseB.type_translation_dict)
TYPE_CODES = {"BP": 1, "LP": 2, "HB": 3, "UZ": -4, "EP": 9, "MX": -9, "CP": -2, "BT": -1, "ZH": -3, "GH": -32}
#: contin types AUTO has no code for: written as UZ
AS_USER_POINT = ("XT", "HH")
#: U(i) columns are written for problems with at most this many unknowns
MAX_U_COLUMNS = 6
#: PAR values a block of s.NAME holds at least (AUTO-07p writes 11 for NPAR <= 11)
MIN_NPAR = 11


def base_size(branch: Branch) -> int | None:
    """The base problem's n for a fold curve ([u, phi, p2]) or Hopf curve ([u, v, w, kappa, p2])."""
    size = branch.states.shape[1] if branch.sizes is None else int(np.max(branch.sizes))
    return base_state_size(branch.kind, size)


def _par_index(names: Sequence[str], par: Mapping[str, int] | None) -> dict[str, int]:
    if par is None:
        return {k: i + 1 for i, k in enumerate(names)}
    missing = [k for k in names if k not in par]
    if missing:
        raise ValueError(f"no PAR index for parameter(s) {', '.join(missing)}")
    unknown = [k for k in par if k not in names]
    if unknown:  # a misspelt name was ignored silently (qa16)
        raise ValueError(f"--par names {', '.join(map(repr, unknown))}, which the run does not have; its parameters "
                         f"are {', '.join(names)}")
    index = {k: int(par[k]) for k in names}
    if len(set(index.values())) != len(index) or min(index.values()) < 1:
        raise ValueError("PAR indices must be distinct integers >= 1")
    return index


def write_auto(branches: Sequence[Branch], name: str, directory: str | os.PathLike[str] = ".",
               par: Mapping[str, int] | None = None, cycles: Mapping[str, Any] | None = None
               ) -> tuple[Path, Path, list[str]]:
    """Write ``branches`` as AUTO-07p's b.NAME and s.NAME in ``directory`` (atomically, each).

    ``par``: contin parameter name -> AUTO PAR index (default: the order of the stored
    parameters, PAR(1), PAR(2), ...; give the equation file's indices to restart AUTO from
    s.NAME).  ``cycles``: the run's ``extra['cycles']`` entry (n, NCOL of its orbits), needed
    for branches of periodic orbits, written as AUTO's periodic solutions (``contin.autoorbits``).
    Returns the two paths and notes (types written as UZ).  ValueError for a branch
    with non-finite parameters or states (AUTO's files cannot hold them) or a bad name.
    """
    from contin.atomic import check_target, publish_together, write_bytes

    if not name or any(c in name for c in "/\\\0") or any(c.isspace() for c in name):
        raise ValueError(f"bad AUTO run name {name!r} (one word, used as b.NAME and s.NAME)")
    if not branches:
        raise ValueError("no branches to export")
    names = list(branches[0].params)
    index = _par_index(names, par)
    npar = max(MIN_NPAR, max(index.values()))
    b_lines: list[str] = []
    s_lines: list[str] = []
    notes: list[str] = []
    for position, branch in enumerate(branches, start=1):
        if list(branch.params) != names:
            raise ValueError(f"branch {branch.id} has other parameters than branch {branches[0].id}")
        if branch.kind == "lpc-curve":  # (its orbit rows were written as a 180-dimensional IPS = 1 state)
            raise ValueError(f"branch {branch.id} is an LPC curve (curve of folds of cycles): AUTO's layout of such "
                             "curves is not written (export the orbit branch it was continued from)")
        if branch.kind == "periodic-orbits":  # AUTO's IPS = 2 layout, with the orbits' mesh
            from contin.autoorbits import periodic_section

            b_part, s_part, more = periodic_section(position, branch, index, npar, cycles)
            b_lines += b_part
            s_lines += s_part
            notes += more
            continue
        n_base = base_size(branch)
        rows = branch_rows(branch, n_base)
        # an observable NaN everywhere is "not computed" (the reader allows it): no column, not an error
        with_phi = "phi" in branch.observables and not bool(np.all(np.isnan(branch.observables["phi"])))
        check_finite(branch, rows, with_phi)
        free = [k for k in branch.free]
        icp = [index[k] for k in free]
        sizes = {r.state.size for r in rows if r.state is not None}
        with_state = all(r.state is not None for r in rows)
        n_u = min(sizes) if sizes else 0
        u_columns = n_u if with_state and len(sizes) == 1 and n_u <= MAX_U_COLUMNS else 0
        columns = [f"PAR({icp[0]})"] + (["L2-NORM"] if with_state else []) + [f"U({j + 1})" for j in range(u_columns)]
        columns += [f"PAR({i})" for i in icp[1:]] + (["phi"] if with_phi else [])
        ndim = max(sizes) if sizes else 0
        b_lines += b_header(ndim, icp, index, npar)
        b_lines.append("   0    PT  TY  LAB" + "".join(("    " + c).ljust(19) for c in columns))
        for pt, row in enumerate(rows, start=1):
            ty, lab = 0, 0
            if row.point is not None:
                kind = row.point.type
                if kind in AS_USER_POINT:
                    notes.append(f"{row.point.name} ({kind}) written as UZ: AUTO has no code for {kind}")
                ty, lab = TYPE_CODES.get(kind, -4), int(row.point.label)
            number = ((pt - 1) % 9999) + 1
            line = "%4d%6d%4d%5d" % (position, -number if row.stable else number, ty, lab)
            values = [row.params[free[0]]]
            if with_state:
                assert row.state is not None
                # math.hypot scales: np.linalg.norm overflowed to 'INF' (and a RuntimeWarning) for
                # entries near 1e300 (qa16)
                values.append(math.hypot(*(float(v) for v in row.state)))
                values += [float(v) for v in row.state[:u_columns]]
            values += [row.params[k] for k in free[1:]]
            values += [row.phi] if with_phi else []
            b_lines.append(line + "".join(e19(v) for v in values))
            if row.point is not None and row.state is not None:
                s_lines += _s_block(position, pt, ty, lab, row, branch, icp, index, npar, n_base)  # PT unsigned in s (AUTO's WRTSP8)
    b_text = "\n".join(b_lines) + "\n"
    s_text = "\n".join(s_lines) + "\n" if s_lines else ""
    directory = Path(directory)
    for target in (directory / f"b.{name}", directory / f"s.{name}"):  # both, before either is written: a
        check_target(target)  # symlinked s.NAME was refused after b.NAME was replaced (qa16)
    # both written before either is renamed: a full disk left a new b.NAME beside the old s.NAME (qa19)
    b_path, s_path = publish_together([(directory / f"b.{name}", lambda tmp: write_bytes(tmp, b_text.encode("ascii"))),
                                       (directory / f"s.{name}", lambda tmp: write_bytes(tmp, s_text.encode("ascii")))])
    return b_path, s_path, notes


def _s_block(br: int, pt: int, ty: int, lab: int, row: Row, branch: Branch, icp: list[int],
             index: Mapping[str, int], npar: int, n_base: int | None) -> list[str]:
    """One labelled solution in AUTO's algebraic layout (parseS.write)."""
    assert row.state is not None and row.point is not None
    u = row.state
    ndim = u.size
    nfpr = len(icp)
    nrowpr = (ndim // 7 + 1) + (npar + 6) // 7 + (nfpr + 19) // 20 + (nfpr + 6) // 7 + (ndim + 6) // 7
    head = "%6d%6d%6d%6d%6d%6d%8d%6d%8d%5d%5d%5d%5d%5d%5d%5d" % (
        br, pt, ty, lab, nfpr, 1, 1, ndim + 1, nrowpr, 1, 0, npar, 0, ndim, 1, 0)
    out = [head]
    values = [0.0, *u]  # T, then U(1..NDIM), 7 a line
    out += ["    " + "".join(e19(v) for v in values[k:k + 7]) for k in range(0, len(values), 7)]
    out += ["".join("%5d" % i for i in icp[k:k + 20]) for k in range(0, nfpr, 20)]
    tangent = row.point.tangent
    if tangent is None:
        tangent = branch.tangent(min(row.point.index, len(branch) - 1))
    tangent = np.asarray(tangent, float)
    # rldot: the free parameters' components (the last len(free) entries of a one-parameter
    # tangent; a curve's p1 is its last entry and p2 sits after the base blocks)
    rl = [float(tangent[-1])] + ([float(tangent[-2])] if nfpr > 1 else [])
    rl = [v if math.isfinite(v) else 0.0 for v in rl]
    out += ["    " + "".join(e19(v) for v in rl[k:k + 7]) for k in range(0, nfpr, 7)]
    ud = np.nan_to_num(tangent[:ndim]) if tangent.size >= ndim else np.zeros(ndim)
    out += ["    " + "".join(e19(v) for v in ud[k:k + 7]) for k in range(0, ndim, 7)]
    par = np.zeros(npar)
    for k, i in index.items():
        par[i - 1] = row.params[k]
    omega = row.point.data.get("omega", math.nan) if row.point.type == "HB" else math.nan
    if math.isfinite(omega) and omega > 0 and PERIOD_PAR not in index.values():
        par[PERIOD_PAR - 1] = 2 * math.pi / omega
    out += ["    " + "".join(e19(v) for v in par[k:k + 7]) for k in range(0, npar, 7)]
    return out
