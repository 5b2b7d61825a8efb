"""Bratu u'' + lam e^u = 0: fold location (spectral and FD orders), bounds, joining, Jacobians."""

import dataclasses

import numpy as np
import pytest

from contin.branch import relabel
from contin.continuation import trace, trace_both
from contin.options import ContinuationOptions, StepOptions
from contin.problem import check_jacobian
from problems.demo import BRATU_FOLD, AllenCahn, Bratu

OPTS = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=40, step=StepOptions(ds=0.1, ds_max=0.5))


def fold(method, n):
    pb = Bratu(method, n)
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", OPTS)
    (lp,) = br.fold_points
    assert lp.converged
    return lp, br


def exact_lambda(theta):
    """lam(theta) of the exact solution u = -2 ln[cosh((x - 1/2) theta / 2) / cosh(theta / 4)]."""
    return theta**2 / (2 * np.cosh(theta / 4) ** 2)


def test_fold_spectral_within_1e9():
    lp, br = fold("cheb", 32)
    assert abs(lp.params["lam"] - BRATU_FOLD) < 1e-9
    # u(1/2) = 2 ln cosh(theta*/4) at the fold, theta* solving d lam / d theta = 0
    from scipy.optimize import brentq

    th = brentq(lambda t: t * np.tanh(t / 4) - 4, 1, 10)  # d lam / d theta = 0
    assert exact_lambda(th) == pytest.approx(BRATU_FOLD, abs=1e-13)
    assert lp.order_parameter == pytest.approx(2 * np.log(np.cosh(th / 4)), abs=1e-8)
    assert lp.index < len(br) - 1 and lp.tangent is not None and abs(lp.tangent[-1]) < 1e-6
    # the branch turns: lam grows up to the fold and decreases after it
    lam = br.parameter_values
    assert np.all(np.diff(lam[: lp.index + 1]) > 0) and np.all(np.diff(lam[lp.index + 1 :]) < 0)
    assert not br.branch_points  # no BP (symmetric or symmetry-breaking) on the 1-D Bratu branch


def test_branch_points_lie_on_exact_solution_curve():
    pb = Bratu("cheb", 32)
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", OPTS)
    # u(1/2) = 2 ln cosh(theta/4) inverts to theta, which must reproduce lam
    theta = 4 * np.arccosh(np.exp(br.order_parameter / 2))
    good = br.order_parameter < 4  # the upper branch beyond u ~ 4 is under-resolved on 33 nodes
    assert good.sum() > 15
    assert np.max(np.abs(exact_lambda(theta[good]) - br.parameter_values[good])) < 1e-9


@pytest.mark.parametrize(
    "method, grids, nominal",
    [("fd2", (16, 32, 64), 2), ("fd4", (32, 64, 128), 4), ("fd6", (48, 64, 96), 6)],
)
def test_fold_observed_order_of_fd_schemes(method, grids, nominal):
    errors = [abs(fold(method, n)[0].params["lam"] - BRATU_FOLD) for n in grids]
    slope = -np.polyfit(np.log(grids), np.log(errors), 1)[0]
    assert abs(slope - nominal) < 0.2, (errors, slope)


def test_bound_gives_ep_exactly_at_the_bound():
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 2.5)}, step=StepOptions(ds=0.3, ds_max=0.5))
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)
    assert br.status == "EP" and "bound" in br.message
    assert br.parameter_values[-1] == 2.5
    assert np.max(np.abs(pb.residual(br.states[-1], {"lam": 2.5}))) < 1e-10
    ep = br.special_points[-1]
    assert ep.type == "EP" and ep.params["lam"] == 2.5 and ep.index == len(br) - 1


def test_stop_at_first_fold():
    pb = Bratu("cheb", 16)
    full = trace(pb, pb.initial(), {"lam": 0.0}, "lam", OPTS)
    stopped = trace(pb, pb.initial(), {"lam": 0.0}, "lam", dataclasses.replace(OPTS, stop_at=("LP1",)))
    (lp,) = stopped.fold_points
    assert stopped.status == "EP" and stopped.message == "stopped after LP1 (stop_at)"
    assert len(stopped) == lp.index + 2 < len(full)  # ends on the point after the fold
    assert lp.params["lam"] == pytest.approx(full.fold_points[0].params["lam"], abs=1e-12)
    assert np.allclose(stopped.parameter_values, full.parameter_values[: len(stopped)], rtol=0, atol=1e-12)
    for bad in (("LP0",), ("XX1",), ("LP",)):
        with pytest.raises(ValueError, match="stop_at labels"):
            ContinuationOptions(stop_at=bad)


