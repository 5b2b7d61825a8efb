"""Accuracy audit of stored states against a fine Chebyshev reference (session 15).

For a run file (``contin trace SCENE ... -o F.h5``) every stored state of every one-parameter
branch is carried onto a fine Chebyshev grid (the problem's ``transfer`` hook; FD states too),
solved again there by Newton at its own parameters and compared in the problem's
``solution_error`` norm.  Independent of the tracer's two-grid check: the reference grid is fixed
(cheb ``ref`` or 2N, whichever is larger) and always Chebyshev.

    python -m benchmarks.audit_families bratu --method fd2 --tol 1e-4
    python -m benchmarks.audit_families disks-steady --tol 1e-6 -- -s H=64
    python -m benchmarks.audit_families nonlocal      # the adaptive non-local scenes (audit16)

Prints one line per (branch, worst point) and a summary: states audited, max error / tol, the
warnings the run printed and its exit code.  Special points are compared by the caller (closed
forms) or with a fixed-grid run on a fine grid.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Run:
    path: str
    exit_code: int
    warnings: list[str]
    stderr: str
    seconds: float


@dataclass
class PointAudit:
    branch: str
    index: int
    at: float
    grid: int
    ref_grid: int
    error: float
    message: str = ""


@dataclass
class FileAudit:
    points: list[PointAudit] = field(default_factory=list)

    def worst(self) -> PointAudit | None:
        ok = [p for p in self.points if math.isfinite(p.error)]
        return max(ok, key=lambda p: p.error) if ok else None

    def failed(self) -> list[PointAudit]:
        return [p for p in self.points if not math.isfinite(p.error)]


def run_trace(scene: str, args: list[str], *, timeout: float = 300, out: str | None = None) -> Run:
    import time

    if out is None:
        fd, out = tempfile.mkstemp(suffix=".h5", prefix=f"audit-{scene}-")
        os.close(fd)
        os.unlink(out)
    cmd = [sys.executable, "-m", "contin", "trace", scene, *args, "--no-stability", "-q", "-o", out]
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    dt = time.perf_counter() - t
    warns = [ln for ln in r.stderr.splitlines() if ln.lower().startswith("warning")]
    return Run(out, r.returncode, warns, r.stderr, dt)


def as_cheb(problem: Any, n: int) -> Any:
    """``problem``'s model on a Chebyshev grid of n intervals (the reference)."""
    from problems.demo import _DirichletBVP
    from problems.disks.model import DiskCouetteProblem
    from problems.nonlocal_flow.cylinder import CylindricalCouette
    from problems.nonlocal_flow.plane import PlaneShear

    if isinstance(problem, DiskCouetteProblem):
        return DiskCouetteProblem("cheb", n, walls=problem.walls, closure=problem.closure, gravity=problem.gravity)
    if isinstance(problem, PlaneShear):
        return PlaneShear("cheb", n, problem.cs, phi_model=problem.phi_model)
    if isinstance(problem, CylindricalCouette):
        return CylindricalCouette("cheb", n, problem.cs, operator=problem.operator)
    if isinstance(problem, _DirichletBVP):
        return type(problem)("cheb", n)
    raise TypeError(f"no reference for {type(problem).__name__}")


def reference_solve(problem: Any, u: np.ndarray, p: Mapping[str, Any], n_ref: int) -> tuple[np.ndarray, np.ndarray, Any]:
    """(T u, u_ref, ref problem): u carried onto cheb n_ref and solved there at p (plain Newton,
    then two precise-residual polish steps where the problem has them)."""
    from contin.newton import newton
    from contin.options import NewtonOptions
    from contin.verify import _polish

    ref = as_cheb(problem, n_ref)
    moved = np.asarray(problem.transfer(u, ref), dtype=float)
    res = newton(ref, moved, p, NewtonOptions(max_iterations=30))
    if not res.converged:
        raise RuntimeError(f"reference Newton on cheb {n_ref} failed: {res.message}")
    return moved, _polish(ref, res.u, p, 1e-12), ref


