"""Robustness sweep 4 (session 18, qa18): interrupted `contin continue` and `gravity-phase` runs,
then what a demanding user tried on every command.

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

import numpy as np
import pytest

from contin import io

from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)


# ----------------------------------------------------------------------------- gravity-phase
PHASE = ["trace", "gravity-phase", "-s", "H_max=45", "--grid", "24", "--no-stability", "-q"]


def test_gravity_phase_stores_each_fold_curve_and_resume_reuses_it(tmp_path, monkeypatch):
    """`contin trace gravity-phase -o F` passed its fold curves to the file only at the end: a run
    stopped at once (second Ctrl-C, SIGKILL) while the second pitchfork's curve was traced kept
    nothing of the first (~30 s at the default grid), and `--resume F` traced every curve again.
    Now each curve is stored when it is finished and --resume reuses it: only fold1 is traced."""
    import problems.couette.gravity as gravity

    traced: list[int] = []
    original = gravity._bp_fold_curves

    def killed_at_fold1(problem, source, params, base, kids, k, *args, **kwargs):
        traced.append(k)
        if k == 1 and len(traced) == 2:
            raise KeyboardInterrupt  # stopped at once while the second curve is traced
        return original(problem, source, params, base, kids, k, *args, **kwargs)

    monkeypatch.setattr(gravity, "_bp_fold_curves", killed_at_fold1)
    out = tmp_path / "phase.h5"
    res = run([*PHASE, "-o", str(out)])
    assert res.exit_code == 130 and traced == [0, 1], res.stderr
    (kept,), meta = io.load(out)
    assert kept.id == "fold0" and meta["complete"] is False and meta["stopped"] == "interrupted"
    res = run([*PHASE, "--resume", str(out)])
    assert res.exit_code == 3 and traced == [0, 1, 1], res.stderr  # fold0 reused, not traced again
    (fold0, fold1), meta = io.load(out)
    assert meta["complete"] is True and np.array_equal(fold0.states, kept.states)
    # each curve passes through its pitchfork (cusp at G = 0): H_n^c = n pi psi, so H_3^c = 3 H_1^c
    (cp0,), (cp1,) = fold0.points("CP"), fold1.points("CP")
    assert cp1.params["H"] == pytest.approx(3 * cp0.params["H"], rel=1e-6)
