"""Periodic orbits in AUTO-07p's b.NAME / s.NAME files (IPS = 2), for :func:`contin.autoformat.write_auto`.

The layout is that of AUTO-07p's writers for boundary-value problems (``src/bvp.f90``: STPLBV
and WRTBV8; ``src/io.f90``: HEADNG and WRLINE):

b.NAME, one section per branch: the header as for equilibria with IPS = 2, a line
    ``NTST= ... NCOL= ...`` and the user-specified / active parameters [PAR(i), 11] (the branch's
    parameter and AUTO's period PAR(11), as in AUTO's own ``ICP = [i, 11]`` runs); the column
    names ``PAR(i)``, ``L2-NORM``, ``MAX U(1)`` .. ``MAX U(N2)`` (N2 = min(n, 5): AUTO writes 7
    values at most), ``PERIOD``; one line per orbit ``%4d%6d%4d%5d`` (BR, PT, TY, LAB), then the
    19-character values: PAR(i), sqrt(int_0^1 |u|^2 dt) (by AUTO's quadrature, :func:`auto_l2_squared`), max over the mesh of u_1 .. u_N2, T.
    BR is negative (AUTO: "Branch number is negative for periodic solutions"), PT < 0 marks a
    stable orbit (all Floquet multipliers but the trivial one inside the unit circle).
s.NAME, one block per labelled orbit: the 16 integers ``6I6,I8,I6,I8,7I5`` IBR, PT (> 0), TY, LAB,
    NFPR = 2, ISW = 1, NTPL = NTST NCOL + 1, NAR = n + 1, NROWPR, NTST, NCOL, NPAR, NPARI = 0,
    NDIM = n, IPS = 2, 0; NTPL rows t, u_1 .. u_n (``4X,7ES19.10E3``, 7 numbers a line) at the
    collocation mesh t_j + k h_j / NCOL (AUTO's and contin's node representation), the last row
    t = 1 with u(1) = u(0); the line of free parameter indices (i, 11); RLDOT (the parameter's and
    the period's tangent components); NTPL rows of the state's tangent udot (the same times);
    PAR(1..NPAR) with PAR(11) = T.  The tangent is scaled as AUTO scales its direction vector:
    int_0^1 |udot|^2 dt + pdot^2 + Tdot^2 = 1 (the same quadrature).

Type codes (AUTO's ``ITP`` for ODEs, parseB.type_translation_dict): LPC 5 (AUTO's LP of an ODE),
BP 6, PD 7, NS 8 (AUTO's TR), HB 3 (where the orbits shrink to an equilibrium), EP 9, MX -9,
UZ -4; other types are written as UZ (-4) and named in the notes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from contin.branch import Branch

__all__ = ["CYCLE_TYPE_CODES", "PERIODIC_IPS", "periodic_section"]

#: AUTO-07p's point type numbers of periodic solutions (ODE codes)
CYCLE_TYPE_CODES = {"LPC": 5, "LP": 5, "BP": 6, "PD": 7, "NS": 8, "HB": 3, "UZ": -4, "EP": 9, "MX": -9}
#: AUTO's problem type of periodic solutions
PERIODIC_IPS = 2
#: values AUTO writes per b-file line after BR PT TY LAB (WRLINE: N1 + N2 <= 7)
MAX_LINE_VALUES = 7


def orbit_mesh(cycles: Mapping[str, Any] | None, branch: Branch) -> tuple[int, int]:
    """(n, NCOL) of a branch of orbits, from the run's ``extra['cycles']`` entry (ValueError without)."""
    if not cycles or "n" not in cycles or "ncol" not in cycles:
        raise ValueError(f"branch {branch.id} holds periodic orbits, but the file does not say their size n and "
                         "NCOL (no 'cycles' entry): it was not written by contin continue --cycles")
    return int(cycles["n"]), int(cycles["ncol"])


