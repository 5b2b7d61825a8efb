"""contin profiles of a file of periodic orbits (contin.orbitprofile, contin.cli.orbit_profiles):
the drawn lines are the stored orbit (``contin.cycles.orbit_of`` of the point's row) over one
period, t from 0 to T, and its phase portrait."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_ivp

from contin import io
from contin.cli import main
from contin.cycles import orbit_of
from contin.orbitprofile import orbit_at


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture
def orbits(ab_orbits):
    return ab_orbits


@pytest.fixture
def drawn(monkeypatch):
    """The lines of the figure the command saves, by gid."""
    import contin.plot

    lines: dict[str, np.ndarray] = {}
    original = contin.plot.save_figure

    def capture(fig, path, **kw):
        for ax in fig.axes:
            for line in ax.get_lines():
                lines[line.get_gid()] = np.asarray(line.get_xydata())
        return original(fig, path, **kw)

    monkeypatch.setattr(contin.plot, "save_figure", capture)
    return lines


def check_orbit(lines: dict[str, np.ndarray], label: str, state: np.ndarray) -> None:
    """u1(t), u2(t) over [0, T] and (u1, u2) are the orbit of the stored row ``state``."""
    mesh, nodes, period = orbit_of(state, 2, None, 4)
    u1, u2, phase = lines[f"{label}:u1"], lines[f"{label}:u2"], lines[f"{label}:phase"]
    t = u1[:, 0]
    assert t[0] == 0.0 and t[-1] == pytest.approx(period, rel=1e-14) and np.all(np.diff(t) > 0)
    np.testing.assert_array_equal(u2[:, 0], t)
    # 4 samples per node interval: every 4th is a node of the stored orbit, the last is u(T) = u(0)
    np.testing.assert_allclose(u1[:-1:4, 1], nodes[:, 0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(u2[:-1:4, 1], nodes[:, 1], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose([u1[-1, 1], u2[-1, 1]], nodes[0], rtol=1e-12)
    np.testing.assert_allclose(np.column_stack([u1[:, 1], u2[:, 1]]), mesh.evaluate(nodes, t / period), rtol=1e-12)
    np.testing.assert_array_equal(phase, np.column_stack([u1[:, 1], u2[:, 1]]))


def test_point_draws_the_stored_orbit_of_the_label(orbits, drawn, tmp_path):
    r = run("profiles", orbits / "cyc.h5", "--point", "LPC1", "-o", tmp_path / "o.png")
    assert r.exit_code == 0, r.output
    (br,), _ = io.load(orbits / "cyc.h5")
    (lpc,) = br.points("LPC")
    check_orbit(drawn, "0 at LPC1", lpc.state)
    assert f"branch 0: at LPC1, D = {lpc.params['D']:.10g}" in r.output
    assert (tmp_path / "o.png").stat().st_size > 1000


def test_at_a_stored_value_draws_that_orbit_and_between_two_interpolates(orbits, drawn, tmp_path):
    (br,), _ = io.load(orbits / "cyc.h5")
    d = [float(v) for v in br.params["D"]]
    r = run("profiles", orbits / "cyc.h5", "--at", f"D={d[5]!r}", "-o", tmp_path / "o.png")
    assert r.exit_code == 0, r.output
    check_orbit(drawn, "0 at stored point 5", br.state(5))
    assert "crossings" not in r.output  # D = d[5] is not reached again past the LPC (40 steps)
    # halfway (in D) between points 5 and 6: the two orbits interpolated, then corrected by Newton
    # at that D: an orbit of the ODE (AUTO's demo ab, written out here), which scipy's integration
    # from the drawn u(0) over the drawn T closes and follows; the interpolation alone is off by
    # 5e-5 (closure) and 2e-3 (along the orbit)
    mid = 0.5 * (d[5] + d[6])
    drawn.clear()
    r = run("profiles", orbits / "cyc.h5", "--at", f"D={mid!r}", "-o", tmp_path / "m.png")
    assert r.exit_code == 0, r.output
    key = "0 interpolated between points 5 and 6, corrected by Newton at D=" + f"{mid:g}"
    t, u1, u2 = drawn[key + ":u1"][:, 0], drawn[key + ":u1"][:, 1], drawn[key + ":u2"][:, 1]

    def ab(_, v, dd=mid, b=14.0, beta=3.0):
        h = dd * (1 - v[0]) * math.exp(v[1])
        return [-v[0] + h, -v[1] + b * h - beta * v[1]]

    sol = solve_ivp(ab, (0, t[-1]), [u1[0], u2[0]], t_eval=t, rtol=1e-11, atol=1e-12)
    scale = max(np.max(np.abs(u1)), np.max(np.abs(u2)))
    assert np.max(np.abs(sol.y[:, -1] - [u1[0], u2[0]])) < 1e-8 * scale
    assert np.max(np.abs(sol.y - [u1, u2])) < 1e-6 * scale
    # without the problem (a file whose scene cannot be rebuilt): the interpolation, T with it
    (plain,) = orbit_at([br], "D", mid, 2, 4)
    periods = br.observables["period"]
    assert plain.how == "interpolated between points 5 and 6"
    assert plain.period == pytest.approx(0.5 * (periods[5] + periods[6]), rel=1e-12)
    assert abs(plain.period - t[-1]) > 1e-6 * t[-1]  # the correction moved it
    # a value between the LPC and the last point is reached before and after the fold: said so
    lpc = br.points("LPC")[0].params["D"]
    assert lpc < d[-1] < d[0]
    r = run("profiles", orbits / "cyc.h5", "--at", f"D={(lpc + d[-1]) / 2!r}", "-o", tmp_path / "f.png")
    assert r.exit_code == 0 and "(the first of 2 crossings of D=" in r.output, r.output


@pytest.mark.parametrize("args, says", [
    ([], "give either --at NAME=VALUE or --point LABEL"),
    (["--at", "D=0.163", "--point", "LPC1"], "give either --at NAME=VALUE or --point LABEL"),
    (["--point", "HB7"], "no point 'HB7'"),
    (["--at", "D=0.3"], "no branch of orbits in"),
    (["--at", "X=1"], "no parameter 'X'"),
    (["--at", "B=14"], "B is constant along the orbits of"),
    (["--at", "D=0.163", "--names", "u3"], "no component 'u3'; the orbits have u1..u2"),
    (["--at", "D=0.163", "--branch", "7"], "no branch '7'"),
])
def test_bad_input_is_one_error_line(orbits, tmp_path, args, says):
    r = run("profiles", orbits / "cyc.h5", *args, "-o", tmp_path / "x.png")
    errors = [ln for ln in r.output.splitlines() if ln.startswith("Error:")]
    assert r.exit_code == 1 and len(errors) == 1 and says in errors[0], r.output
    assert not (tmp_path / "x.png").exists()


def test_point_on_a_file_of_equilibria_is_refused(orbits, tmp_path):
    r = run("profiles", orbits / "ab.h5", "--point", "HB1", "-o", tmp_path / "x.png")
    assert r.exit_code == 1 and "holds none (use --at NAME=VALUE)" in r.output.splitlines()[-1]


def test_an_orbit_newton_does_not_correct_is_drawn_with_a_warning(orbits, tmp_path, monkeypatch):
    import contin.orbitprofile

    def fails(*args, **kwargs):
        raise ValueError("Newton on the collocation system did not converge: (test)")

    monkeypatch.setattr(contin.orbitprofile, "corrected", fails)
    (br,), _ = io.load(orbits / "cyc.h5")
    mid = 0.5 * float(br.params["D"][5] + br.params["D"][6])
    r = run("profiles", orbits / "cyc.h5", "--at", f"D={mid!r}", "-o", tmp_path / "m.png")
    assert r.exit_code == 0, r.output
    warnings = [ln for ln in r.output.splitlines() if ln.startswith("warning:")]
    assert warnings == [f"warning: branch 0: the orbit interpolated between points 5 and 6 was not corrected at "
                        f"D={mid:g}: Newton on the collocation system did not converge: (test); it is drawn as "
                        "interpolated"]
