"""HDF5 storage: exact round trip, layout readable with h5py alone, crash safety, bad files."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from contin import io
from contin.branch import Branch, SpecialPoint
from contin.options import ContinuationOptions, NewtonOptions, StepOptions

sys.path.insert(0, str(Path(__file__).parent))
from cli_fixture_scenes import Y, profiles, toy_branches  # noqa: E402


def assert_same_value(a, b, what):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        assert isinstance(a, np.ndarray) and isinstance(b, np.ndarray), what
        assert a.shape == b.shape, what
        assert a.dtype.kind == b.dtype.kind, (what, a.dtype, b.dtype)
        np.testing.assert_array_equal(a, b, err_msg=what)  # NaN == NaN here
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), what
    elif isinstance(a, dict):
        assert list(a) == list(b), what
        for k in a:
            assert_same_value(a[k], b[k], f"{what}[{k}]")
    elif isinstance(a, (tuple, list)) and a and isinstance(a[0], SpecialPoint):
        assert len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b)):
            for f in dataclasses.fields(SpecialPoint):
                assert_same_value(getattr(x, f.name), getattr(y, f.name), f"{what}[{i}].{f.name}")
    elif isinstance(a, tuple) and any(isinstance(v, float) for v in a):
        assert len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same_value(x, y, f"{what}[{i}]")
    else:
        assert a == b and type(a) is type(b), (what, a, b)


def assert_same_branch(a: Branch, b: Branch) -> None:
    for f in dataclasses.fields(Branch):
        assert_same_value(getattr(a, f.name), getattr(b, f.name), f"branch {a.id}.{f.name}")


def rich_branches() -> list[Branch]:
    bs = toy_branches(a=2.5, n=3)
    rng = np.random.default_rng(1)
    bs[0].eigenvalues = rng.standard_normal((len(bs[0]), 3)) + 1j * rng.standard_normal((len(bs[0]), 3))
    bs[0].audit = ["step 3 rejected: Newton diverged", "step 5 rejected: angle 0.4 > 0.3"]
    bs[1].closed = True
    bs[1].status, bs[1].message = "MX", "Newton failed at lam=0.5"
    bs[2].observables["ds"] = np.arange(len(bs[2]), dtype=float)  # clashes with a reserved name
    bs[2].observables["a/b"] = np.ones(len(bs[2]))  # a '/' in a name
    bs[2].special_points = [SpecialPoint("UZ", 1, {"lam": 2.5}, math.nan, np.arange(7.0), None, label=3)]
    return bs


def test_round_trip_is_exact(tmp_path):
    bs = rich_branches()
    opts = ContinuationOptions(newton=NewtonOptions(tol=1e-11), step=StepOptions(ds=-0.05, ds_max=0.2),
                               bounds={"lam": (-2.0, 3.0)}, max_steps=77)
    path = io.write(tmp_path / "run.h5", bs, scene="toy", parameters={"a": 2.5, "Fr": math.inf, "chi": "jj"},
                    discretization={"method": "cheb", "intervals": 4}, options=opts,
                    command=["contin", "trace", "toy", "-s", "a=2.5"], y=Y, profiles=profiles,
                    notes=["a note"], extra={"x": [1, 2]}, diagram_x="lam")
    loaded, meta = io.load(path)
    assert [b.id for b in loaded] == ["0", "1", "2"]
    for a, b in zip(bs, loaded):
        assert_same_branch(a, b)
    assert meta["complete"] is True
    assert meta["scene"] == "toy"
    assert meta["parameters"] == {"a": 2.5, "Fr": math.inf, "chi": "jj"}
    assert meta["discretization"] == {"method": "cheb", "intervals": 4}
    assert meta["command"] == "contin trace toy -s a=2.5"
    assert io.options_from_dict(meta["options"]) == opts
    assert meta["notes"] == ["a note"] and meta["extra"] == {"x": [1, 2]}
    np.testing.assert_array_equal(meta["y"], Y)
    # profiles of the sampled states, by point index
    prof = meta["profiles"]["1"]
    np.testing.assert_array_equal(prof["index"], np.arange(len(bs[1])))
    for i in prof["index"]:
        np.testing.assert_array_equal(prof["T"][i], profiles(bs[1].states[i])["T"])
    assert meta["git_commit"] != ""


def test_many_points_sample_profiles_and_keep_order(tmp_path):
    lam = np.linspace(0, 1, 500)
    from cli_fixture_scenes import make_branch

    bs = [make_branch(str(k), lam, lam * k, None, []) for k in (10, 2, 1)]  # ids not in sort order
    io.write(tmp_path / "r.h5", bs, y=Y, profiles=profiles, max_profiles=25)
    loaded, meta = io.load(tmp_path / "r.h5")
    assert [b.id for b in loaded] == ["10", "2", "1"]
    idx = meta["profiles"]["2"]["index"]
    assert idx[0] == 0 and idx[-1] == 499 and len(idx) == 25
    np.testing.assert_allclose(meta["profiles"]["2"]["nu"][:, 0], 2 * lam[idx])


def test_layout_readable_with_h5py_alone(tmp_path):
    bs = rich_branches()
    io.write(tmp_path / "run.h5", bs, scene="toy", parameters={"a": 2.5}, y=Y, profiles=profiles)
    with h5py.File(tmp_path / "run.h5", "r") as f:
        assert f.attrs["format"] == "contin" and f.attrs["format_version"] == io.FORMAT_VERSION == 2
        for key in ("contin_version", "git_commit", "created_utc", "command", "scene", "parameters",
                    "discretization", "options"):
            assert key in f.attrs
        g = f["branches/0"]
        assert g.attrs["parameter"] == "lam" and g.attrs["status"] == "EP"
        np.testing.assert_array_equal(g["lam"][()], bs[0].params["lam"])
        np.testing.assert_array_equal(g["phi"][()], bs[0].observables["phi"])
        np.testing.assert_array_equal(g["stable"][()], bs[0].stable)
        assert g["states"].shape == bs[0].states.shape
        assert f["branches/1/profiles/T"].shape == (len(bs[1]), Y.size)
        np.testing.assert_array_equal(f["grid/y"][()], Y)
        sp = f["special_points"]
        assert list(sp["type"].asstr()[()]) == ["BP", "LP", "UZ"]
        assert list(sp["branch"].asstr()[()]) == ["0", "1", "2"]
        np.testing.assert_array_equal(sp["params/lam"][()], [0.0, 0.16, 2.5])
        np.testing.assert_array_equal(sp["converged"][()], [True, False, True])
        np.testing.assert_array_equal(sp["bracket_lo"][()][:2], [-0.25, 0.1])
        np.testing.assert_array_equal(sp["states"][1, :3], bs[1].special_points[0].state)
        assert sp["profiles/nu"].shape == (3, Y.size)
        # a clashing observable name is stored escaped, with a map in the attrs
        assert "q%ds" in f["branches/2"] and "a%2Fb" in f["branches/2"]


def test_corrupt_truncated_and_foreign_files(tmp_path):
    good = io.write(tmp_path / "good.h5", rich_branches())
    size = good.stat().st_size
    cases = {}
    cases["garbage.h5"] = b"this is not an HDF5 file\n" * 20
    cases["truncated.h5"] = good.read_bytes()[: size // 2]
    cases["empty.h5"] = b""
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    with h5py.File(tmp_path / "foreign.h5", "w") as f:
        f["x"] = np.arange(3)
    with h5py.File(tmp_path / "nobranches.h5", "w") as f:
        f.attrs["format"] = "contin"
        f.attrs["format_version"] = 1
    with h5py.File(tmp_path / "future.h5", "w") as f:
        f.attrs["format"] = "contin"
        f.attrs["format_version"] = 99
    for name in [*cases, "foreign.h5", "nobranches.h5", "future.h5"]:
        with pytest.raises(io.FileFormatError) as err:
            io.load(tmp_path / name)
        msg = str(err.value)
        assert "\n" not in msg and name in msg, msg
    with pytest.raises(FileNotFoundError):
        io.load(tmp_path / "missing.h5")


def test_failed_write_leaves_previous_file_and_no_partial(tmp_path, monkeypatch):
    path = tmp_path / "run.h5"
    first = toy_branches(n=2)
    io.write(path, first)
    before = path.read_bytes()

    def boom(*args, **kw):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(io, "_write_special_points", boom)  # fails after the branches are written
    with pytest.raises(RuntimeError):
        io.write(path, toy_branches(n=3))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    with pytest.raises(RuntimeError):
        io.write(tmp_path / "new.h5", toy_branches(n=3))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    monkeypatch.undo()
    loaded, _ = io.load(path)
    assert len(loaded) == 2


def test_writer_publishes_each_branch_and_survives_a_crash_mid_publish(tmp_path, monkeypatch):
    path = tmp_path / "run.h5"
    bs = toy_branches(n=3)
    with pytest.raises(RuntimeError):
        with io.H5Writer(path, scene="toy", parameters={"a": 1.0}) as w:
            assert not path.exists()  # nothing published before the first branch
            w.add_branch(bs[0])
            loaded, meta = io.load(path)
            assert [b.id for b in loaded] == ["0"] and meta["complete"] is False
            assert_same_branch(bs[0], loaded[0])
            w.add_branch(bs[1])
            assert [b.id for b in io.load(path)[0]] == ["0", "1"]
            real = io._write_branch
            calls = []

            def crash_on_third(group, branch, *a):
                calls.append(branch.id)
                if branch.id == "2":
                    raise RuntimeError("killed mid-write")
                return real(group, branch, *a)

            monkeypatch.setattr(io, "_write_branch", crash_on_third)
            w.add_branch(bs[2])
    loaded, meta = io.load(path)  # still the last complete publish
    assert [b.id for b in loaded] == ["0", "1"] and meta["complete"] is False
    assert not (tmp_path / "run.h5.tmp").exists()


def test_writer_checkpoint_ratio_bounds_unpublished_work(tmp_path, monkeypatch):
    """checkpoint_ratio c: a branch is published at once only when the time since the last
    publish is >= c times that publish's duration; the rest wait for the next publish."""
    clock = [100.0]
    monkeypatch.setattr(io.time, "monotonic", lambda: clock[0])
    real = io._publish

    def timed_publish(path, fill):  # every publish "takes" 0.5 s
        real(path, fill)
        clock[0] += 0.5

    monkeypatch.setattr(io, "_publish", timed_publish)
    path = tmp_path / "run.h5"
    bs = toy_branches(n=4)
    with io.H5Writer(path, scene="toy", checkpoint_ratio=4.0) as w:
        w.add_branch(bs[0])  # the first branch: published at once
        assert w.publishes == 1 and not w.pending
        clock[0] += 1.9  # < 4 x 0.5 s since the last publish ended
        w.add_branch(bs[1])
        assert w.publishes == 1 and w.pending
        assert [b.id for b in io.load(path)[0]] == ["0"]
        clock[0] += 0.1  # now exactly 4 x 0.5 s
        w.add_branch(bs[2])
        assert w.publishes == 2 and not w.pending
        assert [b.id for b in io.load(path)[0]] == ["0", "1", "2"]
        w.add_branch(bs[3])
        assert w.pending
    loaded, meta = io.load(path)  # the final publish holds everything
    assert [b.id for b in loaded] == ["0", "1", "2", "3"] and meta["complete"] is True
    assert w.publishes == 3
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="checkpoint_ratio"):
            io.H5Writer(tmp_path / "x.h5", checkpoint_ratio=bad)


