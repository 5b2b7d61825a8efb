"""qa19b: robustness of the LPC curve (``continue ORBITS.h5 --from LPC1 --free B``) and of branch
switching at a branch point of cycles (``continue ORBITS.h5 --from BP1 --cycles``) on the command
line: bad input gets one ``Error:`` line, damaged files are named as such."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from contin.cli import main


def _cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def orbits(tmp_path_factory):
    """contin trace ab; its orbits from HB1 (40 steps: LPC1 at D = 0.1617)."""
    d = tmp_path_factory.mktemp("qa19b")
    ab, cyc = d / "ab.h5", d / "cyc.h5"
    assert _cli("trace", "ab", "-q", "--no-stability", "-o", ab).exit_code == 0
    r = _cli("continue", ab, "--from", "HB1", "--cycles", "--max-steps", 40, "-o", cyc)
    assert r.exit_code == 0 and "LPC1" in r.output, r.output
    return cyc


@pytest.mark.parametrize("name", ["B", "beta"])
def test_nan_fixed_parameter_of_an_lpc_is_a_damaged_file(orbits, tmp_path, name):
    """A NaN in a fixed parameter of LPC1 (B: the curve's second parameter; beta) ended "Error:
    internal error (RuntimeError: Factor is exactly singular)": the file is damaged, and says so."""
    bad = tmp_path / "bad.h5"
    shutil.copy(orbits, bad)
    with h5py.File(bad, "r+") as f:
        f[f"special_points/params/{name}"][0] = np.nan
    for args in (("continue", bad, "--from", "LPC1", "--free", "B", "--max-steps", 3), ("info", bad)):
        r = _cli(*args)
        assert r.exit_code == 1, r.output
        assert r.output.strip().splitlines()[-1] == (
            f"Error: {str(bad)!r} is damaged: dataset special_points/params/{name} holds NaN at row 0 (the writer "
            "stores only finite values there)")


def test_writer_refuses_nan_fixed_parameter_of_a_special_point():
    """The writer's rule matches the reader's: a special point's fixed parameter may be inf, not NaN."""
    from contin.branch import Branch, SpecialPoint
    from contin.io import NonFiniteError, check_finite

    def branch(v):
        sp = SpecialPoint(type="LP", index=0, params={"a": 0.0, "b": v}, order_parameter=0.0, state=np.zeros(1))
        return Branch(id="0", parameter="a", free=("a",), observables={}, newton_iterations=np.zeros(1, int), states=np.zeros((1, 1)), tangents=np.zeros((1, 2)),
                      params={"a": np.zeros(1), "b": np.full(1, 1.0)}, ds=np.ones(1), special_points=[sp])

    check_finite(branch(np.inf))  # Fr = inf: no gravity
    with pytest.raises(NonFiniteError, match="parameter b of LP"):
        check_finite(branch(np.nan))


@pytest.fixture(scope="module")
def pitchfork_orbits(tmp_path_factory):
    """The cycle-pitchfork fixture scene (tests/cycle_fixture_scenes.py): its orbits from HB1, with
    the branch point of cycles BP1 at mu = beta = 0.5."""
    import pathlib

    d = tmp_path_factory.mktemp("qa19b_bpc")
    eq, orb = d / "eq.h5", d / "orb.h5"
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(pathlib.Path(__file__).parent))
        mp.setenv("CONTIN_SCENES", "cycle_fixture_scenes:SCENES")
        assert _cli("trace", "cycle-pitchfork", "-q", "--no-stability", "-o", eq).exit_code == 0
        r = _cli("continue", eq, "--from", "HB1", "--cycles", "-o", orb)
        assert r.exit_code == 0 and "BP1" in r.output, r.output
        yield orb


@pytest.fixture
def fixture_scenes(monkeypatch):
    import pathlib

    monkeypatch.syspath_prepend(str(pathlib.Path(__file__).parent))
    monkeypatch.setenv("CONTIN_SCENES", "cycle_fixture_scenes:SCENES")


def test_amplitude_is_refused_at_a_branch_point_of_cycles(pitchfork_orbits, fixture_scenes):
    """--amplitude was silently ignored by the switch at a BP of cycles (the first orbit is a step of
    --ds): --amplitude 1e300 gave the same orbits as none."""
    r = _cli("continue", pitchfork_orbits, "--from", "BP1", "--cycles", "--amplitude", 0.1)
    assert r.exit_code == 1
    assert r.output.strip().splitlines() == [
        "Error: --amplitude sets the first orbit at a Hopf point or a PD; from the branch point BP1 the first orbit "
        "is a step of --ds along the bifurcating branch (set --ds)"]