def periodic_section(position: int, branch: Branch, index: Mapping[str, int], npar: int,
                     cycles: Mapping[str, Any] | None) -> tuple[list[str], list[str], list[str]]:
    """(b lines, s lines, notes) of a branch of periodic orbits (module docstring)."""
    from contin.autofields import PERIOD_PAR, b_header, branch_rows, check_finite, e19
    from contin.cycles import orbit_of

    n, ncol = orbit_mesh(cycles, branch)
    if PERIOD_PAR in index.values():
        name = next(k for k, i in index.items() if i == PERIOD_PAR)
        raise ValueError(f"parameter {name} is PAR({PERIOD_PAR}), which AUTO keeps for the period of periodic "
                         f"orbits: give it another index (--par {name}=...)")
    rows = branch_rows(branch, None)
    check_finite(branch, rows, False)
    if any(r.state is None for r in rows):
        raise ValueError(f"branch {branch.id}: an orbit without its stored state cannot be written")
    free = list(branch.free)
    if len(free) != 1:
        raise ValueError(f"branch {branch.id} of periodic orbits has free parameters {free}; AUTO's periodic "
                         "runs have one (and the period)")
    icp = [index[free[0]], PERIOD_PAR]
    n_max = max(0, min(n, MAX_LINE_VALUES - len(icp)))
    columns = [(4, f"PAR({icp[0]})"), (4, "L2-NORM")] + [(4, f"MAX U({j + 1})") for j in range(n_max)] + [(5, "PERIOD")]
    # NTST from the first orbit (every orbit of a branch has it; their mesh points differ)
    ntst = orbit_of(rows[0].state, n, None, ncol)[0].ntst if rows and rows[0].state is not None else int(
        (cycles or {}).get("ntst", 0))
    b_lines = b_header(n, icp, index, npar, ips=PERIODIC_IPS, mesh=(ntst, ncol))
    b_lines.append("   0    PT  TY  LAB " + "".join((" " * (k - 1) + c).ljust(19) for k, c in columns))
    s_lines: list[str] = []
    notes: list[str] = []
    for pt, row in enumerate(rows, start=1):
        assert row.state is not None
        mesh, nodes, period = orbit_of(row.state, n, ntst, ncol)
        ty, lab = 0, 0
        if row.point is not None:
            kind = row.point.type
            if kind not in CYCLE_TYPE_CODES:
                notes.append(f"{row.point.name} ({kind}) written as UZ: AUTO has no code for {kind} of periodic orbits")
            ty, lab = CYCLE_TYPE_CODES.get(kind, -4), int(row.point.label)
        number = ((pt - 1) % 9999) + 1
        values = [row.params[free[0]], math.sqrt(auto_l2_squared(mesh, nodes)), *np.max(nodes, axis=0)[:n_max], period]
        b_lines.append("%4d%6d%4d%5d" % (-position, -number if row.stable else number, ty, lab)
                       + "".join(e19(float(v)) for v in values))
        if row.point is not None:
            tangent = row.point.tangent
            if tangent is None:
                tangent = branch.tangent(min(row.point.index, len(branch) - 1))
            s_lines += _s_block(position, number, ty, lab, mesh, nodes, period, np.asarray(tangent, float),
                                row.params, icp, index, npar)
    return b_lines, s_lines, notes


def auto_l2_squared(mesh: Any, nodes: np.ndarray) -> float:
    """int_0^1 |u|^2 dt as AUTO computes it (``mesh.f90`` RNRMSQ): on each mesh interval the
    interpolatory rule of its NCOL + 1 equally spaced nodes (WINT; Boole's rule for NCOL = 4)."""
    from contin.collocation import lagrange_at

    z, w = np.polynomial.legendre.leggauss(mesh.ncol + 1)  # exact for the degree-NCOL basis
    weights = (w / 2) @ lagrange_at(mesh.ncol, (z + 1) / 2)  # WI(k) = int_0^1 l_k(s) ds
    squares = np.sum(np.asarray(nodes, float) ** 2, axis=1)
    blocks = squares[mesh.interval_nodes]  # (NTST, NCOL + 1), the last node wraps to the first
    return float(mesh.h @ (blocks @ weights))


def _lines(values: Any) -> list[str]:
    """AUTO's FORMAT(4X,7ES19.10E3): 7 numbers a line."""
    from contin.autofields import e19

    values = [float(v) for v in values]
    return ["    " + "".join(e19(v) for v in values[k:k + 7]) for k in range(0, len(values), 7)]


def _s_block(br: int, pt: int, ty: int, lab: int, mesh: Any, nodes: np.ndarray, period: float, tangent: np.ndarray,
             params: Mapping[str, float], icp: list[int], index: Mapping[str, int], npar: int) -> list[str]:
    """One labelled orbit as AUTO's WRTBV8 writes it (module docstring)."""
    n, ntst, ncol = mesh.n, mesh.ntst, mesh.ncol
    ntpl, nfpr = ntst * ncol + 1, len(icp)
    nrowpr = ((n // 7 + 1) * ntpl + (npar + 6) // 7 + (nfpr + 19) // 20 + (nfpr + 6) // 7
              + ((n + 6) // 7) * ntpl)
    out = ["%6d%6d%6d%6d%6d%6d%8d%6d%8d%5d%5d%5d%5d%5d%5d%5d" % (
        br, pt, ty, lab, nfpr, 1, ntpl, n + 1, nrowpr, ntst, ncol, npar, 0, n, PERIODIC_IPS, 0)]
    times = np.append(mesh.node_times, 1.0)
    u = np.vstack([nodes, nodes[:1]])  # u(1) = u(0)
    for t, v in zip(times, u):
        out += _lines([t, *v])
    out.append("".join("%5d" % i for i in icp))
    # the stored tangent: [udot at the nodes, Tdot, zeros for the mesh points, pdot]
    size = mesh.size
    ud = np.nan_to_num(tangent[:size - 1]).reshape(mesh.nodes, n) if tangent.size > size else np.zeros((mesh.nodes, n))
    rl = np.nan_to_num([tangent[-1], tangent[size - 1]]) if tangent.size > size else np.zeros(2)
    scale = math.sqrt(auto_l2_squared(mesh, ud) + float(rl @ rl))  # AUTO's scaling (bvp.f90, THL = THU = 1)
    if scale > 0:
        ud, rl = ud / scale, rl / scale
    out += _lines(rl)
    for v in np.vstack([ud, ud[:1]]):
        out += _lines(v)
    par = np.zeros(npar)
    for k, i in index.items():
        par[i - 1] = params[k]
    par[icp[1] - 1] = period
    out += _lines(par)
    return out
