"""``python -m benchmarks.auto_peer [--repeats N] [--jobs a,b,c,d] [--json FILE]``

Runs four gPCF jobs on contin and on AUTO-07p, paired and interleaved (contin, AUTO, AUTO,
contin, ...: each repeat alternates which code goes first), whole processes, wall-clock medians:

  a  uniform shear, nu = 0.3, e = 0.8, H = 2.16 -> 43.13 with BP detection
  b  the main job ``contin trace pitchfork -s nu=0.3 -s e=0.8`` (uniform shear and both signs of
     the banded branches of its first three BPs) -- contin with and without its stability pass
     (AUTO has no stability pass for boundary-value problems)
  c  nu = 0.16: the n = 1 branch through its fold (H = 41.9625323)
  d  the (H, G) fold curve of the first pitchfork and its minimum Froude number Fr* = 254.12

and prints points, seconds, the wall-time ratio contin / AUTO and each special point's error on
both sides: BPs against the closed form H_n^c = n pi psi(nu, e) (problems.couette.pitchfork),
the fold against 41.9625323 and Fr* against 254.1204 (cheb-converged values, README "Speed and
accuracy").  Targets of the main job: <= 1.0x AUTO with the stability pass, <= 0.5x without.

Needs AUTO-07p's library (Debian: apt-get install auto-07p; or AUTO_DIR) and gfortran; without
them it says so and exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FOLD_016 = 41.9625323
FR_STAR = 254.1204
TARGETS = {"b (stability)": 1.0, "b (no stability)": 0.5}


def _contin_cmd(job: str, h5: str) -> list[str]:
    if job.startswith("b"):
        cmd = [sys.executable, "-m", "contin", "trace", "pitchfork", "-s", "nu=0.3", "-s", "e=0.8", "-q", "--json", "-o", h5]
        return cmd + (["--no-stability"] if job == "b (no stability)" else [])
    return [sys.executable, "-m", "benchmarks.auto_peer.contin_jobs", job]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run_contin(job: str, tmp: Path) -> tuple[float, float, dict]:
    h5 = str(tmp / "main.h5")
    c, t = _children_cpu(), time.perf_counter()
    out = subprocess.run(_contin_cmd(job, h5), capture_output=True, text=True, check=True)
    dt, dc = time.perf_counter() - t, _children_cpu() - c
    doc = json.loads(out.stdout)
    if job.startswith("b"):
        bps = sorted(s["params"]["H"] for s in doc["special_points"] if s["type"] == "BP" and s["branch"] == "0")
        doc = {"points": sum(b["n_points"] for b in doc["branches"]), "BP": bps}
    return dt, dc, doc


def _run_auto(job: str, exe: Path, tmp: Path) -> tuple[float, float, dict]:
    from benchmarks.auto_peer.auto import Runner
    from benchmarks.auto_peer.jobs import JOBS

    fn, start = JOBS[job[0]]
    work = tmp / f"auto_{job[0]}"
    work.mkdir(exist_ok=True)
    r = Runner(exe, work, start)
    c, t = _children_cpu(), time.perf_counter()
    res = fn(r)
    dt, dc = time.perf_counter() - t, _children_cpu() - c
    return dt, dc, {**res, "points": r.points}


def _errors(job: str, res: dict) -> list[str]:
    from problems.couette.pitchfork import analytic_critical_gaps

    out = []
    if "BP" in res:
        nu = 0.16 if job == "c" else 0.3
        exact = analytic_critical_gaps(nu, 0.8, 3)
        for h in res["BP"]:
            ex = min(exact, key=lambda x: abs(x - h))
            out.append(f"BP {h:.9g} ({abs(h - ex) / ex:.1e})")
    for h in res.get("LP", []):
        out.append(f"LP {h:.9g} ({abs(h - FOLD_016) / FOLD_016:.1e})")
    if "banded branches" in res:
        out.append(f"{res['banded branches']} of 6 switches reached a banded branch")
    if "Fr*" in res:
        out.append(f"Fr* {res['Fr*']:.7g} ({abs(res['Fr*'] - FR_STAR) / FR_STAR:.1e})")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.auto_peer", description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--jobs", default="a,b,c,d")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args(argv)
    from benchmarks.auto_peer.auto import compile_equations, find_auto

    auto_dir, why = find_auto()
    if auto_dir is None:
        print(f"AUTO-07p peer benchmark skipped: {why}.")
        return 0
    os.environ.setdefault("CONTIN_BLAS_THREADS", "1")
    from benchmarks.precompile import precompile

    precompile()  # .pyc files as an installed copy has them (benchmarks/precompile.py)
    jobs = []
    for j in args.jobs.split(","):
        jobs += ["b (stability)", "b (no stability)"] if j.strip() == "b" else [j.strip()]
    rows = []
    with tempfile.TemporaryDirectory() as tmpname:
        tmp = Path(tmpname)
        exe = compile_equations(auto_dir, tmp)
        for job in jobs:
            tc, ta, cc, ca = [], [], [], []
            for k in range(args.repeats):
                order = ("contin", "auto") if k % 2 == 0 else ("auto", "contin")
                for who in order:
                    if who == "contin":
                        dt, dc, rc = _run_contin(job, tmp)
                        tc.append(dt), cc.append(dc)
                    else:
                        dt, dc, ra = _run_auto(job, exe, tmp)
                        ta.append(dt), ca.append(dc)
            row = {"job": job, "contin_s": statistics.median(tc), "auto_s": statistics.median(ta),
                   "contin_cpu_s": statistics.median(cc), "auto_cpu_s": statistics.median(ca),
                   "contin_points": rc["points"], "auto_points": ra["points"],
                   "contin": _errors(job[0], rc), "auto": _errors(job[0], ra)}
            row["ratio"] = row["contin_s"] / row["auto_s"]
            row["cpu_ratio"] = row["contin_cpu_s"] / row["auto_cpu_s"]
            rows.append(row)
            target = TARGETS.get(job)
            verdict = "" if target is None else f"   target <= {target:g}x: {'met' if row['ratio'] <= target else 'NOT met'}"
            print(f"{job}: contin {row['contin_s']:.2f} s ({row['contin_points']} points), AUTO {row['auto_s']:.2f} s "
                  f"({row['auto_points']} points), ratio {row['ratio']:.2f}x{verdict}; CPU {row['contin_cpu_s']:.2f} s "
                  f"/ {row['auto_cpu_s']:.2f} s = {row['cpu_ratio']:.2f}x")
            print(f"   contin: {'; '.join(row['contin']) or '-'}")
            print(f"   AUTO:   {'; '.join(row['auto']) or '-'}")
            sys.stdout.flush()
    print(f"(wall-clock and CPU (user + system of the child processes) medians of {args.repeats} paired, interleaved "
          "runs; relative errors in parentheses; "
          "AUTO-07p NTST 40, NCOL 4, EPSL = EPSU = 1e-5, EPSS = 1e-5; contin cheb 64 in jobs a, c, d; job b is the main command at its defaults, adaptive grid)")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
