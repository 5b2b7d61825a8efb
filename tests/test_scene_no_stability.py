"""``Scene.stability = False`` and the problem factories of the disks and non-local scenes.

- the flag on a demo scene (``stretched-bratu`` with ``stability=False``, tests/
  stability_flag_fixture_scenes.py): ``contin trace`` runs no post-run stability pass (no
  stability columns, one ``note:`` line; ``-q`` silent), ``contin stability`` refuses its file
  with one ``Error:`` line, while the unflagged scene still gets its pass;
- disks-steady and nonlocal-shear (small runs through the CLI): ``contin verify`` exits 0 with
  every point checked, ``contin stability --point 0`` exits 1 with one ``Error:`` line, and the
  factory rebuilds a problem whose residual at every stored state is at Newton-tolerance level
  (measured: 2.9e-13 and 1.2e-12; NewtonOptions.tol = 1e-10); the same for nonlocal-cylinder
  with report_eqs=1 (rounding of its third-order rows: 2.7e-9);
- files whose branches come from several problems (disks-pitchfork corr=all,
  nonlocal-cylinder report_eqs=0) or no factory (nonlocal-muI) are refused in one line.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from contin import io
from contin.adapt import on_grid
from contin.cli import main
from contin.restart import rebuild_problem

HERE = Path(__file__).parent


def run(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def one_error_line(result, expect: str) -> None:
    assert result.exit_code == 1, (result.exit_code, result.output)
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and expect in lines[0], result.stderr
    assert "Traceback" not in result.output and result.stdout == ""


def max_residual(path: Path) -> float:
    """Largest residual max-norm of the file's stored states in its rebuilt problem (each on its grid)."""
    branches, meta = io.load(path)
    problem = rebuild_problem({**meta, "path": str(path)})
    fixed = {k: v for k, v in meta["parameters"].items() if isinstance(v, int | float) and not isinstance(v, bool)}
    worst = 0.0
    for b in branches:
        for i in range(len(b)):
            p = {**fixed, **{k: float(v[i]) for k, v in b.params.items()}}
            worst = max(worst, float(np.max(np.abs(on_grid(problem, b.grid_at(i)).residual(b.state(i), p)))))
    return worst


