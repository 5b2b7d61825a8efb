"""AUTO-style diagrams: line styles follow stability, runs join, markers and labels, atomic saves."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.figure import Figure

from contin import plot
from contin.branch import SpecialPoint

sys.path.insert(0, str(Path(__file__).parent))
from cli_fixture_scenes import Y, make_branch, profiles, toy_branches  # noqa: E402


def new_ax():
    return Figure().add_subplot()


def lines_of(ax):
    return [ln for ln in ax.get_lines() if ln.get_gid() and ln.get_gid().startswith("branch-")]


def test_stability_runs():
    s = np.array([1, 1, 1, 0, 0, 1, 1], dtype=bool)
    assert plot.stability_runs(s, 7) == [(0, 2, True), (3, 4, False), (5, 6, True)]
    assert plot.stability_runs(None, 4) == [(0, 3, None)]
    assert plot.stability_runs(np.zeros(3, bool), 3) == [(0, 2, False)]
    assert plot.stability_runs(None, 0) == []


def test_solid_stable_dashed_unstable_runs_join():
    lam = np.linspace(0.0, 6.0, 7)
    stable = np.array([1, 1, 1, 0, 0, 1, 1], dtype=bool)
    b = make_branch("0", lam, lam**2, stable, [])
    ax = new_ax()
    plot.plot_branch(b, "lam", "phi", ax)
    lines = lines_of(ax)
    assert [ln.get_linestyle() for ln in lines] == ["-", "--", "-"]
    xs = [list(ln.get_xdata()) for ln in lines]
    assert xs == [[0, 1, 2], [2, 3, 4], [4, 5, 6]]  # boundary points repeated, no gaps
    np.testing.assert_array_equal(lines[1].get_ydata(), [4, 9, 16])
    assert len({ln.get_color() for ln in lines}) == 1  # one colour per branch
    assert lines[0].get_linewidth() > lines[1].get_linewidth()


def test_unknown_stability_is_one_plain_solid_line():
    b = make_branch("0", np.linspace(0, 1, 5), np.linspace(0, 1, 5), None, [])
    ax = new_ax()
    plot.plot_branch(b, y="energy", ax=ax)  # x defaults to the continuation parameter
    (line,) = lines_of(ax)
    assert line.get_linestyle() == "-"
    np.testing.assert_array_equal(line.get_xdata(), b.params["lam"])
    np.testing.assert_array_equal(line.get_ydata(), b.observables["energy"])


def test_runs_split_at_the_located_branch_point():
    trivial = toy_branches()[0]  # stable for lam <= 0, BP located at lam = 0 (= point 4)
    trivial.stable = trivial.params["lam"] < -0.1  # change between points 3 and 4
    trivial.special_points = [SpecialPoint("BP", 3, {"lam": -0.1, "a": 1.0}, 0.0, np.zeros(3), label=1)]
    ax = new_ax()
    plot.plot_branch(trivial, "lam", "phi", ax)
    solid, dashed = lines_of(ax)
    assert solid.get_xdata()[-1] == pytest.approx(-0.1) and dashed.get_xdata()[0] == pytest.approx(-0.1)
    assert (solid.get_linestyle(), dashed.get_linestyle()) == ("-", "--")


def test_special_point_markers_and_labels():
    ax = new_ax()
    bs = toy_branches()
    plot.plot_diagram(bs, "lam", "phi", ax)
    marks = {ln.get_gid(): ln for ln in ax.get_lines() if (ln.get_gid() or "").startswith("sp-")}
    assert set(marks) == {"sp-BP1", "sp-LP2"}
    bp, lp = marks["sp-BP1"], marks["sp-LP2"]
    assert bp.get_marker() == "o" and bp.get_markerfacecolor() != "none"
    assert lp.get_marker() == "s" and lp.get_markerfacecolor() == "none"  # location did not converge
    assert (lp.get_xdata()[0], lp.get_ydata()[0]) == (0.16, 0.4)
    texts = {t.get_text(): t for t in ax.texts}
    assert set(texts) == {"BP1", "LP2"}
    assert texts["LP2"].get_anncoords() == "offset points"
    colors = [lines_of_branch(ax, b.id) for b in bs]
    assert len(set(colors)) == 3  # one colour per branch
    assert ax.get_xlabel() == "lam" and ax.get_ylabel() == "phi"
    assert len(ax.get_legend().get_texts()) == 3


def lines_of_branch(ax, bid):
    (c,) = {ln.get_color() for ln in lines_of(ax) if ln.get_gid().startswith(f"branch-{bid}-")}
    return c


def test_axes_choices_and_errors():
    b = toy_branches()[1]
    ax = new_ax()
    plot.plot_branch(b, "phi", "lam", ax)  # any parameter or observable on either axis
    (line,) = lines_of(ax)
    np.testing.assert_array_equal(line.get_xdata(), b.observables["phi"])
    lp = [ln for ln in ax.get_lines() if ln.get_gid() == "sp-LP2"][0]
    assert (lp.get_xdata()[0], lp.get_ydata()[0]) == (0.4, 0.16)
    with pytest.raises(ValueError, match="no parameter or observable 'tau'.*available: lam, a, Fr, phi, energy"):
        plot.plot_branch(b, "lam", "tau", new_ax())
    with pytest.raises(ValueError, match="no branches"):
        plot.plot_diagram([], "lam")


def test_profiles():
    states = toy_branches()[1].states
    prof = {k: np.array([profiles(u)[k] for u in states[:2]]) for k in ("nu", "T")}
    fig = plot.plot_profiles(Y, prof, labels=["a", "b"])
    axes = fig.get_axes()
    assert [a.get_ylabel() for a in axes] == ["nu", "T"]
    assert len(axes[1].get_lines()) == 2
    np.testing.assert_array_equal(axes[1].get_lines()[1].get_ydata(), prof["T"][1])
    with pytest.raises(ValueError, match="has 3 points but y has 5"):
        plot.plot_profiles(Y, {"nu": np.zeros(3)})


def test_save_figure_is_atomic(tmp_path, monkeypatch):
    fig = plot.plot_diagram(toy_branches(), "lam").figure
    out = plot.save_figure(fig, tmp_path / "d.png")
    good = out.read_bytes()
    assert good[:4] == b"\x89PNG"

    def broken(self, fname, **kw):
        Path(fname).write_bytes(b"partial")
        raise RuntimeError("renderer died")

    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(RuntimeError):
        plot.save_figure(fig, tmp_path / "d.png")
    with pytest.raises(RuntimeError):
        plot.save_figure(fig, tmp_path / "new.svg")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.png"]
    assert (tmp_path / "d.png").read_bytes() == good


def test_cli_diagram_line_styles(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(Path(__file__).parent))
    monkeypatch.setenv("CONTIN_SCENES", "cli_fixture_scenes:SCENES")
    from contin.cli import main

    h5 = tmp_path / "t.h5"
    assert CliRunner().invoke(main, ["trace", "toy", "-q", "-o", str(h5)]).exit_code == 0
    saved = []
    real = plot.save_figure
    monkeypatch.setattr(plot, "save_figure", lambda fig, path, **kw: (saved.append(fig), real(fig, path, **kw))[1])
    r = CliRunner().invoke(main, ["diagram", str(h5), "-o", str(tmp_path / "d.png")])
    assert r.exit_code == 0, r.output
    (ax,) = saved[0].get_axes()
    styles = {ln.get_gid(): ln.get_linestyle() for ln in lines_of(ax)}
    assert styles == {"branch-0-stable": "-", "branch-0-unstable": "--", "branch-1-stable": "-",
                      "branch-2-unknown": "-"}
    assert (tmp_path / "d.png").read_bytes()[:4] == b"\x89PNG"


def test_hopf_curve_neutral_saddle_part_is_dotted(tmp_path):
    """Past a BT a Hopf curve continues as neutral saddles (kappa < 0): that part is drawn dotted
    (gid ...-neutral-saddle), the Hopf part solid, split at the BT."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from contin.continuation import trace
    from contin.hopfcurve import trace_hopf_curve
    from contin.options import ContinuationOptions, StepOptions
    from contin.plot import NEUTRAL_SADDLE_STYLE, STABLE_STYLE, plot_branch
    from tests.hopf_models import AB

    first = ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05), bounds={"D": (0.0, 0.2)}, max_steps=400)
    (hb,) = trace(AB(), np.zeros(2), {"D": 0.0, "B": 14.0, "beta": 3.0}, "D", first).points("HB")
    curve = trace_hopf_curve(AB(), hb, "B", ContinuationOptions(step=StepOptions(ds=0.01, ds_max=0.05),
                                                                bounds={"D": (0.0, 0.5), "B": (0.0, 30.0)},
                                                                max_steps=150), parameter="D")
    kappa = curve.observables["kappa"]
    assert kappa.min() < 0 < kappa.max() and len(curve.points("BT")) == 1
    fig, ax = plt.subplots()
    artists = plot_branch(curve, "D", "B", ax)
    lines = {a.get_gid(): a for a in artists if a.get_gid() and a.get_gid().startswith("branch-")}
    assert lines[f"branch-{curve.id}-neutral-saddle"].get_linestyle() == NEUTRAL_SADDLE_STYLE
    assert lines[f"branch-{curve.id}-hopf"].get_linestyle() == STABLE_STYLE
    bt = curve.points("BT")[0]
    saddle = lines[f"branch-{curve.id}-neutral-saddle"].get_xydata()
    assert np.isclose(saddle[:, 0], bt.params["D"]).any()  # the two parts meet at the located BT
    plt.close(fig)


