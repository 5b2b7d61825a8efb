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
    out = run("trace", "allen-cahn", "--bp-eigs", "-1")
    assert out.returncode == 2 and "Traceback" not in out.stderr


def test_bp_curve_scene_follows_n_pi_psi() -> None:
    """contin trace bp-curve: H_1^c(nu) continued in (nu, H); the scene compares every point with
    pi psi(nu, e) itself, and this test recomputes that deviation from the stored columns."""
    import math

    import numpy as np

    from problems.couette.closures import critical_gap_factor

    out = run("trace", "bp-curve", "-s", "nu_min=0.28", "-s", "nu_max=0.32", "--no-stability", "-q", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["extra"]["nu_reached"] == [0.28, 0.32]
    assert doc["extra"]["max_rel_deviation"] < 1e-10
    ends = [s for s in doc["special_points"] if s["branch"] == "bp-curve" and s["type"] == "EP"]
    assert sorted(round(s["params"]["nu"], 12) for s in ends) == [0.28, 0.32]
    for s in ends:
        ref = math.pi * float(critical_gap_factor(np.float64(s["params"]["nu"]), 0.8, "jj", 0.65))
        assert abs(s["params"]["H"] - ref) / ref < 1e-10


def test_bp_curve_scene_bad_input_is_one_error_line() -> None:
    out = run("trace", "bp-curve", "-s", "nu=0.6", "-s", "nu_max=0.5")
    assert out.returncode == 1 and out.stderr.strip().startswith("Error:") and "Traceback" not in out.stderr
