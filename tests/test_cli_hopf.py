"""CLI: HB and UZ rows of ``contin trace`` (demo scene ``lorenz``), ``--uz``, ``--stop-at``."""

from __future__ import annotations

import json
import math

import numpy as np

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


def test_readme_hopf_section_examples_run():
    """The python blocks of README's "Hopf points, user zeros, Hopf curves" section run as printed
    and give the numbers their comments state."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    section = text[text.index("## Hopf points, user zeros, Hopf curves"):]
    section = section[:section.index("\n## ", 5)]
    code = "\n".join(re.findall(r"```python\n(.*?)\n```", section, flags=re.S))
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)
    assert abs(ns["hb"].params["rho"] - 470 / 19) <= 1e-10 * 470 / 19
    uz = {sp.note: sp.params["rho"] for sp in ns["br"].points("UZ")}
    assert math.isclose(uz["x=7"], 1 + 49 / (8 / 3), rel_tol=1e-11) and math.isclose(uz["rho=25"], 25.0, rel_tol=1e-11)
    from tests.test_hopfcurve import co_bt_reference  # independent scipy solve of the BT system

    bts = ns["curve"].points("BT")
    assert len(bts) == 2
    for bt in bts:
        ref = co_bt_reference(np.concatenate([bt.state[:3], [bt.params["q2"], bt.params["k"]]]))
        assert np.allclose([bt.params["q2"], bt.params["k"]], ref[3:], rtol=1e-9)
