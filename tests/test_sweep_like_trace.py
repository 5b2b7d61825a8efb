"""A `contin sweep` task computes what `contin trace` computes with the same settings.

Before session 18 a task of an adaptive scene without ``grid`` ran on the scene's fixed default
grid (cheb 32) where `trace` ran adaptively at the scene's ``default_tol``, and no task got the
stability pass `trace` runs after a scene's run (``problem_factory`` scenes: brusselator, ab,
lorenz, ...): the task files had neither the same grids and numbers nor stability columns.  Both
now go through one function each (``Scene.accuracy_overrides``, ``contin.scene.stability_after_run``).

The 1-D Brusselator (scene ``brusselator``: adaptive, ``problem_factory``, its stability left to
the command line) has its Hopf point in closed form, b_H = 1 + a^2 + (D1 + D2) pi^2 / L^2, where a
complex pair of the homogeneous state crosses: n_unstable is 0 below b_H and 2 above.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests import cli_sweep
from tests.cli_sweep import one_error, run
from contin import io
from contin.scene import get_scene
from contin.sweep import SweepError, check_spec, parse_sweep, run_task, task_key

real_scenes = cli_sweep.real_scenes  # autouse: the real scene registry, not a fixture's CONTIN_SCENES


def _task_file(tmp_path, scene, params, options):
    path = tmp_path / "task.h5"
    doc = run_task(scene, params, options, str(path))
    assert doc["status"] == "ok", doc
    return doc, *io.load(path)


def _trace_file(tmp_path, args):
    out = tmp_path / "trace.h5"
    res = run(["trace", *args, "-q", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    return io.load(out)


def _same_branches(a, b):
    """Every stored number of two runs' branches equal (bitwise): grids, states, parameters,
    observables, special points, stability columns and audit lines."""
    assert [x.id for x in a] == [y.id for y in b]
    for x, y in zip(a, b):
        assert (x.grid is None) == (y.grid is None)
        if x.grid is not None:
            np.testing.assert_array_equal(x.grid, y.grid)
        np.testing.assert_array_equal(x.states, y.states)
        assert x.params.keys() == y.params.keys() and x.observables.keys() == y.observables.keys()
        for name in x.params:
            np.testing.assert_array_equal(x.params[name], y.params[name])
        for name in x.observables:
            np.testing.assert_array_equal(x.observables[name], y.observables[name])
        assert [(s.name, s.params, s.grid) for s in x.special_points] == [(s.name, s.params, s.grid) for s in y.special_points]
        assert (x.n_unstable is None) == (y.n_unstable is None)
        if x.n_unstable is not None:
            np.testing.assert_array_equal(x.n_unstable, y.n_unstable)
            np.testing.assert_array_equal(x.eigenvalues, y.eigenvalues)
            assert x.stability_k == y.stability_k
        assert x.audit == y.audit


def _b_hopf(p):
    return 1 + p["a"] ** 2 + (p["D1"] + p["D2"]) * math.pi ** 2 / p["L"] ** 2


def test_a_sweep_task_of_an_adaptive_scene_is_the_trace_run_with_its_stability(tmp_path):
    doc, task, meta = _task_file(tmp_path, "brusselator", {"a": 2.0}, {})
    traced, tmeta = _trace_file(tmp_path, ["brusselator", "-s", "a=2"])
    _same_branches(task, traced)
    assert meta["discretization"] == tmeta["discretization"]
    (b,) = task
    # adaptive at the scene's default_tol (the fixed default grid has no grid column), as trace
    assert b.grid is not None and len(set(b.grid.tolist())) > 1
    # the stability pass trace runs after the scene's run: 0 below the closed-form b_H, 2 above
    p = meta["parameters"]
    (hb,) = [s for s in b.special_points if s.type == "HB"]
    assert hb.params["b"] == pytest.approx(_b_hopf(p), rel=1e-10)
    np.testing.assert_array_equal(b.n_unstable, np.where(b.params["b"] < _b_hopf(p), 0, 2))
    # a task of the adaptive default is not the fixed-grid task of an earlier version
    assert doc["key"] != task_key("brusselator", {"a": 2.0}, {})


@pytest.mark.parametrize("options, args", [
    ({"grid": 16}, ["--grid", "16"]),                                   # a fixed grid
    ({"grid": 16, "tol": 1e-6, "max_grid": 64}, ["--grid", "16", "--tol", "1e-6", "--max-grid", "64"]),
    ({"tol": 1e-8, "solve_check": False, "special_tol": 1e-9},
     ["--tol", "1e-8", "--no-solve-check", "--special-tol", "1e-9"]),
    ({"stability": False}, ["--no-stability"]),
])
def test_a_sweep_task_resolves_its_accuracy_and_stability_as_trace(tmp_path, options, args):
    doc, task, _ = _task_file(tmp_path, "brusselator", {"a": 2.0}, options)
    traced, _ = _trace_file(tmp_path, ["brusselator", "-s", "a=2", *args])
    _same_branches(task, traced)
    (b,) = task
    assert (b.grid is None) == (options.get("tol") is None and "grid" in options)
    assert (b.n_unstable is None) == (options.get("stability") is False)
    # the key holds the resolved accuracy only when it is adaptive (fixed-grid keys as before)
    assert (doc["key"] == task_key("brusselator", {"a": 2.0}, options)) == (b.grid is None)


def test_a_task_of_a_scene_without_stability_operator_says_so_in_its_notes(tmp_path):
    """`disks-steady` has no linear-stability operator (Scene.stability False): trace says so in a
    note, and the task file now says it too rather than store branches without a word."""
    scene = get_scene("disks-steady")
    assert not scene.stability
    from contin.scene import SceneRequest, SceneResult, stability_after_run

    lines = []
    stability_after_run(scene, SceneRequest(), SceneResult(branches=[], parameters={}), lines.append)
    assert lines == ["note: scene 'disks-steady' has no linear-stability operator; branches are stored without stability"]


def test_sweep_accuracy_options_are_checked_against_the_scene():
    def spec(options, scene="brusselator"):
        swept = {"brusselator": "a", "ab": "B"}[scene]
        return parse_sweep({"sweep": {"scene": scene}, "grid": {swept: [2.0]}, "options": options})

    with pytest.raises(SweepError, match="scene 'ab' has no adaptive resolution .option 'tol'"):
        check_spec(spec({"tol": 1e-6}, scene="ab"))
    with pytest.raises(SweepError, match="option 'special_tol' needs adaptive resolution: drop option 'grid'"):
        check_spec(spec({"grid": 16, "special_tol": 1e-9}))
    with pytest.raises(SweepError, match="option 'grid' 96 exceeds option 'max_grid' 64"):
        check_spec(spec({"grid": 96, "tol": 1e-6, "max_grid": 64}))
    with pytest.raises(SweepError, match="option 'max_grid', option 'solve_check' need adaptive resolution"):
        check_spec(spec({"grid": 16, "max_grid": 64, "solve_check": False}))
    for bad, why in (({"tol": 0.0}, "in .0, 1."), ({"tol": 1.5}, "in .0, 1."), ({"max_grid": 2}, ">= 8"),
                     ({"solve_check": 1}, "type bool"), ({"special_tol": "x"}, "type int or float")):
        with pytest.raises(SweepError, match=why):
            spec(bad)


def test_contin_sweep_with_a_bad_accuracy_option_is_one_error_line(tmp_path):
    toml = tmp_path / "s.toml"
    toml.write_text('[sweep]\nscene = "ab"\n[grid]\nB = [1.0]\n[options]\ntol = 1e-6\n')
    assert one_error(run(["sweep", str(toml), "-o", str(tmp_path / "out")])).startswith(
        "Error: scene 'ab' has no adaptive resolution (option 'tol'")


@pytest.mark.parametrize("flags, error", [
    (["--max-grid", "64"], "Error: --max-grid needs adaptive resolution: drop --grid or add --tol"),
    (["--no-solve-check"], "Error: --no-solve-check needs adaptive resolution: drop --grid or add --tol"),
    (["--special-tol", "1e-9", "--max-grid", "64"],
     "Error: --special-tol, --max-grid need adaptive resolution: drop --grid or add --tol"),
    (["--tol", "1e-6", "--max-grid", "8"], "Error: --grid 16 exceeds --max-grid 8"),
])
def test_trace_refuses_accuracy_flags_a_fixed_grid_ignores(tmp_path, flags, error):
    """`contin trace brusselator --grid 16 --max-grid 64` ran on the fixed grid 16 and ignored
    --max-grid (and --no-solve-check) with exit 0; --special-tol was refused: now all three are,
    by the rule sweeps use too (Scene.accuracy_overrides)."""
    res = run(["trace", "brusselator", "--grid", "16", *flags, "-q", "-o", str(tmp_path / "x.h5")])
    assert one_error(res) == error
    assert not (tmp_path / "x.h5").exists()


def test_a_sweep_task_says_when_its_kx_columns_cannot_be_computed(tmp_path):
    """`contin trace brusselator --kx 1` warns that the problem has no wavenumber (one warning
    line, the k_x = 0 pass kept); the sweep option kx = [1.0] was dropped without a word in a task
    file.  Both now come from contin.scene.stability_after_run: the task's notes hold the warning."""
    doc, (b,), meta = _task_file(tmp_path, "brusselator", {"a": 2.0}, {"kx": [1.0]})
    warning = ("warning: option kx 1 ignored: scene 'brusselator' has no wavenumber: its problem has no "
               "eigenproblem(u, p, kx, kz), so only k_x = 0 exists (that stability was computed); no growth_rate_kx "
               "column was stored")
    assert warning in doc["notes"] and warning in meta["notes"]
    assert b.n_unstable is not None and not any(k.startswith("growth_rate_kx") for k in b.observables)
    res = run(["trace", "brusselator", "-s", "a=2", "--kx", "1", "-q", "-o", str(tmp_path / "t.h5")])
    assert res.exit_code == 0 and warning.replace("option kx", "--kx") in res.stderr.splitlines()


@pytest.mark.parametrize("scene, params", [
    ("pitchfork", {"nu": 0.3, "e": 0.8, "modes": 1, "H_max": 30.0}),  # adaptive (3e-5), its own stability pass
    ("ab", {"B": 1.0}),                                                # fixed, stability by problem_factory
])
def test_sweep_tasks_of_gpcf_and_ode_scenes_equal_their_trace(tmp_path, scene, params):
    _, task, meta = _task_file(tmp_path, scene, params, {})
    traced, tmeta = _trace_file(tmp_path, [scene, *(a for k, v in params.items() for a in ("-s", f"{k}={v:g}"))])
    _same_branches(task, traced)
    assert meta["discretization"] == tmeta["discretization"]
    assert all(b.n_unstable is not None for b in task if len(b.free) == 1)
