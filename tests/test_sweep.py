"""Parameter sweeps (contin.sweep, `contin sweep`): grid, failures, resume, executors, CLI.

The scene 'normalform' (tests/sweep_fixture_scenes.py) has special points known exactly
(LP at lam = a, BP at lam = b), so every recorded number can be checked.  Worker processes
find it through CONTIN_SCENES and PYTHONPATH, which they inherit.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import contin
from contin.scene import SceneError
from contin.sweep import (
    SweepError,
    load_sweep,
    open_executor,
    parse_sweep,
    read_task_file,
    run_sweep,
    run_task,
    task_key,
)

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent

SWEEP_TOML = """
[sweep]
scene = "normalform"
record = ["special_points", "extra.fold_lam"]

[fixed]
b = 2.0

[grid]
a = [-1.0, 0.5, 7.0]
fail = ["none", "mx", "crash"]
"""


@pytest.fixture
def scenes(monkeypatch):
    monkeypatch.setenv("CONTIN_SCENES", "sweep_fixture_scenes:SCENES")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.syspath_prepend(str(TESTS))


def _spec(grid=None, fixed=None, record=("special_points",), options=None):
    doc = {"sweep": {"scene": "normalform", "record": list(record)}, "fixed": fixed or {"b": 2.0},
           "grid": grid or {"a": [-1.0, 0.5, 3.0]}}
    if options:
        doc["options"] = options
    return parse_sweep(doc)


def _points(summary):
    return [(r.key, r.status, r.special_points) for r in summary.records]


# --------------------------------------------------------------------------- sweep files

def test_grid_is_the_cartesian_product_with_stable_keys(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nscene = "normalform"\n[fixed]\nb = 2\n'
                    '[grid]\na = {start = 0.5, stop = 0.99, num = 8}\nfail = ["none", "mx"]\n'
                    '[options]\nmax_steps = 50\nstability = false\n')
    spec = load_sweep(path)
    tasks = spec.tasks()
    assert spec.n_tasks == len(tasks) == 16
    np.testing.assert_allclose(spec.grid["a"], np.linspace(0.5, 0.99, 8), rtol=0, atol=0)
    # the first grid parameter varies slowest
    assert [t.swept["fail"] for t in tasks[:4]] == ["none", "mx", "none", "mx"]
    assert tasks[2].swept["a"] == pytest.approx(0.57)
    assert tasks[5].params == {"b": 2, "a": tasks[5].swept["a"], "fail": "mx"}
    assert len({t.key for t in tasks}) == 16
    # the key depends on scene, parameter values, options and contin version -- not on int/float
    t = tasks[0]
    assert t.key == task_key("normalform", {"b": 2.0, "a": 0.5, "fail": "none"},
                             {"max_steps": 50, "stability": False})
    assert t.key != task_key("normalform", t.params, {"max_steps": 51, "stability": False})
    assert t.key != task_key("normalform", t.params, spec.options, version=contin.__version__ + ".post1")
    assert t.key != task_key("other", t.params, spec.options)
    log = parse_sweep({"sweep": {"scene": "x"}, "grid": {"nu": {"start": 0.01, "stop": 1.0, "num": 3, "log": True}}})
    np.testing.assert_allclose(log.grid["nu"], [0.01, 0.1, 1.0], rtol=1e-14)


@pytest.mark.parametrize(("doc", "message"), [
    ({"sweep": {"scene": "s"}, "grid": {}}, "the [grid] table is empty"),
    ({"sweep": {"scene": "s"}}, "the [grid] table is empty"),
    ({"sweep": {"scene": "s", "scen": 1}, "grid": {"a": [1]}}, "unknown key 'scen' in [sweep]"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"max_step": 3}}, "unknown key 'max_step' in [options]"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "extra": {}}, "unknown table [extra]"),
    ({"sweep": {}, "grid": {"a": [1]}}, "needs scene ="),
    ({"sweep": {"scene": "s"}, "grid": {"a": []}}, "'a' has an empty list"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1, 2, 1]}}, "lists the value 1 twice"),
    ({"sweep": {"scene": "s"}, "grid": {"a": {"start": 0, "stop": 1}}}, "table with keys start, stop, num"),
    ({"sweep": {"scene": "s"}, "grid": {"a": {"start": 0, "stop": 1, "num": 0}}}, "num must be an integer >= 1"),
    ({"sweep": {"scene": "s"}, "grid": {"a": {"start": 0, "stop": 1, "num": 3, "log": True}}}, "log spacing"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "fixed": {"a": 2}}, "'a' is both fixed and swept"),
    ({"sweep": {"scene": "s", "record": ["folds"]}, "grid": {"a": [1]}}, "cannot record 'folds'"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"grid": 0}}, "'grid' must be >= 1"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"stability": 1}}, "'stability' must be of type bool"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"resolution_tol": "of"}}, "must be a number > 0 or \"off\""),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"resolution_tol": -1e-5}}, "must be a number > 0 or \"off\""),
    # a negative ds was accepted and its sign dropped (the scene chooses the direction); trace refuses it (qa18)
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"ds": -1}}, "option 'ds' must be a finite number > 0"),
    ({"sweep": {"scene": "s"}, "grid": {"a": [1]}, "options": {"engine": "fortran"}},
     "option 'engine' must be one of auto, numpy, numba, got 'fortran'"),
])
def test_bad_sweep_documents_give_one_sentence(doc, message):
    with pytest.raises(SweepError) as info:
        parse_sweep(doc)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_bad_files_scenes_and_parameters(tmp_path, scenes):
    with pytest.raises(SweepError, match="no such sweep file"):
        load_sweep(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[sweep\nscene=1")
    with pytest.raises(SweepError, match="is not valid TOML"):
        load_sweep(bad)
    with pytest.raises(SceneError, match="unknown scene 'nope'"):
        run_sweep(parse_sweep({"sweep": {"scene": "nope"}, "grid": {"a": [1]}}), tmp_path / "o")
    with pytest.raises(SweepError, match="scene 'normalform' has no parameter 'c'"):
        run_sweep(_spec(fixed={"c": 1.0}), tmp_path / "o")
    assert not (tmp_path / "o").exists()  # nothing computed, nothing written


# --------------------------------------------------------------------------- tasks

@pytest.mark.parametrize("value, used", [("off", None), (1e-3, 1e-3), (2, 2.0)])
def test_resolution_tol_option_reaches_the_traces_of_a_task(value, used, scenes):
    doc = run_task("normalform", {"a": 0.25}, {"resolution_tol": value})
    assert doc["status"] == "ok" and doc["extra"]["resolution_tol"] == used
    assert run_task("normalform", {"a": 0.25}, {})["extra"]["resolution_tol"] == 3e-5  # and ends with the task


def test_run_task_returns_exact_special_points_and_writes_a_contin_file(tmp_path, scenes):
    from contin import io

    params = {"a": 0.25, "b": -1.5, "fail": "none"}
    key = task_key("normalform", params, {})
    doc = run_task("normalform", params, {}, str(tmp_path / f"{key}.h5"))
    assert doc["status"] == "ok" and doc["reason"] == "" and doc["key"] == key
    assert [(sp["type"], sp["label"], sp["branch"], sp["params"]["lam"], sp["phi"], sp["converged"])
            for sp in doc["special_points"]] == [("LP", "LP1", "0", 0.25, 0.0, True), ("BP", "BP2", "1", -1.5, 0.0, True)]
    assert doc["extra"] == {"fold_lam": 0.25, "a_plus_b": -1.25, "label": "a=0.25", "resolution_tol": 3e-5}
    json.dumps(doc, allow_nan=False)  # compact and strict JSON
    assert read_task_file(tmp_path / f"{key}.h5") == doc
    branches, meta = io.load(tmp_path / f"{key}.h5")
    assert meta["complete"] and meta["scene"] == "normalform"
    assert [b.id for b in branches] == ["0", "1"]
    assert branches[0].special_points[0].params["lam"] == 0.25
    np.testing.assert_array_equal(branches[0].params["lam"], 0.25 + np.linspace(-1, 1, 21) ** 2)
    # a file of another key, or one without the sweep record, is not a finished task
    os.replace(tmp_path / f"{key}.h5", tmp_path / "0123.h5")
    assert read_task_file(tmp_path / "0123.h5") is None


def test_failing_tasks_are_recorded_with_reasons_and_others_complete(tmp_path, scenes):
    spec = load_sweep(_write(tmp_path / "s.toml", SWEEP_TOML))
    lines = []
    summary = run_sweep(spec, tmp_path / "out", jobs=2, progress=lines.append)
    by = {(r.swept["a"], r.swept["fail"]): r for r in summary.records}
    assert summary.counts() == {"tasks": 9, "ok": 2, "MX": 2, "error": 5, "lost": 0, "pending": 0,
                                "cached": 0, "computed": 9}
    for a in (-1.0, 0.5):
        ok = by[a, "none"]
        assert ok.status == "ok" and ok.reason == ""
        assert [(sp["type"], sp["params"]["lam"]) for sp in ok.special_points] == [("LP", a), ("BP", 2.0)]
        mx = by[a, "mx"]
        assert (mx.status, mx.reason) == ("MX", "branch 1: step size underflow")
        assert [sp["type"] for sp in mx.special_points] == ["LP", "BP"]  # partial results are kept
        crash = by[a, "crash"]
        assert crash.status == "error"
        assert crash.reason.startswith("RuntimeError: deliberate crash (sweep_fixture_scenes.py:")
        assert "Traceback" in read_task_file(tmp_path / "out" / crash.file)["traceback"]
    for fail in ("none", "mx", "crash"):
        assert (by[7.0, fail].status, by[7.0, fail].reason) == ("error", "a must lie in [-5, 5], got 7")
    assert len(lines) == 9 and sum(" ok " in ln for ln in lines) == 2
    assert any(ln.endswith("error: a must lie in [-5, 5], got 7  (0.0 s)") for ln in lines)
    assert all(ln.startswith("[") and "/9] a=" in ln for ln in lines)

    # the single-writer summary: HDF5 table + JSON, in grid order
    with h5py.File(tmp_path / "out" / "summary.h5", "r") as f:
        assert f.attrs["format"] == "contin-sweep" and f.attrs["scene"] == "normalform"
        t = f["tasks"]
        assert list(t["status"].asstr()[()]) == ["ok", "MX", "error", "ok", "MX", "error", "error", "error", "error"]
        np.testing.assert_array_equal(t["params/a"][()], [-1, -1, -1, 0.5, 0.5, 0.5, 7, 7, 7])
        assert list(t["params/fail"].asstr()[()]) == ["none", "mx", "crash"] * 3
        assert list(t["reason"].asstr()[()])[6] == "a must lie in [-5, 5], got 7"
        np.testing.assert_array_equal(t["n_LP"][()], [1, 1, 0, 1, 1, 0, 0, 0, 0])
        # fold_lam is recorded where the scene produced it; NaN exactly where the task failed
        np.testing.assert_array_equal(t["extra/fold_lam"][()], [-1, -1, np.nan, 0.5, 0.5, np.nan, np.nan, np.nan, np.nan])
        sp = f["special_points"]
        np.testing.assert_array_equal(sp["task"][()], [0, 0, 1, 1, 3, 3, 4, 4])
        np.testing.assert_array_equal(sp["params/lam"][()], [-1, 2, -1, 2, 0.5, 2, 0.5, 2])
        assert list(sp["type"].asstr()[()]) == ["LP", "BP"] * 4
    doc = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert doc["counts"]["error"] == 5
    assert doc["tasks"][6]["reason"] == "a must lie in [-5, 5], got 7"
    assert doc["tasks"][3]["extra"] == {"fold_lam": 0.5}  # only what the sweep asked to record
    assert not list((tmp_path / "out").glob("*.tmp"))


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_resume_recomputes_only_missing_tasks(tmp_path, scenes):
    spec = _spec(grid={"a": [-1.0, 0.0, 1.0, 2.0], "fail": ["none", "mx"]})
    out = tmp_path / "out"
    first = run_sweep(spec, out, jobs=2)
    assert (first.n_computed, first.n_cached) == (8, 0)
    files = sorted((out / "tasks").glob("*.h5"))
    assert len(files) == 8
    stamps = {p.name: p.stat().st_mtime_ns for p in files}

    again = run_sweep(spec, out, jobs=2)
    assert (again.n_computed, again.n_cached) == (0, 8)
    assert _points(again) == _points(first)

    victim = first.records[5]
    (out / victim.file).unlink()
    (out / "tasks" / "deadbeef.h5.part").write_bytes(b"half-written")  # a killed task's leftover
    lines = []
    third = run_sweep(spec, out, jobs=2, progress=lines.append)
    assert (third.n_computed, third.n_cached) == (1, 7)
    assert [r.key for r in third.records if not r.cached] == [victim.key]
    assert _points(third) == _points(first)
    assert lines[0] == f"resuming: 7 of 8 tasks already finished in {out / 'tasks'}"
    assert not (out / "tasks" / "deadbeef.h5.part").exists()
    assert {p.name: p.stat().st_mtime_ns for p in (out / "tasks").glob("*.h5") if p.name != Path(victim.file).name} \
        == {k: v for k, v in stamps.items() if k != Path(victim.file).name}

    # a damaged task file (e.g. copied half-way) is not a finished task: it is recomputed
    (out / first.records[0].file).write_bytes(b"\x89HDF garbage")
    fourth = run_sweep(spec, out, jobs=2)
    assert [r.key for r in fourth.records if not r.cached] == [first.records[0].key]
    assert _points(fourth) == _points(first)

    # --retry-failed reruns exactly the MX tasks; a changed option is a new set of tasks
    retried = run_sweep(spec, out, jobs=2, retry_failed=True)
    assert retried.n_computed == 4 and {r.status for r in retried.records if not r.cached} == {"MX"}
    other = run_sweep(_spec(grid=spec.grid, options={"max_steps": 7}), out, jobs=2)
    assert other.n_computed == 8


def test_sigkill_mid_sweep_then_resume(tmp_path, scenes):
    """A real SIGKILL of the whole sweep (parent and workers); the restart computes only
    the tasks without a file, and finished task files are left untouched."""
    toml = _write(tmp_path / "s.toml", '[sweep]\nscene = "normalform"\n[fixed]\ndelay = 0.3\n'
                  "[grid]\na = [-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5]\n")
    out = tmp_path / "out"
    code = f"from contin.sweep import load_sweep, run_sweep; run_sweep(load_sweep({str(toml)!r}), {str(out)!r}, jobs=1)"
    proc = subprocess.Popen([sys.executable, "-c", code], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while len(list((out / "tasks").glob("*.h5"))) < 3:
            assert proc.poll() is None and time.monotonic() < deadline, "sweep ended before it could be killed"
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    time.sleep(0.2)
    done = {p.name: p.stat().st_mtime_ns for p in (out / "tasks").glob("*.h5")}
    assert 3 <= len(done) < 10
    assert not (out / "summary.h5").exists()  # the parent never got to write it

    spec = load_sweep(toml)
    summary = run_sweep(spec, out, jobs=2)
    assert summary.n_cached == len(done)
    assert summary.n_computed == 10 - len(done)
    assert {r.file.removeprefix("tasks/") for r in summary.records if r.cached} == set(done)
    assert {p.name: p.stat().st_mtime_ns for p in (out / "tasks").glob("*.h5") if p.name in done} == done
    assert [r.status for r in summary.records] == ["ok"] * 10
    assert [r.special_points[0]["params"]["lam"] for r in summary.records] == list(spec.grid["a"])


# --------------------------------------------------------------------------- executors

def test_process_pool_and_local_dask_cluster_agree(tmp_path):
    """The shipped demo sweep (real Bratu continuations) on a 2-process pool and on a 2-worker
    LocalCluster: bit-identical special points, the fold at lam* to discretization accuracy,
    and the deliberately failing tasks (lam_min above the fold) recorded with their reason."""
    from problems.demo import BRATU_FOLD

    spec = load_sweep(REPO / "results" / "sweeps" / "demo_bratu.toml")
    pool = run_sweep(spec, tmp_path / "pool", jobs=2)
    with open_executor("local-dask", jobs=2) as executor:
        assert type(executor).__name__ == "ClientExecutor"
        assert len(executor._client.scheduler_info()["workers"]) == 2
        dask = run_sweep(spec, tmp_path / "dask", executor=executor)
    assert dask.n_computed == pool.n_computed == 8
    assert _points(dask) == _points(pool)
    assert [(r.status, r.reason) for r in dask.records] == [(r.status, r.reason) for r in pool.records]
    assert [r.status for r in pool.records] == ["ok"] * 6 + ["error"] * 2
    assert pool.records[-1].reason.startswith("lam_min must lie below the fold lam*=3.513831")
    folds = [sp["params"]["lam"] for r in pool.records for sp in r.special_points if sp["type"] == "LP"]
    assert len(folds) == 6
    np.testing.assert_allclose(folds, BRATU_FOLD, rtol=0, atol=1e-8)
    with h5py.File(tmp_path / "dask" / "summary.h5", "r") as f:
        np.testing.assert_array_equal(f["tasks/n_LP"][()], [1] * 6 + [0] * 2)
        np.testing.assert_allclose(f["special_points/params/lam"][()][f["special_points/type"].asstr()[()] == "LP"],
                                   BRATU_FOLD, atol=1e-8)


def test_scheduler_errors(monkeypatch):
    with pytest.raises(SweepError, match="unknown scheduler 'localhost'; use tcp://HOST:PORT or local-dask"):
        with open_executor("localhost"):
            pass
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if dask were not installed
    with pytest.raises(SweepError, match=r"needs Dask distributed, which is not installed: pip install -e '\.\[dask\]'"):
        with open_executor("local-dask"):
            pass


# --------------------------------------------------------------------------- CLI

def test_cli_sweep(tmp_path, scenes):
    from contin.cli import EXIT_INCOMPLETE, main

    toml = _write(tmp_path / "s.toml", SWEEP_TOML.replace('fail = ["none", "mx", "crash"]', 'fail = ["none"]'))
    runner = CliRunner()
    res = runner.invoke(main, ["sweep", str(toml), "-o", str(tmp_path / "out"), "-j", "2", "--json"])
    assert res.exit_code == EXIT_INCOMPLETE, res.output  # a = 7 is out of range
    doc = json.loads(res.stdout)
    assert [t["status"] for t in doc["tasks"]] == ["ok", "ok", "error"]
    assert [sp["params"]["lam"] for sp in doc["tasks"][1]["special_points"]] == [0.5, 2.0]
    assert "sweep: 3 tasks (2 ok, 1 error; 0 from earlier runs)" in res.stderr
    assert res.stderr.count("/3] a=") == 3

    ok = _write(tmp_path / "ok.toml", SWEEP_TOML.replace("7.0]", "2.0]").replace(', "crash"]', "]"))
    res = runner.invoke(main, ["sweep", str(ok), "-o", str(tmp_path / "ok"), "-j", "2", "--quiet"])
    assert (res.exit_code, res.stdout, res.stderr) == (EXIT_INCOMPLETE, "", "")  # 'mx' tasks fail
    res = runner.invoke(main, ["sweep", str(ok), "-o", str(tmp_path / "ok")])
    assert "resuming: 6 of 6 tasks already finished" in res.stderr

    bad = _write(tmp_path / "bad.toml", SWEEP_TOML.replace("[fixed]", "[fixd]"))
    res = runner.invoke(main, ["sweep", str(bad), "-o", str(tmp_path / "x")])
    assert res.exit_code == 1
    assert res.stderr.strip().splitlines() == [
        f"Error: unknown table [fixd] in {bad}; allowed: [sweep], [fixed], [grid], [options]"]
    res = runner.invoke(main, ["sweep", str(toml), "-o", str(tmp_path / "x"), "--scheduler", "nowhere"])
    assert res.exit_code == 1 and "unknown scheduler 'nowhere'" in res.stderr


def test_shipped_sweep_files_are_valid():
    """Every results/sweeps/*.toml parses; those whose scene is installed also match its parameters."""
    from contin.scene import available_scenes
    from contin.sweep import check_spec

    files = sorted((REPO / "results" / "sweeps").glob("*.toml"))
    specs = {f.name: load_sweep(f) for f in files}
    assert "demo_bratu.toml" in specs
    scenes = available_scenes()
    checked = [name for name, spec in specs.items() if spec.scene in scenes and check_spec(spec)]
    assert "demo_bratu.toml" in checked
    assert specs["demo_bratu.toml"].n_tasks == 8


def test_jobs_above_the_usable_cpus_are_capped_with_a_note(tmp_path, scenes, monkeypatch):
    """qa14: `contin sweep -j 64` on a 2-CPU machine started 64 CPU-bound workers (max_workers =
    min(jobs, tasks)): oversubscription.  Now the pool gets the usable CPUs, and one note says so."""
    import contin.sweep as sweep_mod
    from contin.cli import main

    sizes = []
    real_pool = sweep_mod.ProcessPoolExecutor

    def pool(*args, **kwargs):
        sizes.append(kwargs["max_workers"])
        return real_pool(*args, **kwargs)

    monkeypatch.setattr(sweep_mod, "usable_cpus", lambda: 2)
    monkeypatch.setattr(sweep_mod, "ProcessPoolExecutor", pool)
    assert sweep_mod.worker_count(None) == (2, "") and sweep_mod.worker_count(2) == (2, "")
    grid = SWEEP_TOML.replace("7.0]", "2.0, 3.0]").replace('fail = ["none", "mx", "crash"]', 'fail = ["none"]')
    toml = _write(tmp_path / "s.toml", grid)
    res = CliRunner().invoke(main, ["sweep", str(toml), "-o", str(tmp_path / "out"), "-j", "64"])
    assert res.exit_code == 0, res.output
    assert sizes == [2]
    assert "note: -j 64 capped at 2 worker(s), the CPUs this process may use" in res.stderr
    assert "Traceback" not in res.stderr
    # the library caps as well (no note: it has no terminal)
    run_sweep(_spec(grid={"a": [-1.0, 0.5, 3.0]}), tmp_path / "lib", jobs=1000)
    assert sizes == [2, 2]


def test_a_recorded_extra_name_no_task_has_is_a_warning(tmp_path, scenes):
    """`record = ["extra.fold_lamm"]` (a typo of fold_lam): every task recorded null for it and the
    sweep said nothing (exit 0).  Now one warning line names it; a name the tasks have gets none."""
    from contin.cli import main

    toml = _write(tmp_path / "s.toml", SWEEP_TOML.replace('"extra.fold_lam"]', '"extra.fold_lam", "extra.fold_lamm"]')
                  .replace("7.0]", "2.0]").replace('fail = ["none", "mx", "crash"]', 'fail = ["none"]'))
    res = CliRunner().invoke(main, ["sweep", str(toml), "-o", str(tmp_path / "out"), "-j", "1", "-q", "--json"])
    assert res.exit_code == 0, res.stderr
    assert [ln for ln in res.stderr.splitlines() if ln.startswith("warning:")] == [
        "warning: record = extra.fold_lamm: no task's extra results hold 'fold_lamm' (null in every task); the "
        "scene's extra names are in any task file (contin info --json)"]
    doc = json.loads(res.stdout)
    # fold_lam is recorded: the fixture's fold lies at lam = a
    assert [(t["extra"]["fold_lam"], t["extra"]["fold_lamm"]) for t in doc["tasks"]] == [(-1.0, None), (0.5, None),
                                                                                         (2.0, None)]