def test_cycle_points_are_marked_and_split_the_stability_runs():
    """LPC, PD and NS (contin.cycles) get markers and labels like LP/HB (they were drawn as nothing:
    an orbit file's diagram showed its HB and not its fold of cycles), and a located LPC joins the
    stable and unstable runs it separates."""
    b = toy_branches()[0]
    b.stable = b.params["lam"] < -0.1
    b.special_points = [SpecialPoint("LPC", 3, {"lam": -0.1, "a": 1.0}, 0.5, np.zeros(3), label=1),
                        SpecialPoint("PD", 6, {"lam": 0.2, "a": 1.0}, 0.7, np.zeros(3), label=2),
                        SpecialPoint("NS", 7, {"lam": 0.3, "a": 1.0}, 0.8, np.zeros(3), label=3)]
    ax = new_ax()
    plot.plot_branch(b, "lam", "phi", ax)
    marks = {ln.get_gid(): ln for ln in ax.get_lines() if (ln.get_gid() or "").startswith("sp-")}
    assert {g: (m.get_marker(), m.get_color()) for g, m in marks.items()} == {
        "sp-LPC1": ("o", "black"), "sp-PD2": ("d", "tab:blue"), "sp-NS3": ("p", "tab:green")}
    assert {t.get_text() for t in ax.texts} == {"LPC1", "PD2", "NS3"}
    solid, dashed = lines_of(ax)
    assert (solid.get_xdata()[-1], solid.get_ydata()[-1]) == (-0.1, 0.5) == (dashed.get_xdata()[0], dashed.get_ydata()[0])
