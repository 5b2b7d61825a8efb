"""contin.from_functions: a problem from F(u, p) alone (grouped finite differences or complex
step), and the friendlier defaults found by using it (labels, L2 order parameter, protocol
errors, the check_jacobian hint, stability warning and shift, parameters in files, restarts)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import brentq, minimize_scalar

import contin
from contin import io
from contin.continuation import switch, trace
from contin.fromfunctions import column_groups, detect_sparsity
from contin.options import ContinuationOptions, StepOptions
from contin.problem import ProtocolError, check_jacobian


def bratu(n):
    """u'' + lam e^u = 0 on (0, 1), u(0) = u(1) = 0, second-order differences on n interior points."""
    h = 1.0 / (n + 1)

    def F(u, p):
        up = np.concatenate([[0.0], u, [0.0]])
        return (up[2:] - 2 * up[1:-1] + up[:-2]) / h**2 + p["lam"] * np.exp(u)

    return F


def bratu_fold():
    """lam* of the continuous problem from its closed form: u = -2 ln(cosh(theta (x - 1/2)/2) /
    cosh(theta/4)) solves it with lam = theta^2 / (2 cosh^2(theta/4)); the fold is the maximum."""
    lam = lambda t: t**2 / (2 * math.cosh(t / 4) ** 2)  # noqa: E731
    t = minimize_scalar(lambda t: -lam(t), bounds=(1, 10), method="bounded", options={"xatol": 1e-12}).x
    return lam(t)


def test_closed_form_fold_value():
    assert bratu_fold() == pytest.approx(3.513830719, abs=1e-9)


def test_column_groups_of_banded_patterns():
    for bands, want in (((-1, 0, 1), 3), ((-2, -1, 0, 1, 2), 5), ((0,), 1)):
        pattern = sp.diags([np.ones(30)] * len(bands), bands, shape=(30, 30))
        g = column_groups(pattern)
        assert g.max() + 1 == want
        a = sp.csc_matrix(pattern)
        for k in range(want):  # columns of one group share no row
            rows = np.concatenate([a.indices[a.indptr[j]:a.indptr[j + 1]] for j in np.nonzero(g == k)[0]])
            assert rows.size == np.unique(rows).size


def test_detected_sparsity_and_jacobian_against_exact():
    n = 40
    F = bratu(n)
    p = {"lam": 2.0}
    u = 0.3 * np.sin(np.linspace(0.1, 3.0, n))
    h = 1.0 / (n + 1)
    exact = sp.diags([np.ones(n - 1) / h**2, -2 / h**2 + p["lam"] * np.exp(u), np.ones(n - 1) / h**2], [-1, 0, 1])
    pattern = detect_sparsity(F, u, p)
    assert (pattern != 0).sum() == 3 * n - 2
    for method, tol in (("fd", 1e-7), ("cs", 1e-12)):
        pb = contin.from_functions(F, u, p, method=method)
        assert pb.groups.max() + 1 == 3
        jac = pb.jacobian(u, p).toarray()
        assert np.max(np.abs(jac - exact.toarray())) / np.max(np.abs(exact.toarray())) < tol, method
        assert np.max(np.abs(pb.dresidual_dp(u, p, "lam") - np.exp(u))) < tol


def test_bratu_fold_from_plain_functions():
    """Grouped-FD Jacobian, fold located by the tracer, Richardson in h^2 against the closed form."""
    folds = []
    for n in (100, 200):
        pb = contin.from_functions(bratu(n), np.zeros(n), {"lam": 0.0})
        opts = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, step=StepOptions(ds=0.1, ds_max=0.5), max_steps=200,
                                   stop_at=("LP1",))
        br = trace(pb, np.zeros(n), {"lam": 0.0}, "lam", opts)
        (lp,) = br.fold_points
        assert lp.name == "LP1"  # labelled without relabel
        folds.append(lp.params["lam"])
    h2 = [(1 / 101) ** 2, (1 / 201) ** 2]
    extrapolated = (folds[1] * h2[0] - folds[0] * h2[1]) / (h2[0] - h2[1])
    assert abs(folds[1] - bratu_fold()) < 1e-4
    assert extrapolated == pytest.approx(bratu_fold(), abs=2e-8)


def test_allen_cahn_branch_points_and_labels():
    """u'' + lam (u - u^3) = 0 on (0, pi): the BPs of u = 0 are the eigenvalues of the difference
    Laplacian, lam_k = (4/h^2) sin^2(k h / 2) (-> k^2); labels BP1, BP2, ... without relabel,
    the default order parameter (L2 norm) nonzero on the bifurcated branches."""
    n = 60
    h = math.pi / (n + 1)

    def F(u, p):
        up = np.concatenate([[0.0], u, [0.0]])
        return (up[2:] - 2 * up[1:-1] + up[:-2]) / h**2 + p["lam"] * (u - u**3)

    pb = contin.from_functions(F, np.zeros(n), {"lam": 0.5})
    opts = ContinuationOptions(bounds={"lam": (0.5, 10.0)}, step=StepOptions(ds=0.05, ds_max=0.3), max_steps=400)
    br = trace(pb, np.zeros(n), {"lam": 0.5}, "lam", opts)
    bps = br.branch_points
    exact = [(4 / h**2) * math.sin(k * h / 2) ** 2 for k in (1, 2, 3)]
    assert [bp.name for bp in bps] == ["BP1", "BP2", "BP3"]
    assert np.allclose([bp.params["lam"] for bp in bps], exact, rtol=0, atol=1e-7)
    assert np.allclose(exact, [1, 4, 9], atol=0.02)
    assert np.all(br.observables["phi"] == 0)  # ||u|| on u = 0
    new = switch(pb, br, bps[0], opts, directions=(1,))
    phi = new[0].observables["phi"]
    assert phi.size > 5 and np.all(np.isfinite(phi)) and phi.max() > 0.1
    u = new[0].states[-1]
    assert phi[-1] == pytest.approx(np.linalg.norm(u) / math.sqrt(n), rel=1e-12)


def test_exact_jacobian_is_checked_once_in_debug_mode():
    n = 20
    F = bratu(n)
    h = 1.0 / (n + 1)

    def J(u, p, sign=1.0):
        return sp.diags([np.ones(n - 1) / h**2, -2 / h**2 + sign * p["lam"] * np.exp(u), np.ones(n - 1) / h**2],
                        [-1, 0, 1])

    u, p = np.full(n, 0.1), {"lam": 1.0}
    good = contin.from_functions(F, u, p, jacobian=J, debug=True)
    assert good.jacobian(u, p).shape == (n, n)
    bad = contin.from_functions(F, u, p, jacobian=lambda u, p: J(u, p, -1.0), debug=True)
    with pytest.raises(ValueError, match="check it with contin.problem.check_jacobian"):
        bad.jacobian(u, p)
    quiet = contin.from_functions(F, u, p, jacobian=lambda u, p: J(u, p, -1.0))  # no check without debug
    assert quiet.jacobian(u, p).shape == (n, n)
    assert check_jacobian(quiet, u, p).relative_error > 1e-3


def test_missing_method_is_one_clear_error():
    class Half:
        parameter_names = ("lam",)

        def residual(self, u, p):
            return u - p["lam"]

        def dresidual_dp(self, u, p, name):
            return -np.ones_like(u)

    with pytest.raises(ProtocolError, match=r"has no method jacobian\(\.\.\.\)"):
        trace(Half(), np.zeros(2), {"lam": 0.0}, "lam")
    from contin.newton import newton

    with pytest.raises(ProtocolError, match="jacobian"):
        newton(Half(), np.zeros(2), {"lam": 0.0})


def test_first_point_failure_points_at_check_jacobian():
    n = 10
    F = bratu(n)
    h = 1.0 / (n + 1)
    wrong = lambda u, p: sp.diags([np.ones(n - 1), np.full(n, 5.0), np.ones(n - 1)], [-1, 0, 1]) / h  # noqa: E731
    pb = contin.from_functions(F, np.ones(n), {"lam": 1.0}, jacobian=wrong)
    br = trace(pb, np.ones(n), {"lam": 1.0}, "lam", ContinuationOptions(bounds={"lam": (0.0, 3.0)}))
    assert br.status == "MX" and "check the Jacobian with contin.problem.check_jacobian" in br.message


def test_stability_warns_without_mass_matrix_and_takes_a_shift():
    from contin.stability import stability_pass

    n = 30
    F = bratu(n)
    pb = contin.from_functions(F, np.zeros(n), {"lam": 0.0})
    opts = ContinuationOptions(bounds={"lam": (0.0, 1.0)}, step=StepOptions(ds=0.2, ds_max=0.5))
    br = trace(pb, np.zeros(n), {"lam": 0.0}, "lam", opts)
    with pytest.warns(UserWarning, match="no mass_matrix"):
        stability_pass(pb, br, {"lam": 0.0})
    assert np.all(br.n_unstable == 0)  # lower Bratu branch: stable (-Laplacian > lam e^u)
    pb_m = contin.from_functions(F, np.zeros(n), {"lam": 0.0}, mass_matrix=sp.identity(n))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # sparse path (dense_max below n) with the shift at the eigenvalue of mode 3: the k
        # eigenvalues nearest it, the least stable (mode 1) among them
        stability_pass(pb_m, br, {"lam": 0.0}, dense_max=5, shift=-88.0, n_eigs=3)
    h = 1.0 / (n + 1)
    lap = [-(4 / h**2) * math.sin(k * math.pi * h / 2) ** 2 for k in (1, 2, 3)]
    assert br.eigenvalues[0].real == pytest.approx(lap, rel=1e-8)  # lam = 0: the difference Laplacian


def test_file_parameters_restart_and_stability_message(tmp_path):
    from click.testing import CliRunner

    from contin.cli import main

    n = 60
    h = math.pi / (n + 1)

    def F(u, p):
        up = np.concatenate([[0.0], u, [0.0]])
        return (up[2:] - 2 * up[1:-1] + up[:-2]) / h**2 + p["lam"] * (u - u**3) + p["c"] * u**2

    pb = contin.from_functions(F, np.zeros(n), {"lam": 0.5, "c": 0.0})
    opts = ContinuationOptions(bounds={"lam": (0.5, 5.0)}, step=StepOptions(ds=0.05, ds_max=0.3), max_steps=300)
    br = trace(pb, np.zeros(n), {"lam": 0.5, "c": 0.0}, "lam", opts)
    path = tmp_path / "ac.h5"
    io.write(path, [br])
    _, meta = io.load(path)
    assert meta["parameters"] == {"lam": 0.5, "c": 0.0}
    u, p, t = io.restart(path, "BP2")
    assert p["lam"] == pytest.approx((4 / h**2) * math.sin(h) ** 2, abs=1e-7) and t.size == n + 1
    r = io.restart(path, "bp2")
    new = switch(pb, br, r.point, opts, directions=(1,))
    assert len(new) == 1 and new[0].observables["phi"].max() > 0.1
    again = trace(pb, **r.trace_kwargs(), options=opts)
    assert again.status == "EP" and again.parameter_values[0] == pytest.approx(p["lam"], abs=1e-10)
    with pytest.raises(ValueError, match="no point 'LP7'"):
        io.restart(path, "LP7")
    res = CliRunner().invoke(main, ["stability", str(path), "--point", "BP2"])
    assert res.exit_code == 1 and "names no scene" in res.output and "Traceback" not in res.output


def test_bad_inputs_are_one_sentence_naming_them():
    """from_functions with u0 of no entries ended in "need at least one array to concatenate";
    {'lam': 'x'} in "could not convert string to float: 'x'"; an F returning complex values ran
    with a ComplexWarning per call and the imaginary part dropped (qa15)."""
    import contin

    n, h = 20, 1 / 21

    def F(u, p):
        up = np.concatenate([[0.0], u, [0.0]])
        return (up[2:] - 2 * up[1:-1] + up[:-2]) / h**2 + p["lam"] * np.exp(u)

    with pytest.raises(ValueError, match="u0 has no entries"):
        contin.from_functions(F, np.zeros(0), {"lam": 0.0})
    with pytest.raises(TypeError, match=r"params\['lam'\] must be a real number, got 'x'"):
        contin.from_functions(F, np.zeros(n), {"lam": "x"})
    with pytest.raises(ValueError, match="params must be a dict with a value for every parameter"):
        contin.from_functions(F, np.zeros(n), {})
    with pytest.raises(ValueError, match=r"returned complex values \(complex128\); F must be real"):
        contin.from_functions(lambda u, p: F(u, p) + 1j * u, np.zeros(n), {"lam": 0.0})


def test_pattern_probe_at_parameters_f_refuses_falls_back():
    """The sparsity pattern is also probed at perturbed parameters; an F that raises or returns
    NaN there (a parameter used as a log's argument at its boundary value) gets the pattern of
    the given parameters, with no error."""
    def F(u, p):
        if p["a"] != 1.0:
            raise KeyError("only a = 1")
        return np.array([u[0] - u[1], u[1] + p["a"]])

    pb = contin.from_functions(F, np.zeros(2), {"a": 1.0})
    assert (pb.pattern.toarray() != 0).tolist() == [[True, True], [False, True]]

    def G(u, p):
        return np.array([u[0] * np.log(p["b"]), u[1] + u[0] * np.sqrt(-p["b"] + 1.0)])

    pb = contin.from_functions(G, np.ones(2), {"b": 1.0})
    assert (pb.pattern.toarray() != 0).tolist() == [[False, False], [False, True]]
