"""contin.diagram / contin.seeds / contin.jumps / contin.overlap on non-granular problems:
Allen-Cahn (BPs at k^2, u -> -u), 1-D Swift-Hohenberg (BifurcationKit's automatic-diagram
tutorial; BPs of u = 0 at (1 - m_k)^2), a detached isola with a closed form, Bratu."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from contin.branch import Branch
from contin.continuation import join, trace, trace_both
from contin.diagram import DiagramHooks, DiagramSettings, bifurcation_diagram
from contin.foldcurve import trace_fold_curve
from contin.jumps import halved, jumped, restep, retrace_on_jumps, trace_both_ways, trim_self_overlap
from contin.options import ContinuationOptions, StepOptions
from contin.overlap import StateCoordinates, deduplicate, lies_on, mirror_branch, near, params_at
from contin.seeds import Seed, discover, fold_seeds, homotopy, homotopy_seeds, off_fold
from problems.demo import AllenCahn, Bratu, DetachedIsola
from problems.swift_hohenberg import SwiftHohenberg

AC_OPTS = ContinuationOptions(bounds={"lam": (0.0, 10.0)}, max_steps=200, step=StepOptions(ds=0.1, ds_max=0.5))
SH_START = {"lam": -0.7, "nu": 2.0}
SH_OPTS = ContinuationOptions(bounds={"lam": (-1.0, 1.0)}, max_steps=1000,
                              step=StepOptions(ds=0.01, ds_max=0.02, max_angle=0.3))
ISOLA_OPTS = ContinuationOptions(bounds={"lam": (-3.0, 3.0)}, max_steps=500, step=StepOptions(ds=0.02, ds_max=0.1))


def duplicated_pairs(branches: list[Branch], tol: float = 1e-3, fraction: float = 0.9) -> list[tuple[str, str]]:
    """Pairs (a, b) such that >= fraction of a's points lie within tol of b's polyline in
    (u / sqrt(n), lam) (the full states: independent of the diagram's projected coordinates)."""

    def pts(b: Branch) -> np.ndarray:
        return np.column_stack([b.states / np.sqrt(b.states.shape[1]), b.params["lam"]])

    def dist(points: np.ndarray, line: np.ndarray) -> np.ndarray:
        if len(line) == 1:
            return np.linalg.norm(points - line[0], axis=1)
        a, d = line[:-1], np.diff(line, axis=0)
        dd = np.maximum(np.sum(d * d, axis=1), 1e-300)
        out = []
        for c in range(0, len(points), 8):
            p = points[c: c + 8]
            t = np.clip(np.einsum("psk,sk->ps", p[:, None, :] - a[None], d) / dd, 0.0, 1.0)
            out.append(np.min(np.linalg.norm(p[:, None, :] - a[None] - t[..., None] * d[None], axis=2), axis=1))
        return np.concatenate(out)

    out = []
    for a in branches:
        for b in branches:
            if a is b:
                continue
            pa, pb_ = pts(a), pts(b)
            probe = pa[np.linspace(0, len(pa) - 1, min(20, len(pa))).astype(int)]
            if np.sum(dist(probe, pb_) > tol) > 3:  # more than 15 % of a spread sample off: no
                continue
            if np.mean(dist(pa, pb_) <= tol) >= fraction:
                out.append((a.id, b.id))
    return out


# ----------------------------------------------------------------------------- Allen-Cahn
@pytest.fixture(scope="module")
def allen_cahn():
    pb = AllenCahn("cheb", 32)
    return pb, bifurcation_diagram(pb, pb.initial(), {"lam": 0.0}, "lam", AC_OPTS, DiagramSettings(depth=3))


def test_allen_cahn_each_mode_traced_once_its_negative_mirrored(allen_cahn):
    """u = 0 has BPs at lam = k^2 (k = 1, 2, 3 below 10); each pitchfork's second half is -u of
    the first (u -> -u), so the diagram traces 3 branches and mirrors 3, none twice."""
    pb, d = allen_cahn
    root = d.branch("0")
    assert [bp.params["lam"] for bp in root.branch_points] == pytest.approx([1.0, 4.0, 9.0], abs=1e-8)
    assert len(d.traced) == 4 and len(d.branches) == 7
    assert sorted(d.mirrors.values()) == sorted(b.id for b in d.traced if b.id != "0")
    # the second direction of each symmetry-breaking BP of u = 0 is the stored image: not even probed
    assert sum("(symmetry-breaking BP of an invariant branch)" in s for s in d.skipped) == 3
    assert not any("probe" in s for s in d.skipped)
    for mid, tid in d.mirrors.items():
        m, t = d.branch(mid), d.branch(tid)
        assert np.array_equal(m.states, -t.states) and np.array_equal(m.params["lam"], t.params["lam"])
        assert m.observables["phi"] == pytest.approx(-t.observables["phi"], abs=1e-14)
        for j in (1, len(m) // 2, len(m) - 1):
            assert np.max(np.abs(pb.residual(m.states[j], {"lam": m.params["lam"][j]}))) < 1e-9
    assert not duplicated_pairs(d.branches)
    assert {d.level[b.id] for b in d.branches} == {1, 2}


def test_allen_cahn_depth_one_is_the_start_branch_only():
    pb = AllenCahn("cheb", 32)
    d = bifurcation_diagram(pb, pb.initial(), {"lam": 0.0}, "lam", AC_OPTS, DiagramSettings(depth=1))
    assert [b.id for b in d.branches] == ["0"] and len(d.branch("0").branch_points) == 3


def test_allen_cahn_max_branches_and_no_mirror():
    """max_branches stops the switching (and says so); mirror=False traces both halves of each
    pitchfork instead of reflecting (the -1 half is then new: -u is not yet known)."""
    pb = AllenCahn("cheb", 32)
    few = bifurcation_diagram(pb, pb.initial(), {"lam": 0.0}, "lam", AC_OPTS, DiagramSettings(depth=2, max_branches=3))
    assert len(few.branches) == 3 and any("max_branches = 3 reached" in s for s in few.skipped)
    plain = bifurcation_diagram(pb, pb.initial(), {"lam": 0.0}, "lam", AC_OPTS, DiagramSettings(depth=2, mirror=False))
    assert len(plain.traced) == 7 and not plain.mirrors
    assert not duplicated_pairs(plain.branches)
    for b in plain.branches[1:]:
        twin = next(t for t in plain.branches[1:] if t is not b and t.parent == b.parent)
        assert np.max(np.abs(twin.states[-1] + b.states[-1])) < 1e-6  # the two halves are u and -u


def test_diagram_settings_reject_bad_values():
    with pytest.raises(ValueError, match="depth"):
        DiagramSettings(depth=0)
    with pytest.raises(ValueError, match="tol"):
        DiagramSettings(tol=0.0)


# ----------------------------------------------------------------------------- Swift-Hohenberg
def test_swift_hohenberg_jacobian_and_trivial_branch_points():
    """Exact sparse Jacobian against central differences; the BPs of u = 0 at (1 - m_k)^2,
    m_k = (4/h^2) sin^2(k pi / (2(N+1))) computed here from the tridiagonal Laplacian's
    eigenvalues by scipy."""
    import scipy.linalg as la

    pb = SwiftHohenberg(60, 6.0)
    rng = np.random.default_rng(3)
    u = 0.4 * rng.standard_normal(60)
    p = {"lam": 0.3, "nu": 2.0}
    J = pb.jacobian(u, p).toarray()
    h = 1e-6
    fd = np.column_stack([(pb.residual(u + h * e, p) - pb.residual(u - h * e, p)) / (2 * h) for e in np.eye(60)])
    assert np.max(np.abs(J - fd)) <= 1e-6 * np.max(np.abs(J))
    assert pb.dresidual_dp(u, p, "nu") == pytest.approx((pb.residual(u, {**p, "nu": 2.0 + h})
                                                         - pb.residual(u, {**p, "nu": 2.0 - h})) / (2 * h), abs=1e-6)
    m = la.eigh_tridiagonal(2 * np.ones(60) / pb.h**2, -np.ones(59) / pb.h**2, eigvals_only=True)
    assert pb.trivial_branch_points(-1, 1) == pytest.approx(np.sort([(1 - v) ** 2 for v in m if (1 - v) ** 2 < 1]),
                                                           rel=1e-12)
    assert np.array_equal(pb.residual(-u, p), -pb.residual(u, p))


@pytest.fixture(scope="module")
def sh_depth2():
    pb = SwiftHohenberg()
    return pb, bifurcation_diagram(pb, np.zeros(pb.N), SH_START, "lam", SH_OPTS, DiagramSettings(depth=2))


@pytest.mark.slow
def test_swift_hohenberg_depth2_no_duplicates_mirrors_solve(sh_depth2):
    """BifurcationKit's tutorial problem: the 5 BPs of u = 0 in (-1, 1) at their closed form,
    one traced branch per BP (the other half is its mirror -u), no two branches the same
    solution set, every mirrored state a solution."""
    pb, d = sh_depth2
    root = d.branch("0")
    lam_k = pb.trivial_branch_points(-1.0, 1.0)
    assert len(lam_k) == 5
    assert [bp.params["lam"] for bp in root.branch_points] == pytest.approx(lam_k, abs=1e-8)
    level2 = [b for b in d.traced if d.level[b.id] == 2]
    assert len(level2) == 5 and len(d.mirrors) == 5
    assert not duplicated_pairs(d.branches)
    for mid, tid in d.mirrors.items():
        m = d.branch(mid)
        assert np.array_equal(m.states, -d.branch(tid).states)
        for j in (1, len(m) // 2, len(m) - 1):
            assert np.max(np.abs(pb.residual(m.states[j], {**SH_START, "lam": m.params["lam"][j]}))) < 1e-8


@pytest.mark.slow
def test_swift_hohenberg_depth3_no_duplicates():
    """Depth 3 (BifurcationKit's level 3): every branch a solution set of its own, each traced
    branch's points solve F, fewer traced than found (mirrors), known crossings skipped."""
    pb = SwiftHohenberg()
    d = bifurcation_diagram(pb, np.zeros(pb.N), SH_START, "lam", SH_OPTS, DiagramSettings(depth=3))
    assert not duplicated_pairs(d.branches)
    assert max(d.level.values()) == 3
    assert len(d.traced) < len(d.branches)
    assert any("passes through it" in s for s in d.skipped)
    for b in d.branches:
        for j in (0, len(b) // 2, len(b) - 1):
            assert np.max(np.abs(pb.residual(b.states[j], {**SH_START, "lam": b.params["lam"][j]}))) < 1e-7


# ----------------------------------------------------------------------------- isola seeds
@pytest.fixture(scope="module")
def isola_family():
    """At mu = 5 the circle (x - 2)^2 + lam^2 = mu crosses x = 0 at lam = +-1: switched onto."""
    pb = DetachedIsola()
    d5 = bifurcation_diagram(pb, np.zeros(1), {"lam": -3.0, "mu": 5.0}, "lam", ISOLA_OPTS, DiagramSettings(depth=2))
    return pb, d5


def test_detached_isola_switching_at_mu5(isola_family):
    pb, d5 = isola_family
    root = d5.branch("0")
    assert [bp.params["lam"] for bp in root.branch_points] == pytest.approx([-1.0, 1.0], abs=1e-8)
    circle = [b for b in d5.branches if b.id != "0"]
    assert len(circle) == 1 and circle[0].closed
    x, lam = circle[0].states[:, 0], circle[0].params["lam"]
    assert np.max(np.abs((x - 2) ** 2 + lam**2 - 5.0)) < 1e-9
    assert any("passes through it" in s for s in d5.skipped)  # the second crossing is the same circle


def _homotopy_seed(pb, d5, mu: float) -> Seed:
    circle = next(b for b in d5.branches if b.id != "0")
    i = int(np.argmax(circle.states[:, 0]))  # the top of the circle, x = 2 + sqrt(5 - lam^2)
    p = params_at(circle, i)
    hopts = ContinuationOptions(bounds={"mu": (mu, 5.0)}, max_steps=200, step=StepOptions(ds=0.05, ds_max=0.2))
    x = homotopy(pb, circle.state(i), p, "mu", mu, hopts)
    assert x is not None
    return Seed("homotopy in mu from the top of the mu = 5 circle", x, {**p, "mu": mu}, "homotopy")


def test_isola_found_by_a_homotopy_seed(isola_family):
    """mu = 1: x = 0 has no BP, so switching alone finds nothing else; a homotopy in mu from
    the mu = 5 circle lands on the isola, which is traced closed with its folds at
    lam = +-sqrt(mu) = +-1, x = 2 (closed form)."""
    pb, d5 = isola_family
    alone = bifurcation_diagram(pb, np.zeros(1), {"lam": -3.0, "mu": 1.0}, "lam", ISOLA_OPTS, DiagramSettings(depth=3))
    assert [b.id for b in alone.branches] == ["0"]
    seed = _homotopy_seed(pb, d5, 1.0)
    assert seed.state[0] == pytest.approx(2.0 + math.sqrt(1.0 - seed.params["lam"] ** 2), abs=1e-9)
    d = bifurcation_diagram(pb, np.zeros(1), {"lam": -3.0, "mu": 1.0}, "lam", ISOLA_OPTS, DiagramSettings(depth=3),
                            seeds=[seed])
    assert [b.id for b in d.branches] == ["0", "s0"]
    isola = d.branch("s0")
    assert isola.closed
    x, lam = isola.states[:, 0], isola.params["lam"]
    assert np.max(np.abs((x - 2) ** 2 + lam**2 - 1.0)) < 1e-9
    lps = sorted(isola.fold_points, key=lambda s: s.params["lam"])
    assert [lp.params["lam"] for lp in lps] == pytest.approx([-1.0, 1.0], abs=1e-8)
    assert [lp.order_parameter for lp in lps] == pytest.approx([2.0, 2.0], abs=1e-6)
    # a seed on a known branch is not traced again
    again = bifurcation_diagram(pb, np.zeros(1), {"lam": -3.0, "mu": 1.0}, "lam", ISOLA_OPTS,
                                DiagramSettings(depth=1), seeds=[seed, seed])
    assert [b.id for b in again.branches] == ["0", "s0"] and "on known branch s0" in again.skipped[0]


def test_isola_found_by_both_routes_discover(isola_family):
    """The second route: the fold curve lam^2 = mu (from a fold of the mu = 5 circle) crosses
    mu = 1 at lam = +-1; discover() traces the homotopy seed, finds both fold seeds on it and
    credits both routes to one closed isola."""
    pb, d5 = isola_family
    circle = next(b for b in d5.branches if b.id != "0")
    lp = max(circle.fold_points, key=lambda s: s.params["lam"])
    assert lp.params["lam"] == pytest.approx(math.sqrt(5.0), abs=1e-8)
    curve = trace_fold_curve(pb, lp, "mu", ContinuationOptions(bounds={"lam": (-3.0, 3.0)}, max_steps=200,
                                                               step=StepOptions(ds=0.05, ds_max=0.2)), parameter="lam")
    assert np.max(np.abs(curve.params["lam"] ** 2 - curve.params["mu"])) < 1e-8
    fseeds = fold_seeds(pb, [curve], "mu", 1.0, "lam", (-3.0, 3.0))
    assert sorted(s.params["lam"] for s in fseeds) == pytest.approx([-1.0, 1.0], abs=1e-10)
    coords = StateCoordinates("lam")
    seeds = [_homotopy_seed(pb, d5, 1.0), *fseeds]
    found = discover(pb, seeds, lambda s, bid: trace_both_ways(pb, s.state, s.params, "lam", ISOLA_OPTS,
                                                               coordinates=coords, branch_id=bid),
                     coords, prepare=lambda s: off_fold(pb, s, "lam", ISOLA_OPTS) if s.route == "fold-curve" else s)
    assert [b.id for b in found.branches] == ["0"] and found.branches[0].closed
    assert found.found_by == {"0": ["homotopy", "fold-curve"]}
    assert sum("on known branch 0" in n for n in found.notes) == 2


def test_homotopy_seeds_skip_values_outside_and_fail_past_a_fold(isola_family):
    """homotopy_seeds: only values inside the branch's range; a homotopy that meets a fold in
    mu (x = 2 +- sqrt(mu - lam^2) ends at mu = lam^2) returns None instead of a wrong state."""
    pb, d5 = isola_family
    circle = next(b for b in d5.branches if b.id != "0")
    hopts = ContinuationOptions(bounds={"mu": (0.1, 5.0)}, max_steps=400, step=StepOptions(ds=0.05, ds_max=0.2))
    assert homotopy_seeds(pb, [circle], "mu", 1.0, [10.0], hopts) == []
    i = int(np.argmin(np.abs(circle.params["lam"] - 2.0)))
    assert homotopy(pb, circle.state(i), params_at(circle, i), "mu", 0.1, hopts) is None


# ----------------------------------------------------------------------------- bookkeeping
@pytest.fixture(scope="module")
def bratu():
    pb = Bratu("cheb", 24)
    opts = ContinuationOptions(bounds={"lam": (0.0, 3.6)}, max_steps=300, step=StepOptions(ds=0.05, ds_max=0.1))
    a = trace(pb, np.zeros(pb.n), {"lam": 0.0}, "lam", opts, branch_id="a")
    return pb, opts, a


def test_lies_on_deduplicate_near(bratu):
    """A piece of the Bratu branch traced again from one of its points is the same solution set."""
    pb, opts, a = bratu
    coords = StateCoordinates("lam")
    i = int(np.argmin(np.abs(a.params["lam"][: len(a) // 2] - 2.0)))
    b = trace(pb, a.state(i), params_at(a, i), "lam", ContinuationOptions(bounds={"lam": (0.5, 3.0)}, max_steps=30,
                                                                        step=StepOptions(ds=0.05, ds_max=0.1)),
              branch_id="b")
    assert lies_on(b, a, coords) and not lies_on(a, b, coords)
    kept, dropped = deduplicate([b, a], coords)
    assert [k.id for k in kept] == ["a"] and dropped == [("b", "a")]
    assert near(pb, a.state(i), params_at(a, i), a, coords)
    assert not near(pb, a.state(i) + 0.1, params_at(a, i), a, coords)


def test_trim_self_overlap_and_jumped(bratu):
    """The Bratu branch joined with itself comes back along its own earlier part: cut there,
    and the cut branch counts as jumped; the branch alone is untouched."""
    pb, opts, a = bratu
    coords = StateCoordinates("lam")
    assert trim_self_overlap(a, coords, excursion=0.5) is a and not jumped(a)
    twice = join(a, a)
    n = len(a)
    cut = trim_self_overlap(twice, coords, excursion=0.5)
    assert n < len(cut) < 2 * n - 1
    assert "own earlier part" in cut.message and jumped(cut)
    # the same fold met twice is a jump too
    assert len(twice.fold_points) == 2 and jumped(twice)


def test_restep_continues_from_before_the_overlap_and_leaves_none(bratu):
    """A run that comes back along itself is re-stepped from a few points before the cut with
    half the largest step; the part before is kept as it was, every re-stepped point solves F,
    and the result no longer comes back along itself."""
    pb, opts, a = bratu
    coords = StateCoordinates("lam")
    twice = join(a, a)
    cut = trim_self_overlap(twice, coords, excursion=0.5)
    out = restep(pb, twice, {"lam": 0.0}, opts, coords, excursion=0.5)
    assert "re-stepped from lam" in out.message
    k = len(cut) - 4
    assert np.array_equal(out.states[: k + 1], twice.states[: k + 1])
    assert np.all(out.ds[k + 1:] <= 0.055)  # re-stepped with ds_max = 0.1 / 2
    for j in range(k, len(out)):
        assert np.max(np.abs(pb.residual(out.states[j], {"lam": out.params["lam"][j]}))) < 1e-9
    assert trim_self_overlap(out, coords, excursion=0.5) is out
    assert restep(pb, a, {"lam": 0.0}, opts, coords, excursion=0.5) is a  # nothing to repair


def test_retrace_on_jumps_halves_ds_max_until_no_jump():
    """run(options) is repeated with ds_max halved while jumped() gives a reason; the audit says so."""
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 1.0)}, max_steps=50, step=StepOptions(ds=0.4, ds_max=0.4))
    seen = []

    def run(o):
        seen.append(o.step.ds_max)
        return trace(pb, np.zeros(pb.n), {"lam": 0.0}, "lam", o)

    b = retrace_on_jumps(run, opts, what="test", jumped=lambda br: "too long" if seen[-1] > 0.15 else None)
    assert seen == [0.4, 0.2, 0.1]
    assert "re-traced with ds_max = 0.1" in b.audit[-1] and "too long" in b.audit[-1]
    h = halved(opts)
    assert h.step.ds_max == 0.2 and h.step.ds == 0.2 and h.max_steps == 100


def test_trace_both_ways_matches_trace_both_without_jumps(bratu):
    pb, opts, a = bratu
    i = len(a) // 2
    coords = StateCoordinates("lam")
    one = trace_both_ways(pb, a.state(i), params_at(a, i), "lam", opts, coordinates=coords, restep="local")
    two = trace_both(pb, a.state(i), params_at(a, i), "lam", opts)
    assert np.array_equal(one.params["lam"], two.params["lam"])
    with pytest.raises(ValueError, match="restep"):
        trace_both_ways(pb, a.state(i), params_at(a, i), "lam", opts, restep="sometimes")


def test_mirror_branch_needs_a_symmetry(bratu):
    pb, _, a = bratu

    class NoSym:
        parameter_names = ("lam",)

    with pytest.raises(ValueError, match="symmetry"):
        mirror_branch(NoSym(), a, {"lam": 0.0}, "m")


def test_hooks_select_name_reuse_and_retrace_on_allen_cahn():
    """DiagramHooks on Allen-Cahn (what the gPCF pitchfork scene uses): switch only at the BP
    of mode 2 (lam = 4) under the name 'm2', its image named 'm2.2', the start branch one way from
    the lower bound, no probe; finish() sees traced branches only, on_branch() every stored
    branch with its source; a jumped() report re-traces with ds_max halved; a second run with
    completed= reuses every branch (no trace: the same objects come back)."""
    pb = AllenCahn("cheb", 24)
    finished, stored, asked = [], [], []

    def switch_at(b, bp):
        return "m2" if b.id == "0" and abs(bp.params["lam"] - 4.0) < 0.1 else None

    def jumped(parent, child):
        asked.append(child.id)
        return "test: first trace refused" if len(asked) == 1 else None

    hooks = DiagramHooks(switch_at=switch_at, mirror_id=lambda i: i[:-2] + ".2" if i.endswith(".1") else i + "'",
                         jumped=jumped, finish=lambda b: finished.append(b.id),
                         on_branch=lambda b, src: stored.append((b.id, None if src is None else src.id)))
    settings = DiagramSettings(depth=2, probe_steps=0, start_direction=1, retraces=2)
    d = bifurcation_diagram(pb, pb.initial(), {"lam": 0.0}, "lam", AC_OPTS, settings, hooks=hooks)
    assert [b.id for b in d.branches] == ["0", "m2.1", "m2.2"]
    assert stored == [("0", None), ("m2.1", None), ("m2.2", "m2.1")] and finished == ["0", "m2.1"]
    assert d.branch("0").params["lam"][0] == 0.0 and np.all(np.diff(d.branch("0").params["lam"]) > 0)
    assert [bp.params["lam"] for bp in d.branch("0").branch_points] == pytest.approx([1.0, 4.0, 9.0], abs=1e-8)
    m21 = d.branch("m2.1")
    assert m21.params["lam"][0] == pytest.approx(4.0, abs=1e-6) and "@0" in m21.parent
    assert any("re-traced with ds_max = 0.25" in a for a in m21.audit) and asked == ["m2.1", "m2.1"]
    assert np.array_equal(d.branch("m2.2").states, -m21.states)
    assert sum("not selected" in s for s in d.skipped) == 2
    assert any("m2.2: the image m2.2 of m2.1" in s for s in d.skipped)
    # resume: every branch given back, nothing traced (finish is not called on reused branches)
    finished.clear()
    again = bifurcation_diagram(pb, pb.initial(), {"lam": 0.0}, "lam", AC_OPTS, settings,
                                hooks=replace(hooks, completed={b.id: b for b in d.branches}))
    assert [b.id for b in again.branches] == ["0", "m2.1", "m2.2"] and finished == []
    assert all(a is b for a, b in zip(again.branches, d.branches))


def test_mirror_of_an_adaptive_branch_reflects_each_point_on_its_grid():
    """contin.overlap.mirror_branch on a branch whose points lie on several grids (adaptive run)."""
    from contin.options import AdaptOptions

    pb = AllenCahn("cheb", 16)
    opts = replace(AC_OPTS, adapt=AdaptOptions(tol=1e-10))
    base = trace(pb, pb.initial(), {"lam": 0.0}, "lam", replace(opts, bounds={"lam": (0.0, 2.0)}))
    from contin.continuation import switch

    kid = switch(pb, base, base.branch_points[0], replace(opts, bounds={"lam": (0.0, 8.0)}), directions=(1,))[0]
    if kid.sizes is None:
        pytest.skip("the adaptive run kept one grid")
    m = mirror_branch(pb, kid, {"lam": 0.0}, "img")
    assert m.sizes is not None and np.array_equal(m.sizes, kid.sizes)
    for i in (0, len(kid) // 2, len(kid) - 1):
        assert np.array_equal(m.state(i), -kid.state(i))
    assert m.observables["phi"] == pytest.approx(-kid.observables["phi"], abs=1e-14)
