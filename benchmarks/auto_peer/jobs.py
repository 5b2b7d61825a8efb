"""The four peer jobs on AUTO-07p (see contin_jobs.py for the contin side; same model, same runs).

Each function takes a :class:`benchmarks.auto_peer.auto.Runner` and returns
{'BP': [...], 'LP': [...], 'Fr*': ...} as found by AUTO (full-precision values from fort.8).
"""

from __future__ import annotations

import math

import numpy as np

from benchmarks.auto_peer.auto import Runner

NU, E = 0.3, 0.8
H_MAX = 43.126146774024086  # 3.3 H_1^c, the pitchfork scene's default H_max at nu = 0.3, e = 0.8
#: first step on a switched branch: with DS = 0.5 the first Newton step jumps to H ~ 3e13 and
#: AUTO carries NaN for 300 steps (the guarded residual gives a singular Jacobian)
SWITCH_DS = 0.05


def start(nu: float = NU, H: float = H_MAX / 20) -> dict[str, float]:
    return {"H": H, "nu": nu, "e": E, "G5": 0.0, "num": 0.65}


def uniform(r: Runner, name: str, H_end: float | list[float]) -> list:
    return r.run(name, IRS=0, ISW=1, ICP="['H', 'S', 'Phi']", DS=0.5, UZSTOP=f"{{'H': {H_end!r}}}")


def job_a(r: Runner) -> dict:
    sols = uniform(r, "a", H_MAX)
    return {"BP": [s.par[0] for s in sols if s.type == "BP"]}


def job_b(r: Runner) -> dict:
    sols = uniform(r, "a", H_MAX)
    bps = [s for s in sols if s.type == "BP"]
    ends = []
    for bp in bps:
        for sign in (+1, -1):
            sols = r.run(f"b{bp.label}{'+' if sign > 0 else '-'}", restart="a", IRS=bp.label, ISW=-1,
                         ICP="['H', 'S', 'Phi']", DS=sign * SWITCH_DS, UZSTOP=f"{{'H': {[H_MAX / 20, H_MAX]!r}}}")
            ends.append(sols[-1].par[8] if sols else math.nan)
    # a switch that fell back onto uniform shear ends with Phi = nubar: say so
    return {"BP": [s.par[0] for s in bps], "banded branches": sum(abs(x - NU) > 1e-6 for x in ends)}


def switched(r: Runner, name: str, restart: str, bp, sign: int, nubar: float, **kw: object) -> list:
    """The banded branch at ``bp`` (ISW = -1) in the direction ``sign``; if AUTO's switch falls
    back onto uniform shear (Phi = nubar at the end: seen at nu = 0.16 with a BP located with
    DSMAX = 2), the other direction, which is the mirror branch of the same mode."""
    for s in (sign, -sign):
        sols = r.run(name, restart=restart, IRS=bp.label, ISW=-1, ICP="['H', 'S', 'Phi']", DS=s * SWITCH_DS, **kw)
        if sols and abs(sols[-1].par[8] - nubar) > 1e-6:
            return sols
    return sols


def job_c(r: Runner) -> dict:
    # DSMAX 5 here: with 2 the switched branch needs 390 steps (and one direction falls back)
    sols = r.run("c0", IRS=0, ISW=1, ICP="['H', 'S', 'Phi']", DS=0.5, DSMAX=5.0, UZSTOP="{'H': 70.0}")
    bp = next(s for s in sols if s.type == "BP")
    band = switched(r, "c1", "c0", bp, +1, 0.16, DSMAX=5.0, UZSTOP="{'H': [30.0, 70.0]}")
    return {"BP": [bp.par[0]], "LP": [s.par[0] for s in band if s.type == "LP"]}


#: gaps of job d's coarse pass (Fr* lies at H = 19.11), and the spacing of its fine pass
D_GAPS = [16.0 + 0.5 * k for k in range(14)]
D_FINE = 0.125
#: DSMAX of the continuations in G: with 0.1 AUTO's located folds scatter by 2e-3 in G
#: (1.5456, 1.5473, 1.5450, 1.5478 at H = 18.75 ... 19.125, not a smooth curve); with 0.02 they
#: are smooth and agree with contin's fold curve
D_G_DSMAX = 0.02


def _folds_in_G(r: Runner, bp, gaps: list[float], tag: str) -> list[tuple[float, float]]:
    """(H, G) of the fold in G of the dense-top banded state at each gap of ``gaps``."""
    for sign in (-1, +1):  # the dense-top sign: Phi = nu(1/2) > nubar
        band = r.run(f"d1{tag}", restart="d0", IRS=bp.label, ISW=-1, ICP="['H', 'S', 'Phi']", DS=sign * SWITCH_DS,
                     UZR=f"{{'H': {gaps!r}}}", UZSTOP=f"{{'H': {max(gaps) + 0.25!r}}}")
        uz = [s for s in band if s.type == "UZ" and any(abs(s.par[0] - h) < 1e-3 for h in gaps)]
        if uz and uz[0].par[8] > NU:
            break
    folds = []
    for s in uz:
        for ds in (0.01, -0.01):  # the sign of DS does not fix the direction of G on a restart
            lp = [x for x in r.run(f"d2{tag}_{s.label}", restart=f"d1{tag}", IRS=s.label, ISW=1,
                                   ICP="['G5', 'S', 'Phi']", ISP=0, DS=ds, DSMAX=D_G_DSMAX, STOP="['LP1']")
                  if x.type == "LP" and x.par[4] > 0]
            if lp:
                folds.append((s.par[0], lp[0].par[4] * 1e-5))
                break
    return folds


def job_d(r: Runner) -> dict:
    """Fr* = min over H of the Froude number at which the dense-top (floating-plug) banded state
    of the first pitchfork dies in a fold in G.

    AUTO-07p 0.9.2's two-parameter fold continuation of this BVP (ISW = 2 from the LP in G)
    generates its starting data, but every restart from it diverges at the first Newton step
    (H -> -5e3, then NaN) whatever the step size, with finite-difference or exact Jacobians.  So
    the fold curve is sampled instead: the dense-top branch is followed from the first BP with
    user points (UZR) at D_GAPS, each is continued in G (G5 = 1e5 G) to its fold (LP); a second
    pass at spacing D_FINE around the largest fold, and a parabola through the three folds
    around the largest G give G_max and Fr* = G_max^-1/2.
    """
    sols = uniform(r, "d0", 16.0)
    bp = next(s for s in sols if s.type == "BP")
    coarse = _folds_in_G(r, bp, D_GAPS, "c")
    if not coarse:
        return {"Fr*": math.nan}
    h0 = max(coarse, key=lambda f: f[1])[0]
    folds = _folds_in_G(r, bp, [h0 + D_FINE * k for k in range(-3, 4)], "f")
    if len(folds) < 3:
        return {"Fr*": math.nan}
    hs, gs = np.array(sorted(folds)).T
    k = int(np.clip(np.argmax(gs), 1, len(gs) - 2))
    a, b, c = np.polyfit(hs[k - 1:k + 2], gs[k - 1:k + 2], 2)
    g_max = c - b * b / (4 * a)
    return {"Fr*": float(g_max ** -0.5), "H(Fr*)": float(-b / (2 * a))}


JOBS = {"a": (job_a, start()), "b": (job_b, start()), "c": (job_c, start(0.16, 30.0)), "d": (job_d, start())}