def audit_branches(branches: list[Any], problem_of: Callable[[Any], Any], params: Mapping[str, Any], *,
                   ref_min: int = 128, ref_max: int = 512, skip_first_switched: bool = True) -> FileAudit:
    """Every stored state against cheb max(ref_min, 2N) (at most ref_max)."""
    from contin.adapt import on_grid, solution_error

    out = FileAudit()
    for b in branches:
        if len(getattr(b, "free", ())) != 1 or len(b) == 0:
            continue
        base = problem_of(b)
        for i in range(len(b)):
            try:
                u = np.asarray(b.state(i), dtype=float)
            except KeyError:
                continue
            p = {**params, **{k: float(v[i]) for k, v in b.params.items()}}
            n = int(b.grid_at(i)) if b.grid_at(i) is not None else int(base.grid_size)
            if i == 0 and skip_first_switched and b.parent and str(b.parent).upper().startswith(("BP", "LP")):
                continue  # the parent's BP: J singular at fixed parameters (checked as a special point)
            if any(int(getattr(sp, "index", -1)) == i and sp.type in ("BP", "LP") for sp in b.special_points):
                continue  # a BP/LP row: J singular there; its position is audited instead
            coarse = on_grid(base, n)
            n_ref = min(max(ref_min, 2 * n), ref_max)
            try:
                moved, u_ref, ref = reference_solve(coarse, u, p, n_ref)
                err = float(solution_error(ref, moved, u_ref, p))
                out.points.append(PointAudit(b.id, i, float(b.parameter_values[i]), n, n_ref, err))
            except Exception as exc:  # noqa: BLE001 -- reported
                out.points.append(PointAudit(b.id, i, float(b.parameter_values[i]), n, n_ref, math.nan, str(exc)))
    return out


def file_problem(path: str) -> tuple[list[Any], dict[str, Any], Any]:
    """(branches, metadata, problem_of(branch)) of a run file."""
    from contin import io
    from contin.cli.verify import _problem_of

    branches, meta = io.load(path)
    if meta.get("scene") == "nonlocal-muI":  # no problem_factory: muI.U and phiI.U are two problems
        from problems.nonlocal_flow.plane import PlaneShear
        from problems.nonlocal_flow.scenes import CS_DEFAULTS, _grid_of, critical_state

        method, n = _grid_of(meta.get("discretization", {}))
        cs = critical_state({k: float(meta["parameters"].get(k, v)) for k, v in CS_DEFAULTS.items()})
        pbs = {"muI": PlaneShear(method, n, cs), "phiI": PlaneShear(method, n, cs, phi_model="phiI")}
        return branches, meta, lambda b: pbs[b.id.split(".")[0]]
    if meta.get("scene") == "nonlocal-cylinder":  # report_eqs = 0: derived.ratio and report.ratio
        from problems.nonlocal_flow.cylinder import CylindricalCouette
        from problems.nonlocal_flow.scenes import CS_DEFAULTS, _grid_of, critical_state

        method, n = _grid_of(meta.get("discretization", {}))
        cs = critical_state({k: float(meta["parameters"].get(k, v)) for k, v in CS_DEFAULTS.items()})
        ops = {op: CylindricalCouette(method, n, cs, operator=op) for op in ("derived", "report")}
        return branches, meta, lambda b: ops[b.id.split(".")[0]]
    problem = _problem_of(meta, path)
    return branches, meta, lambda b: problem


