"""AUTO-07p restarts from contin's export: ``python -m benchmarks.auto_peer.export_check``.

Traces contin's `ab` scene (AUTO's demo ab), exports it with ``contin export --auto ab``
(contin.autoformat) and runs AUTO-07p's Fortran core from the exported s.ab: restart at HB1
(IRS = 1) with ISW = 2, ICP = [1, 2], i.e. AUTO continues contin's Hopf point in (D, B), both
directions.  Prints AUTO's GH and BT next to contin's own Hopf curve (`contin continue ... --from
HB1 --free B`).  Needs AUTO-07p and gfortran (benchmarks.auto_peer.auto.find_auto); CI does not.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.auto_peer.auto import compile_equations, find_auto, restart
from benchmarks.auto_peer.fort import _float

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "auto_ab"
CONSTANTS = """NDIM=2, IPS=1, IRS=1, ILP=1
ICP=[1,2]
NTST=15, NCOL=4, IAD=3, ISP=1, ISW=2, IPLT=0, NBC=0, NINT=0
NMX=400, NPR=1000, MXBF=10, IID=2, ITMX=8, ITNW=5, NWTN=3, JAC=0
EPSL=1e-8, EPSU=1e-8, EPSS=1e-6
DS={ds}, DSMIN=0.0001, DSMAX=0.05, IADS=1
NPAR=3, THL={{}}, THU={{}}
UZSTOP={{2: [0.0, 40.0], 1: [0.0, 0.5]}}
"""
#: AUTO writes a codim-2 point's type with the curve's type as its tens digit (BT on a Hopf curve:
#: -31; parseB.type_translation reduces it modulo 10), GH as -32
CODES = {-32: "GH", -1: "BT"}


def auto_points(fort8: Path) -> list[tuple[str, float, float]]:
    """(type, D, B) of the GH and BT blocks of an AUTO fort.8 (PAR(1), PAR(2) at full precision)."""
    lines = fort8.read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        head = [int(x) for x in lines[i].split()]
        ty, nrowpr, npar = head[2], head[8], head[11]
        body = lines[i + 1:i + 1 + nrowpr]
        par = [_float(x) for ln in body[-((npar + 6) // 7):] for x in ln.split()]
        kind = CODES.get(ty) or (CODES.get(-((-ty) % 10)) if ty < 0 else None)
        if kind is not None:
            out.append((kind, par[0], par[1]))
        i += 1 + nrowpr
    return out


def main() -> int:
    auto_dir, why = find_auto()
    if auto_dir is None:
        print(f"skipped: {why}")
        return 0
    work = Path(tempfile.mkdtemp(prefix="contin-export-"))
    try:
        exe = compile_equations(auto_dir, work, DATA / "ab.f90")
        contin = [sys.executable, "-m", "contin"]
        subprocess.run([*contin, "trace", "ab", "-o", "ab.h5", "-q"], cwd=work, check=True)
        subprocess.run([*contin, "export", "ab.h5", "--auto", "ab"], cwd=work, check=True, capture_output=True)
        subprocess.run([*contin, "continue", "ab.h5", "--from", "HB1", "--free", "B", "--bounds", "B=0:40",
                        "-o", "hopf.h5", "--json"], cwd=work, check=True, capture_output=True)
        from contin import io

        (curve,), _ = io.load(work / "hopf.h5")
        ours = {sp.type: (sp.params["D"], sp.params["B"]) for sp in curve.special_points if sp.type in ("GH", "BT")}
        found = []
        for ds in (0.01, -0.01):
            # AUTO reads the restart label from contin's s.ab
            found += auto_points(restart(exe, work, "s.ab", CONSTANTS.format(ds=ds)))
        print("AUTO-07p restarted from contin's s.ab at HB1 (ISW=2, ICP=[1,2]):")
        print(f"{'point':6} {'AUTO D':>16} {'contin D':>16} {'AUTO B':>16} {'contin B':>16}")
        for kind, d, b in found:
            cd, cb = ours.get(kind, (float('nan'), float('nan')))
            print(f"{kind:6} {d:16.10f} {cd:16.10f} {b:16.10f} {cb:16.10f}")
        return 0 if {k for k, _, _ in found} == {"GH", "BT"} else 1
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
