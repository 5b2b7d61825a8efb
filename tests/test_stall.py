"""A branch that ends at its step cap while crawling is said to (contin.stall)."""

from __future__ import annotations

import numpy as np
import pytest

from contin.continuation import trace
from contin.options import ContinuationOptions, StepOptions
from contin.stall import RATIO, STALLED, WINDOW, stalled
from tests.stall_fixture_scenes import problem


def wiggle(amplitude: float, max_steps: int = 80):
    params = {"p": -1.0, "A": amplitude}
    return trace(problem({"A": amplitude}), np.array([-1.0]), params, "p",
                 ContinuationOptions(max_steps=max_steps, step=StepOptions(ds=0.1, ds_max=0.1)))


def test_a_crawl_to_the_step_cap_is_said_and_a_steady_branch_is_not() -> None:
    """u = p - 1e-4 s(p) sin(1e5 p): past p = 0 the tangent turns by ~84 degrees every 3e-5 in p,
    so the steps shrink from 0.1 to ~1e-6 and the 80 steps end within 1e-2 of p = 0 (the plain
    line u = p, A = 0, reaches p = -1 + 80 x 0.1 / sqrt 2 in the same 80 steps of arclength 0.1)."""
    crawl = wiggle(1e-4)
    assert crawl.message.startswith("maximum number of steps") and 0 < crawl.params["p"][-1] < 1e-2
    tail = np.median(np.abs(crawl.ds[-WINDOW:]))
    assert tail <= RATIO * np.max(np.abs(crawl.ds))
    said = stalled(crawl)
    assert said is not None and said.startswith(STALLED)
    assert f"median ds of {tail:.3g}" in said and f"to {crawl.params['p'][-1]:.10g}" in said
    steady = wiggle(0.0)
    assert steady.message.startswith("maximum number of steps") and steady.params["p"][-1] == pytest.approx(-1 + 8 / np.sqrt(2), rel=1e-9)
    assert stalled(steady) is None
    # a crawl that ends otherwise (a bound, MX) is not this message's business
    assert stalled(type("B", (), {"message": "reached bound p=2", "ds": crawl.ds})()) is None


def test_cli_warns_of_a_crawl(tmp_path, monkeypatch) -> None:
    """`contin trace wiggle`: exit 0 (the points are right) but a warning line says that the
    branch crawled and where it stopped; a fixture scene through CONTIN_SCENES."""
    from click.testing import CliRunner

    from contin.cli import main

    monkeypatch.syspath_prepend(str(__import__("pathlib").Path(__file__).parent))
    monkeypatch.setenv("CONTIN_SCENES", "stall_fixture_scenes:SCENES")
    r = CliRunner().invoke(main, ["trace", "wiggle", "-q", "-o", str(tmp_path / "w.h5")])
    assert r.exit_code == 0, r.output
    (line,) = [ln for ln in r.stderr.splitlines() if ln.startswith("warning:")]
    assert line.startswith(f"warning: branch 0: {STALLED}: its last {WINDOW} steps")
    r = CliRunner().invoke(main, ["trace", "wiggle", "-q", "-s", "A=0", "-o", str(tmp_path / "s.h5")])
    assert r.exit_code == 0 and "warning" not in r.stderr, r.output


def test_continue_and_cycles_runs_warn_of_a_crawl(capsys) -> None:
    """`contin continue` (curves and orbits) ends through one helper; it says the same."""
    from contin.cli._runctl import end_of_curve_run

    crawl = wiggle(1e-4)
    end_of_curve_run("the curve", len(crawl), None, False, None, crawl.status, crawl.message, crawl)
    assert capsys.readouterr().err.startswith(f"warning: the curve {STALLED}: its last {WINDOW} steps")
    steady = wiggle(0.0)
    end_of_curve_run("the orbits", len(steady), None, False, None, steady.status, steady.message, steady)
    assert capsys.readouterr().err == ""
