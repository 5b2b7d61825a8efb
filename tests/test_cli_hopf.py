"""CLI: HB and UZ rows of ``contin trace`` (demo scene ``lorenz``), ``--uz``, ``--stop-at``."""

from __future__ import annotations

import json
import math

from click.testing import CliRunner

from contin import io
from contin.cli import main


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_trace_lorenz_prints_hb_and_uz_rows_and_stores_them(tmp_path):
    out = tmp_path / "lorenz.h5"
    res = run("trace", "lorenz", "--uz", "rho=25,30", "-o", str(out), "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    rows = {sp["label"]: sp for sp in doc["special_points"]}
    hb = [r for r in rows.values() if r["type"] == "HB"]
    uz = sorted((r for r in rows.values() if r["type"] == "UZ"), key=lambda r: r["params"]["rho"])
    assert len(hb) == 1 and abs(hb[0]["params"]["rho"] - 470 / 19) <= 1e-10 * 470 / 19
    assert math.isclose(hb[0]["data"]["omega"] ** 2, 1760 / 19, rel_tol=1e-9) and hb[0]["data"]["l1"] > 0
    assert len(uz) == 2
    assert all(math.isclose(r["params"]["rho"], v, rel_tol=1e-11) for r, v in zip(uz, (25.0, 30.0), strict=True))
    assert [r["data"]["value"] for r in uz] == [25.0, 30.0]
    assert "HB" in res.stderr and "omega=" in res.stderr and "subcritical" in res.stderr
    assert "possible Hopf" not in res.stderr  # the stability audit counts the HB
    (branch,), _ = io.load(out)
    assert {sp.type for sp in branch.special_points} >= {"HB", "UZ"}
    assert run("diagram", str(out), "-o", str(tmp_path / "d.png")).exit_code == 0


def test_stop_at_uz_and_bad_uz_input():
    res = run("trace", "lorenz", "--uz", "rho=25,30", "--stop-at", "UZ1", "--json")
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    uz = [sp["params"]["rho"] for sp in doc["special_points"] if sp["type"] == "UZ"]
    assert len(uz) == 1 and math.isclose(uz[0], 25.0, rel_tol=1e-11)
    assert any("stopped after UZ1" in sp["note"] for sp in doc["special_points"] if sp["type"] == "EP")
    for bad in (("--uz", "rho=a"), ("--uz", "rho"), ("--uz", "H=25"), ("--stop-at", "UZ0")):
        res = run("trace", "lorenz", *bad)
        assert res.exit_code != 0
        assert "Error" in res.output and "Traceback" not in res.output
