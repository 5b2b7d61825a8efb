"""AUTO-07p restarts from contin's exported periodic orbits:
``python -m benchmarks.auto_peer.orbit_export_check``.

Traces contin's `ab` scene (AUTO's demo ab), continues its orbits from HB1 through the fold of
cycles for 40 steps (`contin continue ab.h5 --from HB1 --cycles`), exports them in AUTO's IPS=2
layout (`contin export cyc.h5 --auto orb`: b.orb, s.orb) and runs AUTO-07p's Fortran core from the
exported s.orb: restart at the last orbit (IRS = its label) with IPS = 2, ICP = [1, 11] (D and the
period), NTST 20, NCOL 4, back towards the fold.  AUTO must read contin's orbit (mesh, the
NTST*NCOL+1 rows of t, u, PAR(11) = T), converge on it, and find the fold of cycles (LP) where
contin put its LPC.  Prints both.  Needs AUTO-07p and gfortran
(benchmarks.auto_peer.auto.find_auto); CI does not.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from benchmarks.auto_peer.auto import compile_equations, contin_ab_orbits, find_auto, restart
from benchmarks.auto_peer.fort import read_solutions

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "auto_ab"
CONSTANTS = """NDIM=2, IPS=2, IRS={irs}, ILP=1
ICP=[1,11]
NTST=20, NCOL=4, IAD=3, ISP=2, ISW=1, IPLT=0, NBC=0, NINT=0
NMX=40, NPR=1000, MXBF=10, IID=2, ITMX=8, ITNW=7, NWTN=3, JAC=0
EPSL=1e-8, EPSU=1e-8, EPSS=1e-6
DS={ds}, DSMIN=0.00001, DSMAX=0.05, IADS=1
NPAR=11, THL={{11: 0.0}}, THU={{}}
UZSTOP={{1: [0.0, 0.5]}}
"""


def main() -> int:
    auto_dir, why = find_auto()
    if auto_dir is None:
        print(f"skipped: {why}")
        return 0
    work = Path(tempfile.mkdtemp(prefix="contin-orbits-"))
    try:
        exe = compile_equations(auto_dir, work, DATA / "ab.f90")
        contin = contin_ab_orbits(work)
        subprocess.run([*contin, "export", "cyc.h5", "--auto", "orb"], cwd=work, check=True, capture_output=True)
        ours = read_solutions(work / "s.orb")
        (lpc,) = [s for s in ours if s.type == "LP"]
        last = ours[-1]
        runs = {}
        for ds in (-0.01, 0.01):
            runs[ds] = read_solutions(restart(exe, work, "s.orb", CONSTANTS.format(irs=last.label, ds=ds)))
        print(f"AUTO-07p restarted from contin's s.orb at label {last.label} (IPS=2, ICP=[1,11], NTST 20, NCOL 4):")
        print(f"{'':28} {'D = PAR(1)':>16} {'period':>16}")
        print(f"{'contin, restart orbit':28} {last.par[0]:16.11f} {last.par[10]:16.10f}")
        lps = [s for s in runs[-0.01] if s.type == "LP"]
        for s in lps:
            print(f"{'AUTO LP (back, DS<0)':28} {s.par[0]:16.11f} {s.par[10]:16.10f}")
        print(f"{'contin LPC':28} {lpc.par[0]:16.11f} {lpc.par[10]:16.10f}")
        ahead = runs[0.01]
        if ahead:
            print(f"{'AUTO forward (DS>0), end':28} {ahead[-1].par[0]:16.11f} {ahead[-1].par[10]:16.10f}  ({ahead[-1].type})")
        if len(lps) != 1:
            print(f"AUTO found {len(lps)} folds of cycles going back; expected 1")
            return 1
        off = abs(lps[0].par[0] - lpc.par[0]) / abs(lpc.par[0])
        print(f"LP: AUTO - contin = {lps[0].par[0] - lpc.par[0]:.3g} in D ({off:.2g} relative), "
              f"{lps[0].par[10] - lpc.par[10]:.3g} in the period")
        return 0 if off < 1e-6 else 1
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