@pytest.fixture(scope="module")
def lpc_curve(orbits):
    """A short LPC curve from LPC1 of the ab orbits (2 steps each way, NCOL 5: not the orbits' 4)."""
    out = orbits.parent / "lpc.h5"
    r = _cli("continue", orbits, "--from", "LPC1", "--free", "B", "--max-steps", 2, "--ncol", 5, "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.mark.parametrize("where", ["branches/lpc/states", "special_points/states"])
def test_edited_period_of_an_lpc_curve_is_a_damaged_file(lpc_curve, tmp_path, where):
    """The orbits of an LPC curve were not checked on reading as those of an orbit branch are: an
    edited period (-1) was drawn by `profiles --point` as 'period T = -1'."""
    import json

    from contin import io

    (curve,), meta = io.load(lpc_curve)  # the intact file reads (NCOL 5 in its 'cycles' entry)
    cyc = meta["extra"]["cycles"] if isinstance(meta["extra"], dict) else json.loads(meta["extra"])["cycles"]
    assert (cyc["n"], cyc["ncol"], curve.kind) == (2, 5, "lpc-curve")
    t_index = cyc["n"] * cyc["ntst"] * cyc["ncol"]  # [nodes (n NTST NCOL), T, interior mesh]
    assert np.isclose(curve.states[0, t_index], curve.observables["period"][0], rtol=0, atol=0)
    bad = tmp_path / "bad.h5"
    shutil.copy(lpc_curve, bad)
    with h5py.File(bad, "r+") as f:
        f[where][0, t_index] = -1.0
    label = curve.special_points[0].name
    r = _cli("profiles", bad, "--point", label, "-o", tmp_path / "p.png")
    assert r.exit_code == 1, r.output
    row = label if where.startswith("special") else 0
    assert r.output.strip().splitlines()[-1] == (
        f"Error: {str(bad)!r} is damaged: dataset {where} (row {row}) is no orbit: its period must be > 0 and its "
        "mesh increase from 0 to 1 (period -1)")


def test_lpc_curve_from_an_lpc_on_its_bound(orbits):
    """`--bounds D=<LPC1's D to 10 digits>:0.2` (rounded up past the stored value) said 'Error: start
    value D=0.161696 lies outside its bounds (0.161696, 0.2)': the LPC curve now starts on the bound
    as the fold and Hopf curves do (qa17), and a start truly outside is named with 10 digits."""
    from contin import io

    (orb,), _ = io.load(orbits)
    (lpc,) = orb.points("LPC")
    d = lpc.params["D"]
    lo = float(f"{d:.10g}")
    assert lo > d  # the case: the printed value lies just above the stored one
    r = _cli("continue", orbits, "--from", "LPC1", "--free", "B", "--bounds", f"D={lo!r}:0.2", "--max-steps", 2)
    assert r.exit_code == 0, r.output
    assert "reached bound D=" in r.output
    r = _cli("continue", orbits, "--from", "LPC1", "--free", "B", "--bounds", "D=0.17:0.2", "--max-steps", 2)
    assert r.exit_code == 1
    assert r.output.strip().splitlines() == [
        f"Error: start value D={d:.10g} of LPC1 lies outside its bounds (0.17, 0.2)"]


def test_lpc_curve_start_failing_on_a_coarser_mesh_blames_the_mesh(orbits):
    """--ntst 2: the LPC orbit carried onto 2 intervals is no fold there; the start failed with
    '... check the Jacobian with contin.problem.check_jacobian' (the problem's Jacobian is right)."""
    r = _cli("continue", orbits, "--from", "LPC1", "--free", "B", "--ntst", 2, "--max-steps", 2)
    assert r.exit_code == 3, r.output
    last = r.output.strip().splitlines()[-1]
    assert last.startswith("warning: the curve ended with MX: Newton failed at the start point"), last
    assert last.endswith("; the LPC orbit (NTST = 20, NCOL = 4) carried onto NTST = 2, NCOL = 4 is no fold there: "
                         "choose a finer mesh"), last
    assert "check_jacobian" not in r.output


def test_trace_resume_of_an_orbit_file_names_it_as_orbits(orbits, lpc_curve):
    """`trace ab --resume cyc.h5` (orbits from HB1) said the file 'holds a two-parameter curve'."""
    r = _cli("trace", "ab", "--resume", orbits)
    assert r.exit_code == 1
    assert r.output.strip().splitlines() == [
        f"Error: {str(orbits)!r} holds periodic orbits of `contin continue --cycles` (from HB1), not a run of "
        "`contin trace`; --resume continues a trace run (give another -o to keep the orbits)"]
    r = _cli("trace", "ab", "--resume", lpc_curve)  # an LPC curve is one
    assert r.exit_code == 1
    assert f"Error: {str(lpc_curve)!r} holds a two-parameter curve of `contin continue` (from LPC1)" in r.output


def test_unconverged_lp_of_an_lpc_curve_is_a_warning(tmp_path, fixture_scenes):
    """The transcritical cycle-pitchfork (q = 0.4): the other half at BP1 turns at the fold of cycles
    mu = beta + q^2/4 = 0.54; its LPC curve in (mu, q) is that parabola, whose extremum of mu (LP at
    q = 0, mu = beta) lies where the fold meets the pitchfork of cycles and its location does not
    converge: the table's note said so, with no warning line (exit 0)."""
    from contin import io

    eq, orb, sw = tmp_path / "eq.h5", tmp_path / "orb.h5", tmp_path / "sw.h5"
    assert _cli("trace", "cycle-pitchfork", "-s", "q=0.4", "-q", "--no-stability", "-o", eq).exit_code == 0
    assert _cli("continue", eq, "--from", "HB1", "--cycles", "-o", orb).exit_code == 0
    r = _cli("continue", orb, "--from", "BP1", "--cycles", "--other-half", "-o", sw)
    assert r.exit_code == 0, r.output
    (b,), _ = io.load(sw)
    (lpc,) = b.points("LPC")
    assert abs(lpc.params["mu"] - (0.5 + 0.4 ** 2 / 4)) < 1e-8
    out = tmp_path / "lpc.h5"
    r = _cli("continue", sw, "--from", "LPC1", "--free", "q", "--max-steps", 10, "-o", out)
    assert r.exit_code == 0, r.output
    (curve,), _ = io.load(out)
    np.testing.assert_allclose(curve.params["mu"], 0.5 + curve.params["q"] ** 2 / 4, rtol=0, atol=1e-10)
    (lp,) = [p for p in curve.points("LP") if not p.converged]
    assert abs(lp.params["mu"] - 0.5) < 1e-6 and abs(lp.params["q"]) < 1e-3
    assert (f"warning: the curve: {lp.name} at mu={lp.params['mu']:.10g}: location did not converge (its position "
            "is less accurate than asked)") in r.output.splitlines()


def test_bounds_at_a_branch_point_of_cycles_name_the_bp(pitchfork_orbits, fixture_scenes):
    """The switch at BP1 (mu = beta = 0.5; the bifurcated cycles z^2 = beta - mu exist for mu < 0.5)
    with --bounds excluding it, or excluding the side the new branch goes to, said 'start value
    mu=0.499699 lies outside its bounds (0.5, 0.9)' (its first orbit, not BP1); a bound on BP1
    itself (to rounding) is inside."""
    r = _cli("continue", pitchfork_orbits, "--from", "BP1", "--cycles", "--bounds", "mu=0.6:0.9")
    assert r.exit_code == 1
    assert r.output.strip().splitlines() == [
        "Error: BP1 at mu = 0.5 lies outside the bounds 0.6 <= mu <= 0.9; its cycles bifurcate there"]
    for extra in ((), ("--other-half",)):  # a pitchfork: both halves go to mu < beta
        r = _cli("continue", pitchfork_orbits, "--from", "BP1", "--cycles", *extra, "--bounds", "mu=0.5:0.9")
        assert r.exit_code == 1
        (line,) = r.output.strip().splitlines()
        assert line.startswith("Error: the branch bifurcating at BP1 (mu = 0.5) leaves the bounds 0.5 <= mu <= 0.9 "
                               "at once: its first orbit is at mu = 0.49"), line
    r = _cli("continue", pitchfork_orbits, "--from", "BP1", "--cycles", "--bounds", "mu=0.1:0.5", "--max-steps", 2)
    assert r.exit_code == 0, r.output
