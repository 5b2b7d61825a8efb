"""Robustness sweep 5 (session 19, qa19): extreme gPCF parameters, resumed sweep task files, then the
periodic-orbit paths of session 18 (`continue --from HB1 --cycles`, orbit files fed to every command).

Each test names the command that misbehaved before its fix.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from contin import io

from tests.cli_sweep import one_error, real_scenes, run  # noqa: E402,F401  (real_scenes: autouse)


# ----------------------------------------------------------------------------- extreme gPCF parameters
@pytest.mark.parametrize("args, expect", [
    (["gravity", "-s", "Fr=1e-150"], "parameter Fr = 1e-150 is out of range; scene 'gravity' needs 1e-50 <= Fr <= 1e+50"),
    (["gravity", "-s", "Fr=1e300"], "parameter Fr = 1e+300 is out of range; scene 'gravity' needs 1e-50 <= Fr <= 1e+50"),
    (["gravity", "-s", "Fr=1e154"], "parameter Fr = 1e+154 is out of range; scene 'gravity' needs 1e-50 <= Fr <= 1e+50"),
    (["gravity", "-s", "nu=1e-300"], "parameter nu = 1e-300 is out of range; it must satisfy 1e-06 <= nu < 0.65"),
    (["gravity", "-s", "H_min=1e-300"], "parameter H_min = 1e-300 is out of range; it must satisfy 1e-50 <= H_min <= 1e+50"),
    (["gravity", "-s", "H_max=1e300"], "parameter H_max = 1e+300 is out of range; it must satisfy 1e-50 <= H_max <= 1e+50"),
    (["gravity-phase", "-s", "Fr_start=1e300"], "parameter Fr_start = 1e+300 is out of range; it must satisfy 1e-50"),
    (["gravity-phase", "-s", "Fr_start=1e-150"], "parameter Fr_start = 1e-150 is out of range; it must satisfy 1e-50"),
    (["pitchfork", "-s", "nu=1e-300"], "parameter nu = 1e-300 is out of range; it must satisfy 1e-06 <= nu < 0.65"),
    (["pitchfork", "-s", "nu=1e-50"], "parameter nu = 1e-50 is out of range; it must satisfy 1e-06 <= nu < 0.65"),
    (["pitchfork", "-s", "H=1e-300"], "parameter H = 1e-300 is out of range; it must satisfy 1e-50 <= H <= 1e+50"),
    (["pitchfork", "-s", "H=1e300"], "parameter H = 1e+300 is out of range; it must satisfy 1e-50 <= H <= 1e+50"),
    (["pitchfork", "-s", "H_max=1e300"], "parameter H_max = 1e+300 is out of range; it must satisfy 1e-50 <= H_max"),
])
def test_extreme_gpcf_parameters_are_one_line_naming_the_parameter_and_its_range(args, expect, tmp_path):
    """`contin trace gravity -s Fr=1e-150` (and Fr=1e300) ended 'Error: arithmetic failure (OverflowError:
    Numerical result out of range): a parameter or step is probably out of the model's range', Fr=1e154
    the same with ZeroDivisionError (the G-homotopy's weight 1/G^2), nu=1e-300 a RuntimeWarning and
    'non-finite entries', pitchfork nu=1e-50 'index 51 is out of bounds', H_max=1e300 ran on for
    minutes.  Now problems.couette.params (G <= 1e100, nu >= 1e-6, 1e-50 <= H <= 1e50) and the scenes
    (their homotopy in G needs G >= 1e-100) refuse them before computing, naming the range."""
    out = tmp_path / "x.h5"
    err = one_error(run(["trace", *args, "--no-stability", "-q", "-o", str(out)]))
    assert err.startswith("Error: " + expect), err
    assert not out.exists()


def test_froude_number_conversion_at_the_ends_of_its_range():
    """build_params({'Fr': 1e300}) raised OverflowError (Fr**2): G = Fr^-2 = 1e-600 is 0 in double
    precision; Fr below 1e-50 (G above 1e100) is a ValueError naming Fr and the range."""
    from problems.couette.params import build_params

    assert build_params({"Fr": 1e300})["G"] == 0.0
    assert build_params({"Fr": 1e160})["G"] == pytest.approx(1e-320, rel=1e-3)  # subnormal
    assert build_params({"Fr": 1e-50})["G"] == pytest.approx(1e100, rel=1e-15)
    with pytest.raises(ValueError, match=r"parameter Fr = 1e-150 is out of range; it must satisfy Fr >= 1e-50"):
        build_params({"Fr": 1e-150})
    with pytest.raises(ValueError, match=r"parameter G = 1e\+300 is out of range; it must satisfy 0 <= G <= 1e\+100"):
        build_params({"G": 1e300})


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


# ----------------------------------------------------------------------------- periodic orbits
@pytest.fixture(scope="module")
def ab_file(ab_orbits):
    """AUTO's demo ab in D (two Hopf points, HB1 subcritical at D = 0.16504; tests/conftest.py)."""
    return ab_orbits / "ab.h5"


@pytest.mark.parametrize("amplitude, predicted", [("1e300", "D = -inf"), ("100", "D = -75.")])
def test_a_huge_start_amplitude_is_one_line_naming_the_predicted_parameter(ab_file, tmp_path, amplitude, predicted):
    """`contin continue ab.h5 --from HB1 --cycles --amplitude 1e300` ended 'Error: arithmetic failure
    (OverflowError: Numerical result out of range)' (eps**2 of the normal-form shift) and `--amplitude
    100` 'did not converge: Newton diverged' at D = -75.9: far outside the bounds 0 <= D <= 0.5.  Now
    contin.cycles.start_orbit refuses a first orbit predicted outside the bounds, saying so."""
    out = tmp_path / "o.h5"
    err = one_error(run(["continue", str(ab_file), "--from", "HB1", "--cycles", "--amplitude", amplitude,
                         "-o", str(out)]))
    assert err.startswith(f"Error: the first periodic orbit near HB1 (amplitude {float(amplitude):g}) is predicted at "
                          f"{predicted}"), err
    assert "outside the bounds 0 <= D <= 0.5" in err and "give a smaller amplitude" in err, err
    assert not out.exists()
    # a Hopf point outside the bounds is named as such (no amplitude would help)
    err = one_error(run(["continue", str(ab_file), "--from", "HB1", "--cycles", "--bounds", "D=0.2:0.3", "-o", str(out)]))
    assert err.startswith("Error: HB1 at D = 0.1650420453 lies outside the bounds 0.2 <= D <= 0.3"), err


@pytest.mark.parametrize("failure", ["ENOSPC", "EROFS"])
def test_export_auto_on_a_full_or_read_only_disk_keeps_both_previous_files(ab_orbits, tmp_path, monkeypatch, failure):
    """`contin export ORBITS.h5 --auto orb -d DIR` on a full disk (a 64 kB tmpfs) replaced b.orb and then
    failed on s.orb: a new diagram beside the old solutions, which AUTO would read as one run.  On a
    read-only file system it ended 'Error: Read-only file system: 'DIR/b.orb.tmp'' (the temporary's
    clean-up failed too).  Now contin.atomic.publish_together writes both before renaming either, and
    the line names the file."""
    import errno

    import contin.atomic as atomic

    out = tmp_path / "auto"
    out.mkdir()
    (out / "b.orb").write_text("old b\n")
    (out / "s.orb").write_text("old s\n")
    original = atomic.write_bytes
    code = getattr(errno, failure)

    def fail_on_s(tmp, data):  # the disk fills up (or is read-only) at the second file
        if tmp.name.startswith("s.") or failure == "EROFS":
            raise OSError(code, os.strerror(code), str(tmp))
        original(tmp, data)

    monkeypatch.setattr(atomic, "write_bytes", fail_on_s)
    err = one_error(run(["export", str(ab_orbits / "cyc.h5"), "--auto", "orb", "-d", str(out)]))
    if failure == "ENOSPC":
        assert err == (f"Error: cannot write '{out / 's.orb'}': No space left on device (disk or quota full); "
                       "the previous versions of 'b.orb', 's.orb' are unchanged"), err
    else:
        assert err == f"Error: cannot write '{out / 'b.orb'}': Read-only file system", err
    assert (out / "b.orb").read_text() == "old b\n" and (out / "s.orb").read_text() == "old s\n"
    assert sorted(p.name for p in out.iterdir()) == ["b.orb", "s.orb"]  # no temporary left


def _edited(src: Path, dst: Path, edit) -> Path:
    import shutil

    import h5py

    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        edit(f)
    return dst


def _set_cycles(value):
    def edit(f):
        extra = json.loads(f.attrs["extra"])
        extra["cycles"] = value(extra["cycles"])
        f.attrs["extra"] = json.dumps(extra)
    return edit


def _mesh_reversed(f):
    states = f["branches/0/states"][()]
    states[:, -2:] = states[:, -2:][:, ::-1]  # the last two interior mesh points swapped: not increasing
    del f["branches/0/states"]
    f["branches/0/states"] = states


@pytest.mark.parametrize("edit, expect", [
    (_set_cycles(lambda c: [1, 2]), "attribute extra holds a 'cycles' entry of type list, not the mapping"),
    (_set_cycles(lambda c: {**c, "n": "three"}), "needs whole numbers n >= 1, ncol >= 1 and ntst >= 2, got n = 'three'"),
    (_set_cycles(lambda c: {**c, "ncol": 0}), "needs whole numbers n >= 1, ncol >= 1 and ntst >= 2, got n = 2, ncol = 0"),
    (_set_cycles(lambda c: {**c, "n": 3}), "dataset branches/0/states (row 0) holds 180 entries, which is no orbit of n = 3"),
    (_mesh_reversed, "dataset branches/0/states (row 0) is no orbit: its period must be > 0 and its mesh increase"),
])
@pytest.mark.parametrize("command", [["info"], ["diagram", "-o", "d.png"], ["profiles", "--point", "LPC1", "-o", "p.png"],
                                     ["export", "--auto", "x", "-d", "."],
                                     ["continue", "--from", "LPC1", "--cycles", "-o", "c.h5"]])
def test_an_orbit_file_with_an_edited_collocation_or_mesh_is_a_damaged_file(ab_orbits, tmp_path, monkeypatch, edit,
                                                                              expect, command):
    """A file of orbits whose extra['cycles'] entry was edited ended `contin continue F --from PD1 --cycles`
    with 'internal error (AttributeError: 'list' object has no attribute 'get')', `profiles` and `export`
    with 'invalid literal for int() with base 10' or 'collocation needs NTST >= 2 and NCOL >= 1 (got
    NTST = 260, NCOL = 0)', and `info` and `diagram` showed it (exit 0); a mesh that does not increase
    was drawn by `profiles --point`.  The reader checks the orbits' layout now (contin.filecheck.check_orbits)."""
    monkeypatch.chdir(tmp_path)
    path = _edited(ab_orbits / "cyc.h5", tmp_path / "bad.h5", edit)
    name, *rest = command
    err = one_error(run([name, str(path), *rest]))
    assert err.startswith(f"Error: '{path}' is damaged: ") and expect in err, err


def test_a_ctrl_c_after_the_orbits_are_finished_keeps_them_complete(ab_file, tmp_path, monkeypatch):
    """`contin continue ab.h5 --from HB1 --cycles` + Ctrl-C while the end of the orbits was located or
    their multipliers computed (the last ~2 s of a 6 s run): every orbit was computed, yet the file was
    marked interrupted (complete False) and `contin info` sent the user to compute it again.  A stop
    that cut nothing short (contin.cancel.is_stopped_branch) now leaves the result complete; the note
    says so, and the run still ends as interrupted (exit 130)."""
    import contin.cycles as cycles
    from contin.cancel import request_stop

    original = cycles.finish_branch

    def ctrl_c_in_the_multipliers(*args, **kwargs):
        request_stop()  # the first Ctrl-C arrives while the multipliers are computed
        return original(*args, **kwargs)

    monkeypatch.setattr(cycles, "finish_branch", ctrl_c_in_the_multipliers)
    out = tmp_path / "cyc.h5"
    res = run(["continue", str(ab_file), "--from", "HB1", "--cycles", "--max-steps", "8", "-o", str(out)])
    assert res.exit_code == 130 and one_error(res) == "Error: interrupted (Ctrl-C)", res.stderr
    assert f"note: the orbits (9 points) were finished before the Ctrl-C took effect: saved complete in {out}" in res.stderr
    (orbits,), meta = io.load(out)
    assert meta["complete"] is True and meta["stopped"] == "" and len(orbits) == 9
    assert "maximum number of steps (8) reached" in orbits.message


def test_profiles_at_a_value_between_a_fold_of_cycles_and_its_neighbours(ab_orbits, tmp_path):
    """`contin profiles ORBITS.h5 --at D=0.1616962` said 'no branch of orbits in F reaches D=0.161696'
    (the value rounded): ab's fold of cycles LPC1 lies at D = 0.16169613, its stored neighbours at
    0.16169803 and 0.16169627, so D = 0.1616962 is crossed only between a stored orbit and the fold.
    The located points now take part in the search (contin.orbitprofile.orbit_at); the orbit drawn is
    a periodic solution at that D (checked by integrating the ODE over its period with solve_ivp)."""
    from scipy.integrate import solve_ivp

    from contin.orbitprofile import orbit_at
    from contin.restart import rebuild_problem

    path = ab_orbits / "cyc.h5"
    (branch,), meta = io.load(path)
    lpc = branch.points("LPC")[0]
    k = lpc.index
    near = min(branch.params["D"][k], branch.params["D"][k + 1])
    value = float(lpc.params["D"] + near) / 2
    res = run(["profiles", str(path), "--at", f"D={value!r}", "-o", str(tmp_path / "p.png")])
    assert res.exit_code == 0, res.stderr
    assert f"branch 0: interpolated between stored point {k} and LPC1, corrected by Newton" in res.stderr, res.stderr
    cycles = meta["extra"]["cycles"]
    (orbit,) = orbit_at([branch], "D", value, cycles["n"], cycles["ncol"], rebuild_problem({**meta, "path": str(path)}))
    assert orbit.params["D"] == value and orbit.doubt in ("", None)
    problem = rebuild_problem({**meta, "path": str(path)})
    ode = solve_ivp(lambda t, u: problem.residual(u, orbit.params), (0, orbit.period), orbit.nodes[0],
                    method="DOP853", rtol=1e-11, atol=1e-12)
    assert np.abs(ode.y[:, -1] - orbit.nodes[0]).max() < 1e-6
    # beyond the fold no orbit: one line giving the range the branch covers
    err = one_error(run(["profiles", str(path), "--at", "D=0.1616961", "-o", str(tmp_path / "q.png")]))
    assert err.startswith("Error: no branch of orbits in") and "reaches D=0.1616961 (branch 0: D = 0.1616961303 .. " in err


def test_profiles_at_a_value_between_a_fold_and_the_stored_profiles_next_to_it(tmp_path):
    """`contin profiles br.h5 --at lam=3.5135` (Bratu's fold LP1 at lam* = 3.51383; the stored profiles
    next to it at lam = 3.5112 and 3.5088, every other point being stored) said 'no stored branch of
    br.h5 reaches lam=3.5135' although the branch turns at 3.51383.  The located points' stored
    profiles now take part in the search (contin.io.profiles_at)."""
    path = tmp_path / "br.h5"
    assert run(["trace", "bratu", "-q", "-o", str(path)]).exit_code == 0
    branches, meta = io.load(path)
    (lp,) = branches[0].points("LP")
    assert abs(lp.params["lam"] - 3.513830719125162) < 1e-8  # Jacobsen & Schmitt 2002
    value = 3.5135
    idx = meta["profiles"]["0"]["index"]
    assert not np.any((branches[0].params["lam"][idx] > value))  # no stored profile reaches it
    res = run(["profiles", str(path), "--at", f"lam={value}", "-o", str(tmp_path / "p.png")])
    assert res.exit_code == 0, res.stderr
    assert "branch 0: interpolated between point " in res.stderr and " and LP1 (the first of 2 crossings" in res.stderr
    ((_, how, prof),) = io.profiles_at(branches, meta, "lam", value)
    before = int(how.split()[3])
    row = list(idx).index(before)
    lo, hi = sorted([float(np.max(meta["profiles"]["0"]["u"][row])), float(np.max(meta["special_point_profiles"]["u"][0]))])
    assert lo < float(np.max(prof["u"])) < hi


def test_profiles_of_an_interrupted_file_of_orbits_says_it_is_incomplete(ab_orbits, tmp_path):
    """`contin profiles STOPPED.h5 --at D=0.2` of orbits a Ctrl-C cut short at D = 0.169 said only 'no
    branch of orbits reaches D=0.2', as if the orbits ended there; diagram, export and fit of an
    incomplete file print a warning line (qa18), profiles did not."""
    path = _edited(ab_orbits / "cyc.h5", tmp_path / "stopped.h5",
                   lambda f: (f.attrs.__setitem__("complete", False), f.attrs.__setitem__("stopped", "interrupted")))
    res = run(["profiles", str(path), "--point", "LPC1", "-o", str(tmp_path / "p.png")])
    assert res.exit_code == 0, res.stderr
    assert f"warning: {path} is incomplete (its run was interrupted): its curve ends where it stopped" in res.stderr


def test_steps_below_the_rounding_of_the_values_are_said_to_move_nothing(tmp_path):
    """`contin trace bratu --ds-max 1e-300` stored 61 points within lam = 0 .. 6e-299 (the states the
    same to rounding), 'maximum number of steps (60) reached', exit 0 and no word: the crawl test
    (contin.stall) compares the last steps with the branch's largest, which were all as small.  A
    branch whose largest step is at the rounding of its values (1e-12 of their size) is said to have
    moved nothing."""
    res = run(["trace", "bratu", "--ds-max", "1e-300", "-q", "-o", str(tmp_path / "b.h5")])
    assert ("warning: branch 0: ended at its step cap crawling: its largest step was 0, at the rounding of its "
            "values (of size 1): lam moved 5.98e-299 in 60 steps; give a larger step (--ds/--ds-max)") in res.stderr, res.stderr
    (b,), _ = io.load(tmp_path / "b.h5")
    assert float(np.max(b.params["lam"])) < 1e-290  # it really did not move (Bratu's lam runs to 3.5138)
    res = run(["trace", "bratu", "--ds-max", "1e-6", "--max-steps", "5", "-q", "-o", str(tmp_path / "c.h5")])
    assert "crawling" not in res.stderr, res.stderr  # small steps that do move are not flagged


def test_jj_walls_whose_base_branch_stops_at_its_first_point_is_a_warning_not_a_numpy_error(tmp_path):
    """`contin trace jj-walls -s phi_w=1e-20` (nearly specular walls: the base branch's first step
    fails) ended 'Error: attempt to get argmax of an empty sequence': the note on the base branch's
    steepest stretch took the slope of a one-point branch.  Now the run ends as any branch that stops
    at MX does: its point stored, a warning line, exit 3."""
    out = tmp_path / "j.h5"
    res = run(["trace", "jj-walls", "-s", "phi_w=1e-20", "--no-stability", "-o", str(out)])
    assert res.exit_code == 3 and "Error" not in res.stderr, res.stderr
    assert "warning: branch 0 ended with MX: step failed at H=" in res.stderr
    branches, meta = io.load(out)
    assert meta["complete"] is True and branches[0].status == "MX" and len(branches[0]) == 1


@pytest.mark.parametrize("window", ["1e-300", "1e-5"])
def test_gravity_unfolding_with_a_window_narrower_than_its_first_step_names_the_window(window, tmp_path):
    """`contin trace gravity-unfolding -s window=1e-5` ended 'Error: start value H=13.0687 lies outside its
    bounds (13.0685, 13.0685)' and window=1e-300 'bounds for 'H' must satisfy lo < hi': the branches
    switched at the pitchfork start one step (ds = 0.002) away from it.  Now the line names the window."""
    out = tmp_path / "u.h5"
    err = one_error(run(["trace", "gravity-unfolding", "-s", f"window={window}", "--no-stability", "-q",
                         "-o", str(out)]))
    assert err.startswith(f"Error: window = {float(window):g} is too narrow: the branches switched at BP1 "
                          "(H_c = 13.06852933)") and err.endswith("give window >= 0.002"), err
