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
