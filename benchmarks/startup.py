"""Start-up figures: ``python -m benchmarks.startup [--repeats N] [--json FILE]``.

Prints wall-clock medians (whole processes, ``--repeats`` runs each, default 7) of

- ``contin --version`` and ``contin --help`` (target <= 0.15 s);
- ``import contin.cli`` inside the interpreter (and which heavy libraries it loaded: none);
- start-up to the first continuation step of the main job ``contin trace pitchfork -s nu=0.3
  -s e=0.8``, measured by a wrapper that runs the CLI with ``contin.continuation.trace``
  replaced by a stop watch: process launch to the first call of ``trace``, and to the end of
  that trace run for one step (``max_steps=1``; target <= 0.3 s: everything the first step
  needs is imported and built by then, so deferring an import past the call cannot hide it);
  ``python -c pass`` (the interpreter alone) alongside.

The project's .pyc files are written first (benchmarks/precompile.py).  These are measurements, not tests (tests/test_startup.py asserts the import structure).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

HEAVY = ("numpy", "scipy", "h5py", "matplotlib", "numba")

_IMPORT = """
import sys, time
t = time.perf_counter()
import contin.cli
dt = time.perf_counter() - t
print(dt, ",".join(m for m in {heavy!r} if m in sys.modules))
"""

# Runs the CLI of the main job as it is (the stop watch is patched in when the CLI imports
# contin.continuation).  The first call of contin.continuation.trace (or trace_both)
# prints the time since launch (passed in CONTIN_T0), then runs that trace for one continuation
# step (max_steps = 1: Newton at the start point, the test functions, one predictor-corrector
# step) and prints the time again, and ends the process.  The second figure cannot be lowered by
# moving imports past the first call: whatever the first step needs is loaded by then.
_FIRST_STEP = """
import dataclasses, importlib.abc, importlib.machinery, inspect, os, sys, time


def first(*args, **kwargs):
    import contin.continuation as c

    called = time.time() - float(os.environ["CONTIN_T0"])
    bound = inspect.signature(c.trace_real).bind_partial(*args, **kwargs)
    opts = bound.arguments.get("options", c.ContinuationOptions())
    bound.arguments["options"] = dataclasses.replace(opts, max_steps=1)
    branch = c.trace_real(*bound.args, **bound.kwargs)
    done = time.time() - float(os.environ["CONTIN_T0"])
    assert len(branch) >= 2, branch.message
    print(called, done, flush=True)
    os._exit(0)


class Patch(importlib.abc.MetaPathFinder):
    # replaces trace/trace_both right after contin.continuation is executed, wherever the CLI
    # first imports it (importing it here first would change what the CLI imports before it)
    def find_spec(self, name, path, target=None):
        if name != "contin.continuation":
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            module.trace_real, module.trace, module.trace_both = module.trace, first, first

        spec.loader.exec_module = exec_module
        return spec


sys.meta_path.insert(0, Patch())
from contin.cli import main
main(["trace", "pitchfork", "-s", "nu=0.3", "-s", "e=0.8", "-q", "--no-stability", "-o", os.devnull + ".h5"])
"""

TARGETS = {"contin --version": 0.15, "contin --help": 0.15, "first continuation step": 0.3}


def _contin() -> list[str]:
    return [sys.executable, "-m", "contin"]


def _wall(cmd: list[str], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _first_step(repeats: int, tmp: str) -> tuple[float, float]:
    called, done = [], []
    for _ in range(repeats):
        env = {**os.environ, "CONTIN_T0": repr(time.time())}
        out = subprocess.run([sys.executable, "-c", _FIRST_STEP.replace("os.devnull + \".h5\"", repr(tmp))],
                             env=env, capture_output=True, text=True, check=True)
        t_call, t_done = out.stdout.split()[-2:]
        called.append(float(t_call))
        done.append(float(t_done))
    return statistics.median(called), statistics.median(done)


def measure(repeats: int = 7) -> dict[str, float | str]:
    import tempfile

    rows: dict[str, float | str] = {}
    rows["python -c pass"] = _wall([sys.executable, "-c", "pass"], repeats)
    rows["contin --version"] = _wall([*_contin(), "--version"], repeats)
    rows["contin --help"] = _wall([*_contin(), "--help"], repeats)
    imp = [subprocess.run([sys.executable, "-c", _IMPORT.format(heavy=HEAVY)], capture_output=True, text=True,
                          check=True).stdout.split() for _ in range(repeats)]
    rows["import contin.cli (in-process)"] = statistics.median(float(x[0]) for x in imp)
    rows["heavy modules after import contin.cli"] = imp[0][1] if len(imp[0]) > 1 else "none"
    with tempfile.TemporaryDirectory() as tmp:
        rows["first call of trace"], rows["first continuation step"] = _first_step(repeats, os.path.join(tmp, "x.h5"))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.startup", description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args(argv)
    from benchmarks.precompile import precompile

    precompile()  # as an installed copy has them (benchmarks/precompile.py)
    rows = measure(args.repeats)
    print(f"start-up, wall-clock medians of {args.repeats} runs (s)")
    for name, value in rows.items():
        if isinstance(value, str):
            print(f"  {name:40s} {value}")
            continue
        target = TARGETS.get(name)
        verdict = "" if target is None else f"  target <= {target:g}: {'met' if value <= target else 'NOT met'}"
        print(f"  {name:40s} {value:7.3f}{verdict}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
