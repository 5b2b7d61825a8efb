"""``contin fit`` and ``contin unfold`` (gravity unfolding of the gPCF pitchfork)."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from contin.cli import main


def test_fit_compute_agrees_with_lyapunov_schmidt(tmp_path):
    """b1 and alpha1 fitted to branches at G = 2e-8..1e-7 near H_1^c agree with the
    Lyapunov-Schmidt coefficients within 5 %; the file is reusable without --compute."""
    path = tmp_path / "bp.h5"
    r = CliRunner().invoke(main, ["fit", "--compute", str(path), "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["critical_value"] == pytest.approx(13.0685293, abs=1e-6)
    assert doc["relative_difference"]["b1"] < 0.05
    assert doc["relative_difference"]["alpha1"] < 0.05
    assert doc["G"] == [2e-8, 5e-8, 1e-7]
    again = CliRunner().invoke(main, ["fit", str(path), "--json"])
    assert again.exit_code == 0
    assert json.loads(again.stdout)["fit"]["alpha1"] == pytest.approx(doc["fit"]["alpha1"], rel=1e-12)


def test_fit_bad_input(tmp_path):
    r = CliRunner().invoke(main, ["fit", str(tmp_path / "missing.h5")])
    assert r.exit_code == 1 and "Error" in r.output
    r = CliRunner().invoke(main, ["fit", "--compute", str(tmp_path / "x.h5"), "--G", "-1"])
    assert r.exit_code == 1 and "positive" in r.output


def test_unfold_bad_setting():
    r = CliRunner().invoke(main, ["unfold", "-s", "bogus=1"])
    assert r.exit_code == 1 and "unknown setting 'bogus'" in r.output


@pytest.mark.slow
def test_unfold_floating_plug_limit(tmp_path):
    """nu = 0.3, e = 0.8: the fold curve of the first pitchfork reaches its largest G at
    Fr* = 254 (H = 19.1): no floating-plug state below Fr* (slides: isola gone at Fr = 250)."""
    fig = tmp_path / "pd.png"
    r = CliRunner().invoke(main, ["unfold", "--json", "-o", str(fig)])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["fr_min_floating_plug"] == pytest.approx(254.1, abs=1.0)
    assert fig.exists()
    assert doc["critical_gaps"][0] == pytest.approx(13.0685, abs=1e-3)
