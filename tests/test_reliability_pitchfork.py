"""Issue 16: the pitchfork scene names every BP of uniform shear by its mode (H_n^c = n pi psi).

Uniform shear starts below H_1^c whatever H_max is (H_max = 1000 used to start at H = 50, past
H_3^c, and called H_21^c "BP1" and its branch "banded n = 1"), steps never cross two BPs (H_max =
200 skipped modes 4, 6, 7, ...), and the modes it did not find are named in a note.  The
reference is the closed form H_n^c = n pi psi(nu, e) of physics.md section 4, psi computed here
from the closure functions.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from contin.scene import SceneRequest, get_scene
from problems.couette.closures import coefficients


def pi_psi(nu: float, e: float) -> float:
    """pi psi, psi^2 = (f4/f5) / ((f1/f1')(f2'/f2 + f5'/f5) - 2) (physics.md section 4), written out here."""
    c = coefficients(np.float64(nu), e, "jj", 0.65)
    bracket = (c.f1 / c.f1_nu) * (c.f2_nu / c.f2 + c.f5_nu / c.f5) - 2.0
    return math.pi * math.sqrt(float(c.f4 / c.f5 / bracket))


def _run(H_max: float, grid: int):
    return get_scene("pitchfork").run(SceneRequest(params={"nu": 0.3, "e": 0.8, "H_max": H_max, "modes": 1},
                                                   grid=grid, stability=False))


def _modes(res):
    base = next(b for b in res.branches if b.id == "0")
    out = {}
    for bp in base.branch_points:
        m = re.search(r"mode (\d+)", bp.note)
        out[bp.params["H"]] = int(m.group(1)) if m else None
    return out


def test_pitchfork_H_max_200_finds_and_names_every_mode():
    hc = pi_psi(0.3, 0.8)
    res = _run(200.0, 64)
    base = res.branches[0]
    assert base.parameter_values[0] < hc  # starts below H_1^c
    modes = _modes(res)
    assert sorted(modes.values()) == list(range(1, int(200 / hc) + 1))  # 1..15, none skipped
    for H, n in modes.items():
        assert abs(H - n * hc) <= 1e-7 * n * hc
    assert not any("were not found" in n for n in res.notes)
    band = next(b for b in res.branches if b.id == "n1.1")
    assert band.kind == "banded n=1"
    assert abs(band.parameter_values[0] - hc) <= 1e-7 * hc


def test_pitchfork_H_max_1000_starts_below_H1c_and_says_which_modes_are_missing():
    hc = pi_psi(0.3, 0.8)
    res = _run(1000.0, 32)
    base = res.branches[0]
    assert base.parameter_values[0] < hc
    modes = _modes(res)
    first = min(modes)
    assert modes[first] == 1 and abs(first - hc) <= 1e-6 * hc  # "BP1" is H_1^c, not H_21^c
    band = next(b for b in res.branches if b.id == "n1.1")
    assert abs(band.parameter_values[0] - hc) <= 1e-6 * hc
    crit = [r for r in res.extra["criticality"] if r["branch"] == "n1.1"]
    assert crit[0]["n"] == 1 and crit[0]["kind"] == "supercritical"  # nu = 0.3 is supercritical (a ~ 113)
    found = {n for n in modes.values() if n is not None}
    for H, n in modes.items():  # named BPs sit at their n pi psi, the others are said to be off
        if n is not None:
            assert abs(H - n * hc) <= 0.02 * n * hc
        else:
            assert any(f"BP at H = {H:.10g}" in note and "matches no mode" in note for note in res.notes)
    expected = set(range(1, int(1000 / hc) + 1))
    missing = expected - found
    assert missing, "cheb 32 cannot resolve all 76 modes below H = 1000"
    note = next(n for n in res.notes if "were not found on uniform shear" in n)
    assert note.startswith(f"{len(missing)} of the {len(expected)} modes")
    shown = [int(m) for m in re.findall(r"(\d+) \(H = ", note)]
    assert shown == sorted(missing)[:12]


def test_resume_reuses_each_finished_branch_not_only_pairs(monkeypatch):
    """A kill between n2.1 and n2.2 must not retrace n2.1 (README: at most the branch in progress is lost)."""
    import contin.diagram as builder  # the scene switches through the core diagram builder

    req = dict(params={"nu": 0.3, "e": 0.8, "H_max": 30.0, "modes": 2}, grid=32, stability=False)
    full = get_scene("pitchfork").run(SceneRequest(**req))
    by_id = {b.id: b for b in full.branches}
    assert {"0", "n1.1", "n1.2", "n2.1", "n2.2"} <= set(by_id)
    calls = []
    real = builder.switch

    def counting(problem, base, bp, options, directions=(1,), **kw):
        calls.append(tuple(directions))
        return real(problem, base, bp, options, directions=directions, **kw)

    monkeypatch.setattr(builder, "switch", counting)
    done = {k: by_id[k] for k in ("0", "n1.1", "n1.2", "n2.1")}  # killed while tracing n2.2
    again = get_scene("pitchfork").run(SceneRequest(**req, completed=done))
    assert calls == [(-1,)]  # only n2.2 (mode 2 is S-invariant: its second sign is traced, not mirrored)
    out = {b.id: b for b in again.branches}
    for k in done:
        assert out[k] is done[k]
    np.testing.assert_allclose(out["n2.2"].parameter_values, by_id["n2.2"].parameter_values, rtol=1e-10)
