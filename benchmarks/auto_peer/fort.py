"""Readers of AUTO-07p's output files (its Python CLUI does not run with current numpy).

fort.7 (b.*): the bifurcation diagram, one line per computed point: BR, PT, TY, LAB, then the
    ICP parameters and norms; header/comment lines start with BR = 0.
fort.8 (s.*): one block per labelled solution: a header of 12+ integers (IBR, NTOT, ITP, LAB,
    NFPR, ISW, NTPL, NAR, NROWPR, NTST, NCOL, NPAR, ...), then NROWPR lines holding the mesh and
    solution (NTPL x NAR numbers), the free parameter indices, their directions, the solution's
    derivative and, last, the NPAR parameter values (full precision, unlike fort.7).
Point types ITP (AUTO-07p manual, 'Output files'): 1/6 BP (algebraic/BVP), 2/5 LP, 3 HB, 4 or
-4 UZ, 9 EP, -9 MX.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

TYPES = {1: "BP", 6: "BP", 2: "LP", 5: "LP", 3: "HB", 4: "UZ", -4: "UZ", 9: "EP", -9: "MX", 7: "PD", 8: "TR"}


@dataclass(frozen=True)
class Solution:
    branch: int
    point: int
    type: str
    label: int
    par: tuple[float, ...]  # PAR(1..NPAR)


def _float(text: str) -> float:
    # AUTO writes three-digit exponents ("1.0E-005") and, for huge values, drops the E ("1.7976+308")
    t = text.replace("D", "E")
    if "E" not in t.upper() and ("+" in t[1:] or "-" in t[1:]):
        i = max(t.rfind("+"), t.rfind("-"))
        t = t[:i] + "E" + t[i:]
    return float(t)


def read_solutions(path: str | Path) -> list[Solution]:
    """Every labelled solution of a fort.8 file."""
    lines = Path(path).read_text().splitlines()
    out: list[Solution] = []
    i = 0
    while i < len(lines):
        if not lines[i].strip():
            i += 1
            continue
        head = [int(x) for x in lines[i].split()]
        ibr, ntot, itp, lab, nrowpr, npar = head[0], head[1], head[2], head[3], head[8], head[11]
        tokens = " ".join(lines[i + 1:i + 1 + nrowpr]).split()
        par = tuple(_float(x) for x in tokens[-npar:])
        out.append(Solution(ibr, abs(ntot), TYPES.get(itp, str(itp)), lab, par))
        i += 1 + nrowpr
    return out


def count_points(path: str | Path) -> int:
    """Number of computed points in a fort.7 file (lines with a nonzero branch number)."""
    n = 0
    for line in Path(path).read_text().splitlines():
        parts = line.split()
        if len(parts) > 4 and parts[0].lstrip("-").isdigit() and int(parts[0]) != 0:
            n += 1
    return n