def test_writer_replaces_same_id_and_final_publish_is_complete(tmp_path):
    path = tmp_path / "run.h5"
    bs = toy_branches(n=2)
    with io.H5Writer(path, scene="toy") as w:
        w.add_branch(bs[0])
        changed = dataclasses.replace(bs[0], message="updated")
        w.add_branch(changed)
    loaded, meta = io.load(path)
    assert [b.message for b in loaded] == ["updated"] and meta["complete"] is True


def test_check_writable_fails_fast(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        io.H5Writer(tmp_path / "no" / "such" / "dir.h5")
    with pytest.raises(IsADirectoryError):
        io.H5Writer(tmp_path)
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        with pytest.raises(OSError, match="cannot write"):
            io.H5Writer(ro / "x.h5")


def test_round_trip_with_save_every_state_index(tmp_path):
    b = toy_branches()[0]
    keep = np.array([0, 3, 6, 8])
    b.states = b.states[keep]
    b.state_index = keep
    io.write(tmp_path / "s.h5", [b], y=Y, profiles=profiles)
    (got,), meta = io.load(tmp_path / "s.h5")
    assert_same_branch(b, got)
    np.testing.assert_array_equal(got.state(6), b.states[2])
    # profiles are indexed by point along the branch, not by row of `states`
    np.testing.assert_array_equal(meta["profiles"]["0"]["index"], keep)


def test_broken_profile_function_does_not_lose_the_run(tmp_path, caplog):
    def bad(u):
        raise ZeroDivisionError("profile bug")

    io.write(tmp_path / "r.h5", toy_branches(), y=Y, profiles=bad)
    branches, meta = io.load(tmp_path / "r.h5")
    assert len(branches) == 3 and meta["profiles"] == {} and meta["complete"]
    assert "profile bug" in caplog.text


def test_write_of_a_stopped_result_is_incomplete_with_its_reason(tmp_path):
    """``io.write(..., stopped=REASON)``: a partial result (``contin continue`` cut short by Ctrl-C)
    is published with complete=False and the reason, as a run's writer leaves a stopped run; the
    branches are the same as in a complete write, and no lock is left behind."""
    branches = rich_branches()
    done, part = tmp_path / "done.h5", tmp_path / "part.h5"
    io.write(done, branches, scene="toy")
    io.write(part, branches, scene="toy", stopped="interrupted")
    (b_done, m_done), (b_part, m_part) = io.load(done), io.load(part)
    assert m_done["complete"] is True and m_done["stopped"] == ""
    assert m_part["complete"] is False and m_part["stopped"] == "interrupted"
    for a, b in zip(b_done, b_part, strict=True):
        assert_same_branch(a, b)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["done.h5", "part.h5"]


def test_files_record_the_library_versions(tmp_path):
    """Bitwise reproduction of a file needs the same numpy/scipy (numba) builds: the file says which."""
    import platform

    import scipy

    io.write(tmp_path / "run.h5", rich_branches(), scene="toy", parameters={"a": 2.5})
    with h5py.File(tmp_path / "run.h5", "r") as f:
        libs = json.loads(f.attrs["libraries"])
    assert libs["numpy"] == np.__version__ and libs["scipy"] == scipy.__version__
    assert libs["python"] == platform.python_version() and libs["h5py"] == h5py.__version__
    _, meta = io.load(tmp_path / "run.h5")
    assert meta["libraries"] == libs
