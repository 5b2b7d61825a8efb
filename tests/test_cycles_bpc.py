"""Branch points of periodic orbits (BPC, AUTO's BP on a periodic branch) and branch switching there.

References are closed forms of tests/cycle_models.CyclePitchfork: Stuart-Landau in (x, y) with a
transverse z' = (beta - r^2) z - q z^2 - z^3.  The cycle r^2 = mu, z = 0, T = 2 pi has the
multipliers exp(-4 pi mu) (radial) and exp(2 pi (beta - mu)) (z), the latter through +1 at
mu = beta: the BPC.  The bifurcated cycles have r^2 = mu, z^2 + q z = beta - mu, T = 2 pi, and the
multipliers exp(-4 pi mu) and exp(2 pi (beta - mu - 2 q z - 3 z^2)); with q != 0 they turn at the
fold of cycles mu = beta + q^2 / 4.  Both families end where r^2 = mu shrinks to 0: the Hopf point
mu = 0 of the equilibria (0, 0, z).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from contin.continuation import trace
from contin.cycles import CycleOptions, branch_point_start, continue_branch_point, continue_cycles, orbit_of
from contin.options import ContinuationOptions
from tests.cycle_models import Bautin, CyclePitchfork

BETA = 0.5
OPTS = ContinuationOptions(bounds={"mu": (-1, 1)}, max_steps=200)


def _hopf(q: float):
    b = trace(CyclePitchfork(), np.zeros(3), {"mu": -0.3, "beta": BETA, "q": q}, "mu",
              ContinuationOptions(bounds={"mu": (-1, 1)}))
    (hb,) = b.points("HB")
    return hb


@pytest.fixture(scope="module")
def pitchfork():
    return continue_cycles(CyclePitchfork(), _hopf(0.0), "mu", OPTS)


@pytest.fixture(scope="module")
def transcritical():
    return continue_cycles(CyclePitchfork(), _hopf(0.4), "mu", OPTS)


def _sorted_moduli(values: np.ndarray) -> np.ndarray:
    return -np.sort(-np.abs(values), axis=1)


def test_pitchfork_of_cycles_located_at_mu_beta(pitchfork):
    br = pitchfork
    assert [s.type for s in br.special_points] == ["BP", "EP"]  # no LPC, PD or NS
    (bp,) = br.points("BP")
    assert bp.converged and "branch point of cycles (a Floquet multiplier through +1)" in bp.note
    assert abs(bp.params["mu"] - BETA) < 1e-9  # measured 2.5e-13 (NTST 20, adapted mesh)
    assert abs(bp.data["multiplier"] - 1.0) < 1e-9
    assert math.isclose(bp.data["period"], 2 * math.pi, rel_tol=1e-10)
    _, nodes, _ = orbit_of(bp.state, 3)
    np.testing.assert_allclose(nodes[:, 0] ** 2 + nodes[:, 1] ** 2, BETA, rtol=1e-7)
    assert np.abs(nodes[:, 2]).max() < 1e-12
    mu = br.parameter_values
    expected = _sorted_moduli(np.c_[np.exp(-4 * np.pi * mu), np.exp(2 * np.pi * (BETA - mu))])
    np.testing.assert_allclose(_sorted_moduli(br.eigenvalues), expected, rtol=1e-7, atol=1e-12)
    assert list(br.stable) == [m > BETA for m in mu]


def test_bpc_location_converges_with_the_mesh():
    """Uniform meshes: the BPC's distance from mu = beta falls faster than h^(2 NCOL) (measured
    NTST 4: 1.4e-8, NTST 8: 5.1e-12)."""
    hb = _hopf(0.0)
    err = {}
    for ntst in (4, 8):
        br = continue_cycles(CyclePitchfork(), hb, "mu", OPTS, CycleOptions(ntst=ntst, adapt_mesh=False))
        (bp,) = br.points("BP")
        err[ntst] = abs(bp.params["mu"] - BETA)
    assert err[4] < 1e-7 and err[8] < err[4] / 2**8


def test_transcritical_bpc_and_no_bpc_at_folds(transcritical):
    """q = 0.4: the BPC is transcritical (the determinant test sees it as well); the LPC of the
    bifurcated cycles (mu = beta + q^2 / 4) and Bautin's LPC (mu = -b^2 / 4) are not reported as BPs."""
    (bp,) = transcritical.points("BP")
    assert bp.converged and abs(bp.params["mu"] - BETA) < 1e-9 and "branch point of cycles" in bp.note
    hb = Bautin()
    b = trace(hb, np.zeros(2), {"mu": -0.3, "b": 1.0, "w": 1.0}, "mu", ContinuationOptions(bounds={"mu": (-1, 1)}))
    br = continue_cycles(hb, b.points("HB")[0], "mu", ContinuationOptions(bounds={"mu": (-1, 0.3)}, max_steps=200))
    assert [s.type for s in br.special_points] == ["LPC", "EP"]
    assert abs(br.points("LPC")[0].params["mu"] + 0.25) < 1e-8