def test_trace_both_joins_halves_through_the_start():
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=30, step=StepOptions(ds=0.1, ds_max=0.3))
    # start on the lower branch at lam = 2: backward reaches lam = 0, forward passes the fold
    br = trace_both(pb, pb.initial(), {"lam": 2.0}, "lam", opts)
    relabel([br])
    types = [sp.type for sp in br.special_points]
    assert types[0] == "EP" and types[-1] == "EP" and types.count("LP") == 1
    assert [sp.label for sp in br.special_points] == list(range(1, len(types) + 1))
    assert br.parameter_values[0] == 0.0
    lam = br.parameter_values
    lp = br.fold_points[0]
    assert abs(lp.params["lam"] - BRATU_FOLD) < 1e-8
    assert np.all(np.diff(lam[: lp.index + 1]) > 0)
    # indices are consistent: the LP lies between its neighbouring points
    assert lam[lp.index] <= lp.params["lam"] and lam[lp.index + 1] <= lp.params["lam"]
    # tangents oriented along the traversal direction, no duplicated start point
    steps = np.diff(np.column_stack([br.states.mean(axis=1), lam]), axis=0)
    assert np.all(np.linalg.norm(steps, axis=1) > 1e-6)
    assert np.all(np.sign(br.tangents[1 : lp.index, -1]) > 0)
    assert len(br.ds) == len(br) and br.ds[0] == 0.0 and np.all(br.ds[1:] > 0)


def test_secant_predictor_and_save_every():
    pb = Bratu("cheb", 16)
    opts = ContinuationOptions(bounds={"lam": (0.0, 4.0)}, max_steps=30, save_every=4,
                               step=StepOptions(ds=0.1, ds_max=0.3, predictor="secant"))
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", opts)
    assert abs(br.fold_points[0].params["lam"] - BRATU_FOLD) < 1e-8
    assert br.state_index is not None and br.states.shape[0] == len(br.state_index) < len(br)
    i = int(br.state_index[2])
    assert np.array_equal(br.state(i), br.states[2])
    with pytest.raises(KeyError):
        br.state(1)


@pytest.mark.parametrize("method", ["cheb", "fd2", "fd4", "fd6"])
def test_jacobians_match_finite_differences(method):
    rng = np.random.default_rng(0)
    for pb in (Bratu(method, 16), AllenCahn(method, 16)):
        u = 0.5 * rng.standard_normal(pb.n)
        chk = check_jacobian(pb, u, {"lam": 2.0}, parameters=("lam",))
        assert chk.relative_error < 1e-8
        assert chk.dp_errors["lam"] < 1e-6


def test_fine_grid_traces_past_the_fold_despite_rounding_floor():
    # fd4 on 2001 nodes: |D2| ~ 1e7 puts the rounding residual near the default tol 1e-10;
    # the corrector must accept the rounding floor rather than end in MX.
    pb = Bratu("fd4", 2000)
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", ContinuationOptions(
        bounds={"lam": (0.0, 4.0)}, max_steps=20, step=StepOptions(ds=0.1, ds_max=0.5)))
    assert br.status == "EP"
    assert abs(br.fold_points[0].params["lam"] - BRATU_FOLD) < 1e-8


@pytest.mark.parametrize("below", [1e-10, 1e-4])
def test_a_user_zero_next_to_the_fold_is_located_on_both_sides(below):
    """A value of lam just below lam* is crossed twice in the step that turns at the fold (p - value
    has one sign at both ends): before session 15 no UZ was reported at all, exit 0.  Now both
    crossings are located, one on each side of the LP, and each state is the closed form's."""
    from scipy.optimize import brentq

    target = BRATU_FOLD - below
    pb = Bratu("cheb", 32)
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", dataclasses.replace(OPTS, user_zeros={"lam": [target]}))
    relabel([br])
    (lp,) = br.fold_points
    uz = br.points("UZ")
    assert len(uz) == 2 and all(sp.converged for sp in uz), [(sp.params, sp.note) for sp in uz]
    assert [sp.params["lam"] for sp in uz] == pytest.approx([target, target], abs=1e-12)
    assert uz[0].order_parameter < lp.order_parameter < uz[1].order_parameter
    th = brentq(lambda t: t * np.tanh(t / 4) - 4, 1, 10)
    lo = brentq(lambda t: exact_lambda(t) - target, 1, th)
    hi = brentq(lambda t: exact_lambda(t) - target, th, 10)
    for sp, theta in zip(uz, (lo, hi), strict=True):
        assert sp.order_parameter == pytest.approx(2 * np.log(np.cosh(theta / 4)), abs=1e-8)
    assert not any("detection gap" in line for line in br.audit)


