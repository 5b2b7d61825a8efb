"""The gPCF gravity jobs as scenes with the generic commands: ``contin trace gravity-unfolding``
then ``contin fit FILE --at BP1`` (was ``contin fit --compute``), and ``contin trace
gravity-phase`` (was ``contin unfold``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main
from problems.couette import compiled


def test_fit_agrees_with_lyapunov_schmidt(tmp_path):
    """``contin fit --json`` at G = 0, 1e-7, 3e-7 near H_1^c: B(H), alpha(G), beta(G)
    with errors; b1, alpha1 AND beta1 of the canonical unfolding agree with Lyapunov-Schmidt
    within 5 % (measured < 0.5 %) and within the stated errors; alpha(0) = beta(0) = 0; the
    file's one-parameter folds are predicted to 2e-3; no hysteresis point (alpha1 beta1 < 0)."""
    path = tmp_path / "bp.h5"
    r = CliRunner().invoke(main, ["trace", "gravity-unfolding", "-s", "G=1e-7,3e-7", "--no-stability", "-q",
                                  "-o", str(path)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["fit", str(path), "--at", "BP1", "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["critical_value"] == pytest.approx(13.0685293, abs=1e-6)
    assert doc["imperfection"] == "G" and doc["delta"] == "delta_s" and doc["parameter"] == "H"
    assert doc["imperfection_values"] == [0.0, 1e-7, 3e-7]
    for k in ("b1", "alpha1", "beta1"):
        c = doc["coefficients"][k]
        assert c["relative_difference"] < 5e-3 and c["agree_5pct"]
        assert 0 < c["fit_err"] and abs(c["fit"] - c["lyapunov_schmidt"]) <= 3 * (c["fit_err"] + c["lyapunov_schmidt_err"])
    assert doc["coefficients"]["beta1"]["lyapunov_schmidt"] == pytest.approx(-1546.1, rel=1e-3)
    assert doc["B"]["b1"] == pytest.approx(0.0088522, rel=1e-3) and doc["B"]["b1_err"] > 0
    alpha = {a["mu"]: a for a in doc["alpha"]}
    beta = {b["mu"]: b for b in doc["beta"]}
    assert abs(alpha[0.0]["alpha"]) < 1e-8 * alpha[1e-7]["alpha"]
    assert abs(beta[0.0]["beta"]) < 1e-6 * abs(beta[1e-7]["beta"])
    assert alpha[1e-7]["alpha"] / 1e-7 == pytest.approx(50.62, rel=1e-3)
    assert beta[1e-7]["beta"] / 1e-7 == pytest.approx(-1546, rel=0.02)
    assert all(a["alpha_err"] > 0 for a in doc["alpha"]) and all(b["beta_err"] > 0 for b in doc["beta"])
    folds = {f["mu"]: f for f in doc["folds"]}
    assert sorted(folds) == [1e-7, 3e-7]
    # next-order error grows like G^(4/3): 3.5e-4 at 1e-7, 1.5e-3 at 3e-7 (leading order: 1.7e-2, 2.8e-2)
    assert abs(folds[1e-7]["rel_error"]) < 5e-4 and abs(folds[3e-7]["rel_error"]) < 2e-3
    for f in folds.values():
        assert abs(f["predicted_leading"] / f["lambda_minus_lc"] - 1) > 10 * abs(f["rel_error"])
    assert doc["hysteresis"]["exists"] is False and doc["hysteresis"]["perturbative"] is False
    assert doc["hysteresis"]["mu"] ** -0.5 == pytest.approx(40.6, rel=0.02)  # Fr = G^-1/2 where it would be
    assert len(doc["fit"]["unfolding"]["covariance"]["matrix"]) == 5
    # the pitchfork continued in (H, G): the fold curve through the cusp at BP1 meets the folds that
    # the one-parameter traces at G = 3e-7 located, and is mirror-symmetric (H(G) = H(-G))
    cusp = tmp_path / "cusp.h5"
    r = CliRunner().invoke(main, ["continue", str(path), "--from", "BP1", "--free", "G", "--bounds", "G=-3e-7:3e-7",
                                  "--bounds", "H=12:14", "--ds", "0.01", "--ds-max", "0.05", "-o", str(cusp)])
    assert r.exit_code == 0, r.output
    (curve,), _ = io.load(cusp)
    ends = [sp for sp in curve.special_points if sp.type == "EP"]
    assert sorted(sp.params["G"] for sp in ends) == pytest.approx([-3e-7, 3e-7], abs=1e-18)
    h_lp = folds[3e-7]["lambda_minus_lc"] + doc["critical_value"]
    for sp in ends:
        assert sp.params["H"] == pytest.approx(h_lp, abs=1e-7)
    # continued in nu instead (which keeps the symmetry, so the pitchfork persists): the curve of
    # pitchforks H_1^c(nu), against the closed form pi psi(nu, e) of physics.md sec. 4
    from problems.couette.pitchfork import analytic_critical_gaps

    pf = tmp_path / "pf.h5"
    r = CliRunner().invoke(main, ["continue", str(path), "--from", "BP1", "--free", "nu", "--bounds", "nu=0.29:0.31",
                                  "--bounds", "H=1:20", "--ds", "0.005", "--ds-max", "0.01", "-o", str(pf)])
    assert r.exit_code == 0, r.output
    (bpc,), _ = io.load(pf)
    assert bpc.kind == "bp-curve" and bpc.free == ("H", "nu")
    nu = bpc.params["nu"]
    assert nu.min() == pytest.approx(0.29, abs=1e-12) and nu.max() == pytest.approx(0.31, abs=1e-12)
    ref = np.array([analytic_critical_gaps(v, 0.8, 1)[0] for v in nu])
    assert np.max(np.abs(bpc.params["H"] - ref) / ref) < 1e-9


def test_fit_bad_input(tmp_path):
    r = CliRunner().invoke(main, ["fit", str(tmp_path / "missing.h5"), "--at", "BP1"])
    assert r.exit_code == 1 and "Error" in r.output
    r = CliRunner().invoke(main, ["fit", str(tmp_path / "missing.h5"), "--at", "BP1", "--window", "0"])
    assert r.exit_code == 1 and "--window must be a finite number > 0" in r.output
    r = CliRunner().invoke(main, ["fit", str(tmp_path / "missing.h5"), "--at", "BP1", "--delta-max", "nan"])
    assert r.exit_code == 1 and "--delta-max must be a finite number > 0" in r.output
    r = CliRunner().invoke(main, ["trace", "gravity-unfolding", "-s", "G=-1"])
    assert r.exit_code == 1 and "positive" in r.output
    r = CliRunner().invoke(main, ["trace", "gravity-unfolding", "-s", "window=0"])
    assert r.exit_code == 1 and "window must be > 0" in r.output


def test_unfold_bad_setting():
    r = CliRunner().invoke(main, ["trace", "gravity-phase", "-s", "bogus=1"])
    assert r.exit_code == 1 and "unknown parameter 'bogus'" in r.output
    for bad, msg in (("Fr_start=-100", "Fr_start"), ("H_max=nan", "not a number"), ("H_min=60", "H_min < H_max"),
                     ("nu=0.7", "0 < nu < 0.65")):
        r = CliRunner().invoke(main, ["trace", "gravity-phase", "-s", bad])
        assert r.exit_code != 0 and msg in r.output, (bad, r.output)


def test_unfold_checks_the_output_before_computing(tmp_path):
    r = CliRunner().invoke(main, ["trace", "gravity-phase", "-o", str(tmp_path / "no" / "such" / "dir.h5")])
    assert r.exit_code == 1 and "does not exist" in r.output


@pytest.mark.slow
def test_unfold_floating_plug_limit(tmp_path):
    """nu = 0.3, e = 0.8: the fold curve of the first pitchfork reaches its largest G at
    Fr* = 254 (H = 19.1): no floating-plug state below Fr* (slides: isola gone at Fr = 250)."""
    out = tmp_path / "pd.h5"
    r = CliRunner().invoke(main, ["trace", "gravity-phase", "--json", "-q", "-o", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["extra"]["fr_min_floating_plug"] == pytest.approx(254.1, abs=1.0)
    assert out.exists()
    assert doc["extra"]["critical_gaps"][0] == pytest.approx(13.0685, abs=1e-3)
    # the CLI's default engine (auto): the compiled one where numba is installed (the test extra)
    assert doc["discretization"]["engine"] == ("numba" if compiled.available() else "numpy")
