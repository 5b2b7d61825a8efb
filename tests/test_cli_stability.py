"""``contin stability`` and the stability pass of ``contin trace`` / ``info`` / ``diagram``.

Scenes come from tests/stability_fixture_scenes.py ('shear': uniform shear and a banded state of
CouetteProblem, with a problem_factory) and tests/cli_fixture_scenes.py ('toy': no factory),
through CONTIN_SCENES.  Reference numbers: the corrected 4x4 amplitude system of physics.md
section 4 (problems.couette.linear.uniform_shear_modes) and H_n^c = n pi psi.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.cli import main
from contin.cli.stability import parse_kx_spec
from contin.plot import plot_eigenfunction, plot_growth_rate
from contin.stability import eigenvalues
from problems.couette.closures import critical_gap_factor
from problems.couette.linear import linear_operator, uniform_shear_modes
from problems.couette.model import CouetteProblem

HERE = Path(__file__).parent
NU, E = 0.3, 0.8
H1C = np.pi * float(critical_gap_factor(NU, E))


@pytest.fixture(autouse=True)
def scenes(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", "stability_fixture_scenes:SCENES,cli_fixture_scenes:SCENES")


def run(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def strict_json(text: str):
    def reject(name):
        raise AssertionError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=reject)


def one_error_line(result, expect: str) -> None:
    assert result.exit_code == 1, (result.exit_code, result.output)
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: "), result.stderr
    assert expect in lines[0], lines[0]
    assert result.stdout == ""


def shear_file(path: Path, H_values, method: str = "cheb", N: int = 32, banded: bool = False) -> Path:
    """A run file of uniform-shear states (and optionally the banded pair) written with io.write."""
    import stability_fixture_scenes as fx

    pr = CouetteProblem(method, N)
    branches = [fx.shear_branch(pr, NU, E, H_values)]
    if banded:
        u, p = fx.banded_pair(pr, NU, E)
        branches.append(fx._branch(pr, "b", [u, pr.symmetry(u)], [p, p], kind="banded"))
    io.write(path, branches, scene="shear", parameters={"nu": NU, "e": E},
             discretization={"method": method, "intervals": N}, y=pr.grid.y, diagram_x="H")
    return path


def stability_json(path: Path, *args: str) -> dict:
    r = run("stability", path, "--json", *args)
    assert r.exit_code == 0, r.output
    return strict_json(r.stdout)


# --------------------------------------------------------------------------- numbers

def test_growth_rate_at_kx0_is_the_4x4_mode_past_and_before_H1c(tmp_path):
    f = shear_file(tmp_path / "s.h5", [10.0, 25.0])
    for point, H in ((1, 25.0), (0, 10.0)):
        doc = stability_json(f, "--branch", "0", "--point", str(point), "--kx", "0")
        lead = uniform_shear_modes(NU, E, H, 1)  # corrected system (with -nu V in the U equation)
        g = doc["growth_rate"][0]
        listed = np.array(doc["leading_eigenvalues"]["0"]) @ [1, 1j]
        assert np.min(np.abs(listed - lead[0])) < 1e-8  # the n = 1 mode is among the leading ones
        if H > H1C:
            assert g == pytest.approx(lead[0].real, abs=1e-8) and g > 1e-4
            assert doc["n_unstable"] == [1]
        else:
            assert g < -1e-3 and doc["n_unstable"] == [0]
        assert doc["params"]["H"] == H and doc["point"] == point


def test_at_parameter_value_is_a_newton_corrected_state(tmp_path):
    f = shear_file(tmp_path / "s.h5", [10.0, 20.0, 25.0])
    doc = stability_json(f, "--branch", "0", "--at", "H=22", "--kx", "0")
    assert doc["params"]["H"] == 22.0 and doc["point"] == "H=22"
    assert doc["growth_rate"][0] == pytest.approx(uniform_shear_modes(NU, E, 22.0, 1)[0].real, abs=1e-8)
    # at a stored point's own value it is that point
    at = stability_json(f, "--branch", "0", "--at", "H=25", "--kx", "0,0.5")
    stored = stability_json(f, "--branch", "0", "--point", "2", "--kx", "0,0.5")
    np.testing.assert_allclose(at["growth_rate"], stored["growth_rate"], rtol=0, atol=1e-10)


def test_printed_4x4_system_differs_but_has_the_same_neutral_point(tmp_path):
    f = shear_file(tmp_path / "s.h5", [25.0])
    g = stability_json(f, "--point", "0", "--kx", "0")["growth_rate"][0]
    printed = uniform_shear_modes(NU, E, 25.0, 1, advection=False)[0].real
    assert abs(printed - g) > 1e-4  # the -nubar V advection term matters for growth rates
    assert abs(uniform_shear_modes(NU, E, H1C, 1, advection=False)[0].real) < 1e-10
    assert abs(uniform_shear_modes(NU, E, H1C, 1)[0].real) < 1e-10


def test_json_document_is_strict_and_complete(tmp_path):
    f = shear_file(tmp_path / "s.h5", [25.0])
    r = run("stability", f, "--branch", "0", "--point", "-1", "--kx", "0:1:5", "--json")
    assert r.exit_code == 0 and "NaN" not in r.stdout
    doc = strict_json(r.stdout)
    assert set(doc) >= {"branch", "point", "params", "kx", "growth_rate", "phase_speed", "leading_eigenvalues"}
    assert doc["branch"] == "0" and doc["point"] == 0
    assert doc["kx"] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert len(doc["growth_rate"]) == len(doc["phase_speed"]) == 5
    assert doc["phase_speed"][0] is None  # k = 0: no phase speed
    assert all(isinstance(c, float) for c in doc["phase_speed"][1:])
    assert set(doc["leading_eigenvalues"]) == {"0", "0.25", "0.5", "0.75", "1"}
    for kx, g in zip(doc["kx"], doc["growth_rate"]):
        lead = doc["leading_eigenvalues"][f"{kx:.12g}"]
        assert len(lead) == 6 and lead[0][0] == g
        assert all(a[0] >= b[0] for a, b in itertools.pairwise(lead))  # real part descending
    # phase speed = Im omega / |k| of the least-stable mode
    lead = doc["leading_eigenvalues"]["0.5"][0]
    assert doc["phase_speed"][2] == pytest.approx(lead[1] / 0.5, rel=1e-12)


def test_growth_rate_curve_is_continuous_in_kx(tmp_path):
    f = shear_file(tmp_path / "s.h5", [14.0], N=24, banded=True)
    jumps = []
    curves = {}
    for count in (11, 21, 41):  # kx steps 0.2, 0.1, 0.05
        doc = stability_json(f, "--branch", "b", "--point", "0", "--kx", f"0:2:{count}")
        g = np.array(doc["growth_rate"])
        curves[count] = g
        jumps.append(np.max(np.abs(np.diff(g))))
    np.testing.assert_allclose(curves[41][::2], curves[21], rtol=0, atol=1e-12)  # same kx, same values
    assert jumps[1] < 0.6 * jumps[0] and jumps[2] < 0.6 * jumps[1]  # max jump ~ step: continuous
    assert jumps[2] < 0.02
    assert np.all(curves[41] < 0)  # the banded state just past H_1^c is stable at every kx


def test_reflection_invariance_of_the_growth_rate_curve(tmp_path):
    f = shear_file(tmp_path / "s.h5", [14.0], banded=True)
    a = stability_json(f, "--branch", "b", "--point", "0", "--kx", "0:3:7")
    b = stability_json(f, "--branch", "b", "--point", "1", "--kx", "0:3:7")  # the mirror image S x
    np.testing.assert_allclose(a["growth_rate"], b["growth_rate"], rtol=0, atol=1e-10)
    # (x, y) -> (-x, -y) maps kx to -kx; with complex conjugation back to kx: c -> -c
    ca, cb = (np.array(d["phase_speed"][1:], dtype=float) for d in (a, b))
    np.testing.assert_allclose(ca, -cb, rtol=0, atol=1e-9)
    assert np.max(np.abs(ca)) > 0.3  # travelling modes: the check is not vacuous
    # a symmetric state (uniform shear, S x = x): the spectrum is closed under conjugation
    pr = CouetteProblem("cheb", 32)
    p = pr.params({"nu": NU, "e": E, "H": 25.0})
    w = eigenvalues(*pr.eigenproblem(pr.uniform_state(p), p, kx=1.0))
    mismatch = np.min(np.abs(w[:, None] - np.conj(w)[None, :]), axis=1) / np.maximum(1.0, np.abs(w))
    assert np.max(mismatch) < 1e-8 and np.max(np.abs(w.imag)) > 0.3


def test_fd_states_use_the_chebyshev_eigenproblem(tmp_path):
    cheb = shear_file(tmp_path / "c.h5", [25.0], banded=True)
    fd = shear_file(tmp_path / "f.h5", [25.0], method="fd4", N=64, banded=True)
    for branch, point, kx in (("0", "0", "0"), ("b", "0", "0"), ("b", "0", "1")):
        gc = stability_json(cheb, "--branch", branch, "--point", point, "--kx", kx)
        gf = stability_json(fd, "--branch", branch, "--point", point, "--kx", kx)
        zc = np.array(gc["leading_eigenvalues"][kx][0]) @ [1, 1j]
        zf = np.array(gf["leading_eigenvalues"][kx][0]) @ [1, 1j]
        assert abs(zc - zf) < 1e-6, (branch, kx, zc, zf)
    # the FD grid itself would give a spurious least-stable mode at kx = 1
    pr = CouetteProblem("fd4", 48)
    import stability_fixture_scenes as fx

    u, p = fx.banded_pair(pr, NU, E)
    nu, uu, T, _, _ = pr.unpack(u)
    raw = eigenvalues(*linear_operator(pr.grid, nu, uu, T, p, kx=1.0), dense_max=10_000)[0]
    good = eigenvalues(*pr.eigenproblem(u, p, kx=1.0))[0]
    assert abs(raw - good) > 1e-3
    assert pr.eigen_grid().method == "cheb" and pr.eigen_grid().size == 49


def test_eigenvector_profiles_shape_and_error():
    pr = CouetteProblem("fd2", 40)
    y, prof = pr.eigenvector_profiles(np.zeros(pr.size), np.arange(5 * 41, dtype=complex))
    assert y.shape == (41,) and list(prof) == ["nu", "u", "v", "w", "T"] and prof["T"][0] == 4 * 41
    with pytest.raises(ValueError, match="expected"):
        pr.eigenvector_profiles(np.zeros(pr.size), np.zeros(7))


# --------------------------------------------------------------------------- labels, figures

def test_special_point_label_gives_the_neutral_state(tmp_path):
    f = shear_file(tmp_path / "s.h5", [10.0, 20.0, 30.0])
    doc = stability_json(f, "--branch", "0", "--point", "bp1", "--kx", "0")
    assert doc["point"] == "BP1" and doc["params"]["H"] == pytest.approx(H1C, rel=1e-12)
    assert abs(doc["growth_rate"][0]) < 1e-10  # the mode is neutral at H_1^c


def test_figures_and_eigenfunction(tmp_path):
    f = shear_file(tmp_path / "s.h5", [14.0], banded=True)
    out = tmp_path / "g.png"
    r = run("stability", f, "--branch", "b", "--point", "0", "--kx", "0.5", "-o", out, "--eigenfunction", "--json")
    assert r.exit_code == 0, r.output
    assert out.stat().st_size > 1000 and (tmp_path / "g_eigenfunction.png").stat().st_size > 1000
    doc = strict_json(r.stdout)
    ef = doc["eigenfunction"]
    assert ef["kx"] == 0.5 and ef["omega"] == doc["leading_eigenvalues"]["0.5"][0]
    assert list(ef["fields"]) == ["nu", "u", "v", "w", "T"] and len(ef["y"]) == 33
    amp = np.array([np.hypot(ef["fields"][n]["re"], ef["fields"][n]["im"]) for n in ef["fields"]])
    assert np.max(amp) == pytest.approx(1.0, abs=1e-12)  # normalised: largest component 1
    assert np.max(np.abs(ef["fields"]["w"]["re"])) < 1e-8  # kz = 0: spanwise velocity decouples
    for n in ("u", "v"):  # no-slip
        assert abs(ef["fields"][n]["re"][0]) < 1e-10 and abs(ef["fields"][n]["im"][-1]) < 1e-10


def test_plot_helpers():
    kx = np.linspace(0, 1, 4)
    fig = plot_growth_rate(kx, -kx, np.array([np.nan, 1, 1, 1]))
    gids = {ln.get_gid() for ax in fig.axes for ln in ax.lines}
    assert {"growth-rate", "phase-speed"} <= gids
    assert len(fig.axes[1].lines[0].get_xdata()) == 3  # the nan (k = 0) point is left out
    with pytest.raises(ValueError, match="equal-length"):
        plot_growth_rate(kx, kx[:2], kx)
    fig = plot_eigenfunction(np.linspace(-0.5, 0.5, 3), {"a": np.array([1, 1j, 0])})
    assert {ln.get_gid() for ln in fig.axes[0].lines} == {"a-re", "a-im"}
    with pytest.raises(ValueError, match="shape"):
        plot_eigenfunction(np.zeros(3), {"a": np.zeros(2)})


def test_table_output_without_json(tmp_path):
    f = shear_file(tmp_path / "s.h5", [25.0])
    r = run("stability", f, "--point", "0", "--kx", "0,1")
    assert r.exit_code == 0
    lines = r.stdout.splitlines()
    assert lines[1].split()[:2] == ["kx", "growth"] and len(lines) == 5


# --------------------------------------------------------------------------- errors

def test_parse_kx_spec():
    assert parse_kx_spec("0:3:61")[-1] == 3.0 and len(parse_kx_spec("0:3:61")) == 61
    assert parse_kx_spec("0.5, 1") == [0.5, 1.0] and parse_kx_spec("2") == [2.0]
    assert parse_kx_spec("1:1:1") == [1.0]
    for bad in ("0:3", "a", "0:3:0", "0:3:1", "nan", "inf", "", "1:2:x"):
        with pytest.raises(ValueError, match="bad --kx"):
            parse_kx_spec(bad)


@pytest.mark.parametrize("args, expect", [
    (["--branch", "7", "--point", "0"], "no branch '7'"),
    (["--branch", "0", "--point", "5"], "out of range"),
    (["--branch", "0", "--point", "LP4"], "no point 'LP4'"),
    (["--branch", "0", "--point", "0", "--kx", "0:3"], "bad --kx"),
    (["--branch", "0", "--point", "0", "--kx", "x,1"], "bad --kx"),
    (["--branch", "0", "--point", "0", "--kx", "0:1:0"], "COUNT"),
    (["--branch", "0", "--point", "0", "--eigenfunction"], "needs -o"),
    (["--point", "0"], "choose one with --branch"),
    (["--branch", "0"], "exactly one of --point"),
    (["--branch", "0", "--point", "0", "--at", "H=12"], "exactly one of --point"),
    (["--branch", "0", "--at", "H"], "--at needs NAME=VALUE"),
    (["--branch", "0", "--at", "H=abc"], "--at needs NAME=VALUE"),
    (["--branch", "0", "--at", "H=40"], "does not reach H = 40"),
    (["--branch", "0", "--at", "Fr=12"], "no parameter 'Fr'"),
])
def test_errors_are_one_line_exit_1(tmp_path, args, expect):
    f = shear_file(tmp_path / "s.h5", [10.0, 25.0], banded=True)
    one_error_line(run("stability", f, *args), expect)


def test_files_without_a_rebuildable_problem(tmp_path):
    toy = tmp_path / "toy.h5"
    assert run("trace", "toy", "-o", toy, "-q").exit_code == 0
    one_error_line(run("stability", toy, "--branch", "0", "--point", "1"), "has no problem_factory")
    pr = CouetteProblem("cheb", 8)
    import stability_fixture_scenes as fx

    other = tmp_path / "other.h5"
    io.write(other, [fx.shear_branch(pr, NU, E, [5.0, 6.0])], scene="nosuchscene", parameters={})
    one_error_line(run("stability", other, "--point", "0"), "unknown scene 'nosuchscene'")
    wrong = tmp_path / "wrong.h5"  # discretization attribute disagrees with the states
    io.write(wrong, [fx.shear_branch(pr, NU, E, [5.0, 6.0])], scene="shear", parameters={},
             discretization={"method": "cheb", "intervals": 16})
    one_error_line(run("stability", wrong, "--point", "0", "--kx", "0"), "has 28 entries but the problem")
    one_error_line(run("stability", tmp_path / "toy.h5", "--branch", "0", "--point", "0", "-o",
                       tmp_path / "no" / "g.png"), "does not exist")


# --------------------------------------------------------------------------- trace, info, diagram

def expected_n_unstable(H):
    return np.searchsorted(H1C * np.arange(1, 5), H)  # modes n with H_n^c < H


@pytest.mark.parametrize("selfstab", ["0", "1"])
def test_trace_runs_stability_by_default(tmp_path, selfstab):
    out = tmp_path / "t.h5"
    r = run("trace", "shear", "-s", f"selfstab={selfstab}", "-s", "n=6", "--kx", "0.5", "-o", out, "--json", "-q")
    assert r.exit_code == 0, r.output
    doc = strict_json(r.stdout)
    (b,), _ = io.load(out)
    H = b.params["H"]
    np.testing.assert_array_equal(b.n_unstable, expected_n_unstable(H))
    np.testing.assert_array_equal(b.stable, H < H1C)
    assert b.stability_k == (0.0, 0.0) and b.eigenvalues.shape == (6, 6)
    assert list(b.n_unstable) == [0, 0, 1, 1, 1, 2]  # H = 5, 10, .., 30; H_1^c = 13.07, H_2^c = 26.14
    for i in (1, 4):  # leading eigenvalue = the 4x4 n = 1 mode (the least stable at kx = 0)
        assert b.eigenvalues[i, 0] == pytest.approx(uniform_shear_modes(NU, E, H[i], 1)[0], abs=1e-8)
    assert doc["stability"]["0"]["audit"] == [] and doc["stability"]["0"]["n_unstable"] == list(b.n_unstable)
    # --kx adds columns; they match `contin stability` at that wavenumber
    g = b.observables["growth_rate_kx0.5"]
    assert np.all(b.observables["n_unstable_kx0.5"] == 0)
    single = stability_json(out, "--point", "4", "--kx", "0.5")
    assert g[4] == pytest.approx(single["growth_rate"][0], abs=1e-12)


def test_no_stability_and_audit_reporting(tmp_path):
    plain = tmp_path / "n.h5"
    assert run("trace", "shear", "--no-stability", "-o", plain, "-q").exit_code == 0
    (b,), _ = io.load(plain)
    assert b.stable is None and b.n_unstable is None and b.stability_k is None
    assert "growth_rate_kx0.5" not in b.observables
    # without the BP at H_2^c the change 1 -> 2 of n_unstable is unexplained
    bad = tmp_path / "bad.h5"
    r = run("trace", "shear", "-s", "dropbp=1", "-o", bad)
    assert r.exit_code == 0
    audit_lines = [ln for ln in r.stderr.splitlines() if ln.startswith("audit: branch 0")]
    assert len(audit_lines) == 1 and "changes 1 -> 2" in audit_lines[0] and "no BP/LP" in audit_lines[0]
    info = run("info", bad)
    assert "audit of branch 0:" in info.stdout and "changes 1 -> 2" in info.stdout
    assert "stability of branch 0 (kx=0, kz=0): n_unstable 0..2" in info.stdout
    doc = strict_json(run("info", bad, "--json").stdout)
    assert len(doc["audit"]["0"]) == 1
    good = run("info", plain)
    assert "audit of branch" not in good.stdout and "stability of branch" not in good.stdout


def test_diagram_draws_stable_solid_unstable_dashed(tmp_path):
    out = tmp_path / "t.h5"
    assert run("trace", "shear", "-s", "n=6", "-o", out, "-q").exit_code == 0
    svg = tmp_path / "d.svg"
    r = run("diagram", out, "-y", "nu_bottom", "-o", svg)
    assert r.exit_code == 0, r.output
    text = svg.read_text()
    assert 'id="branch-0-stable"' in text and 'id="branch-0-unstable"' in text


def test_rejected_step_diagnostics_survive_the_audit(tmp_path):
    import stability_fixture_scenes as fx

    from contin.stability import audit, stability_pass

    pr = CouetteProblem("cheb", 16)
    b = fx.shear_branch(pr, NU, E, [5.0, 20.0])
    b.audit = ["step 3: H=7 ds=0.1 rejected: Newton diverged"]
    stability_pass(pr, b)
    assert audit(b) == [] and b.audit == ["step 3: H=7 ds=0.1 rejected: Newton diverged"]
    b.special_points = []
    msgs = audit(b)
    assert len(msgs) == 1 and b.audit == ["step 3: H=7 ds=0.1 rejected: Newton diverged", *msgs]
    io.write(tmp_path / "a.h5", [b], scene="shear")
    (back,), _ = io.load(tmp_path / "a.h5")
    assert back.audit == b.audit and back.stability_k == (0.0, 0.0)