def test_a_user_zero_next_to_a_fold_that_is_not_located_is_a_detection_gap():
    """Without location (DetectionOptions.locate=False) the fold's parameter is not known: the step
    says that the user zero may have been crossed twice and skipped, instead of saying nothing."""
    pb = Bratu("cheb", 32)
    no_location = dataclasses.replace(OPTS, detection=dataclasses.replace(OPTS.detection, locate=False))
    plain = trace(pb, pb.initial(), {"lam": 0.0}, "lam", no_location)
    lam = plain.parameter_values
    (lp,) = plain.fold_points  # not located: its index is the step (i, i + 1) that turns at the fold
    ends = max(lam[lp.index], lam[lp.index + 1])
    assert ends < BRATU_FOLD
    target = float(0.5 * (ends + BRATU_FOLD))  # beyond both ends of the step that holds the fold
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam", dataclasses.replace(no_location, user_zeros={"lam": [target]}))
    np.testing.assert_array_equal(br.parameter_values, lam)
    assert not br.points("UZ")
    gaps = [line for line in br.audit if "detection gap" in line]
    assert len(gaps) == 1 and f"lam={target!r}" in gaps[0] and "crossed twice and skipped" in gaps[0], br.audit


def test_a_symmetry_that_holds_only_at_other_parameters_is_not_used():
    """StretchedBratu inherited Bratu's reflection, a symmetry of F only at a = 0: the branch from the
    reflection-invariant u = 0 symmetrized every Newton iterate at a = 0.5 and no step converged
    (MX at lam = 2.4e-5).  The tracer now checks J and F_p for equivariance at the start
    (contin.continuation.EQUIVARIANCE_TOL) and traces without the symmetry when it fails."""
    from problems.demo import StretchedBratu

    class ReflectedStretched(StretchedBratu):  # the defect: the reflection claimed at every a
        symmetry = Bratu.symmetry

    pb = ReflectedStretched("cheb", 24)
    br = trace(pb, pb.initial(), {"lam": 0.0, "a": 0.5}, "lam", OPTS)
    (lp,) = br.fold_points
    assert lp.params["lam"] == pytest.approx(BRATU_FOLD / 1.5, abs=1e-9)
    with pytest.raises(ValueError, match="symmetry is not one of F at these parameters"):
        trace(pb, pb.initial(), {"lam": 0.0, "a": 0.5}, "lam", OPTS, symmetric=True)
    # at a = 0 it is one, and the branch is traced as S-invariant as before
    br0 = trace(pb, pb.initial(), {"lam": 0.0, "a": 0.0}, "lam", OPTS, symmetric=True)
    assert br0.fold_points[0].params["lam"] == pytest.approx(BRATU_FOLD, abs=1e-9)


def test_the_diagram_stores_no_mirror_image_that_is_no_solution():
    """contin.diagram stored the image of every non-invariant branch under the problem's symmetry
    without tracing it: with a symmetry that is one of F only at other parameters (Bratu's
    reflection claimed on StretchedBratu at a = 0.5) the image 0' was a "branch" whose states have
    residual 9, exit 0.  The image's states are now checked (contin.overlap.image_defect)."""
    from contin.diagram import bifurcation_diagram
    from contin.newton import max_norm
    from problems.demo import StretchedBratu

    class ReflectedStretched(StretchedBratu):
        symmetry = Bratu.symmetry

    pb = ReflectedStretched("cheb", 24)
    d = bifurcation_diagram(pb, pb.initial(), {"lam": 0.0, "a": 0.5}, "lam", OPTS)
    assert not d.mirrors and [b.id for b in d.branches] == ["0"]
    assert any("0': not stored as the image of 0: the problem's symmetry is not one of F" in s for s in d.skipped)
    for b in d.branches:
        assert max(max_norm(pb.residual(b.state(i), {"a": 0.5, "lam": b.params["lam"][i]})) for i in range(len(b))) < 1e-8


def test_an_event_that_vanishes_twice_next_to_the_fold_is_located_on_both_sides():
    """An event g(u, p) = lam - (lam* - 1e-10) has one sign at both ends of the step that turns at the
    fold: it was missed like a parameter zero; it is located on both sides of the LP too."""
    target = BRATU_FOLD - 1e-10
    pb = Bratu("cheb", 32)
    br = trace(pb, pb.initial(), {"lam": 0.0}, "lam",
               dataclasses.replace(OPTS, events={"near the fold": lambda u, p: p["lam"] - target}))
    relabel([br])
    (lp,) = br.fold_points
    uz = br.points("UZ")
    assert len(uz) == 2 and all(sp.converged and sp.note == "near the fold" for sp in uz), [sp.note for sp in uz]
    assert [sp.params["lam"] for sp in uz] == pytest.approx([target, target], abs=1e-12)
    assert uz[0].order_parameter < lp.order_parameter < uz[1].order_parameter
