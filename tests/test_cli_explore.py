"""``contin trace SCENE --depth D``: the core diagram builder (contin.diagram.explore) from the
command line, on the demo scenes' start points; numbers against closed forms (Allen-Cahn BPs of
u = 0 at lam = k^2, Swift-Hohenberg at (1 - m_k)^2) and an independent duplicate test on the
stored states."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def duplicates(branches, tol: float = 1e-3) -> list[tuple[str, str]]:
    """Pairs (a, b) with >= 90 % of a's stored points within tol of b's points (max norm over
    (u, lam), nearest stored point): independent of the builder's projected coordinates."""
    out = []
    for a in branches:
        pa = np.column_stack([a.states, a.params["lam"]])
        for b in branches:
            if a is b:
                continue
            pb = np.column_stack([b.states, b.params["lam"]])
            # distance to the nearest point of b, refined by b's step: points of a on b lie within
            # half of b's largest step of one of b's points
            step = float(np.max(np.abs(np.diff(pb, axis=0)))) if len(pb) > 1 else 0.0
            d = np.min(np.max(np.abs(pa[:, None, :] - pb[None, :, :]), axis=2), axis=1)
            if np.mean(d <= tol + 0.5 * step) >= 0.9:
                out.append((a.id, b.id))
    return out


def test_allen_cahn_depth3_from_the_cli(tmp_path):
    """u = 0 on [0, pi] for lam in [0, 10]: BPs at 1, 4, 9 (closed form k^2), one traced branch per
    BP and its mirror -u, nothing twice, the file readable by info/diagram."""
    out = tmp_path / "ac.h5"
    res = run("trace", "allen-cahn", "--grid", "24", "--depth", "3", "--no-stability", "-o", str(out))
    assert res.exit_code == 0, res.output
    branches, meta = io.load(str(out))
    ids = [b.id for b in branches]
    assert len(branches) == 7 and len(set(ids)) == 7
    assert sorted(ids) == sorted(["0", "0.BP2.1", "0.BP2.1'", "0.BP3.1", "0.BP3.1'", "0.BP4.1", "0.BP4.1'"])
    root = next(b for b in branches if b.id == "0")
    assert [bp.params["lam"] for bp in root.branch_points] == pytest.approx([1.0, 4.0, 9.0], abs=1e-8)
    mirrors = meta["extra"]["diagram"]["mirrors"]
    assert mirrors == {"0.BP2.1'": "0.BP2.1", "0.BP3.1'": "0.BP3.1", "0.BP4.1'": "0.BP4.1"}
    for mid, tid in mirrors.items():
        m, t = (next(b for b in branches if b.id == i) for i in (mid, tid))
        assert np.array_equal(m.states, -t.states)
    assert not duplicates(branches)
    # the switched branches leave u = 0 at their BP: mode k has lam -> k^2 as its amplitude -> 0
    for k in (1, 2, 3):
        b = next(b for b in branches if b.id == f"0.BP{k + 1}.1")
        assert b.params["lam"][0] == pytest.approx(k * k, abs=1e-6)
        assert np.max(np.abs(b.states[-1])) > 0.1
    info = run("info", str(out))
    assert info.exit_code == 0 and "0.BP4.1'" in info.output


def test_bratu_depth_gives_the_fold_only(tmp_path):
    """Bratu has no BP: --depth 3 is the start branch alone, its fold at lam* = 3.513830719125162."""
    out = tmp_path / "bratu.h5"
    res = run("trace", "bratu", "--grid", "24", "--depth", "3", "--no-stability", "-o", str(out))
    assert res.exit_code == 0, res.output
    branches, _ = io.load(str(out))
    assert [b.id for b in branches] == ["0"]
    assert [lp.params["lam"] for lp in branches[0].fold_points] == pytest.approx([3.513830719125162], abs=1e-9)


@pytest.mark.slow
def test_swift_hohenberg_depth2_from_the_cli(tmp_path):
    """BifurcationKit's tutorial problem (N = 40, lam <= 0.6): the 4 BPs of u = 0 at their closed
    form (1 - m_k)^2, one traced branch and one mirror per BP, no duplicate (~15 s)."""
    from problems.swift_hohenberg import SwiftHohenberg

    out = tmp_path / "sh.h5"
    res = run("trace", "swift-hohenberg", "--grid", "40", "--depth", "2", "--no-stability", "-s", "lam_max=0.6",
              "-o", str(out))
    assert res.exit_code == 0, res.output
    branches, meta = io.load(str(out))
    exact = SwiftHohenberg(40, 6.0).trivial_branch_points(-1.0, 0.6)
    assert len(exact) == 4
    root = next(b for b in branches if b.id == "0")
    assert [bp.params["lam"] for bp in root.branch_points] == pytest.approx(exact, abs=1e-9)
    assert len(branches) == 9 and len(meta["extra"]["diagram"]["mirrors"]) == 4
    assert not duplicates(branches)
    for b in branches:  # every stored point solves F (mirrors included)
        pb = SwiftHohenberg(40, 6.0)
        for j in (0, len(b) // 2, len(b) - 1):
            assert np.max(np.abs(pb.residual(b.states[j], {"lam": b.params["lam"][j], "nu": 2.0}))) < 1e-7


def test_swift_hohenberg_trace_names_bps_against_closed_form():
    """Without --depth the scene traces u = 0 only; its notes compare each BP with (1 - m_k)^2."""
    res = run("trace", "swift-hohenberg", "--grid", "30", "--no-stability", "--json", "-s", "lam_max=0.2", "-q")
    assert res.exit_code == 0, res.output
    import json

    doc = json.loads(res.stdout)
    notes = [n for n in doc["notes"] if "closed form" in n]
    assert len(notes) == 2
    errors = [float(n.rsplit("error ", 1)[1].rstrip(")")) for n in notes]
    assert max(abs(e) for e in errors) < 1e-9 and all(math.isfinite(e) for e in errors)


@pytest.mark.parametrize("args, message", [
    (("trace", "lorenz", "--depth", "2"), "gives no start point"),
    (("trace", "bratu", "--max-branches", "3"), "--max-branches needs --depth"),
    (("trace", "bratu", "--depth", "2", "--tol", "1e-6"), "fixed grid"),
    (("trace", "bratu", "--depth", "0"), "depth"),
    (("trace", "swift-hohenberg", "--depth", "2", "--method", "cheb"), "one discretization"),
])
def test_depth_bad_input_one_error_line(args, message):
    res = run(*args)
    assert res.exit_code != 0
    assert message in res.output and "Traceback" not in res.output
