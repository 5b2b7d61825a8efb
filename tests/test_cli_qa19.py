"""Robustness sweep 5 (session 19, qa19): extreme gPCF parameters, resumed sweep task files, then the
periodic-orbit paths of session 18 (`continue --from HB1 --cycles`, orbit files fed to every command).

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from contin import io

from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)


# ----------------------------------------------------------------------------- sweep task files
def test_trace_resume_of_a_sweep_task_file_keeps_its_sweep_task(tmp_path):
    """`contin trace bratu --resume TASK.h5` of a file `contin sweep` wrote dropped its root attribute
    `sweep_task` (the writer over it knew only its own attributes): the next `contin sweep` into that
    directory found the task unfinished and computed it again.  io.load now returns the file's other
    root attributes (meta['attrs']) and trace --resume writes them back."""
    import h5py

    toml = tmp_path / "s.toml"
    toml.write_text('[sweep]\nscene = "bratu"\nrecord = ["LP"]\n[grid]\nlam_min = [0.0]\n'
                    '[options]\ngrid = 16\nstability = false\n')
    out = tmp_path / "out"
    assert run(["sweep", str(toml), "-o", str(out), "-j", "1", "-q"]).exit_code == 0
    (task,) = (out / "tasks").glob("*.h5")
    with h5py.File(task, "r") as f:
        before = str(f.attrs["sweep_task"])
    res = run(["trace", "bratu", "--resume", str(task), "-q"])
    assert res.exit_code == 0, res.stderr
    with h5py.File(task, "r") as f:
        assert str(f.attrs["sweep_task"]) == before
    res = run(["sweep", str(toml), "-o", str(out), "-j", "1"])
    assert res.exit_code == 0 and "1 from earlier runs" in res.stderr, res.stderr
    doc = json.loads((out / "summary.json").read_text())
    assert [t["cached"] for t in doc["tasks"]] == [True]


def test_trim_to_new_compares_the_seed_with_the_states_of_its_own_grid():
    """`contin trace gravity -s Fr=1e20` ended 'Error: operands could not be broadcast together with
    shapes (616,901) (1,261)': contin.overlap.trim_to_new looked for the seed (cheb 64, 261 unknowns)
    among the NaN-padded states of a branch that had refined its grid (up to 901 unknowns).  Now the
    seed is compared with the points of its own size: the part of the branch off the known one, from
    the seed on, is kept (one point of overlap)."""
    from contin.branch import Branch, pad_rows
    from contin.overlap import trim_to_new

    class XY:
        def branch(self, b):
            return np.column_stack([b.params["x"], b.observables["phi"]])

        def point(self, problem, u, p):
            return np.array([p["x"]])

    def branch(x, sizes):
        n = len(x)
        states = pad_rows([np.full(k, xi) for xi, k in zip(x, sizes)])
        return Branch(parameter="x", free=("x",), params={"x": np.asarray(x, float)},
                      observables={"phi": np.asarray(x, float)}, states=states,
                      tangents=pad_rows([np.ones(k + 1) for k in sizes]), ds=np.ones(n),
                      newton_iterations=np.zeros(n, np.int64), sizes=np.asarray(sizes),
                      grid=np.asarray(sizes))

    x = np.arange(7.0)
    b = branch(x, [3, 3, 3, 3, 5, 5, 5])  # refined from the seed's grid (3 unknowns) to 5 at x = 4
    known = branch(x[:3], [3, 3, 3])      # the points x = 0, 1, 2 run along a known branch
    out = trim_to_new(b, np.full(3, 3.0), [known], XY(), tol=1e-6)
    assert list(out.params["x"]) == [2.0, 3.0, 4.0, 5.0, 6.0]
    assert np.array_equal(out.state(4), np.full(5, 6.0))
    # a branch with no state of the seed's size is left as it is (nothing to compare)
    c = branch(x, [5] * 7)
    assert trim_to_new(c, np.full(3, 3.0), [known], XY(), tol=1e-6) is c
