"""Steady granular plane Couette flow problem (problems/couette/model.py, params.py).

Reference numbers: physics.md sections 1.2 and 4 (uniform shear T0, p0; H_n^c = n pi psi).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import brentq

from contin.problem import Problem, check_jacobian
from problems.couette.closures import critical_gap_factor, uniform_shear
from problems.couette.model import CouetteProblem
from problems.couette.params import (
    DEFAULTS,
    PARAMETER_NAMES,
    build_params,
    froude_to_gravity,
    gravity_to_froude,
)
from problems.discretization import cell_integration_matrix, make_grid


def newton(problem, x, p, tol=1e-10, max_iterations=40):
    """Damped Newton: halve the step until the state is admissible and |F| decreases.

    Converged when a full step is below 1e-10 (x is O(1)) and max |F| < tol; the residual
    floor is set by rounding in rows with large entries (cheb D2 ~ N^4).
    """
    norm = np.max(np.abs(problem.residual(x, p)))
    for _ in range(max_iterations):
        dx = spla.spsolve(problem.jacobian(x, p).tocsc(), -problem.residual(x, p))
        lam = 1.0
        while True:
            trial = x + lam * dx
            if problem.admissible(trial, p) is None:
                trial_norm = np.max(np.abs(problem.residual(trial, p)))
                if trial_norm < max(norm, tol) or lam < 1e-3:
                    break
            lam *= 0.5
            assert lam > 1e-6, "Newton line search failed"
        x, norm = trial, trial_norm
        if norm < tol and lam == 1.0 and np.max(np.abs(dx)) < 1e-10:
            return x
    raise AssertionError(f"Newton did not converge, |F| = {norm:.3e}")


def perturbed(problem, p, seed=0):
    """A smooth non-uniform, non-symmetric state near uniform shear (for derivative checks)."""
    rng = np.random.default_rng(seed)
    x = problem.initial_guess(p)
    nu, u, T, P, M = problem.unpack(x)
    y = problem.grid.y
    nu = nu * (1 + 0.2 * np.sin(3 * y) + 0.1 * y**2 + 0.02 * rng.standard_normal(y.size))
    u = u + 0.1 * np.cos(2 * y) + 0.03 * y**3
    T = T * (1 + 0.3 * y + 0.1 * np.cos(5 * y))
    M = None if M is None else problem.cumulative_mass(nu) + 0.01 * rng.standard_normal(y.size)
    return problem.pack(nu, u, T, 1.1 * P, M)


# --------------------------------------------------------------------------- uniform shear
@pytest.mark.parametrize("method,N", [("cheb", 48), ("cheb", 24), ("fd2", 40), ("fd4", 64), ("fd6", 60)])
def test_uniform_shear_solves_discrete_equations_exactly(method, N):
    problem = CouetteProblem(method, N)
    for nu in (0.1, 0.3, 0.55):
        for e in (0.5, 0.8, 0.99):
            for H in (2.0, 20.0, 300.0):
                p = problem.params({"nu": nu, "e": e, "H": H})
                x = problem.uniform_state(p)
                assert np.max(np.abs(problem.residual(x, p))) <= 1e-12
                t0, s0, p0 = uniform_shear(nu, e)
                _, u, T, P, _ = problem.unpack(x)
                assert np.all(T == T[0]) and T[0] == pytest.approx(t0, rel=1e-14)
                assert P == pytest.approx(p0, rel=1e-14)
                np.testing.assert_array_equal(u, problem.grid.y)
                obs = problem.observables(x, p)
                assert obs["shear_stress"] == pytest.approx(s0, rel=1e-12)
                assert obs["delta"] == 0.0


def test_uniform_shear_reference_values():
    # physics.md section 4: e = 0.8, chi_JJ(0.65), nu = 0.3: T0 = 0.48174, S0 = 0.32282, p0 = 0.83152
    problem = CouetteProblem("cheb", 16)
    p = problem.params({"nu": 0.3, "e": 0.8})
    obs = problem.observables(problem.uniform_state(p), p)
    assert obs["T_mid"] == pytest.approx(0.48174, abs=1e-5)
    assert obs["shear_stress"] == pytest.approx(0.32282, abs=1e-5)
    assert obs["pressure"] == pytest.approx(0.83152, abs=1e-5)
    assert problem.order_parameter(problem.uniform_state(p), p) == 0.3


def test_uniform_shear_also_solves_gravity_instance_at_zero_gravity():
    problem = CouetteProblem("fd4", 32, gravity=True)
    p = problem.params({"nu": 0.4})
    x = problem.uniform_state(p)
    assert np.max(np.abs(problem.residual(x, p))) <= 1e-12
    np.testing.assert_allclose(problem.unpack(x)[4], 0.4 * problem.grid.y, rtol=0, atol=1e-15)


def test_uniform_state_rejects_elastic_limit():
    problem = CouetteProblem("cheb", 8)
    with pytest.raises(ValueError, match="e = 1"):
        problem.uniform_state(problem.params({"e": 1.0}))


# --------------------------------------------------------------------------- derivatives
CASES = [
    (method, walls, gravity)
    for method, walls, gravity in [
        ("cheb", "noslip", False),
        ("cheb", "noslip", True),
        ("cheb", "jj", False),
        ("cheb", "jj", True),
        ("fd4", "noslip", False),
        ("fd4", "noslip", True),
        ("fd4", "jj", False),
        ("fd4", "jj", True),
    ]
]


@pytest.mark.parametrize("method,walls,gravity", CASES)
@pytest.mark.parametrize("dufour", [False, True])
def test_jacobian_and_parameter_derivatives_against_finite_differences(method, walls, gravity, dufour):
    N = 16 if method == "cheb" else 24
    problem = CouetteProblem(method, N, walls=walls, gravity=gravity, dufour=dufour)
    p = problem.params({"H": 15.0, "nu": 0.35, "e": 0.7, "G": 3e-4 if gravity else 0.0})
    x = perturbed(problem, p)
    names = ("nu", "e", "H", "num") + (("phi_w", "ew") if walls == "jj" else ()) + (("G",) if gravity else ())
    check = check_jacobian(problem, x, p, parameters=names)
    assert check.relative_error < 1e-8
    for name in names:
        scale = np.max(np.abs(problem.dresidual_dp(x, p, name)))
        assert scale > 0
        assert check.dp_errors[name] < 1e-6 * scale, name

    # Sharper: complex-step columns are exact to rounding, so compare row by row.
    jac = problem.jacobian(x, p).toarray()
    cs = np.empty_like(jac)
    for j in range(x.size):
        xc = x.astype(complex)
        xc[j] += 1e-30j
        cs[:, j] = problem.residual(xc, p).imag / 1e-30
    row_scale = np.max(np.abs(cs), axis=1)
    assert np.all(row_scale > 0)
    assert np.max(np.max(np.abs(jac - cs), axis=1) / row_scale) < 1e-12


@pytest.mark.parametrize("method,walls,gravity", CASES)
@pytest.mark.parametrize("dufour", [False, True])
def test_dense_jacobian_is_the_sparse_one_bitwise(method, walls, gravity, dufour):
    # contin factorizes small systems from dense_jacobian (contin.problem): it must be the
    # same matrix, entry for entry, or branch switching would round differently
    problem = CouetteProblem(method, 16 if method == "cheb" else 24, walls=walls, gravity=gravity, dufour=dufour)
    p = problem.params({"H": 15.0, "nu": 0.35, "e": 0.7, "G": 3e-4 if gravity else 0.0})
    x = perturbed(problem, p)
    dense = problem.dense_jacobian(x, p)
    assert dense.flags.f_contiguous and dense.shape == (problem.size, problem.size)
    sparse = problem.jacobian(x, p).toarray()
    assert np.array_equal(dense, sparse)
    # both assemblies of the dense J (one bincount scatter; term by term with dense operator
    # blocks, the default on large Chebyshev grids) give it bit for bit
    layout, rows, cols = problem._jacobian_terms(x, p)
    for blockwise in (False, True):
        d = layout.assemble_dense(rows, cols, blockwise=blockwise)
        assert d.flags.f_contiguous and d.tobytes(order="F") == sparse.tobytes(order="F")


def test_blockwise_dense_jacobian_on_a_large_chebyshev_grid():
    # cheb 96: the operator blocks hold > BLOCKWISE_MIN entries, so dense_jacobian adds them
    # term by term; same bits as the CSR Jacobian and as the one-scatter assembly
    from problems.couette.model import BLOCKWISE_MIN

    problem = CouetteProblem("cheb", 96)
    p = problem.params({"H": 15.0, "nu": 0.35, "e": 0.7})
    x = perturbed(problem, p)
    layout, rows, cols = problem._jacobian_terms(x, p)
    scatter = layout.assemble_dense(rows, cols, blockwise=False)
    assert layout._dense_entries >= BLOCKWISE_MIN
    dense = problem.dense_jacobian(x, p)
    assert dense.tobytes() == scatter.tobytes() and dense.flags.f_contiguous
    assert np.array_equal(dense, problem.jacobian(x, p).toarray())
    # into an earlier J (contin's scratch): overwritten, not merely added to
    old = np.full((problem.size, problem.size), np.nan, order="F")
    again = problem.dense_jacobian(x, p, out=old)
    assert again is old and again.tobytes() == scatter.tobytes()


def test_parameter_derivative_of_inactive_parameters_is_zero():
    problem = CouetteProblem("cheb", 12)
    p = problem.params({})
    x = perturbed(problem, p)
    for name in ("phi_w", "ew"):
        assert np.all(problem.dresidual_dp(x, p, name) == 0.0)
    dnu = problem.dresidual_dp(x, p, "nu")
    assert dnu[problem.i_P] == -1.0 and np.count_nonzero(dnu) == 1
    with pytest.raises(ValueError, match="gravity=True"):
        problem.dresidual_dp(x, p, "G")
    with pytest.raises(ValueError, match="unknown parameter 'Fr'"):
        problem.dresidual_dp(x, p, "Fr")


def test_jacobian_is_sparse_and_banded_for_finite_differences():
    for N in (40, 80):
        problem = CouetteProblem("fd4", N)
        p = problem.params({})
        jac = problem.jacobian(perturbed(problem, p), p)
        assert sp.issparse(jac) and jac.format == "csr"
        assert jac.shape == (3 * (N + 1) + 1, 3 * (N + 1) + 1)
        # 6 field blocks with <= 7 entries per row (fd4 D2: 5 centred, 6 one-sided), plus the
        # dense mass-constraint row and the P column
        assert jac.nnz <= 6 * 7 * (N + 1) + 2 * (N + 1) + 1


def test_gravity_free_noslip_instance_builds_no_gravity_or_wall_terms(monkeypatch):
    problem = CouetteProblem("fd2", 16)
    assert problem.size == 3 * 17 + 1 and problem.i_M is None and not hasattr(problem, "_cells")

    def forbidden(*args, **kwargs):
        raise AssertionError("Johnson-Jackson terms evaluated for no-slip walls")

    monkeypatch.setattr(problem, "_wall_coefficients", forbidden)
    p = problem.params({})
    x = perturbed(problem, p)
    problem.residual(x, p)
    problem.jacobian(x, p)
    with pytest.raises(ValueError, match="gravity=True"):
        problem.residual(x, dict(p, G=1e-6))


# --------------------------------------------------------------------------- symmetry
@pytest.mark.parametrize("method", ["cheb", "fd6"])
@pytest.mark.parametrize("walls", ["noslip", "jj"])
def test_reflection_equivariance(method, walls):
    problem = CouetteProblem(method, 20, walls=walls, dufour=walls == "jj")
    p = problem.params({"H": 17.0, "phi_w": 0.3, "ew": 0.8})
    assert problem.symmetric(p)
    x = perturbed(problem, p, seed=3)
    S = problem.symmetry_matrix()
    np.testing.assert_array_equal(S @ x, problem.symmetry(x))
    np.testing.assert_array_equal(problem.symmetry(problem.symmetry(x)), x)
    F, FS = problem.residual(x, p), problem.residual(problem.symmetry(x), p)
    assert np.max(np.abs(FS - S @ F)) < 1e-11 * np.max(np.abs(F))
    J, JS = problem.jacobian(x, p), problem.jacobian(problem.symmetry(x), p)
    assert abs(JS @ S - S @ J).max() < 1e-12 * abs(J).max()
    # the state is not symmetric, so this is not a vacuous check
    assert np.max(np.abs(problem.symmetry(x) - x)) > 0.01


@pytest.mark.parametrize("walls", ["noslip", "jj"])
@pytest.mark.parametrize("method,N", [("fd4", 24), ("fd4", 25), ("cheb", 15), ("cheb", 16)])
def test_reflection_maps_gravity_to_its_negative(walls, method, N):
    """F(Sx, -G) = S F(x, G) with the same S on unknowns and rows (even and odd N)."""
    problem = CouetteProblem(method, N, walls=walls, gravity=True)
    p = problem.params({"G": 2e-4, "H": 12.0})
    assert not problem.symmetric(p)
    x = perturbed(problem, p, seed=5)
    S = problem.symmetry_matrix()
    np.testing.assert_array_equal(S @ x, problem.symmetry(x))
    np.testing.assert_array_equal(S @ (S @ x), x)
    F = problem.residual(x, p)
    assert np.max(np.abs(F[problem.i_M])) > 1e-3  # x is off the mass rows' solution set
    minus = dict(p, G=-p["G"])
    FS = problem.residual(problem.symmetry(x), minus)
    assert np.max(np.abs(FS - S @ F)) < 1e-11 * np.max(np.abs(F))
    assert np.max(np.abs(problem.residual(problem.symmetry(x), p) - S @ F)) > 1e-3
    J, JS = problem.jacobian(x, p), problem.jacobian(problem.symmetry(x), minus)
    assert abs(JS @ S - S @ J).max() < 1e-12 * abs(J).max()
    # at G = 0 the gravity instance is symmetric in the ordinary sense
    zero = dict(p, G=0.0)
    assert problem.symmetric(zero)
    assert np.max(np.abs(problem.residual(problem.symmetry(x), zero) - S @ problem.residual(x, zero))) < 1e-11


# --------------------------------------------------------------------------- bifurcations
@pytest.mark.parametrize("nu", [0.2, 0.3, 0.5])
@pytest.mark.parametrize("e", [0.5, 0.8, 0.95])
def test_uniform_shear_jacobian_is_singular_at_the_critical_gaps(nu, e):
    """det J(uniform shear; H) changes sign exactly at H_n^c = n pi psi (physics.md section 4)."""
    problem = CouetteProblem("cheb", 48)
    psi = float(critical_gap_factor(nu, e))

    def logdet(H):
        p = problem.params({"nu": nu, "e": e, "H": H})
        return np.linalg.slogdet(problem.jacobian(problem.uniform_state(p), p).toarray())

    ref = 0.0

    def det(H):
        sign, value = logdet(H)
        return sign * math.exp(value - ref)

    for n in (1, 2, 3):
        hc = n * math.pi * psi
        a, b = 0.97 * hc, 1.03 * hc
        ref = logdet(a)[1]  # keeps det O(1) near the root
        assert det(a) * det(b) < 0
        root = brentq(det, a, b, xtol=1e-13 * hc, rtol=1e-15)
        assert abs(root / hc - 1) < 1e-8, (n, root, hc)


def test_no_singularity_below_the_first_critical_gap():
    nu, e = 0.3, 0.8
    hc = math.pi * float(critical_gap_factor(nu, e))  # 13.0685 (physics.md section 6)
    assert hc == pytest.approx(13.0685, abs=1e-4)
    problem = CouetteProblem("cheb", 32)
    signs = []
    for H in np.linspace(0.2, 0.99, 12) * hc:
        p = problem.params({"nu": nu, "e": e, "H": H})
        signs.append(np.linalg.slogdet(problem.jacobian(problem.uniform_state(p), p).toarray())[0])
    assert len(set(signs)) == 1


# --------------------------------------------------------------------------- steady states
def _balances(problem, p):
    x = newton(problem, problem.initial_guess(p), p)
    assert problem.admissible(x, p) is None
    source, flux = problem.energy_balance(x, p)
    return x, abs(source - flux), problem.momentum_balance(x, p)


def test_johnson_jackson_state_balances():
    problem = CouetteProblem("cheb", 40, walls="jj")
    p = problem.params({"H": 20.0, "nu": 0.3})
    x, energy_error, momentum = _balances(problem, p)
    source, flux = problem.energy_balance(x, p)
    # slip walls: net heat leaves the walls, produced in the bulk (not a trivial 0 = 0)
    assert source > 1e-4 and flux > 1e-4
    assert energy_error < 1e-12
    assert momentum["shear_stress"] < 1e-11
    assert momentum["normal_stress"] < 1e-12
    assert momentum["normal_stress_gradient"] < 1e-10
    obs = problem.observables(x, p)
    assert obs["nu_bottom"] == pytest.approx(obs["nu_top"], abs=1e-12)  # symmetric base state
    assert problem.grid.integrate(problem.profiles(x)["nu"]) == pytest.approx(0.3, abs=1e-14)
    nu, u, T, _, _ = problem.unpack(x)
    assert -0.5 < u[0] < -0.3 and 0.3 < u[-1] < 0.5  # slip at both walls
    # the shear stress equals the wall friction H s_w u_slip at both walls
    s = problem.shear_stress(x, p)
    assert np.max(np.abs(s - s[-1])) < 1e-11
    np.testing.assert_allclose(problem.symmetry(x), x, atol=1e-11)


def test_gravity_state_balances():
    problem = CouetteProblem("cheb", 40, gravity=True)
    p = problem.params({"H": 10.0, "Fr": 1000.0})
    assert p["G"] == pytest.approx(1e-6, rel=1e-15)
    x, energy_error, momentum = _balances(problem, p)
    assert energy_error < 1e-13
    assert momentum["shear_stress"] < 1e-11
    assert momentum["normal_stress"] < 1e-12
    assert momentum["normal_stress_gradient"] < 1e-10
    obs = problem.observables(x, p)
    # below H_1^c gravity compresses the near-uniform state towards the bottom wall
    assert obs["nu_bottom"] > 0.3 > obs["nu_top"]
    nu, _, T, P, M = problem.unpack(x)
    assert M[0] == pytest.approx(-0.15, abs=1e-14) and M[-1] == pytest.approx(0.15, abs=1e-14)
    np.testing.assert_allclose(M, problem.cumulative_mass(nu), rtol=0, atol=1e-14)
    assert problem.grid.integrate(nu) == pytest.approx(0.3, abs=1e-14)
    q = problem.heat_flux(x, p)
    assert abs(q[0]) < 1e-14 and abs(q[-1]) < 1e-14  # adiabatic walls


def test_gravity_hydrostatic_pressure_drop():
    from problems.couette.closures import coefficients

    problem = CouetteProblem("cheb", 32, gravity=True, walls="jj")
    p = problem.params({"H": 12.0, "G": 5e-6})
    x = newton(problem, problem.initial_guess(p), p)
    nu, _, T, _, _ = problem.unpack(x)
    f1 = coefficients(nu, p["e"], "jj", p["num"]).f1
    drop = f1[0] * T[0] - f1[-1] * T[-1]
    assert drop == pytest.approx(p["H"] ** 3 * p["G"] * p["nu"], rel=1e-11)


@pytest.mark.parametrize(
    "walls,gravity,G", [("jj", False, 0.0), ("noslip", True, 1e-6), ("jj", True, 2e-6)]
)
@pytest.mark.parametrize("method,sizes", [("fd2", (96, 192)), ("fd4", (48, 96)), ("fd6", (32, 64)), ("cheb", (8, 16))])
def test_balances_converge_at_the_scheme_order(walls, gravity, G, method, sizes):
    """Energy and shear-stress balance errors fall at the nominal order of the scheme.

    The window |observed - nominal| < 0.9 separates the orders 2, 4, 6 of the family; at these
    sizes fd6 with JJ walls is still pre-asymptotic (observed 5.2, approaching 6 as N grows
    until rounding takes over).  Chebyshev: errors fall by > 1e3 from N = 8 to 16.
    """
    errors, shear = [], []
    for N in sizes:
        problem = CouetteProblem(method, N, walls=walls, gravity=gravity)
        p = problem.params({"H": 10.0 if gravity else 20.0, "G": G})
        _, energy_error, momentum = _balances(problem, p)
        errors.append(energy_error)
        shear.append(momentum["shear_stress"])
    if method == "cheb":  # exponential: doubling N gains far more than 2^6
        assert errors[1] < 1e-11 and shear[1] < 1e-9
        assert shear[0] > 1e3 * shear[1] and errors[0] > 1e3 * errors[1]
        return
    order = int(method[2:])
    shear_order = math.log2(shear[0] / shear[1])
    energy_order = math.log2(errors[0] / errors[1])
    assert abs(shear_order - order) < 0.9, shear_order
    assert abs(energy_order - order) < 0.9, energy_order
    assert errors[1] > 1e-15  # a real discretization error, not rounding


# --------------------------------------------------------------------------- small API
def test_profiles_observables_admissible():
    problem = CouetteProblem("cheb", 10, gravity=True)
    p = problem.params({"nu": 0.25})
    x = perturbed(problem, p)
    prof = problem.profiles(x)
    assert set(prof) == {"nu", "u", "T", "M"}
    np.testing.assert_array_equal(problem.pack(prof["nu"], prof["u"], prof["T"], x[problem.i_P], prof["M"]), x)
    obs = problem.observables(x, p)
    assert obs["phi"] == obs["nu_top"] == prof["nu"][-1] == problem.order_parameter(x, p)
    assert obs["delta"] == pytest.approx(prof["nu"][-1] - 0.25, abs=0)
    assert problem.admissible(x, p) is None
    bad = x.copy()
    bad[problem.i_T][3] = -0.1
    assert "temperature" in problem.admissible(bad, p)
    bad = x.copy()
    bad[problem.i_nu][0] = 0.65
    assert "packing limit" in problem.admissible(bad, p)
    bad = x.copy()
    bad[2] = np.nan
    assert "non-finite" in problem.admissible(bad, p)
    assert isinstance(problem, Problem)
    assert problem.options == {"method": "cheb", "N": 10, "walls": "noslip", "chi": "jj", "gravity": True, "dufour": False,
                               "engine": "numpy"}


def test_cell_integration_matrix():
    for method, N in [("cheb", 20), ("fd2", 16), ("fd4", 16), ("fd6", 24)]:
        grid = make_grid(method, N)
        cells = cell_integration_matrix(grid)
        assert cells.shape == (N, N + 1)
        np.testing.assert_allclose(np.asarray(cells.sum(axis=0)).ravel(), grid.weights, rtol=0, atol=1e-16)
        dense = cells.toarray()
        np.testing.assert_allclose(dense, dense[::-1, ::-1], rtol=0, atol=1e-16)
    # exactness: cheb integrates the degree-N interpolant, fdP local degree P-1 polynomials
    grid = make_grid("cheb", 12)
    f = grid.y**12 - grid.y**5
    cum = np.concatenate([[0.0], np.cumsum(cell_integration_matrix(grid) @ f)])
    exact = (grid.y**13 + 0.5**13) / 13 - (grid.y**6 - 0.5**6) / 6
    np.testing.assert_allclose(cum, exact, rtol=0, atol=2e-16)
    grid = make_grid("fd4", 16)
    f = grid.y**3 + grid.y
    cum = np.concatenate([[0.0], np.cumsum(cell_integration_matrix(grid) @ f)])
    np.testing.assert_allclose(cum, (grid.y**4 - 0.5**4) / 4 + (grid.y**2 - 0.25) / 2, rtol=0, atol=1e-16)
    assert cell_integration_matrix(make_grid("fd4", 40)).nnz == 4 * 40  # banded


# --------------------------------------------------------------------------- parameters
def test_build_params_defaults_and_froude():
    p = build_params()
    assert p == DEFAULTS and tuple(p) == PARAMETER_NAMES
    assert build_params({"Fr": math.inf})["G"] == 0.0
    assert build_params({"Fr": "inf"})["G"] == 0.0
    assert build_params({"Fr": 2000})["G"] == pytest.approx(2.5e-7, rel=1e-15)
    assert build_params({"Fr": 100, "G": 1e-4})["G"] == 1e-4
    assert froude_to_gravity(922.0) == pytest.approx(922.0**-2, rel=1e-15)
    assert gravity_to_froude(froude_to_gravity(922.0)) == pytest.approx(922.0, rel=1e-14)
    assert gravity_to_froude(0.0) == math.inf
    # Carnahan-Starling chi allows densities above nu_m
    assert build_params({"nu": 0.7}, chi="cs")["nu"] == 0.7


@pytest.mark.parametrize(
    "values,chi,message",
    [
        ({"nu": 0.0}, "jj", "parameter nu = 0.0 is out of range; it must satisfy 0 < nu < 0.65"),
        ({"nu": 0.65}, "jj", "0 < nu < 0.65"),
        ({"nu": 0.7}, "ls", "0 < nu < 0.65"),
        ({"nu": 1.0}, "cs", "0 < nu < 1"),
        ({"nu": 0.5, "num": 0.45}, "jj", "0 < nu < 0.45"),
        ({"e": 0.0}, "jj", "0 < e <= 1"),
        ({"e": 1.2}, "jj", "0 < e <= 1"),
        ({"H": -3}, "jj", "0 < H < inf"),
        ({"Fr": 0.0}, "jj", "Froude number must be > 0"),
        ({"Fr": -5.0}, "jj", "Froude number must be > 0"),
        ({"G": -1e-3}, "jj", "0 <= G < inf"),
        ({"phi_w": 1.5}, "jj", "0 <= phi_w <= 1"),
        ({"ew": 0.0}, "jj", "0 < ew <= 1"),
        ({"num": 1.2}, "jj", "0 < num < 1"),
        ({"gamma": 1.0}, "jj", "unknown parameter 'gamma'"),
        ({"H": "wide"}, "jj", "parameter H = 'wide' is not a number"),
        ({"e": float("nan")}, "jj", "parameter e is NaN"),
        ({"Fr": 100, "G": 1.0}, "jj", "disagree"),
        ({}, "py", "unknown radial distribution"),
    ],
)
def test_build_params_rejects_bad_input_with_one_sentence(values, chi, message):
    with pytest.raises(ValueError) as info:
        build_params(values, chi=chi)
    text = str(info.value)
    assert message in text and "\n" not in text


def test_constructor_rejects_bad_options():
    with pytest.raises(ValueError, match="unknown wall model"):
        CouetteProblem("cheb", 16, walls="rough")
    with pytest.raises(ValueError, match="unknown radial distribution"):
        CouetteProblem("cheb", 16, chi="pb")
    with pytest.raises(ValueError, match="unknown discretization"):
        CouetteProblem("spline", 16)
    with pytest.raises(ValueError, match="grid too small"):
        CouetteProblem("fd6", 8)
    problem = CouetteProblem("cheb", 8)
    with pytest.raises(ValueError, match="gravity=True"):
        problem.params({"Fr": 100})
    with pytest.raises(ValueError, match="parameter G is missing"):
        problem.validate({k: v for k, v in DEFAULTS.items() if k != "G"})


def test_uniform_shear_refuses_elastic_limit():
    from problems.couette.closures import uniform_shear

    with pytest.raises(ValueError, match="e = 1 has no steady uniform shear"):
        uniform_shear(0.3, 1.0)
    t0, s0, p0 = uniform_shear(0.3, 0.8)
    assert (t0, s0, p0) == pytest.approx((0.48174, 0.32282, 0.83152), abs=1e-5)


@pytest.mark.parametrize("kw", [dict(method="cheb", N=24), dict(method="fd4", N=64, walls="jj"),
                                dict(method="fd6", N=40, dufour=True),
                                dict(method="cheb", N=16, walls="jj", dufour=True, gravity=True)])
def test_analytic_dF_dH_equals_complex_step(kw):
    """dresidual_dp(.., 'H') is analytic; it must equal the complex step to rounding."""
    from contin.problem import complex_step_dp

    pb = CouetteProblem(**kw)
    p = pb.params({"nu": 0.3, "e": 0.8, "H": 16.0, **({"G": 1e-3} if kw.get("gravity") else {})})
    x = pb.initial_guess(p)
    y = pb.grid.y
    x[pb.i_nu] += 0.02 * np.sin(np.pi * y) + 0.01 * np.cos(np.pi * (y + 0.5))
    x[pb.i_T] *= 1 + 0.1 * y**2
    x[pb.i_u] += 0.01 * np.cos(np.pi * y)
    ref = complex_step_dp(pb, x, p, "H")
    assert np.max(np.abs(pb.dresidual_dp(x, p, "H") - ref)) < 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("chi", ["jj", "cs", "ls"])
def test_real_coefficients_equal_the_general_ones_bitwise(chi):
    """closures.real_coefficients (the residual's stacked fast path) = closures.coefficients, bitwise."""
    from problems.couette.closures import coefficients, real_coefficients

    nu = np.concatenate([np.linspace(0.01, 0.6, 37), np.random.default_rng(1).uniform(0.0, 0.64, 200)])
    for e in (0.5, 0.8, 0.99):
        fast, ref = real_coefficients(nu, e, chi, 0.65), coefficients(nu, e, chi, 0.65)
        for name in ref._fields:
            a, b = np.asarray(getattr(fast, name)), np.asarray(getattr(ref, name))
            assert a.shape == b.shape == nu.shape, name
            np.testing.assert_array_equal(a, b, err_msg=name)
    assert not np.any(real_coefficients(nu, 0.8, chi, 0.65).fh)


def test_grid_setup_shared_per_grid_and_bounded():
    """Issue 14: the per-grid set-up (operators, Jacobian layouts, reflection matrix) is built once
    per process and grid and shared by instances (adaptive runs revisit grids; each branch of a
    diagram has its own instance), without changing a number: residual and Jacobian of an
    instance on a shared set-up equal those of one built from scratch; the cache stays bounded."""
    import problems.couette.model as m

    p = {**m.CouetteProblem("cheb", 12).params({"nu": 0.3, "e": 0.8}), "H": 11.0}
    for method, N, gravity in [("cheb", 12, False), ("fd4", 40, True)]:
        m._SETUPS.pop((method, N, gravity), None)
        fresh = m.CouetteProblem(method, N, gravity=gravity)
        x = fresh.initial_guess(p) * (1 + 0.01 * np.sin(np.arange(fresh.size)))
        J0, F0, S0 = fresh.jacobian(x, p).toarray(), fresh.residual(x, p), fresh.symmetry_matrix().toarray()
        again = m.CouetteProblem(method, N, gravity=gravity)
        assert again._ops is fresh._ops  # shared, not rebuilt
        np.testing.assert_array_equal(again.jacobian(x, p).toarray(), J0)
        np.testing.assert_array_equal(again.residual(x, p), F0)
        np.testing.assert_array_equal(again.symmetry_matrix().toarray(), S0)
    for N in range(8, 8 + m._SETUPS_MAX + 5):
        m.CouetteProblem("cheb", N)
    assert len(m._SETUPS) == m._SETUPS_MAX


def test_admissible_fast_path_agrees_with_the_detailed_checks():
    # admissible's fast path (argmin/argmax of nu, T and x) returns None exactly where every
    # detailed check passes: edge states on each side of each bound, non-finite entries in
    # every block, huge but finite entries
    problem = CouetteProblem("cheb", 10, gravity=True)
    p = problem.params({"nu": 0.25})
    x = perturbed(problem, p)
    limit = p["num"]

    def detailed(v):
        nu, T = v[problem.i_nu], v[problem.i_T]
        ok = np.all(np.isfinite(v)) and np.min(T) > 0 and np.min(nu) > 0 and np.max(nu) < limit
        return None if ok else "bad"

    cases = [x]
    for block, k, value in [(problem.i_nu, 0, 0.0), (problem.i_nu, 4, -0.0), (problem.i_nu, 9, limit),
                            (problem.i_nu, 2, np.nextafter(limit, 0)), (problem.i_nu, 3, 5e-324),
                            (problem.i_T, 0, 0.0), (problem.i_T, 5, 5e-324), (problem.i_T, 7, np.inf),
                            (problem.i_u, 1, np.nan), (problem.i_u, 2, -np.inf), (problem.i_T, 3, np.nan),
                            (problem.i_nu, 6, np.nan), (problem.i_M, 0, np.inf), (problem.i_u, 0, 1e200)]:
        v = x.copy()
        v[block][k] = value
        cases.append(v)
    v = x.copy()
    v[problem.i_P] = np.nan
    cases.append(v)
    for v in cases:
        got = problem.admissible(v, p)
        assert (got is None) == (detailed(v) is None), (v, got)
    huge = x.copy()
    huge[problem.i_u][0], huge[problem.i_P] = 1e300, -1.7e308
    assert problem.admissible(huge, p) is None