def numeric(params: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in params.items() if isinstance(v, int | float) and not isinstance(v, bool)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--method", default="cheb")
    ap.add_argument("--tol", type=float, default=None)
    ap.add_argument("--ref-min", type=int, default=128)
    ap.add_argument("--ref-max", type=int, default=512)
    ap.add_argument("--file", default=None, help="audit this file instead of running the trace")
    ap.add_argument("extra", nargs="*")
    a = ap.parse_args(argv)
    if a.file:
        run = Run(a.file, 0, [], "", 0.0)
    else:
        args = ["--method", a.method, *(["--tol", str(a.tol)] if a.tol else []), *a.extra]
        run = run_trace(a.scene, args)
    print(f"{a.scene} {a.method} tol {a.tol}: exit {run.exit_code}, {len(run.warnings)} warnings, {run.seconds:.1f} s")
    for w in run.warnings:
        print("   ", w[:200])
    if run.exit_code not in (0, 3) and not os.path.exists(run.path):
        print(run.stderr[-2000:])
        return 1
    branches, meta, problem_of = file_problem(run.path)
    tol = a.tol if a.tol else 3e-5
    audit = audit_branches(branches, problem_of, numeric(meta.get("parameters", {})),
                           ref_min=a.ref_min, ref_max=a.ref_max)
    for b in branches:
        pts = [p for p in audit.points if p.branch == b.id and math.isfinite(p.error)]
        if not pts:
            continue
        w = max(pts, key=lambda p: p.error)
        bad = sum(p.error > tol for p in pts)
        print(f"  {b.id:14s} {b.status} {len(pts):4d} states, grids {min(p.grid for p in pts)}..{max(p.grid for p in pts)}, "
              f"max {w.error:.2g} = {w.error / tol:.2g} tol at {b.parameter} = {w.at:.8g} (grid {w.grid} vs cheb {w.ref_grid}); "
              f"{bad} > tol")
    for p in audit.failed():
        print(f"  unchecked {p.branch} {p.index}: {p.message}")
    for b in branches:
        for sp in b.special_points:
            print(f"  {b.id} {sp.name} {sp.type} {b.parameter}={sp.params.get(b.parameter, float('nan')):.12g} "
                  f"grid {getattr(sp, 'grid', None)} {sp.note[:120] if sp.note else ''}")
    w = audit.worst()
    print(f"SUMMARY {a.scene} {a.method} tol {tol:g}: {len(audit.points)} states, max {w.error if w else math.nan:.3g} "
          f"= {(w.error / tol) if w else math.nan:.3g} tol, exit {run.exit_code}, warnings {len(run.warnings)}")
    return 0



# ----------------------------------------------------------------------------- batch audit
BRATU_FOLD = 3.513830719125162


def closed_form(scene: str, sp: Any, params: Mapping[str, Any]) -> float | None:
    """The exact position of special point sp of a demo scene (None: no closed form)."""
    if scene in ("bratu", "stretched-bratu") and sp.type == "LP":
        return BRATU_FOLD / (1.0 + float(params.get("a", 0.0)))
    if scene == "allen-cahn" and sp.type == "BP":
        lam = float(sp.params["lam"])
        return float(round(math.sqrt(lam))) ** 2
    if scene == "brusselator" and sp.type == "HB":
        a, d1, d2, length = (float(params.get(k, v)) for k, v in (("a", 2.0), ("D1", 0.02), ("D2", 0.01), ("L", 1.0)))
        best = None
        for k in range(1, 6):  # the mode k nearest the located b
            b = 1 + a * a + (d1 + d2) * (k * math.pi / length) ** 2
            if best is None or abs(b - float(sp.params["b"])) < abs(best - float(sp.params["b"])):
                best = b
        return best
    return None


def audit_run(scene: str, method: str, tol: float | None, extra: list[str], *, ref_min: int = 128,
              ref_max: int = 512, timeout: float = 300) -> dict[str, Any]:
    args = ["--method", method, *(["--tol", repr(tol)] if tol else []), *extra]
    run = run_trace(scene, args, timeout=timeout)
    out: dict[str, Any] = {"scene": scene, "method": method, "tol": tol, "extra": extra, "exit": run.exit_code,
                           "warnings": run.warnings, "seconds": run.seconds}
    if not os.path.exists(run.path):
        out["error"] = run.stderr[-1500:]
        return out
    branches, meta, problem_of = file_problem(run.path)
    params = numeric(meta.get("parameters", {}))
    out["run_tol"] = run_tol(meta)
    audit = audit_branches(branches, problem_of, params, ref_min=ref_min, ref_max=ref_max)
    out["audit"] = audit
    out["branches"] = [(b.id, b.status, b.message[:160], len(b)) for b in branches]
    sps = []
    for b in branches:
        for sp in b.special_points:
            if sp.type not in ("LP", "BP", "HB"):
                continue
            exact = closed_form(scene, sp, {**params, **{k: float(v) for k, v in sp.params.items()}})
            hc = (meta.get("extra") or {}).get(b.id, {}) if scene == "disks-pitchfork" else {}
            if sp.type == "BP" and isinstance(hc, dict) and hc.get("H_c"):
                # uniform shear's BPs: H_n^c = n pi psi in closed form (problems.disks.closures.critical_gaps)
                val0 = float(sp.params["H"])
                exact = min((float(h) for h in hc["H_c"]), key=lambda h: abs(h - val0))
            val = float(sp.params.get(b.parameter, math.nan))
            rel = abs(val - exact) / abs(exact) if exact is not None else math.nan
            sps.append((b.id, sp.name, sp.type, val, exact, rel, getattr(sp, "grid", None), sp.note or ""))
    out["special"] = sps
    os.unlink(run.path)
    return out


def run_tol(meta: Mapping[str, Any]) -> float | None:
    """The tol a run file was computed to: its adaptive tol (a scene's default_tol when --tol was
    not given), else None."""
    options = meta.get("options") or {}
    adapt = options.get("adapt") or {}
    tol = adapt.get("tol") if isinstance(adapt, Mapping) else None
    if tol is None:  # an unfinished or failed run: its options are the overrides ({'tol': 1e-08})
        tol = options.get("tol")
    return float(tol) if isinstance(tol, int | float) and not isinstance(tol, bool) else None


def report(r: dict[str, Any]) -> str:
    tol = r["tol"] or r.get("run_tol") or 3e-5
    lines = [f"== {r['scene']} {r['method']} tol {r['tol']} {' '.join(r['extra'])}: exit {r['exit']}, "
             f"{len(r['warnings'])} warnings, {r['seconds']:.1f} s"]
    lines += [f"   W {w[:220]}" for w in r["warnings"] if "accepted by its estimate" not in w]
    warned = warned_points(r["warnings"])
    n_silent = 0
    if "error" in r:
        return "\n".join(lines + [r["error"]])
    for bid, status, msg, n in r["branches"]:
        pts = [p for p in r["audit"].points if p.branch == bid and math.isfinite(p.error)]
        if not pts:
            lines.append(f"   {bid:14s} {status} {n} points, none audited ({msg})")
            continue
        w = max(pts, key=lambda p: p.error)
        bad = [p for p in pts if p.error > tol]
        lines.append(f"   {bid:14s} {status} {len(pts):3d} states, grids {min(p.grid for p in pts)}..{max(p.grid for p in pts)}, "
                     f"max {w.error:.2g} = {w.error / tol:.2g} tol at {w.at:.8g} (grid {w.grid}); {len(bad)} > tol"
                     + (f"  [{msg}]" if status != "EP" or "limit" in msg else ""))
        silent = [p for p in bad if not any(abs(p.at - v) <= 1e-8 * max(1.0, abs(v)) for v in warned.get(bid, ()))]
        n_silent += len(silent)
        if bad:
            lines.append(f"       {len(bad) - len(silent)} of {len(bad)} > tol warned; silent: {len(silent)}")
        for p in silent[:6]:
            lines.append(f"       SILENT > tol: index {p.index} at {p.at:.10g} grid {p.grid}: {p.error:.2g}")
    for p in r["audit"].failed():
        lines.append(f"   unchecked {p.branch} {p.index}: {p.message[:150]}")
    for bid, name, kind, val, exact, rel, grid, note in r["special"]:
        lines.append(f"   {bid} {name} {kind} {val:.12g}" + (f" exact {exact:.12g} rel {rel:.2g}" if exact else "")
                     + f" grid {grid} {note[:110]}")
    w = r["audit"].worst()
    lines.append(f"SUMMARY {r['scene']} {r['method']} tol {tol:g}: {len(r['audit'].points)} states, max "
                 f"{(w.error / tol) if w else math.nan:.3g} tol, exit {r['exit']}, warnings {len(r['warnings'])}, "
                 f"SILENT above tol {n_silent}")
    return "\n".join(lines)


def warned_points(warnings: list[str]) -> dict[str, list[float]]:
    """{branch: [parameter values]} of the 'accepted by its estimate' warnings."""
    import re

    out: dict[str, list[float]] = {}
    for w in warnings:
        m = re.match(r"warning: branch (\S+): step \d+: \w+=(\S+) accepted by its estimate", w)
        if m:
            out.setdefault(m.group(1), []).append(float(m.group(2)))
    return out


def batch(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--methods", default="cheb,fd2,fd4")
    ap.add_argument("--tols", default="1e-4,1e-6")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--grid", default=None, help="a fixed grid (scenes without --tol)")
    ap.add_argument("--ref-max", type=int, default=512, help="largest reference grid (cheb)")
    a = ap.parse_args(argv)
    extra = [x for s in a.set for x in ("-s", s)]
    for scene in a.scenes:
        for method in a.methods.split(","):
            for tol in a.tols.split(","):
                try:
                    r = audit_run(scene, method, float(tol) if tol else None,
                                  extra + (["--grid", a.grid] if a.grid else []), ref_max=a.ref_max)
                    print(report(r), flush=True)
                except subprocess.TimeoutExpired:
                    print(f"== {scene} {method} tol {tol}: TIMEOUT", flush=True)


#: The adaptive non-local scenes of session 16 (audit16): scene, its extra options
NONLOCAL = (("nonlocal-shear", []), ("nonlocal-cylinder", ["-s", "report_eqs=1"]), ("nonlocal-muI", []))


def nonlocal_audit(argv: list[str] | None = None) -> None:
    """Every stored state of the adaptive non-local scenes at their default tol, 1e-6 and 1e-10,
    on cheb and fd4, against cheb 128..160 re-solves (one SUMMARY line per run: max error / tol,
    the states above tol no warning names)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default=",".join(s for s, _ in NONLOCAL))
    ap.add_argument("--methods", default="cheb,fd4")
    ap.add_argument("--tols", default=",1e-6,1e-10", help="'' is the scene's default tol")
    ap.add_argument("--ref-max", type=int, default=160)
    a = ap.parse_args(argv)
    extras = dict(NONLOCAL)
    for scene in a.scenes.split(","):
        for method in a.methods.split(","):
            for tol in a.tols.split(","):
                try:
                    r = audit_run(scene, method, float(tol) if tol else None, list(extras.get(scene, [])),
                                  ref_min=128, ref_max=a.ref_max, timeout=900)
                    print(report(r), flush=True)
                except subprocess.TimeoutExpired:
                    print(f"== {scene} {method} tol {tol}: TIMEOUT", flush=True)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "batch":
        batch(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "nonlocal":
        nonlocal_audit(sys.argv[2:])
    else:
        raise SystemExit(main())
