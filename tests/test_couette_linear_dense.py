"""The dense stability assembly and the k_x = 0 Schur/split spectrum against the former sparse path.

References computed in the test: the sparse assembly as it was (``benchmarks/reference_sparse_stability.py``,
kept verbatim), dense QZ (``contin.stability.eigenvalues``) on the full pencil, and the exact 4 x 4
uniform-shear modes of physics.md section 4 (``linear.uniform_shear_modes``).
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.reference_sparse_stability import reference_k0_eigenvalues, sparse_linear_operator
from contin.continuation import switch
from contin.stability import count_unstable, eigenvalues
from problems.couette import linear as L
from problems.couette import pitchfork as pf
from problems.couette.model import CouetteProblem
from problems.discretization import make_grid

NU, E = 0.3, 0.8


def _gap(a, b):
    """max over a of the distance to the nearest element of b, relative to max(1, |a_i|) (a
    conjugate pair whose real parts tie to rounding may come in either order)."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.min(np.abs(a[:, None] - b[None, :]), axis=1) / np.maximum(1.0, np.abs(a))))


def _profiles(grid, asym=0.0):
    y = grid.y
    nu = 0.3 + 0.02 * np.cos(np.pi * (y + 0.5)) + asym * np.sin(np.pi * y)
    T = 0.5 - 0.03 * np.cos(np.pi * (y + 0.5)) ** 2
    u = y + 0.05 * np.sin(2 * np.pi * y)
    return nu, u, T


@pytest.mark.parametrize("method,N", [("cheb", 24), ("fd4", 30)])
@pytest.mark.parametrize("walls", ["noslip", "jj"])
@pytest.mark.parametrize("kx", [0.0, 0.7])
def test_dense_assembly_equals_sparse(method, N, walls, kx):
    """Same matrices to rounding, with the Dufour term, gravity and spanwise waves switched on."""
    grid = make_grid(method, N)
    nu, u, T = _profiles(grid, asym=0.01)
    p = {"e": E, "H": 20.0, "G": 1e-3, "phi_w": 0.5, "ew": 0.9}
    for kz in (0.0, 0.4):
        A0, B0 = sparse_linear_operator(grid, nu, u, T, p, walls=walls, kx=kx, kz=kz, dufour=True)
        A1, B1 = L.linear_operator(grid, nu, u, T, p, walls=walls, kx=kx, kz=kz, dufour=True)
        Ad, Bd = L.linear_operator(grid, nu, u, T, p, walls=walls, kx=kx, kz=kz, dufour=True, dense=True)
        scale = abs(A0).max()
        assert abs(A1 - A0).max() <= 1e-14 * scale and abs(B1 - B0).max() == 0.0
        assert np.abs(Ad - A0.toarray()).max() <= 1e-14 * scale and np.array_equal(Bd, B0.toarray())
        assert A1.dtype == A0.dtype


@pytest.fixture(scope="module")
def branch_states():
    """Uniform shear, a symmetry-breaking (n = 1) and a symmetric (n = 2) banded state at cheb 64."""
    pb = CouetteProblem("cheb", 64)
    p = pb.params({"nu": NU, "e": E})
    hc = pf.analytic_critical_gaps(NU, E, 2)
    from contin.options import ContinuationOptions, StepOptions

    o = ContinuationOptions(step=StepOptions(ds=0.1 * hc[0], ds_max=0.3 * hc[0]),
                            bounds={"H": (0.8 * hc[0], 2.6 * hc[0])}, max_steps=40)
    base = pf.trace_base(pb, p, 0.9 * hc[0], o)
    bps = sorted(base.branch_points, key=lambda b: b.params["H"])[:2]
    states = [("uniform", base.state(len(base) // 2), {**p, "H": float(base.params["H"][len(base) // 2])})]
    for name, bp in zip(("n1", "n2"), bps):
        band = switch(pb, base, bp, o, directions=(+1,))[0]
        for i in (2, len(band) - 1):
            states.append((f"{name}[{i}]", band.state(i), {**p, "H": float(band.params["H"][i])}))
    return pb, states


def test_k0_spectrum_equals_former_path(branch_states):
    """Leading eigenvalues to 1e-10 (relative to max(1, |omega|)) and identical unstable counts
    against the former sparse path, and the whole spectrum against dense QZ of the full pencil."""
    pb, states = branch_states
    split_used = {}
    for name, x, p in states:
        nu, u, T, _, _ = pb.unpack(x)
        old = reference_k0_eigenvalues(pb.grid, nu, u, T, p)
        new = L.k0_spectrum(pb.grid, nu, u, T, p, gravity=False)
        assert new.size == old.size
        lead = slice(0, 8)
        assert _gap(new[lead], old) < 1e-10 and _gap(old[lead], new) < 1e-10, name
        assert count_unstable(new) == count_unstable(old), name
        A, B = pf.StabilityOperator(pb).eigenproblem(x, p)
        qz = eigenvalues(A, B)
        assert qz.size == new.size
        # QZ on the full pencil is the less accurate side here: at the strongly banded n1 state it
        # differs by 1.1e-10 from the former Schur path as much as from the new one (2e-12 apart)
        assert _gap(new[lead], qz) < 1e-9 and _gap(qz[lead], new) < 1e-9, name
        try:
            L.k0_spectrum(pb.grid, nu, u, T, p, gravity=False, split=True)
            split_used[name] = True
        except ValueError:
            split_used[name] = False
    # the split applies exactly on the S-invariant states: uniform shear and the n = 2 branch
    assert split_used == {name: not name.startswith("n1") for name, _, _ in states}


def test_split_equals_unsplit_and_uniform_shear_modes(branch_states):
    """On uniform shear the split spectrum equals the unsplit one and its leading eigenvalues are
    the exact 4 x 4 modes of physics.md section 4 (n = 1, 2: odd n in the S-odd half)."""
    pb, states = branch_states
    name, x, p = states[0]
    nu, u, T, _, _ = pb.unpack(x)
    w_split = L.k0_spectrum(pb.grid, nu, u, T, p, gravity=False, split=True)
    w_full = L.k0_spectrum(pb.grid, nu, u, T, p, gravity=False, split=False)
    assert _gap(w_split[:10], w_full) < 1e-10 and _gap(w_full[:10], w_split) < 1e-10
    for n in (1, 2):
        exact = L.uniform_shear_modes(NU, E, p["H"], n)[0]
        assert np.min(np.abs(w_split - exact)) < 1e-10 * max(1.0, abs(exact))


def test_split_refused_on_asymmetric_state():
    grid = make_grid("cheb", 24)
    nu, u, T = _profiles(grid, asym=0.01)
    with pytest.raises(ValueError, match="not reflection-symmetric"):
        L.k0_spectrum(grid, nu, u, T, {"e": E, "H": 20.0}, split=True)
    assert L.k0_spectrum(grid, nu, u, T, {"e": E, "H": 20.0}).size > 0


def test_stability_operator_spectrum_uses_it(branch_states):
    pb, states = branch_states
    op = pf.StabilityOperator(pb)
    for name, x, p in states:
        w = op.spectrum(x, p)
        old = pf.finite_eigenvalues(*op.eigenproblem(x, p))
        assert _gap(w[:6], old) < 1e-10 and _gap(old[:6], w) < 1e-10, name
