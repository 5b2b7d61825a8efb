"""Allen-Cahn u'' + lam (u - u^3) = 0 on [0, pi]: BPs at k^2, symmetry-breaking switching."""

import numpy as np
import pytest

from contin.branch import relabel
from contin.continuation import switch, trace
from contin.options import ContinuationOptions, StepOptions
from problems.demo import AllenCahn

OPTS = ContinuationOptions(bounds={"lam": (0.0, 10.0)}, max_steps=200, step=StepOptions(ds=0.1, ds_max=0.5))


@pytest.fixture(scope="module")
def diagram():
    pb = AllenCahn("cheb", 32)
    trivial = trace(pb, pb.initial(), {"lam": 0.0}, "lam", OPTS)
    relabel([trivial])
    children = {bp.name: switch(pb, trivial, bp, OPTS) for bp in trivial.branch_points}
    relabel([trivial] + [c for cs in children.values() for c in cs])
    return pb, trivial, children


def test_branch_points_at_k_squared(diagram):
    _, trivial, _ = diagram
    bps = trivial.branch_points
    assert [round(bp.params["lam"]) for bp in bps] == [1, 4, 9]
    for bp, k in zip(bps, (1, 2, 3)):
        assert abs(bp.params["lam"] - k**2) < 1e-8
        assert bp.converged and "symmetry-breaking" in bp.note
        assert bp.bracket[0] <= bp.params["lam"] <= bp.bracket[1]
        assert trivial.parameter_values[bp.index] <= bp.params["lam"] <= trivial.parameter_values[bp.index + 1]
    assert not trivial.fold_points
    assert trivial.status == "EP" and trivial.parameter_values[-1] == 10.0
    assert np.max(np.abs(trivial.states)) == 0.0  # symmetrised: the trivial branch stays exactly u = 0


def test_switching_gives_both_signs_of_each_mode_supercritically(diagram):
    pb, trivial, children = diagram
    for k, bp in zip((1, 2, 3), trivial.branch_points):
        pair = children[bp.name]
        assert len(pair) == 2
        for br in pair:
            assert br.kind == "bifurcated" and br.parent == f"{bp.name}@0"
            assert br.status == "EP" and br.parameter_values[-1] == 10.0
            lam = br.parameter_values
            amp = br.observables["max_abs"]
            assert lam[0] == pytest.approx(k**2, abs=1e-8) and amp[0] == 0.0
            # supercritical: lam > k^2 off the BP and grows with the amplitude
            assert np.all(lam[1:] > k**2) and np.all(np.diff(lam) > 0) and np.all(np.diff(amp) > 0)
            # mode k has k - 1 interior nodes; |u| < 1 (the constant states +-1 bound it)
            assert np.all(br.observables["nodes"][1:] == k - 1)
            assert np.all(amp < 1)
            # near the BP: lam - k^2 = (3/4) k^2 a^2 + O(a^4) for u = a sin(kx) (Galerkin)
            i = np.searchsorted(amp, 0.1)
            a = amp[i]
            assert (lam[i] - k**2) / (0.75 * k**2 * a**2) == pytest.approx(1.0, abs=0.05)
            for j in (1, len(br) // 2, len(br) - 1):
                assert np.max(np.abs(pb.residual(br.states[j], {"lam": lam[j]}))) < 1e-9
            assert not br.branch_points and not br.fold_points
        plus, minus = pair
        # the two halves are mirror images u -> -u
        assert np.sign(plus.order_parameter[1]) == -np.sign(minus.order_parameter[1])
        lam_grid = np.linspace(k**2 + 0.1, 9.9, 5)
        phi_p = np.interp(lam_grid, plus.parameter_values, plus.order_parameter)
        phi_m = np.interp(lam_grid, minus.parameter_values, minus.order_parameter)
        assert np.allclose(phi_p, -phi_m, atol=1e-6)


def test_labels_unique_across_run(diagram):
    _, trivial, children = diagram
    labels = [sp.label for br in [trivial] + [c for cs in children.values() for c in cs] for sp in br.special_points]
    assert labels == list(range(1, len(labels) + 1))


def test_without_symmetry_the_full_determinant_finds_the_same_bps():
    pb = AllenCahn("cheb", 24)
    br = trace(pb, pb.initial(), {"lam": 0.5}, "lam", OPTS, symmetric=False)
    assert [bp.params["lam"] for bp in br.branch_points] == pytest.approx([1, 4, 9], abs=1e-8)
    assert all("symmetry" not in bp.note for bp in br.branch_points)
    for bp in br.branch_points:
        plus, minus = switch(pb, br, bp, OPTS)
        assert plus.parameter_values[-1] == 10.0 and minus.parameter_values[-1] == 10.0
        assert plus.order_parameter[-1] == pytest.approx(-minus.order_parameter[-1], abs=1e-6)


def test_first_direction_of_a_switch_raises_the_order_parameter(diagram):
    """directions=(+1,) is reproducible: the null vector is oriented so that the order parameter
    grows along it (its sign out of the LU is arbitrary)."""
    pb, trivial, _ = diagram
    for bp in trivial.branch_points:
        (first,) = switch(pb, trivial, bp, OPTS, directions=(+1,))
        (second,) = switch(pb, trivial, bp, OPTS, directions=(-1,))
        assert first.order_parameter[1] > bp.order_parameter > second.order_parameter[1]


def test_null_vector_orientation_is_sign_independent():
    from contin.extended import ExtendedSystem
    from contin.switching import _oriented

    pb = AllenCahn("cheb", 16)
    system = ExtendedSystem(pb, {"lam": 1.0}, "lam")
    x0 = system.pack(pb.initial(), 1.0)
    phi = system.unit(system.pack(np.sin(np.linspace(0, np.pi, x0.size - 1)) - 0.2, 0.0))
    assert np.array_equal(_oriented(system, x0, phi), _oriented(system, x0, -phi))
    assert system.order_parameter(x0 + 1e-3 * _oriented(system, x0, phi)) > system.order_parameter(x0)
