"""Hopf points of a stored branch from a wavenumber family of eigenproblems (contin.hopfscan),
and their use by the stability pass (SceneRequest.run_stability).

Toy problem with a closed form: the steady state is u = 0 for every p; the stability problem at
wavenumber kx is A x = omega B x with A = [[p - kx^2 - u2, -(1 + kx), 0], [1 + kx, p - kx^2, 0],
[0, 0, 1]], B = diag(1, 1, 0) (one infinite eigenvalue), so omega = p - kx^2 +- i (1 + kx): a
travelling mode crosses at p = kx^2 with frequency 1 + kx.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from contin.continuation import trace
from contin.hopfscan import locate_hopf, number_new_points
from contin.options import ContinuationOptions, StepOptions
from contin.scene import SceneRequest
from contin.stability import audit, growth_columns, stability_pass


class Travelling:
    parameter_names = ("p",)

    def residual(self, u, p):
        return -u + np.array([0.0, 0.0, u[0] * u[1]])  # u = 0 for every p

    def jacobian(self, u, p):
        return sp.csc_matrix(np.array([[-1.0, 0, 0], [0, -1.0, 0], [u[1], u[0], -1.0]]))

    def dresidual_dp(self, u, p, name):
        return np.zeros(3)

    def eigenproblem(self, u, p, kx=0.0, kz=0.0):
        r = p["p"] - kx * kx - u[1]
        a = np.array([[r, -(1 + kx), 0.0], [1 + kx, p["p"] - kx * kx, 0.0], [0.0, 0.0, 1.0]])
        return a, np.diag([1.0, 1.0, 0.0])


def branch():
    opts = ContinuationOptions(step=StepOptions(ds=0.13, ds_max=0.13), bounds={"p": (-1.0, 2.0)})
    return trace(Travelling(), np.zeros(3), {"p": -1.0}, "p", opts)


def test_locate_hopf_at_two_wavenumbers_against_the_closed_form():
    br = branch()
    assert not br.points("HB")  # the problem has its own eigenproblem: the tracer leaves it to the scan
    for kx in (0.0, 0.5, 1.2):
        scan = locate_hopf(Travelling(), br, kx=kx)
        (hb,) = scan.points
        assert not scan.reasons
        assert hb.converged and abs(hb.params["p"] - kx * kx) <= 1e-10 * max(1.0, kx * kx)
        assert hb.data["omega"] == pytest.approx(1 + kx, rel=1e-12) and hb.data["kx"] == kx
        assert br.parameter_values[hb.index] <= hb.params["p"] <= br.parameter_values[hb.index + 1]


def test_stability_pass_audit_line_becomes_a_located_hb():
    br = branch()
    stability_pass(Travelling(), br)
    assert any("possible Hopf point, not located" in m for m in audit(br))
    request = SceneRequest(params={}, stability=True, kx=(0.5,))
    br.n_unstable = None  # let run_stability do the pass
    messages = request.run_stability(Travelling(), br, {})
    assert not any("possible Hopf" in m for m in messages), messages
    hbs = sorted(br.points("HB"), key=lambda s: s.data["kx"])
    assert [h.data["kx"] for h in hbs] == [0.0, 0.5]
    assert [h.params["p"] for h in hbs] == pytest.approx([0.0, 0.25], abs=1e-10)
    number_new_points([br])
    assert len({sp.label for sp in br.special_points}) == len(br.special_points)
    assert all(sp.label > 0 for sp in br.special_points)


def test_count_change_without_complex_crossing_is_a_stated_reason():
    class RealCrossing(Travelling):
        def eigenproblem(self, u, p, kx=0.0, kz=0.0):
            return np.diag([p["p"] - kx, -1.0, -2.0]), np.eye(3)  # a real eigenvalue crosses at p = kx

    br = branch()
    counts = growth_columns(RealCrossing(), br, kx=0.5)["n_unstable_kx0.5"]
    scan = locate_hopf(RealCrossing(), br, kx=0.5, counts=counts)
    assert not scan.points and len(scan.reasons) == 1 and "no complex pair" in scan.reasons[0]


def test_crossings_closer_than_the_points_resolve_are_doubtful():
    """Re omega of the travelling pair flips sign at every stored point past p = 0.9 (noise-level
    eigenvalue, as gPCF's long-wave mode on plugs next to packing): the HBs there are located
    but their notes and the reasons say 'doubtful'; the isolated crossing at p = kx^2 is not."""
    from contin.hopfscan import doubtful_crossings

    assert doubtful_crossings([3, 10, 11, 13, 20]) == [(10, 13)]
    assert doubtful_crossings([3, 6, 9]) == []

    class Noisy(Travelling):
        def eigenproblem(self, u, p, kx=0.0, kz=0.0):
            a, b = super().eigenproblem(u, p, kx, kz)
            if p["p"] > 0.9:  # Re omega = +-1e-3 alternating with the 0.13-spaced points
                r = 1e-3 * np.sin(np.pi * (p["p"] + 1.0) / 0.13 + 0.5)
                a[0, 0] = a[1, 1] = r
            return a, b

    br = branch()
    counts = growth_columns(Noisy(), br, kx=0.5)["n_unstable_kx0.5"]
    scan = locate_hopf(Noisy(), br, kx=0.5, counts=counts)
    clean = [h for h in scan.points if "doubtful" not in h.note]
    noisy = [h for h in scan.points if "doubtful" in h.note]
    assert [h.params["p"] for h in clean] == pytest.approx([0.25], abs=1e-10)
    assert len(noisy) >= 3 and all(h.params["p"] > 0.9 for h in noisy)
    assert len(scan.reasons) == 1 and "doubtful" in scan.reasons[0]
