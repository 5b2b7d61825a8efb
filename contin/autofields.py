"""AUTO-07p's fixed-width fields and the rows of a branch, shared by the writers of b.NAME / s.NAME
for equilibria (:mod:`contin.autoformat`) and for periodic orbits (:mod:`contin.autoorbits`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from contin.branch import Branch, SpecialPoint

__all__ = ["PERIOD_PAR", "Row", "b_header", "branch_rows", "check_finite", "e19"]

#: the index of AUTO's period parameter
PERIOD_PAR = 11

def e19(x: float) -> str:
    """AUTO's 19-character float (``AUTOutil.format19_10E3``): %19.10E with a 3-digit exponent."""
    s = "%19.10E" % x
    if s[-4] == "E":
        s = s[1:-2] + "0" + s[-2:]
    return s


@dataclass(frozen=True)
class Row:
    params: dict[str, float]
    state: np.ndarray | None
    stable: bool | None
    phi: float
    point: SpecialPoint | None = None


def branch_rows(branch: Branch, n_base: int | None) -> list[Row]:
    """The branch's stored points with its special points attached or inserted (module docstring)."""
    names = list(branch.params)
    first = branch.parameter
    rows = []
    for i in range(len(branch)):
        try:
            state = branch.state(i)
        except KeyError:  # save_every dropped it
            state = None
        if state is not None and n_base is not None:
            state = state[:n_base]
        stable = None if branch.stable is None else bool(branch.stable[i])
        phi = float(branch.observables["phi"][i]) if "phi" in branch.observables else math.nan
        rows.append(Row({k: float(branch.params[k][i]) for k in names}, state, stable, phi))
    inserted: dict[int, list[Row]] = {}
    for sp in sorted(branch.special_points, key=lambda s: (s.index, s.label)):
        value = sp.params.get(first, math.nan)
        own = None
        for j in (sp.index, sp.index + 1):
            if 0 <= j < len(rows) and rows[j].point is None and _same(rows[j].params.get(first), value):
                own = j
                break
        if own is not None:
            r = rows[own]
            rows[own] = Row(r.params, r.state if sp.state is None else _base(sp.state, n_base), r.stable, r.phi, sp)
        else:
            stable = rows[min(sp.index, len(rows) - 1)].stable if rows else None
            params = {k: float(sp.params.get(k, math.nan)) for k in names}
            phi = float(sp.order_parameter)
            inserted.setdefault(sp.index, []).append(Row(params, _base(sp.state, n_base), stable, phi, sp))
    out: list[Row] = []
    for i, r in enumerate(rows):
        out.append(r)
        out.extend(inserted.get(i, []))
    return out


def _same(a: float | None, b: float) -> bool:
    return a is not None and (a == b or abs(a - b) <= 1e-13 * max(1.0, abs(b)))


def _base(state: Any, n_base: int | None) -> np.ndarray | None:
    if state is None:
        return None
    state = np.asarray(state, float)
    return state if n_base is None else state[:n_base]


def check_finite(branch: Branch, rows: list[Row], with_phi: bool) -> None:
    for k, r in enumerate(rows):
        bad = [name for name, v in r.params.items() if not math.isfinite(v)]
        if bad or (r.state is not None and not np.all(np.isfinite(r.state))) or (with_phi and not math.isfinite(r.phi)):
            what = f"parameter {bad[0]}" if bad else "state" if r.state is not None and not np.all(np.isfinite(r.state)) else "order parameter"
            raise ValueError(f"branch {branch.id}: the {what} of point {k + 1} is not finite; AUTO's files cannot hold it")


def b_header(ndim: int, icp: list[int], index: Mapping[str, int], npar: int, ips: int = 1,
              mesh: tuple[int, int] | None = None) -> list[str]:
    bounds = "  -1.7976+308  1.7976+308 -1.7976+308  1.7976+308"  # RL0 RL1 A0 A1: no bounds, as AUTO writes them
    names = ", ".join(f"{i}: {k!r}" for k, i in sorted(index.items(), key=lambda kv: kv[1]))
    isw = 2 if len(icp) > 1 and ips == 1 else 1  # two parameters: a curve of codim-2 points (an orbit's are p, T)
    return [
        "   0" + bounds,
        "   0   NDIM=%4d   IPS =%4d   IRS =%4d   ILP =%4d" % (ndim, ips, 0, 1),
        *(["   0   NTST=%4d   NCOL=%4d" % mesh] if mesh is not None else []),
        "   0   ISW =%4d   NPAR=%4d" % (isw, npar),
        "   0   User-specified parameter:    " + "".join("%7d" % i for i in icp),
        "   0   Active continuation parameter:" + "".join("%7d" % i for i in icp),
        f"   0   parnames = {{{names}}}",
        "   0",
    ]
