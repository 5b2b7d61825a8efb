"""The compiled engine of gPCF (problems.couette.compiled; CouetteProblem(engine="numba")).

It is a second implementation of the residual, the Jacobian and dF/dH, so it is held to the
numpy path on every configuration it covers (wall models x chi models x gravity x grids, on
states away from any solution), its Jacobian to finite differences of its own residual, and a
whole continuation run (uniform branch, BP, switch, banded branch) to the numpy engine's.
Then the engine choice end to end: errors for what it does not cover, --engine on the CLI
and in sweep files, and the provenance in the HDF5 file.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main
from contin.continuation import switch, trace
from contin.linalg import DENSE_LIMIT
from contin.options import ContinuationOptions, StepOptions
from contin.sweep import run_task
from problems.couette import compiled
from problems.couette.closures import critical_gap_factor
from problems.couette.model import CouetteProblem

pytestmark = pytest.mark.skipif(not compiled.available(), reason="numba is not installed")
# (the test extra installs numba, so in CI this module always runs; the skip is for a bare install)

CONFIGS = [(method, n, walls, chi, gravity)
           for method, n in (("cheb", 12), ("cheb", 33), ("fd4", 40))
           for walls in ("noslip", "jj") for chi in ("jj", "cs", "ls") for gravity in (False, True)]


def _pair(method, n, walls="noslip", chi="jj", gravity=False):
    kw = {"walls": walls, "chi": chi, "gravity": gravity}
    return CouetteProblem(method, n, **kw), CouetteProblem(method, n, engine="numba", **kw)


def _perturbed_state(problem, p, seed=0):
    """A state far from any solution (5 % noise on every unknown), so no term vanishes."""
    rng = np.random.default_rng(seed)
    x = problem.initial_guess(p)
    return x * (1.0 + 0.05 * rng.standard_normal(x.size))


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(a)))


@pytest.mark.parametrize("method,n,walls,chi,gravity", CONFIGS)
def test_kernels_equal_the_numpy_path(method, n, walls, chi, gravity):
    ref, fast = _pair(method, n, walls, chi, gravity)
    values = {"nu": 0.3, "e": 0.8, "H": 20.0, "phi_w": 0.6, "ew": 0.9}
    if gravity:
        values["G"] = 2e-4  # H^3 G = 1.6: the gravity column is as large as the others
    p = ref.params(values)
    x = _perturbed_state(ref, p)
    assert _rel(ref.residual(x, p), fast.residual(x, p)) < 1e-14
    jd = fast.dense_jacobian(x, p)
    assert jd.flags.f_contiguous and jd.shape == (ref.size, ref.size)
    assert _rel(ref.dense_jacobian(x, p), jd) < 1e-14
    assert _rel(ref.jacobian(x, p).toarray(), fast.jacobian(x, p).toarray()) < 1e-14
    assert _rel(ref.dresidual_dp(x, p, "H"), fast.dresidual_dp(x, p, "H")) < 1e-14
    # the complex step (dF/de) goes through the numpy path of either engine
    assert _rel(ref.dresidual_dp(x, p, "e"), fast.dresidual_dp(x, p, "e")) < 1e-14


def test_jacobian_against_finite_differences_of_its_own_residual():
    _, fast = _pair("cheb", 16, "jj", "jj", True)
    p = fast.params({"nu": 0.25, "e": 0.9, "H": 15.0, "G": 1e-4, "phi_w": 0.5, "ew": 0.95})
    x = _perturbed_state(fast, p, seed=3)
    jac = fast.dense_jacobian(x, p)
    fd = np.empty_like(jac)
    for j in range(x.size):  # central differences, O(h^2) ~ 1e-12 at h = 1e-6 |x_j|
        h = 1e-6 * max(abs(x[j]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        fd[:, j] = (fast.residual(xp, p) - fast.residual(xm, p)) / (2 * h)
    assert np.max(np.abs(fd - jac)) < 1e-6 * np.max(np.abs(jac))
    h = 1e-6 * p["H"]
    dh = (fast.residual(x, {**p, "H": p["H"] + h}) - fast.residual(x, {**p, "H": p["H"] - h})) / (2 * h)
    assert np.max(np.abs(dh - fast.dresidual_dp(x, p, "H"))) < 1e-6 * np.max(np.abs(dh))


def test_cache_follows_the_state_and_the_parameters():
    ref, fast = _pair("cheb", 12)
    p = ref.params({"nu": 0.3, "e": 0.8, "H": 20.0})
    x = _perturbed_state(ref, p)
    fast.residual(x, p)
    x2 = x.copy()
    x2[3] *= 1.01  # the cache must not return the fields of x for x2, nor those of e = 0.8 at e = 0.7
    q = {**p, "e": 0.7}
    assert _rel(ref.residual(x2, p), fast.residual(x2, p)) < 1e-14
    assert _rel(ref.residual(x2, q), fast.residual(x2, q)) < 1e-14
    assert _rel(ref.dense_jacobian(x2, q), fast.dense_jacobian(x2, q)) < 1e-14


def test_a_continuation_run_matches_the_numpy_engine():
    """Uniform branch in H through the first BP, switch, banded branch to H = 20 (cheb N = 16)."""
    opts = ContinuationOptions(step=StepOptions(ds=0.5, ds_max=1.0), bounds={"H": (5.0, 20.0)}, max_steps=200,
                               resolution_tol=None)
    out = {}
    for engine in ("numpy", "numba"):
        pb = CouetteProblem("cheb", 16, engine=engine)
        p = pb.params({"nu": 0.3, "e": 0.8, "H": 10.0})
        br = trace(pb, pb.uniform_state(p), p, "H", opts)
        bp = br.branch_points[0]
        banded = switch(pb, br, bp, opts, directions=(+1,))[0]
        out[engine] = (bp.params["H"], len(br), len(banded), banded.status, banded.states[-1],
                       int(np.sum(banded.newton_iterations)))
    hc_numpy, hc_numba = out["numpy"][0], out["numba"][0]
    assert abs(hc_numba - math.pi * critical_gap_factor(0.3, 0.8)) < 1e-9 * hc_numba  # H_1^c = pi psi
    assert abs(hc_numba - hc_numpy) < 1e-11 * hc_numpy
    assert out["numba"][1:4] == out["numpy"][1:4]  # same steps, same end (EP at H = 20)
    assert np.max(np.abs(out["numba"][4] - out["numpy"][4])) < 1e-9
    assert abs(out["numba"][5] - out["numpy"][5]) <= 2


def test_engine_choice_and_its_errors(monkeypatch):
    assert CouetteProblem("cheb", 12, engine="auto").engine == "numba"
    assert CouetteProblem("cheb", 12, engine="auto", dufour=True).engine == "numpy"
    big = (DENSE_LIMIT - 1) // 3 + 1  # intervals: 3 (N + 1) + 1 > DENSE_LIMIT
    assert CouetteProblem("fd2", big, engine="auto").engine == "numpy"
    with pytest.raises(ValueError, match="unknown engine 'fortran'; choose one of numpy, numba or auto"):
        CouetteProblem("cheb", 12, engine="fortran")
    with pytest.raises(ValueError, match="does not cover the Dufour flux"):
        CouetteProblem("cheb", 12, engine="numba", dufour=True)
    with pytest.raises(ValueError, match=f"for at most {DENSE_LIMIT} unknowns"):
        CouetteProblem("fd2", big, engine="numba")
    monkeypatch.setattr(compiled, "available", lambda: False)
    with pytest.raises(ValueError, match=r"needs numba: pip install 'contin\[fast\]'"):
        CouetteProblem("cheb", 12, engine="numba")
    assert CouetteProblem("cheb", 12, engine="auto").engine == "numpy"
    assert "engine='numpy'" in repr(CouetteProblem("cheb", 12, engine="auto"))


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def test_cli_engine_option_and_provenance(tmp_path, monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)
    found = {}
    for engine in ("numpy", "numba"):
        out = tmp_path / f"{engine}.h5"
        r = _run("trace", "pitchfork", "--grid", 16, "--no-stability", "-s", "H_max=20", "--engine", engine,
                 "--resolution-tol", "off", "-o", out, "-q")
        assert r.exit_code == 0, r.output
        branches, meta = io.load(out)
        assert meta["discretization"] == {"method": "cheb", "intervals": 16, "engine": engine}
        found[engine] = [(b.id, sp.type, sp.params["H"]) for b in branches for sp in b.special_points]
    assert [f[:2] for f in found["numba"]] == [f[:2] for f in found["numpy"]]
    assert found["numba"][0][1] == "BP"
    assert np.allclose([f[2] for f in found["numba"]], [f[2] for f in found["numpy"]], rtol=1e-11, atol=0)
    r = _run("trace", "pitchfork", "--engine", "fortran")
    assert r.exit_code == 2 and "'fortran' is not one of 'auto', 'numpy', 'numba'" in r.output


def test_sweep_engine_option_reaches_the_scene(tmp_path, monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)
    found = {}
    for engine in ("numpy", "numba"):
        out = tmp_path / f"{engine}.h5"
        doc = run_task("pitchfork", {"H_max": 16.0}, {"engine": engine, "grid": 16, "stability": False}, str(out))
        assert doc["status"] == "ok"
        assert io.load(out)[1]["discretization"]["engine"] == engine
        found[engine] = [sp["params"]["H"] for sp in doc["special_points"] if sp["type"] == "BP"]
    assert len(found["numba"]) == 1 and found["numba"] == pytest.approx(found["numpy"], rel=1e-11, abs=0)


@pytest.mark.parametrize("n", [16, 48])
def test_accuracy_runs_record_the_engine_and_meet_the_hc_target(n):
    """Issue 6's target, H_1^c within 1e-10 relative at Chebyshev N <= 48, with the compiled engine."""
    from contin.accuracy import relative_error, run_accuracy
    from problems.couette.keypoints import SCENES, exact_hc1

    report = run_accuracy(SCENES["gpcf-keypoints"], {}, ["cheb"], [n], memory=False, engine="numba")
    (run,) = report.runs
    assert run.engine == "numba" and not run.failed
    assert relative_error(run.values["Hc1"], exact_hc1(0.3, 0.8)) < 1e-10
    assert report.to_json()["runs"][0]["engine"] == "numba"