def _check_bifurcated(br, q: float) -> np.ndarray:
    """r^2 = mu, z^2 + q z = beta - mu and T = 2 pi at every node of every orbit; the z of the first node."""
    mu = br.parameter_values
    first_z = []
    for i in range(len(br)):
        _, nodes, period = orbit_of(br.state(i), 3)
        x, y, z = nodes.T
        np.testing.assert_allclose(x * x + y * y, mu[i], rtol=2e-8, atol=1e-12)  # measured 7.5e-9
        np.testing.assert_allclose(z * z + q * z, BETA - mu[i], atol=1e-9)  # measured 2.7e-12
        assert math.isclose(period, 2 * math.pi, rel_tol=1e-10)  # measured 3.8e-12
        first_z.append(z[0])
    return np.array(first_z)


def test_switch_at_a_pitchfork_of_cycles(pitchfork):
    """Both halves z = +-sqrt(beta - mu) from BP1, stable (multipliers exp(-4 pi mu) and
    exp(-4 pi (beta - mu))), ending at the Hopf point mu = 0 of the equilibria (0, 0, +-sqrt(beta))."""
    (bp,) = pitchfork.points("BP")
    zs = []
    for d in (1, -1):
        br = continue_branch_point(CyclePitchfork(), bp, "mu", 3, OPTS, direction=d)
        assert br.kind == "periodic-orbits" and br.parent == bp.name and br.status == "EP"
        assert [s.type for s in br.special_points] == ["HB", "EP"]
        assert abs(br.points("HB")[0].params["mu"]) < 1e-9
        mu = br.parameter_values
        assert mu[0] < BETA and np.all(np.diff(mu) < 0)
        zs.append(_check_bifurcated(br, 0.0))
        expected = _sorted_moduli(np.c_[np.exp(-4 * np.pi * mu), np.exp(-4 * np.pi * (BETA - mu))])
        np.testing.assert_allclose(_sorted_moduli(br.eigenvalues), expected, rtol=1e-6, atol=1e-12)
        assert br.stable.all()
    assert np.all(zs[0] > 0) and np.all(zs[1] < 0)  # the two halves


def test_switch_at_a_transcritical_bpc(transcritical):
    """q = 0.4: one half goes to mu < beta (z > 0) and ends at mu = 0; the other (z < 0) turns at
    the fold of cycles mu = beta + q^2 / 4, z = -q / 2 (LPC, no BP) and comes back on the other root."""
    q = 0.4
    (bp,) = transcritical.points("BP")
    halves = {d: continue_branch_point(CyclePitchfork(), bp, "mu", 3, OPTS, direction=d) for d in (1, -1)}
    types = sorted(tuple(s.type for s in br.special_points) for br in halves.values())
    assert types == [("HB", "EP"), ("LPC", "HB", "EP")]
    for br in halves.values():
        z = _check_bifurcated(br, q)
        assert abs(br.points("HB")[0].params["mu"]) < 1e-9
        if br.points("LPC"):
            (lpc,) = br.points("LPC")
            assert lpc.converged and abs(lpc.params["mu"] - (BETA + q * q / 4)) < 1e-9
            _, nodes, _ = orbit_of(lpc.state, 3)
            np.testing.assert_allclose(nodes[:, 2], -q / 2, atol=1e-6)
            assert z[0] < 0
        else:
            assert np.all(z > 0)


