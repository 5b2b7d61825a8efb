"""CLI: --bp-eigs switches on the eigenvalue-count BP detector (contin.bpdetect) for a scene."""

from __future__ import annotations

import json
import subprocess
import sys


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "contin", *args], capture_output=True, text=True, timeout=600)


def test_trace_bp_eigs_reports_kernel_dimensions() -> None:
    out = run("trace", "allen-cahn", "--bp-eigs", "6", "--no-stability", "-q", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    bps = [s for s in doc["special_points"] if s["type"] == "BP"]
    # pitchforks of the trivial branch at lam = k^2 (Dirichlet eigenvalues on [0, pi]), k = 1, 2, 3
    assert [round(s["params"]["lam"], 9) for s in bps if s["branch"] == "0"] == [1.0, 4.0, 9.0]
    assert all("kernel dimension 1" in s["note"] for s in bps if s["branch"] == "0")


def test_trace_bp_eigs_bad_value_is_a_usage_error() -> None:
    out = run("trace", "allen-cahn", "--bp-eigs", "0")
    assert out.returncode == 2 and "Traceback" not in out.stderr