@pytest.mark.parametrize("where, value", [("nu", 0.65), ("nu", 0.0), ("T", -1.0)])
def test_unphysical_states_give_non_finite_values_not_exceptions(where, value):
    """As in the numpy engine (whose callers check finiteness and admissibility): division by
    zero and roots of negatives give inf/nan (numba's error_model='numpy'), no ZeroDivisionError."""
    ref, fast = _pair("cheb", 12)
    p = ref.params({})
    x = ref.initial_guess(p)
    x[(ref.i_nu if where == "nu" else ref.i_T).start + 3] = value
    with np.errstate(all="ignore"):  # the numpy engine warns where numba is silent
        for problem in (ref, fast):
            assert not np.all(np.isfinite(problem.dense_jacobian(x, p)))
            assert problem.admissible(x, p) is not None
        assert np.array_equal(np.isfinite(ref.residual(x, p)), np.isfinite(fast.residual(x, p)))


def test_cli_engine_numba_without_numba_is_one_error_line(monkeypatch):
    monkeypatch.delenv("CONTIN_SCENES", raising=False)
    monkeypatch.setattr(compiled, "available", lambda: False)
    r = _run("trace", "pitchfork", "--grid", 16, "--engine", "numba", "-q")
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 1 and r.stdout == ""
    assert lines == ["Error: engine='numba' needs numba: pip install 'contin[fast]' (or use engine='numpy')"]
    r = _run("trace", "pitchfork", "--grid", 16, "-s", "H_max=14", "--no-stability", "-q", "--json")  # auto: numpy
    assert r.exit_code == 0 and '"engine": "numpy"' in r.stdout