def test_a_bp_without_a_multiplier_at_one_is_not_confirmed_nor_switched(pitchfork):
    """A BP at an orbit whose multipliers are far from +1 (the determinant changed sign for another
    reason) is marked not converged, and switching there is refused."""
    from contin.cycles import _branch_point_of_cycles

    br = pitchfork
    i = 2
    fake = dataclasses.replace(br.points("BP")[0], state=br.state(i), params={k: float(v[i]) for k, v in br.params.items()},
                               note="", data={})
    marked = _branch_point_of_cycles(CyclePitchfork(), fake, 3, CycleOptions(), None)
    assert not marked.converged and marked.note.startswith("not confirmed")
    # the nontrivial multiplier nearest +1 there: the radial one
    assert abs(marked.data["multiplier"] - math.exp(-4 * math.pi * fake.params["mu"])) < 1e-6
    with pytest.raises(ValueError, match="no Floquet multiplier at \\+1"):
        branch_point_start(CyclePitchfork(), marked, "mu", 3)
    with pytest.raises(ValueError, match="not at EP2"):
        branch_point_start(CyclePitchfork(), br.points("EP")[0], "mu", 3)


# --- command line --------------------------------------------------------------------------
def _cli(*args):
    from click.testing import CliRunner

    from contin.cli import main

    return CliRunner().invoke(main, [str(a) for a in args])


def test_cli_bpc_switch_and_auto_export(tmp_path, monkeypatch):
    """trace -> --cycles from HB1 (BP1 with its note) -> --cycles from BP1 (and --other-half): the
    bifurcating cycles z^2 = beta - mu; export --auto writes BP1 with AUTO's code 6."""
    from contin import io
    from tests.test_autoorbits import read_b, read_s

    here = __import__("pathlib").Path(__file__).parent
    monkeypatch.syspath_prepend(str(here))
    monkeypatch.setenv("CONTIN_SCENES", "cycle_fixture_scenes:SCENES")
    eq, orb = tmp_path / "eq.h5", tmp_path / "orb.h5"
    assert _cli("trace", "cycle-pitchfork", "-q", "--no-stability", "-o", eq).exit_code == 0
    r = _cli("continue", eq, "--from", "HB1", "--cycles", "-o", orb)
    assert r.exit_code == 0, r.output
    assert "branch point of cycles" in r.output
    (orbits,), _ = io.load(orb)
    (bp,) = orbits.points("BP")
    assert bp.name == "BP1" and abs(bp.params["mu"] - BETA) < 1e-9
    signs = []
    for extra, out in (((), tmp_path / "sw.h5"), (("--other-half",), tmp_path / "sw2.h5")):
        r = _cli("continue", orb, "--from", "BP1", "--cycles", *extra, "-o", out)
        assert r.exit_code == 0, r.output
        assert r.output.startswith("bifurcating periodic orbits from BP1")
        (sw,), meta = io.load(out)
        assert sw.parent == "BP1" and meta["extra"]["cycles"]["n"] == 3
        signs.append(np.sign(_check_bifurcated(sw, 0.0)))
    assert np.all(signs[0] == -signs[1][0])  # the two halves
    r = _cli("export", orb, "--auto", "x", "-d", tmp_path)
    assert r.exit_code == 0, r.output
    _, _, rows = read_b(tmp_path / "b.x")
    assert [(row[2], row[3]) for row in rows if row[2]] == [(6, 1), (9, 2)]
    assert [(b["ITP"], b["LAB"]) for b in read_s(tmp_path / "s.x")] == [(6, 1), (9, 2)]
    r = _cli("continue", eq, "--from", "HB1", "--cycles", "--other-half")
    assert r.exit_code == 1 and "Error: --other-half is for --cycles from a branch point (BP)" in r.output
    r = _cli("continue", orb, "--from", "EP2", "--cycles")
    assert r.exit_code == 1 and "only a PD or a BP continues" in r.output
