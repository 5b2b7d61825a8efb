"""``contin continue FILE --from LABEL --free NAME`` and ``contin fit FILE --at BP`` on a
non-granular problem: the fixture scene tests/twoparam_fixture_scenes.py,
F = x^3 - lam x + mu + K mu x^2 + Q x^5 (K = 0.5, Q = 0.2), whose fold curve and canonical
unfolding are known in closed form."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main

HERE = Path(__file__).parent
K, Q = 0.5, 0.2


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.syspath_prepend(str(HERE))
    mp.setenv("CONTIN_SCENES", "twoparam_fixture_scenes:SCENES")
    path = tmp_path_factory.mktemp("cont") / "ip.h5"
    r = CliRunner().invoke(main, ["trace", "imperfect-pitchfork", "--no-stability", "-q", "-o", str(path)])
    assert r.exit_code == 0, r.output
    yield path
    mp.undo()


@pytest.fixture(autouse=True)
def scenes(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", "twoparam_fixture_scenes:SCENES")


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _on_fold_curve(curve):
    """max residual of the closed form: lam = 3x^2 + 2K mu x + 5Q x^4, F(x, lam, mu) = 0."""
    n = 1
    x = curve.states[:, 0]
    lam, mu = curve.params["lam"], curve.params["mu"]
    assert np.allclose(curve.states[:, 2 * n], mu)  # the augmented state carries the second parameter
    r1 = lam - (3 * x**2 + 2 * K * mu * x + 5 * Q * x**4)
    r2 = x**3 - lam * x + mu + K * mu * x**2 + Q * x**5
    return max(np.max(np.abs(r1)), np.max(np.abs(r2)))


def test_fold_curve_from_LP(run_file, tmp_path):
    branches, _ = io.load(run_file)
    lp = next(sp for b in branches for sp in b.fold_points)
    out = tmp_path / "lp.h5"
    r = invoke("continue", run_file, "--from", lp.name, "--free", "mu", "--bounds", "mu=-0.01:0.01", "-o", out)
    assert r.exit_code == 0, r.output
    (curve,), meta = io.load(out)
    assert meta["scene"] == "imperfect-pitchfork" and curve.free == ("lam", "mu")
    assert len(curve) > 50 and _on_fold_curve(curve) < 1e-9
    # through the cusp at the pitchfork (lam, mu) = (0, 0) to both bounds of mu, ending exactly on them
    mu = curve.params["mu"]
    assert mu[0] == pytest.approx(-0.01, abs=1e-12) and mu[-1] == pytest.approx(0.01, abs=1e-12)
    assert np.all(np.abs(mu) <= 0.01 + 1e-12)
    ends = [sp for sp in curve.special_points if sp.type == "EP"]
    assert [sp.note for sp in ends] == ["reached bound mu=-0.01", "reached bound mu=0.01"]
    assert curve.params["lam"].min() > -1e-9
    cusp = [sp for sp in curve.special_points if sp.type == "LP"]
    assert len(cusp) == 1 and abs(cusp[0].params["lam"]) < 1e-8 and abs(cusp[0].params["mu"]) < 1e-8
    assert [sp.label for sp in curve.special_points] == list(range(1, len(curve.special_points) + 1))


def test_pitchfork_continued_in_its_imperfection_gives_both_halves_of_the_cusp(run_file, tmp_path):
    out = tmp_path / "bp.h5"
    r = invoke("continue", run_file, "--from", "BP2", "--free", "mu", "--bounds", "mu=-0.01:0.01", "-o", out, "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["extra"]["from"] == "BP2" and doc["branches"][0]["free"] == ["lam", "mu"]
    (curve,), _ = io.load(out)
    assert _on_fold_curve(curve) < 1e-9
    x = curve.states[:, 0]
    assert x.min() < -0.05 and x.max() > 0.05  # both halves (d lam/ds = 0 at the start)


def test_continue_bad_input(run_file, tmp_path):
    def err(*args, expect):
        r = invoke("continue", run_file, *args)
        assert r.exit_code == 1 and "Error:" in r.output and expect in r.output, r.output
        assert "Traceback" not in r.output

    err("--from", "EP1", "--free", "mu", expect="only BP, BT, HB, HH, LP, ZH points")
    err("--from", "LP99", "--free", "mu", expect="no point 'LP99'")
    err("--from", "BP2", "--free", "lam", expect="must differ")
    err("--from", "BP2", "--free", "nope", expect="unknown parameter 'nope'")
    err("--from", "BP2", "--free", "mu", "--ds", "nan", expect="--ds must be a finite number > 0")
    err("--from", "BP2", "--free", "mu", "--ds", "-1", expect="--ds must be a finite number > 0")
    err("--from", "BP2", "--free", "mu", "--bounds", "mu=1:0", expect="LO < HI")
    err("--from", "BP2", "--free", "mu", "--bounds", "K=0:1", expect="only the two free parameters")
    err("--from", "BP2", "--free", "mu", "-o", tmp_path / "no" / "x.h5", expect="does not exist")
    # a BP that the second parameter does not unfold (K multiplies mu: at mu = 0 the pitchfork stays)
    # and that is not a symmetry-breaking pitchfork (the fixture has no symmetry): refused
    err("--from", "BP2", "--free", "K", expect="'K' does not unfold BP2")
    err("--from", "BP2", "--free", "Q", expect="'Q' does not unfold BP2")


def test_hopf_point_is_continued_to_its_bogdanov_takens_point():
    """HB of the BT normal form (x' = y, y' = b1 + b2 x + x^2 - x y, tests/hopf_models.py): the
    Hopf curve is the line b1 = 0 (closed form) and meets the BT point at b1 = b2 = 0."""
    from contin.continuation import trace
    from contin.options import ContinuationOptions, StepOptions
    from contin.twoparam import continue_point
    from tests.hopf_models import BTNormalForm

    x = 0.5 * (1 - math.sqrt(1 + 4 * 0.5))
    opts = ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b1": (-1.0, 0.2)}, max_steps=200)
    br = trace(BTNormalForm(), np.array([x, 0.0]), {"b1": -0.5, "b2": -1.0}, "b1", opts)
    (hb,) = br.points("HB")
    curve = continue_point(BTNormalForm(), br, hb, "b2",
                           ContinuationOptions(step=StepOptions(ds=0.05, ds_max=0.1), bounds={"b2": (-2.0, 1.0)},
                                               max_steps=200))
    assert curve.free == ("b1", "b2") and np.allclose(curve.params["b1"], 0.0, atol=1e-10)
    (bt,) = curve.points("BT")
    assert abs(bt.params["b1"]) < 1e-10 and abs(bt.params["b2"]) < 1e-10


def test_unknown_point_types_are_a_clear_error():
    from contin.branch import Branch, SpecialPoint
    from contin.twoparam import NotAvailable, continue_point

    uz = SpecialPoint(type="UZ", index=0, params={"lam": 0.0, "mu": 0.0}, order_parameter=0.0,
                      state=np.zeros(1), label=3)
    br = Branch(parameter="lam", free=("lam",), params={"lam": np.zeros(1), "mu": np.zeros(1)}, observables={},
                states=np.zeros((1, 1)), tangents=np.zeros((1, 2)), ds=np.zeros(1),
                newton_iterations=np.zeros(1, dtype=np.int64), special_points=[uz])
    with pytest.raises(NotAvailable, match="UZ3: only BP, BT, HB, HH, LP, ZH points can be continued in two parameters"):
        continue_point(object(), br, uz, "mu", None)


def test_fit_recovers_the_closed_form_unfolding(run_file):
    """b1 = 1, alpha1 = 1, beta1 = K, q5 = Q, b2 = 0, from both the fit and Lyapunov-Schmidt;
    the fitted graph holds the fixture's F exactly, so the fit is exact to rounding."""
    r = invoke("fit", run_file, "--at", "BP2", "--delta-max", "0.3", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["imperfection"] == "mu" and doc["delta"] == "x" and doc["critical_value"] == pytest.approx(0, abs=1e-10)
    want = {"b1": 1.0, "alpha1": 1.0, "beta1": K, "q5": Q, "b2": 0.0}
    for k, v in want.items():
        c = doc["coefficients"][k]
        assert c["fit"] == pytest.approx(v, abs=1e-9), k
        assert c["lyapunov_schmidt"] == pytest.approx(v, abs=1e-8), k
    for f in doc["folds"]:  # lam_LP(mu) of the unfolding against the file's located folds
        assert abs(f["rel_error"]) < 1e-7
    # without the problem (no Lyapunov-Schmidt): the same fit
    r = invoke("fit", run_file, "--at", "BP2", "--delta-max", "0.3", "--json", "--no-ls")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["coefficients"]["beta1"]["fit"] == pytest.approx(K, abs=1e-9)


def test_fit_bad_label(run_file):
    r = invoke("fit", run_file, "--at", "LP9")
    assert r.exit_code == 1 and "needs a branch point" in r.output
    r = invoke("fit", run_file, "--at", "BP2", "--delta-min", "0.1", "--delta-max", "0.05")
    assert r.exit_code == 1 and "--delta-min" in r.output