@pytest.fixture
def flagged(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("CONTIN_SCENES", "stability_flag_fixture_scenes:SCENES")


def test_flag_skips_the_pass_and_refuses_stability(flagged, tmp_path):
    out = tmp_path / "nostab.h5"
    r = run("trace", "stretched-bratu-nostab", "-o", out)
    assert r.exit_code == 0, r.output
    notes = [ln for ln in r.stderr.splitlines() if "no linear-stability operator" in ln]
    assert len(notes) == 1 and notes[0].startswith("note: "), r.stderr
    assert "warning: stability" not in r.stderr  # no doubtful pass (M = I) was run
    branches, _ = io.load(out)
    assert branches and all(b.n_unstable is None for b in branches)
    one_error_line(run("stability", out, "--point", "0"), "has no linear-stability operator")
    quiet = run("trace", "stretched-bratu-nostab", "-q", "-o", tmp_path / "q.h5")
    assert quiet.exit_code == 0 and "no linear-stability operator" not in quiet.stderr
    # --kx on such a scene is reported as ignored, never silently dropped
    kx = run("trace", "stretched-bratu-nostab", "-q", "--kx", "0.5", "-o", tmp_path / "kx.h5")
    assert kx.exit_code == 0 and "warning: --kx 0.5 ignored" in kx.stderr
    # the unflagged scene keeps its post-run pass (the flag changes nothing else)
    base = tmp_path / "base.h5"
    assert run("trace", "stretched-bratu", "-q", "-o", base).exit_code == 0
    assert all(b.n_unstable is not None for b in io.load(base)[0])


def test_scene_flag_defaults_true():
    from contin.scene import get_scene

    assert get_scene("bratu").stability is True
    for name in ("disks-pitchfork", "disks-criticality", "savage-rheology", "disks-steady",
                 "nonlocal-shear", "nonlocal-muI", "nonlocal-cylinder"):
        assert get_scene(name).stability is False, name


# residual bound: NewtonOptions.tol = 1e-10 (measured 2.9e-13 disks, 1.2e-12 plane shear); the
# cylinder's third-order u rows on cheb 48 carry rounding ~1e-9 (measured 2.7e-9; the derived
# operator's residual at the same states is 6e-3 to 4: the factory rebuilt the report's problem)
@pytest.mark.parametrize("scene, args, branches, bound", [
    ("disks-steady", ("-s", "H=8"), 1, 1e-10),
    ("nonlocal-shear", ("-s", "ell_min=2.5", "-s", "ell_max=4", "-s", "W_min=30", "-s", "W_max=50",
                        "--max-steps", "6"), 7, 1e-10),
    ("nonlocal-cylinder", ("-s", "report_eqs=1", "--max-steps", "8"), 1, 1e-8),
])
def test_verify_and_factory(tmp_path, scene, args, branches, bound):
    out = tmp_path / f"{scene}.h5"
    r = run("trace", scene, *args, "-o", out)
    assert r.exit_code == 0, r.output
    assert "note: scene" in r.stderr and "no linear-stability operator" in r.stderr
    v = run("verify", out, "--json")
    assert v.exit_code == 0, v.output
    doc = json.loads(v.stdout)
    assert doc["ok"] and len(doc["branches"]) == branches
    stored = {b.id: len(b) for b in io.load(out)[0]}
    for b in doc["branches"]:
        assert b["checked"] == stored[b["branch"]] > 0 and b["max_error"] <= doc["tol"]
    text = run("verify", out)
    assert text.exit_code == 0 and "checked" in text.stdout
    one_error_line(run("stability", out, "--point", "0"), "has no linear-stability operator")
    assert max_residual(out) < bound


def test_files_of_several_problems_are_refused():
    from problems.disks.scenes import pitchfork_factory
    from problems.nonlocal_flow.scenes import cylinder_factory

    disc = {"method": "cheb", "intervals": 16}
    with pytest.raises(ValueError, match="three closures"):
        pitchfork_factory({"corr": "all"}, disc)
    assert pitchfork_factory({"corr": "fv"}, disc).closure.G == "fv"
    with pytest.raises(ValueError, match="two problems"):
        cylinder_factory({"report_eqs": 0.0}, disc)
    assert cylinder_factory({"report_eqs": 1.0}, disc).operator == "report"
    # through the CLI, on the shipped files: one line naming the file
    results = HERE.parent / "results"
    one_error_line(run("verify", results / "disks" / "pitchfork.h5"), "cannot rebuild the problem of")
    one_error_line(run("verify", results / "nonlocal" / "cylinder.h5"), "stores the branches of two problems")
    one_error_line(run("verify", results / "nonlocal" / "muI.h5"), "has no problem_factory")


@pytest.mark.slow
def test_continue_rebuilds_the_disks_problem(tmp_path):
    """contin continue on a disks-pitchfork file (one closure, fixed grid) through its factory: the
    pitchfork followed in e lies on the closed form H_1^c(e) (measured: 1e-9 at e = 0.75, 0.85). ~9 s."""
    from problems.disks.closures import DiskClosure, critical_gaps
    from problems.disks.model import DiskCouetteProblem

    pf, curve = tmp_path / "pf.h5", tmp_path / "curve.h5"
    assert run("trace", "disks-pitchfork", "-s", "corr=cs", "-s", "modes=1", "-s", "banded_steps=4", "--grid", "32",
               "-q", "-o", pf).exit_code == 0
    r = run("continue", pf, "--from", "BP1", "--branch", "cs", "--free", "e", "--bounds", "e=0.75:0.85",
            "--max-steps", "10", "-o", curve)
    assert r.exit_code == 0, r.output
    (branch,), _ = io.load(curve)
    closure = DiskClosure(G="cs")
    pb = DiskCouetteProblem("cheb", 32, closure=closure)
    for sp in branch.special_points:
        p = pb.params({"nu": 0.5, "e": sp.params["e"]})
        assert sp.params["H"] == pytest.approx(critical_gaps(p, closure, 1)[0], rel=1e-8)
