"""AUTO-07p's LPC curve of demo ab against contin's: ``python -m benchmarks.auto_peer.lpc_curve_check``.

contin: `contin trace ab`, its orbits from HB1 (`--cycles`, 40 steps, through LPC1 at B = 14), the
LPC curve from LPC1 in (D, B) (`contin continue cyc.h5 --from LPC1 --free B`, NTST 20, NCOL 4,
B up to 14.5).  AUTO: the orbits exported in AUTO's IPS = 2 layout (`contin export cyc.h5 --auto
orb`), and AUTO-07p's Fortran core restarted at the LPC's label with ISW = 2, ICP = [1, 2, 11] (D,
B and the period), NTST 20, NCOL 4 (its starting data first, then both directions from them),
every point written (NPR = 1).  Prints both
curves at AUTO's points (contin's D interpolated at AUTO's B), and where each ends towards the
generalized Hopf point of the Hopf curve (README: (D, B) = (0.2789854144, 11.0158490940)).  Needs
AUTO-07p and gfortran (benchmarks.auto_peer.auto.find_auto); CI does not run it.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.auto_peer.auto import compile_equations, contin_ab_orbits, find_auto, restart
from benchmarks.auto_peer.fort import read_solutions

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "auto_ab"
GH = (0.2789854144, 11.0158490940)
CONSTANTS = """NDIM=2, IPS=2, IRS={irs}, ILP=1
ICP=[1,2,11]
NTST=20, NCOL=4, IAD=3, ISP=2, ISW=2, IPLT=0, NBC=0, NINT=0
NMX={nmx}, NPR=1, MXBF=10, IID=2, ITMX=8, ITNW=7, NWTN=3, JAC=0
EPSL=1e-8, EPSU=1e-8, EPSS=1e-6
DS={ds}, DSMIN=0.00001, DSMAX=0.05, IADS=1
NPAR=11, THL={{11: 0.0}}, THU={{}}
UZSTOP={{1: [0.0, 0.5], 2: [0.0, 14.5]}}
"""


def main() -> int:
    auto_dir, why = find_auto()
    if auto_dir is None:
        print(f"skipped: {why}")
        return 0
    work = Path(tempfile.mkdtemp(prefix="contin-lpc-"))
    try:
        exe = compile_equations(auto_dir, work, DATA / "ab.f90")
        contin = contin_ab_orbits(work)
        subprocess.run([*contin, "continue", "cyc.h5", "--from", "LPC1", "--free", "B", "--bounds", "B=0:14.5",
                        "-o", "lpc.h5"], cwd=work, check=False, capture_output=True)
        subprocess.run([*contin, "export", "cyc.h5", "--auto", "orb"], cwd=work, check=True, capture_output=True)
        from contin import io

        (curve,), _ = io.load(str(work / "lpc.h5"))
        ours = read_solutions(work / "s.orb")
        (lpc,) = [s for s in ours if s.type == "LP"]
        def auto(source: str, irs: int, ds: float, nmx: int) -> list:
            return read_solutions(restart(exe, work, source, CONSTANTS.format(irs=irs, ds=ds, nmx=nmx)))

        # AUTO's ISW = 2 at a periodic LP first generates the fold system's starting data (its null
        # vector) and ends "Restart at EP label below"; the curve is the restart from that EP
        start = auto("s.orb", lpc.label, 0.01, 50)[-1]  # (its ITP is 59: an EP of the LP-generating run)
        shutil.copy(work / "fort.8", work / "start.8")
        runs = {ds: auto("start.8", start.label, ds, 200) for ds in (-0.01, 0.01)}
        from scipy.interpolate import CubicSpline

        d, b = curve.params["D"], curve.params["B"]
        order = np.argsort(b)
        keep = np.concatenate([[True], np.diff(b[order]) > 0])
        spline = CubicSpline(b[order][keep], d[order][keep])  # contin's D between its points, at AUTO's B
        print(f"LPC curve of demo ab from LPC1 (D = {lpc.par[0]:.10f}, B = 14), NTST 20, NCOL 4")
        print(f"contin: {len(curve)} points, {curve.status} {curve.message}")
        for g in curve.points("GH"):
            print(f"contin GH: D = {g.params['D']:.10f}, B = {g.params['B']:.10f} ({'converged' if g.converged else 'estimate'})")
        j = int(np.argmin(curve.order_parameter))
        print(f"contin's smallest orbit: D = {d[j]:.10f}, B = {b[j]:.10f} (amplitude {curve.order_parameter[j]:.2g}); "
              f"GH of the Hopf curve: D = {GH[0]:.10f}, B = {GH[1]:.10f}")
        worst = 0.0
        for ds, sols in runs.items():
            pts = list(sols)
            print(f"AUTO ISW=2 DS={ds:+g}: {len(pts)} points, last {pts[-1].type} at D = {pts[-1].par[0]:.10f}, "
                  f"B = {pts[-1].par[1]:.10f}, T = {pts[-1].par[10]:.8f}")
            print(f"  {'B':>14} {'D (AUTO)':>16} {'D (contin)':>16} {'difference':>11} {'T (AUTO)':>12}")
            for s in pts[:: max(1, len(pts) // 12)]:
                if not b.min() <= s.par[1] <= b.max():
                    continue
                ours_d = float(spline(s.par[1]))
                worst = max(worst, abs(ours_d - s.par[0]))
                print(f"  {s.par[1]:14.8f} {s.par[0]:16.11f} {ours_d:16.11f} {ours_d - s.par[0]:11.2e} {s.par[10]:12.7f}")
        print(f"largest |D(contin) - D(AUTO)| at AUTO's points: {worst:.2e} (includes contin's cubic interpolation in B)")
        return 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
