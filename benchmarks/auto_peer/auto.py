"""Running AUTO-07p (the Debian package's Fortran core) on benchmarks/auto_peer/gpcf.f90.

The equation file is compiled once with gfortran against ``$AUTO_DIR/lib/*.o`` (what AUTO's
``@r`` does through its makefile); each run feeds a constants file on stdin, a restart file as
fort.3, and leaves fort.7/fort.8, saved as b.<name>/s.<name> (AUTO's ``@sv``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path

from benchmarks.auto_peer.fort import Solution, count_points, read_solutions

HERE = Path(__file__).resolve().parent
PARNAMES = "{1: 'H', 2: 'S', 3: 'nubar', 4: 'e', 5: 'G5', 6: 'num', 9: 'Phi'}"

#: constants shared by every run (AUTO-07p manual, chapter 10): NTST 40 mesh intervals with
#: NCOL 4 collocation points, adaptive mesh (IAD 3), BP and LP detection (ISP 2, ILP 1), exact
#: Jacobian (JAC 1: complex step in gpcf.f90).  EPSL = EPSU = 1e-5: with 1e-6 or 1e-7 Newton
#: does not converge at the BPs of uniform shear ("Possible special point", not labelled); EPSS
#: below 1e-5 loses BPs too (1e-6: one of three found, in 16 s).  DSMAX 2 (5: BPs only to 1e-6).
COMMON = dict(NDIM=5, IPS=4, ILP=1, NTST=40, NCOL=4, IAD=3, ISP=2, IPLT=0, NBC=6, NINT=0, NMX=300, NPR=1000,
              MXBF=0, IID=0, ITMX=8, ITNW=7, NWTN=3, JAC=1, EPSL=1e-5, EPSU=1e-5, EPSS=1e-5, DSMIN=1e-6,
              DSMAX=2.0, IADS=1, NPAR=20)


def find_auto() -> tuple[Path | None, str]:
    """(AUTO_DIR, '') when AUTO-07p's library and gfortran are available, else (None, why not)."""
    candidates = [os.environ.get("AUTO_DIR", ""), "/usr/lib/auto-07p"]
    auto_dir = next((Path(c) for c in candidates if c and (Path(c) / "lib" / "main.o").exists()), None)
    if auto_dir is None:
        return None, "AUTO-07p is not installed (apt-get install auto-07p; or set AUTO_DIR)"
    if shutil.which("gfortran") is None:
        return None, "gfortran is not installed (apt-get install gfortran; AUTO-07p compiles each equation file)"
    return auto_dir, ""


def compile_equations(auto_dir: Path, workdir: Path, source: Path = HERE / "gpcf.f90") -> Path:
    """The executable of an AUTO equation file (default: gpcf.f90), linked against AUTO's library."""
    exe = workdir / f"{source.stem}.exe"
    objects = sorted(str(p) for p in (auto_dir / "lib").glob("*.o"))
    subprocess.run(["gfortran", "-O2", "-fopenmp", "-std=legacy", str(source), *objects, "-o", str(exe)],
                   cwd=workdir, check=True, capture_output=True)
    return exe


def contin_ab_orbits(workdir: Path) -> list[str]:
    """contin's side of the ab orbit checks, in ``workdir``: ``trace ab`` (ab.h5) and its orbits from
    HB1, 40 steps through the fold of cycles (cyc.h5); the command prefix that ran them."""
    import sys

    contin = [sys.executable, "-m", "contin"]
    subprocess.run([*contin, "trace", "ab", "-o", "ab.h5", "-q"], cwd=workdir, check=True)
    subprocess.run([*contin, "continue", "ab.h5", "--from", "HB1", "--cycles", "--max-steps", "40", "-o", "cyc.h5"],
                   cwd=workdir, check=True, capture_output=True)
    return contin


def restart(exe: Path, workdir: Path, solutions: str, constants_text: str) -> Path:
    """One AUTO run of ``exe`` in ``workdir`` from the s-file ``solutions`` (copied to fort.3, where
    AUTO's IRS finds its label) with the constants ``constants_text`` on stdin; the fort.8 path."""
    for f in ("fort.7", "fort.8", "fort.9"):
        (workdir / f).unlink(missing_ok=True)
    shutil.copy(workdir / solutions, workdir / "fort.3")
    subprocess.run([str(exe)], input=constants_text, text=True, cwd=workdir, check=True, capture_output=True,
                   env={**os.environ, "OMP_NUM_THREADS": "1"})
    return workdir / "fort.8"


def constants(**kw: object) -> str:
    c = {**COMMON, **kw}
    lines = [f"parnames = {PARNAMES}"]
    for key, value in c.items():
        if isinstance(value, str) and key not in ("ICP", "UZSTOP", "UZR", "STOP"):
            value = repr(value)
        lines.append(f"{key} = {value}")
    return "\n".join(lines) + "\n"


class Runner:
    """Runs of one AUTO job in ``workdir`` with the start parameters ``start`` (GPCF_PAR)."""

    def __init__(self, exe: Path, workdir: Path, start: Mapping[str, float]) -> None:
        self.exe = exe
        self.workdir = workdir
        self.env = {**os.environ, "OMP_NUM_THREADS": "1",
                    "GPCF_PAR": " ".join(repr(float(start[k])) for k in ("H", "nu", "e", "G5", "num"))}
        self.points = 0

    def run(self, name: str, restart: str | None = None, **kw: object) -> list[Solution]:
        for f in ("fort.7", "fort.8", "fort.9", "fort.3"):
            (self.workdir / f).unlink(missing_ok=True)
        if restart is not None:
            shutil.copy(self.workdir / f"s.{restart}", self.workdir / "fort.3")
        subprocess.run([str(self.exe)], input=constants(**kw), text=True, cwd=self.workdir, env=self.env,
                       check=True, capture_output=True)
        shutil.move(self.workdir / "fort.7", self.workdir / f"b.{name}")
        shutil.move(self.workdir / "fort.8", self.workdir / f"s.{name}")
        self.points += count_points(self.workdir / f"b.{name}")
        return read_solutions(self.workdir / f"s.{name}")
