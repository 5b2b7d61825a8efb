"""Branch bookkeeping (reversed, relabel) and the demo scenes."""

import numpy as np
import pytest

from contin.branch import relabel
from contin.continuation import trace
from contin.options import ContinuationOptions, StepOptions
from contin.scene import SceneError, SceneRequest
from problems.demo import BRATU_FOLD, Bratu
from problems.scenes_demo import SCENES


@pytest.fixture(scope="module")
def bratu_branch():
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=25, step=StepOptions(ds=0.1, ds_max=0.4))
    return trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)


def test_reversed_remaps_points_steps_and_special_points(bratu_branch):
    br = bratu_branch
    rv = br.reversed()
    s = len(br)
    assert len(rv) == s
    assert np.array_equal(rv.parameter_values, br.parameter_values[::-1])
    assert np.array_equal(rv.tangents, -br.tangents[::-1])
    # ds[j] is the step into point j: reversed point j is reached by the original step into S-j
    assert rv.ds[0] == 0 and np.array_equal(rv.ds[1:], br.ds[:0:-1])
    lp, rlp = br.fold_points[0], rv.fold_points[0]
    lam = rv.parameter_values
    assert lam[rlp.index] <= rlp.params["lam"] and lam[rlp.index + 1] <= rlp.params["lam"]
    assert rlp.index == s - 2 - lp.index
    assert rv.special_points[0].type == "EP" and rv.special_points[0].index == 0
    back = rv.reversed()
    assert [sp.index for sp in back.special_points] == [sp.index for sp in br.special_points]
    assert np.array_equal(back.ds, br.ds)


def test_relabel_numbers_across_branches(bratu_branch):
    a, b = bratu_branch, bratu_branch.reversed()
    relabel([a, b])
    assert [sp.name for sp in a.special_points] == ["LP1", "EP2"]
    assert [sp.name for sp in b.special_points] == ["EP3", "LP4"]


def test_bratu_scene_reports_fold_and_validates_input():
    seen = []
    result = SCENES["bratu"].run(SceneRequest(on_branch=seen.append))
    (br,) = result.branches
    assert seen == [br]
    assert abs(br.fold_points[0].params["lam"] - BRATU_FOLD) < 1e-9
    assert result.discretization == {"method": "cheb", "intervals": 32}
    assert result.profiles(br.states[3])["u"].shape == result.y.shape
    with pytest.raises(SceneError, match="unknown parameter"):
        SCENES["bratu"].run(SceneRequest(params={"mu": 1}))
    with pytest.raises(SceneError, match="must be a number"):
        SCENES["bratu"].run(SceneRequest(params={"lam_max": "abc"}))
    with pytest.raises(SceneError, match="below the fold"):
        SCENES["bratu"].run(SceneRequest(params={"lam_min": 3.6}))
    with pytest.raises(SceneError, match="unknown discretization"):
        SCENES["bratu"].run(SceneRequest(method="fd3"))


def test_allen_cahn_scene_switches_at_every_bp():
    result = SCENES["allen-cahn"].run(SceneRequest(grid=24, params={"lam_max": 5.0}))
    trivial, *children = result.branches
    assert [round(bp.params["lam"], 8) for bp in trivial.branch_points] == [1.0, 4.0]
    assert len(children) == 4 and all(c.kind == "bifurcated" for c in children)
    assert {c.parent for c in children} == {bp.name + "@0" for bp in trivial.branch_points}
    labels = [sp.label for b in result.branches for sp in b.special_points]
    assert labels == list(range(1, len(labels) + 1))
